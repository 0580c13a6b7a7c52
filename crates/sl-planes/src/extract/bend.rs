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
//!   continuous surface runs through both; a step of more than `2τ` between two surfaces
//!   fails here, a smaller one the step test below);
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
//! - no step at the border is larger than one plane holds: the mean difference of the two
//!   cells of each border pair, less the strips' slope over the 4 px between them, is at most
//!   `2·(τ − √(χ²₁·σ²_px))` (a plane through the border then holds both sides' pixels within
//!   `τ` at 99.9 % with the frame's pixel noise; 0.48 px for a Kinect at its model's noise)
//!   or not beyond it by more than its own noise (`χ²₁`, 99.9 %). The pieces' fits can be
//!   parallel and `2τ` apart with no bend at all — a lid on a box, a picture on a wall, a
//!   keyboard on a desk — and a step is what tells those from the pieces of one surface. Two
//!   pieces with such a step are never put into one set through a third piece that meets both;
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

use super::patches::{CHI2_1_999, CHI2_2_999};
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

/// The root of `x`'s set in the forest `parent`.
fn find_root(parent: &[u16], mut x: u16) -> u16 {
    while parent[x as usize] != x {
        x = parent[x as usize];
    }
    x
}

/// Joins the sets of `parent` (a forest, each piece its own set to begin with) along `pairs`
/// in their order, the root of each union being the one with the larger `key`; a union that
/// would put the two pieces of a pair in `apart` into one set is skipped (a step between two
/// pieces is not bridged by a third that meets both).
fn join_sets<K: Ord>(
    parent: &mut [u16],
    pairs: impl Iterator<Item = (u16, u16)>,
    apart: &[(u16, u16)],
    key: impl Fn(u16) -> K,
) {
    for (a, b) in pairs {
        let (ra, rb) = (find_root(parent, a), find_root(parent, b));
        if ra == rb {
            continue;
        }
        let bridged = apart.iter().any(|&(x, y)| {
            let (rx, ry) = (find_root(parent, x), find_root(parent, y));
            (rx == ra && ry == rb) || (rx == rb && ry == ra)
        });
        if bridged {
            continue;
        }
        let (root, child) = if key(ra) >= key(rb) {
            (ra, rb)
        } else {
            (rb, ra)
        };
        parent[child as usize] = root;
    }
}

/// What the border between two candidate pieces says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Border {
    /// One continuous surface runs through it: the pieces are joined.
    Meets,
    /// Nothing proved either way (strips too short or too noisy), or the slope turns there (a
    /// crease): not joined.
    Unproven,
    /// A step larger than one plane holds: two surfaces, never joined, not even through a
    /// third piece.
    Steps,
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
        self.join_apart.clear();
        pairs.retain(|(_, a, b, range)| {
            match self.pieces_meet_at_the_border(*a, *b, range.clone(), wq, hq, kappa, fx, tau) {
                Border::Meets => true,
                Border::Unproven => false,
                Border::Steps => {
                    self.join_apart.push((*a, *b));
                    false
                }
            }
        });
        pairs.sort_unstable_by(|p, q| p.0.total_cmp(&q.0));
        // A set's root is its piece with the most pixels.
        let sums = &self.final_sums;
        join_sets(
            &mut self.joined_into,
            pairs.iter().map(|p| (p.1, p.2)),
            &self.join_apart,
            |r| (sums[r as usize].pixels, std::cmp::Reverse(r)),
        );
        self.join_pairs = pairs;
        for i in 0..n {
            let r = find_root(&self.joined_into, i as u16);
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
    fn pieces_meet_at_the_border(
        &mut self,
        a: u16,
        b: u16,
        range: std::ops::Range<usize>,
        wq: usize,
        hq: usize,
        kappa: f64,
        fx: f64,
        tau: f64,
    ) -> Border {
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
            return Border::Unproven;
        };
        // Slope covariance of each strip's fit: κ_corr·σ²_cell·S⁻¹.
        let var = self.noise.kappa * self.noise.var_cell;
        let cov = |s: &AffineSums| {
            let [sxx, sxy, syy] = s.slope_information();
            let det = sxx * syy - sxy * sxy;
            (det > 0.0).then(|| [var * syy / det, -var * sxy / det, var * sxx / det])
        };
        let (Some(ca), Some(cb)) = (cov(&sums[0]), cov(&sums[1])) else {
            return Border::Unproven;
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
            return Border::Unproven;
        }
        let chi2 = (syy * ga * ga - 2.0 * sxy * ga * gb + sxx * gb * gb) / det;
        if chi2 > CHI2_2_999 {
            return Border::Unproven;
        }
        // No step at the border larger than one plane holds: the mean disparity of the two
        // cells of each border pair differs by the surface's slope over the 4 px between them
        // (the strips' mean slope), and by the step between the pieces. One affine surface
        // through the border holds both sides' pixels within `τ` (at 99.9 %, the frame's pixel
        // noise) while the step is at most `2·(τ − √(χ²₁·σ²_px))` (0.48 px for a Kinect at
        // its model's noise); a step beyond that by more than its own noise is two surfaces
        // (a lid on a box, a keyboard on a desk), however well their slopes agree.
        let (gx, gy) = ((fa.a + fb.a) / 2.0, (fa.b + fb.b) / 2.0);
        let (mut sum, mut count) = (0.0, 0.0);
        for s in border {
            let (da, db) = (
                f64::from(cd[s.cell_a as usize]),
                f64::from(cd[s.cell_b as usize]),
            );
            if !(da.is_finite() && db.is_finite()) {
                continue;
            }
            let ((xa, ya), (xb, yb)) = (
                cell_centre_px(s.cell_a as usize, wq),
                cell_centre_px(s.cell_b as usize, wq),
            );
            sum += db - da - gx * (xb - xa) - gy * (yb - ya);
            count += 1.0;
        }
        if count == 0.0 {
            return Border::Unproven;
        }
        let step_px = (sum / count).abs();
        let largest = 2.0 * (tau - self.noise.pixel_bound_px());
        let beyond = step_px - largest;
        // Each difference has the noise of two cells (their positive correlation only lowers
        // it); the differences along a border are correlated as sums of cells are.
        let var_step = 2.0 * (var / count).min(self.noise.var_cell);
        if beyond <= 0.0 || beyond * beyond <= CHI2_1_999 * var_step {
            Border::Meets
        } else {
            Border::Steps
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pieces join along their pairs, the larger piece the root; two pieces with a step between
    /// them stay apart even when a third piece meets both (and then joins only the first it
    /// meets).
    #[test]
    fn a_step_is_not_bridged_by_a_piece_that_meets_both_sides() {
        let pixels = [100usize, 50, 30, 10];
        let key = |r: u16| pixels[r as usize];
        let mut parent: Vec<u16> = (0..4).collect();
        join_sets(&mut parent, [(0, 2), (2, 1), (3, 1)].into_iter(), &[], key);
        let roots: Vec<u16> = (0..4).map(|i| find_root(&parent, i)).collect();
        assert_eq!(roots, [0, 0, 0, 0]);
        // 0 and 1 have a step between them: 2 joins 0 first, then cannot join 1; 3 joins 1.
        let mut parent: Vec<u16> = (0..4).collect();
        join_sets(
            &mut parent,
            [(0, 2), (2, 1), (3, 1)].into_iter(),
            &[(0, 1)],
            key,
        );
        let roots: Vec<u16> = (0..4).map(|i| find_root(&parent, i)).collect();
        assert_eq!(roots, [0, 1, 0, 1]);
        // The same with the pairs in the other order: 2 joins 1, the larger.
        let mut parent: Vec<u16> = (0..4).collect();
        join_sets(
            &mut parent,
            [(2, 1), (0, 2), (3, 1)].into_iter(),
            &[(1, 0)],
            key,
        );
        let roots: Vec<u16> = (0..4).map(|i| find_root(&parent, i)).collect();
        assert_eq!(roots, [0, 1, 1, 1]);
    }
}
