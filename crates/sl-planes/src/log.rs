//! Box-approximated Laplacian-of-Gaussian of a disparity map and the planarity mask.
//!
//! The Gaussian is replaced by two passes of a `(2r+1)²` box filter (a separable, triangle-like
//! kernel of variance `2r(r+1)/3` per axis, so `r ≈ (√(1+6σ²) − 1)/2`), computed with direct
//! shifted-slice additions that the compiler vectorises (for `r = 1`, the default, the two boxes
//! are one separable `[1 2 3 2 1]` pass per axis). The Laplacian is the 5-point stencil
//! with step `s = max(1, round(σ))` on the smoothed map:
//! `L = M(x−s,y) + M(x+s,y) + M(x,y−s) + M(x,y+s) − 4M`. Like the LoG it is exactly zero on any
//! affine disparity (a plane), whatever its depth, so a **fixed** threshold in disparity pixels
//! separates planar from non-planar pixels. A pixel is planar only when it and its four
//! neighbours pass (an erosion that closes the zero-crossing line in the middle of an edge).
//!
//! Invalid pixels are NaN in the input: any window touching one yields NaN, which fails the
//! threshold test, so a pixel is planar only with a complete valid support (image borders count
//! as invalid). The extractor therefore feeds it the half-resolution disparity extended across
//! holes and a margin beyond the image border (`crate::extend`, exact for a plane), so that only
//! the extended map's own NaN (far inside wide holes) cut the support.
//!
//! The passes are streamed row by row through rings of a few rows (for `r = 1`), so that only
//! the input and the mask span the whole map, and a band of mask rows can be computed alone
//! from the input rows a few above it.

/// Largest box radius.
pub const MAX_BOX_RADIUS: usize = 8;

/// Box radius and Laplacian step for a LoG scale `sigma_px` (in pixels of the filtered image).
pub fn log_geometry(sigma_px: f64) -> (usize, usize) {
    let r = (((1.0 + 6.0 * sigma_px * sigma_px).sqrt() - 1.0) / 2.0)
        .round()
        .max(1.0) as usize;
    let s = sigma_px.round().max(1.0) as usize;
    (r.min(MAX_BOX_RADIUS), s)
}

/// Reusable buffers for [`planar_mask_uncounted`].
#[derive(Debug, Default, Clone)]
pub struct LogBuffers {
    a: Vec<f32>,
    b: Vec<f32>,
    raw: Vec<u8>,
}

/// Horizontal then vertical box sum of radius `r` from `src` into `dst` via `tmp`; NaN where
/// the window leaves the image. Every element is written once (no prefill).
fn box_sum(src: &[f32], dst: &mut Vec<f32>, tmp: &mut Vec<f32>, w: usize, h: usize, r: usize) {
    let n = w * h;
    tmp.resize(n, f32::NAN);
    dst.resize(n, f32::NAN);
    if w <= 2 * r || h <= 2 * r {
        dst[..n].fill(f32::NAN);
        return;
    }
    let inner = w - 2 * r;
    for (row, out) in src.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        let (head, rest) = out.split_at_mut(r);
        let (mid, tail) = rest.split_at_mut(inner);
        head.fill(f32::NAN);
        tail.fill(f32::NAN);
        mid.copy_from_slice(&row[..inner]);
        for k in 1..=2 * r {
            for (o, &v) in mid.iter_mut().zip(&row[k..k + inner]) {
                *o += v;
            }
        }
    }
    for (y, out) in dst.chunks_exact_mut(w).enumerate() {
        if y < r || y + r >= h {
            out.fill(f32::NAN);
            continue;
        }
        out.copy_from_slice(&tmp[(y - r) * w..(y - r + 1) * w]);
        for k in 1..=2 * r {
            let row = &tmp[(y - r + k) * w..(y - r + k + 1) * w];
            for (o, &v) in out.iter_mut().zip(row) {
                *o += v;
            }
        }
    }
}

/// `o = (a + e) + 2(b + d) + 3c` elementwise over `r = [a, b, c, d, e]` (the common length;
/// slices cut to it so that the loop has no bounds checks and vectorises).
// (Indexing the cut slices is what removes the checks.)
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn tent_row(o: &mut [f32], r: [&[f32]; 5]) {
    let n = r.iter().fold(o.len(), |n, s| n.min(s.len()));
    let o = &mut o[..n];
    let [a, b, c, d, e] = r.map(|s| &s[..n]);
    for i in 0..n {
        o[i] = (a[i] + e[i]) + 2.0 * (b[i] + d[i]) + 3.0 * c[i];
    }
}

/// `o = |l + r + u + d − 4m| <= thr` (as 1/0) elementwise over `[l, m, r, u, d]` (as
/// [`tent_row`]).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn laplacian_row(o: &mut [u8], s: [&[f32]; 5], thr: f32) {
    let n = s.iter().fold(o.len(), |n, v| n.min(v.len()));
    let o = &mut o[..n];
    let [l, m, r, u, d] = s.map(|v| &v[..n]);
    for i in 0..n {
        let lap = l[i] + r[i] + u[i] + d[i] - 4.0 * m[i];
        o[i] = u8::from(lap.abs() <= thr);
    }
}

/// The horizontal `[1 2 3 2 1]` pass of one row (`row.len() == out.len() > 4`) into `out`: NaN
/// in the two columns at each end, where the window leaves the image.
#[inline(always)]
fn tent_row_horizontal(out: &mut [f32], row: &[f32]) {
    let n = out.len() - 4;
    let (head, rest) = out.split_at_mut(2);
    let (mid, tail) = rest.split_at_mut(n);
    head.fill(f32::NAN);
    tail.fill(f32::NAN);
    tent_row(
        mid,
        [
            &row[..n],
            &row[1..1 + n],
            &row[2..2 + n],
            &row[3..3 + n],
            &row[4..4 + n],
        ],
    );
}

/// The separable `[1 2 3 2 1]` filter (two 3×3 box sums) of `src` into `dst` via `tmp`; NaN
/// where the 5×5 window leaves the image.
#[cfg(test)]
fn tent5(src: &[f32], dst: &mut Vec<f32>, tmp: &mut Vec<f32>, w: usize, h: usize) {
    let n = w * h;
    tmp.resize(n, f32::NAN);
    dst.resize(n, f32::NAN);
    if w <= 4 || h <= 4 {
        dst[..n].fill(f32::NAN);
        return;
    }
    for (row, out) in src.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        tent_row_horizontal(out, row);
    }
    for (y, out) in dst.chunks_exact_mut(w).enumerate() {
        if y < 2 || y + 2 >= h {
            out.fill(f32::NAN);
            continue;
        }
        let r = |k: usize| &tmp[(y + k - 2) * w..(y + k - 1) * w];
        tent_row(out, [r(0), r(1), r(2), r(3), r(4)]);
    }
}

/// Writes the planarity mask (1 = planar, 0 = not) of the disparity `d` (NaN = invalid) into
/// `mask`: pixels whose box-LoG response, and that of their four neighbours, is at most
/// `threshold_px` in magnitude, with a complete valid support. Returns the number of planar
/// pixels.
#[allow(clippy::too_many_arguments)]
#[cfg(test)]
pub fn planar_mask(
    d: &[f32],
    width: usize,
    height: usize,
    radius: usize,
    step: usize,
    threshold_px: f32,
    buf: &mut LogBuffers,
    mask: &mut Vec<u8>,
) -> usize {
    mask.resize(width * height, 0);
    planar_mask_impl::<true>(
        d,
        width,
        height,
        radius,
        step,
        threshold_px,
        buf,
        &mut mask[..width * height],
        0,
    )
}

/// The planarity mask of the map `d` (`width × height`; as the tests' `planar_mask`, without
/// the count of planar pixels), in
/// bands of rows on the caller's pool when `parallel` (one [`LogBuffers`] per band in
/// `bufs`). Every mask value is computed by the same operations in any band, so the mask is
/// the same on any number of threads; each band recomputes the few rows of the smoothing
/// around it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn planar_mask_uncounted(
    d: &[f32],
    width: usize,
    height: usize,
    radius: usize,
    step: usize,
    threshold_px: f32,
    bufs: &mut Vec<LogBuffers>,
    mask: &mut Vec<u8>,
    parallel: bool,
) {
    use rayon::prelude::*;
    let (w, h) = (width, height);
    mask.resize(w * h, 0);
    // Bands only for the streamed smoothing (`r = 1`, the default); a wider box smooths the
    // whole map at once.
    let bands = if parallel && radius <= 1 && w > 0 {
        rayon::current_num_threads().min(h / 16).max(1)
    } else {
        1
    };
    if bufs.len() < bands {
        bufs.resize_with(bands, LogBuffers::default);
    }
    let rows_per = h.div_ceil(bands).max(1);
    let band = |(b, (out, buf)): (usize, (&mut [u8], &mut LogBuffers))| {
        planar_mask_impl::<false>(d, w, h, radius, step, threshold_px, buf, out, b * rows_per);
    };
    let mask = &mut mask[..w * h];
    if bands > 1 {
        mask.par_chunks_mut(rows_per * w)
            .zip(bufs.par_iter_mut())
            .enumerate()
            .for_each(band);
    } else if let Some(buf) = bufs.first_mut() {
        band((0, (mask, buf)));
    }
}

/// The planarity mask of rows `y0..y0 + mask.len() / width` of the map `d` into `mask` (for
/// `radius > 1` only the whole map, `y0 = 0`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn planar_mask_impl<const COUNT: bool>(
    d: &[f32],
    width: usize,
    height: usize,
    radius: usize,
    step: usize,
    threshold_px: f32,
    buf: &mut LogBuffers,
    mask: &mut [u8],
    y0: usize,
) -> usize {
    let (w, h) = (width, height);
    let r = radius.clamp(1, MAX_BOX_RADIUS);
    let s = step.max(1);
    if w <= 2 * s + 2 || h <= 2 * s + 2 {
        mask.fill(0);
        return 0;
    }
    let LogBuffers { a, b, raw } = buf;
    // Rows are streamed: the horizontal pass into a ring of 5 rows (`a`), the smoothed map
    // into a ring of `2s + 1` rows (`b`), the Laplacian test into a ring of 3 rows (`raw`), so
    // that only the input and the mask span the whole frame. For `r > 1` the smoothed map is
    // computed whole (two box sums) and `b` holds all of its rows.
    let nb = if r == 1 {
        b.resize((2 * s + 1) * w, f32::NAN);
        a.resize(5 * w, f32::NAN);
        2 * s + 1
    } else {
        box_sum(&d[..w * h], b, a, w, h, r);
        let b1 = std::mem::take(b);
        box_sum(&b1, b, a, w, h, r);
        *a = b1;
        h
    };
    let nwin = ((2 * r + 1) * (2 * r + 1)) as f32;
    let thr = threshold_px * nwin * nwin;
    raw.resize(3 * w, 0);
    let inner = w - 2 * s;
    // Next rows of the horizontal pass, the smoothed map and the Laplacian test to compute:
    // the mask row `y0` needs the Laplacian rows from `y0 − 1`, which need the smoothed rows
    // from `y0 − 1 − s`, which need the horizontal rows from `y0 − 3 − s`.
    let y0 = if r == 1 { y0 } else { 0 };
    let first_raw = y0.saturating_sub(1);
    let first_b = first_raw.saturating_sub(s);
    let (mut next_a, mut next_b, mut next_raw) = (
        first_b.saturating_sub(2),
        if r == 1 { first_b } else { h },
        first_raw,
    );
    let mut count = 0usize;
    for (y, out) in mask
        .chunks_exact_mut(w)
        .take(h.saturating_sub(y0))
        .enumerate()
        .map(|(i, o)| (y0 + i, o))
    {
        // The mask row needs the Laplacian rows up to y + 1.
        while next_raw <= (y + 1).min(h - 1) {
            let k = next_raw;
            next_raw += 1;
            let out = &mut raw[(k % 3) * w..(k % 3 + 1) * w];
            if k < s || k + s >= h {
                out.fill(0);
                continue;
            }
            // The Laplacian row needs the smoothed rows up to k + s.
            while next_b <= k + s {
                let m = next_b;
                next_b += 1;
                let out = &mut b[(m % nb) * w..(m % nb + 1) * w];
                if m < 2 || m + 2 >= h {
                    out.fill(f32::NAN);
                    continue;
                }
                while next_a <= m + 2 {
                    let row = &d[next_a * w..(next_a + 1) * w];
                    let out = &mut a[(next_a % 5) * w..(next_a % 5 + 1) * w];
                    next_a += 1;
                    tent_row_horizontal(out, row);
                }
                let t = |i: usize| &a[(i % 5) * w..(i % 5 + 1) * w];
                tent_row(out, [t(m - 2), t(m - 1), t(m), t(m + 1), t(m + 2)]);
            }
            let row = |i: usize| &b[(i % nb) * w..(i % nb + 1) * w];
            let (c, up, dn) = (row(k), &row(k - s)[s..s + inner], &row(k + s)[s..s + inner]);
            let (head, rest) = out.split_at_mut(s);
            let (mid, tail) = rest.split_at_mut(inner);
            head.fill(0);
            tail.fill(0);
            let (left, centre, right) = (&c[..inner], &c[s..s + inner], &c[2 * s..2 * s + inner]);
            laplacian_row(mid, [left, centre, right, up, dn], thr);
        }
        // Erosion by the 4-neighbour cross.
        if y == 0 || y + 1 == h {
            out.fill(0);
            continue;
        }
        let rr = |i: usize| &raw[(i % 3) * w..(i % 3 + 1) * w];
        let (u, c, dn) = (rr(y - 1), rr(y), rr(y + 1));
        out[0] = 0;
        out[w - 1] = 0;
        for (((((o, &cl), &cm), &cr), &uu), &dd) in out[1..w - 1]
            .iter_mut()
            .zip(&c[..w - 2])
            .zip(&c[1..w - 1])
            .zip(&c[2..])
            .zip(&u[1..w - 1])
            .zip(&dn[1..w - 1])
        {
            *o = cm & cl & cr & uu & dd;
        }
        if COUNT {
            count += out.iter().map(|&v| usize::from(v)).sum::<usize>();
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tent_is_two_boxes() {
        let (w, h) = (23, 17);
        let d: Vec<f32> = (0..w * h)
            .map(|i| {
                if i % 37 == 5 {
                    f32::NAN
                } else {
                    ((i * 7919) % 101) as f32 * 0.37
                }
            })
            .collect();
        let (mut b1, mut b2, mut t, mut tmp) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        box_sum(&d, &mut b1, &mut tmp, w, h, 1);
        box_sum(&b1, &mut b2, &mut tmp, w, h, 1);
        tent5(&d, &mut t, &mut tmp, w, h);
        for (u, v) in b2.iter().zip(&t) {
            assert_eq!(u.is_nan(), v.is_nan());
            if !u.is_nan() {
                assert!((u - v).abs() <= 1e-4 * u.abs().max(1.0), "{u} vs {v}");
            }
        }
    }

    /// The planarity mask the row-streamed filter must reproduce: whole-frame passes.
    fn reference_mask(d: &[f32], w: usize, h: usize, s: usize, thr: f32) -> Vec<u8> {
        let (mut b, mut tmp) = (Vec::new(), Vec::new());
        tent5(d, &mut b, &mut tmp, w, h);
        let thr = thr * 81.0;
        let mut raw = vec![0u8; w * h];
        for y in s..h - s {
            for x in s..w - s {
                let at = |x: usize, y: usize| b[y * w + x];
                let lap =
                    at(x - s, y) + at(x + s, y) + at(x, y - s) + at(x, y + s) - 4.0 * at(x, y);
                raw[y * w + x] = u8::from(lap.abs() <= thr);
            }
        }
        let mut mask = vec![0u8; w * h];
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                mask[i] = raw[i] & raw[i - 1] & raw[i + 1] & raw[i - w] & raw[i + w];
            }
        }
        mask
    }

    #[test]
    fn streamed_tent_matches_whole_frame_passes() {
        let mut buf = LogBuffers::default();
        let mut mask = Vec::new();
        for (w, h, s) in [(31, 19, 1), (40, 33, 2), (37, 25, 3), (8, 9, 3)] {
            let d: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    // Holes and bumps in the right part only, an affine left part.
                    let right = x as usize > w / 2;
                    if right && i % 23 == 7 {
                        f32::NAN
                    } else {
                        let bump = if right && (i * 7919) % 13 < 3 {
                            0.3
                        } else {
                            0.0
                        };
                        20.0 + 0.1 * x - 0.05 * y + bump
                    }
                })
                .collect();
            let n = planar_mask(&d, w, h, 1, s, 0.05, &mut buf, &mut mask);
            let want = if w <= 2 * s + 2 || h <= 2 * s + 2 {
                vec![0u8; w * h]
            } else {
                reference_mask(&d, w, h, s, 0.05)
            };
            assert_eq!(mask, want, "{w}x{h}, s = {s}");
            assert_eq!(n, want.iter().map(|&v| usize::from(v)).sum::<usize>());
            assert!(n > 0 || w < 30, "{w}x{h}: nothing planar");
        }
    }

    /// In bands of rows on pools of 1 to 5 threads (17 to 83 rows a band), the mask is the
    /// whole-frame reference's.
    #[test]
    fn banded_mask_matches_whole_frame_passes() {
        let (w, h) = (53, 83);
        let d: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                // Holes and bumps in the right part and in a band of rows only.
                let rough = x as usize > w / 2 || (40..46).contains(&(i / w));
                if rough && (i % 29 == 3 || (i * 7919) % 97 < 2) {
                    f32::NAN
                } else {
                    let bump = if rough && (i * 104_729) % 17 < 4 {
                        0.4
                    } else {
                        0.0
                    };
                    20.0 + 0.1 * x - 0.05 * y + bump
                }
            })
            .collect();
        for s in [1, 2] {
            let want = reference_mask(&d, w, h, s, 0.05);
            assert!(want.contains(&1) && want.contains(&0));
            for threads in 1..=5 {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("pool");
                let (mut bufs, mut mask) = (Vec::new(), Vec::new());
                pool.install(|| {
                    planar_mask_uncounted(&d, w, h, 1, s, 0.05, &mut bufs, &mut mask, true)
                });
                assert_eq!(mask, want, "s = {s}, {threads} threads");
            }
        }
    }

    #[test]
    fn affine_is_planar_and_steps_are_not() {
        let (w, h) = (80, 60);
        let mut d: Vec<f32> = (0..w * h)
            .map(|i| 30.0 + 0.05 * (i % w) as f32 - 0.03 * (i / w) as f32)
            .collect();
        let mut buf = LogBuffers::default();
        let mut mask = Vec::new();
        let (r, s) = log_geometry(2.0);
        assert_eq!((r, s), (2, 2));
        let n = planar_mask(&d, w, h, r, s, 0.05, &mut buf, &mut mask);
        // Everything at least r+s from the border is planar.
        assert_eq!(n, (w - 2 * (2 * r + s + 1)) * (h - 2 * (2 * r + s + 1)));
        // A 1 px step at x = 40 makes a band non-planar; an invalid pixel kills its support.
        for y in 0..h {
            for x in 40..w {
                d[y * w + x] += 1.0;
            }
        }
        d[30 * w + 15] = f32::NAN;
        planar_mask(&d, w, h, r, s, 0.05, &mut buf, &mut mask);
        assert_eq!(mask[30 * w + 40], 0);
        assert_eq!(mask[30 * w + 39], 0);
        assert_eq!(mask[30 * w + 15], 0);
        let reach = 2 * r + s + 1;
        assert_eq!(mask[30 * w + 15 + reach], 0);
        assert_eq!(mask[30 * w + 15 + reach + 1], 1);
        // The whole band around the edge is non-planar, including its zero crossing.
        for x in 36..44 {
            assert_eq!(mask[30 * w + x], 0, "x = {x}");
        }
        assert_eq!(mask[30 * w + 60], 1);
    }
}
