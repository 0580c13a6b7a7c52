//! Pieces of a neighbouring surface that a plane took in, given back (issue 12's residual
//! structure test).
//!
//! The final pass gives a plane every pixel within `τ` of it, and a pixel of an unlabelled cell
//! beside it when it is within the pixel's noise. Far away, a slightly raised or tilted
//! neighbour (a sheet on a worktop, an object on a tray, the strip of a worktop below a
//! standing picture) is within both of them, and a few hundred of its pixels along the plane's
//! border tilt a plane of a few thousand pixels by several degrees; in the next frame the
//! same plane takes in a different piece, or none, and is not found again. Its residual is
//! not white there: the piece sits off the plane by more than the noise allows over its whole
//! area. A surface bent by the sensor's distortion is not affine either, but it bends
//! smoothly, and the whole surface takes part.
//!
//! The test, on each plane's labelled pixels of every [`SAMPLE_ROW_STEP`]-th row and every
//! [`X_STEP`]-th column, averaged over [`BLOCK`] × [`BLOCK`]-pixel blocks:
//!
//! 1. A quadratic surface (6 parameters) is fitted to the blocks' mean residuals against the
//!    plane's affine fit, each block weighted by the inverse variance of its mean under the
//!    noise model: the pixel variance `σ_D² + 1/(12q²)` (times the frame's measured noise
//!    scale), correlated over the block-matching window with the model's triangular
//!    autocorrelation (`uncertainty`), so a block of 8 samples has `0.6·σ²`, not `σ²/8`. The
//!    quadratic takes the smooth bend; what it cannot take is local.
//! 2. Each block's residual from the quadratic, in units of its standard deviation, is tested
//!    against the one-sided 99.9 % quantile of the normal distribution (as every test of the
//!    extractor). The blocks beyond it are outliers; the quadratic is fitted again without
//!    them and the blocks tested again.
//! 3. **Off its surroundings too.** The distortion of real frames is not quadratic over a whole
//!    wall: it ripples over a few hundred pixels (TUM's desk came out with blocks of 10,000
//!    pixels beyond the quadratic's bound). A block counts as off only where it is also off the
//!    median of the plane's blocks within [`LOCAL_RADIUS`] blocks by as much (in units of the
//!    difference's deviation): that median follows a ripple (exactly, for a linear trend
//!    across the window), and a neighbour's piece smaller than half the window does not move
//!    it. So the stage gives back pieces of up to about 2,500 pixels (less along the image
//!    border, which halves the window), and none of a smoothly rippled surface.
//!    (Scaling the units by each plane's own robust spread of them instead, tried first, left
//!    almost every piece in: the planes that took a neighbour in are the ones with a wide
//!    spread.)
//! 4. The 4-connected sets of blocks off on the same side, seeded beyond the 99.9 % quantile
//!    and grown over the adjacent blocks beyond the 99 % quantile (a hysteresis threshold: a
//!    neighbour's rim shares its blocks with the plane's own pixels), are pieces. A piece is
//!    given back (its pixels left unlabelled, the plane refitted without them) when it has at
//!    least `min_piece_pixels` of the plane's pixels (a single block beyond the quantile is
//!    what the noise gives one block in a thousand), at most half of the plane's pixels, and
//!    leaves the plane at least `min_pixels` (a plane that is mostly off its own fit is the
//!    crease test's case, not this one's).
//!
//! Measured on the real sequences and the simulated rooms in docs/bench/README.md, session 75;
//! it is off by default (`PlaneConfig::give_back_taken_in`) for its cost and its small effect.
//!
//! Written by hand: the test is specific to the extractor's labels and noise model.

use super::patches::Z_999;
use super::*;
use crate::quadratic::QuadraticMoments;
#[cfg(test)]
use sl_core::DisparityImage;

/// Side of a test block, pixels.
pub(super) const BLOCK: usize = 8;

/// Columns sampled in a block's sample rows (every second pixel: pixels 2 apart are correlated
/// through the 9-pixel-wide matching window, so every pixel would add little).
pub(super) const X_STEP: usize = 2;

/// Samples of a full block.
const MAX_BLOCK_SAMPLES: usize = (BLOCK / X_STEP) * (BLOCK / SAMPLE_ROW_STEP);

/// Fewest samples of a block for its mean to enter the test (of 8 on a full block).
const MIN_BLOCK_SAMPLES: u16 = 3;

/// Fewest blocks a plane needs to be tested (well above the quadratic's 6 parameters).
const MIN_BLOCKS: usize = 24;

/// Standard-normal quantile (99 %, one-sided) over which a block beside a piece joins it: a
/// piece is seeded by blocks beyond the 99.9 % quantile (one test per block of the plane) and
/// grows over the adjacent blocks off on the same side beyond this one (a test per block at
/// the piece's edge), as a hysteresis threshold, so that the rim of a neighbour, whose blocks
/// also hold some of the plane's own pixels, goes with it.
const Z_99: f64 = 2.326_348;

/// Radius of a block's surroundings for [`off_its_surroundings`], blocks (9 × 9 blocks, 72
/// pixels: eight matching windows across, and a piece of up to about 40 blocks, 2,500 pixels,
/// fills less than half of it).
const LOCAL_RADIUS: usize = 4;

/// Step between the surrounding blocks [`off_its_surroundings`] reads (every second block
/// of the window each way: 24 blocks; their median follows the ripple as well as all 80 do,
/// at a third of the cost).
const LOCAL_STEP: usize = 2;

/// Fewest surrounding blocks for the local test (a block with fewer is on a plane too narrow to
/// tell a piece from the plane's own shape, and is not given back).
const MIN_LOCAL_BLOCKS: usize = 6;

/// Pixels of a row looked at together for a plane's label.
const SCAN_CHUNK: usize = 32;

/// Scale of the quadratic's coordinates, pixels.
const COORD_SCALE_PX: f64 = 64.0;

/// One plane's samples in one block: its label, how many, and the sums of their coordinates
/// and residuals against the plane's affine fit.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct BlockSlot {
    label: u16,
    n: u16,
    // (At most `MAX_BLOCK_SAMPLES` samples a block: their coordinate sums are exact in `f32`,
    // and their residuals are small.)
    sx: f32,
    sy: f32,
    sr: f32,
}

/// A block's samples: up to two planes' (a third plane's, rare, is not tested there).
pub(super) type BlockSlots = [BlockSlot; 2];

/// A block of a plane under test: its block index, the mean position and mean residual of its
/// samples, the noise of that mean, and its residual from the plane's quadratic.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TestBlock {
    block: u32,
    x: f64,
    y: f64,
    r: f64,
    /// Inverse variance of `r` (its weight in the fit).
    weight: f64,
    /// Inverse standard deviation of `r`.
    inv_sd: f64,
    /// Residual of `r` from the plane's quadratic, px.
    e: f64,
}

impl TestBlock {
    /// The residual from the quadratic in units of its standard deviation.
    #[inline]
    fn z(&self) -> f64 {
        self.e * self.inv_sd
    }
}

/// Mean pairwise correlation of the samples of a full block (every [`X_STEP`]-th pixel of the
/// rows [`SAMPLE_ROW_STEP`] apart in a [`BLOCK`]-pixel block), for the triangular
/// autocorrelation of a `wx × wy` window, excluding each sample with itself.
fn block_correlation(wx: f64, wy: f64) -> f64 {
    let rho = |l: f64, w: f64| (1.0 - l.abs() / w.max(1.0)).max(0.0);
    let xs = || (0..BLOCK).step_by(X_STEP).map(|x| x as f64);
    let ys = || (0..BLOCK).step_by(SAMPLE_ROW_STEP).map(|y| y as f64);
    let (mut sum, mut pairs) = (0.0, 0.0);
    for ya in ys() {
        for xa in xs() {
            for yb in ys() {
                for xb in xs() {
                    if xa == xb && ya == yb {
                        continue;
                    }
                    sum += rho(xa - xb, wx) * rho(ya - yb, wy);
                    pairs += 1.0;
                }
            }
        }
    }
    if pairs > 0.0 { sum / pairs } else { 0.0 }
}

/// Adds `n` samples of label `l` (coordinate sums `sx`, `sy`, residual sum `sr`) to a block's
/// slot of that label, or to a free one; a third label in a block is not tested there.
#[inline]
fn add_to_slot(slots: &mut BlockSlots, l: u16, n: u16, sx: f32, sy: f32, sr: f32) {
    let s = if slots[0].label == l || slots[0].label == 0 {
        &mut slots[0]
    } else if slots[1].label == l || slots[1].label == 0 {
        &mut slots[1]
    } else {
        return;
    };
    s.label = l;
    s.n += n;
    s.sx += sx;
    s.sy += sy;
    s.sr += sr;
}

/// Variance factor of the mean of `n` samples of a block: `1/n + (1 − 1/n)·ρ̄`.
#[inline]
fn mean_variance_factor(n: u16, rho_bar: f64) -> f64 {
    let inv = 1.0 / f64::from(n.max(1));
    inv + (1.0 - inv) * rho_bar
}

/// The quadratic basis at scaled coordinates.
#[inline]
fn basis(u: f64, v: f64) -> [f64; 6] {
    [1.0, u, v, u * u, u * v, v * v]
}

impl PlaneExtractor {
    /// Gives back the pieces of neighbouring surfaces the planes of the final pass took in
    /// (see the module documentation). `labels` are the full-resolution labels, updated with
    /// the planes' statistics.
    #[inline(never)]
    pub(super) fn give_back_taken_in(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        wq: usize,
        labels: &mut [u16],
    ) {
        let n_planes = self.final_sums.len();
        if n_planes == 0 || w == 0 || self.full_res_fits.len() < n_planes {
            return;
        }
        let h = labels.len() / w;
        let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
        self.block_slots.clear();
        self.block_slots.resize(bw * bh, BlockSlots::default());
        // 0. The disparity of the sample rows (every later read is on them).
        let n_rows = h.div_ceil(SAMPLE_ROW_STEP);
        // (Every value is written below: no clearing.)
        self.block_disparity.resize(n_rows * w, 0.0);
        for (k, out) in self.block_disparity.chunks_exact_mut(w).enumerate() {
            d.row_into(k * SAMPLE_ROW_STEP, w, out);
        }
        // 1. Block sums of every plane's residuals, a block's samples of a row at a time: one
        // label for all of them (inside a plane) is added at once.
        for y in (0..h).filter(|&y| is_sample_row(y)) {
            let yf = self.rows.of(y);
            let brow = (y / BLOCK) * bw;
            let row = &labels[y * w..(y + 1) * w];
            let drow = &self.block_disparity[(y / SAMPLE_ROW_STEP) * w..][..w];
            for (bx, seg) in row.chunks(BLOCK).enumerate() {
                let x0 = bx * BLOCK;
                let first = seg[0];
                let uniform = seg.len() == BLOCK && seg.iter().step_by(X_STEP).all(|&l| l == first);
                if uniform {
                    let p = usize::from(first).wrapping_sub(1);
                    if p >= n_planes {
                        continue;
                    }
                    // The samples x0, x0 + X_STEP, …: their count and coordinate sum are fixed.
                    const N: usize = BLOCK / X_STEP;
                    let sx = (N * x0 + X_STEP * N * (N - 1) / 2) as f64;
                    let sd: f32 = drow[x0..x0 + BLOCK].iter().step_by(X_STEP).sum();
                    let f = &self.full_res_fits[p];
                    let sr = f64::from(sd) - f.a * sx - N as f64 * (f.b * yf + f.c);
                    add_to_slot(
                        &mut self.block_slots[brow + bx],
                        first,
                        N as u16,
                        sx as f32,
                        (N as f64 * yf) as f32,
                        sr as f32,
                    );
                    continue;
                }
                for x in (x0..x0 + seg.len()).step_by(X_STEP) {
                    let l = row[x];
                    let p = usize::from(l).wrapping_sub(1);
                    if p >= n_planes {
                        continue;
                    }
                    let r = f64::from(drow[x]) - self.full_res_fits[p].eval(x as f64, yf);
                    add_to_slot(
                        &mut self.block_slots[brow + bx],
                        l,
                        1,
                        x as f32,
                        yf as f32,
                        r as f32,
                    );
                }
            }
        }
        // 2. The blocks of each plane, grouped by plane (counting sort).
        self.block_start.clear();
        self.block_start.resize(n_planes + 2, 0);
        for slots in &self.block_slots {
            for s in slots {
                if s.n >= MIN_BLOCK_SAMPLES {
                    self.block_start[usize::from(s.label) + 1] += 1;
                }
            }
        }
        for i in 1..self.block_start.len() {
            self.block_start[i] += self.block_start[i - 1];
        }
        let total = self.block_start[n_planes + 1] as usize;
        self.block_tests.clear();
        self.block_tests.resize(total, TestBlock::default());
        self.block_fill.clear();
        self.block_fill.extend_from_slice(&self.block_start);
        // Weights and inverse deviations by sample count.
        let rho_bar = block_correlation(self.noise_window.0, self.noise_window.1);
        let var_px = self.crease_noise.var_px;
        let by_count: [(f64, f64, f64); MAX_BLOCK_SAMPLES + 1] = std::array::from_fn(|n| {
            let var = var_px * mean_variance_factor(n as u16, rho_bar);
            (1.0 / n.max(1) as f64, 1.0 / var, 1.0 / var.sqrt())
        });
        for (k, slots) in self.block_slots.iter().enumerate() {
            for s in slots {
                if s.n < MIN_BLOCK_SAMPLES {
                    continue;
                }
                let (inv_n, weight, inv_sd) = by_count[usize::from(s.n).min(MAX_BLOCK_SAMPLES)];
                let at = &mut self.block_fill[usize::from(s.label)];
                self.block_tests[*at as usize] = TestBlock {
                    block: k as u32,
                    x: f64::from(s.sx) * inv_n,
                    y: f64::from(s.sy) * inv_n,
                    r: f64::from(s.sr) * inv_n,
                    weight,
                    inv_sd,
                    e: 0.0,
                };
                *at += 1;
            }
        }
        self.block_mark.clear();
        self.block_mark.resize(bw * bh, u32::MAX);
        self.given_back_cells.clear();
        self.given_back_cells.resize(wq * h.div_ceil(CELL), 0);
        let min_piece = self.cfg.min_piece_pixels.max(1);
        for p in 0..n_planes {
            let (b0, b1) = (
                self.block_start[p + 1] as usize,
                self.block_start[p + 2] as usize,
            );
            if b1 - b0 < MIN_BLOCKS || self.final_sums[p].pixels < 2 * self.cfg.min_pixels {
                continue;
            }
            if !standardise_blocks(&mut self.block_tests[b0..b1]) {
                continue;
            }
            let removed = self.remove_pieces(p, b0..b1, bw, w, wq, min_piece, labels);
            if removed.pixels > 0 {
                self.update_plane(p, &removed, w, labels);
            }
        }
    }

    /// Finds the pieces among plane `p`'s standardised blocks `range` and unlabels those that
    /// qualify; the pixels unlabelled, their moments (sample rows) and metric sums (metric
    /// rows, without residuals).
    #[allow(clippy::too_many_arguments)]
    fn remove_pieces(
        &mut self,
        p: usize,
        range: std::ops::Range<usize>,
        bw: usize,
        w: usize,
        wq: usize,
        min_piece: usize,
        labels: &mut [u16],
    ) -> FinalAcc {
        let label = p as u16 + 1;
        let h = labels.len() / w;
        let blocks = &self.block_tests[range.clone()];
        for (i, b) in blocks.iter().enumerate() {
            self.block_mark[b.block as usize] = i as u32;
        }
        let plane_pixels = self.final_sums[p].pixels;
        let mut left = plane_pixels;
        let mut removed = FinalAcc::default();
        let mut seen = std::mem::take(&mut self.block_seen);
        let mut stack = std::mem::take(&mut self.block_stack);
        let mut piece = std::mem::take(&mut self.block_piece);
        seen.clear();
        seen.resize(blocks.len(), false);
        // Each block's standardised residual, kept where its surroundings agree that it is
        // off (see `off_its_surroundings`), 0 elsewhere.
        let mut off = std::mem::take(&mut self.block_off);
        let mut window = std::mem::take(&mut self.block_window);
        off.clear();
        off.extend(blocks.iter().map(|b| {
            if b.z().abs() <= Z_99 {
                return 0.0;
            }
            let local = off_its_surroundings(b, blocks, &self.block_mark, bw, &mut window);
            if local * b.z().signum() > 0.0 {
                b.z().signum() * b.z().abs().min(local.abs())
            } else {
                0.0
            }
        }));
        for start in 0..blocks.len() {
            if seen[start] || off[start].abs() <= Z_999 {
                continue;
            }
            let sign = off[start].signum();
            piece.clear();
            stack.push(start);
            seen[start] = true;
            while let Some(i) = stack.pop() {
                piece.push(i);
                let k = blocks[i].block as usize;
                let (bx, by) = (k % bw, k / bw);
                let mut visit = |nk: usize| {
                    let j = self.block_mark[nk];
                    if j != u32::MAX {
                        let j = j as usize;
                        if !seen[j] && off[j] * sign > Z_99 {
                            seen[j] = true;
                            stack.push(j);
                        }
                    }
                };
                if bx > 0 {
                    visit(k - 1);
                }
                if bx + 1 < bw {
                    visit(k + 1);
                }
                if by > 0 {
                    visit(k - bw);
                }
                if k + bw < self.block_mark.len() {
                    visit(k + bw);
                }
            }
            // The plane's pixels in the piece's blocks.
            let count_in = |k: usize, labels: &[u16]| -> usize {
                let (x0, y0) = ((k % bw) * BLOCK, (k / bw) * BLOCK);
                (y0..(y0 + BLOCK).min(h))
                    .map(|y| {
                        labels[y * w + x0..y * w + (x0 + BLOCK).min(w)]
                            .iter()
                            .filter(|&&l| l == label)
                            .count()
                    })
                    .sum()
            };
            let pixels: usize = piece
                .iter()
                .map(|&i| count_in(blocks[i].block as usize, labels))
                .sum();
            if pixels < min_piece
                || 2 * pixels > plane_pixels
                || left.saturating_sub(pixels) < self.cfg.min_pixels
            {
                continue;
            }
            for &i in &piece {
                let k = blocks[i].block as usize;
                let (x0, y0) = ((k % bw) * BLOCK, (k / bw) * BLOCK);
                for y in y0..(y0 + BLOCK).min(h) {
                    let x1 = (x0 + BLOCK).min(w);
                    let row = &mut labels[y * w + x0..y * w + x1];
                    if !is_sample_row(y) {
                        for l in row.iter_mut().filter(|l| **l == label) {
                            *l = 0;
                        }
                        continue;
                    }
                    let yf = self.rows.of(y);
                    let metric = is_metric_row(y);
                    let drow = &self.block_disparity[(y / SAMPLE_ROW_STEP) * w + x0..][..x1 - x0];
                    for (i, l) in row.iter_mut().enumerate() {
                        if *l != label {
                            continue;
                        }
                        *l = 0;
                        let (xf, df) = ((x0 + i) as f64, f64::from(drow[i]));
                        removed.sums.add(xf, yf, df);
                        if metric {
                            removed.inv.add(xf, yf, df, 0.0, 1.0);
                        }
                    }
                }
                // The block's cells (2 × 2) follow.
                let (i0, j0) = (x0 / CELL, y0 / CELL);
                for j in j0..j0 + BLOCK / CELL {
                    for i in i0..(i0 + BLOCK / CELL).min(wq) {
                        if let Some(c) = self.cell_labels.get_mut(j * wq + i)
                            && *c == label
                        {
                            *c = 0;
                        }
                        if let Some(g) = self.given_back_cells.get_mut(j * wq + i) {
                            *g = 1;
                        }
                    }
                }
            }
            left -= pixels;
            removed.pixels += pixels;
        }
        for b in blocks {
            self.block_mark[b.block as usize] = u32::MAX;
        }
        self.block_seen = seen;
        self.block_off = off;
        self.block_window = window;
        self.block_stack = stack;
        self.block_piece = piece;
        removed
    }

    /// Takes the `removed` pixels out of plane `p`'s final statistics: pixel count, moments
    /// and centroid sums by subtraction, then its fit, and the squared metric residuals of the
    /// pixels left against that fit (its metric rows again).
    fn update_plane(&mut self, p: usize, removed: &FinalAcc, w: usize, labels: &[u16]) {
        let label = p as u16 + 1;
        let mut acc = self.final_sums[p];
        acc.pixels = acc.pixels.saturating_sub(removed.pixels);
        acc.sums.subtract(&removed.sums);
        let r = &removed.inv;
        acc.inv.n -= r.n;
        acc.inv.si -= r.si;
        acc.inv.sxi -= r.sxi;
        acc.inv.syi -= r.syi;
        let Some(fit) = acc.sums.solve() else {
            return;
        };
        let h = labels.len() / w;
        let mut sr2 = 0.0;
        for y in (acc.y0..acc.y1.min(h)).filter(|&y| is_metric_row(y)) {
            let yf = self.rows.of(y);
            let row = &labels[y * w..(y + 1) * w];
            let drow = &self.block_disparity[(y / SAMPLE_ROW_STEP) * w..][..w];
            // Chunks without the label are skipped after one branch-free test; a chunk's
            // squared relative residuals are summed in `f32` lanes (they vectorise), about the
            // fit's value at the chunk's first pixel.
            let mut row_sum = [0.0f32; SCAN_CHUNK];
            for (c, (lc, dc)) in row
                .chunks_exact(SCAN_CHUNK)
                .zip(drow.chunks_exact(SCAN_CHUNK))
                .enumerate()
            {
                if !holds_label(lc, label) {
                    continue;
                }
                let x0 = c * SCAN_CHUNK;
                let f0 = fit.eval(x0 as f64, yf) as f32;
                let a = fit.a as f32;
                for (i, ((s, &l), &dv)) in row_sum.iter_mut().zip(lc).zip(dc).enumerate() {
                    let on = l == label;
                    let dv = if on { dv } else { 1.0 };
                    let rd = (dv - (f0 + a * i as f32)) / dv;
                    *s += if on { rd * rd } else { 0.0 };
                }
            }
            sr2 += row_sum.iter().map(|&v| f64::from(v)).sum::<f64>();
            // The pixels after the last whole chunk.
            let tail = row.len() - row.len() % SCAN_CHUNK;
            for (x, _) in row
                .iter()
                .enumerate()
                .skip(tail)
                .filter(|(_, l)| **l == label)
            {
                let df = f64::from(drow[x]);
                let rd = (df - fit.eval(x as f64, yf)) / df;
                sr2 += rd * rd;
            }
        }
        acc.inv.sr2 = sr2;
        self.final_sums[p] = acc;
        self.full_res_fits[p] = fit;
    }
}

/// Block `b`'s residual from the quadratic against the median of the residuals of the plane's
/// other blocks within [`LOCAL_RADIUS`] blocks (every [`LOCAL_STEP`]-th each way), in units of
/// the difference's standard deviation (0 when fewer than [`MIN_LOCAL_BLOCKS`] surround it). The distortion the quadratic cannot
/// take varies over a hundred pixels and more, so the median of the surroundings follows it
/// (exactly for a linear trend across a symmetric window), while a piece of a neighbour that
/// fills less than half the window does not move it.
fn off_its_surroundings(
    b: &TestBlock,
    blocks: &[TestBlock],
    mark: &[u32],
    bw: usize,
    window: &mut Vec<f64>,
) -> f64 {
    let k = b.block as usize;
    let bh = mark.len() / bw.max(1);
    let (bx, by) = (k % bw, k / bw);
    window.clear();
    let r = LOCAL_RADIUS as isize;
    for dy in (-r..=r).step_by(LOCAL_STEP) {
        for dx in (-r..=r).step_by(LOCAL_STEP) {
            let (x, y) = (bx as isize + dx, by as isize + dy);
            if (dx, dy) == (0, 0) || x < 0 || y < 0 || x >= bw as isize || y >= bh as isize {
                continue;
            }
            let j = mark[y as usize * bw + x as usize];
            if j != u32::MAX {
                window.push(blocks[j as usize].e);
            }
        }
    }
    let m = window.len();
    if m < MIN_LOCAL_BLOCKS {
        return 0.0;
    }
    let (_, median, _) = window.select_nth_unstable_by(m / 2, f64::total_cmp);
    // The median of m values has about π/(2m) of one value's variance.
    let inflation = (1.0 + std::f64::consts::FRAC_PI_2 / m as f64).sqrt();
    (b.e - *median) * b.inv_sd / inflation
}

/// Fits the quadratic to `blocks` (twice: the second time without the outliers of the first)
/// and sets each block's standardised residual `z`; `false` when the fit is undetermined.
fn standardise_blocks(blocks: &mut [TestBlock]) -> bool {
    let (mut cx, mut cy, mut sw) = (0.0, 0.0, 0.0);
    for b in blocks.iter() {
        let wgt = b.weight;
        cx += wgt * b.x;
        cy += wgt * b.y;
        sw += wgt;
    }
    if sw.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return false;
    }
    let (cx, cy) = (cx / sw, cy / sw);
    let inv_s = 1.0 / COORD_SCALE_PX;
    for pass in 0..2 {
        if pass == 1 && blocks.iter().all(|b| b.z().abs() <= Z_999) {
            break;
        }
        let mut q = QuadraticMoments::default();
        for b in blocks.iter() {
            if pass == 1 && b.z().abs() > Z_999 {
                continue;
            }
            q.add((b.x - cx) * inv_s, (b.y - cy) * inv_s, b.r, b.weight);
        }
        let Some(sol) = q.sums().solve() else {
            return false;
        };
        for b in blocks.iter_mut() {
            let phi = basis((b.x - cx) * inv_s, (b.y - cy) * inv_s);
            let fit: f64 = phi.iter().zip(sol.coef.iter()).map(|(a, c)| a * c).sum();
            b.e = b.r - fit;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::tests::gauss;

    /// A 640 × 480 disparity frame of a far wall (about 2.5 m for a Kinect) whose disparity
    /// is `surface`, with the camera's white noise, and the camera.
    fn frame(surface: impl Fn(f64, f64) -> f64, seed: u64) -> (DisparityImage, Camera) {
        let cam = Camera::kinect_v1();
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let sigma = cam.sensor.sigma_d_px;
        let mut state = seed;
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (surface(x, y) + sigma * gauss(&mut state)) as f32
            })
            .collect();
        (DisparityImage::from_vec(w, h, data).unwrap(), cam)
    }

    fn extract(d: &DisparityImage, cam: &Camera, give_back: bool) -> PlaneSegmentation {
        let cfg = PlaneConfig {
            give_back_taken_in: give_back,
            ..PlaneConfig::default()
        };
        PlaneExtractor::new(cfg)
            .unwrap()
            .extract_disparity(d, cam)
            .unwrap()
    }

    /// A wall with a board 0.3 px (about 4 cm at 2.5 m) in front of it along its lower border,
    /// 48 × 24 px (a piece smaller than half of a block's surroundings, which the image border
    /// halves there): within `τ` of the wall, so the wall takes it in; the test gives it back,
    /// and the wall's fit is the wall's again.
    #[test]
    fn a_raised_piece_at_the_border_is_given_back() {
        let wall = |x: f64, y: f64| 17.4 + 0.002 * x - 0.001 * y;
        let board = |x: f64, y: f64| (200.0..248.0).contains(&x) && y >= 456.0;
        let (d, cam) = frame(|x, y| wall(x, y) + if board(x, y) { 0.3 } else { 0.0 }, 7);
        let w = cam.intrinsics.width;
        let on_board = |seg: &PlaneSegmentation| {
            (0..seg.labels.data().len())
                .filter(|&i| board((i % w) as f64, (i / w) as f64) && seg.labels.data()[i] != 0)
                .count()
        };
        let before = extract(&d, &cam, false);
        let after = extract(&d, &cam, true);
        assert_eq!(before.planes.len(), 1, "{:?}", before.planes);
        assert_eq!(after.planes.len(), 1, "{:?}", after.planes);
        // 1,152 board pixels: the wall took most of them in; most are given back.
        assert!(on_board(&before) > 900, "{}", on_board(&before));
        assert!(on_board(&after) < 300, "{}", on_board(&after));
        // `explain` names the board's region as given back.
        let cfg = PlaneConfig {
            give_back_taken_in: true,
            ..PlaneConfig::default()
        };
        let mut ex = PlaneExtractor::new(cfg).unwrap();
        let seg = ex.extract_disparity(&d, &cam).unwrap();
        let regions = ex.explain_unlabelled(&seg, 500);
        assert!(
            regions
                .iter()
                .any(|r| r.reason == RejectReason::GivenBack && r.pixels >= 500),
            "{regions:?}"
        );
        // The wall's fit, at the board's corner, back near the wall's own disparity.
        let err = |seg: &PlaneSegmentation| {
            (seg.planes[0].affine.eval(224.0, 470.0) - wall(224.0, 470.0)).abs()
        };
        assert!(
            err(&after) < 0.5 * err(&before),
            "{} {}",
            err(&before),
            err(&after)
        );
    }

    /// A wall bent by the sensor's distortion (the largest curvature the extractor allows,
    /// `bend_px_per_px2`) loses nothing: the quadratic takes the bend.
    #[test]
    fn a_bent_wall_keeps_every_pixel() {
        let c = PlaneConfig::default().bend_px_per_px2 * 585.0 / 580.0;
        for seed in 0..3 {
            let (d, cam) = frame(
                |x, y| 17.4 + 0.002 * x + 0.5 * c * ((x - 320.0).powi(2) + (y - 240.0).powi(2)),
                seed,
            );
            let before = extract(&d, &cam, false);
            let after = extract(&d, &cam, true);
            assert_eq!(before, after, "seed {seed}");
        }
    }

    /// A wall bent beyond any quadratic — a low-frequency ripple like the residual distortion
    /// of real Kinect frames, 0.15 px over a few hundred pixels — loses nothing either: each
    /// block is compared with its surroundings too, which follow the ripple.
    #[test]
    fn a_rippled_wall_keeps_every_pixel() {
        use std::f64::consts::TAU;
        for seed in 0..3 {
            let (d, cam) = frame(
                |x, y| {
                    17.4 + 0.002 * x
                        + 0.15 * (TAU * x / 400.0).sin() * (TAU * y / 300.0 + 1.0).cos()
                },
                seed,
            );
            let before = extract(&d, &cam, false);
            let after = extract(&d, &cam, true);
            assert_eq!(before, after, "seed {seed}");
        }
    }

    #[test]
    fn a_full_block_mean_keeps_most_of_the_pixel_variance() {
        // 8 samples of a 9 × 11 window's correlated noise: far from σ²/8.
        let rho = block_correlation(9.0, 11.0);
        let f = mean_variance_factor(8, rho);
        assert!(f > 0.5 && f < 0.8, "{f}");
        // White noise: σ²/n.
        let white = block_correlation(1.0, 1.0);
        assert!((mean_variance_factor(8, white) - 0.125).abs() < 1e-12);
    }
}
