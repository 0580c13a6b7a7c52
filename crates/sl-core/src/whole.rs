//! Whole numbers of `f32` values without a libm call or a saturating conversion.
//!
//! The baseline x86-64 target has no SSE4.1 `roundss`, so `f32::floor`, `ceil` and `round` are
//! library calls there, and Rust's `as` conversions saturate (a compare and a select or two
//! after the hardware conversion). Adding a power of two whose unit in the last place is 1
//! rounds a bounded value to the nearest integer in one add, which lands in the low mantissa
//! bits: sl-tsdf's pixel lookups, block discovery and raycast tile bounds and sl-track's
//! projective association use that (and it vectorises). Each function states the range it is
//! exact in; the tests compare them with the library functions there. Written by hand: no
//! crate offers these bounded, branch-free forms.
//!
//! ```
//! use sl_core::whole::{floor_i32, round_index};
//!
//! assert_eq!(floor_i32(-2.5), -3);
//! // The pixel a projected coordinate rounds to (half away from zero, as `f32::round`), and
//! // whether it lies in a row of 640 pixels.
//! assert_eq!(round_index(638.5, 640.0), (true, 639));
//! assert!(!round_index(639.5, 640.0).0);
//! assert!(!round_index(f32::NAN, 640.0).0);
//! ```

/// `2^23`: adding it to an `x` in `[0, 2^22]` rounds `x` to the nearest integer (ties to
/// even), which is then in the low mantissa bits.
pub const MAGIC: f32 = 8_388_608.0;

/// `1.5·2^23`: adding it to an `x` with `|x| < 2^22` rounds `x` to the nearest integer, which
/// is then the low mantissa bits (two's complement relative to the constant's bits).
pub const MAGIC_SIGNED: f32 = 12_582_912.0;

/// Magnitude below which [`floor_i32`] is exact: `2^22`.
pub const EXACT_LIMIT: f32 = 4_194_304.0;

/// The nearest integer to `x ∈ [0, 2^22]` (ties to even), as f32; a plain add and subtract
/// that vectorises (Rust does not reassociate floating-point arithmetic).
#[inline(always)]
pub fn round_f32(x: f32) -> f32 {
    (x + MAGIC) - MAGIC
}

/// `x as u32` for an integral `x ∈ [0, 2^23)`, without a (saturating, non-vectorising)
/// float-to-int conversion.
#[inline(always)]
pub fn exact_u32(x: f32) -> u32 {
    (x + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits())
}

/// `floor` as an integer for `|x| <` [`EXACT_LIMIT`], without a libm call or a saturating
/// conversion, so that it vectorises.
#[inline(always)]
pub fn floor_i32(x: f32) -> i32 {
    let s = x + MAGIC_SIGNED;
    let r = s - MAGIC_SIGNED;
    let ri = (s.to_bits() as i32).wrapping_sub(MAGIC_SIGNED.to_bits() as i32);
    ri.wrapping_sub(i32::from(r > x))
}

/// `x.clamp(0.0, lim)` rounded up, as an index: `x.ceil().clamp(0.0, lim) as usize` for a
/// whole `lim ∈ [0, 2^22]` and any `x` (NaN gives 0).
#[inline(always)]
pub fn ceil_index(x: f32, lim: f32) -> usize {
    let (i, r, c) = nearest_clamped(x, lim);
    i + usize::from(r < c)
}

/// `x.clamp(0.0, lim)` rounded down, as an index: `x.floor().clamp(0.0, lim) as usize` for a
/// whole `lim ∈ [0, 2^22]` and any `x` (NaN gives 0).
#[inline(always)]
pub fn floor_index(x: f32, lim: f32) -> usize {
    let (i, r, c) = nearest_clamped(x, lim);
    i - usize::from(r > c)
}

/// Whether `x.round()` (half away from zero) lies in `[0, n)`, and that index: `(true, i)`
/// then, `(false, _)` otherwise (also for NaN and ±∞; the second value is then meaningless).
/// `round(x) ≥ 0 ⇔ x > −½` and `round(x) < n ⇔ x < n − ½` for a whole `n ∈ [0, 2^22]`. Inside,
/// `|x| < 2^22`: the magic add gives the nearest integer with ties to even, and a tie rounded
/// down (`x − r = ½`, exact for a whole `r` within ½ of `x`) is moved up.
#[inline(always)]
pub fn round_index(x: f32, n: f32) -> (bool, i32) {
    let inside = (x > -0.5) & (x < n - 0.5);
    let s = x + MAGIC_SIGNED;
    let r = s - MAGIC_SIGNED;
    let i = (s.to_bits() as i32).wrapping_sub(MAGIC_SIGNED.to_bits() as i32);
    (inside, i.wrapping_add(i32::from(x - r == 0.5)))
}

/// `c = x.clamp(0.0, lim)` (0 for NaN), the nearest integer to it as an index and as `f32`.
/// Clamping first gives the same index as rounding first: the bounds are whole numbers.
#[inline(always)]
fn nearest_clamped(x: f32, lim: f32) -> (usize, f32, f32) {
    let c = if x >= 0.0 { x.min(lim) } else { 0.0 };
    let s = c + MAGIC;
    (
        s.to_bits().wrapping_sub(MAGIC.to_bits()) as usize,
        s - MAGIC,
        c,
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn magic_rounding_matches_round_ties_even() {
        let mut xs = vec![
            0.0f32,
            0.5,
            1.5,
            2.5,
            0.499_999_97,
            639.5,
            640.5,
            4_194_304.0,
        ];
        for i in 0..20_000u32 {
            let base = (i / 4) as f32;
            xs.push(base);
            xs.push(f32::from_bits(base.to_bits() + 1));
            xs.push(base + 0.5);
            if base > 0.0 {
                xs.push(f32::from_bits(base.to_bits() - 1));
                xs.push(f32::from_bits((base + 0.5).to_bits() - 1));
            }
            xs.push(i as f32 * 0.37 + 0.013);
        }
        for x in xs {
            let r = round_f32(x);
            assert_eq!(r, x.round_ties_even(), "{x}");
            assert_eq!(exact_u32(r), r as u32, "{x}");
        }
        assert_eq!(exact_u32(8_388_607.0), 8_388_607);
    }

    #[test]
    fn magic_floor_matches_floor_below_the_limit() {
        assert_eq!(floor_i32(-0.5), -1);
        assert_eq!(floor_i32(2.0), 2);
        for i in -40_000i32..40_000 {
            for x in [
                i as f32 * 0.25,
                i as f32 * 97.13 + 0.5,
                f32::from_bits((i as f32).to_bits().wrapping_sub(u32::from(i != 0))),
            ] {
                assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
            }
        }
        for x in [-4_194_303.5f32, 4_194_303.5, -0.0, 1e-30, -1e-30] {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }

    /// Values every rounding is checked on: non-finite, extreme, signed zeros, tiny, huge, and
    /// quarter-whole numbers with their neighbours on either side, and values off the grid.
    fn awkward_values() -> Vec<f32> {
        let mut xs = vec![
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
            -0.0,
            0.0,
            1e-30,
            -1e-30,
            1e9,
            -1e9,
        ];
        for i in -3_000i32..3_000 {
            let v = i as f32 * 0.25;
            xs.extend([
                v,
                f32::from_bits(v.to_bits().wrapping_add(1)),
                f32::from_bits(v.to_bits().wrapping_sub(1)),
                i as f32 * 7.31 + 0.013,
            ]);
        }
        xs
    }

    /// The clamped indices equal the library's round-then-clamp-then-convert for every kind
    /// of value: inside the range, at and next to whole numbers, beyond either bound, huge,
    /// infinite and NaN.
    #[test]
    fn clamped_indices_match_the_library() {
        let xs = awkward_values();
        for lim in [0.0f32, 1.0, 159.0, 639.0, 65_535.0, 4_194_304.0] {
            for &x in &xs {
                assert_eq!(
                    ceil_index(x, lim),
                    x.ceil().clamp(0.0, lim) as usize,
                    "ceil {x} {lim}"
                );
                assert_eq!(
                    floor_index(x, lim),
                    x.floor().clamp(0.0, lim) as usize,
                    "floor {x} {lim}"
                );
            }
        }
    }

    /// The index and the inside flag equal `f32::round`'s pixel and the bounds test on it,
    /// at and next to whole and half-whole numbers, beyond either bound, huge, infinite and
    /// NaN.
    #[test]
    fn round_index_matches_the_library() {
        let mut xs = awkward_values();
        xs.extend([-0.5f32, 0.5, 0.499_999_97, -0.499_999_97]);
        for k in [639.5f32, 4_194_303.5, 2_097_151.5] {
            xs.extend([
                k,
                f32::from_bits(k.to_bits() + 1),
                f32::from_bits(k.to_bits() - 1),
            ]);
        }
        for n in [0.0f32, 1.0, 160.0, 640.0, 4_194_304.0] {
            for &x in &xs {
                let r = x.round();
                let inside = r >= 0.0 && r < n;
                let (ok, i) = round_index(x, n);
                assert_eq!(ok, inside, "inside {x} {n}");
                if inside {
                    assert_eq!(i, r as i32, "index {x} {n}");
                }
            }
        }
    }
}
