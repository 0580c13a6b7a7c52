//! Pieces of one bent surface joined after the final pass (issue 12).
//!
//! A real Kinect-class frame is not affine in disparity over a whole surface: the sensor's
//! low-frequency distortion bends it (Herrera et al., Smisek et al.). The extractor's planes
//! are affine and a pixel is labelled only within `τ` of one, so a large bent surface leaves
//! its rims beyond `τ`, and they come out as planes of their own a few degrees off the surface:
//! corner pieces of a simulated wall with the distortion on, bands on a real desk.
//!
//! Two planes are pieces of one bent surface when
//! - they share a border on the cell grid of at least [`MIN_SHARED_CELLS`] cells;
//! - their affine functions meet along it: the mean gap `|f_a − f_b|` at the shared cell
//!   borders is at most `2τ` (a pixel on either side is within `τ` of its own plane, and one
//!   continuous surface runs through both; a depth step between two surfaces is larger);
//! - the surface's gradient is continuous across the border: the disparity slopes of the two
//!   pieces *at the border* (affine fits of their cells within [`STRIP_CELLS`] cells of it)
//!   agree within the noise model (`χ²₂` at 99.9 % with the cells' noise, inflated by the
//!   correlation of the block-matching error, as the seeding's tests) once what the bend can
//!   turn between the two strips (`κ` times their distance) is taken off the difference; and
//!   the strips must be long and quiet enough for that test to see a crease at their depth
//!   (two surfaces meeting at a right angle at depth `Z` turn the slope by about
//!   `B/Z = D/f`): a border of a few cells far away proves nothing and joins nothing. A crease
//!   between two surfaces — the floor and a wall, two walls meeting in a far corner — turns
//!   the slope at the border by `B·|Δ(n/d)|` (0.015 px/px for two walls 5 m away), and is
//!   kept;
//! - the turn between the pieces' whole fits is no more than the distortion can make between
//!   their centroids, `|∇f_a − ∇f_b| ≤ κ·|c_a − c_b|` (for a quadratic bend of largest
//!   curvature `κ` a piece's least-squares slope is the bend's gradient at its centroid), with
//!   `κ` = [`PlaneConfig::bend_px_per_px2`] at 585 px, scaled as `585/f`: a distortion that is
//!   a fixed function of the viewing direction, in disparity pixels (`∝ f`), has a curvature
//!   in px/px² that scales as `1/f`.
//!
//! The joined pieces take the label of the piece with the most pixels. The plane stays that
//! piece's own fit (its parameters, RMS and centroid): the distortion grows towards the image
//! border, where the rims are, and a fit of the union would tilt with how much of the rim is in
//! view. Its pixel count is the union's.

use super::patches::CHI2_2_999;
use super::*;
use crate::fit::AffineSums;

/// Focal length of the frames on which the default [`PlaneConfig::bend_px_per_px2`] was
/// measured (7-Scenes' Kinect), pixels.
pub(super) const BEND_MEASURED_AT_FOCAL_PX: f64 = 585.0;

/// Cells of shared border two planes need to be joined (8 pixels: about one matching window).
const MIN_SHARED_CELLS: usize = 2;

/// Depth of the strip on each side of a shared border whose cells give each piece's slope at
/// the border, cells (16 pixels: nearly two matching windows of a Kinect).
pub(super) const STRIP_CELLS: usize = 4;

/// Most border cells whose strip neighbourhoods are visited per pair: a longer border is
/// sampled every `n`-th cell in scan order (each neighbourhood is 9 cells wide, so a
/// straight border stays covered up to 288 cells; at most about 5,000 cell visits per pair).
const MAX_BORDER_SAMPLES: usize = 32;

/// Most planes for which the borders are grouped by pair with a counting sort (a table of
/// `n²` counters).
const MAX_COUNTING_PLANES: usize = 256;

/// The full-resolution pixel coordinates of the centre of cell `k` of a grid `wq` cells wide:
/// cell `(i, j)` is centred on pixel `(4i + 1.5, 4j + 1.5)` (as for `cell_to_full`).
pub(super) fn cell_centre_px(k: usize, wq: usize) -> (f64, f64) {
    (
        (CELL * (k % wq)) as f64 + 1.5,
        (CELL * (k / wq)) as f64 + 1.5,
    )
}

/// `|f_a − f_b|` at the border between 4-neighbouring cells `ca` and `cb` of a grid `wq` cells
/// wide (halfway between their centres), px.
pub(super) fn border_gap(
    fa: &DisparityAffine,
    fb: &DisparityAffine,
    ca: usize,
    cb: usize,
    wq: usize,
) -> f64 {
    let ((xa, ya), (xb, yb)) = (cell_centre_px(ca, wq), cell_centre_px(cb, wq));
    let (x, y) = ((xa + xb) / 2.0, (ya + yb) / 2.0);
    (fa.eval(x, y) - fb.eval(x, y)).abs()
}

/// Calls `f(k, k')` for every pair of 4-neighbouring cells of the grid `cl` (`wq × hq`) that
/// may be a border between two planes: the right neighbours row by row, then the ones below.
/// Rows are compared 16 cells at a time and a chunk with no two different labelled cells is
/// skipped whole (most of the grid); `f` sees the other pairs of a chunk too and must check.
pub(super) fn for_each_cell_border(
    cl: &[u16],
    wq: usize,
    hq: usize,
    f: &mut impl FnMut(usize, usize),
) {
    let mut scan = |from: usize, to: usize, step: usize| {
        let mut k = from;
        while k < to {
            let end = (k + 16).min(to);
            let border = cl[k..end]
                .iter()
                .zip(&cl[k + step..end + step])
                .fold(false, |m, (&a, &b)| m | ((a != b) & (a != 0) & (b != 0)));
            if border {
                (k..end).for_each(|c| f(c, c + step));
            }
            k = end;
        }
    };
    for j in 0..hq {
        scan(j * wq, (j + 1) * wq - 1, 1);
    }
    scan(0, wq * hq.saturating_sub(1), wq);
}

/// One border between 4-neighbouring cells of two planes: the planes' indices (lower first),
/// the cell of each, and the gap between their affine functions there.
#[derive(Debug, Clone, Copy)]
pub(super) struct Seam {
    a: u16,
    b: u16,
    cell_a: u32,
    cell_b: u32,
    gap_px: f32,
}

impl PlaneExtractor {
    /// Joins the planes of the final pass that are pieces of one bent surface (see the module
    /// documentation): `joined_into[i]` names the plane whose label plane `i`'s pixels take
    /// (itself when not joined), and the root's pixel count and row range include its pieces'.
    /// `fx` is the focal length of the grid being extracted.
    pub(super) fn join_bent_pieces(&mut self, wq: usize, hq: usize, fx: f64, tau: f64) {
        let n = self.final_sums.len();
        self.joined_into.clear();
        self.joined_into.extend((0..n).map(|i| i as u16));
        let kappa = self.cfg.bend_px_per_px2 * BEND_MEASURED_AT_FOCAL_PX / fx;
        if n < 2
            || wq == 0
            || hq == 0
            || kappa <= 0.0
            || !kappa.is_finite()
            || self.cell_labels.len() < wq * hq
            || self.cell_disparity.len() < wq * hq
        {
            return;
        }
        let min_pixels = self.cfg.min_pixels;
        self.join_fits.clear();
        self.join_fits.extend(self.final_sums.iter().map(|a| {
            if a.pixels < min_pixels || a.sums.n < 3.0 {
                return None;
            }
            let f = a.sums.solve()?;
            Some((f, a.sums.sx / a.sums.n, a.sums.sy / a.sums.n))
        }));
        self.collect_seams(wq, hq);
        if self.join_seams.is_empty() {
            return;
        }
        // Candidate pairs, the most alike (slope change per pixel of distance) first.
        self.join_pairs.clear();
        let fits = &self.join_fits;
        let mut start = 0;
        for run in self.join_seams.chunk_by(|s, t| (s.a, s.b) == (t.a, t.b)) {
            let range = start..start + run.len();
            start = range.end;
            let (a, b) = (run[0].a as usize, run[0].b as usize);
            let mean_gap = run.iter().map(|s| f64::from(s.gap_px)).sum::<f64>() / run.len() as f64;
            if run.len() < MIN_SHARED_CELLS || mean_gap > 2.0 * tau {
                continue;
            }
            let (Some((fa, xa, ya)), Some((fb, xb, yb))) = (fits[a], fits[b]) else {
                continue;
            };
            let turn = (fa.a - fb.a).hypot(fa.b - fb.b);
            let dist = (xa - xb).hypot(ya - yb);
            if turn <= kappa * dist {
                self.join_pairs
                    .push((turn / dist.max(1.0), a as u16, b as u16, range));
            }
        }
        // The gradient's continuity across each candidate's border.
        let mut pairs = std::mem::take(&mut self.join_pairs);
        pairs.retain(|(_, a, b, range)| {
            self.slopes_meet_at_the_border(*a, *b, range.clone(), wq, hq, kappa, fx)
        });
        pairs.sort_unstable_by(|p, q| p.0.total_cmp(&q.0));
        // Union-find; a set's root is its piece with the most pixels.
        let find = |parent: &[u16], mut x: u16| {
            while parent[x as usize] != x {
                x = parent[x as usize];
            }
            x
        };
        for (_, a, b, _) in &pairs {
            let (ra, rb) = (find(&self.joined_into, *a), find(&self.joined_into, *b));
            if ra == rb {
                continue;
            }
            let key = |r: u16| (self.final_sums[r as usize].pixels, std::cmp::Reverse(r));
            let (root, child) = if key(ra) >= key(rb) {
                (ra, rb)
            } else {
                (rb, ra)
            };
            self.joined_into[child as usize] = root;
        }
        self.join_pairs = pairs;
        for i in 0..n {
            let r = find(&self.joined_into, i as u16);
            self.joined_into[i] = r;
            if r as usize != i {
                let child = self.final_sums[i];
                let root = &mut self.final_sums[r as usize];
                root.pixels += child.pixels;
                root.y0 = root.y0.min(child.y0);
                root.y1 = root.y1.max(child.y1);
            }
        }
    }

    /// Every border between 4-neighbouring cells of two planes with fits, with the gap between
    /// the two affine functions there, sorted by pair (`join_seams`). Rows are compared 16
    /// cells at a time and runs of equal labels skipped (most of the grid).
    fn collect_seams(&mut self, wq: usize, hq: usize) {
        self.join_seams.clear();
        let (cl, fits, seams) = (&self.cell_labels, &self.join_fits, &mut self.join_seams);
        let mut push = |ca: usize, cb: usize| {
            let (a, b) = (cl[ca], cl[cb]);
            if a == 0 || b == 0 || a == b {
                return;
            }
            let fit = |l: u16| fits.get(l as usize - 1).copied().flatten();
            let (Some((fa, ..)), Some((fb, ..))) = (fit(a), fit(b)) else {
                return;
            };
            let gap_px = border_gap(&fa, &fb, ca, cb, wq) as f32;
            let (a, b, ca, cb) = if a < b {
                (a, b, ca, cb)
            } else {
                (b, a, cb, ca)
            };
            seams.push(Seam {
                a: a - 1,
                b: b - 1,
                cell_a: ca as u32,
                cell_b: cb as u32,
                gap_px,
            });
        };
        for_each_cell_border(cl, wq, hq, &mut push);
        if self.join_seams.is_empty() {
            return;
        }
        // Grouped by pair (a counting sort: stable, so each pair's borders stay in scan order,
        // the right neighbours row by row, then the ones below; a sort beyond 256 planes).
        let n = self.join_fits.len();
        if n > MAX_COUNTING_PLANES {
            self.join_seams
                .sort_by_key(|s| (s.a, s.b, s.cell_a.min(s.cell_b)));
            return;
        }
        self.join_pair_start.clear();
        self.join_pair_start.resize(n * n + 1, 0);
        for s in &self.join_seams {
            self.join_pair_start[s.a as usize * n + s.b as usize + 1] += 1;
        }
        for i in 1..self.join_pair_start.len() {
            self.join_pair_start[i] += self.join_pair_start[i - 1];
        }
        self.join_seams_by_pair.clear();
        self.join_seams_by_pair
            .resize(self.join_seams.len(), self.join_seams[0]);
        for s in &self.join_seams {
            let slot = &mut self.join_pair_start[s.a as usize * n + s.b as usize];
            self.join_seams_by_pair[*slot as usize] = *s;
            *slot += 1;
        }
        std::mem::swap(&mut self.join_seams, &mut self.join_seams_by_pair);
    }

    /// Whether planes `a` and `b` (indices) have the same disparity slope at their shared
    /// border `join_seams[range]`: affine fits of each plane's cells within [`STRIP_CELLS`]
    /// of the border (of at most [`MAX_BORDER_SAMPLES`] of its cells, evenly spaced along
    /// it), their slopes' difference, less the turn `κ·d` a bend makes between the
    /// strips' centroids `d` apart, tested with `χ²₂` (99.9 %) under the cells' noise
    /// (variance inflated by the correlation of the matching error).
    #[allow(clippy::too_many_arguments)]
    fn slopes_meet_at_the_border(
        &mut self,
        a: u16,
        b: u16,
        range: std::ops::Range<usize>,
        wq: usize,
        hq: usize,
        kappa: f64,
        fx: f64,
    ) -> bool {
        self.join_mark.resize(wq * hq, u32::MAX);
        self.join_stamp = self.join_stamp.wrapping_add(1);
        let stamp = self.join_stamp;
        let mut sums = [AffineSums::default(); 2];
        let (r, cl, cd) = (STRIP_CELLS, &self.cell_labels, &self.cell_disparity);
        let mark = &mut self.join_mark;
        let border = &self.join_seams[range];
        let step = border.len().div_ceil(MAX_BORDER_SAMPLES).max(1);
        for s in border.iter().step_by(step) {
            for (side, (cell, label)) in [(s.cell_a, a), (s.cell_b, b)].into_iter().enumerate() {
                let (ci, cj) = (cell as usize % wq, cell as usize / wq);
                let (i0, i1) = (ci.saturating_sub(r), (ci + r).min(wq - 1));
                for j in cj.saturating_sub(r)..=(cj + r).min(hq - 1) {
                    for k in j * wq + i0..=j * wq + i1 {
                        if cl[k] != label + 1 || mark[k] == stamp {
                            continue;
                        }
                        mark[k] = stamp;
                        let d = f64::from(cd[k]);
                        if d.is_finite() {
                            let (x, y) = cell_centre_px(k, wq);
                            sums[side].add(x, y, d);
                        }
                    }
                }
            }
        }
        let (Some(fa), Some(fb)) = (sums[0].solve(), sums[1].solve()) else {
            return false;
        };
        // Slope covariance of each strip's fit: κ_corr·σ²_cell·S⁻¹.
        let var = self.noise.kappa * self.noise.var_cell;
        let cov = |s: &AffineSums| {
            let [sxx, sxy, syy] = s.slope_information();
            let det = sxx * syy - sxy * sxy;
            (det > 0.0).then(|| [var * syy / det, -var * sxy / det, var * sxx / det])
        };
        let (Some(ca), Some(cb)) = (cov(&sums[0]), cov(&sums[1])) else {
            return false;
        };
        // The bend may turn the slope by up to κ·(distance between the strips): that much of
        // the difference is taken off before the noise test.
        let dist = (sums[0].sx / sums[0].n - sums[1].sx / sums[1].n)
            .hypot(sums[0].sy / sums[0].n - sums[1].sy / sums[1].n);
        let (ga, gb) = (fa.a - fb.a, fa.b - fb.b);
        let turn = ga.hypot(gb);
        let shrink = if turn > 0.0 {
            (turn - kappa * dist).max(0.0) / turn
        } else {
            0.0
        };
        let (ga, gb) = (ga * shrink, gb * shrink);
        let (sxx, sxy, syy) = (ca[0] + cb[0], ca[1] + cb[1], ca[2] + cb[2]);
        let det = sxx * syy - sxy * sxy;
        // The test must be able to see a crease: two surfaces at the border's depth `Z`
        // meeting at a right angle turn the slope by about `B/Z = D/f` px/px (two walls in a
        // corner by twice that, the floor below a wall by `B/h`). Strips too short or too
        // noisy for that (a border of a few cells far away) prove nothing, and nothing is
        // joined.
        let d_border = (sums[0].sd + sums[1].sd) / (sums[0].n + sums[1].n);
        if det <= 0.0 || CHI2_2_999 * (sxx + syy) > (d_border / fx).powi(2) {
            return false;
        }
        let chi2 = (syy * ga * ga - 2.0 * sxy * ga * gb + sxx * gb * gb) / det;
        chi2 <= CHI2_2_999
    }
}
