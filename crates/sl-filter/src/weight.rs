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
//! whole weight is one multiply-add `y = T − e'²` (with `T = 2²³·(t − δ + 127)` per tap and the
//! difference pre-scaled, `e' = 2^11.5·e`, so that `e'² = 2²³·e²`), one truncating conversion
//! and the floor below; the spatial weight is folded into `T` for free. The explicit AVX-512
//! and AVX2 kernels (see [`crate::kernel`]) spend 6 vector operations per tap including the
//! difference and the two sums, against 10 and 12 with the degree-3 polynomial `2^x` this
//! replaced (measured 1.6–1.9× faster per frame).
//!
//! **How far from the Gaussian.** `w` is continuous, monotone in `x` and equals
//! `2^(x − δ)·(1 + φ)/2^φ`; `(1 + φ)/2^φ` lies in `[1, 1.0614]`, and `δ` centres it, so
//! `|w/2^x − 1| ≤ 2.99 %` everywhere (`WEIGHT_RELATIVE_ERROR`, asserted by the tests): a
//! Gaussian range kernel with a ±3 % ripple, well inside what the choice of its σ (a multiple of
//! the sensor noise) already moves. The filters' accuracy is unchanged by it: on `cargo xtask
//! validate --only filter` every RMSE moved by at most 0.01 mm against the exact exponential
//! (docs/bench/README.md, session 35). [`crate::reference`] computes the same function in `f64`,
//! so the fast paths are still tested against an executable specification.
//!
//! **The floor.** No weight is below `2^−126`, the smallest normal `f32`: the kernels take the
//! maximum of `y` and `2²³` before truncating it (one operation; `maxps` returns `2²³` for a
//! NaN or `−∞`, an invalid neighbour whose sentinel makes `e'² = ∞`), and a tap's spatial
//! weight counts as at least `2^−100`. So a far or invalid neighbour weighs `2^−126` instead of
//! 0 — it moves a filtered value by at most `2^−126` times its distance to the sentinel
//! (`10^18`), about `10^−20` of the value — and no weight, and no product of a weight with a
//! difference, is ever subnormal (a subnormal result costs a ~100-cycle microcode assist per
//! vector instruction on Intel cores; measured ~130× on a Skylake-SP). A floored weight comes
//! with `e'² ≥ 2²³·26` (the spatial floor), so `|w·e'| ≥ 2^−126·1.5·10⁴` stays normal too.
//! (A compare and a zero-masking would make those weights exactly 0 at one more operation per
//! tap: measured 11 % slower on the AVX-512 path.)

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

/// The bit pattern of the smallest weight, `2^−126` (`2²³`, the smallest normal `f32`).
pub(crate) const FLOOR_BITS: i32 = 1 << 23;

/// Largest relative error of [`range_weight`] against `2^x` (asserted by the tests).
#[cfg(test)]
const WEIGHT_RELATIVE_ERROR: f64 = 0.0299;

/// The constant of one window tap for [`range_weight`]: `T = 2²³·(t − δ + 127)` for the tap's
/// spatial exponent `t ≤ 0` (log2 of its spatial weight).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TapExp {
    /// `T`, in `[2²³·27, 2²³·(127 − δ)]`.
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
            y0: ((t - DELTA + BIAS) * EXPONENT_UNIT) as f32,
        }
    }
}

/// The weight of the centre tap (`t = 0`, `e = 0`, i.e. `T` of `t = 0` truncated): every range
/// filter path starts its sums with it.
pub(crate) const CENTRE_WEIGHT: f32 =
    f32::from_bits((((BIAS - DELTA) * EXPONENT_UNIT) as f32) as u32);

/// The range weight of a tap with constant `k` and scaled difference `e' = 2^11.5·e` (see the
/// module docs): the bit pattern `max(⌊T − e'²⌋, 2²³)` (`2²³` also for NaN).
/// `FMA`: `T − e'²` is one fused multiply-add (the SIMD kernels), otherwise a product and a
/// subtraction.
#[inline(always)]
pub(crate) fn range_weight<const FMA: bool>(e: f32, k: &TapExp) -> f32 {
    let y = if FMA {
        (-e).mul_add(e, k.y0)
    } else {
        k.y0 - e * e
    };
    // Above the floor y lies in [2^23, 2^31), where every `f32` is an integer: the truncation
    // `cvttps2dq` of the SIMD kernels is exact there, and their `maxps` with 2^23 before it is
    // this select (NaN fails the comparison).
    let y = if y > FLOOR_BITS as f32 {
        y
    } else {
        FLOOR_BITS as f32
    };
    f32::from_bits(integer_bits(y))
}

/// The integer `y ∈ [2^23, 2^31)` (an integer-valued `f32`) as a `u32`.
#[inline(always)]
fn integer_bits(y: f32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        // LLVM does not vectorise the saturating `as` cast on x86 (measured 1.7× slower
        // portable filters, 4× slower AVX2 ones): `y + 2^52` in `f64` holds the integer in its
        // low mantissa bits, and converts and adds as vectors.
        (f64::from(y) + 4_503_599_627_370_496.0).to_bits() as u32
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // AArch64's conversion saturates in hardware; the value never saturates anyway.
        y as i32 as u32
    }
}

/// The same weight in `f64`, as [`crate::reference`] computes it, for the spatial exponent `t`
/// and the range term `e²` (both log2 units).
pub(crate) fn weight_f64(t: f64, e2: f64) -> f64 {
    let y = t.clamp(SPATIAL_FLOOR_EXP2 + DELTA, 0.0) - e2 - DELTA;
    let n = y.floor();
    let w = n.exp2() * (1.0 + (y - n));
    // NaN fails `w > floor`.
    let floor = 2.0f64.powi(-126);
    if w > floor { w } else { floor }
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

    #[test]
    fn weights_are_the_log_linear_exp2_within_its_bound_and_never_below_2_pow_minus_126() {
        let floor = 2.0f64.powi(-126);
        let mut worst = 0.0f64;
        let mut worst_f64 = 0.0f64;
        let mut floored = 0;
        for t in spatial_t() {
            let k = TapExp::new(t);
            for i in 0..=200_000 {
                // e² from 0 to 140, past the floor.
                let e2 = 140.0 * f64::from(i) / 200_000.0;
                let e = (e2.sqrt() * E_SCALE) as f32;
                for e in [e, -e] {
                    let es = f64::from(e) / E_SCALE;
                    let x = t - es * es;
                    let exact = x.exp2();
                    let spec = weight_f64(t, es * es);
                    for w in [range_weight::<false>(e, &k), range_weight::<true>(e, &k)] {
                        assert!(w.is_normal(), "t {t} e {e}: {w}");
                        worst_f64 = worst_f64.max((f64::from(w) / spec - 1.0).abs());
                        if f64::from(w) == floor {
                            // Only where 2^x is at most about the floor.
                            assert!(exact < 2.0 * floor, "t {t} e {e}: floor for {exact}");
                            floored += 1;
                        } else {
                            worst = worst.max((f64::from(w) / exact - 1.0).abs());
                        }
                    }
                }
            }
        }
        assert!(floored > 1000);
        assert!(worst < WEIGHT_RELATIVE_ERROR, "against 2^x: {worst}");
        // Tight: the interpolation uses most of the bound.
        assert!(worst > 0.029, "{worst}");
        // The f32 evaluation is the f64 specification up to the rounding of `T − e'²` (an ulp
        // of at most 64 in a value above 2^27, i.e. 2^−17 of the weight) and of `e'`.
        assert!(worst_f64 < 2.0e-5, "against the f64 function: {worst_f64}");
    }

    #[test]
    fn the_weight_is_continuous_and_monotone() {
        let k = TapExp::new(0.0);
        let mut last = f32::INFINITY;
        for i in 0..=300_000 {
            let e = (f64::from(i) / 300_000.0 * 11.0 * E_SCALE) as f32;
            let w = range_weight::<true>(e, &k);
            assert!(w <= last, "e' {e}: {w} after {last}");
            last = w;
        }
        // Across an exponent boundary the two sides meet: 2^n·(1 + 1) = 2^(n+1)·(1 + 0).
        for n in [-1.0, -5.0, -37.0] {
            let below = weight_f64(0.0, -(n + DELTA - 1e-12));
            let at = weight_f64(0.0, -(n + DELTA));
            assert!((below / at - 1.0).abs() < 1e-11, "{n}: {below} {at}");
        }
    }

    #[test]
    fn invalid_and_far_neighbours_weigh_the_floor() {
        let floor = f32::from_bits(FLOOR_BITS as u32);
        assert_eq!(f64::from(floor), 2.0f64.powi(-126));
        let k = TapExp::new(-0.72);
        for e in [
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1.0e20,
            -3.0e5 * E_SCALE as f32,
            12.0 * E_SCALE as f32,
        ] {
            assert_eq!(range_weight::<false>(e, &k), floor, "{e}");
            assert_eq!(range_weight::<true>(e, &k), floor, "{e}");
        }
        // A spatial weight below 2^−100 counts as 2^−100 (also −∞ and NaN).
        for t in [-150.0, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(TapExp::new(t), TapExp::new(-100.0 + DELTA));
        }
        let w = range_weight::<true>(0.0, &TapExp::new(-150.0));
        assert!((f64::from(w) / 2.0f64.powi(-100) - 1.0).abs() < 0.03, "{w}");
        // The centre: 2^−δ·(1 + …) within the bound of 1.
        let c = CENTRE_WEIGHT;
        assert_eq!(c, range_weight::<true>(0.0, &TapExp::new(0.0)));
        assert_eq!(c, range_weight::<false>(0.0, &TapExp::new(0.0)));
        assert!((f64::from(c) - 1.0).abs() < WEIGHT_RELATIVE_ERROR, "{c}");
        assert!((f64::from(c) / weight_f64(0.0, 0.0) - 1.0).abs() < 1e-6);
    }
}
