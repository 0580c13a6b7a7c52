//! The explicit AVX-512 kernel of the range filters' constant-radius fast paths.
//!
//! Same arithmetic as `chunk` with `range_weight::<true>` (bit-identical, asserted by
//! `x256`'s test for both explicit kernels): per tap the difference `e' = v_q·s − s·v_p` (one
//! multiply-add), `y = T − e'²` (one multiply-add), the truncating conversion whose bit pattern
//! is the negated weight (`vcvttps2dq`; 0 below `2^−127`, see [`crate::weight`]), and the two
//! sums: 5 vector operations (6 with the floor `vmaxps` of session 93 and before, 10 with the
//! polynomial `2^x` of session 34 and before). Without the floor: 5×5 disc 0.193 → 0.176 ms,
//! square 0.285 → 0.265 ms, 7×7 disc 0.321 → 0.303 ms, square 0.485 → 0.459 ms (AMD EPYC,
//! person frame, one thread, best of 3 runs of 100, two interleaved rounds; session 94). Two
//! 16-lane groups are
//! interleaved, which hides the latency of each tap's dependency chain (measured ~25 % faster
//! than one group at a time). The AVX2 kernel's three passes per chunk (scales, taps, epilogue) were tried here
//! too: no gain on a Zen 4 core (5×5 square 0.306 → 0.310 ms at best, some runs 0.41 ms).

use std::arch::x86_64::*;

use super::{
    CHUNK, CW, MAX_CLASSES, MAX_FAST_RADIUS, MAX_SCALE, Padded, RangeMode, Taps, VALID_LIMIT,
    class, for_each_chunk, is_row, is_tap,
};
use crate::weight::CENTRE_WEIGHT;

/// 16 lanes from the start of `a` (at least 16 long), as an unaligned vector load.
#[inline(always)]
fn load(a: &[f32]) -> __m512 {
    let mut v = [0.0f32; 16];
    v.copy_from_slice(&a[..16]);
    bytemuck::cast(v)
}

/// Filters the block of whole rows `out` (see [`super::block_fast`]).
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
#[inline]
pub(super) fn block<
    const R: usize,
    const DISC: bool,
    const S: usize,
    M: RangeMode,
    const DISP: bool,
>(
    taps: Taps<'_>,
    p: &Padded<'_>,
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    let k = 2 * R + 1;
    let mut t = [0.0f32; MAX_CLASSES];
    for dy in 0..k {
        for dx in 0..k {
            t[class::<R>(dy, dx)] = taps.exps[dy * k + dx].y0;
        }
    }
    let rows_on = std::hint::black_box(u32::MAX);
    for_each_chunk::<S, 32>(p, out, k, |rows, dst, groups| {
        chunk::<R, DISC, S, M, DISP>(rows, &t, dst, mode, fb, rows_on, groups);
    });
}

/// One chunk of `CHUNK` output pixels, two 16-lane groups at a time. Not inlined: inlined
/// into the row loop, LLVM's scheduler hoists the taps' independent work far ahead of the
/// sums and spills most of it to the stack (measured 1.7× slower).
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
#[inline(never)]
fn chunk<const R: usize, const DISC: bool, const S: usize, M: RangeMode, const DISP: bool>(
    rows: &[&[f32; CW]; 2 * MAX_FAST_RADIUS + 1],
    t: &[f32; MAX_CLASSES],
    dst: &mut [f32; CHUNK],
    mode: M,
    fb: f32,
    rows_on: u32,
    groups: u32,
) {
    let coef = _mm512_set1_ps(mode.coef());
    let max_scale = _mm512_set1_ps(MAX_SCALE);
    let tv: [__m512; MAX_CLASSES] = core::array::from_fn(|c| _mm512_set1_ps(t[c]));
    let zero = _mm512_setzero_ps();
    let inf = _mm512_set1_ps(f32::INFINITY);
    let valid_limit = _mm512_set1_ps(VALID_LIMIT);
    let fbv = _mm512_set1_ps(fb);
    let scale = |c: __m512| {
        if M::ADAPTIVE {
            _mm512_min_ps(_mm512_div_ps(coef, _mm512_mul_ps(c, c)), max_scale)
        } else {
            coef
        }
    };
    for g in 0..CHUNK / 32 {
        let i = 32 * g;
        let ca = load(&rows[R][i + R * S..]);
        let cb = load(&rows[R][i + 16 + R * S..]);
        // Invalid centres hold the sentinel (≥ VALID_LIMIT), valid ones are below it.
        if (S > 1 && groups & (1 << g) == 0)
            || _mm512_cmp_ps_mask::<_CMP_LT_OQ>(_mm512_min_ps(ca, cb), valid_limit) == 0
        {
            // All 32 centres are invalid (holes are common in Kinect frames): the output
            // is 0 whatever the neighbours are. Or, in a dilated pass (the test is compiled
            // out of the others), none of them is kept.
            dst[i..i + 32].fill(0.0);
            continue;
        }
        let (sa, sb) = (scale(ca), scale(cb));
        let (zsa, zsb) = (_mm512_mul_ps(sa, ca), _mm512_mul_ps(sb, cb));
        // The centre tap (difference 0) initialises the sums.
        let centre = _mm512_set1_ps(CENTRE_WEIGHT);
        let (mut swa, mut swb) = (centre, centre);
        let (mut sda, mut sdb) = (zero, zero);
        macro_rules! weigh {
            ($nb:expr, $s:ident, $zs:ident, $sw:ident, $sd:ident, $t:ident) => {
                let e = _mm512_fmsub_ps($nb, $s, $zs);
                let y = _mm512_fnmadd_ps(e, e, $t);
                // ⌊y⌋'s bit pattern is the negated weight; −0.0 below −2³¹ and for NaN and
                // −∞ (invalid neighbours): the conversion's integer indefinite.
                let w = _mm512_castsi512_ps(_mm512_cvttps_epi32(y));
                $sw = _mm512_add_ps($sw, w);
                $sd = _mm512_fmadd_ps(w, e, $sd);
            };
        }
        // The window unrolled; taps outside it or at the centre vanish at compile time.
        macro_rules! tap {
            ($dy:literal, $dx:literal) => {
                if is_tap::<R, DISC>($dy, $dx) {
                    let tc = tv[class::<R>($dy, $dx)];
                    weigh!(load(&rows[$dy][i + $dx * S..]), sa, zsa, swa, sda, tc);
                    weigh!(load(&rows[$dy][i + 16 + $dx * S..]), sb, zsb, swb, sdb, tc);
                }
            };
        }
        // Each window row is its own basic block (`rows_on` is all ones, but opaque to the
        // optimiser): this bounds how far LLVM's instruction scheduler moves the taps'
        // independent work ahead of the sums. Without it, the thin-LTO build computes all
        // the weights of a group first and spills them to the stack (measured 25–40 %
        // slower in isolation).
        macro_rules! row {
            ($dy:literal) => {
                if is_row::<R>($dy) && rows_on & (1 << $dy) != 0 {
                    tap!($dy, 0);
                    tap!($dy, 1);
                    tap!($dy, 2);
                    tap!($dy, 3);
                    tap!($dy, 4);
                    tap!($dy, 5);
                    tap!($dy, 6);
                }
            };
        }
        row!(0);
        row!(1);
        row!(2);
        row!(3);
        row!(4);
        row!(5);
        row!(6);
        for (c, s, sw, sd, off) in [(ca, sa, swa, sda, 0), (cb, sb, swb, sdb, 16)] {
            let valid = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(c, zero)
                & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(c, valid_limit);
            // The epilogue of `super::finish`, with masks.
            let v = _mm512_add_ps(c, _mm512_div_ps(sd, _mm512_mul_ps(sw, s)));
            let (v, c_out) = if DISP {
                (_mm512_div_ps(fbv, v), _mm512_div_ps(fbv, c))
            } else {
                (v, c)
            };
            let ok = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(v, zero)
                & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v, inf);
            let v = _mm512_mask_blend_ps(ok, c_out, v);
            let v: [f32; 16] = bytemuck::cast(_mm512_maskz_mov_ps(valid, v));
            dst[i + off..i + off + 16].copy_from_slice(&v);
        }
    }
}
