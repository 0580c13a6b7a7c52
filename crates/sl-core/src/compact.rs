//! Numbers in messages, compact at any size ([`Compact`]).

use std::fmt;

/// Displays an `f64` as Rust does (`0.04`, `-3`, `NaN`, `inf`) for magnitudes from 1e-4 to
/// below 1e6 and in scientific notation beyond them (`1e300`, `2.5e-7`), where `{}` would
/// print `1e300` as a 301-digit decimal: for the values an error message repeats back.
///
/// ```
/// use sl_core::Compact;
/// assert_eq!(Compact(0.04).to_string(), "0.04");
/// assert_eq!(Compact(1e300).to_string(), "1e300");
/// assert_eq!(Compact(-2.5e-7).to_string(), "-2.5e-7");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compact(pub f64);

impl fmt::Display for Compact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Compact;

    #[test]
    fn numbers_are_compact_at_any_size() {
        for (v, s) in [
            (0.0, "0"),
            (1e-4, "0.0001"),
            (999_999.0, "999999"),
            (1e6, "1e6"),
            (-1e300, "-1e300"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
            (1.0 / 30.0, "0.03333333333333333"),
        ] {
            assert_eq!(Compact(v).to_string(), s);
        }
    }
}
