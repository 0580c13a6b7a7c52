//! The explicit AVX2 + FMA kernel of the range filters' constant-radius fast paths.
//!
//! Bit-identical to the compiler-vectorised `chunk` with `range_weight::<true>` (asserted by
//! the tests below): every tap performs the same fused operations in the same order — the
//! difference `e'` and `y = T − e'²` (two multiply-adds), the truncating conversion whose bit
//! pattern is the negated weight (0 below `2^−127`: see [`crate::weight`]), and the two sums
//! (5 vector operations and one load; 6 with the floor of session 93 and before, 13 with the
//! polynomial `2^x` of session 34 and before). What the explicit code adds:
//!
//! - **Two 8-lane groups are interleaved**, as in the AVX-512 kernel: each group's two sums
//!   are dependency chains of one multiply-add (or add) per tap, so one group alone waits on
//!   their latency (measured on a Zen 4 core, 7×7: 1.77 ms a frame with one group, 1.26 ms
//!   with two). The cheaper weight leaves enough of AVX2's 16 registers for both groups.
//! - **The per-tap constant is a memory operand** of the multiply-add, reloaded for every
//!   group instead of held in registers.
//! - **Groups of 16 pixels whose centres are all invalid are skipped** (their output is 0,
//!   as in `finish`), as the AVX-512 kernel does.
//! - **No floor**: the conversion's out-of-range result is the zero weight (negated weights,
//!   [`crate::weight`]), so no maximum is taken: 5×5 disc 0.311 → 0.290 ms, square 0.486 →
//!   0.448 ms (AMD EPYC, AVX2 code, person frame, one thread, best of 3 runs of 100, three
//!   interleaved rounds; session 94).
//! - **Three passes over a chunk**: the centres' range scales (a division each), then the taps
//!   (only the two sums per pixel are kept), then the epilogue (another division). The
//!   divisions leave the chain from a group's first tap to its stored result, so one group's
//!   taps overlap the next one's start; measured on a Zen 4 core (AVX2 code, person frame,
//!   one thread, best of 3 interleaved runs of 60): 5×5 square 0.553 → 0.539 ms, disc 0.356 →
//!   0.344 ms; 7×7 square 0.963 → 0.936 ms, disc 0.624 → 0.606 ms. The AVX-512 kernel gained
//!   nothing from it.

use std::arch::x86_64::*;

use super::{
    CHUNK, CW, MAX_FAST_RADIUS, MAX_SCALE, Padded, RangeMode, Taps, VALID_LIMIT, for_each_chunk,
    is_tap,
};
use crate::weight::{CENTRE_WEIGHT, TapExp};

/// 8 lanes from the start of `a` (at least 8 long), as an unaligned vector load.
#[inline(always)]
fn load(a: &[f32]) -> __m256 {
    let mut v = [0.0f32; 8];
    v.copy_from_slice(&a[..8]);
    bytemuck::cast(v)
}

/// Side of the frame the unrolled windows are listed in (the 7×7 window of the largest radius).
const FRAME: usize = 2 * MAX_FAST_RADIUS + 1;
/// Positions of that frame.
const TAPS: usize = FRAME * FRAME;

/// Index `dy * FRAME + dx` of the `n`-th tap (row-major, centre excluded) of the window.
const fn nth_tap<const R: usize, const DISC: bool>(n: usize) -> Option<usize> {
    let mut count = 0;
    let mut dy = 0;
    while dy < FRAME {
        let mut dx = 0;
        while dx < FRAME {
            if is_tap::<R, DISC>(dy, dx) {
                if count == n {
                    return Some(dy * FRAME + dx);
                }
                count += 1;
            }
            dx += 1;
        }
        dy += 1;
    }
    None
}

/// The constant `T` of one tap, broadcast.
#[derive(Clone, Copy)]
struct Class {
    y0: __m256,
}

/// Filters the block of whole rows `out` (see [`super::block_fast`]).
#[target_feature(enable = "avx2,fma")]
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
    // One entry per position of the 7×7 frame (`dy * 7 + dx`), not per tap class: each tap
    // loads its own constants right where it uses them (see `chunk`).
    let mut per_tap = [TapExp::default(); TAPS];
    for dy in 0..k {
        for dx in 0..k {
            per_tap[dy * FRAME + dx] = taps.exps[dy * k + dx];
        }
    }
    let cls: [Class; TAPS] = per_tap.map(|e| Class {
        y0: _mm256_set1_ps(e.y0),
    });
    let taps_on = std::hint::black_box(u64::MAX);
    for_each_chunk::<S, 16>(p, out, k, |rows, dst, groups| {
        chunk::<R, DISC, S, M, DISP>(rows, &cls, dst, mode, fb, taps_on, groups);
    });
}

/// One chunk of `CHUNK` output pixels in three passes (scales, taps, epilogue), the taps two
/// 8-lane groups at a time. Not inlined, for the same reason as the AVX-512 kernel's `chunk`
/// (the scheduler would hoist and spill the taps' work).
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn chunk<const R: usize, const DISC: bool, const S: usize, M: RangeMode, const DISP: bool>(
    rows: &[&[f32; CW]; 2 * MAX_FAST_RADIUS + 1],
    cls: &[Class; TAPS],
    dst: &mut [f32; CHUNK],
    mode: M,
    fb: f32,
    taps_on: u64,
    groups: u32,
) {
    let coef = _mm256_set1_ps(mode.coef());
    let max_scale = _mm256_set1_ps(MAX_SCALE);
    let zero = _mm256_setzero_ps();
    let centre = _mm256_set1_ps(CENTRE_WEIGHT);
    let inf = _mm256_set1_ps(f32::INFINITY);
    let valid_limit = _mm256_set1_ps(VALID_LIMIT);
    let fbv = _mm256_set1_ps(fb);
    // `Adaptive::scale`: `coef / c²`, then `s < MAX_SCALE ? s : MAX_SCALE` (= `vminps`).
    let scale = |c: __m256| {
        if M::ADAPTIVE {
            _mm256_min_ps(_mm256_div_ps(coef, _mm256_mul_ps(c, c)), max_scale)
        } else {
            coef
        }
    };
    // `c > 0 && c < VALID_LIMIT` (the centre test of `super::finish`).
    let valid = |c: __m256| {
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(c, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(c, valid_limit),
        )
    };
    // Phase 1, independent per 8 lanes: the range scale `s` and `s·c` of every centre (their
    // divisions off the taps' critical path), and which groups of 16 have a valid centre.
    let mut sv = [zero; CHUNK / 8];
    let mut zsv = [zero; CHUNK / 8];
    let mut okv = [zero; CHUNK / 8];
    for (j, ((s, zs), ok)) in sv.iter_mut().zip(&mut zsv).zip(&mut okv).enumerate() {
        let c = load(&rows[R][8 * j + R * S..]);
        *s = scale(c);
        *zs = _mm256_mul_ps(*s, c);
        *ok = valid(c);
    }
    let mut swv = [centre; CHUNK / 8];
    let mut sdv = [zero; CHUNK / 8];
    // Phase 2: the taps, two 8-lane groups interleaved; only the sums leave the loop.
    for g in 0..CHUNK / 16 {
        let i = 16 * g;
        if (S > 1 && groups & (1 << g) == 0)
            || _mm256_movemask_ps(_mm256_or_ps(okv[2 * g], okv[2 * g + 1])) == 0
        {
            // No valid centre among the 16: phase 3 writes 0 there whatever the sums are. Or,
            // in a dilated pass (the only ones given a mask by the multi-scale filter; the test
            // is compiled out of the others), none of them is kept: whatever phase 3 writes is
            // replaced by the input.
            continue;
        }
        // Opaque to the optimiser: the constants are reloaded for every group, where each tap
        // uses them (folded into the multiply-adds as memory operands), instead of being
        // hoisted out of the loop into more values than AVX2's 16 registers hold.
        let cls = std::hint::black_box(cls);
        let (sa, sb) = (sv[2 * g], sv[2 * g + 1]);
        let (zsa, zsb) = (zsv[2 * g], zsv[2 * g + 1]);
        // The centre tap (difference 0) initialises the sums.
        let (mut swa, mut swb) = (centre, centre);
        let (mut sda, mut sdb) = (zero, zero);
        macro_rules! weigh {
            ($nb:expr, $s:ident, $zs:ident, $sw:ident, $sd:ident, $y0:expr) => {
                // `range_weight::<true>`: e', y = T − e'², ⌊y⌋ as the bits of −w (−0.0
                // when y < −2³¹ or NaN: the conversion's integer indefinite).
                let e = _mm256_fmsub_ps($nb, $s, $zs);
                let y = _mm256_fnmadd_ps(e, e, $y0);
                let w = _mm256_castsi256_ps(_mm256_cvttps_epi32(y));
                $sw = _mm256_add_ps($sw, w);
                $sd = _mm256_fmadd_ps(w, e, $sd);
            };
        }
        macro_rules! step {
            ($n:literal) => {
                // One basic block per three taps (`taps_on` is all ones but opaque): it keeps
                // the scheduler from hoisting later taps' work ahead and spilling it.
                if $n % 3 != 0 || taps_on & (1 << $n) != 0 {
                    if let Some(q) = const { nth_tap::<R, DISC>($n) } {
                        let row = rows[q / FRAME];
                        weigh!(
                            load(&row[i + q % FRAME * S..]),
                            sa,
                            zsa,
                            swa,
                            sda,
                            cls[q].y0
                        );
                        weigh!(
                            load(&row[i + 8 + q % FRAME * S..]),
                            sb,
                            zsb,
                            swb,
                            sdb,
                            cls[q].y0
                        );
                    }
                }
            };
        }
        step!(0);
        step!(1);
        step!(2);
        step!(3);
        step!(4);
        step!(5);
        step!(6);
        step!(7);
        step!(8);
        step!(9);
        step!(10);
        step!(11);
        step!(12);
        step!(13);
        step!(14);
        step!(15);
        step!(16);
        step!(17);
        step!(18);
        step!(19);
        step!(20);
        step!(21);
        step!(22);
        step!(23);
        step!(24);
        step!(25);
        step!(26);
        step!(27);
        step!(28);
        step!(29);
        step!(30);
        step!(31);
        step!(32);
        step!(33);
        step!(34);
        step!(35);
        step!(36);
        step!(37);
        step!(38);
        step!(39);
        step!(40);
        step!(41);
        step!(42);
        step!(43);
        step!(44);
        step!(45);
        step!(46);
        step!(47);
        swv[2 * g] = swa;
        swv[2 * g + 1] = swb;
        sdv[2 * g] = sda;
        sdv[2 * g + 1] = sdb;
    }
    // Phase 3, independent per 8 lanes: the epilogue of `super::finish`, with masks.
    for (j, out) in dst.chunks_exact_mut(8).enumerate() {
        let c = load(&rows[R][8 * j + R * S..]);
        let v = _mm256_add_ps(c, _mm256_div_ps(sdv[j], _mm256_mul_ps(swv[j], sv[j])));
        let (v, c_out) = if DISP {
            (_mm256_div_ps(fbv, v), _mm256_div_ps(fbv, c))
        } else {
            (v, c)
        };
        let ok = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(v, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(v, inf),
        );
        let v = _mm256_blendv_ps(c_out, v, ok);
        let v: [f32; 8] = bytemuck::cast(_mm256_and_ps(okv[j], v));
        out.copy_from_slice(&v);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{
        Adaptive, BLOCK_ROWS, Fixed, INVALID_FILL, Isa, RangeMode, Source, Taps, dispatch,
        stride_for, vectorised_avx2_reference,
    };
    use crate::weight::{E_SCALE, LOG2_E, TapExp};

    /// Filters the whole image block by block with the explicit kernel of `isa`, or the
    /// compiler-vectorised AVX2 + FMA code (`None`).
    fn filter<M: RangeMode, const DISP: bool>(
        taps: Taps<'_>,
        src: &Source<'_>,
        mode: M,
        fb: f32,
        isa: Option<Isa>,
    ) -> Vec<f32> {
        let (w, h) = (src.width, src.height);
        let stride = stride_for(w, taps.radius);
        let mut out = vec![0.0f32; w * h];
        let mut buf = vec![0.0f32; stride * (BLOCK_ROWS + 2 * taps.radius)];
        for (bi, block) in out.chunks_mut(w * BLOCK_ROWS).enumerate() {
            let rows = block.len() / w;
            let buf = &mut buf[..stride * (rows + 2 * taps.radius)];
            let y0 = bi * BLOCK_ROWS;
            if let Some(isa) = isa {
                dispatch::<M, DISP>(isa, taps, src, y0, stride, buf, block, mode, fb);
            } else {
                // The caller checked AVX2 and FMA support at run time.
                vectorised_avx2_reference::<M, DISP>(taps, src, y0, stride, buf, block, mode, fb);
            }
        }
        out
    }

    /// A frame with smooth surfaces, depth steps of every size (some range weights cut off,
    /// some not), noise, isolated and large holes, and a width that is not a multiple of the
    /// chunk.
    fn frame(w: usize, h: usize) -> Vec<f32> {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        let mut d = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let base = 0.6 + 0.01 * x as f32 + 0.004 * y as f32;
                let step = if (x / 23 + y / 11) % 3 == 0 {
                    0.002 * (x % 7) as f32 + 0.3 * ((y / 5) % 2) as f32
                } else {
                    0.0
                };
                let mut z = base + step + 0.003 * (rnd() - 0.5);
                if rnd() < 0.05 || ((40..75).contains(&x) && (5..30).contains(&y)) {
                    z = 0.0;
                }
                d[y * w + x] = z;
            }
        }
        d
    }

    fn check<M: RangeMode, const DISP: bool>(isa: Isa, src: &Source<'_>, mode: M, fb: f32) {
        for r in 1..=3usize {
            for disc in [false, true] {
                let k = 2 * r + 1;
                let sigma = r as f64 / 2.0;
                let mut exps = Vec::new();
                for dy in 0..k {
                    for dx in 0..k {
                        let d2 = (dx.abs_diff(r).pow(2) + dy.abs_diff(r).pow(2)) as f64;
                        let t = -d2 / (2.0 * sigma * sigma) * f64::from(LOG2_E);
                        exps.push(TapExp::new(t));
                    }
                }
                let taps = Taps {
                    radius: r,
                    step: 1,
                    disc,
                    taps: &[],
                    exps: &exps,
                };
                let a = filter::<M, DISP>(taps, src, mode, fb, Some(isa));
                let b = filter::<M, DISP>(taps, src, mode, fb, None);
                let diff = a
                    .iter()
                    .zip(&b)
                    .filter(|(x, y)| x.to_bits() != y.to_bits())
                    .count();
                assert_eq!(
                    diff, 0,
                    "{isa:?} r {r} disc {disc} DISP {DISP}: {diff} pixels differ"
                );
                assert!(a.iter().filter(|&&v| v > 0.0).count() > a.len() / 2);
            }
        }
    }

    /// The explicit AVX2 and AVX-512 kernels, each against the compiler-vectorised AVX2 + FMA
    /// code (the AVX-512 one where the CPU has it).
    #[test]
    fn bit_identical_to_the_compiler_vectorised_code() {
        if !Isa::Avx2.is_supported() {
            return;
        }
        for isa in [Isa::Avx2, Isa::Avx512] {
            if isa.is_supported() {
                check_isa(isa);
            }
        }
    }

    fn check_isa(isa: Isa) {
        let (w, h) = (301, 37);
        let data = frame(w, h);
        let src = Source {
            data: &data,
            width: w,
            height: h,
            fill: INVALID_FILL,
            disparity_fb: None,
            min_m: 0.1,
            max_m: 20.0,
            keep: None,
        };
        let coef = |sigma: f64| ((f64::from(LOG2_E) / 2.0).sqrt() / sigma * E_SCALE) as f32;
        // Adaptive with the Kinect's k and a tenth of it (more cut-off weights), fixed σ.
        check::<_, false>(isa, &src, Adaptive(coef(0.0028)), 0.0);
        check::<_, false>(isa, &src, Adaptive(coef(0.00028)), 0.0);
        check::<_, false>(isa, &src, Fixed(coef(0.01)), 0.0);
        // Disparity (fb / z) with a fixed σ in disparity pixels.
        let fb = 580.0 * 0.075;
        let disp = Source {
            disparity_fb: Some(fb),
            ..src
        };
        check::<_, true>(isa, &disp, Fixed(coef(0.5)), fb);
    }
}
