//! The paper's plane extraction in the disparity domain (section 3.4), made robust and fast.
//!
//! 0. The disparity (`f·B/Z`, or given) is averaged over 2×2 blocks (invalid if any pixel is):
//!    the seed and refinement stages work on this half-resolution map, which is 4× cheaper and
//!    halves the noise. The block mean of an affine function is that function at the block
//!    centre, so plane parameters carry over exactly.
//! 1. **Seeds.** The box-approximated LoG of the disparity (see [`crate::log`]) is thresholded
//!    at a fixed value in disparity pixels; 4-connected components of planar pixels with at least
//!    `min_pixels` (full-resolution) pixels are seeds. Each seed gets a least-squares affine fit
//!    `D = a·x + b·y + c` followed by a trimmed refit (residuals below `2τ`); the k-means
//!    iterations then refit on the pixels within `τ`: a truncated-quadratic (hard-redescending)
//!    robust estimate.
//! 2. **k-means refinement**: a block keeps its incumbent label (its seed's, or the previous
//!    pass's) while that plane fits it within `τ`; any other valid block goes to the plane with
//!    the smallest disparity residual if it is below the fixed threshold `τ` (candidates: planes
//!    whose support box, grown by a margin, covers the block's tile). The incumbent rule keeps
//!    the extension of one plane from cutting a band through another plane's seed. Planes are refitted from one-pass moment sums
//!    (accumulated run by run), planes that one affine function explains jointly (each within
//!    `merge_px` RMS) are merged (sums add), and planar blocks left unassigned form new seeds (so
//!    a component spanning a shallow crease splits into its planes). Repeats until the labels
//!    settle or `max_iterations`.
//! 3. **Coherence and final pass**: 4-connected pieces of a plane's blocks smaller than
//!    `min_piece_pixels` are dropped; then every full-resolution pixel takes its block's label if
//!    that plane fits it within `τ`, otherwise (and for unlabelled blocks touching a labelled
//!    one) the best candidate within `τ`; pixels fitting several planes take the label that
//!    dominates their 8-neighbourhood. The planes are refitted on the stride-2 sample of the
//!    final labels (pixels `(2i, 2j)`), which also gives the RMS residuals and the centroid;
//!    pixel counts are exact.
//!
//! Everything after the disparity conversion works on the disparity, so the threshold means the
//! same at 0.6 m and at 4 m: the noise of a structured-light camera is constant in disparity.

use nalgebra::Point3;
use sl_core::{Camera, DepthImage, DisparityImage, Image, Intrinsics};

use crate::components::RunLabeler;
use crate::error::{PlanesError, Result};
use crate::fit::AffineSums;
use crate::log::{LogBuffers, log_geometry, planar_mask};
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
    /// RMS residual below this, pixels (of the 2×2-averaged disparity).
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

/// Tile size of the candidate lists, in half-resolution blocks (16 full-resolution pixels).
const TILE_H: usize = 8;
/// Growth margin of a plane's support box per iteration, half-resolution blocks.
const MARGIN_H: u32 = 8;
/// Most planes tracked at once.
const MAX_PLANES: usize = 4000;
/// No merge target.
const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Cand {
    /// Affine fit in half-resolution block coordinates.
    f: DisparityAffine,
    /// Moments in half-resolution block coordinates.
    sums: AffineSums,
    /// Support box `[x0, y0, x1, y1]` (inclusive), half-resolution blocks.
    bbox: [u32; 4],
    alive: bool,
    /// Index of the plane this one was merged into.
    into: u32,
}

/// The full-resolution affine function of a half-resolution one: block `(i, j)` is centred on
/// pixel `(2i + ½, 2j + ½)`.
fn half_to_full(f: &DisparityAffine) -> DisparityAffine {
    DisparityAffine {
        a: f.a / 2.0,
        b: f.b / 2.0,
        c: f.c - (f.a + f.b) / 4.0,
    }
}

/// Per-plane accumulators of the final statistics: moments on the stride-2 sample of pixels
/// `(2i, 2j)` in `(i, j)` coordinates, metric sums in full-resolution coordinates, and the exact
/// full-resolution pixel count.
#[derive(Debug, Clone, Copy, Default)]
struct FinalAcc {
    sums: AffineSums,
    /// Σ(r/D)², Σ1/D, Σx/D, Σy/D over the sample.
    sr2: f64,
    si: f64,
    sxi: f64,
    syi: f64,
    pixels: usize,
}

/// A reusable plane extractor: holds its work buffers so that repeated calls on frames of the
/// same size allocate little beyond the output.
#[derive(Debug, Clone, Default)]
pub struct PlaneExtractor {
    cfg: PlaneConfig,
    d: Vec<f32>,
    dh: Vec<f32>,
    mask: Vec<u8>,
    log: LogBuffers,
    cc: RunLabeler,
    planes: Vec<Cand>,
    labh: Vec<u16>,
    free: Vec<u8>,
    tile_off: Vec<u32>,
    tile_list: Vec<u16>,
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
}

/// Extracts planes from a depth image (metres) with a new extractor.
pub fn extract_planes(
    depth: &DepthImage,
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
    pub fn extract_depth(
        &mut self,
        depth: &DepthImage,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        let (w, h) = (depth.width(), depth.height());
        Self::check(w, h, &camera.intrinsics)?;
        let fb = camera.sensor.fb();
        let fbf = fb as f32;
        self.d.clear();
        self.d.extend(depth.data().iter().map(|&z| {
            if z > 0.0 && z.is_finite() {
                fbf / z
            } else {
                0.0
            }
        }));
        self.run(w, h, &camera.intrinsics, fb)
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
        self.d.clear();
        self.d.extend(
            disparity
                .data()
                .iter()
                .map(|&v| if v > 0.0 && v.is_finite() { v } else { 0.0 }),
        );
        self.run(w, h, &camera.intrinsics, camera.sensor.fb())
    }

    fn downsample(&mut self, w: usize, w2: usize, h2: usize) {
        self.dh.clear();
        self.dh.resize(w2 * h2, f32::NAN);
        for j in 0..h2 {
            let r0 = &self.d[2 * j * w..2 * j * w + 2 * w2];
            let r1 = &self.d[(2 * j + 1) * w..(2 * j + 1) * w + 2 * w2];
            let out = &mut self.dh[j * w2..(j + 1) * w2];
            for (i, o) in out.iter_mut().enumerate() {
                let (a, b, c, d) = (r0[2 * i], r0[2 * i + 1], r1[2 * i], r1[2 * i + 1]);
                let ok = a > 0.0 && b > 0.0 && c > 0.0 && d > 0.0;
                *o = if ok { 0.25 * (a + b + c + d) } else { f32::NAN };
            }
        }
    }

    fn run(&mut self, w: usize, h: usize, k: &Intrinsics, fb: f64) -> Result<PlaneSegmentation> {
        let cfg = self.cfg;
        let tau = cfg.threshold_px as f32;
        self.planes.clear();
        self.acc.clear();
        let (w2, h2) = (w / 2, h / 2);
        let mut labels = vec![0u16; w * h];
        if w2 < 8 || h2 < 8 {
            return self.finish(w, h, k, fb, labels);
        }
        // 0. Half resolution.
        self.downsample(w, w2, h2);
        // 1. Seeds.
        let (r, s) = log_geometry(cfg.log_sigma_px / 2.0);
        planar_mask(
            &self.dh,
            w2,
            h2,
            r,
            s,
            cfg.log_threshold_px as f32,
            &mut self.log,
            &mut self.mask,
        );
        self.cc.label(&self.mask, w2, h2);
        let min_h = (cfg.min_pixels / 4).max(3);
        self.labh.clear();
        self.labh.resize(w2 * h2, 0);
        self.free.clear();
        self.free.resize(w2 * h2, 0);
        self.seed_from_components(w2, min_h);
        self.merge();
        self.compact();

        // 2. k-means refinement at half resolution.
        for it in 0..cfg.max_iterations {
            if self.planes.is_empty() {
                break;
            }
            self.build_tiles(w2, h2);
            let (changed, free) = self.coarse_pass(w2, h2, tau);
            for p in self.planes.iter_mut() {
                p.alive = p.sums.n >= min_h as f64;
                if p.alive {
                    match p.sums.solve() {
                        Some(f) => p.f = f,
                        None => p.alive = false,
                    }
                }
            }
            self.merge();
            self.compact();
            if it + 1 < cfg.max_iterations && free >= min_h {
                self.cc.label(&self.free, w2, h2);
                let before = self.planes.len();
                self.seed_from_components(w2, min_h);
                if self.planes.len() > before {
                    self.merge();
                    self.compact();
                    continue;
                }
            }
            if changed * 500 < w2 * h2 {
                break;
            }
        }

        // 3. Coherence at half resolution, then the final full-resolution pass.
        if !self.planes.is_empty() {
            if cfg.min_piece_pixels > 0 {
                self.drop_small_pieces(w2, h2);
            }
            self.build_tiles(w2, h2);
            self.final_pass(w, h, w2, h2, tau, &mut labels);
            self.resolve_ambiguous(w, h, &mut labels);
            self.statistics(w, h, &labels);
        }
        self.finish(w, h, k, fb, labels)
    }

    /// Creates planes from the components in `self.cc` (on the half-resolution grid of width
    /// `w2`) with at least `min` blocks: least squares, then refitted on the inliers within 2τ.
    fn seed_from_components(&mut self, w2: usize, min: usize) {
        let nc = self.cc.sizes.len();
        self.comp_sums.clear();
        self.comp_sums.resize(nc, AffineSums::default());
        self.comp_box.clear();
        self.comp_box.resize(nc, [u32::MAX, u32::MAX, 0, 0]);
        self.comp_fit.clear();
        self.comp_fit.resize(nc, None);
        let lim = 2.0 * self.cfg.threshold_px;
        for pass in 0..2 {
            for s in self.comp_sums.iter_mut() {
                *s = AffineSums::default();
            }
            for (ri, run) in self.cc.runs.iter().enumerate() {
                let c = self.cc.component[ri] as usize;
                if self.cc.sizes[c] < min {
                    continue;
                }
                let f = self.comp_fit[c];
                if pass > 0 && f.is_none() {
                    continue;
                }
                let j = run.y as usize;
                if pass == 0 {
                    let bb = &mut self.comp_box[c];
                    bb[0] = bb[0].min(run.x0);
                    bb[1] = bb[1].min(run.y);
                    bb[2] = bb[2].max(run.x1 - 1);
                    bb[3] = bb[3].max(run.y);
                }
                let row = &self.dh[j * w2..(j + 1) * w2];
                let sums = &mut self.comp_sums[c];
                let jf = j as f64;
                // Inliers are accumulated in sub-runs (closed-form x moments).
                let (fa, fc) = f.map_or((0.0, 0.0), |f| (f.a, f.b * jf + f.c));
                let (mut sd, mut sxd, mut sdd) = (0.0, 0.0, 0.0);
                let mut start = run.x0 as usize;
                let (x0, x1) = (run.x0 as usize, run.x1 as usize);
                for (i, &dv) in row.iter().enumerate().take(x1).skip(x0) {
                    let d = f64::from(dv);
                    let inlier = f.is_none() || (d - (fa * i as f64 + fc)).abs() < lim;
                    if inlier {
                        sd += d;
                        sxd += i as f64 * d;
                        sdd += d * d;
                    } else {
                        sums.add_run(jf, start, i, sd, sxd, sdd);
                        (sd, sxd, sdd) = (0.0, 0.0, 0.0);
                        start = i + 1;
                    }
                }
                sums.add_run(jf, start, run.x1 as usize, sd, sxd, sdd);
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
                self.labh[y * w2 + run.x0 as usize..y * w2 + run.x1 as usize].fill(lab);
            }
        }
    }

    /// Merges planes that one affine function explains jointly: the least-squares plane of the
    /// union fits each of the two with an RMS below `merge_px`.
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

    /// Removes dead planes and renumbers the half-resolution labels (merged planes' blocks go
    /// to the plane they merged into).
    fn compact(&mut self) {
        let n = self.planes.len();
        self.lut.clear();
        self.lut.resize(n + 1, 0);
        let mut next = 0u16;
        let mut newidx = vec![0u16; n];
        for (i, p) in self.planes.iter().enumerate() {
            if p.alive {
                next += 1;
                newidx[i] = next;
            }
        }
        for i in 0..n {
            let mut r = i;
            let mut guard = 0;
            while !self.planes[r].alive && self.planes[r].into != NONE && guard < n {
                r = self.planes[r].into as usize;
                guard += 1;
            }
            self.lut[i + 1] = if self.planes[r].alive { newidx[r] } else { 0 };
        }
        if self.lut.iter().enumerate().any(|(i, &v)| v as usize != i) {
            for l in self.labh.iter_mut() {
                *l = self.lut.get(*l as usize).copied().unwrap_or(0);
            }
        }
        self.planes.retain(|p| p.alive);
        for p in self.planes.iter_mut() {
            p.into = NONE;
        }
    }

    /// Candidate lists per tile (8×8 blocks): the planes whose support box, grown by the
    /// margin, overlaps the tile.
    fn build_tiles(&mut self, w2: usize, h2: usize) {
        let (tw, th) = (w2.div_ceil(TILE_H), h2.div_ceil(TILE_H));
        self.tile_off.clear();
        self.tile_off.resize(tw * th + 1, 0);
        let range = |p: &Cand| {
            let x0 = p.bbox[0].saturating_sub(MARGIN_H) as usize / TILE_H;
            let y0 = p.bbox[1].saturating_sub(MARGIN_H) as usize / TILE_H;
            let x1 = ((p.bbox[2].saturating_add(MARGIN_H)) as usize / TILE_H).min(tw - 1);
            let y1 = ((p.bbox[3].saturating_add(MARGIN_H)) as usize / TILE_H).min(th - 1);
            (x0.min(tw - 1), y0.min(th - 1), x1, y1)
        };
        for p in &self.planes {
            let (x0, y0, x1, y1) = range(p);
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    self.tile_off[ty * tw + tx + 1] += 1;
                }
            }
        }
        for t in 0..tw * th {
            self.tile_off[t + 1] += self.tile_off[t];
        }
        let total = self.tile_off[tw * th] as usize;
        self.tile_list.clear();
        self.tile_list.resize(total, 0);
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.tile_off[..tw * th]);
        for (pi, p) in self.planes.iter().enumerate() {
            let (x0, y0, x1, y1) = range(p);
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    let c = &mut self.cursor[ty * tw + tx];
                    self.tile_list[*c as usize] = pi as u16;
                    *c += 1;
                }
            }
        }
    }

    /// One assignment pass on the half-resolution map; refills the planes' sums and boxes.
    /// Returns the number of labels that changed and the number of planar but unassigned blocks
    /// (marked in `free`).
    fn coarse_pass(&mut self, w2: usize, h2: usize, tau: f32) -> (usize, usize) {
        for p in self.planes.iter_mut() {
            p.sums = AffineSums::default();
            p.bbox = [u32::MAX, u32::MAX, 0, 0];
        }
        self.fa.clear();
        self.fa.extend(self.planes.iter().map(|p| p.f.a as f32));
        let tiles = Tiles {
            off: &self.tile_off,
            list: &self.tile_list,
            tw: w2.div_ceil(TILE_H),
        };
        coarse_assign(
            &self.dh,
            &self.mask,
            &mut self.labh,
            &mut self.free,
            &mut self.planes,
            &self.fa,
            &mut self.rowc,
            &tiles,
            (w2, h2),
            tau,
        )
    }

    /// The full-resolution assignment: the block's label is tried first; if it does not fit,
    /// or the block is unlabelled but touches a labelled block, all candidates of the tile are
    /// searched. Pixels of unlabelled blocks away from planes stay unlabelled (coherence).
    fn final_pass(
        &mut self,
        w: usize,
        h: usize,
        w2: usize,
        h2: usize,
        tau: f32,
        labels: &mut [u16],
    ) {
        self.acc.clear();
        self.acc.resize(self.planes.len(), FinalAcc::default());
        self.amb.clear();
        self.full.clear();
        self.full
            .extend(self.planes.iter().map(|p| half_to_full(&p.f)));
        self.fa.clear();
        self.fa.extend(self.full.iter().map(|f| f.a as f32));
        let tiles = Tiles {
            off: &self.tile_off,
            list: &self.tile_list,
            tw: w2.div_ceil(TILE_H),
        };
        final_assign(
            &self.d,
            &self.labh,
            labels,
            &mut self.acc,
            &mut self.amb,
            &self.full,
            &self.fa,
            &mut self.rowc,
            &tiles,
            (w, h, w2, h2),
            tau,
        );
    }

    /// Pixels within the threshold of two planes take the label that dominates their
    /// 8-neighbourhood (ties keep the smaller residual).
    fn resolve_ambiguous(&mut self, w: usize, h: usize, labels: &mut [u16]) {
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
            if c2 > c1 && labels[i] == k1 {
                self.acc[k1 as usize - 1].pixels -= 1;
                self.acc[k2 as usize - 1].pixels += 1;
                labels[i] = k2;
            }
        }
    }

    /// Drops 4-connected pieces of a plane's half-resolution blocks smaller than
    /// `min_piece_pixels / 4` blocks.
    fn drop_small_pieces(&mut self, w2: usize, h2: usize) {
        self.cc.label(&self.labh, w2, h2);
        let min = self.cfg.min_piece_pixels.div_ceil(4);
        for (ri, run) in self.cc.runs.iter().enumerate() {
            if self.cc.sizes[self.cc.component[ri] as usize] >= min {
                continue;
            }
            let y = run.y as usize;
            self.labh[y * w2 + run.x0 as usize..y * w2 + run.x1 as usize].fill(0);
        }
    }

    /// Moments and metric sums on the stride-2 sample of the final labels.
    fn statistics(&mut self, w: usize, h: usize, labels: &[u16]) {
        for y in (0..h).step_by(2) {
            let yf = y as f64;
            let jf = (y / 2) as f64;
            self.rowc.clear();
            self.rowc
                .extend(self.full.iter().map(|f| (f.b * yf + f.c) as f32));
            let row_d = &self.d[y * w..(y + 1) * w];
            let row_l = &labels[y * w..(y + 1) * w];
            let mut cur = 0u16;
            let mut i0 = 0usize;
            let mut rs = RunSums::default();
            for (i, (&dv, &lab)) in row_d
                .iter()
                .step_by(2)
                .zip(row_l.iter().step_by(2))
                .enumerate()
            {
                if lab != cur {
                    rs.flush(&mut self.acc, cur, jf, i0, i);
                    cur = lab;
                    i0 = i;
                }
                if lab != 0 {
                    let ku = lab as usize - 1;
                    let (Some(&a), Some(&c)) = (self.fa.get(ku), self.rowc.get(ku)) else {
                        continue;
                    };
                    let x = 2 * i;
                    let r = dv - (a * x as f32 + c);
                    let df = f64::from(dv);
                    let inv = f64::from(1.0 / dv);
                    let ri = f64::from(r) * inv;
                    rs.sd += df;
                    rs.sxd += i as f64 * df;
                    rs.sdd += df * df;
                    rs.si += inv;
                    rs.sxi += x as f64 * inv;
                    rs.sr2 += ri * ri;
                }
            }
            rs.flush(&mut self.acc, cur, jf, i0, w.div_ceil(2));
        }
    }

    /// Final refit, 3D conversion, statistics, and compaction of the ids by decreasing size.
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
            // The sample's (i, j) = (x/2, y/2).
            let Some(fs) = a.sums.solve() else { continue };
            let f = DisparityAffine {
                a: fs.a / 2.0,
                b: fs.b / 2.0,
                c: fs.c,
            };
            let Ok(plane) = f.to_plane(k, fb) else {
                continue;
            };
            let centroid_m = Point3::new(
                fb * (a.sxi - k.cx * a.si) / (k.fx * n),
                fb * (a.syi - k.cy * a.si) / (k.fy * n),
                fb * a.si / n,
            );
            out.push((
                pi,
                PlaneInfo {
                    id: 0,
                    plane,
                    affine: f,
                    pixels: a.pixels,
                    rms_px: a.sums.rms(&fs),
                    rms_m: plane.offset_m * (a.sr2.max(0.0) / n).sqrt(),
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
        for l in labels.iter_mut() {
            *l = self.lut.get(*l as usize).copied().unwrap_or(0);
        }
        self.acc.clear();
        Ok(PlaneSegmentation {
            labels: Image::from_vec(w, h, labels)?,
            planes: out.into_iter().map(|(_, p)| p).collect(),
        })
    }
}

/// Candidate lists per tile.
struct Tiles<'a> {
    off: &'a [u32],
    list: &'a [u16],
    tw: usize,
}

impl Tiles<'_> {
    #[inline]
    fn cands(&self, tx: usize, ty: usize) -> &[u16] {
        let t = ty * self.tw + tx.min(self.tw - 1);
        match (self.off.get(t), self.off.get(t + 1)) {
            (Some(&a), Some(&b)) => self.list.get(a as usize..b as usize).unwrap_or(&[]),
            _ => &[],
        }
    }
}

/// Index and |residual| of the best candidate under `tau` (index `u16::MAX` if none).
#[inline(always)]
fn best_of(cands: &[u16], fa: &[f32], rowc: &[f32], d: f32, xf: f32, tau: f32) -> u16 {
    let mut best = tau;
    let mut lab = 0u16;
    for &k in cands {
        let ku = k as usize;
        if let (Some(&a), Some(&c)) = (fa.get(ku), rowc.get(ku)) {
            let r = (d - (a * xf + c)).abs();
            if r < best {
                best = r;
                lab = k + 1;
            }
        }
    }
    lab
}

#[allow(clippy::too_many_arguments)]
fn coarse_assign(
    dh: &[f32],
    mask: &[u8],
    labh: &mut [u16],
    free_mask: &mut [u8],
    planes: &mut [Cand],
    fa: &[f32],
    rowc: &mut Vec<f32>,
    tiles: &Tiles<'_>,
    (w2, h2): (usize, usize),
    tau: f32,
) -> (usize, usize) {
    let (mut changed, mut free) = (0usize, 0usize);
    for j in 0..h2 {
        let jf = j as f64;
        rowc.clear();
        rowc.extend(planes.iter().map(|p| (p.f.b * jf + p.f.c) as f32));
        let rowc: &[f32] = rowc;
        let ty = j / TILE_H;
        let row = &dh[j * w2..(j + 1) * w2];
        let mrow = &mask[j * w2..(j + 1) * w2];
        let lrow = &mut labh[j * w2..(j + 1) * w2];
        let frow = &mut free_mask[j * w2..(j + 1) * w2];
        let mut cur = 0u16;
        let mut rx0 = 0usize;
        let (mut sd, mut sxd, mut sdd) = (0.0f64, 0.0f64, 0.0f64);
        for (tx, ((dt, mt), (lt, ft))) in row
            .chunks(TILE_H)
            .zip(mrow.chunks(TILE_H))
            .zip(lrow.chunks_mut(TILE_H).zip(frow.chunks_mut(TILE_H)))
            .enumerate()
        {
            let cands = tiles.cands(tx, ty);
            let i0 = tx * TILE_H;
            for (o, (((&d, &m), l), f)) in dt
                .iter()
                .zip(mt)
                .zip(lt.iter_mut())
                .zip(ft.iter_mut())
                .enumerate()
            {
                let i = i0 + o;
                // The incumbent (seed or previous) label is kept while it fits within τ, so
                // the extension of another plane cannot cut a band through a seeded region;
                // other blocks take the best candidate.
                let prev = *l;
                let xf = i as f32;
                let keep = prev != 0
                    && match (fa.get(prev as usize - 1), rowc.get(prev as usize - 1)) {
                        (Some(&a), Some(&c)) => (d - (a * xf + c)).abs() < tau,
                        _ => false,
                    };
                let lab = if keep {
                    prev
                } else {
                    best_of(cands, fa, rowc, d, xf, tau)
                };
                let fr = lab == 0 && m == 1;
                *f = u8::from(fr);
                free += usize::from(fr);
                changed += usize::from(*l != lab);
                *l = lab;
                if lab != cur {
                    if cur != 0
                        && let Some(p) = planes.get_mut(cur as usize - 1)
                    {
                        p.sums.add_run(jf, rx0, i, sd, sxd, sdd);
                        grow(&mut p.bbox, rx0, i - 1, j);
                    }
                    cur = lab;
                    rx0 = i;
                    (sd, sxd, sdd) = (0.0, 0.0, 0.0);
                }
                if lab != 0 {
                    let df = f64::from(d);
                    sd += df;
                    sxd += i as f64 * df;
                    sdd += df * df;
                }
            }
        }
        if cur != 0
            && let Some(p) = planes.get_mut(cur as usize - 1)
        {
            p.sums.add_run(jf, rx0, w2, sd, sxd, sdd);
            grow(&mut p.bbox, rx0, w2 - 1, j);
        }
    }
    (changed, free)
}

/// Running sums of one run of equally labelled pixels in a row.
#[derive(Default, Clone, Copy)]
struct RunSums {
    sd: f64,
    sxd: f64,
    sdd: f64,
    sr2: f64,
    si: f64,
    sxi: f64,
}

impl RunSums {
    #[inline]
    fn flush(&mut self, acc: &mut [FinalAcc], lab: u16, y: f64, x0: usize, x1: usize) {
        if lab != 0
            && let Some(a) = acc.get_mut(lab as usize - 1)
        {
            a.sums.add_run(y, x0, x1, self.sd, self.sxd, self.sdd);
            a.sr2 += self.sr2;
            a.si += self.si;
            a.sxi += self.sxi;
            a.syi += y * self.si;
        }
        *self = RunSums::default();
    }
}

#[allow(clippy::too_many_arguments)]
fn final_assign(
    d: &[f32],
    labh: &[u16],
    labels: &mut [u16],
    acc: &mut [FinalAcc],
    amb: &mut Vec<(u32, u16, u16)>,
    full: &[DisparityAffine],
    fa: &[f32],
    rowc: &mut Vec<f32>,
    tiles: &Tiles<'_>,
    (w, h, w2, h2): (usize, usize, usize, usize),
    tau: f32,
) {
    let th = h2.div_ceil(TILE_H);
    let ftile = 2 * TILE_H;
    let empty: &[u16] = &[];
    for y in 0..h {
        let yf = y as f64;
        rowc.clear();
        rowc.extend(full.iter().map(|f| (f.b * yf + f.c) as f32));
        let rowc: &[f32] = rowc;
        let j = y / 2;
        let ty = (j / TILE_H).min(th.saturating_sub(1));
        let hrow = |jj: usize| {
            if jj < h2 {
                &labh[jj * w2..(jj + 1) * w2]
            } else {
                empty
            }
        };
        let hint_row = hrow(j);
        let up_row = if j > 0 { hrow(j - 1) } else { empty };
        let dn_row = hrow(j + 1);
        let mut cur = 0u16;
        let mut rx0 = 0usize;
        let row_d = &d[y * w..(y + 1) * w];
        let row_l = &mut labels[y * w..(y + 1) * w];
        for (txf, (dt, lt)) in row_d.chunks(ftile).zip(row_l.chunks_mut(ftile)).enumerate() {
            let cands = tiles.cands(txf, ty);
            let x0 = txf * ftile;
            for (o, (&dv, l)) in dt.iter().zip(lt.iter_mut()).enumerate() {
                let x = x0 + o;
                let mut lab = 0u16;
                if dv > 0.0 {
                    let xf = x as f32;
                    let i = x / 2;
                    let hint = hint_row.get(i).copied().unwrap_or(0);
                    let mut search = hint != 0;
                    if hint != 0
                        && let (Some(&a), Some(&c)) =
                            (fa.get(hint as usize - 1), rowc.get(hint as usize - 1))
                        && (dv - (a * xf + c)).abs() < tau
                    {
                        lab = hint;
                        search = false;
                    }
                    if hint == 0 {
                        let g = |r: &[u16], ii: usize| r.get(ii).copied().unwrap_or(0);
                        search = (i > 0 && g(hint_row, i - 1) != 0)
                            || g(hint_row, i + 1) != 0
                            || g(up_row, i) != 0
                            || g(dn_row, i) != 0;
                    }
                    if search {
                        let (mut best, mut second) = (tau, tau);
                        let mut sk = 0u16;
                        for &k in cands {
                            let ku = k as usize;
                            let (Some(&a), Some(&c)) = (fa.get(ku), rowc.get(ku)) else {
                                continue;
                            };
                            let ar = (dv - (a * xf + c)).abs();
                            if ar < best {
                                second = best;
                                sk = lab;
                                best = ar;
                                lab = k + 1;
                            } else if ar < second {
                                second = ar;
                                sk = k + 1;
                            }
                        }
                        if lab != 0 && sk != 0 {
                            amb.push(((y * w + x) as u32, lab, sk));
                        }
                    }
                }
                *l = lab;
                if lab != cur {
                    if cur != 0
                        && let Some(a) = acc.get_mut(cur as usize - 1)
                    {
                        a.pixels += x - rx0;
                    }
                    cur = lab;
                    rx0 = x;
                }
            }
        }
        if cur != 0
            && let Some(a) = acc.get_mut(cur as usize - 1)
        {
            a.pixels += w - rx0;
        }
    }
}

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
