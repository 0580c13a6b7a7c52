//! Row kernels of the extractor, written so that the per-pixel work vectorises with the
//! baseline instruction set (no target features): depth → disparity with 2×2 averaging, and
//! the residual test of a run of pixels against one plane with masked moment accumulation.
//!
//! The moments of the pixels that pass the test are accumulated in 8 `f32` lanes as
//! **residuals** `r = D − (a·x + c)` against the tested plane and column offsets `x − x₀`
//! within segments of at most 256 pixels: both are small, so `f32` keeps the sums exact to
//! well below the disparity noise (integer moments are exact below 2²⁴), and each segment is
//! flushed into the `f64` moments of [`AffineSums`] by the exact change of variables
//! `D = r + a·x + c`, `x = x₀ + x'`.

use wide::{CmpGt, CmpLt, f32x4, u32x4};

use crate::fit::AffineSums;

/// Lanes of the accumulators.
pub(crate) const LANES: usize = 8;
/// Longest stretch of pixels accumulated in `f32` before a flush to `f64`.
const SEGMENT: usize = 256;

/// Metric sums of a plane's samples: their number, `Σ1/D`, `Σx/D`, `Σy/D` and `Σ(r/D)²` (r
/// the residual against the plane's prediction). With `D = f·B/Z` they give the centroid and
/// the RMS point-to-plane distance.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct InvSums {
    pub n: f64,
    pub si: f64,
    pub sxi: f64,
    pub syi: f64,
    pub sr2: f64,
}

impl InvSums {
    /// Adds (`sign` = 1) or removes (`sign` = −1) one sample of disparity `d` and residual `r`.
    #[inline]
    pub fn add(&mut self, x: f64, y: f64, d: f64, r: f64, sign: f64) {
        let inv = 1.0 / d;
        self.n += sign;
        self.si += sign * inv;
        self.sxi += sign * x * inv;
        self.syi += sign * y * inv;
        self.sr2 += sign * (r * inv) * (r * inv);
    }

    /// Adds the sums of `o`.
    pub fn merge(&mut self, o: &InvSums) {
        self.n += o.n;
        self.si += o.si;
        self.sxi += o.sxi;
        self.syi += o.syi;
        self.sr2 += o.sr2;
    }
}

/// Horizontal sum of 4 lanes, in `f64`.
#[inline(always)]
fn hsum4(v: f32x4) -> f64 {
    let t = v.to_array();
    (f64::from(t[0]) + f64::from(t[1])) + (f64::from(t[2]) + f64::from(t[3]))
}

/// The lane accumulators (one register each: few enough to stay in registers).
#[derive(Clone, Copy)]
struct Lanes {
    sr: f32x4,
    sxr: f32x4,
    srr: f32x4,
    si: f32x4,
    sxi: f32x4,
    sr2: f32x4,
}

impl Lanes {
    const ZERO: Lanes = Lanes {
        sr: f32x4::ZERO,
        sxr: f32x4::ZERO,
        srr: f32x4::ZERO,
        si: f32x4::ZERO,
        sxi: f32x4::ZERO,
        sr2: f32x4::ZERO,
    };
}

/// Keep bytes (little-endian word) of each 8-bit lane mask.
static SPREAD: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut i = 0;
    while i < 256 {
        let mut v = 0u64;
        let mut b = 0;
        while b < 8 {
            if i & (1 << b) != 0 {
                v |= 1u64 << (8 * b);
            }
            b += 1;
        }
        t[i] = v;
        i += 1;
    }
    t
};

/// All-ones 16-bit lanes of each 8-bit lane mask (labels of the pixels that pass).
static SPREAD16: [[u16; LANES]; 256] = {
    let mut t = [[0u16; LANES]; 256];
    let mut i = 0;
    while i < 256 {
        let mut b = 0;
        while b < LANES {
            if i & (1 << b) != 0 {
                t[i][b] = u16::MAX;
            }
            b += 1;
        }
        i += 1;
    }
    t
};

#[inline(always)]
fn load4(d: &[f32], o: usize) -> f32x4 {
    // One unaligned load (NaN past the end, which callers never ask for).
    match d.get(o..o + 4).map(<[f32; 4]>::try_from) {
        Some(Ok(a)) => f32x4::from(a),
        _ => f32x4::splat(f32::NAN),
    }
}

/// One chunk of 8 pixels at offsets `x`, `x + 4` (lane vectors) from the segment start;
/// returns the 8-bit mask of the pixels that pass.
#[inline(always)]
fn step<const MOM: bool, const INV: bool>(
    l: &mut Lanes,
    d: &[f32; LANES],
    x: (f32x4, f32x4),
    a: f32x4,
    c0: f32x4,
    tau: f32x4,
) -> usize {
    let zero = f32x4::ZERO;
    let (d0, d1) = (load4(d, 0), load4(d, 4));
    let r0 = d0 - (a * x.0 + c0);
    let r1 = d1 - (a * x.1 + c0);
    let m0 = r0.abs().cmp_lt(tau) & d0.cmp_gt(zero);
    let m1 = r1.abs().cmp_lt(tau) & d1.cmp_gt(zero);
    if MOM {
        let (rm0, rm1) = (r0 & m0, r1 & m1);
        l.sr += rm0 + rm1;
        l.sxr += rm0 * x.0 + rm1 * x.1;
        l.srr += rm0 * rm0 + rm1 * rm1;
        if INV {
            let one = f32x4::splat(1.0);
            // Rejected lanes may divide by 0: masked away.
            let (iv0, iv1) = ((one / d0) & m0, (one / d1) & m1);
            let (ri0, ri1) = (rm0 * iv0, rm1 * iv1);
            l.si += iv0 + iv1;
            l.sxi += iv0 * x.0 + iv1 * x.1;
            l.sr2 += ri0 * ri0 + ri1 * ri1;
        }
    }
    (m0.move_mask() | (m1.move_mask() << 4)) as usize & 0xff
}

/// Count, `Σo` and `Σo²` over the set bits `o` of each 8-bit mask (the baseline x86-64 has no
/// `popcnt`).
static BIT_MOMENTS: [(u32, u32, u32); 256] = {
    let mut t = [(0u32, 0u32, 0u32); 256];
    let mut m = 0;
    while m < 256 {
        let (mut c, mut s1, mut s2) = (0u32, 0u32, 0u32);
        let mut o = 0;
        while o < 8 {
            if m & (1 << o) != 0 {
                c += 1;
                s1 += o;
                s2 += o * o;
            }
            o += 1;
        }
        t[m as usize] = (c, s1, s2);
        m += 1;
    }
    t
};

/// Count, `Σx'` and `Σx'²` of the rejected pixels of a segment (x' the offset in the segment).
#[derive(Clone, Copy, Default)]
struct Misses {
    n: u32,
    sx: u32,
    sxx: u64,
}

impl Misses {
    /// Adds the pixels of the 8-bit `mask` at offsets `xb + o`.
    #[inline(always)]
    fn add(&mut self, mask: usize, xb: u32) {
        if mask != 0 {
            let (c, t1, t2) = BIT_MOMENTS[mask & 0xff];
            self.n += c;
            self.sx += c * xb + t1;
            self.sxx += u64::from(c * xb * xb + 2 * xb * t1 + t2);
        }
    }
}

/// Tests the first `n` pixels `d[k]` at columns `x0 + k` of row `y` against the plane whose
/// prediction on this row is `a·x + c_row`: pixel `k` passes when `|D − prediction| < tau` and
/// `D > 0` (NaN fails). Writes 1/0 into `keep[k]` and returns the number that pass. With `MOM`
/// the moments of the passing pixels are added to `sums` (and with `INV` the metric sums to
/// `inv`, residuals against the same prediction).
///
/// `d` and `keep` may extend beyond `n` (the rest of the row): up to 7 values beyond `n` may
/// be read from `d` (ignored) and up to 7 bytes beyond `n` of `keep` overwritten (with 0).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn fit_run<const MOM: bool, const INV: bool>(
    d: &[f32],
    keep: &mut [u8],
    n: usize,
    x0: usize,
    y: f64,
    a: f64,
    c_row: f64,
    tau: f32,
    sums: &mut AffineSums,
    inv: &mut InvSums,
) -> usize {
    fit_run_labels::<MOM, INV, false>(d, keep, &mut [], 0, n, x0, y, a, c_row, tau, sums, inv)
}

/// [`fit_run`] that also writes `v` (or 0 for the pixels that fail) into `labels`, which may
/// extend beyond `n` like `keep` (up to 7 values beyond `n` are overwritten with 0).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn fit_run_labels<const MOM: bool, const INV: bool, const LAB: bool>(
    d: &[f32],
    keep: &mut [u8],
    labels: &mut [u16],
    v: u16,
    n: usize,
    x0: usize,
    y: f64,
    a: f64,
    c_row: f64,
    tau: f32,
    sums: &mut AffineSums,
    inv: &mut InvSums,
) -> usize {
    let n = n.min(d.len()).min(keep.len());
    let af = a as f32;
    let (av, tv) = (f32x4::splat(af), f32x4::splat(tau));
    let lane = f32x4::from([0.0, 1.0, 2.0, 3.0]);
    let (four, eight) = (f32x4::splat(4.0), f32x4::splat(8.0));
    let mut kept = 0usize;
    let mut s0 = 0;
    while s0 < n {
        let s1 = (s0 + SEGMENT).min(n);
        let len = s1 - s0;
        let xs = (x0 + s0) as f64;
        let c0 = (a * xs + c_row) as f32;
        let cv = f32x4::splat(c0);
        let mut l = Lanes::ZERO;
        let mut x = (lane, lane + four);
        let mut miss = Misses::default();
        let full = len / LANES;
        let mut o = s0;
        let mut xb = 0u32;
        // The whole chunks of the segment (`s0 + body <= n`, within `d` and `keep`; labels
        // only where they exist).
        let body = full * LANES;
        let dseg = d.get(s0..s0 + body).unwrap_or(&[]);
        let kseg = keep.get_mut(s0..s0 + body).unwrap_or(&mut []);
        let nl = labels.len();
        let lseg = labels
            .get_mut(s0.min(nl)..(s0 + body).min(nl))
            .unwrap_or(&mut []);
        let mut lch = lseg.chunks_exact_mut(LANES);
        for (dc, kc) in dseg.chunks_exact(LANES).zip(kseg.chunks_exact_mut(LANES)) {
            let (Ok(dc), Ok(kc)) = (
                <&[f32; LANES]>::try_from(dc),
                <&mut [u8; LANES]>::try_from(kc),
            ) else {
                break;
            };
            let bits = step::<MOM, INV>(&mut l, dc, x, av, cv, tv);
            let kb = SPREAD[bits].to_le_bytes();
            *kc = kb;
            if LAB && let Some(Ok(lc)) = lch.next().map(<&mut [u16; LANES]>::try_from) {
                *lc = SPREAD16[bits].map(|m| m & v);
            }
            if MOM {
                miss.add(!bits & 0xff, xb);
            } else {
                miss.n += BIT_MOMENTS[!bits & 0xff].0;
            }
            x = (x.0 + eight, x.1 + eight);
            xb += LANES as u32;
            o += LANES;
        }
        let nr = s1 - o;
        if nr > 0 {
            // The tail: lanes beyond `nr` are NaN (they fail and are not counted).
            let valid = |i: usize| i < nr;
            let dt: [f32; LANES] = match d.get(o..o + LANES) {
                Some(full) => std::array::from_fn(|i| if valid(i) { full[i] } else { f32::NAN }),
                None => std::array::from_fn(|i| {
                    d.get(o + i)
                        .copied()
                        .filter(|_| valid(i))
                        .unwrap_or(f32::NAN)
                }),
            };
            let bits = step::<MOM, INV>(&mut l, &dt, x, av, cv, tv);
            let kb = SPREAD[bits].to_le_bytes();
            match keep.get_mut(o..o + LANES) {
                Some(kc) => kc.copy_from_slice(&kb),
                None => {
                    for (i, k) in keep[o..].iter_mut().enumerate().take(nr) {
                        *k = kb[i];
                    }
                }
            }
            if LAB {
                let lc = match labels.get_mut(o..o + LANES) {
                    Some(lc) => lc,
                    None => labels
                        .get_mut(o..(o + nr).min(labels.len()))
                        .unwrap_or(&mut []),
                };
                for (lv, &m) in lc.iter_mut().zip(&SPREAD16[bits]) {
                    *lv = m & v;
                }
            }
            miss.add(!bits & ((1 << nr) - 1), xb);
        }
        s0 = s1;
        let lenf = len as f64;
        let nk = lenf - f64::from(miss.n);
        kept += len - miss.n as usize;
        if !MOM || nk == 0.0 {
            continue;
        }
        let n = nk;
        let sx = lenf * (lenf - 1.0) / 2.0 - f64::from(miss.sx);
        let sxx = (lenf - 1.0) * lenf * (2.0 * lenf - 1.0) / 6.0 - miss.sxx as f64;
        let (sr, sxr, srr) = (hsum4(l.sr), hsum4(l.sxr), hsum4(l.srr));
        // In segment coordinates x' = x − xs the prediction is ra·x' + rc.
        let (ra, rc) = (f64::from(af), f64::from(c0));
        let sd = sr + ra * sx + rc * n;
        let sxd_local = sxr + ra * sxx + rc * sx;
        let sdd =
            srr + 2.0 * ra * sxr + 2.0 * rc * sr + ra * ra * sxx + 2.0 * ra * rc * sx + rc * rc * n;
        let gx = sx + xs * n;
        let gxx = sxx + 2.0 * xs * sx + xs * xs * n;
        sums.n += n;
        sums.sx += gx;
        sums.sy += y * n;
        sums.sd += sd;
        sums.sxx += gxx;
        sums.sxy += y * gx;
        sums.syy += y * y * n;
        sums.sxd += sxd_local + xs * sd;
        sums.syd += y * sd;
        sums.sdd += sdd;
        if INV {
            let si = hsum4(l.si);
            inv.n += n;
            inv.si += si;
            inv.sxi += hsum4(l.sxi) + xs * si;
            inv.syi += y * si;
            inv.sr2 += hsum4(l.sr2);
        }
    }
    kept
}

/// Low mantissa bits of an encoded residual that carry the candidate index.
const IDX_MASK: u32 = 0xFFF;

/// The candidate search encodes `|r| + 1` with its low 12 mantissa bits replaced by the
/// candidate's index: one `min` then tracks the smallest residual and its plane together (the
/// residual is quantised to 2⁻¹¹ relative, far below the noise). Values are ≥ 1, so the float
/// order is the order of the residuals.
#[derive(Clone, Copy)]
struct Enc {
    one: f32x4,
    hi: f32x4,
    lane: [f32x4; 2],
}

impl Enc {
    #[inline(always)]
    fn new() -> Self {
        let lane = f32x4::from([0.0, 1.0, 2.0, 3.0]);
        Enc {
            one: f32x4::splat(1.0),
            hi: f32x4::splat(f32::from_bits(!IDX_MASK)),
            lane: [lane, lane + f32x4::splat(4.0)],
        }
    }

    /// Encoded `|d − (a·(x0 + lane) + c)|` for candidate index `k` (both halves).
    #[inline(always)]
    fn residuals(&self, d: &[f32x4; 2], a: f32, c0: f32, k: u32) -> [f32x4; 2] {
        let (av, cv) = (f32x4::splat(a), f32x4::splat(c0));
        let kv = f32x4::splat(f32::from_bits(k));
        [0, 1].map(|h| (((d[h] - (av * self.lane[h] + cv)).abs() + self.one) & self.hi) | kv)
    }

    /// The encoded threshold with the "no plane" index.
    #[inline(always)]
    fn limit(&self, tau: f32) -> f32x4 {
        f32x4::splat(f32::from_bits(
            ((tau + 1.0).to_bits() & !IDX_MASK) | IDX_MASK,
        ))
    }
}

/// Bit mask of the valid (positive, not NaN) values among 8 disparities.
#[inline(always)]
pub(crate) fn valid_mask(d: &[f32; LANES]) -> u32 {
    let z = f32x4::ZERO;
    let (a, b) = (load4(d, 0).cmp_gt(z), load4(d, 4).cmp_gt(z));
    (a.move_mask() | (b.move_mask() << 4)) as u32 & 0xff
}

/// Labels (index + 1, 0 = none) of 8 encoded residuals.
#[inline(always)]
fn decode(v: &[f32x4; 2]) -> [u16; LANES] {
    // (`IDX_MASK + 1` wraps to 0: no plane.)
    let (m, one) = (u32x4::splat(IDX_MASK), u32x4::splat(1));
    let dec = |x: f32x4| (((u32x4::from(x.to_array().map(f32::to_bits)) & m) + one) & m).to_array();
    let (a, b) = (dec(v[0]), dec(v[1]));
    [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]].map(|i| i as u16)
}

/// The two best candidates of 8 pixels ([`search8_two`]): labels (index + 1, 0 = none under
/// `tau` or an invalid pixel) and absolute residuals (quantised to 2⁻¹¹ relative; meaningless
/// where the label is 0).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Best2 {
    pub best: [u16; LANES],
    pub best_res: [f32; LANES],
    pub second: [u16; LANES],
    pub second_res: [f32; LANES],
}

/// For 8 pixels (disparity `d`, NaN or 0 = invalid) at columns `x0 + k` of a row: the labels
/// (index + 1) of the two candidate planes with the smallest |residual| under `tau` (0 if
/// none), and their residuals. The planes' predictions on this row are `fa[k]·x + rowc[k]`.
#[inline]
pub(crate) fn search8_two(
    d: &[f32; LANES],
    x0: f32,
    cands: &[u16],
    fa: &[f32],
    rowc: &[f32],
    tau: f32,
) -> Best2 {
    let e = Enc::new();
    let dd = [load4(d, 0), load4(d, 4)];
    let lim = e.limit(tau);
    let mut best = [lim; 2];
    let mut second = [lim; 2];
    for &k in cands {
        let ku = k as usize;
        let (Some(&a), Some(&c)) = (fa.get(ku), rowc.get(ku)) else {
            continue;
        };
        let r = e.residuals(&dd, a, a * x0 + c, u32::from(k));
        // `fast_min` / `fast_max` return their argument when `r` is NaN (invalid pixel): the
        // pixel keeps "no plane".
        for h in 0..2 {
            second[h] = r[h].fast_max(best[h]).fast_min(second[h]);
            best[h] = r[h].fast_min(best[h]);
        }
    }
    Best2 {
        best: decode(&best),
        best_res: decode_residual(&best),
        second: decode(&second),
        second_res: decode_residual(&second),
    }
}

/// The absolute residuals of 8 encoded values (the index bits cleared, minus the offset 1).
#[inline(always)]
fn decode_residual(v: &[f32x4; 2]) -> [f32; LANES] {
    let dec = |x: f32x4| {
        x.to_array()
            .map(|f| f32::from_bits(f.to_bits() & !IDX_MASK) - 1.0)
    };
    let (a, b) = (dec(v[0]), dec(v[1]));
    [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
}

/// Depth (metres, any non-positive or non-finite value invalid) → disparity `f·B/Z` (0 when
/// invalid) for one row.
#[inline]
pub(crate) fn depth_to_disparity_row(z: &[f32], d: &mut [f32], fb: f32) {
    let (fbv, zero, inf) = (f32x4::splat(fb), f32x4::ZERO, f32x4::splat(f32::INFINITY));
    let mut zc = z.chunks_exact(4);
    let mut dc = d.chunks_exact_mut(4);
    for (zs, ds) in (&mut zc).zip(&mut dc) {
        let zv = load4(zs, 0);
        let ok = zv.cmp_gt(zero) & zv.cmp_lt(inf);
        ds.copy_from_slice(&((fbv / zv) & ok).to_array());
    }
    for (o, &zv) in dc.into_remainder().iter_mut().zip(zc.remainder()) {
        *o = if zv > 0.0 && zv < f32::INFINITY {
            fb / zv
        } else {
            0.0
        };
    }
}

/// The 2×2 block means of two disparity rows, by blocks of 256 columns through stack scratch
/// rows (which stay in L1): into `strict`, NaN where any of the four is invalid (not
/// positive); into `partial`, the same, except that a block with invalid pixels takes the mean
/// of a diagonal whose two pixels are valid ([`block_mean_or_diagonal`]).
#[inline]
pub(crate) fn downsample_rows(r0: &[f32], r1: &[f32], strict: &mut [f32], partial: &mut [f32]) {
    const B: usize = 256;
    let (mut sum, mut min) = ([0f32; B], [0f32; B]);
    for ((b0, b1), (ob, pb)) in r0
        .chunks(B)
        .zip(r1.chunks(B))
        .zip(strict.chunks_mut(B / 2).zip(partial.chunks_mut(B / 2)))
    {
        let n = b0.len().min(b1.len());
        let (sum, min) = (&mut sum[..n], &mut min[..n]);
        for (((s, m), &a), &b) in sum.iter_mut().zip(min.iter_mut()).zip(b0).zip(b1) {
            *s = a + b;
            *m = if a < b { a } else { b };
        }
        for (i, (((o, po), sp), mp)) in ob
            .iter_mut()
            .zip(pb.iter_mut())
            .zip(sum.chunks_exact(2))
            .zip(min.chunks_exact(2))
            .enumerate()
        {
            let mm = if mp[0] < mp[1] { mp[0] } else { mp[1] };
            let v = 0.25 * (sp[0] + sp[1]);
            if mm > 0.0 {
                *o = v;
                *po = v;
            } else {
                *o = f32::NAN;
                let x = 2 * i;
                *po = block_mean_or_diagonal([b0[x], b0[x + 1], b1[x], b1[x + 1]]);
            }
        }
    }
}

/// The value of a 2×2 block `[top-left, top-right, bottom-left, bottom-right]` of disparities at
/// its centre: the mean of the four when all are valid (positive; NaN is not), else the mean of
/// a diagonal whose two values are (`top-left` + `bottom-right`, then `top-right` +
/// `bottom-left`), else NaN.
///
/// A diagonal's midpoint is the block's centre, so for an affine function (the disparity of a
/// plane) the diagonal's mean is exactly the block's mean: scattered invalid pixels (a
/// stereo camera's dropped matches, a depth map aligned to a larger colour image) then cost a
/// block only when both diagonals lose a pixel, instead of whenever one pixel of the four is
/// missing: with 5 % of the pixels missing at random, 1 % of the blocks and 4 % of the
/// 4×4-pixel cells (four blocks) are lost instead of 19 % and 56 %.
#[inline]
pub(crate) fn block_mean_or_diagonal(v: [f32; 4]) -> f32 {
    let [tl, tr, bl, br] = v;
    let (a, b, c, d) = (tl > 0.0, tr > 0.0, bl > 0.0, br > 0.0);
    if a && b && c && d {
        0.25 * ((tl + bl) + (tr + br))
    } else if a && d {
        0.5 * (tl + br)
    } else if b && c {
        0.5 * (tr + bl)
    } else {
        f32::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plane::DisparityAffine;

    #[test]
    fn run_moments_match_direct_sums() {
        let f = DisparityAffine {
            a: 0.031,
            b: -0.012,
            c: 61.0,
        };
        // Long rows (several segments and a tail) with a few outliers and invalid pixels.
        let x0 = 37usize;
        let n = 613;
        let (mut s, mut inv) = (AffineSums::default(), InvSums::default());
        let (mut t, mut tinv) = (AffineSums::default(), InvSums::default());
        for y in [211.0, 218.0, 240.0] {
            let d: Vec<f32> = (0..n)
                .map(|k| {
                    let x = (x0 + k) as f64;
                    let noise = 0.1 * ((k * 7919 % 97) as f64 / 97.0 - 0.5);
                    let v = f.eval(x, y) + noise + if k % 53 == 0 { 2.0 } else { 0.0 };
                    if k % 101 == 5 { 0.0 } else { v as f32 }
                })
                .collect();
            // A longer buffer: the kernel may write ahead.
            let mut keep = vec![0u8; n + 8];
            let kept = fit_run::<true, true>(
                &d,
                &mut keep,
                n,
                x0,
                y,
                f.a,
                f.b * y + f.c,
                0.5,
                &mut s,
                &mut inv,
            );
            let mut count = 0;
            for (k, &dv) in d.iter().enumerate() {
                let x = (x0 + k) as f64;
                let r = f64::from(dv) - f.eval(x, y);
                let ok = r.abs() < 0.5 && dv > 0.0;
                assert_eq!(keep[k] == 1, ok, "pixel {k}");
                if ok {
                    count += 1;
                    t.add(x, y, f64::from(dv));
                    tinv.add(x, y, f64::from(dv), r, 1.0);
                }
            }
            assert_eq!(kept, count);
        }
        let close = |u: f64, v: f64| (u - v).abs() <= 1e-6 * u.abs().max(1.0);
        for (u, v) in [
            (s.n, t.n),
            (s.sx, t.sx),
            (s.sy, t.sy),
            (s.sd, t.sd),
            (s.sxx, t.sxx),
            (s.sxy, t.sxy),
            (s.syy, t.syy),
            (s.sxd, t.sxd),
            (s.syd, t.syd),
            (s.sdd, t.sdd),
            (inv.si, tinv.si),
            (inv.sxi, tinv.sxi),
            (inv.syi, tinv.syi),
        ] {
            assert!(close(u, v), "{u} vs {v}");
        }
        // Σ(r/D)² sums tiny f32 terms: relative precision of f32 accumulation.
        assert!(
            (inv.sr2 - tinv.sr2).abs() < 1e-5 * tinv.sr2,
            "{} vs {}",
            inv.sr2,
            tinv.sr2
        );
        // The fits agree and the RMS (which needs Σd² to high relative precision) too.
        let (g, h) = (s.solve().unwrap(), t.solve().unwrap());
        assert!(
            (g.a - h.a).abs() < 1e-7 && (g.b - h.b).abs() < 1e-7,
            "{g:?} {h:?}"
        );
        assert!((s.rms(&g) - t.rms(&h)).abs() < 1e-5);
        assert!((s.rms(&f) - t.rms(&f)).abs() < 1e-5);
    }

    /// The vectorised candidate searches against a scalar reference.
    #[test]
    fn searches_match_scalar() {
        let planes: Vec<(f32, f32)> = (0..23)
            .map(|k| (0.01 * (k as f32 - 11.0), 40.0 + 0.13 * k as f32))
            .collect();
        let fa: Vec<f32> = planes.iter().map(|p| p.0).collect();
        let rowc: Vec<f32> = planes.iter().map(|p| p.1).collect();
        let cands: Vec<u16> = (0..23).rev().collect();
        let x0 = 96.0f32;
        for seed in 0..200u32 {
            let d: [f32; LANES] = std::array::from_fn(|i| {
                let h = (seed.wrapping_mul(2654435761) ^ (i as u32 * 40503)) % 1000;
                match h % 17 {
                    0 => f32::NAN,
                    1 => 0.0,
                    _ => 38.0 + h as f32 * 0.006,
                }
            });
            let two = search8_two(&d, x0, &cands, &fa, &rowc, 0.5);
            let (b1, b2) = (two.best, two.second);
            for i in 0..LANES {
                let res = |k: u16| {
                    let (a, c) = planes[k as usize - 1];
                    (d[i] - (a * (x0 + i as f32) + c)).abs()
                };
                let mut r: Vec<(f32, u16)> = cands
                    .iter()
                    .map(|&k| (res(k + 1), k + 1))
                    .filter(|(r, _)| *r < 0.5)
                    .collect();
                r.sort_by(|p, q| p.0.total_cmp(&q.0));
                // The encoding quantises residuals to 2⁻¹¹ relative: near-ties may swap and a
                // residual within that of τ may count as inside.
                let q = 1e-3;
                let ok = |got: u16, want: Option<f32>| match (got, want) {
                    (0, None) => true,
                    (0, Some(w)) => w > 0.5 - q,
                    (g, None) => res(g) < 0.5 + q,
                    (g, Some(w)) => (res(g) - w).abs() <= q,
                };
                if d[i].is_nan() || d[i] <= 0.0 {
                    assert_eq!((two.best[i], two.second[i]), (0, 0), "invalid pixel");
                    continue;
                }
                let best = r.first().map(|p| p.0);
                assert!(ok(b1[i], best), "{r:?} vs {}", b1[i]);
                let second = r.get(1).map(|p| p.0);
                assert!(
                    ok(b2[i], second) || (b2[i] != 0 && ok(b2[i], best)),
                    "{r:?} vs {} {}",
                    b1[i],
                    b2[i]
                );
                if b1[i] != 0 {
                    assert_ne!(b1[i], b2[i]);
                    assert!((two.best_res[i] - res(b1[i])).abs() <= q, "{r:?}");
                }
                if b2[i] != 0 {
                    assert!((two.second_res[i] - res(b2[i])).abs() <= q, "{r:?}");
                }
            }
        }
    }

    #[test]
    fn disparity_rows() {
        let z = [1.0f32, 0.0, -1.0, f32::NAN, f32::INFINITY, 2.0];
        let mut d = [9.0f32; 6];
        depth_to_disparity_row(&z, &mut d, 40.0);
        assert_eq!(d, [40.0, 0.0, 0.0, 0.0, 0.0, 20.0]);
        let (mut h, mut p) = ([0f32; 3], [0f32; 3]);
        downsample_rows(
            &[1.0, 2.0, 3.0, 0.0, 5.0, 5.0],
            &[3.0, 2.0, 1.0, 1.0, 5.0, 5.0],
            &mut h,
            &mut p,
        );
        assert_eq!((h[0], p[0]), (2.0, 2.0));
        // One pixel of the block missing: strict NaN; partial the other diagonal (3 and 1),
        // exact for a plane.
        assert!(h[1].is_nan());
        assert_eq!(p[1], 2.0);
        assert_eq!((h[2], p[2]), (5.0, 5.0));
        // Both diagonals broken: invalid in both.
        downsample_rows(&[1.0, 0.0], &[1.0, 0.0], &mut h[..1], &mut p[..1]);
        assert!(h[0].is_nan() && p[0].is_nan());
        downsample_rows(&[0.0, 0.0], &[1.0, 1.0], &mut h[..1], &mut p[..1]);
        assert!(h[0].is_nan() && p[0].is_nan());
        // One diagonal complete: its mean.
        downsample_rows(&[1.0, 0.0], &[0.0, 3.0], &mut h[..1], &mut p[..1]);
        assert!(h[0].is_nan());
        assert_eq!(p[0], 2.0);
    }

    /// A block with one or two missing pixels on one diagonal takes the other diagonal's mean:
    /// for an affine function the value at the block's centre, as the mean of all four.
    #[test]
    fn a_block_with_a_diagonal_left_has_the_planes_value_at_its_centre() {
        let f = |x: f32, y: f32| 20.0 + 0.3 * x - 0.7 * y;
        let (x0, y0) = (10.0f32, 4.0f32);
        let v = [
            f(x0, y0),
            f(x0 + 1.0, y0),
            f(x0, y0 + 1.0),
            f(x0 + 1.0, y0 + 1.0),
        ];
        let centre = f(x0 + 0.5, y0 + 0.5);
        let full = block_mean_or_diagonal(v);
        assert!((full - centre).abs() < 1e-5);
        for missing in [[0usize].as_slice(), &[1], &[2], &[3], &[0, 3], &[1, 2]] {
            let mut w = v;
            for &m in missing {
                w[m] = 0.0;
            }
            let got = block_mean_or_diagonal(w);
            assert!(
                (got - centre).abs() < 1e-5,
                "{missing:?}: {got} vs {centre}"
            );
        }
        for missing in [[0usize, 1], [0, 2], [1, 3], [2, 3]] {
            let mut w = v;
            for m in missing {
                w[m] = 0.0;
            }
            assert!(block_mean_or_diagonal(w).is_nan(), "{missing:?}");
        }
    }
}
