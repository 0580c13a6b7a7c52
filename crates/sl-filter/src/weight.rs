//! The range filters' weight `w ≈ 2^x`, `x = t − e²`, in three vector operations.
//!
//! **The function.** A range filter weighs tap `q` of pixel `p` by `2^x` with
//! `x = t − e² ≤ 0`: `t = −|q − p|²/(2σ_s²)·log2 e` the tap's spatial exponent and
//! `e² = (v_q − v_p)²/(2σ_p²)·log2 e` the range term. The kernels evaluate instead the
//! *log-linear* interpolation of `2^x` between its values at integer exponents:
//!
//! ```text
//! w(x) = 2^n·(1 + φ),   n + φ = x − δ,   n integer, φ ∈ [0, 1),   δ = 0.04368,
//! ```
//!
//! which is exactly what an `f32` is when its bit pattern is read as a fixed-point number:
//! `2²³·(x − δ + 127)`, truncated to an integer, *is* the bit pattern of `w(x)` (the integer
//! part lands in the exponent field, the fraction in the mantissa; Schraudolph 1999). So the
//! whole weight is one multiply-add `y = T − e'²` (with `T` per tap and the difference
//! pre-scaled, `e' = 2^11.5·e`, so that `e'² = 2²³·e²`) and one truncating conversion; the
//! spatial weight is folded into `T` for free. The explicit AVX-512 and AVX2 kernels (see
//! [`crate::kernel`]) spend 5 vector operations per tap including the difference and the two
//! sums, against 10 and 12 with the degree-3 polynomial `2^x` this replaced (measured 1.6–1.9×
//! faster per frame) and 6 with the floor it had until session 94 (below).
//!
//! **How far from the Gaussian.** `w` is continuous, monotone in `x` and equals
//! `2^(x − δ)·(1 + φ)/2^φ`; `(1 + φ)/2^φ` lies in `[1, 1.0614]`, and `δ` centres it, so
//! `|w/2^x − 1| ≤ 2.99 %` everywhere (`WEIGHT_RELATIVE_ERROR`, asserted by the tests) down to
//! `2^−126`: a Gaussian range kernel with a ±3 % ripple, well inside what the choice of its σ
//! (a multiple of the sensor noise) already moves. The filters' accuracy is unchanged by it: on
//! `cargo xtask validate --only filter` every RMSE moved by at most 0.01 mm against the exact
//! exponential (docs/bench/README.md, session 35). [`crate::reference`] computes the same
//! function in `f64`, so the fast paths are still tested against an executable specification.
//!
//! **Negated weights, and zero below `2^−127`.** The kernels carry every weight *negated*
//! (both sums change sign, their ratio does not): `T = 2²³·(t − δ + 127) − 2³¹`, so the
//! truncated `y` is the bit pattern of `−w` read as an `i32` (the sign bit is `−2³¹`). Where
//! `2^x` falls below `2^−127`, `y` falls below `−2³¹`, out of the `i32` range, and
//! `cvttps2dq` returns its "integer indefinite" `0x8000_0000` — the bit pattern of `−0.0`, a
//! weight of exactly 0; it does the same for a NaN `y`, and `−∞` (an invalid neighbour, whose
//! sentinel makes `e'² = ∞`). So far and invalid neighbours weigh nothing with no operation
//! spent on it. Until session 94 the weights were positive and floored at `2^−126` by a
//! maximum before the conversion, one operation per tap more: removing it made the AVX2 and
//! AVX-512 fast paths 5–9 % faster on an AMD EPYC core (docs/bench/README.md, session 94).
//! Between `2^−127` and `2^−126` the weight is subnormal, a linear ramp to 0 (the exponent
//! field 0): continuous and monotone. A subnormal operand can cost a microcode assist on Intel
//! cores (about 100 cycles for a vector instruction; on the AMD EPYC the speed-up above was
//! measured on, whatever they cost is included in it). Counted on
//! real frames (5×5 disc, the Kinect's adaptive σ, every tap of every valid pixel): 0 (person)
//! to 2·10⁻⁴ (7-Scenes) of the 8-lane tap groups hold one, at most about 90 groups a 640×480
//! frame, so at most about 10 µs a frame on an Intel core if each costs an assist (an estimate:
//! no Intel core was at hand), against the 5–9 % (15–25 µs a frame at 5×5) the removed
//! maximum cost. Every product `w·e'` of a normal weight
//! stays normal: a tap's spatial weight counts as at least `2^−100`, so a weight at `2^−126`
//! comes with `e'² ≥ 2²³·26`, `|w·e'| ≥ 2^−126·1.5·10⁴`.

/// `2^11.5`: the factor folded into the range scale, so that `e'² = (2^11.5·e)² = 2²³·e²` is
/// already in units of the `f32` mantissa's last bit.
pub(crate) const E_SCALE: f64 = 2_896.309_375_740_099_7;

/// `δ` of the module docs (log2 units): centres the log-linear interpolation's error on 0.
const DELTA: f64 = 0.043_677_448_9;

/// `2²³`: one unit of the exponent field.
const EXPONENT_UNIT: f64 = 8_388_608.0;

/// Exponent bias of `f32`.
const BIAS: f64 = 127.0;

/// Log2 of the smallest spatial weight a tap counts with.
const SPATIAL_FLOOR_EXP2: f64 = -100.0;

/// `2³¹`: `T` is offset by it so that `y` is the bit pattern of the *negated* weight.
const SIGN_OFFSET: f64 = 2_147_483_648.0;

/// The lowest `y` that is a weight's bit pattern, `−2³¹` (`−0.0`): the scalar paths clamp `y`
/// to it, as `cvttps2dq`'s integer indefinite does in the SIMD kernels.
const ZERO_WEIGHT_Y: f32 = -2_147_483_648.0;

/// Largest relative error of [`range_weight`] against `2^x` (asserted by the tests).
#[cfg(test)]
const WEIGHT_RELATIVE_ERROR: f64 = 0.0299;

/// The constant of one window tap for [`range_weight`]: `T = 2²³·(t − δ + 127) − 2³¹` for the
/// tap's spatial exponent `t ≤ 0` (log2 of its spatial weight).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TapExp {
    /// `T`, in `[2²³·27 − 2³¹, 2²³·(127 − δ) − 2³¹]`.
    pub y0: f32,
}

impl TapExp {
    /// The constant for the spatial exponent `t` (`t = 0` for the centre), clamped to
    /// `[−100, 0]`: a weight never exceeds 1, every `T − e'²` fits an `i32`, and a floored
    /// weight's difference is large (module docs). NaN counts as `−∞`.
    pub(crate) fn new(t: f64) -> Self {
        let t = t.clamp(SPATIAL_FLOOR_EXP2 + DELTA, 0.0);
        let t = if t.is_nan() {
            SPATIAL_FLOOR_EXP2 + DELTA
        } else {
            t
        };
        Self {
            y0: ((t - DELTA + BIAS) * EXPONENT_UNIT - SIGN_OFFSET) as f32,
        }
    }
}

/// The (negated) weight of the centre tap (`t = 0`, `e = 0`, i.e. `T` of `t = 0` truncated):
/// every range filter path starts its sums with it.
pub(crate) const CENTRE_WEIGHT: f32 =
    f32::from_bits(((((BIAS - DELTA) * EXPONENT_UNIT - SIGN_OFFSET) as f32) as i32) as u32);

/// The negated range weight `−w` of a tap with constant `k` and scaled difference
/// `e' = 2^11.5·e` (see the module docs): the bit pattern `⌊T − e'²⌋` as an `i32`, `−0.0` below
/// `−2³¹` and for NaN.
/// `FMA`: `T − e'²` is one fused multiply-add (the SIMD kernels), otherwise a product and a
/// subtraction.
#[inline(always)]
pub(crate) fn range_weight<const FMA: bool>(e: f32, k: &TapExp) -> f32 {
    let y = if FMA {
        (-e).mul_add(e, k.y0)
    } else {
        k.y0 - e * e
    };
    // y lies below T < −2^30, where every `f32` is an integer: the truncation `cvttps2dq` of
    // the SIMD kernels is exact there, and its out-of-range result for y < −2^31 (and NaN) is
    // the bit pattern of −0.0, which this select reproduces (NaN fails the comparison).
    let y = if y > ZERO_WEIGHT_Y { y } else { ZERO_WEIGHT_Y };
    f32::from_bits(integer_bits(y))
}

/// The integer `y ∈ [−2³¹, 0)` (an integer-valued `f32`) as the bits of an `i32`.
#[inline(always)]
fn integer_bits(y: f32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        // LLVM does not vectorise the saturating `as` cast on x86 (measured 1.7× slower
        // portable filters, 4× slower AVX2 ones): `y + 1.5·2^52` in `f64` holds `2^51 + y` in
        // its low mantissa bits (ulp 1), whose low 32 bits are `y` in two's complement, and
        // converts and adds as vectors.
        (f64::from(y) + 6_755_399_441_055_744.0).to_bits() as u32
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // AArch64's conversion saturates in hardware; the value never saturates anyway.
        y as i32 as u32
    }
}

/// The same weight (positive) in `f64`, as [`crate::reference`] computes it, for the spatial
/// exponent `t` and the range term `e²` (both log2 units): the log-linear `2^x` down to
/// `2^−126`, a linear ramp to 0 at `2^−127` (the `f32` path's subnormals), 0 below.
pub(crate) fn weight_f64(t: f64, e2: f64) -> f64 {
    let y = t.clamp(SPATIAL_FLOOR_EXP2 + DELTA, 0.0) - e2 - DELTA;
    if y >= -126.0 {
        let n = y.floor();
        n.exp2() * (1.0 + (y - n))
    } else if y > -127.0 {
        (y + 127.0) * 2.0f64.powi(-126)
    } else {
        // NaN too.
        0.0
    }
}

/// `log2(e)`.
pub const LOG2_E: f32 = std::f32::consts::LOG2_E;

#[cfg(test)]
mod tests {
    use super::*;

    /// Spatial exponents `t = −d²/(2σ_s²)·log2 e` of real windows (σ_s = 1 px, d² = 0, 1, 2, 4,
    /// 5, 8) and a few others, down to the cutoff.
    fn spatial_t() -> Vec<f64> {
        let mut t: Vec<f64> = [0.0, 1.0, 2.0, 4.0, 5.0, 8.0]
            .iter()
            .map(|d2| -d2 / 2.0 * std::f64::consts::LOG2_E)
            .collect();
        t.extend([-13.0, -42.5, -99.2]);
        t
    }

    /// The weight a kernel adds, positive (the kernels carry it negated).
    fn weight<const FMA: bool>(e: f32, k: &TapExp) -> f32 {
        let w = range_weight::<FMA>(e, k);
        assert!(w.is_sign_negative(), "{e}: {w}");
        -w
    }

    #[test]
    fn weights_are_the_log_linear_exp2_within_its_bound_then_a_ramp_to_zero() {
        let normal_floor = 2.0f64.powi(-126);
        let mut worst = 0.0f64;
        let mut worst_f64 = 0.0f64;
        let (mut ramp, mut zero) = (0, 0);
        for t in spatial_t() {
            let k = TapExp::new(t);
            for i in 0..=200_000 {
                // e² from 0 to 140, past the last weight.
                let e2 = 140.0 * f64::from(i) / 200_000.0;
                let e = (e2.sqrt() * E_SCALE) as f32;
                for e in [e, -e] {
                    let es = f64::from(e) / E_SCALE;
                    let x = t - es * es;
                    let exact = x.exp2();
                    let spec = weight_f64(t, es * es);
                    for w in [weight::<false>(e, &k), weight::<true>(e, &k)] {
                        let w = f64::from(w);
                        if w >= normal_floor {
                            worst = worst.max((w / exact - 1.0).abs());
                            worst_f64 = worst_f64.max((w / spec - 1.0).abs());
                        } else if w > 0.0 {
                            // The subnormal ramp: only where 2^x is about 2^−127..2^−126.
                            assert!(exact < 1.1 * normal_floor, "t {t} e {e}: {w} for {exact}");
                            assert!((w - spec).abs() <= 2.0f64.powi(-140), "{w} {spec}");
                            ramp += 1;
                        } else {
                            assert!(exact < 0.6 * normal_floor, "t {t} e {e}: 0 for {exact}");
                            assert_eq!(spec, 0.0, "t {t} e {e}");
                            zero += 1;
                        }
                    }
                }
            }
        }
        assert!(ramp > 10 && zero > 1000, "{ramp} {zero}");
        assert!(worst < WEIGHT_RELATIVE_ERROR, "against 2^x: {worst}");
        // Tight: the interpolation uses most of the bound.
        assert!(worst > 0.029, "{worst}");
        // The f32 evaluation is the f64 specification up to the rounding of `T − e'²` (an ulp
        // of at most 128 in a value of magnitude above 2^30, i.e. 2^−16 of the weight) and of
        // `e'`.
        assert!(worst_f64 < 3.0e-5, "against the f64 function: {worst_f64}");
    }

    #[test]
    fn the_weight_is_continuous_and_monotone() {
        let k = TapExp::new(0.0);
        let mut last = f32::INFINITY;
        for i in 0..=300_000 {
            let e = (f64::from(i) / 300_000.0 * 12.0 * E_SCALE) as f32;
            let w = weight::<true>(e, &k);
            assert!(w <= last, "e' {e}: {w} after {last}");
            last = w;
        }
        assert_eq!(last, 0.0);
        // Across an exponent boundary the two sides meet: 2^n·(1 + 1) = 2^(n+1)·(1 + 0); and
        // the ramp meets the last normal binade and zero.
        for n in [-1.0, -5.0, -37.0, -126.0, -127.0] {
            let below = weight_f64(0.0, -(n + DELTA - 1e-12));
            let at = weight_f64(0.0, -(n + DELTA));
            assert!(
                (below - at).abs() <= 1e-11 * at.max(2.0f64.powi(-126)),
                "{n}: {below} {at}"
            );
        }
    }

    #[test]
    fn invalid_and_far_neighbours_weigh_nothing() {
        let k = TapExp::new(-0.72);
        for e in [
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1.0e20,
            -3.0e5 * E_SCALE as f32,
            12.0 * E_SCALE as f32,
        ] {
            // −0.0: the bit pattern of `cvttps2dq`'s integer indefinite.
            assert_eq!(
                range_weight::<false>(e, &k).to_bits(),
                (-0.0f32).to_bits(),
                "{e}"
            );
            assert_eq!(
                range_weight::<true>(e, &k).to_bits(),
                (-0.0f32).to_bits(),
                "{e}"
            );
        }
        assert_eq!(weight_f64(-0.72, f64::NAN), 0.0);
        assert_eq!(weight_f64(-0.72, f64::INFINITY), 0.0);
        // A spatial weight below 2^−100 counts as 2^−100 (also −∞ and NaN).
        for t in [-150.0, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(TapExp::new(t), TapExp::new(-100.0 + DELTA));
        }
        let w = weight::<true>(0.0, &TapExp::new(-150.0));
        assert!((f64::from(w) / 2.0f64.powi(-100) - 1.0).abs() < 0.03, "{w}");
        // The centre: 2^−δ·(1 + …) within the bound of 1.
        let c = -CENTRE_WEIGHT;
        assert_eq!(CENTRE_WEIGHT, range_weight::<true>(0.0, &TapExp::new(0.0)));
        assert_eq!(CENTRE_WEIGHT, range_weight::<false>(0.0, &TapExp::new(0.0)));
        assert!((f64::from(c) - 1.0).abs() < WEIGHT_RELATIVE_ERROR, "{c}");
        // `T` rounded to an `f32` of magnitude above 2^30 (ulp 128, 2^−16 of the mantissa).
        assert!((f64::from(c) / weight_f64(0.0, 0.0) - 1.0).abs() < 2.0f64.powi(-16));
    }
}
