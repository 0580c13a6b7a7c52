//! The interior gate of the multi-scale filter's coarse passes: where a wide pass's whole window
//! is inside the image, valid and free of depth jumps.
//!
//! A pixel is *bad* when it is invalid or more than one range σ from its right or lower
//! neighbour. A pass of half-width `R` is used at `p` only if no bad pixel lies in the
//! `(2R+1)²` square around it; so the gate is the bad-pixel mask dilated by a square of side
//! `2R + 1` (the union of the bad pixels' squares), inverted, and cleared within `R` of the
//! border.
//!
//! **How.** A dilation by a square is separable: a row pass (any bad pixel within `±R` in the
//! row), then a column pass over its result. Each pass is computed by doubling: the mask `D_1`
//! of the bad pixels, then `D_2m(x) = D_m(x) | D_m(x + m)` (a bad pixel in `[x, x + 2m)`) until
//! `m` is the largest power of two not above `2R + 1`, and the window `[x − R, x + R]` is the
//! union of the two overlapping runs `D_m(x − R) | D_m(x + R + 1 − m)`. That is
//! `⌈log2(2R + 1)⌉` elementwise ORs of byte masks per pass — 5 for the widest default pass
//! (`R` = 16 px) — each a loop the compiler vectorises, where a running count over every
//! window is a serial loop per row (written by hand: no crate offers a 2D binary dilation
//! over byte masks without pulling in an image-processing library).

use rayon::prelude::*;
use sl_core::DepthImage;

use crate::domain::Domain;
use crate::kernel::avx2_twin;

/// The gate's working buffers, reused across passes and calls: the frame's domain values
/// ([`Domain::image_into`], also read by the crease test) and two byte masks.
#[derive(Default)]
pub(crate) struct Gate {
    /// The domain value of every pixel of the last frame gated (NaN where invalid).
    pub(crate) values: Vec<f32>,
    /// The masks the doubling steps alternate between.
    masks: [Vec<bool>; 2],
}

impl Gate {
    /// Pixels whose whole `(2r+1)²` neighbourhood is inside the image, valid and free of depth
    /// jumps (neighbours more than one range σ apart), written into `out`; the frame's domain
    /// values are left in [`Gate::values`] for the crease test. Only there is a wide pass
    /// symmetric: a window clipped by the border, a hole or a rejected surface averages one
    /// side of the pixel only, which on a slope (a floor at grazing incidence) shifts the depth
    /// by the slope times the window's off-centre mean, up to `r` pixels' worth. Elsewhere the
    /// finer result is kept.
    ///
    /// Cost: one image of domain values and about `2·⌈log2(2r + 1)⌉ + 3` passes of byte masks
    /// (module docs), by rows in parallel, without per-pixel allocation; built for AVX2 with
    /// `avx2` (`kernel::avx2_twin!`).
    pub(crate) fn interior_into(
        &mut self,
        depth: &DepthImage,
        domain: Domain,
        r: usize,
        out: &mut Vec<bool>,
        avx2: bool,
    ) {
        let (w, h) = (depth.width(), depth.height());
        out.clear();
        out.resize(w * h, false);
        domain.image_into(depth, &mut self.values, avx2);
        if 2 * r + 1 > w || 2 * r + 1 > h {
            return;
        }
        let span = 2 * r + 1;
        // The largest power of two not above the window's side.
        let m = 1 << span.ilog2();
        let [a, b] = &mut self.masks;
        a.resize(w * h, false);
        b.resize(w * h, false);
        // Rows (in parallel): the bad pixels, then whether one lies within ±r in the row.
        let u = &*self.values;
        a.par_chunks_mut(w).enumerate().for_each_init(
            || (vec![false; w], vec![false; w]),
            |(bad, tmp), (y, near)| near_row(avx2, u, y, domain, r, m, bad, tmp, near),
        );
        // Columns: doubling over rows, alternating between the two masks.
        let mut step = 1;
        let (mut from, mut to) = (a, b);
        while step < m {
            to.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let lower = &from[y * w..(y + 1) * w];
                match from.get((y + step) * w..(y + step + 1) * w) {
                    Some(upper) => or_row(avx2, row, lower, upper, false),
                    None => row.copy_from_slice(lower),
                }
            });
            std::mem::swap(&mut from, &mut to);
            step *= 2;
        }
        let runs = &*from;
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            if y < r || y + r >= h {
                return;
            }
            let first = &runs[(y - r) * w..(y - r + 1) * w];
            let last = &runs[(y + r + 1 - m) * w..(y + r + 2 - m) * w];
            or_row(avx2, row, first, last, true);
        });
    }
}

avx2_twin! {
    /// Row `y` of the row pass: whether a bad pixel lies within ±r (all true within `r` of the
    /// row's ends), from the bad pixels' runs of `m` (`bad` and `tmp` are scratch rows).
    #[allow(clippy::too_many_arguments)]
    fn near_row(
        u: &[f32],
        y: usize,
        domain: Domain,
        r: usize,
        m: usize,
        bad: &mut [bool],
        tmp: &mut [bool],
        near: &mut [bool],
    ) {
        let w = near.len();
        bad_pixels(u, w, y, domain, bad);
        let run = doubled(bad, tmp, m);
        for x in r..w - r {
            near[x] = run[x - r] | run[x + r + 1 - m];
        }
        // Columns within r of the border are never interior.
        near[..r].fill(true);
        near[w - r..].fill(true);
    }
}

avx2_twin! {
    /// `out = a | b` elementwise, negated with `invert`.
    fn or_row(out: &mut [bool], a: &[bool], b: &[bool], invert: bool) {
        for ((o, &l), &u) in out.iter_mut().zip(a).zip(b) {
            *o = (l | u) ^ invert;
        }
    }
}

/// The bad pixels of row `y` (invalid, or a jump of more than one σ to the right or lower
/// neighbour; comparisons with NaN are false; the last row is compared with itself).
#[inline(always)]
fn bad_pixels(u: &[f32], w: usize, y: usize, domain: Domain, bad: &mut [bool]) {
    let h = u.len() / w;
    let row = &u[y * w..(y + 1) * w];
    let below = &u[(y + 1).min(h - 1) * w..][..w];
    let jump = |v: f32, n: f32, s: f32| (v - n).abs() > s;
    // One loop per kind of σ, so each vectorises (as in `crease.rs`).
    match domain.constant_sigma() {
        Some(s) => {
            for x in 0..w - 1 {
                let v = row[x];
                bad[x] = v.is_nan() | jump(v, row[x + 1], s) | jump(v, below[x], s);
            }
        }
        None => {
            for x in 0..w - 1 {
                let (v, s) = (row[x], domain.sigma(row[x]));
                bad[x] = v.is_nan() | jump(v, row[x + 1], s) | jump(v, below[x], s);
            }
        }
    }
    let v = row[w - 1];
    bad[w - 1] = v.is_nan() | jump(v, below[w - 1], domain.sigma(v));
}

/// The runs of `m` (a power of two) of a row mask by doubling: entry `x` of the result says
/// whether `mask` holds a true in `[x, x + m)` (truncated at the row's end). `mask` and `tmp`
/// (of the same length) are overwritten; the result is one of them.
#[inline(always)]
fn doubled<'a>(mask: &'a mut [bool], tmp: &'a mut [bool], m: usize) -> &'a [bool] {
    let (mut from, mut to) = (mask, tmp);
    let mut step = 1;
    while step < m {
        let n = from.len().saturating_sub(step);
        for ((o, &l), &u) in to.iter_mut().zip(&from[..n]).zip(&from[step..]) {
            *o = l | u;
        }
        to[n..].copy_from_slice(&from[n..]);
        std::mem::swap(&mut from, &mut to);
        step *= 2;
    }
    from
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubling_gives_runs_of_every_power_of_two() {
        let base: Vec<bool> = (0..37).map(|i| i % 11 == 3 || i == 36).collect();
        for m in [1, 2, 4, 8, 16, 32, 64] {
            let (mut mask, mut tmp) = (base.clone(), vec![false; base.len()]);
            let run = doubled(&mut mask, &mut tmp, m).to_vec();
            for (x, &got) in run.iter().enumerate() {
                let want = base[x..(x + m).min(base.len())].iter().any(|&b| b);
                assert_eq!(got, want, "m {m} x {x}");
            }
        }
    }
}
