//! The paper's plane extraction in the disparity domain (section 3.4), made robust and fast
//! (≈ 3 ms per 640×480 frame on one core; the per-stage times are in [`StageTimes`]).
//!
//! 0. The disparity (`f·B/Z`, or given) is averaged over 2×2 blocks (half resolution, for the
//!    LoG) and over 4×4 pixels (**cells**, for the seeds and the k-means refinement). The mean
//!    of an affine function over a block is its value at the block's centre, so plane
//!    parameters carry over exactly between the grids. So is the mean of a block's diagonal: a
//!    block with missing pixels takes the mean of a diagonal whose two pixels are valid (exact
//!    for a plane), and a cell is the mean of its four blocks' values, invalid when a block has
//!    neither diagonal. Scattered missing pixels (a stereo camera's dropped matches, depth
//!    aligned to a larger colour image) then cost few cells: with 5 % of the pixels missing at
//!    random a cell of 16 pixels with one missing is no longer lost (56 % of the cells were).
//!    The LoG's values come from the blocks of four valid pixels only (two-pixel means are
//!    twice as noisy), extended across the rest as across any hole.
//! 1. **Seeds** (issue 12, `patches`). The box-approximated LoG of the half-resolution
//!    disparity (the `log` module) is thresholded at a fixed value in disparity pixels; a cell
//!    is planar when its four blocks are (the LoG finds jumps and sharp creases). The LoG reads
//!    the map extended across holes and beyond the image border by least-squares lines through
//!    the nearest valid values of each row and column (the `extend` module): exact for a plane,
//!    so a strip of a surface along the border or between occlusion bands keeps planar cells
//!    (without it every pixel within the LoG's reach, 8 px, of a hole or the border failed, and
//!    a box face or a far ceiling seen as a 30-pixel strip was never seeded). The cell grid
//!    is cut into patches of 4×4 cells; each patch gets a least-squares affine fit
//!    `D = a·x + b·y + c` of its planar cells and is used when its residual is what the noise
//!    allows. Neighbouring patches merge, most similar first, while one affine function explains
//!    the union: the extra residual sum of squares of the joint fit, in units of the noise of a
//!    cell (from the sensor's `σ_D`, the `1/q` quantisation and the correlation window of the
//!    disparity error, `noise_window_x_px × noise_window_y_px`), stays below the 99.9 % quantile
//!    of χ² with 3 degrees of freedom. Sets of at least `min_pixels` are seeds. This is what the
//!    LoG alone cannot do: a crease between a floor and a wall far away bends the disparity by
//!    hundredths of a pixel per pixel, far below a LoG threshold above the noise, but the two
//!    sides' affine fits differ by many standard deviations (without it, one "plane" swallowed
//!    rings of several surfaces at the same disparity). The k-means iterations then refit on the
//!    cells within `τ`: a truncated-quadratic (hard-redescending) robust estimate.
//! 2. **k-means refinement** on the cells: a cell keeps its incumbent label (its seed's, or the
//!    previous pass's) while that plane fits it within `τ`, unless a cell of another plane
//!    touches it; any other valid cell, and every cell at such a border, goes to the plane with
//!    the smallest disparity residual if it is below the fixed threshold `τ`, among the planes
//!    of its neighbouring cells (spatial coherence: a plane grows into adjacent cells; coplanar
//!    but disconnected regions join by merging). A border cell that no plane explains within
//!    the noise of a cell (99.9 %) keeps its incumbent while within `τ`. Planes are refitted from moment sums
//!    accumulated run by run, planes that one affine function explains jointly (each within
//!    `merge_px` RMS, or the extra residual of one fit within the noise model's χ²₃ bound, as
//!    for the patches) are merged (sums add), and planar cells left unassigned form new seeds
//!    (patches of the free cells, merged by the same test). Repeats until the labels
//!    settle or `max_iterations`.
//! 3. **Growth, coherence and final pass**: each plane grows, round by round, over the valid
//!    unlabelled cells 4-connected to it that its (fixed) fit explains within the noise of a
//!    cell (99.9 %), so a surface seen as a thin strip whose noisy cells fail the LoG is taken
//!    to its end (the passes above reach one cell further each); 4-connected pieces of a
//!    plane's cells smaller than `min_piece_pixels` are dropped; pieces of one plane between
//!    which the camera sees behind the plane (the free space of a hole: two box tops at one
//!    height with the floor between them) become separate planes, while pieces parted by an
//!    occluder in front stay one; then every full-resolution pixel takes its cell's label if
//!    that plane fits it within `τ`; otherwise, for the pixels of unlabelled cells touching a
//!    labelled one, and for all pixels of cells at a border between planes, the plane of the
//!    neighbouring cells with the smallest residual (in units of the pixel's noise, `σ_D` and
//!    `1/q`) when it is within the noise (99.9 %), else as away from borders. Pixels fitting
//!    two planes take the label that dominates their 8-neighbourhood. The planes are refitted on
//!    the labelled pixels of every fourth row (which also gives the RMS residual in pixels; the
//!    centroid and the RMS in metres come from every eighth row); pixel counts are exact.
//!    Optionally (`PlaneConfig::refine_seams`, off by default; `seam`), the pixels within half
//!    a matching window of a crease between two planes are re-decided with the planes' local
//!    fits where a whole fit is off there (a surface bent by the sensor's distortion).
//! 4. **Planes across a crease** (`crease`): a plane whose pixels are curved beyond what the
//!    sensor's distortion (`bend_px_per_px2`) and the noise allow, and fitted better by a hinge
//!    (two affine pieces meeting along a line, two parameters fewer) than by any quadratic, is
//!    split where its two sides' fits intersect: far away, the pixels along a crease between
//!    two surfaces (or a box face and a strip of the wall beside it) are within `τ` of one
//!    affine function. Sides smaller than `min_pixels` are left unlabelled
//!    (`PlaneConfig::split_creases`).
//!    Optionally (`PlaneConfig::give_back_taken_in`, off by default; `taken_in`), the pieces
//!    of a neighbouring surface a plane took in — 8 × 8-pixel blocks of its pixels off a
//!    quadratic fit of the whole plane by more than the noise model allows (99.9 %, grown at
//!    99 %), in connected
//!    pieces of at least `min_piece_pixels` — are left unlabelled and the plane refitted.
//! 5. **Pieces of bent surfaces** (`bend`): adjacent planes whose functions meet along their
//!    border, whose slopes at the border agree within the noise and whose whole fits differ by
//!    no more than the sensor's distortion bends a surface (`bend_px_per_px2`) take the label
//!    of the largest piece, whose fit stays the plane.
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
use crate::extend::{ExtendBuffers, extend_map};
use crate::fit::AffineSums;
use crate::kernels::{
    InvSums, LANES, depth_to_disparity_row, downsample_rows, fit_run, fit_run_labels, search8_two,
    valid_mask,
};
use crate::log::{LogBuffers, log_geometry, planar_mask_uncounted};
use crate::plane::DisparityAffine;
use crate::uncertainty::{FitNoise, plane_sigmas};
use sl_core::Plane;

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

/// Every how many rows the labelled pixels feed the final fit.
const SAMPLE_ROW_STEP: usize = 4;

/// Rows whose labelled pixels feed the final fit (a quarter of the rows).
#[inline]
fn is_sample_row(y: usize) -> bool {
    y.is_multiple_of(SAMPLE_ROW_STEP)
}

/// Rows whose labelled pixels feed the metric statistics (centroid, RMS in metres; an eighth
/// of the rows).
#[inline]
fn is_metric_row(y: usize) -> bool {
    y.is_multiple_of(8)
}

/// Per-plane accumulators of the final statistics: moments of the labelled pixels of the even
/// rows (full-resolution coordinates), their metric sums, and the exact pixel count.
#[derive(Debug, Clone, Copy)]
struct FinalAcc {
    sums: AffineSums,
    inv: InvSums,
    pixels: usize,
    /// Rows `y0..y1` holding the plane's pixels (`usize::MAX..0` while it has none).
    y0: usize,
    y1: usize,
}

impl Default for FinalAcc {
    /// No pixel yet: empty sums and the empty row range.
    fn default() -> Self {
        Self {
            sums: AffineSums::default(),
            inv: InvSums::default(),
            pixels: 0,
            y0: usize::MAX,
            y1: 0,
        }
    }
}

impl FinalAcc {
    #[inline]
    fn add_rows(&mut self, y: usize) {
        self.y0 = self.y0.min(y);
        self.y1 = self.y1.max(y + 1);
    }

    /// Adds the pixels, rows and moments of `o` (another band of the same plane).
    fn merge(&mut self, o: &FinalAcc) {
        self.sums.merge(&o.sums);
        self.inv.merge(&o.inv);
        self.pixels += o.pixels;
        self.y0 = self.y0.min(o.y0);
        self.y1 = self.y1.max(o.y1);
    }
}

/// A reusable plane extractor: holds its work buffers so that repeated calls on frames of the
/// same size allocate nothing beyond the output (the label image and the plane list).
///
/// Threads: the final per-pixel pass runs in bands of rows on the caller's rayon pool when it
/// has more than one thread (called from outside every pool, the extraction moves onto a worker
/// of the global pool once per frame); the result is the same, bit for bit, on any number of
/// threads. So do the half-resolution map (2×2 means) of the LoG and the cells, its extension
/// across holes, the LoG's planarity mask, the patches' fits and their neighbours' joint fits
/// in the seeding, and the k-means passes (in fixed bands of 8 cell rows, whose sums are added
/// in band order). The other stages are sequential.
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
    /// The configuration.
    cfg: PlaneConfig,
    /// Two-row scratch per piece of the half-resolution map (depth converted to disparity).
    half_res_scratch: Vec<Vec<f32>>,
    /// Cell-averaged disparity on the 4×4 cell grid.
    cell_disparity: Vec<f32>,
    /// Planarity mask of the cells (1 = the LoG says locally planar).
    cell_planar: Vec<u8>,
    /// Plane label per cell (0 = none), the working segmentation of the coarse stages.
    cell_labels: Vec<u16>,
    /// Planarity mask produced by the LoG, before it is reduced to cells.
    log_mask: Vec<u8>,
    /// Work rows of the box-approximated LoG, one set per band of rows.
    log_buffers: Vec<LogBuffers>,
    /// The half-resolution disparity with a margin of the LoG's reach on every side, extended
    /// across holes and the image border (`extend`), the LoG's input.
    half_res_extended: Vec<f32>,
    /// The half-resolution map with the blocks that keep a complete diagonal (see
    /// `input::half_resolution`): which half-resolution pixels are data.
    half_res_partial: Vec<f32>,
    /// The planarity mask of `half_res_extended` (same size).
    extended_mask: Vec<u8>,
    /// Buffers of the extension.
    extend_buffers: ExtendBuffers,
    /// Connected components of cell masks (seeds, regrowth, piece filtering).
    components: RunLabeler,
    /// The plane candidates (affine fits, sums, boxes, merge links).
    planes: Vec<Cand>,
    /// Second candidate buffer, swapped with `planes` when they are renumbered.
    planes_spare: Vec<Cand>,
    /// Cells that are planar but unassigned after a coarse pass (1 = free).
    free_cells: Vec<u8>,
    /// Per-pixel (or per-cell) keep bytes of the row being assigned: 1 = done, 0 = search.
    keep_row: Vec<u8>,
    /// Scratch and output of the coarse passes' bands of cell rows.
    coarse_bands: Vec<refine::CoarseBand>,
    /// The cells the growth tests in its current round (`grow`).
    grow_candidates: Vec<u32>,
    /// The cells labelled in the current round of the growth, with their labels.
    grow_taken: Vec<(u32, u16)>,
    /// Per cell: 1 while it is among the growth's candidates.
    grow_queued: Vec<u8>,
    /// The 4-connected pieces of the planes' cells (`split_separated`).
    split_pieces: Vec<split::Piece>,
    /// The big pieces, by plane.
    split_order: Vec<u32>,
    /// Per label: 1 when its plane was split or made by a split.
    split_affected: Vec<u8>,
    /// A row of zero cell labels (stands in for a missing row above or below).
    zero_cell_row: Vec<u16>,
    /// Plane indices in merge / renumbering order.
    plane_order: Vec<u32>,
    /// Per plane: ∂D/∂x as `f32`, for the vectorised searches.
    slope_x: Vec<f32>,
    /// Per plane: its affine fit converted to full-resolution pixel coordinates.
    full_res_fits: Vec<DisparityAffine>,
    /// Per plane: pixels, rows and moments accumulated by the final pass.
    final_sums: Vec<FinalAcc>,
    /// Scratch and output of the final pass's bands of rows.
    final_bands: Vec<final_band::FinalBand>,
    /// Pixels that fit two planes, in row order.
    ambiguous: Vec<final_band::AmbiguousPixel>,
    /// Per component: affine moment sums of its cells (seeding).
    component_sums: Vec<AffineSums>,
    /// Per component: bounding box on the cell grid (seeding).
    component_box: Vec<[u32; 4]>,
    /// Per component: its robust affine fit, if it has one (seeding).
    component_fit: Vec<Option<DisparityAffine>>,
    /// Per root patch: bounding box of its set on the cell grid (seeding).
    patch_box: Vec<[u32; 4]>,
    /// Label lookup table for renumbering (old label → new label).
    relabel_lut: Vec<u16>,
    /// Per plane of the final pass: the plane its pixels belong to after the pieces of bent
    /// surfaces are joined (`bend`; itself when not joined).
    joined_into: Vec<u16>,
    /// The crease test (`crease`): per plane, the quadratic sums of its residual on the grid,
    /// the row being accumulated and the centre of its coordinates (NaN: not tested); the
    /// planes touched by the current row; the samples of the planes tested further and the
    /// work list.
    crease_quad: Vec<crate::quadratic::QuadraticSums>,
    crease_rows: Vec<crate::quadratic::RowMoments>,
    crease_centres: Vec<(f64, f64)>,
    crease_touched: Vec<u16>,
    /// Per plane: the columns of its grid samples (first, last).
    crease_columns: Vec<(u32, u32)>,
    /// The noise of the crease test's samples (a grid `crease::GRID_X` × `crease::GRID_Y` pixels apart).
    crease_noise: FitNoise,
    /// The same for the dense samples of small planes (`crease::DENSE_STEP` × `SAMPLE_ROW_STEP`).
    crease_dense_noise: FitNoise,
    crease_samples: Vec<crease::CreaseSample>,
    crease_work: Vec<crease::CreaseWork>,
    /// Per plane of the final pass: 1 when it (or the surface it was joined into) was left
    /// out as too uncertain (`PlaneConfig::max_normal_sigma_deg`; for `explain`).
    dropped_uncertain: Vec<u8>,
    /// Per plane of the final pass: its fit and pixel centroid (`bend`).
    join_fits: Vec<Option<(DisparityAffine, f64, f64)>>,
    /// Borders between cells of two planes (`bend`).
    join_seams: Vec<bend::Seam>,
    /// The same grouped by pair (scratch of the counting sort).
    join_seams_by_pair: Vec<bend::Seam>,
    /// Per pair of planes `a·n + b`: where its borders start in `join_seams` (counting sort).
    join_pair_start: Vec<u32>,
    /// Pairs of planes that may be pieces of one bent surface: `(slope turn per pixel, a, b,
    /// their borders in `join_seams`)`.
    join_pairs: Vec<(f64, u16, u16, std::ops::Range<usize>)>,
    /// Bend-join candidates with a step at their border (`bend`): never in one set.
    join_apart: Vec<(u16, u16)>,
    /// Per cell: the stamp of the last border strip that took it (`bend`).
    join_mark: Vec<u32>,
    /// The current stamp of `join_mark`.
    join_stamp: u32,
    /// Borders between cells of two planes, `(a, b, cell of a, cell of b)`, sorted by pair
    /// (`seam`).
    seam_pairs: Vec<(u16, u16, u32, u32)>,
    /// Per cell: the stamp of the last pair's disputed cells, strip or listed disputed cells
    /// that took it (`seam`).
    seam_mark: Vec<u32>,
    /// The current stamp of `seam_mark`: the listed disputed cells' (the strip's is one less,
    /// the sampled disputed cells' two less).
    seam_stamp: u32,
    /// The disputed cells of the current pair (`seam`).
    seam_cells: Vec<u32>,
    /// Noise of a cell's mean disparity (from the sensor model and the configuration, scaled
    /// by the frame's own noise level, `noise_level`).
    noise: CellNoise,
    /// The camera's sensor model of the frame being extracted.
    noise_sensor: sl_core::SensorModel,
    /// The correlation window of its disparity error, pixels of the frame.
    noise_window: (f64, f64),
    /// The frame's own noise level against the model (`noise_level`).
    noise_meter: NoiseMeter,
    /// The factor by which the last frame's pixel variance exceeded the model's (1: it did
    /// not), applied to every noise of the extractor.
    noise_scale: f64,
    /// Whether the last frame's pixel noise (`noise`, scaled) exceeded `threshold_px`, so that
    /// no plane was extracted (`noise_level`).
    noise_beyond_threshold: bool,
    /// Noise of the final fit's samples (the planes' uncertainties).
    fit_noise: FitNoise,
    /// Per patch (then per set of patches): moments of its planar cells.
    patch_sums: Vec<AffineSums>,
    /// Per patch (set): the residual sum of squares of its fit (NaN = not a planar patch).
    patch_rss: Vec<f64>,
    /// Edges between neighbouring patches: `(ΔRSS, patch, patch)`.
    patch_edges: Vec<(f32, u32, u32)>,
    /// The same per row of patches, before they are gathered in row order.
    patch_row_edges: Vec<Vec<(f32, u32, u32)>>,
    /// Union-find parents of the patches.
    patch_parent: Vec<u32>,
    /// Per root patch: its plane label (0 = none).
    patch_plane: Vec<u16>,
    /// Per patch: what the first seeding made of it (for [`PlaneExtractor::explain_unlabelled`]).
    patch_status: Vec<PatchStatus>,
    /// The same for the reseeding of the free cells (scratch).
    patch_status_reseed: Vec<PatchStatus>,
    /// Wall-clock time per stage of the last frame.
    times: StageTimes,
    /// The frame replicated onto its sensor's grid (a decimated camera, `decimated`).
    sensor_grid_input: Vec<f32>,
    /// The decimation factor and sensor-grid labels of the last extraction when it ran on the
    /// sensor's grid (for [`PlaneExtractor::explain_unlabelled`]).
    sensor_grid: Option<(usize, Image<u16>)>,
    /// The image rows of the extraction running (see [`RowCentres`]).
    rows: RowCentres,
    /// Per block of the taken-in test (`taken_in`): up to two planes' sample sums.
    block_slots: Vec<taken_in::BlockSlots>,
    /// The disparity of the sample rows (every [`SAMPLE_ROW_STEP`]-th), for the taken-in test.
    block_disparity: Vec<f32>,
    /// Start of each plane's blocks in `block_tests` (by label, counting sort).
    block_start: Vec<u32>,
    /// Fill positions of the counting sort.
    block_fill: Vec<u32>,
    /// The blocks of every plane, grouped by plane.
    block_tests: Vec<taken_in::TestBlock>,
    /// Block → index among the blocks of the plane under test (`u32::MAX`: not its block).
    block_mark: Vec<u32>,
    /// Visited blocks, search stack and current piece of the piece search.
    block_seen: Vec<bool>,
    block_stack: Vec<usize>,
    block_piece: Vec<usize>,
    /// The blocks' residuals where their surroundings agree they are off, and the scratch of
    /// a block's surroundings.
    block_off: Vec<f64>,
    block_window: Vec<f64>,
    /// Cells (4 × 4 pixels) whose pixels a plane gave back in the last extraction (1), for
    /// `explain`; empty when the stage did not run.
    given_back_cells: Vec<u8>,
}

/// Where a full-resolution row's disparity was measured, in the image's rows: the row itself,
/// or on a decimated frame replicated onto its sensor's grid (`decimated`) the centre of the
/// `n` rows its value was copied over. A block of `n` equal rows holds the value at its
/// centre, `(n − 1)/2` rows below its first; a fit at the rows' own coordinates would read a
/// plane's disparity as a staircase and, from the rows it samples (every
/// [`SAMPLE_ROW_STEP`]-th: the first row of every block when `n` divides the step), move the
/// plane by up to `(n − 1)/2` rows along its disparity gradient. On a floor seen through a
/// 320×240 Kinect stream, that is centimetres at 2 m (`decimated`'s test).
#[derive(Debug, Clone, Copy)]
pub(super) struct RowCentres {
    /// The replication factor (1: the frame's own rows).
    n: usize,
}

impl Default for RowCentres {
    fn default() -> Self {
        Self { n: 1 }
    }
}

impl RowCentres {
    /// Rows replicated `n` times (1 or 0: not replicated).
    pub(super) fn replicated(n: usize) -> Self {
        Self { n: n.max(1) }
    }

    /// The coordinate of row `y`'s values.
    #[inline]
    pub(super) fn of(self, y: usize) -> f64 {
        if self.n == 1 {
            y as f64
        } else {
            (y - y % self.n) as f64 + 0.5 * (self.n - 1) as f64
        }
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

    /// The cell noise of `camera`'s images: the window is given in the sensor's pixels, so a
    /// camera resampled from its sensor ([`Camera::resampled`]) sees it scaled.
    fn set_noise(&mut self, camera: &Camera) {
        let s = camera.pixels_per_sensor_pixel();
        let (wx, wy) = (
            self.cfg.noise_window_x_px * s,
            self.cfg.noise_window_y_px * s,
        );
        self.noise_sensor = camera.sensor;
        self.noise_window = (wx, wy);
        self.noise_scale = 1.0;
        self.set_noise_sigma(camera.sensor.sigma_d_px);
    }

    /// Every noise of the extractor for a disparity error of `sigma_d` px and the model's
    /// quantisation and window.
    fn set_noise_sigma(&mut self, sigma_d: f64) {
        let q = self.noise_sensor.subpixel_steps;
        let (wx, wy) = self.noise_window;
        self.noise = CellNoise::new(sigma_d, q, wx, wy);
        self.fit_noise = FitNoise::new(sigma_d, q, wx, wy, SAMPLE_ROW_STEP);
        self.crease_noise = FitNoise::on_grid(sigma_d, q, wx, wy, crease::GRID_X, crease::GRID_Y);
        self.crease_dense_noise =
            FitNoise::on_grid(sigma_d, q, wx, wy, crease::DENSE_STEP, SAMPLE_ROW_STEP);
    }

    /// Scales the pixel variance `σ_D² + 1/(12q²)` of every noise of the extractor by
    /// `factor` (≥ 1), keeping the quantisation and the window: the frame's own noise level
    /// (`noise_level`).
    fn scale_noise(&mut self, factor: f64) {
        self.set_noise_sigma(self.noise_sensor.sigma_d_for_variance_scale(factor));
    }

    /// The factor by which the last frame's disparity-error variance exceeded the camera's
    /// model, measured on the frame's own patches ([`PlaneConfig::estimate_noise`]): every
    /// noise test of that extraction and the planes' uncertainties used the model's pixel
    /// variance times this. 1 when the frame was within its model (or too small to tell).
    pub fn noise_scale(&self) -> f64 {
        self.noise_scale
    }

    /// Whether the last frame was too noisy for [`PlaneConfig::threshold_px`]: its measured
    /// disparity error (the pixel variance `σ_D² + 1/(12q²)` times
    /// [`PlaneExtractor::noise_scale`]) has a standard deviation above the threshold, so a
    /// true plane would keep fewer than 68 % of its pixels within it and the extractor
    /// returned no plane (see [`RejectReason::NoiseBeyondThreshold`]). A sensor that noisy
    /// needs a larger `threshold_px`. Always `false` with
    /// [`PlaneConfig::estimate_noise`] off (the camera's model is then trusted).
    pub fn noise_beyond_threshold(&self) -> bool {
        self.noise_beyond_threshold
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
    /// A camera whose frames are its sensor decimated by a whole factor of 2–8
    /// ([`Camera::resampled`]) is extracted on the sensor's grid (each pixel replicated; see
    /// the `decimated` module): every scale of the extractor, `min_pixels` included, is in the
    /// sensor's pixels, so the same scene gives the same planes at either resolution.
    pub fn extract_depth<'a>(
        &mut self,
        depth: impl Into<DepthView<'a>>,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        let depth: DepthView<'a> = depth.into();
        let (w, h) = (depth.width(), depth.height());
        self.extract_on_sensor_grid(depth.data(), w, h, camera, Self::extract_depth_rows)
    }

    /// [`PlaneExtractor::extract_depth`] on the frame's own pixels.
    fn extract_depth_rows(
        &mut self,
        z: &[f32],
        w: usize,
        h: usize,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        Self::check(w, h, &camera.intrinsics)?;
        let mut t0 = Instant::now();
        self.times = StageTimes::default();
        let fb = camera.sensor.fb();
        let fbf = fb as f32;
        self.set_noise(camera);
        // The full-resolution disparity is never stored: rows are converted where used.
        let src = FullDisparity::Depth { z, fb: fbf };
        self.times.add(Stage::Disparity, &mut t0);
        self.run(src, w, h, &camera.intrinsics, fb, t0)
    }

    /// Extracts planes from a disparity image (pixels, 0 = invalid), e.g. raw Kinect disparity
    /// converted to pixels; `f·B` of the camera relates it to depth. A decimated camera is
    /// handled as in [`PlaneExtractor::extract_depth`].
    pub fn extract_disparity(
        &mut self,
        disparity: &DisparityImage,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        let (w, h) = (disparity.width(), disparity.height());
        self.extract_on_sensor_grid(disparity.data(), w, h, camera, Self::extract_disparity_rows)
    }

    /// [`PlaneExtractor::extract_disparity`] on the frame's own pixels.
    fn extract_disparity_rows(
        &mut self,
        d: &[f32],
        w: usize,
        h: usize,
        camera: &Camera,
    ) -> Result<PlaneSegmentation> {
        Self::check(w, h, &camera.intrinsics)?;
        let mut t0 = Instant::now();
        self.times = StageTimes::default();
        // The disparity is used in place: every test treats non-positive and non-finite values
        // as invalid.
        let src = FullDisparity::Disparity(d);
        self.set_noise(camera);
        self.times.add(Stage::Disparity, &mut t0);
        self.run(src, w, h, &camera.intrinsics, camera.sensor.fb(), t0)
    }

    fn run(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        k: &Intrinsics,
        fb: f64,
        mut t0: Instant,
    ) -> Result<PlaneSegmentation> {
        let cfg = self.cfg;
        let tau = cfg.threshold_px as f32;
        self.planes.clear();
        self.final_sums.clear();
        // What the taken-in stage gave back is this frame's (none unless it runs).
        self.given_back_cells.clear();
        let (w2, h2) = (w / 2, h / 2);
        let (wq, hq) = (w2 / 2, h2 / 2);
        // The final pass appends the rows of the label image (no zeroing of the whole image).
        let mut labels: Vec<u16> = Vec::with_capacity(w * h);
        if wq < 8 || hq < 8 {
            // Too small a frame for the cell grid: no plane, and nothing of an earlier frame
            // left for `explain_unlabelled` to read.
            self.cell_disparity.clear();
            self.cell_planar.clear();
            self.cell_labels.clear();
            self.patch_status.clear();
            self.joined_into.clear();
            labels.resize(w * h, 0);
            return self.finish(w, h, k, fb, labels);
        }
        // 0. The half-resolution disparity (2×2 means) and the cells (4×4 means).
        self.cell_disparity.resize(wq * hq, f32::NAN);
        // Row scratch; `fit_run` may write up to 7 bytes past a run.
        self.keep_row.resize(w + LANES, 0);
        // 1. Seeds: the LoG on the half-resolution map, extended across holes and the image
        // border (exact for planes, see `extend`) so that pixels next to them can be planar;
        // then components on the cell grid.
        let parallel = rayon::current_num_threads() > 1;
        let (r, s) = log_geometry(cfg.log_sigma_px / 2.0);
        let m = 2 * r + s + 1;
        let (we, he) = (w2 + 2 * m, h2 + 2 * m);
        self.half_res_extended.clear();
        self.half_res_extended.resize(we * he, f32::NAN);
        self.half_res_partial.clear();
        self.half_res_partial.resize(w2 * h2, f32::NAN);
        half_resolution(
            d,
            w,
            h,
            &mut self.half_res_extended,
            we,
            m,
            &mut self.half_res_partial,
            &mut self.cell_disparity,
            &mut self.half_res_scratch,
            parallel,
        );
        self.calibrate_noise(wq, hq);
        // The LoG response is linear in the disparity: its noise grows with the frame's, and
        // so does the threshold that was set for the camera's noise.
        let log_threshold = cfg.log_threshold_px * self.noise_scale.sqrt();
        // Half-resolution pixels without data (NaN even with a diagonal) stay non-planar; the
        // mask is cut back below.
        self.log_mask.clear();
        self.log_mask
            .extend(self.half_res_partial.iter().map(|v| u8::from(!v.is_nan())));
        extend_map(
            &mut self.half_res_extended,
            we,
            he,
            m,
            &mut self.extend_buffers,
            parallel,
        );
        planar_mask_uncounted(
            &self.half_res_extended,
            we,
            he,
            r,
            s,
            log_threshold as f32,
            &mut self.log_buffers,
            &mut self.extended_mask,
            parallel,
        );
        for (out, row) in self
            .log_mask
            .chunks_exact_mut(w2)
            .zip(self.extended_mask.chunks_exact(we).skip(m))
        {
            for (o, &p) in out.iter_mut().zip(&row[m..m + w2]) {
                *o &= p;
            }
        }
        self.planar_cells(w2, wq, hq);
        self.times.add(Stage::Log, &mut t0);
        if self.noise_beyond_threshold {
            // No plane can hold this frame's pixels within `τ` (`noise_level`): none is
            // extracted; the LoG's cells stay for `explain_unlabelled`.
            self.patch_status.clear();
            self.cell_labels.clear();
            self.joined_into.clear();
            labels.resize(w * h, 0);
            let out = self.finish(w, h, k, fb, labels);
            self.times.add(Stage::Output, &mut t0);
            return out;
        }
        let min_q = (cfg.min_pixels / (CELL * CELL)).max(3);
        self.seed_from_patches(wq, hq, min_q, false);
        self.seed_leftover_components(wq, hq, min_q);
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
                let before = self.planes.len();
                self.seed_from_patches(wq, hq, min_q, true);
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

        // 3. Growth and coherence on the cell grid, then the final full-resolution pass.
        if !self.planes.is_empty() {
            self.grow(wq, hq);
            let labelled = cfg.min_piece_pixels > 0;
            if labelled {
                self.drop_small_pieces(wq, hq);
            }
            self.split_separated(wq, hq, f64::from(tau), min_q, labelled);
            self.times.add(Stage::Components, &mut t0);
            self.order_by_size();
            self.final_pass(d, w, h, wq, tau, &mut labels);
            self.times.add(Stage::FinalPass, &mut t0);
            self.resolve_ambiguous(d, w, h, &mut labels);
            if cfg.refine_seams {
                self.refine_seams(d, w, h, wq, hq, tau, &mut labels);
            }
            self.times.add(Stage::Disambiguate, &mut t0);
            if cfg.split_creases {
                self.split_creases(d, w, wq, k.fx, &mut labels);
            }
            if cfg.give_back_taken_in {
                self.give_back_taken_in(d, w, wq, &mut labels);
            }
            self.join_bent_pieces(wq, hq, k.fx, f64::from(tau));
            self.times.add(Stage::Merge, &mut t0);
        } else {
            self.joined_into.clear();
        }
        labels.resize(w * h, 0);
        let out = self.finish(w, h, k, fb, labels);
        self.times.add(Stage::Output, &mut t0);
        out
    }
}

mod assign;
mod bend;
mod config;
mod crease;
mod decimated;
mod explain;
mod final_band;
mod grow;
mod input;
mod merge;
mod noise_level;
mod output;
mod patches;
mod refine;
mod rows;
mod seam;
mod seeds;
mod split;
mod stages;
mod taken_in;
#[cfg(test)]
mod tests;

pub use config::PlaneConfig;
pub use explain::{RegionExplanation, RejectReason};
use input::*;
pub use noise_level::{NoiseMeter, frame_noise_scale};
pub use output::{PlaneInfo, PlaneSegmentation};
use patches::{CellNoise, PatchStatus};
use rows::*;
pub use stages::{Stage, StageTimes};
