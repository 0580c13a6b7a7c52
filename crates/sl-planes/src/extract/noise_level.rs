//! The frame's own noise level, measured on its patches (issue 12: planes on cameras the model
//! does not describe exactly).
//!
//! Every test of the extractor takes its noise from the camera's model: `σ_D`, the `1/q`
//! quantisation and the correlation of the block-matching window (`CellNoise`). A sensor
//! noisier than its model says — a worn or warm unit, a preset's typical `σ_D` for a camera
//! that is not typical, another make behind a Kinect preset — makes every planar patch look
//! curved to those tests: planes come out cut into pieces and spurious (on the simulated rooms,
//! a sensor twice as noisy as its camera says left 33 spurious planes in 60 rooms, against 6
//! once the camera was told; docs/bench/README.md, session 42).
//!
//! The frame says how noisy it is. Over every patch of `PATCH × PATCH` cells whose cells all
//! have data, the residual sum of squares of the patch's affine fit, `RSS/((n − 3)·var_cell)`,
//! follows under the model a known law: a weighted sum of `χ²₁` terms whose weights are the
//! eigenvalues of `M·C·M` (`C` the cells' correlation matrix from the matching window, `M` the
//! projection off the affine functions), approximated by a scaled `χ²_ν` with the same mean and
//! variance (Satterthwaite) and its quantiles by Wilson–Hilferty. Patches across an edge or on
//! a curved surface only add to the upper tail, so the frame's **lower quartile** is compared
//! with the law's: up to three quarters of the patches may be non-planar. When the frame's is
//! larger than the law's by more than its own sampling error allows (one-sided, 99.9 %), every
//! variance of the extractor is scaled by the ratio for this frame (the pixel variance
//! `σ_D² + 1/(12q²)`, so the correlation structure is kept); otherwise the camera's model
//! stands. The camera's `σ_D` is thus a floor, never lowered: a quieter frame than the model
//! keeps the model's tests.
//!
//! **Two scales.** The same test runs on patches of 4 × 4 blocks of 2 × 2 cells (32 × 32 px),
//! against their own law (the correlation and variance of 8-px block means under the model's
//! window). A sensor whose error is correlated over a *wider* window than the model's hides part
//! of it at 16 px — an affine fit over 16 px absorbs a smooth error — and shows it at 32 px, so
//! the 32-px reading counts when it is significantly above the 16-px one (beyond its own
//! sampling error, one-sided, 99.9 %); otherwise both read the same variance and the 16-px
//! reading, on four times the patches, stands (the larger of the two would be biased upwards:
//! it cost the tracker frames on noisier simulated sensors). On the simulated rooms through a
//! 13 × 15-px, 0.12-px sensor (development seeds 0–59, the Kinect model given) the measured scale
//! rises from 1.63 to 2.17 (the true pixel-variance ratio is 2.5) and the spurious planes fall
//! from 27 to 11; every 9 × 11-px and 5 × 5-px configuration keeps its scale. Real frames
//! average their error away faster than the model between 16 and 32 px (docs/NOISE_MODEL.md §3):
//! there the 32-px reading is the lower one.
//!
//! Measured (lower quartile / the law's, before any scaling): the simulator at the model's
//! noise 0.87–1.00; real Kinect frames 0.87–0.96 (7-Scenes, person, floor scan) and 1.06–1.10
//! (TUM fr1, NYU raw); the simulator at `σ_D` 0.10 / 0.14 px against a camera of 0.07 px about
//! 1.8 / 3.4.
//!
//! Written by hand: the law is specific to the extractor's cells and patches.

#[cfg(test)]
use super::patches::min_rss;
use rayon::prelude::*;

use super::patches::{
    CellNoise, PATCH, Z_999, block_correlations, block_variance_factor, cell_correlations,
};
use super::*;

/// Fewest full patches for an estimate (a 640×480 frame has 1,200 patches).
const MIN_PATCHES: usize = 64;

/// The lower quartile's standard normal quantile.
const Z_P25: f64 = -0.674_489_750_196_081_7;

/// The law of `RSS/((n − 3)·var_cell)` of a full patch's affine fit under the camera's noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PatchRssLaw {
    /// Its mean.
    pub(super) mean: f64,
    /// The degrees of freedom of the matched `χ²_ν`.
    pub(super) nu: f64,
}

/// Degrees of freedom of a full patch's affine fit.
const PATCH_DOF: f64 = (PATCH * PATCH) as f64 - 3.0;

impl PatchRssLaw {
    /// The law for cells whose means are correlated as `rho_x(lag)·rho_y(lag)` (lags in cells,
    /// `rho(0) = 1`).
    pub(super) fn new(rho_x: &[f64; PATCH], rho_y: &[f64; PATCH]) -> Self {
        const N: usize = PATCH * PATCH;
        let centre = (PATCH as f64 - 1.0) / 2.0;
        let coord = |a: usize| ((a % PATCH) as f64 - centre, (a / PATCH) as f64 - centre);
        // Σ over the patch of x² (and of y²): the affine design is orthogonal about the centre.
        let sxx: f64 = (0..N).map(|a| coord(a).0 * coord(a).0).sum();
        let proj = |a: usize, b: usize| {
            let ((xa, ya), (xb, yb)) = (coord(a), coord(b));
            (xa * xb + ya * yb) / sxx + 1.0 / N as f64
        };
        let corr = |a: usize, b: usize| {
            rho_x[(a % PATCH).abs_diff(b % PATCH)] * rho_y[(a / PATCH).abs_diff(b / PATCH)]
        };
        // MC = C − P·C.
        let mut mc = [[0.0f64; N]; N];
        for (a, row) in mc.iter_mut().enumerate() {
            for (b, v) in row.iter_mut().enumerate() {
                let pc: f64 = (0..N).map(|k| proj(a, k) * corr(k, b)).sum();
                *v = corr(a, b) - pc;
            }
        }
        let trace: f64 = (0..N).map(|a| mc[a][a]).sum();
        let trace_sq: f64 = (0..N)
            .flat_map(|a| (0..N).map(move |b| (a, b)))
            .map(|(a, b)| mc[a][b] * mc[b][a])
            .sum();
        Self {
            mean: trace / PATCH_DOF,
            nu: trace * trace / trace_sq,
        }
    }

    /// The quantile of standard normal quantile `z` (Wilson–Hilferty).
    fn quantile(&self, z: f64) -> f64 {
        let k = 2.0 / (9.0 * self.nu);
        self.mean * (1.0 - k + z * k.sqrt()).max(0.0).powi(3)
    }

    /// The lower quartile.
    pub(super) fn lower_quartile(&self) -> f64 {
        self.quantile(Z_P25)
    }

    /// The relative standard error of the lower quartile of `n` samples (through the normal
    /// cube-root transform: `σ·√(p(1 − p))/φ(z_p)/√n` there, three times relative here).
    fn lower_quartile_rel_error(&self, n: usize) -> f64 {
        let k = 2.0 / (9.0 * self.nu);
        let phi = (-0.5 * Z_P25 * Z_P25).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let se_root = k.sqrt() * (0.25f64 * 0.75).sqrt() / phi / (n as f64).sqrt();
        3.0 * se_root / (1.0 - k + Z_P25 * k.sqrt())
    }

    /// The frame's lower quartile of `n` patches against the law's, with its sampling error.
    fn reading(&self, lower_quartile: f64, n: usize) -> Reading {
        Reading {
            ratio: lower_quartile / self.lower_quartile(),
            rel_error: self.lower_quartile_rel_error(n),
        }
    }
}

/// A frame's noise read at one scale: its patches' lower quartile over the law's, and the
/// relative sampling error of that quartile.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Reading {
    ratio: f64,
    rel_error: f64,
}

impl Reading {
    /// The ratio when it exceeds `floor` beyond its sampling error (one-sided, 99.9 %), else 1.
    fn excess_over(&self, floor: f64) -> f64 {
        if self.ratio.is_finite() && self.ratio > floor * (1.0 + Z_999 * self.rel_error) {
            self.ratio
        } else {
            1.0
        }
    }
}

/// The residual sum of squares of the least-squares affine fit to a full patch of cell
/// disparities (row-major), or `None` when a cell has no data. About the patch's centre the
/// affine design is orthogonal (`Σ1 = 16`, `Σx² = Σy² = 20`, no cross terms), so the fit's
/// explained part is `b₀²/16 + (b_x² + b_y²)/20`; the values are taken about the first cell's
/// (in `f64`) so that the difference does not cancel.
fn full_patch_rss(v: &[f32; PATCH * PATCH]) -> Option<f64> {
    if !v.iter().all(|d| d.is_finite() && *d > 0.0) {
        return None;
    }
    // Cell coordinates about the patch's centre, and `Σx²` (= `Σy²`).
    const C: [f64; PATCH] = [-1.5, -0.5, 0.5, 1.5];
    const SXX: f64 = 20.0;
    const N: f64 = (PATCH * PATCH) as f64;
    let origin = f64::from(v[0]);
    let (mut s0, mut sx, mut sy, mut s2) = (0.0, 0.0, 0.0, 0.0);
    for (row, &y) in v.chunks_exact(PATCH).zip(&C) {
        let mut r0 = 0.0;
        for (&d, &x) in row.iter().zip(&C) {
            let e = f64::from(d) - origin;
            r0 += e;
            sx += x * e;
            s2 += e * e;
        }
        s0 += r0;
        sy += y * r0;
    }
    Some((s2 - s0 * s0 / N - (sx * sx + sy * sy) / SXX).max(0.0))
}

/// Measures frames' disparity noise against their camera's model ([`PlaneExtractor`] does it
/// on every frame, see [`PlaneConfig::estimate_noise`]; other stages that take their noise from
/// the camera's model use it on its own, such as a tracker's uncertainty of a pose). Keeps the
/// law of the last camera's window and its buffers, so that a sequence allocates nothing per
/// frame.
#[derive(Debug, Clone, Default)]
pub struct NoiseMeter {
    /// The correlation window of the disparity error, pixels of the sensor.
    window_px: (f64, f64),
    /// The laws of the last window in the frame's pixels (patches of cells, patches of blocks
    /// of 2 × 2 cells), with that window.
    law: Option<((f64, f64), [PatchRssLaw; 2])>,
    /// Scratch: the frame's cell disparities (`measure`) and the patches' residual ratios.
    cells: Vec<f32>,
    ratios: Vec<f64>,
}

impl NoiseMeter {
    /// A meter for a sensor whose error is correlated over `cfg.noise_window_*_px` (pixels of
    /// the sensor).
    pub fn new(cfg: &PlaneConfig) -> Self {
        Self {
            window_px: (cfg.noise_window_x_px, cfg.noise_window_y_px),
            ..Self::default()
        }
    }

    /// The factor by which the disparity-error variance of a depth frame (metres, 0 = invalid)
    /// exceeds `camera`'s noise model, measured as [`PlaneExtractor`] does (its
    /// [`PlaneExtractor::noise_scale`]) but on the frame alone: cells are the 4×4-pixel blocks
    /// whose every pixel has depth. 1 when the frame is within its model or too small to tell
    /// (fewer than 64 full patches of 4×4 cells). The cost of one pass over the frame.
    pub fn measure<'a>(&mut self, depth: impl Into<DepthView<'a>>, camera: &Camera) -> Result<f64> {
        let depth: DepthView<'a> = depth.into();
        let (w, h) = (depth.width(), depth.height());
        PlaneExtractor::check(w, h, &camera.intrinsics)?;
        let s = camera.pixels_per_sensor_pixel();
        let (wx, wy) = (self.window_px.0 * s, self.window_px.1 * s);
        let var_cell = CellNoise::new(
            camera.sensor.sigma_d_px,
            camera.sensor.subpixel_steps,
            wx,
            wy,
        )
        .var_cell;
        let fb = camera.sensor.fb() as f32;
        let (wq, hq) = (w / CELL, h / CELL);
        let z = depth.data();
        let mut cells = std::mem::take(&mut self.cells);
        cells.clear();
        cells.resize(wq * hq, f32::NAN);
        // Rows of cells in parallel (on the caller's pool): the pass over the frame's pixels is
        // the measurement's cost.
        cells
            .par_chunks_exact_mut(wq.max(1))
            .enumerate()
            .take(hq)
            .for_each(|(j, row)| {
                for (i, cell) in row.iter_mut().enumerate() {
                    let mut sum = 0.0f32;
                    let mut full = true;
                    for y in j * CELL..(j + 1) * CELL {
                        for &zz in &z[y * w + i * CELL..y * w + (i + 1) * CELL] {
                            full &= zz > 0.0 && zz.is_finite();
                            sum += fb / zz;
                        }
                    }
                    if full {
                        *cell = sum / (CELL * CELL) as f32;
                    }
                }
            });
        let excess = self.excess(&cells, wq, hq, var_cell, (wx, wy));
        self.cells = cells;
        Ok(excess)
    }

    /// The factor by which the noise of the `wq × hq` cell disparities `cells` (non-finite or
    /// ≤ 0 = no data) exceeds a model of cell variance `var_cell` correlated over `window`
    /// (pixels of the frame), over their full patches: 1 when it does not, significantly (see
    /// the module documentation). Measured at two scales, on patches of 4 × 4 cells (16 × 16
    /// px) and of 4 × 4 blocks of 2 × 2 cells (32 × 32 px), each against its own law. A sensor
    /// whose error is correlated over a wider window than the model's shows it at the larger
    /// scale only (an affine fit over 16 px absorbs much of a wide error), so the 32-px reading
    /// counts when it is significantly above the 16-px one (beyond its own sampling error,
    /// one-sided, 99.9 %); otherwise the two read the same variance and the 16-px reading, the
    /// one with four times the patches, stands (their larger would be biased upwards).
    pub(super) fn excess(
        &mut self,
        cells: &[f32],
        wq: usize,
        hq: usize,
        var_cell: f64,
        window: (f64, f64),
    ) -> f64 {
        if var_cell.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || cells.len() < wq * hq
        {
            return 1.0;
        }
        let [fine_law, coarse_law] = match self.law {
            Some((w, laws)) if w == window => laws,
            _ => {
                let block = 2 * CELL;
                let laws = [
                    PatchRssLaw::new(&cell_correlations(window.0), &cell_correlations(window.1)),
                    PatchRssLaw::new(
                        &block_correlations(window.0, block),
                        &block_correlations(window.1, block),
                    ),
                ];
                self.law = Some((window, laws));
                laws
            }
        };
        let fine = patch_reading(&mut self.ratios, cells, wq, hq, var_cell, &fine_law);
        let block_factor =
            |w: f64| block_variance_factor(w, 2 * CELL) / block_variance_factor(w, CELL);
        let var_block = var_cell * block_factor(window.0) * block_factor(window.1);
        let coarse = block_patch_reading(&mut self.ratios, cells, wq, hq, var_block, &coarse_law);
        let fine_ratio = fine.map_or(1.0, |f| f.ratio.max(1.0));
        match (fine, coarse) {
            (_, Some(c)) if c.excess_over(fine_ratio) > 1.0 => c.ratio,
            (Some(f), _) => f.excess_over(1.0),
            (None, _) => 1.0,
        }
    }
}

/// [`patch_reading`] on the means of 2 × 2 cells (blocks of variance `var_block`) of the
/// `w × h` cells `cells`, over their full patches of 4 × 4 blocks; `ratios` is scratch.
fn block_patch_reading(
    ratios: &mut Vec<f64>,
    cells: &[f32],
    w: usize,
    h: usize,
    var_block: f64,
    law: &PatchRssLaw,
) -> Option<Reading> {
    ratios.clear();
    const SIDE: usize = 2 * PATCH;
    for pj in 0..h / SIDE {
        for pi in 0..w / SIDE {
            let mut v = [0.0f32; PATCH * PATCH];
            let mut full = true;
            for (bj, dst) in v.chunks_exact_mut(PATCH).enumerate() {
                let r0 = (pj * SIDE + 2 * bj) * w + pi * SIDE;
                let (top, bottom) = (&cells[r0..r0 + SIDE], &cells[r0 + w..r0 + w + SIDE]);
                for ((d, t), b) in dst
                    .iter_mut()
                    .zip(top.chunks_exact(2))
                    .zip(bottom.chunks_exact(2))
                {
                    // A block has data when its four cells have (NaN compares false).
                    full &= t[0] > 0.0 && t[1] > 0.0 && b[0] > 0.0 && b[1] > 0.0;
                    *d = (t[0] + t[1] + b[0] + b[1]) / 4.0;
                }
            }
            if let Some(rss) = full.then(|| full_patch_rss(&v)).flatten() {
                ratios.push(rss / (PATCH_DOF * var_block));
            }
        }
    }
    quartile_reading(ratios, law)
}

/// The reading of the `w × h` values `cells` (cell or block disparities, non-finite or ≤ 0 = no
/// data) of variance `var_cell` against `law`, on their full patches (see
/// [`NoiseMeter::excess`]); `ratios` is scratch.
fn patch_reading(
    ratios: &mut Vec<f64>,
    cells: &[f32],
    w: usize,
    h: usize,
    var_cell: f64,
    law: &PatchRssLaw,
) -> Option<Reading> {
    ratios.clear();
    for pj in 0..h / PATCH {
        for pi in 0..w / PATCH {
            let mut v = [0.0f32; PATCH * PATCH];
            for (j, dst) in v.chunks_exact_mut(PATCH).enumerate() {
                let row = (pj * PATCH + j) * w + pi * PATCH;
                dst.copy_from_slice(&cells[row..row + PATCH]);
            }
            if let Some(rss) = full_patch_rss(&v) {
                ratios.push(rss / (PATCH_DOF * var_cell));
            }
        }
    }
    quartile_reading(ratios, law)
}

/// The lower quartile of the patches' `ratios` against `law` (`None` with fewer than
/// [`MIN_PATCHES`]).
fn quartile_reading(ratios: &mut [f64], law: &PatchRssLaw) -> Option<Reading> {
    let n = ratios.len();
    if n < MIN_PATCHES {
        return None;
    }
    let (_, &mut q25, _) = ratios.select_nth_unstable_by(n / 4, f64::total_cmp);
    Some(law.reading(q25, n))
}

impl PlaneExtractor {
    /// Measures the frame's noise on its full patches of `cell_disparity` (`wq × hq` cells)
    /// and, when it exceeds the camera's model, scales every noise of the extractor by it
    /// (see the module documentation). Sets `noise_scale`.
    pub(super) fn calibrate_noise(&mut self, wq: usize, hq: usize) {
        self.noise_scale = 1.0;
        self.noise_beyond_threshold = false;
        if !self.cfg.estimate_noise {
            return;
        }
        let excess = self.noise_meter.excess(
            &self.cell_disparity,
            wq,
            hq,
            self.noise.var_cell,
            self.noise_window,
        );
        if excess > 1.0 {
            self.noise_scale = excess;
            self.scale_noise(excess);
            // A plane is the pixels within `τ` of an affine disparity: with a pixel error whose
            // σ exceeds `τ`, a true plane keeps fewer than 68 % of its pixels within it, and
            // every noise test, scaled to that error, passes surfaces of any shape (uniform
            // random depth measures a scale in the thousands). Such a frame is reported, not
            // segmented.
            self.noise_beyond_threshold = self.noise.var_px > self.cfg.threshold_px.powi(2);
        }
    }
}

/// [`NoiseMeter::measure`] with a meter of its own (for one frame; a sequence keeps one
/// [`NoiseMeter`]): the factor by which the frame's disparity-error variance exceeds `camera`'s
/// noise model, the correlation window `cfg.noise_window_*_px` in the sensor's pixels.
pub fn frame_noise_scale<'a>(
    depth: impl Into<DepthView<'a>>,
    camera: &Camera,
    cfg: &PlaneConfig,
) -> Result<f64> {
    NoiseMeter::new(cfg).measure(depth, camera)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Standard normal samples: Box–Muller on a xorshift generator (deterministic; `state`
    /// non-zero).
    fn gaussians(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            let mut u = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (u1, u2) = (u(), u());
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        }
    }

    fn law(window_x: f64, window_y: f64) -> PatchRssLaw {
        PatchRssLaw::new(&cell_correlations(window_x), &cell_correlations(window_y))
    }

    #[test]
    fn white_cells_follow_chi2_with_thirteen_degrees_of_freedom() {
        let l = law(1.0, 1.0);
        assert!((l.mean - 1.0).abs() < 1e-12, "{l:?}");
        assert!((l.nu - 13.0).abs() < 1e-9, "{l:?}");
    }

    #[test]
    fn the_law_matches_a_monte_carlo_of_correlated_cells() {
        // Cells correlated over a 9 × 11 px window: the Gaussian model's quartile by
        // simulation (independent of this module's algebra) against the law's.
        let l = law(9.0, 11.0);
        let (rx, ry) = (cell_correlations(9.0), cell_correlations(11.0));
        // A 16 × 16 correlation matrix and its Cholesky factor.
        const N: usize = PATCH * PATCH;
        let c = nalgebra::SMatrix::<f64, N, N>::from_fn(|a, b| {
            rx[(a % PATCH).abs_diff(b % PATCH)] * ry[(a / PATCH).abs_diff(b / PATCH)]
        });
        let chol = nalgebra::Cholesky::new(c).expect("positive definite");
        let lo = chol.l();
        let mut gauss = gaussians(0x2545_f491_4f6c_dd1d);
        let mut ratios: Vec<f64> = (0..20_000)
            .map(|_| {
                let e = lo * nalgebra::SVector::<f64, N>::from_fn(|_, _| gauss());
                let mut s = AffineSums::default();
                for a in 0..N {
                    s.add((a % PATCH) as f64, (a / PATCH) as f64, e[a]);
                }
                min_rss(&s).unwrap_or(f64::NAN) / PATCH_DOF
            })
            .collect();
        ratios.sort_by(f64::total_cmp);
        let q25 = ratios[ratios.len() / 4];
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        assert!((mean / l.mean - 1.0).abs() < 0.03, "{mean} {l:?}");
        assert!(
            (q25 / l.lower_quartile() - 1.0).abs() < 0.05,
            "{q25} {}",
            l.lower_quartile()
        );
    }

    #[test]
    fn the_closed_form_rss_is_the_least_squares_one() {
        let mut v = [0.0f32; PATCH * PATCH];
        for (a, d) in v.iter_mut().enumerate() {
            let (x, y) = ((a % PATCH) as f32, (a / PATCH) as f32);
            // A plane far from zero plus a pattern no plane fits.
            *d = 40.0 + 0.3 * x - 0.2 * y + 0.01 * ((a * 7919) % 13) as f32;
        }
        let mut s = AffineSums::default();
        for (a, &d) in v.iter().enumerate() {
            s.add((a % PATCH) as f64, (a / PATCH) as f64, f64::from(d));
        }
        let (got, want) = (full_patch_rss(&v).unwrap(), min_rss(&s).unwrap());
        assert!(
            (got - want).abs() < 1e-9 * want.max(1e-12) + 1e-12,
            "{got} {want}"
        );
        v[5] = f32::NAN;
        assert_eq!(full_patch_rss(&v), None);
        v[5] = 0.0;
        assert_eq!(full_patch_rss(&v), None);
    }

    /// A 640 × 480 Kinect frame of a tilted wall whose disparity error is white Gaussian noise
    /// averaged over a `window` box (the block-matching model, no quantisation), scaled to
    /// `sigma_d_px`.
    fn wall(window: (usize, usize), sigma_d_px: f64, seed: u64) -> (DepthImage, Camera) {
        let cam = Camera::kinect_v1();
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let (bw, bh) = window;
        let (pw, ph) = (w + bw, h + bh);
        let mut gauss = gaussians(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
        let white: Vec<f64> = (0..pw * ph).map(|_| gauss()).collect();
        // The box mean of bw × bh white samples has variance 1/(bw·bh).
        let scale = sigma_d_px * ((bw * bh) as f64).sqrt() / (bw * bh) as f64;
        let fb = cam.sensor.fb();
        let depth = DepthImage::from_image(sl_core::image::Image::from_fn(w, h, |x, y| {
            let mut e = 0.0;
            for yy in y..y + bh {
                e += white[yy * pw + x..yy * pw + x + bw].iter().sum::<f64>();
            }
            let d = 20.0 + 0.01 * x as f64 + 0.004 * y as f64 + scale * e;
            (fb / d) as f32
        }));
        (depth, cam)
    }

    /// The excess the 16-px patches alone read on the cells of the last frame `meter`
    /// measured (`d`, against the Kinect model).
    fn fine_only(meter: &mut NoiseMeter, d: &DepthImage) -> f64 {
        let (wq, hq) = (d.width() / CELL, d.height() / CELL);
        let noise = CellNoise::new(0.07, 8, 9.0, 11.0);
        let cells = std::mem::take(&mut meter.cells);
        patch_reading(
            &mut meter.ratios,
            &cells,
            wq,
            hq,
            noise.var_cell,
            &law(9.0, 11.0),
        )
        .map_or(1.0, |r| r.excess_over(1.0))
    }

    #[test]
    fn a_wider_error_than_the_models_is_seen_at_the_larger_scale() {
        let mut meter = NoiseMeter::new(&PlaneConfig::default());
        let var_model = crate::uncertainty::pixel_variance(0.07, 8);
        // The model's own noise: no excess at either scale.
        let (d, cam) = wall((9, 11), 0.07, 1);
        assert_eq!(meter.measure(&d, &cam).unwrap_or(f64::NAN), 1.0);
        // Twice the model's σ_D over the model's window: the 16-px patches see it.
        let (d, cam) = wall((9, 11), 0.14, 2);
        let s = meter.measure(&d, &cam).unwrap_or(f64::NAN);
        let truth = 0.14f64.powi(2) / var_model;
        assert!((s / truth - 1.0).abs() < 0.2, "{s} vs {truth}");
        // The 32-px patches read the same variance, not significantly more: the 16-px
        // reading (four times the patches) stands.
        assert_eq!(s, fine_only(&mut meter, &d));
        // A wider window (17 × 19 px) at 0.12 px: an affine fit over 16 px absorbs much of
        // it, the 32-px patches see more of it.
        let (d, cam) = wall((17, 19), 0.12, 3);
        let both = meter.measure(&d, &cam).unwrap_or(f64::NAN);
        let fine = fine_only(&mut meter, &d);
        let truth = 0.12f64.powi(2) / var_model;
        assert!(fine < 0.8 * truth, "16 px alone: {fine} vs {truth}");
        assert!(
            both > 1.2 * fine && both < 1.5 * truth,
            "{both} vs {fine}, {truth}"
        );
    }

    #[test]
    fn only_a_clear_excess_counts() {
        let l = law(9.0, 11.0);
        let q = l.lower_quartile();
        assert_eq!(l.reading(q, 1000).excess_over(1.0), 1.0);
        assert_eq!(l.reading(0.5 * q, 1000).excess_over(1.0), 1.0);
        assert_eq!(l.reading(1.03 * q, 1000).excess_over(1.0), 1.0);
        assert!((l.reading(2.0 * q, 1000).excess_over(1.0) - 2.0).abs() < 1e-12);
        // Fewer patches, a larger sampling error.
        assert_eq!(l.reading(1.1 * q, 100).excess_over(1.0), 1.0);
        assert_eq!(l.reading(f64::NAN, 1000).excess_over(1.0), 1.0);
    }
}
