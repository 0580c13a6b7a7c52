//! The paper's plane extraction in the disparity domain (section 3.4), made robust and fast
//! (≈ 3 ms per 640×480 frame on one core; the per-stage times are in [`StageTimes`]).
//!
//! 0. The disparity (`f·B/Z`, or given) is averaged over 2×2 blocks (half resolution, for the
//!    LoG) and over 4×4 pixels (**cells**, for the seeds and the k-means refinement), invalid if
//!    any pixel is. The mean of an affine function over a block is its value at the block's
//!    centre, so plane parameters carry over exactly between the grids.
//! 1. **Seeds.** The box-approximated LoG of the half-resolution disparity (the `log` module)
//!    is thresholded at a fixed value in disparity pixels; a cell is planar when its four blocks
//!    are. 4-connected components of planar cells with at least `min_pixels` (full-resolution)
//!    pixels are seeds. Each seed gets a least-squares affine fit `D = a·x + b·y + c` followed
//!    by a trimmed refit (residuals below `2τ`); the k-means iterations then refit on the cells
//!    within `τ`: a truncated-quadratic (hard-redescending) robust estimate.
//! 2. **k-means refinement** on the cells: a cell keeps its incumbent label (its seed's, or the
//!    previous pass's) while that plane fits it within `τ`; any other valid cell goes to the
//!    plane with the smallest disparity residual if it is below the fixed threshold `τ`, among
//!    the planes of its neighbouring cells (spatial coherence: a plane grows into adjacent cells;
//!    coplanar but disconnected regions join by merging). Planes are refitted from moment sums
//!    accumulated run by run, planes that one affine function explains jointly (each within
//!    `merge_px` RMS) are merged (sums add), and planar cells left unassigned form new seeds (so
//!    a component spanning a shallow crease splits into its planes). Repeats until the labels
//!    settle or `max_iterations`.
//! 3. **Coherence and final pass**: 4-connected pieces of a plane's cells smaller than
//!    `min_piece_pixels` are dropped; then every full-resolution pixel takes its cell's label if
//!    that plane fits it within `τ`; otherwise, and for the pixels of unlabelled cells touching
//!    a labelled one, the best plane of the neighbouring cells within `τ`. Pixels fitting two
//!    planes take the label that dominates their 8-neighbourhood. The planes are refitted on
//!    the labelled pixels of every fourth row (which also gives the RMS residual in pixels; the
//!    centroid and the RMS in metres come from every eighth row); pixel counts are exact.
//!
//! Everything after the disparity conversion works on the disparity, so the threshold means the
//! same at 0.6 m and at 4 m: the noise of a structured-light camera is constant in disparity.
//!
//! The per-pixel and per-cell loops are run-based and vectorised (`wide`, baseline SSE2): runs
//! of equal labels are tested against their plane eight pixels at a time with the moments of
//! the pixels that pass accumulated as small residuals in `f32` lanes (see `kernels`), and the
//! candidate searches compare eight pixels with each candidate at once. A [`PlaneExtractor`]
//! keeps its buffers, so a video allocates only the output per frame.

use std::time::Instant;

use nalgebra::Point3;
#[cfg(test)]
use sl_core::DepthImage;
use sl_core::{Camera, DepthView, DisparityImage, Image, Intrinsics};
use wide::{CmpEq, i16x8};

use crate::components::RunLabeler;
use crate::error::{PlanesError, Result};
use crate::fit::AffineSums;
use crate::kernels::{
    InvSums, LANES, depth_to_disparity_row, downsample_rows, fit_run, fit_run_labels, search8,
    search8_two, valid_mask,
};
use crate::log::{LogBuffers, RowSource, log_geometry, planar_mask_uncounted};
use crate::plane::{DisparityAffine, Plane3};

/// Parameters of the disparity-domain extractor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneConfig {
    /// Fixed residual threshold `τ` in disparity pixels: a pixel belongs to a plane when
    /// `|D − D_plane| < τ`.
    pub threshold_px: f64,
    /// Threshold on the magnitude of the box-LoG response, disparity pixels.
    pub log_threshold_px: f64,
    /// Scale of the LoG, pixels.
    pub log_sigma_px: f64,
    /// Minimum pixels of a seed component and of an output plane.
    pub min_pixels: usize,
    /// Maximum refinement iterations (coarse passes) before the final pass.
    pub max_iterations: usize,
    /// Two planes merge when the least-squares plane of their union fits each of them with an
    /// RMS residual below this, pixels (of the cell-averaged disparity).
    pub merge_px: f64,
    /// Disconnected pieces of a plane smaller than this are dropped (0 keeps all).
    pub min_piece_pixels: usize,
}

impl Default for PlaneConfig {
    fn default() -> Self {
        Self {
            threshold_px: 0.5,
            log_threshold_px: 0.1,
            log_sigma_px: 2.0,
            min_pixels: 1000,
            max_iterations: 3,
            merge_px: 0.3,
            min_piece_pixels: 256,
        }
    }
}

impl PlaneConfig {
    /// Checks the ranges of all parameters.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(PlanesError::InvalidConfig(format!(
                    "{name} = {v} must be positive and finite"
                )))
            }
        };
        pos("threshold_px", self.threshold_px)?;
        pos("log_threshold_px", self.log_threshold_px)?;
        pos("merge_px", self.merge_px)?;
        pos("log_sigma_px", self.log_sigma_px)?;
        if self.log_sigma_px > 16.0 {
            return Err(PlanesError::InvalidConfig(format!(
                "log_sigma_px = {} must be at most 16",
                self.log_sigma_px
            )));
        }
        if self.min_pixels < 3 {
            return Err(PlanesError::InvalidConfig(
                "min_pixels must be at least 3".into(),
            ));
        }
        Ok(())
    }
}

/// One extracted plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneInfo {
    /// Label in the label image (1-based; planes are sorted by decreasing size).
    pub id: u16,
    /// The 3D plane in camera coordinates.
    pub plane: Plane3,
    /// The disparity function `D = a·x + b·y + c` of the plane.
    pub affine: DisparityAffine,
    /// Number of pixels with this label.
    pub pixels: usize,
    /// RMS disparity residual of the labelled pixels, pixels.
    pub rms_px: f64,
    /// RMS point-to-plane distance of the labelled pixels, metres.
    pub rms_m: f64,
    /// Centroid of the labelled points, camera coordinates, metres.
    pub centroid_m: Point3<f64>,
}

/// The result of a plane extraction.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneSegmentation {
    /// Per-pixel plane id (0 = not on any plane).
    pub labels: Image<u16>,
    /// The planes, `planes[i].id == i + 1`.
    pub planes: Vec<PlaneInfo>,
}

/// Cells per chunk of the coarse search (one vector of 8 lanes).
const CHUNK: usize = LANES;
/// Most planes tracked at once.
const MAX_PLANES: usize = 4000;
/// No merge target.
const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Cand {
    /// Affine fit in cell coordinates.
    f: DisparityAffine,
    /// Moments in cell coordinates.
    sums: AffineSums,
    /// Support box `[x0, y0, x1, y1]` (inclusive), cells.
    bbox: [u32; 4],
    alive: bool,
    /// Index of the plane this one was merged into.
    into: u32,
}

/// Side of a cell of the k-means grid, pixels.
const CELL: usize = 4;

/// The full-resolution affine function of a cell-grid one: cell `(i, j)` is centred on pixel
/// `(4i + 1.5, 4j + 1.5)`.
fn cell_to_full(f: &DisparityAffine) -> DisparityAffine {
    let (a, b) = (f.a / 4.0, f.b / 4.0);
    DisparityAffine {
        a,
        b,
        c: f.c - 1.5 * (a + b),
    }
}

/// Rows whose labelled pixels feed the final fit (a quarter of the rows).
#[inline]
fn is_sample_row(y: usize) -> bool {
    y.is_multiple_of(4)
}

/// Rows whose labelled pixels feed the metric statistics (centroid, RMS in metres; an eighth
/// of the rows).
#[inline]
fn is_metric_row(y: usize) -> bool {
    y.is_multiple_of(8)
}

/// Per-plane accumulators of the final statistics: moments of the labelled pixels of the even
/// rows (full-resolution coordinates), their metric sums, and the exact pixel count.
#[derive(Debug, Clone, Copy, Default)]
struct FinalAcc {
    sums: AffineSums,
    inv: InvSums,
    pixels: usize,
    /// Rows `y0..y1` holding the plane's pixels.
    y0: usize,
    y1: usize,
}

impl FinalAcc {
    #[inline]
    fn add_rows(&mut self, y: usize) {
        self.y0 = self.y0.min(y);
        self.y1 = self.y1.max(y + 1);
    }
}

/// A reusable plane extractor: holds its work buffers so that repeated calls on frames of the
/// same size allocate nothing beyond the output (the label image and the plane list).
///
/// ```
/// use sl_core::{Camera, DepthImage};
/// use sl_planes::{PlaneConfig, PlaneExtractor, Stage};
///
/// let cam = Camera::kinect_v1();
/// let k = cam.intrinsics;
/// let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
/// // A fronto-parallel wall at 2 m, then a frame with nothing valid.
/// let wall = DepthImage::from_vec(k.width, k.height, vec![2.0; k.width * k.height])?;
/// assert_eq!(ex.extract_depth(&wall, &cam)?.planes.len(), 1);
/// let empty = DepthImage::invalid(k.width, k.height);
/// assert!(ex.extract_depth(&empty, &cam)?.planes.is_empty());
/// // Time per stage of the last frame.
/// let _ns = ex.stage_times().ns(Stage::FinalPass);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct PlaneExtractor {
    cfg: PlaneConfig,
    d: Vec<f32>,
    dh: Vec<f32>,
    dq: Vec<f32>,
    maskq: Vec<u8>,
    labq: Vec<u16>,
    mask: Vec<u8>,
    log: LogBuffers,
    cc: RunLabeler,
    planes: Vec<Cand>,
    spare: Vec<Cand>,
    free: Vec<u8>,
    keep: Vec<u8>,
    need: Vec<u8>,
    hruns: Vec<(u32, u32, u16)>,
    pre_row: Vec<u16>,
    drow: Vec<f32>,
    ukeep: Vec<u8>,
    chunks: Vec<(u32, u64)>,
    near_tag: Vec<u32>,
    near_set: Vec<[u16; 16]>,
    near_len: Vec<u8>,
    zrow: Vec<u16>,
    cursor: Vec<u32>,
    fa: Vec<f32>,
    rowc: Vec<f32>,
    full: Vec<DisparityAffine>,
    acc: Vec<FinalAcc>,
    amb: Vec<(u32, u16, u16)>,
    comp_sums: Vec<AffineSums>,
    comp_box: Vec<[u32; 4]>,
    comp_fit: Vec<Option<DisparityAffine>>,
    lut: Vec<u16>,
    times: StageTimes,
}

/// The full-resolution input of [`PlaneExtractor::run`].
enum Source<'a> {
    /// Disparity (pixels; non-positive or non-finite = invalid), used in place.
    Disparity(&'a [f32]),
    /// Depth (metres), converted row pair by row pair into `d` (two rows).
    Depth {
        z: &'a [f32],
        d: &'a mut [f32],
        fb: f32,
    },
}

/// The full-resolution disparity for the final pass: the input disparity, or the depth, whose
/// rows are converted again where they are used (the same conversion, so the same bits, without
/// writing and re-reading a full-resolution disparity image).
#[derive(Clone, Copy)]
enum FullDisparity<'a> {
    /// Disparity (pixels; non-positive or non-finite = invalid).
    Disparity(&'a [f32]),
    /// Depth (metres) and `f·B`.
    Depth { z: &'a [f32], fb: f32 },
}

impl<'a> FullDisparity<'a> {
    /// Row `y` (width `w`) of the disparity, converted into `scratch` (length `w`) for depth.
    #[inline]
    fn row<'s>(self, y: usize, w: usize, scratch: &'s mut [f32]) -> &'s [f32]
    where
        'a: 's,
    {
        match self {
            FullDisparity::Disparity(d) => &d[y * w..(y + 1) * w],
            FullDisparity::Depth { z, fb } => {
                depth_to_disparity_row(&z[y * w..(y + 1) * w], scratch, fb);
                scratch
            }
        }
    }

    /// The disparity of pixel `i` (the scalar form of `depth_to_disparity_row` for depth).
    #[inline]
    fn at(self, i: usize) -> f32 {
        match self {
            FullDisparity::Disparity(d) => d[i],
            FullDisparity::Depth { z, fb } => {
                let zv = z[i];
                if zv > 0.0 && zv < f32::INFINITY {
                    fb / zv
                } else {
                    0.0
                }
            }
        }
    }
}

/// The half-resolution disparity (2×2 means, NaN = invalid) produced row by row for the LoG,
/// from the full-resolution rows (converted from depth on the way) while they are in L1; after
/// each odd row, the row of the cells `dq` (2×2 means of the half-resolution map).
struct HalfRows<'a, 'b> {
    src: Source<'a>,
    /// The last two half-resolution rows.
    dh: &'b mut [f32],
    dq: &'b mut [f32],
    /// Full-resolution width.
    w: usize,
    /// Next half-resolution row.
    next: usize,
}

impl<'a> HalfRows<'a, '_> {
    /// Produces the next half-resolution row (and cell row) and returns its index.
    fn produce(&mut self) -> usize {
        let (w, y2) = (self.w, self.next);
        self.next += 1;
        let pair = 2 * y2 * w..(2 * y2 + 2) * w;
        let r2: &[f32] = match &mut self.src {
            Source::Disparity(d) => &d[pair],
            Source::Depth { z, d, fb } => {
                let (zp, dp) = (&z[pair], &mut d[..2 * w]);
                for (zr, dr) in zp.chunks_exact(w).zip(dp.chunks_exact_mut(w)) {
                    depth_to_disparity_row(zr, dr, *fb);
                }
                dp
            }
        };
        let (r0, r1) = r2.split_at(w);
        let w2 = w / 2;
        let (q0, q1) = self.dh.split_at_mut(w2);
        let out = if y2.is_multiple_of(2) { q0 } else { q1 };
        downsample_rows(r0, r1, out);
        if !y2.is_multiple_of(2) {
            let (q0, q1) = self.dh.split_at(w2);
            let (wq, j) = (w2 / 2, y2 / 2);
            let out = &mut self.dq[j * wq..(j + 1) * wq];
            for ((o, p), q) in out
                .iter_mut()
                .zip(q0.chunks_exact(2))
                .zip(q1.chunks_exact(2))
            {
                *o = 0.25 * ((p[0] + p[1]) + (q[0] + q[1]));
            }
        }
        y2
    }

    /// Produces the rows the LoG left (all of `dh` and `dq` are then done) and returns the
    /// full-resolution disparity.
    fn finish(mut self, h: usize) -> FullDisparity<'a> {
        while self.next < h / 2 {
            self.produce();
        }
        match self.src {
            Source::Disparity(d) => FullDisparity::Disparity(d),
            Source::Depth { z, fb, .. } => FullDisparity::Depth { z, fb },
        }
    }
}

impl RowSource for HalfRows<'_, '_> {
    fn next_row(&mut self) -> &[f32] {
        let y2 = self.produce();
        let w2 = self.w / 2;
        &self.dh[(y2 % 2) * w2..(y2 % 2 + 1) * w2]
    }
}

/// Extracts planes from a depth image (metres) with a new extractor.
pub fn extract_planes<'a>(
    depth: impl Into<DepthView<'a>>,
    camera: &Camera,
    cfg: &PlaneConfig,
) -> Result<PlaneSegmentation> {
    PlaneExtractor::new(*cfg)?.extract_depth(depth, camera)
}

impl PlaneExtractor {
    /// A new extractor with the given configuration.
    pub fn new(cfg: PlaneConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            ..Self::default()
        })
    }

    /// The configuration.
    pub fn config(&self) -> &PlaneConfig {
        &self.cfg
    }

    /// Wall-clock time per stage of the last extraction.
    pub fn stage_times(&self) -> &StageTimes {
        &self.times
    }

    fn check(w: usize, h: usize, k: &Intrinsics) -> Result<()> {
        if w != k.width || h != k.height {
            return Err(PlanesError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: w,
                height: h,
            });
        }
        Ok(())
    }

    /// Extracts planes from a depth image (metres, 0 = invalid); the disparity is `f·B / Z` with
    /// the camera's sensor model.
    ///
    /// `depth` is a `&DepthImage` or a [`DepthView`] over a buffer the caller owns (no copy).
    pub fn extract_depth<'a>(
        &mut self,
        depth: impl Into<DepthView<'a>>,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        let depth: DepthView<'a> = depth.into();
        let (w, h) = (depth.width(), depth.height());
        Self::check(w, h, &camera.intrinsics)?;
        let mut t0 = Instant::now();
        self.times = StageTimes::default();
        let fb = camera.sensor.fb();
        let fbf = fb as f32;
        // Scratch for one row pair: the full-resolution disparity is never stored.
        let mut d = std::mem::take(&mut self.d);
        d.resize(2 * w, 0.0);
        let src = Source::Depth {
            z: depth.data(),
            d: &mut d,
            fb: fbf,
        };
        self.times.add(Stage::Disparity, &mut t0);
        let out = self.run(src, w, h, &camera.intrinsics, fb, t0);
        self.d = d;
        out
    }

    /// Extracts planes from a disparity image (pixels, 0 = invalid), e.g. raw Kinect disparity
    /// converted to pixels; `f·B` of the camera relates it to depth.
    pub fn extract_disparity(
        &mut self,
        disparity: &DisparityImage,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        let (w, h) = (disparity.width(), disparity.height());
        Self::check(w, h, &camera.intrinsics)?;
        let mut t0 = Instant::now();
        self.times = StageTimes::default();
        // The disparity is used in place: every test treats non-positive and non-finite values
        // as invalid.
        let src = Source::Disparity(disparity.data());
        self.times.add(Stage::Disparity, &mut t0);
        self.run(src, w, h, &camera.intrinsics, camera.sensor.fb(), t0)
    }

    fn run(
        &mut self,
        src: Source<'_>,
        w: usize,
        h: usize,
        k: &Intrinsics,
        fb: f64,
        mut t0: Instant,
    ) -> Result<PlaneSegmentation> {
        let cfg = self.cfg;
        let tau = cfg.threshold_px as f32;
        self.planes.clear();
        self.acc.clear();
        let (w2, h2) = (w / 2, h / 2);
        let (wq, hq) = (w2 / 2, h2 / 2);
        // The final pass appends the rows of the label image (no zeroing of the whole image).
        let mut labels: Vec<u16> = Vec::with_capacity(w * h);
        if wq < 8 || hq < 8 {
            labels.resize(w * h, 0);
            return self.finish(w, h, k, fb, labels);
        }
        // 0. The disparity and its 2×2 means, row pair by row pair as the LoG consumes them.
        self.dh.resize(2 * w2, f32::NAN);
        self.dq.resize(wq * hq, f32::NAN);
        let mut rows = HalfRows {
            src,
            dh: &mut self.dh,
            dq: &mut self.dq,
            w,
            next: 0,
        };
        // Row scratch; `fit_run` may write up to 7 bytes past a run.
        self.keep.resize(w + LANES, 0);
        // 1. Seeds: the LoG on the half-resolution map, components on the cell grid.
        let (r, s) = log_geometry(cfg.log_sigma_px / 2.0);
        planar_mask_uncounted(
            &mut rows,
            w2,
            h2,
            r,
            s,
            cfg.log_threshold_px as f32,
            &mut self.log,
            &mut self.mask,
        );
        let d = rows.finish(h);
        self.planar_cells(w2, wq, hq);
        self.times.add(Stage::Log, &mut t0);
        self.cc.label(&self.maskq, wq, hq);
        self.times.add(Stage::Components, &mut t0);
        let min_q = (cfg.min_pixels / (CELL * CELL)).max(3);
        self.seed_from_components(wq, min_q);
        self.times.add(Stage::SeedFits, &mut t0);
        self.merge();
        self.compact();
        self.times.add(Stage::Merge, &mut t0);

        // 2. k-means refinement on the cell grid (4×4 pixels).
        for it in 0..cfg.max_iterations {
            if self.planes.is_empty() {
                break;
            }
            let (changed, free) = self.coarse_pass(wq, hq, tau);
            for p in self.planes.iter_mut() {
                p.alive = p.sums.n >= min_q as f64;
                if p.alive {
                    match p.sums.solve() {
                        Some(f) => p.f = f,
                        None => p.alive = false,
                    }
                }
            }
            self.times.add(Stage::Refine, &mut t0);
            self.merge();
            self.compact();
            self.times.add(Stage::Merge, &mut t0);
            if it + 1 < cfg.max_iterations && free >= min_q {
                self.cc.label(&self.free, wq, hq);
                self.times.add(Stage::Components, &mut t0);
                let before = self.planes.len();
                self.seed_from_components(wq, min_q);
                self.times.add(Stage::SeedFits, &mut t0);
                if self.planes.len() > before {
                    self.merge();
                    self.compact();
                    self.times.add(Stage::Merge, &mut t0);
                    continue;
                }
            }
            if changed * 500 < wq * hq {
                break;
            }
        }

        // 3. Coherence on the cell grid, then the final full-resolution pass.
        if !self.planes.is_empty() {
            if cfg.min_piece_pixels > 0 {
                self.drop_small_pieces(wq, hq);
            }
            self.times.add(Stage::Components, &mut t0);
            self.order_by_size();
            self.final_pass(d, w, h, wq, tau, &mut labels);
            self.times.add(Stage::FinalPass, &mut t0);
            self.resolve_ambiguous(d, w, h, &mut labels);
            self.times.add(Stage::Disambiguate, &mut t0);
        }
        labels.resize(w * h, 0);
        let out = self.finish(w, h, k, fb, labels);
        self.times.add(Stage::Output, &mut t0);
        out
    }

    /// Creates planes from the components in `self.cc` (on the cell grid of width `wg`) with at
    /// least `min` cells: least squares, then refitted on the inliers within 2τ.
    #[inline(never)]
    fn seed_from_components(&mut self, wg: usize, min: usize) {
        let nc = self.cc.sizes.len();
        self.comp_sums.clear();
        self.comp_sums.resize(nc, AffineSums::default());
        self.comp_box.clear();
        self.comp_box.resize(nc, [u32::MAX, u32::MAX, 0, 0]);
        self.comp_fit.clear();
        self.comp_fit.resize(nc, None);
        let lim = 2.0 * self.cfg.threshold_px as f32;
        let mut inv = InvSums::default();
        for pass in 0..2 {
            if pass > 0 {
                self.comp_sums.fill(AffineSums::default());
            }
            for (ri, run) in self.cc.runs.iter().enumerate() {
                let c = self.cc.component[ri] as usize;
                if self.cc.sizes[c] < min {
                    continue;
                }
                let j = run.y as usize;
                let (x0, x1) = (run.x0 as usize, run.x1 as usize);
                // The rest of the row: `fit_run` reads and writes ahead.
                let seg = &self.dq[j * wg + x0..(j + 1) * wg];
                let keep = &mut self.keep[x0..];
                let n = x1 - x0;
                let jf = j as f64;
                let sums = &mut self.comp_sums[c];
                if pass == 0 {
                    grow(&mut self.comp_box[c], x0, x1 - 1, j);
                    // Plain least squares; residuals against the run's first value.
                    let d0 = f64::from(seg[0]);
                    fit_run::<true, false>(
                        seg,
                        keep,
                        n,
                        x0,
                        jf,
                        0.0,
                        d0,
                        f32::INFINITY,
                        sums,
                        &mut inv,
                    );
                } else if let Some(f) = self.comp_fit[c] {
                    // Trimmed refit on the inliers within 2τ.
                    fit_run::<true, false>(
                        seg,
                        keep,
                        n,
                        x0,
                        jf,
                        f.a,
                        f.b * jf + f.c,
                        lim,
                        sums,
                        &mut inv,
                    );
                }
            }
            for c in 0..nc {
                if self.cc.sizes[c] >= min && (pass == 0 || self.comp_fit[c].is_some()) {
                    let s = &self.comp_sums[c];
                    self.comp_fit[c] = if s.n >= (min as f64) * 0.5 {
                        s.solve()
                    } else {
                        None
                    };
                }
            }
        }
        // Each seed's blocks start with its label (the incumbent in the k-means passes).
        let mut plane_of: Vec<u16> = vec![0; nc];
        for (c, slot) in plane_of.iter_mut().enumerate() {
            if let Some(f) = self.comp_fit[c]
                && self.planes.len() < MAX_PLANES
            {
                *slot = self.planes.len() as u16 + 1;
                self.planes.push(Cand {
                    f,
                    sums: self.comp_sums[c],
                    bbox: self.comp_box[c],
                    alive: true,
                    into: NONE,
                });
            }
        }
        for (ri, run) in self.cc.runs.iter().enumerate() {
            let lab = plane_of[self.cc.component[ri] as usize];
            if lab != 0 {
                let y = run.y as usize;
                self.labq[y * wg + run.x0 as usize..y * wg + run.x1 as usize].fill(lab);
            }
        }
    }

    /// The planarity of the cells (all four of their half-resolution blocks planar), and fresh
    /// label and free-cell grids.
    #[inline(never)]
    fn planar_cells(&mut self, w2: usize, wq: usize, hq: usize) {
        self.labq.clear();
        self.labq.resize(wq * hq, 0);
        self.maskq.resize(wq * hq, 0);
        self.free.clear();
        self.free.resize(wq * hq, 0);
        for (j, mq) in self.maskq.chunks_exact_mut(wq).take(hq).enumerate() {
            let m0 = &self.mask[2 * j * w2..(2 * j + 1) * w2];
            let m1 = &self.mask[(2 * j + 1) * w2..(2 * j + 2) * w2];
            for ((o, p), q) in mq
                .iter_mut()
                .zip(m0.chunks_exact(2))
                .zip(m1.chunks_exact(2))
            {
                *o = p[0] & p[1] & q[0] & q[1];
            }
        }
    }

    /// Merges planes that one affine function explains jointly: the least-squares plane of the
    /// union fits each of the two with an RMS below `merge_px`.
    #[inline(never)]
    fn merge(&mut self) {
        let mp = self.cfg.merge_px;
        let pre = 4.0 * self.cfg.threshold_px;
        for _round in 0..8 {
            let mut merged = false;
            let n = self.planes.len();
            for i in 0..n {
                if !self.planes[i].alive {
                    continue;
                }
                for j in (i + 1)..n {
                    if !self.planes[j].alive {
                        continue;
                    }
                    let (pi, pj) = (&self.planes[i], &self.planes[j]);
                    let bb = union_box(&pi.bbox, &pj.bbox);
                    let df = DisparityAffine {
                        a: pi.f.a - pj.f.a,
                        b: pi.f.b - pj.f.b,
                        c: pi.f.c - pj.f.c,
                    };
                    let worst = [
                        (bb[0], bb[1]),
                        (bb[2], bb[1]),
                        (bb[0], bb[3]),
                        (bb[2], bb[3]),
                    ]
                    .iter()
                    .map(|&(x, y)| df.eval(f64::from(x), f64::from(y)).abs())
                    .fold(0.0, f64::max);
                    if worst > pre {
                        continue;
                    }
                    let mut u = pi.sums;
                    u.merge(&pj.sums);
                    let Some(f) = u.solve() else { continue };
                    if pi.sums.rms(&f) < mp && pj.sums.rms(&f) < mp {
                        let pi = &mut self.planes[i];
                        pi.sums = u;
                        pi.f = f;
                        pi.bbox = bb;
                        self.planes[j].alive = false;
                        self.planes[j].into = i as u32;
                        merged = true;
                    }
                }
            }
            if !merged {
                break;
            }
        }
    }

    /// Removes dead planes and renumbers the cell labels (merged planes' cells go
    /// to the plane they merged into).
    #[inline(never)]
    fn compact(&mut self) {
        let n = self.planes.len();
        self.lut.clear();
        self.lut.resize(n + 1, 0);
        let mut next = 0u16;
        let newidx = &mut self.cursor;
        newidx.clear();
        newidx.resize(n, 0);
        for (i, p) in self.planes.iter().enumerate() {
            if p.alive {
                next += 1;
                newidx[i] = u32::from(next);
            }
        }
        for i in 0..n {
            let mut r = i;
            let mut guard = 0;
            while !self.planes[r].alive && self.planes[r].into != NONE && guard < n {
                r = self.planes[r].into as usize;
                guard += 1;
            }
            self.lut[i + 1] = if self.planes[r].alive {
                newidx[r] as u16
            } else {
                0
            };
        }
        if self.lut.iter().enumerate().any(|(i, &v)| v as usize != i) {
            relabel(&mut self.labq, &self.lut);
        }
        self.planes.retain(|p| p.alive);
        for p in self.planes.iter_mut() {
            p.into = NONE;
        }
    }

    /// Renumbers the planes by decreasing support (cells of the last pass), so that the
    /// final ids (by decreasing pixel count) usually need no relabelling of the full image.
    #[inline(never)]
    fn order_by_size(&mut self) {
        let n = self.planes.len();
        let order = &mut self.cursor;
        order.clear();
        order.extend(0..n as u32);
        order.sort_by(|&a, &b| {
            self.planes[b as usize]
                .sums
                .n
                .total_cmp(&self.planes[a as usize].sums.n)
        });
        if order.iter().enumerate().all(|(i, &o)| o as usize == i) {
            return;
        }
        self.lut.clear();
        self.lut.resize(n + 1, 0);
        self.spare.clear();
        for (new, &old) in order.iter().enumerate() {
            self.lut[old as usize + 1] = new as u16 + 1;
            self.spare.push(self.planes[old as usize]);
        }
        std::mem::swap(&mut self.planes, &mut self.spare);
        relabel(&mut self.labq, &self.lut);
    }

    /// One assignment pass on the cells; refills the planes' sums and boxes. Returns the number
    /// of labels that changed and the number of planar but unassigned cells (marked in `free`).
    ///
    /// Runs of equal incumbent labels are tested against their plane in one vectorised sweep
    /// (the cells that pass are accumulated there); the cells that fail, and unlabelled cells,
    /// then take the best of the planes of the cells around them, searched 8 cells at a time.
    #[inline(never)]
    fn coarse_pass(&mut self, wq: usize, hq: usize, tau: f32) -> (usize, usize) {
        for p in self.planes.iter_mut() {
            p.sums = AffineSums::default();
            p.bbox = EMPTY_BOX;
        }
        self.fa.clear();
        self.fa.extend(self.planes.iter().map(|p| p.f.a as f32));
        // With at most 64 planes, the planes around a chunk are the bits of the labels of the
        // three rows around it (above: this pass's labels; this row: a copy from before its
        // searches; below: not yet searched).
        let small = self.planes.len() <= 64;
        let planes = &mut self.planes;
        let mut inv = InvSums::default();
        let (mut changed, mut free) = (0usize, 0usize);
        for j in 0..hq {
            if small {
                self.pre_row.clear();
                self.pre_row
                    .extend_from_slice(&self.labq[j * wq..(j + 1) * wq]);
            }
            let jf = j as f64;
            self.rowc.clear();
            self.rowc
                .extend(planes.iter().map(|p| (p.f.b * jf + p.f.c) as f32));
            let rowc: &[f32] = &self.rowc;
            let fa: &[f32] = &self.fa;
            let row = &self.dq[j * wq..(j + 1) * wq];
            let mrow = &self.maskq[j * wq..(j + 1) * wq];
            let (above, rest) = self.labq.split_at_mut(j * wq);
            let (lrow, below) = rest.split_at_mut(wq);
            let up: &[u16] = if j > 0 { &above[(j - 1) * wq..] } else { &[] };
            let dn: &[u16] = below.get(..wq).unwrap_or(&[]);
            let frow = &mut self.free[j * wq..(j + 1) * wq];
            let keep = &mut self.keep[..];
            let mut near = [0u16; 16];
            // Incumbents.
            let mut i = 0;
            while i < wq {
                let v = lrow[i];
                let e = run_end(lrow, i);
                match planes.get_mut((v as usize).wrapping_sub(1)) {
                    Some(p) => {
                        let kept = fit_run::<true, false>(
                            &row[i..],
                            &mut keep[i..],
                            e - i,
                            i,
                            jf,
                            p.f.a,
                            p.f.b * jf + p.f.c,
                            tau,
                            &mut p.sums,
                            &mut inv,
                        );
                        if kept > 0 {
                            let ks = &keep[i..e];
                            let first = ks.iter().position(|&k| k != 0).unwrap_or(0);
                            let last = ks.iter().rposition(|&k| k != 0).unwrap_or(0);
                            grow(&mut p.bbox, i + first, i + last, j);
                        }
                    }
                    None => keep[i..e].fill(0),
                }
                i = e;
            }
            // The others, one tile (8 blocks) at a time.
            frow.fill(0);
            let mut i0 = 0;
            while i0 < wq {
                let i1 = (i0 + CHUNK).min(wq);
                let (dt, kt) = (&row[i0..i1], &keep[i0..i1]);
                let kk = <[u8; LANES]>::try_from(kt).unwrap_or_else(|_| pad(kt, 1));
                // Lanes to search: keep byte 0.
                let searched = byte_mask(!u64::from_le_bytes(kk) & ALL_KEPT);
                if searched == 0 {
                    i0 = i1;
                    continue;
                }
                let d8 = <[f32; LANES]>::try_from(dt).unwrap_or_else(|_| pad(dt, f32::NAN));
                let (labs, found) = if searched & valid_mask(&d8) != 0 {
                    // Candidates: the planes of the cells around the chunk (spatial
                    // coherence; coplanar disconnected regions join by merging).
                    let (a, b) = (i0.saturating_sub(1), (i1 + 1).min(wq));
                    let nc = if small {
                        let bits =
                            or_bits(up, a, b) | or_bits(&self.pre_row, a, b) | or_bits(dn, a, b);
                        bits_to_planes(bits, &mut near)
                    } else {
                        neighbour_planes([up, &*lrow, dn], a, b, &mut near)
                    };
                    search8(&d8, i0 as f32, &near[..nc], fa, rowc, tau)
                } else {
                    ([0u16; LANES], 0)
                };
                let (lt, mt) = (&mut lrow[i0..i1], &mrow[i0..i1]);
                let mut todo = searched & (found | nonzero_mask(lt) | byte_mask(pad_word(mt)));
                // Searched lanes outside `todo` stay unlabelled (invalid or no plane fits)
                // and were unlabelled, unmasked: nothing changes.
                while todo != 0 {
                    let o = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let (lab, old) = (labs[o], lt[o]);
                    changed += usize::from(lab != old);
                    lt[o] = lab;
                    let fr = lab == 0 && mt[o] == 1;
                    frow[i0 + o] = u8::from(fr);
                    free += usize::from(fr);
                    if let Some(p) = planes.get_mut((lab as usize).wrapping_sub(1)) {
                        let ii = i0 + o;
                        p.sums.add(ii as f64, jf, f64::from(dt[o]));
                        grow(&mut p.bbox, ii, ii, j);
                    }
                }
                i0 = i1;
            }
        }
        (changed, free)
    }

    /// The full-resolution assignment, with the final moments of the sample rows: each pixel
    /// takes its cell's label if that plane fits it within `τ` (runs of equal cell labels are
    /// tested in one vectorised sweep); otherwise, and for the pixels of unlabelled cells
    /// touching a labelled cell, the planes of the cells around are searched, 8 pixels at a time
    /// (pixels that fit two planes are recorded for the disambiguation). Pixels of unlabelled
    /// cells away from planes stay unlabelled (coherence).
    #[inline(never)]
    fn final_pass(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        wq: usize,
        tau: f32,
        labels: &mut Vec<u16>,
    ) {
        // Each row is labelled in place: the row is appended as zeros to `labels` (which holds
        // the rows above on entry to the row), then written.
        labels.clear();
        let mut drow = std::mem::take(&mut self.drow);
        drow.resize(w, 0.0);
        self.acc.clear();
        self.acc.resize(
            self.planes.len(),
            FinalAcc {
                y0: usize::MAX,
                ..FinalAcc::default()
            },
        );
        self.amb.clear();
        self.full.clear();
        self.full
            .extend(self.planes.iter().map(|p| cell_to_full(&p.f)));
        self.fa.clear();
        self.fa.extend(self.full.iter().map(|f| f.a as f32));
        let full: &[DisparityAffine] = &self.full;
        let fa: &[f32] = &self.fa;
        let acc = &mut self.acc;
        let amb = &mut self.amb;
        let empty: &[u16] = &[];
        let hrow = |jj: usize| self.labq.get(jj * wq..(jj + 1) * wq).unwrap_or(empty);
        let mut inv_dummy = InvSums::default();
        let mut sums_dummy = AffineSums::default();
        let nchunks = w.div_ceil(LANES);
        // With at most 64 planes, labels are at most 64 (bit masks of the candidates).
        let small = self.planes.len() <= 64;
        self.near_tag.clear();
        self.near_tag.resize(nchunks, 0);
        self.near_set.resize(nchunks, [0; 16]);
        self.near_len.resize(nchunks, 0);
        self.need.clear();
        self.need.resize(wq, 0);
        self.zrow.clear();
        self.zrow.resize(wq, 0);
        for y in 0..h {
            let yf = y as f64;
            let (stats, metric) = (is_sample_row(y), is_metric_row(y));
            self.rowc.clear();
            self.rowc
                .extend(full.iter().map(|f| (f.b * yf + f.c) as f32));
            let rowc: &[f32] = &self.rowc;
            let j = y / CELL;
            let hint_row = hrow(j);
            let up_row = if j > 0 { hrow(j - 1) } else { empty };
            let dn_row = hrow(j + 1);
            let zrow = &self.zrow[..];
            let nh = hint_row.len();
            let need = &mut self.need[..nh];
            if y % CELL == 0 {
                let up2 = if up_row.is_empty() { zrow } else { up_row };
                let dn2 = if dn_row.is_empty() { zrow } else { dn_row };
                touching(hint_row, up2, dn2, need);
                // The keep bytes of the pixels of unlabelled cells (0 = search).
                self.ukeep.clear();
                self.ukeep
                    .extend(need.iter().flat_map(|&nd| [1 - nd; CELL]));
                // The runs of equal cell labels, shared by the rows of this cell row.
                self.hruns.clear();
                let mut i = 0;
                while i < nh {
                    let e = run_end(hint_row, i);
                    self.hruns.push((i as u32, e as u32, hint_row[i]));
                    i = e;
                }
            }
            let row_d = d.row(y, w, &mut drow[..w]);
            labels.resize((y + 1) * w, 0);
            let row_l = &mut labels[y * w..(y + 1) * w];
            let keep = &mut self.keep[..];
            // keep: 1 = labelled or stays unlabelled, 0 = search.
            for &(i, e, v) in &self.hruns {
                let (i, e) = (i as usize, e as usize);
                let (x0, x1) = (CELL * i, (CELL * e).min(w));
                if let Some(a) = (v as usize).checked_sub(1).and_then(|ku| acc.get_mut(ku)) {
                    // The rest of the row: `fit_run` reads and writes ahead.
                    let (seg, ks) = (&row_d[x0..], &mut keep[x0..]);
                    let f = &full[v as usize - 1];
                    let c_row = f.b * yf + f.c;
                    let n = x1 - x0;
                    let lab = &mut row_l[x0..];
                    let kept = if metric {
                        fit_run_labels::<true, true, true>(
                            seg,
                            ks,
                            lab,
                            v,
                            n,
                            x0,
                            yf,
                            f.a,
                            c_row,
                            tau,
                            &mut a.sums,
                            &mut a.inv,
                        )
                    } else if stats {
                        fit_run_labels::<true, false, true>(
                            seg,
                            ks,
                            lab,
                            v,
                            n,
                            x0,
                            yf,
                            f.a,
                            c_row,
                            tau,
                            &mut a.sums,
                            &mut inv_dummy,
                        )
                    } else {
                        fit_run_labels::<false, false, true>(
                            seg,
                            ks,
                            lab,
                            v,
                            n,
                            x0,
                            yf,
                            f.a,
                            c_row,
                            tau,
                            &mut sums_dummy,
                            &mut inv_dummy,
                        )
                    };
                    a.pixels += kept;
                    a.add_rows(y);
                } else {
                    // Unlabelled cells: searched only when touching a labelled cell (`x1` is
                    // `CELL · e`, within the pattern of this cell row).
                    let ks = &mut keep[x0..x1];
                    match self.ukeep.get(x0..x1) {
                        Some(u) => ks.copy_from_slice(u),
                        None => ks.fill(1),
                    }
                }
            }
            // Columns beyond the cell grid (width not a multiple of the cell), or rows without
            // one: unlabelled cells (after the runs, which may write ahead).
            let g = |r: &[u16], ii: usize| r.get(ii).is_some_and(|&l| l != 0);
            for (x, k) in keep.iter_mut().enumerate().take(w).skip(CELL * nh) {
                let i = x / CELL;
                let t = (i > 0 && g(hint_row, i - 1))
                    || g(hint_row, i + 1)
                    || g(up_row, i)
                    || g(dn_row, i);
                *k = u8::from(!t);
            }
            let keep = &keep[..w];
            // Searches, 8 pixels at a time: first the chunks with a pixel to search.
            let nch = w.div_ceil(LANES);
            self.chunks.resize(nch + 1, (0, 0));
            let mut count = 0usize;
            let mut kw = keep.chunks_exact(LANES);
            for (c, kc) in (&mut kw).enumerate() {
                let word = u64::from_le_bytes(<[u8; LANES]>::try_from(kc).unwrap_or([1; LANES]));
                if word != ALL_KEPT {
                    self.chunks[count] = (c as u32, word);
                    count += 1;
                }
            }
            let tail = kw.remainder();
            if !tail.is_empty() {
                let word = u64::from_le_bytes(pad(tail, 1));
                self.chunks[count] = ((w / LANES) as u32, word);
                count += usize::from(word != ALL_KEPT);
            }
            for &(c, word) in &self.chunks[..count] {
                let x0 = c as usize * LANES;
                let x1 = (x0 + LANES).min(w);
                let mut todo = byte_mask(!word & ALL_KEPT);
                let (dc, lc) = (&row_d[x0..x1], &mut row_l[x0..x1]);
                let d8 = <[f32; LANES]>::try_from(dc).unwrap_or_else(|_| pad(dc, f32::NAN));
                todo &= valid_mask(&d8);
                if todo == 0 {
                    continue;
                }
                // Candidates: the planes of the cells around the chunk (coherence), the same
                // for the rows of a cell row.
                let ci = c as usize;
                let tag = j as u32 + 1;
                if self.near_tag[ci] != tag {
                    let (c0, c1) = (x0 / CELL, (x0 + LANES).div_ceil(CELL));
                    let (a, b) = (c0.saturating_sub(1), c1 + 1);
                    let nc = if small {
                        let bits =
                            or_bits(up_row, a, b) | or_bits(hint_row, a, b) | or_bits(dn_row, a, b);
                        bits_to_planes(bits, &mut self.near_set[ci])
                    } else {
                        neighbour_planes([up_row, hint_row, dn_row], a, b, &mut self.near_set[ci])
                    };
                    self.near_len[ci] = nc as u8;
                    self.near_tag[ci] = tag;
                }
                let near = &self.near_set[ci][..self.near_len[ci] as usize];
                let (best, second) = search8_two(&d8, x0 as f32, near, fa, rowc, tau);
                todo &= nonzero_mask(&best);
                while todo != 0 {
                    let o = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let lab = best[o];
                    let Some(a) = acc.get_mut((lab as usize).wrapping_sub(1)) else {
                        continue;
                    };
                    lc[o] = lab;
                    let x = x0 + o;
                    a.pixels += 1;
                    a.add_rows(y);
                    if stats {
                        let (xf, df) = (x as f64, f64::from(dc[o]));
                        a.sums.add(xf, yf, df);
                        if metric {
                            let r = df - full[lab as usize - 1].eval(xf, yf);
                            a.inv.add(xf, yf, df, r, 1.0);
                        }
                    }
                    if second[o] != 0 {
                        amb.push(((y * w + x) as u32, lab, second[o]));
                    }
                }
            }
        }
        self.drow = drow;
    }

    /// Pixels within the threshold of two planes take the label that dominates their
    /// 8-neighbourhood (ties keep the smaller residual); the statistics follow.
    #[inline(never)]
    fn resolve_ambiguous(&mut self, d: FullDisparity<'_>, w: usize, h: usize, labels: &mut [u16]) {
        for &(i, k1, k2) in &self.amb {
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            let (mut c1, mut c2) = (0u32, 0u32);
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    if nx == x && ny == y {
                        continue;
                    }
                    let l = labels[ny * w + nx];
                    c1 += u32::from(l == k1);
                    c2 += u32::from(l == k2);
                }
            }
            let (u1, u2) = (k1 as usize - 1, k2 as usize - 1);
            if c2 > c1 && labels[i] == k1 && u1 < self.acc.len() && u2 < self.acc.len() {
                labels[i] = k2;
                self.acc[u1].pixels -= 1;
                self.acc[u2].pixels += 1;
                self.acc[u2].add_rows(y);
                if is_sample_row(y) {
                    let (xf, yf, df) = (x as f64, y as f64, f64::from(d.at(i)));
                    let (f1, f2) = (self.full[u1], self.full[u2]);
                    let a1 = &mut self.acc[u1];
                    a1.sums.remove(xf, yf, df);
                    if is_metric_row(y) {
                        a1.inv.add(xf, yf, df, df - f1.eval(xf, yf), -1.0);
                    }
                    let a2 = &mut self.acc[u2];
                    a2.sums.add(xf, yf, df);
                    if is_metric_row(y) {
                        a2.inv.add(xf, yf, df, df - f2.eval(xf, yf), 1.0);
                    }
                }
            }
        }
    }

    /// Drops 4-connected pieces of a plane's cells smaller than `min_piece_pixels / 16` cells.
    #[inline(never)]
    fn drop_small_pieces(&mut self, wq: usize, hq: usize) {
        self.cc.label(&self.labq, wq, hq);
        let min = self.cfg.min_piece_pixels.div_ceil(CELL * CELL);
        for (ri, run) in self.cc.runs.iter().enumerate() {
            if self.cc.sizes[self.cc.component[ri] as usize] >= min {
                continue;
            }
            let y = run.y as usize;
            self.labq[y * wq + run.x0 as usize..y * wq + run.x1 as usize].fill(0);
        }
    }

    /// Final refit, 3D conversion, statistics, and compaction of the ids by decreasing size.
    #[inline(never)]
    fn finish(
        &mut self,
        w: usize,
        h: usize,
        k: &Intrinsics,
        fb: f64,
        mut labels: Vec<u16>,
    ) -> Result<PlaneSegmentation> {
        let mut out: Vec<(usize, PlaneInfo)> = Vec::new();
        for (pi, a) in self.acc.iter().enumerate() {
            let n = a.sums.n;
            if a.pixels < self.cfg.min_pixels || n < 3.0 {
                continue;
            }
            let Some(f) = a.sums.solve() else { continue };
            let Ok(plane) = f.to_plane(k, fb) else {
                continue;
            };
            let s = &a.inv;
            let (centroid_m, rms_m) = if s.n >= 1.0 {
                (
                    Point3::new(
                        fb * (s.sxi - k.cx * s.si) / (k.fx * s.n),
                        fb * (s.syi - k.cy * s.si) / (k.fy * s.n),
                        fb * s.si / s.n,
                    ),
                    plane.offset_m * (s.sr2.max(0.0) / s.n).sqrt(),
                )
            } else {
                // No metric sample (a tiny plane): the point at the mean pixel.
                let (mx, my) = (a.sums.sx / n, a.sums.sy / n);
                let z = fb / f.eval(mx, my);
                (
                    Point3::new((mx - k.cx) * z / k.fx, (my - k.cy) * z / k.fy, z),
                    plane.offset_m * a.sums.rms(&f) / (fb / z),
                )
            };
            out.push((
                pi,
                PlaneInfo {
                    id: 0,
                    plane,
                    affine: f,
                    pixels: a.pixels,
                    rms_px: a.sums.rms(&f),
                    rms_m,
                    centroid_m,
                },
            ));
        }
        out.sort_by_key(|o| std::cmp::Reverse(o.1.pixels));
        self.lut.clear();
        self.lut.resize(self.acc.len() + 1, 0);
        for (new, (old, info)) in out.iter_mut().enumerate() {
            info.id = new as u16 + 1;
            self.lut[*old + 1] = info.id;
        }
        // Relabel only the rows of the planes whose id changes.
        let (mut y0, mut y1) = (usize::MAX, 0);
        for (i, a) in self.acc.iter().enumerate() {
            if self.lut[i + 1] as usize != i + 1 && a.pixels > 0 {
                y0 = y0.min(a.y0);
                y1 = y1.max(a.y1);
            }
        }
        if y0 < y1 && w > 0 {
            relabel(&mut labels[y0 * w..(y1 * w).min(w * h)], &self.lut);
        }
        self.acc.clear();
        Ok(PlaneSegmentation {
            labels: Image::from_vec(w, h, labels)?,
            planes: out.into_iter().map(|(_, p)| p).collect(),
        })
    }
}

/// The stages of [`PlaneExtractor`], for [`StageTimes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Set-up of the input. The depth → disparity conversion and the 2×2 and 4×4 averaging
    /// are streamed row by row into the LoG, so their time counts in [`Stage::Log`].
    Disparity,
    /// Depth → disparity and 2×2 / 4×4 averaging, box LoG, threshold and erosion (half
    /// resolution), and the planar cells.
    Log,
    /// Connected components (planar cells, free cells, coherence pieces).
    Components,
    /// Per-component robust affine fits.
    SeedFits,
    /// Merging of close planes and renumbering.
    Merge,
    /// k-means assignment passes on the cells (searches, sums, refits).
    Refine,
    /// Full-resolution assignment with the final moments.
    FinalPass,
    /// Neighbourhood disambiguation of pixels that fit two planes.
    Disambiguate,
    /// Final refit, 3D planes, statistics and output labels.
    Output,
}

impl Stage {
    /// All stages in pipeline order.
    pub const ALL: [Stage; 9] = [
        Stage::Disparity,
        Stage::Log,
        Stage::Components,
        Stage::SeedFits,
        Stage::Merge,
        Stage::Refine,
        Stage::FinalPass,
        Stage::Disambiguate,
        Stage::Output,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Disparity => "input set-up",
            Stage::Log => "disparity+log",
            Stage::Components => "components",
            Stage::SeedFits => "seed fits",
            Stage::Merge => "merge",
            Stage::Refine => "k-means refine",
            Stage::FinalPass => "final pass",
            Stage::Disambiguate => "disambiguate",
            Stage::Output => "output/stats",
        }
    }
}

/// Wall-clock time per stage of the last extraction, nanoseconds (see
/// [`PlaneExtractor::stage_times`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StageTimes {
    ns: [u64; 9],
}

impl StageTimes {
    /// Nanoseconds spent in `stage`.
    pub fn ns(&self, stage: Stage) -> u64 {
        self.ns[stage as usize]
    }

    /// Total nanoseconds.
    pub fn total_ns(&self) -> u64 {
        self.ns.iter().sum()
    }

    fn add(&mut self, stage: Stage, t0: &mut Instant) {
        let now = Instant::now();
        self.ns[stage as usize] += (now - *t0).as_nanos() as u64;
        *t0 = now;
    }
}

/// End of the run of values equal to `row[i]` that starts at `i` (4 values per step).
#[inline]
fn run_end(row: &[u16], i: usize) -> usize {
    let v = row[i];
    let vv = u64::from(v) * 0x0001_0001_0001_0001;
    let rest = &row[i..];
    let mut words = rest.chunks_exact(4);
    let mut base = i;
    for q in &mut words {
        let w = u64::from(q[0])
            | (u64::from(q[1]) << 16)
            | (u64::from(q[2]) << 32)
            | (u64::from(q[3]) << 48);
        let x = w ^ vv;
        if x != 0 {
            return base + (x.trailing_zeros() / 16) as usize;
        }
        base += 4;
    }
    words
        .remainder()
        .iter()
        .position(|&l| l != v)
        .map_or(row.len(), |n| base + n)
}

/// Replaces every label `l` by `lut[l]` (0 beyond the table): when few labels change, 8 labels
/// at a time are compared with each of them and blended with its new value (a chunk equal to
/// the previous one reuses its result). Callers' labels are all within the table.
fn relabel(labels: &mut [u16], lut: &[u16]) {
    let mut changed = [0i16; 16];
    let mut nc = 0;
    for (l, &v) in lut.iter().enumerate() {
        if v as usize != l {
            if nc == changed.len() {
                remap(labels, lut);
                return;
            }
            changed[nc] = l as i16;
            nc += 1;
        }
    }
    let from = changed.map(i16x8::splat);
    let to = changed.map(|l| i16x8::splat(lut.get(l as u16 as usize).copied().unwrap_or(0) as i16));
    let map = |v: i16x8| {
        from[..nc]
            .iter()
            .zip(&to[..nc])
            .fold(v, |r, (&f, &t)| v.cmp_eq(f).blend(t, r))
    };
    // Runs of equal chunks (inside a plane) reuse the previous chunk's result.
    let (mut prev_v, mut prev_r) = (i16x8::ZERO, map(i16x8::ZERO));
    let mut ch = labels.chunks_exact_mut(LANES);
    for c in &mut ch {
        let Ok(c8) = <&mut [u16; LANES]>::try_from(c) else {
            continue;
        };
        let v = i16x8::from(c8.map(|l| l as i16));
        if v.cmp_eq(prev_v).move_mask() & 0xff != 0xff {
            prev_v = v;
            prev_r = map(v);
        }
        *c8 = prev_r.to_array().map(|l| l as u16);
    }
    remap(ch.into_remainder(), lut);
}

/// Replaces every label `l` by `lut[l]` (0 beyond the table).
fn remap(labels: &mut [u16], lut: &[u16]) {
    for l in labels.iter_mut() {
        *l = lut.get(*l as usize).copied().unwrap_or(0);
    }
}

/// Bit `l − 1` of label `l` for labels 1..=64 (0 for 0 and larger labels).
static LABEL_BIT: [u64; 128] = {
    let mut t = [0u64; 128];
    let mut l = 1;
    while l <= 64 {
        t[l] = 1 << (l - 1);
        l += 1;
    }
    t
};

/// The distinct planes (label − 1) of the cells `i0..i1` of `rows` (rows may be shorter or
/// empty) into `out` (at most 16); returns their number.
#[inline(always)]
fn neighbour_planes(rows: [&[u16]; 3], i0: usize, i1: usize, out: &mut [u16; 16]) -> usize {
    // Labels up to 64 as bits, larger ones one by one.
    let mut bits = 0u64;
    let mut big = 0u16;
    for r in rows {
        for &l in r.get(i0.min(r.len())..i1.min(r.len())).unwrap_or(&[]) {
            bits |= LABEL_BIT.get(l as usize).copied().unwrap_or(0);
            big = big.max(l);
        }
    }
    let mut n = 0;
    while bits != 0 && n < out.len() {
        out[n] = bits.trailing_zeros() as u16;
        bits &= bits - 1;
        n += 1;
    }
    if big > 64 {
        for r in rows {
            for &l in r.get(i0.min(r.len())..i1.min(r.len())).unwrap_or(&[]) {
                if l > 64 && n < out.len() && !out[..n].contains(&(l - 1)) {
                    out[n] = l - 1;
                    n += 1;
                }
            }
        }
    }
    n
}

/// The bits `l − 1` of the labels `l` of `row[a..b]` (labels ≤ 64; an empty or short row
/// contributes its part of the range).
#[inline(always)]
fn or_bits(row: &[u16], a: usize, b: usize) -> u64 {
    // Callers have at most 64 planes: labels ≤ 64 < 128.
    row.get(a..b.min(row.len()))
        .unwrap_or(&[])
        .iter()
        .fold(0u64, |m, &l| m | LABEL_BIT[(l & 127) as usize])
}

/// The planes (label − 1) of a bit mask into `out` (at most 16); returns their number.
#[inline(always)]
fn bits_to_planes(mut bits: u64, out: &mut [u16; 16]) -> usize {
    let mut n = 0;
    while bits != 0 && n < out.len() {
        out[n] = bits.trailing_zeros() as u16;
        bits &= bits - 1;
        n += 1;
    }
    n
}

/// `s` padded to 8 elements with `fill`.
#[inline]
fn pad<T: Copy>(s: &[T], fill: T) -> [T; LANES] {
    let mut a = [fill; LANES];
    let n = s.len().min(LANES);
    a[..n].copy_from_slice(&s[..n]);
    a
}

/// Bit mask of the non-zero bytes of a word whose bytes are 0 or 1.
#[inline(always)]
fn byte_mask(v: u64) -> u32 {
    (v.wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

/// Up to 8 bytes (0 or 1) as a little-endian word, zero-padded.
#[inline(always)]
fn pad_word(s: &[u8]) -> u64 {
    u64::from_le_bytes(<[u8; LANES]>::try_from(s).unwrap_or_else(|_| pad(s, 0)))
}

/// Bit mask of the non-zero values among up to 8 labels.
#[inline(always)]
fn nonzero_mask(s: &[u16]) -> u32 {
    let a = <[u16; LANES]>::try_from(s).unwrap_or_else(|_| pad(s, 0));
    let v = i16x8::from(a.map(|l| l as i16));
    (v.cmp_eq(i16x8::ZERO).move_mask() as u32 ^ 0xff) & 0xff
}

/// Keep bytes of 8 cells or pixels that all passed.
const ALL_KEPT: u64 = 0x0101_0101_0101_0101;

/// `need[i]` = 1 for the unlabelled cells of `row` with a labelled 4-neighbour, else 0
/// (`up` and `dn` have the length of `row`).
fn touching(row: &[u16], up: &[u16], dn: &[u16], need: &mut [u8]) {
    for ((o, &u), &d) in need.iter_mut().zip(up).zip(dn) {
        *o = u8::from((u | d) != 0);
    }
    if row.len() > 1 {
        for (o, &l) in need[1..].iter_mut().zip(row) {
            *o |= u8::from(l != 0);
        }
        for (o, &r) in need.iter_mut().zip(&row[1..]) {
            *o |= u8::from(r != 0);
        }
    }
    for (o, &c) in need.iter_mut().zip(row) {
        *o &= u8::from(c == 0);
    }
}

/// An empty support box.
const EMPTY_BOX: [u32; 4] = [u32::MAX, u32::MAX, 0, 0];

fn grow(bb: &mut [u32; 4], x0: usize, x1: usize, y: usize) {
    bb[0] = bb[0].min(x0 as u32);
    bb[1] = bb[1].min(y as u32);
    bb[2] = bb[2].max(x1 as u32);
    bb[3] = bb[3].max(y as u32);
}

fn union_box(a: &[u32; 4], b: &[u32; 4]) -> [u32; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::{Camera, Intrinsics, SensorModel};

    /// The depth rows converted for the final pass and the per-pixel conversion of the
    /// disambiguation agree bit for bit, invalid depths (0, negative, NaN, ∞) included.
    #[test]
    fn depth_rows_and_pixels_agree() {
        let (w, h, fb) = (13usize, 3usize, 43.5f32);
        let specials = [0.0, -1.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        let z: Vec<f32> = (0..w * h)
            .map(|i| {
                if i % 5 == 0 {
                    specials[(i / 5) % specials.len()]
                } else {
                    0.3 + 0.0173 * i as f32
                }
            })
            .collect();
        let full = FullDisparity::Depth { z: &z, fb };
        let mut scratch = vec![0.0; w];
        for y in 0..h {
            let row = full.row(y, w, &mut scratch).to_vec();
            for (x, &d) in row.iter().enumerate() {
                let i = y * w + x;
                assert_eq!(d.to_bits(), full.at(i).to_bits(), "pixel {i}");
                let ok = z[i] > 0.0 && z[i].is_finite();
                assert_eq!(d > 0.0, ok, "pixel {i}");
            }
        }
    }

    /// Two tilted planes with a depth step between them, on frames whose sizes are not
    /// multiples of the cell (tail columns and rows), through both entry points.
    #[test]
    fn odd_sizes_and_disparity_input() {
        for (w, h) in [(163usize, 125usize), (160, 120), (97, 61)] {
            let k = Intrinsics::new(w, h, 150.0, 150.0, w as f64 / 2.0, h as f64 / 2.0).unwrap();
            let cam = Camera {
                intrinsics: k,
                sensor: SensorModel::kinect_v1(),
            };
            let left = Plane3::new(nalgebra::Vector3::new(0.3, 0.0, -1.0), 1.5).unwrap();
            let right = Plane3::new(nalgebra::Vector3::new(-0.3, 0.1, -1.0), 2.5).unwrap();
            let depth: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let p = if x < w as f64 / 2.0 { &left } else { &right };
                    p.depth_at(&k, x, y).unwrap_or(0.0) as f32
                })
                .collect();
            let depth = DepthImage::from_vec(w, h, depth).unwrap();
            let cfg = PlaneConfig {
                min_pixels: 200,
                min_piece_pixels: 64,
                ..PlaneConfig::default()
            };
            let mut ex = PlaneExtractor::new(cfg).unwrap();
            let seg = ex.extract_depth(&depth, &cam).unwrap();
            assert_eq!(seg.planes.len(), 2, "{w}x{h}: {:?}", seg.planes);
            let labelled = seg.labels.data().iter().filter(|&&l| l != 0).count();
            assert!(
                labelled as f64 > 0.9 * (w * h) as f64,
                "{w}x{h}: {labelled}"
            );
            // Sorted by size, ids 1.., the label counts match.
            for (i, p) in seg.planes.iter().enumerate() {
                assert_eq!(p.id as usize, i + 1);
                let n = seg.labels.data().iter().filter(|&&l| l == p.id).count();
                assert_eq!(n, p.pixels);
                let truth = if p.plane.normal.x > 0.0 {
                    &left
                } else {
                    &right
                };
                assert!(p.plane.angle_deg(truth) < 0.1, "{:?}", p.plane);
            }
            // The same through the disparity entry point, also with garbage where invalid.
            let disp = depth.to_disparity(&cam.sensor);
            let seg2 = ex.extract_disparity(&disp, &cam).unwrap();
            assert_eq!(seg2.planes.len(), 2);
            assert_eq!(seg2.labels, seg.labels);
            if w < 160 {
                continue;
            }
            // (A hole of 8×8 pixels and a few isolated pixels.)
            let is_bad = |i: usize| {
                let (x, y) = (i % w, i / w);
                (20..28).contains(&x) && (30..38).contains(&y) || i % 997 == 3
            };
            let mut bad = disp.data().to_vec();
            for (i, v) in bad.iter_mut().enumerate().filter(|(i, _)| is_bad(*i)) {
                *v = [f32::NAN, f32::INFINITY, -4.0, f32::NEG_INFINITY][i % 4];
            }
            let bad = DisparityImage::from_vec(w, h, bad).unwrap();
            let seg3 = ex.extract_disparity(&bad, &cam).unwrap();
            // (The isolated invalid pixels break the LoG support around them: fewer seeds,
            // but never an invalid pixel labelled or a non-finite statistic.)
            assert!(!seg3.planes.is_empty());
            for (i, &l) in seg3.labels.data().iter().enumerate() {
                if is_bad(i) {
                    assert_eq!(l, 0, "invalid pixel {i} labelled");
                }
            }
            assert!(seg3.planes.iter().all(|p| p.rms_px.is_finite()
                && p.rms_m.is_finite()
                && p.centroid_m.iter().all(|c| c.is_finite())));
        }
    }

    #[test]
    fn empty_and_tiny_frames() {
        let cam = Camera::kinect_v1();
        let k = cam.intrinsics;
        let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
        let seg = ex
            .extract_depth(&DepthImage::invalid(k.width, k.height), &cam)
            .unwrap();
        assert!(seg.planes.is_empty());
        assert!(seg.labels.data().iter().all(|&l| l == 0));
        assert!(ex.stage_times().total_ns() > 0);
        // Too small for the cell grid: no planes, no panic.
        let tiny = Intrinsics::new(20, 12, 30.0, 30.0, 10.0, 6.0).unwrap();
        let cam = Camera {
            intrinsics: tiny,
            sensor: SensorModel::kinect_v1(),
        };
        let seg = ex
            .extract_depth(&DepthImage::from_vec(20, 12, vec![1.0; 240]).unwrap(), &cam)
            .unwrap();
        assert!(seg.planes.is_empty());
        // A size mismatch is an error.
        assert!(
            ex.extract_depth(&DepthImage::invalid(10, 10), &cam)
                .is_err()
        );
    }
}
