//! A fast, branch-free `2^x` / `e^x`, and the range weights of the bilateral filters.
//!
//! `2^x` is split into `2^round(x) · 2^f` with `f ∈ [−½, ½]`: the integer part is built directly
//! in the exponent bits of an `f32` (rounding with the `1.5·2²³` magic-number trick, so the whole
//! function is a handful of adds, multiplies and integer ops that vectorise on SSE2, AVX2 and
//! AVX-512), and `2^f` is a degree-4 polynomial fitted for minimal *relative* error on
//! `[−½, ½]` (iteratively reweighted least squares on Chebyshev nodes). Its relative error is
//! `2.6·10⁻⁶` in exact arithmetic; with `f32` rounding the measured bound against
//! `f64::exp2` is below `4·10⁻⁶` over the whole domain (tested in this module).
//!
//! The filters' range weight `w = 2^(t − e²)` (`t ≤ 0` the tap's spatial exponent, `e` the
//! scaled depth difference) uses a degree-3 fit instead (relative error `7.5·10⁻⁵`, bound
//! [`RANGE_WEIGHT_RELATIVE_ERROR`]) and is specialised per tap (`TapExp`, `range_weight`):
//! `e²` is rounded with the magic number *inside* the multiply-adds that compute it, and the
//! spatial weight `2^t` is folded into the polynomial's coefficients, so a tap costs 9 vector
//! operations including the cutoff. The AVX-512 kernel evaluates the same polynomial on `[0, 1)`
//! (`EXP2_UNIT`) with `vreduceps` / `vscalefps` doing the split (7 operations; see
//! [`crate::kernel`]).
//!
//! [`exp2_fast`] clamps inputs below −126 to `2^−126` (the smallest normal `f32`; NaN also maps
//! there). The range weights are exactly 0 below about `2^−100` and for infinite or NaN
//! differences, which is how far-away and invalid neighbours contribute nothing, and which
//! keeps every product of a weight and a depth difference out of the slow subnormal range
//! (measured: a subnormal result costs ~130× a normal one on this Skylake-SP).

/// `1.5·2²³ + 127`: adding it to an `|x| < 2²¹` rounds `x` to an integer held in the low
/// mantissa bits, already offset by the exponent bias 127; shifting those bits left by 23 then
/// drops the constant high bits and leaves exactly the `f32` exponent field of `2^round(x)`.
pub(crate) const MAGIC: f32 = 12_583_039.0;

/// Minimax-relative-error coefficients of `2^f` on `[−½, ½]`, degree 4.
#[cfg(test)]
const C0: f32 = 0.999_999_3;
#[cfg(test)]
const C1: f32 = 0.693_121_8;
#[cfg(test)]
const C2: f32 = 0.240_247_44;
#[cfg(test)]
const C3: f32 = 0.055_917_86;
#[cfg(test)]
const C4: f32 = 0.009_570_101;
/// Degree-3 coefficients (relative error 7.5·10⁻⁵), used for the filters' range weights.
const D0: f32 = 0.999_928_06;
const D1: f32 = 0.693_260_97;
const D2: f32 = 0.242_611_13;
const D3: f32 = 0.055_171_665;

/// The degree-3 polynomial of [`range_weight`] moved to `[0, 1)`: `2^f ≈ √2·D(f − ½)` (same
/// relative error), coefficients in Horner order `[P3, P2, P1, P0]`. Used by the AVX-512
/// kernel, which splits `y = ⌊y⌋ + f` with `vreduceps`.
pub(crate) const EXP2_UNIT: [f32; 4] = [0.078_024_52, 0.226_067_18, 0.695_833_5, 0.999_925_2];

/// `log2(e)`.
pub const LOG2_E: f32 = std::f32::consts::LOG2_E;

/// Largest relative error of [`exp2_fast`] and [`exp_fast`] against the exact function on their
/// domains (asserted by the tests of this module).
#[cfg(test)]
pub const MAX_RELATIVE_ERROR: f32 = 4.0e-6;

/// `2^x` for `x ≤ 127` with relative error below [`MAX_RELATIVE_ERROR`]; `x < −126` (and NaN)
/// give `2^−126`.
#[inline(always)]
#[cfg(test)]
pub fn exp2_fast(x: f32) -> f32 {
    // `x > -126` is false for NaN, so NaN maps to the clamp value. Written as a select (not
    // `f32::max`) so that it compiles to a single `maxps`.
    let x = if x > -126.0 { x } else { -126.0 };
    let x = if x < 127.0 { x } else { 127.0 };
    let t = x + MAGIC;
    let f = x - (t - MAGIC);
    let p = C0 + f * (C1 + f * (C2 + f * (C3 + f * C4)));
    let scale = f32::from_bits(t.to_bits() << 23);
    p * scale
}

/// Largest relative error of the filters' range-weight function (degree-3 polynomial), asserted
/// by the tests of this module. Its effect on a filtered depth is at most about twice this
/// times the weighted spread of the depth differences in the window: < 0.2 µm for the 1–3 mm
/// spreads the range kernel lets through at 1 m.
#[cfg(test)]
pub const RANGE_WEIGHT_RELATIVE_ERROR: f32 = 8.0e-5;

/// Range weights `2^(t − e²)` whose exponent is below about −100 are exactly 0 (see
/// [`TapExp`]).
pub(crate) const WEIGHT_CUTOFF_EXP2: f64 = -100.0;

/// The constants of one window tap for [`range_weight`]: the tap's spatial weight `2^t` folded
/// into the polynomial's coefficients, and the cutoff.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TapExp {
    /// `2^t·D3, 2^t·D2, 2^t·D1, 2^t·D0` (Horner order).
    pub c: [f32; 4],
    /// Lanes with `MAGIC − round(e²)` at or below this get weight exactly 0.
    pub cut: f32,
}

impl TapExp {
    /// The constants for the spatial exponent `t ≤ 0` (log2 of the tap's spatial weight).
    pub(crate) fn new(t: f64) -> Self {
        // Keep iff round(e²) < floor(100 + t): then t − e² ≥ −99.5, so every kept weight and
        // every product of a kept weight with a depth difference is a normal f32.
        let limit = (t - WEIGHT_CUTOFF_EXP2).floor();
        if limit < 1.0 {
            // The spatial weight alone is below the cutoff: the tap never contributes.
            return Self {
                c: [0.0; 4],
                cut: f32::INFINITY,
            };
        }
        let ws = t.exp2();
        let d = [D3, D2, D1, D0].map(|d| (f64::from(d) * ws) as f32);
        Self {
            c: d,
            cut: (f64::from(MAGIC) - limit) as f32,
        }
    }
}

/// The range-filter weight `w = 2^(t − e²)` of a tap with constants `k = TapExp::new(t)`,
/// with relative error below [`RANGE_WEIGHT_RELATIVE_ERROR`], and exactly 0 when
/// `t − e²` is below about −100 (and for infinite or NaN `e`).
///
/// `e²` is split as `m + g` with `m = round(e²)` (the `1.5·2²³` magic number again, fused
/// into the `e²` of a multiply-add) and `|g| ≤ ½`, so `w = 2^(−m) · (2^t·2^(−g))`: the
/// integer part goes into the exponent bits, and `2^t·2^(−g)` is a degree-3 polynomial with the
/// spatial weight folded into its coefficients. Per tap this is 9 operations (two multiply-adds
/// for the split, one subtraction, three for the polynomial, shift, compare, masked multiply) —
/// one fewer than computing `x = t − e²` and then `2^x` (previous version).
/// Returning 0 (rather than a tiny weight) matters for speed: `tiny weight × depth difference`
/// would be a subnormal number, and subnormal arithmetic costs a ~100-cycle microcode assist
/// per vector instruction on x86.
#[inline(always)]
pub(crate) fn range_weight<const FMA: bool>(e: f32, k: &TapExp) -> f32 {
    // t1 = MAGIC − round(e²), exact (the fused multiply-add rounds once, to the integer grid).
    let t1 = if FMA {
        (-e).mul_add(e, MAGIC)
    } else {
        MAGIC - e * e
    };
    let m = MAGIC - t1;
    // −g = m − e² ∈ [−½, ½].
    let g = if FMA { (-e).mul_add(e, m) } else { m - e * e };
    let [c3, c2, c1, c0] = k.c;
    let p = if FMA {
        g.mul_add(g.mul_add(g.mul_add(c3, c2), c1), c0)
    } else {
        c0 + g * (c1 + g * (c2 + g * c3))
    };
    // The low 9 bits of t1's mantissa are 127 − m: shifted into the exponent field they make
    // 2^(−m) for 0 ≤ m ≤ 126 (the cut keeps m < 100).
    let scale = f32::from_bits(t1.to_bits() << 23);
    if t1 > k.cut { p * scale } else { 0.0 }
}

/// `e^x` for `x ≤ 88` with relative error below [`MAX_RELATIVE_ERROR`] (plus the rounding of
/// `x·log2 e`, i.e. `|x|·6·10⁻⁸`); `x < −87.3` gives `2^−126`.
#[inline(always)]
#[cfg(test)]
pub fn exp_fast(x: f32) -> f32 {
    exp2_fast(x * LOG2_E)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f32, b: f64) -> f64 {
        (f64::from(a) / b - 1.0).abs()
    }

    #[test]
    fn exp2_relative_error_is_bounded_on_the_whole_domain() {
        let mut worst = 0.0f64;
        let n = 2_000_000;
        for i in 0..=n {
            let x = -126.0 + 253.0 * (i as f32) / (n as f32);
            let e = rel(exp2_fast(x), f64::from(x).exp2());
            worst = worst.max(e);
        }
        assert!(
            worst < f64::from(MAX_RELATIVE_ERROR),
            "worst relative error {worst}"
        );
        // The bound is tight (not a loose constant): the fit uses most of it.
        assert!(worst > 1e-6);
        // Exact at integers up to the polynomial's constant term.
        assert!(rel(exp2_fast(-3.0), 0.125) < 1e-6);
    }

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
    fn range_weight_relative_error_is_bounded_and_cut_off_below_2_pow_minus_100() {
        let mut worst = 0.0f64;
        for t in spatial_t() {
            let k = TapExp::new(t);
            for i in 0..=200_000 {
                // e² from 0 to 110, past the cutoff.
                let e = (110.0 * f64::from(i) / 200_000.0).sqrt() as f32;
                for e in [e, -e] {
                    let exact = (t - f64::from(e) * f64::from(e)).exp2();
                    for w in [range_weight::<false>(e, &k), range_weight::<true>(e, &k)] {
                        if w == 0.0 {
                            // Only below the cutoff (with ±1 of rounding slack).
                            assert!(exact < 2.0f64.powf(-98.4), "t {t} e {e}: 0 for {exact}");
                        } else {
                            assert!(exact > 2.0f64.powf(-100.6), "t {t} e {e}: kept {exact}");
                            assert!(w.is_normal());
                            worst = worst.max(rel(w, exact));
                        }
                    }
                }
            }
        }
        assert!(
            worst < f64::from(RANGE_WEIGHT_RELATIVE_ERROR),
            "range weights: {worst}"
        );
        // Tight: the degree-3 fit uses most of the bound.
        assert!(worst > 3e-5, "{worst}");
    }

    #[test]
    fn unit_interval_polynomial_matches_the_range_weight_polynomial() {
        // The AVX-512 kernel evaluates 2^f on [0, 1) with `EXP2_UNIT` (vreduceps / vscalefps
        // supply the exact split y = ⌊y⌋ + f and the exact scaling by 2^⌊y⌋).
        let [p3, p2, p1, p0] = EXP2_UNIT;
        let mut worst = 0.0f64;
        for i in 0..1_000_000 {
            let f = i as f32 / 1_000_000.0;
            let p = f.mul_add(f.mul_add(f.mul_add(p3, p2), p1), p0);
            worst = worst.max(rel(p, f64::from(f).exp2()));
        }
        assert!(worst < f64::from(RANGE_WEIGHT_RELATIVE_ERROR), "{worst}");
        assert!(worst > 3e-5, "{worst}");
    }

    #[test]
    fn exp_matches_std_exp() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -80.0 + 160.0 * (i as f32) / 200_000.0;
            // Compare with f32::exp, as the issue asks, and with the exact value.
            let exact = f64::from(x).exp();
            let std = x.exp();
            let e = rel(exp_fast(x), exact);
            // Allow the rounding of x·log2(e) in f32: relative error |x|·2⁻²⁴·ln 2 ·… ≤ 6e-8·|x|.
            let allowed = f64::from(MAX_RELATIVE_ERROR) + 6.0e-8 * f64::from(x.abs());
            assert!(e < allowed, "x = {x}: {e}");
            assert!(rel(std, exact) < 1e-6);
            worst = worst.max(rel(exp_fast(x), f64::from(std)));
        }
        assert!(worst < 1e-5, "{worst}");
    }

    #[test]
    fn clamps_and_nan() {
        let tiny = f32::from_bits(1 << 23);
        assert_eq!(exp2_fast(-1000.0), exp2_fast(-126.0));
        assert!((exp2_fast(-1000.0) / tiny - 1.0).abs() < 1e-5);
        assert!(exp2_fast(f32::INFINITY).is_finite());
        assert!((exp2_fast(0.0) - 1.0).abs() < 1e-6);
        // Invalid neighbours: infinite or NaN differences (and huge finite ones) weigh 0.
        let k = TapExp::new(-0.72);
        for e in [
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1.0e20,
            -3.0e5,
            11.0,
        ] {
            assert_eq!(range_weight::<false>(e, &k), 0.0, "{e}");
            assert_eq!(range_weight::<true>(e, &k), 0.0, "{e}");
        }
        // A spatial weight below the cutoff disables the tap.
        assert_eq!(range_weight::<true>(0.0, &TapExp::new(-150.0)), 0.0);
        assert_eq!(range_weight::<true>(0.0, &TapExp::new(0.0)), D0);
    }
}
