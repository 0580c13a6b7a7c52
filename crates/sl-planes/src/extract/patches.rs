//! Seeds from patches (issue 12): the cell grid is cut into patches of 4×4 cells (16×16
//! pixels); each patch gets an affine fit of its planar cells, and neighbouring patches are
//! merged, most similar pairs first, while one affine function explains the union **as well as
//! the noise model allows**: the increase of the residual sum of squares when two sets share one
//! fit, `ΔRSS = RSS(a ∪ b) − RSS(a) − RSS(b)`, divided by the noise variance of a cell and the
//! correlation inflation `κ` ([`CellNoise`]), is χ² with 3 degrees of freedom for one plane;
//! above its 99.9 % quantile the two are different planes. This is what the LoG cannot see: a
//! crease between a floor and a wall 3 m away bends the disparity by a few hundredths of a pixel
//! per pixel, far below any LoG threshold above the noise, but the affine fits on either side
//! differ by many standard deviations of the fit.
//!
//! A patch is used only when its own fit is planar at the same confidence (its RSS against
//! `χ²` with the effective degrees of freedom `(n − 3)/κ`), so patches straddling a crease or a
//! jump do not bridge two surfaces.

use rayon::prelude::*;

use super::*;
use crate::fit::AffineSums;

/// Side of a patch, cells.
pub(super) const PATCH: usize = 4;

/// What the seeding made of a patch (kept for `explain`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) enum PatchStatus {
    /// Fewer than 12 planar cells.
    #[default]
    TooFewCells,
    /// Its fit's residual exceeds the noise.
    Residual,
    /// Planar.
    Planar,
}
/// Fewest usable cells of a patch (of 16).
const PATCH_MIN_CELLS: f64 = 12.0;
/// Standard-normal quantile of the tests (99.9 %, one-sided).
pub(super) const Z_999: f64 = 3.090_232;
/// The 99.9 % quantile of χ² with 2 degrees of freedom (the `bend` stage's slope test).
pub(super) const CHI2_2_999: f64 = 13.816;
/// The 99.9 % quantile of χ² with 3 degrees of freedom.
const CHI2_3_999: f64 = 16.266;
/// The 99.9 % quantile of χ² with 1 degree of freedom, squared standard-normal units: one
/// pixel's residual is within the noise at the tests' confidence when `r² ≤ CHI2_1_999·σ²`
/// (`|r| ≤ 3.29 σ`).
pub(super) const CHI2_1_999: f64 = 10.828;

/// The disparity noise of one cell (a 4×4-pixel mean) from the sensor model and the
/// correlation of the disparity error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CellNoise {
    /// Variance of one pixel's disparity error, px² (`σ_D² + 1/(12q²)`).
    pub(crate) var_px: f64,
    /// Variance of a cell's mean disparity, px².
    pub(crate) var_cell: f64,
    /// Correlation inflation of sums over cells: `Σ_lags ρ_cell` (1 for white noise), the ratio
    /// of the number of cells to the number of effectively independent samples.
    pub(crate) kappa: f64,
}

impl Default for CellNoise {
    fn default() -> Self {
        Self::new(0.07, 8, 1.0, 1.0)
    }
}

/// `Σ_{i,j<n} ρ(i − j) / n²` for the triangular autocorrelation `ρ(l) = max(0, 1 − |l|/w)` of a
/// box-averaged field (the block-matching window), and the correlation of two such `n`-means
/// `lag` blocks apart.
fn block_mean_cov(n: usize, w: f64, lag: usize) -> f64 {
    let rho = |l: i64| (1.0 - l.unsigned_abs() as f64 / w).max(0.0);
    let mut s = 0.0;
    for i in 0..n as i64 {
        for j in 0..n as i64 {
            s += rho(i - j - (lag * n) as i64);
        }
    }
    s / (n * n) as f64
}

/// The correlation of two cell means `lag` cells apart along an axis whose matching window is
/// `window` pixels wide (`[1, ρ(1), …]`; 1 × 1: white noise, no correlation between cells).
pub(super) fn cell_correlations(window: f64) -> [f64; PATCH] {
    block_correlations(window, CELL)
}

/// [`cell_correlations`] for blocks of `block_px` pixels instead of cells.
pub(super) fn block_correlations(window: f64, block_px: usize) -> [f64; PATCH] {
    let w = window.max(1.0);
    let v0 = block_mean_cov(block_px, w, 0);
    std::array::from_fn(|lag| block_mean_cov(block_px, w, lag) / v0)
}

/// The variance of the mean of a `block_px`-pixel run over that of one pixel, along an axis
/// whose matching window is `window` pixels wide.
pub(super) fn block_variance_factor(window: f64, block_px: usize) -> f64 {
    block_mean_cov(block_px, window.max(1.0), 0)
}

impl CellNoise {
    /// The noise of a 4×4-pixel cell mean for a disparity error of `sigma_d_px` plus the
    /// `1/q` px quantisation (uniform, variance `1/(12q²)`), correlated with the triangular
    /// autocorrelation of a `window_x × window_y` pixel matching window (1 × 1: white noise).
    pub(crate) fn new(sigma_d_px: f64, q: u32, window_x: f64, window_y: f64) -> Self {
        let var_px = crate::uncertainty::pixel_variance(sigma_d_px, q);
        let axis = |w: f64| {
            let w = w.max(1.0);
            let v0 = block_mean_cov(CELL, w, 0);
            // Σ over cell lags of the correlation between cell means (both signs).
            let mut sum = 1.0;
            for lag in 1..64 {
                let c = block_mean_cov(CELL, w, lag) / v0;
                if c <= 0.0 {
                    break;
                }
                sum += 2.0 * c;
            }
            (v0, sum)
        };
        let (vx, kx) = axis(window_x);
        let (vy, ky) = axis(window_y);
        Self {
            var_px,
            var_cell: var_px * vx * vy,
            kappa: kx * ky,
        }
    }

    /// The `p = 99.9 %` quantile of `χ²_ν` divided by `ν` (Wilson–Hilferty), `ν ≥ 0.5`.
    fn chi2_ratio(nu: f64) -> f64 {
        let nu = nu.max(0.5);
        let k = 2.0 / (9.0 * nu);
        (1.0 - k + Z_999 * k.sqrt()).powi(3)
    }

    /// The largest disparity residual of one pixel that the noise explains, px: the 99.9 %
    /// two-sided bound `√(χ²₁(0.999)·(σ_D² + 1/(12q²)))`, 0.26 px for the Kinect's
    /// `σ_D = 0.07 px`, `q = 8` (the pixel's error is the same at every depth in disparity; the
    /// correlation of the error does not change its variance).
    pub(crate) fn pixel_bound_px(&self) -> f64 {
        (CHI2_1_999 * self.var_px).sqrt()
    }

    /// The largest residual of one cell's mean disparity that the noise explains, px (as
    /// [`Self::pixel_bound_px`] for the variance of a cell).
    pub(crate) fn cell_bound_px(&self) -> f64 {
        (CHI2_1_999 * self.var_cell).sqrt()
    }

    /// Whether a patch fit with residual sum of squares `rss` over `n` cells is planar.
    pub(super) fn planar(&self, rss: f64, n: f64) -> bool {
        let nu = (n - 3.0) / self.kappa;
        rss / (n - 3.0) <= self.var_cell * Self::chi2_ratio(nu)
    }

    /// Whether two sets that one affine function explains with the extra residual `d_rss`
    /// are one plane.
    pub(super) fn same(&self, d_rss: f64) -> bool {
        d_rss <= CHI2_3_999 * self.kappa * self.var_cell
    }
}

/// Minimum residual sum of squares of an affine fit (`None` when it has no fit).
pub(super) fn min_rss(s: &AffineSums) -> Option<f64> {
    s.solve().map(|f| s.rss(&f))
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[parent[i as usize] as usize];
        parent[i as usize] = p;
        i = p;
    }
    i
}

/// One row of patches to fit: its index, sums, residuals and statuses.
type PatchRowTask<'a> = (
    usize,
    ((&'a mut [AffineSums], &'a mut [f64]), &'a mut [PatchStatus]),
);

/// The sums and fits of one row `pj` of patches (`sums`, `rss` and `status` are that row):
/// a patch with at least [`PATCH_MIN_CELLS`] cells in `mask` gets the moments of those cells,
/// and its residual sum of squares when its fit is planar (NaN otherwise).
#[allow(clippy::too_many_arguments)]
fn fit_patch_row(
    cells: &[f32],
    mask: &[u8],
    wq: usize,
    pj: usize,
    noise: &CellNoise,
    sums: &mut [AffineSums],
    rss: &mut [f64],
    status: &mut [PatchStatus],
) {
    for (pi, ((s, r_out), st_out)) in sums.iter_mut().zip(rss.iter_mut()).zip(status).enumerate() {
        // A patch with fewer than `PATCH_MIN_CELLS` cells in the mask cannot be used (its
        // sums are never read): skip its sums. After the first refinement pass most patches
        // have no free cell at all.
        let in_mask: usize = (pj * PATCH..(pj + 1) * PATCH)
            .map(|j| {
                let r = &mask[j * wq + pi * PATCH..j * wq + (pi + 1) * PATCH];
                r.iter().filter(|&&m| m != 0).count()
            })
            .sum();
        if (in_mask as f64) < PATCH_MIN_CELLS {
            // (`status` is already `TooFewCells`.)
            continue;
        }
        for j in pj * PATCH..(pj + 1) * PATCH {
            for i in pi * PATCH..(pi + 1) * PATCH {
                let d = cells[j * wq + i];
                if mask[j * wq + i] != 0 && d.is_finite() && d > 0.0 {
                    s.add(i as f64, j as f64, f64::from(d));
                }
            }
        }
        let mut st = PatchStatus::TooFewCells;
        if s.n >= PATCH_MIN_CELLS
            && let Some(r) = min_rss(s)
        {
            st = PatchStatus::Residual;
            if noise.planar(r, s.n) {
                *r_out = r;
                st = PatchStatus::Planar;
            }
        }
        *st_out = st;
    }
}

impl PlaneExtractor {
    /// Seeds the planes from merged patches (see the module docs): sets of at least `min`
    /// cells become planes, their planar cells labelled. `free` restricts the cells to the
    /// planar cells that the last refinement pass left unassigned.
    #[inline(never)]
    pub(super) fn seed_from_patches(&mut self, wq: usize, hq: usize, min: usize, free: bool) {
        let noise = self.noise;
        let mask: &[u8] = if free {
            &self.free_cells
        } else {
            &self.cell_planar
        };
        let (wp, hp) = (wq / PATCH, hq / PATCH);
        let np = wp * hp;
        let sums = &mut self.patch_sums;
        sums.clear();
        sums.resize(np, AffineSums::default());
        let rss = &mut self.patch_rss;
        rss.clear();
        rss.resize(np, f64::NAN);
        // What the first seeding made of each patch is kept (for `explain`); the reseeding's
        // goes to scratch.
        let status = if free {
            &mut self.patch_status_reseed
        } else {
            &mut self.patch_status
        };
        status.clear();
        status.resize(np, PatchStatus::TooFewCells);
        let parallel = rayon::current_num_threads() > 1;
        // Each patch's sums and fit (patches are independent: one patch row per task).
        let cells = &self.cell_disparity;
        let patch_row = |(pj, ((srow, rrow), st)): PatchRowTask<'_>| {
            fit_patch_row(cells, mask, wq, pj, &noise, srow, rrow, st);
        };
        if parallel {
            sums.par_chunks_mut(wp)
                .zip(rss.par_chunks_mut(wp))
                .zip(status.par_chunks_mut(wp))
                .enumerate()
                .for_each(patch_row);
        } else {
            sums.chunks_mut(wp)
                .zip(rss.chunks_mut(wp))
                .zip(status.chunks_mut(wp))
                .enumerate()
                .for_each(patch_row);
        }
        // Edges between usable 4-neighbours, by increasing ΔRSS.
        let edges = &mut self.patch_edges;
        edges.clear();
        let (sums_r, rss_r): (&[AffineSums], &[f64]) = (sums, rss);
        let edge_row = |pj: usize, out: &mut Vec<(f32, u32, u32)>| {
            out.clear();
            for p in pj * wp..(pj + 1) * wp {
                if rss_r[p].is_nan() {
                    continue;
                }
                let (pi, pj) = (p % wp, p / wp);
                for q in [
                    (pi + 1 < wp).then_some(p + 1),
                    (pj + 1 < hp).then_some(p + wp),
                ]
                .into_iter()
                .flatten()
                {
                    if rss_r[q].is_nan() {
                        continue;
                    }
                    let mut u = sums_r[p];
                    u.merge(&sums_r[q]);
                    if let Some(ru) = min_rss(&u) {
                        let d = ru - rss_r[p] - rss_r[q];
                        if noise.same(d) {
                            out.push((d as f32, p as u32, q as u32));
                        }
                    }
                }
            }
        };
        let row_edges = &mut self.patch_row_edges;
        if row_edges.len() < hp {
            row_edges.resize_with(hp, Vec::new);
        }
        if parallel {
            row_edges[..hp]
                .par_iter_mut()
                .enumerate()
                .for_each(|(pj, out)| edge_row(pj, out));
        } else {
            for (pj, out) in row_edges[..hp].iter_mut().enumerate() {
                edge_row(pj, out);
            }
        }
        for e in &row_edges[..hp] {
            edges.extend_from_slice(e);
        }
        edges.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let parent = &mut self.patch_parent;
        parent.clear();
        parent.extend(0..np as u32);
        for &(_, p, q) in edges.iter() {
            let (a, b) = (find(parent, p), find(parent, q));
            if a == b {
                continue;
            }
            let (a, b) = (a as usize, b as usize);
            let mut u = sums[a];
            u.merge(&sums[b]);
            let Some(ru) = min_rss(&u) else { continue };
            if noise.same(ru - rss[a] - rss[b]) {
                // Union by size: the larger root stays.
                let (keep, gone) = if sums[a].n >= sums[b].n {
                    (a, b)
                } else {
                    (b, a)
                };
                parent[gone] = keep as u32;
                sums[keep] = u;
                rss[keep] = ru;
            }
        }
        // Roots with enough cells become planes.
        let plane_of = &mut self.patch_plane;
        plane_of.clear();
        plane_of.resize(np, 0);
        let boxes = &mut self.patch_box;
        boxes.clear();
        boxes.resize(np, [u32::MAX, u32::MAX, 0, 0]);
        for (p, rp) in rss.iter().enumerate() {
            if rp.is_nan() {
                continue;
            }
            let r = find(parent, p as u32) as usize;
            let (pi, pj) = (p % wp, p / wp);
            grow(&mut boxes[r], pi * PATCH, (pi + 1) * PATCH - 1, pj * PATCH);
            grow(
                &mut boxes[r],
                pi * PATCH,
                (pi + 1) * PATCH - 1,
                (pj + 1) * PATCH - 1,
            );
        }
        for p in 0..np {
            if rss[p].is_nan() || parent[p] as usize != p || sums[p].n < min as f64 {
                continue;
            }
            if self.planes.len() >= MAX_PLANES {
                break;
            }
            let Some(f) = sums[p].solve() else { continue };
            self.planes.push(Cand {
                f,
                sums: sums[p],
                bbox: boxes[p],
                alive: true,
                into: NONE,
            });
            plane_of[p] = self.planes.len() as u16;
        }
        for p in 0..np {
            if rss[p].is_nan() {
                continue;
            }
            let lab = plane_of[find(parent, p as u32) as usize];
            if lab == 0 {
                continue;
            }
            let (pi, pj) = (p % wp, p / wp);
            for j in pj * PATCH..(pj + 1) * PATCH {
                for i in pi * PATCH..(pi + 1) * PATCH {
                    let d = self.cell_disparity[j * wq + i];
                    if mask[j * wq + i] != 0 && d.is_finite() && d > 0.0 {
                        self.cell_labels[j * wq + i] = lab;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_cells_average_sixteen_pixels() {
        let n = CellNoise::new(0.07, 8, 1.0, 1.0);
        let var_px = 0.07f64.powi(2) + 1.0 / (12.0 * 64.0);
        assert!((n.var_cell - var_px / 16.0).abs() < 1e-12);
        assert!((n.kappa - 1.0).abs() < 1e-12);
    }

    #[test]
    fn correlated_noise_keeps_variance_and_inflates_sums() {
        let w = CellNoise::new(0.07, 8, 1.0, 1.0);
        let c = CellNoise::new(0.07, 8, 9.0, 11.0);
        // A 9×11 window barely averages out over 4×4 pixels, and neighbouring cells share it.
        assert!(c.var_cell > 8.0 * w.var_cell, "{c:?}");
        assert!(c.kappa > 3.0 && c.kappa < 12.0, "{c:?}");
    }

    #[test]
    fn chi2_quantile_is_close() {
        // χ²₃(0.999) = 16.27, χ²₁₀(0.999) = 29.59.
        assert!((CellNoise::chi2_ratio(3.0) * 3.0 - 16.27).abs() < 0.5);
        assert!((CellNoise::chi2_ratio(10.0) * 10.0 - 29.59).abs() < 0.5);
    }
}
