//! Integer arguments: [`int`] and [`opt_int`] (used as `#[pyo3(from_py_with = …)]`) take any
//! Python integer (an `int`, a NumPy integer, anything with `__index__`) and raise
//! `sldepth.SlDepthError` (a `ValueError`) naming the accepted range when the value does not
//! fit the Rust type — a negative count or size, or one beyond the type's maximum — where
//! pyo3's own conversion raises `OverflowError`, which is not a `ValueError`. A value that is
//! not an integer at all (a float, a string) stays pyo3's `TypeError`, and so is a bool
//! (`True` is the integer 1 to Python; as for the float arguments, [`crate::reals`], it is
//! refused rather than read as a count or a seed). pyo3 notes the argument's name on either
//! error ("while processing 'radius'").

use pyo3::exceptions::{PyOverflowError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyInt;

use crate::errors::value_error;

/// The integer types [`int`] converts to, with their range for the message.
pub(crate) trait Bounded: Sized + TryFrom<i128> {
    /// The smallest and largest values, as the message prints them.
    fn range() -> (i128, u128);
}

macro_rules! bounded {
    ($($t:ty),*) => {$(
        impl Bounded for $t {
            fn range() -> (i128, u128) {
                // Lossless: every type listed fits i128 below and u128 above.
                (<$t>::MIN as i128, <$t>::MAX as u128)
            }
        }
    )*};
}
bounded!(u16, u32, u64, usize);

/// The Python integer `obj` as `T`; out of `T`'s range, a `ValueError` naming the range; a bool,
/// a `TypeError`.
pub(crate) fn int<T: Bounded>(obj: &Bound<'_, PyAny>) -> PyResult<T> {
    if crate::reals::is_bool(obj)? {
        return Err(PyTypeError::new_err(format!(
            "expected an integer, not a bool ({obj})"
        )));
    }
    let out_of_range = |shown: String| {
        let (lo, hi) = T::range();
        value_error(format!("expected an integer in {lo}..={hi}, got {shown}"))
    };
    match obj.extract::<i128>() {
        Ok(v) => T::try_from(v).map_err(|_| out_of_range(v.to_string())),
        // Beyond i128: an integer out of range of every `T` here.
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
            let shown = obj
                .cast::<PyInt>()
                .ok()
                .and_then(|i| i.str().ok())
                .map(|s| s.to_string())
                .filter(|s| s.len() <= 40)
                .unwrap_or_else(|| "an integer beyond that".to_owned());
            Err(out_of_range(shown))
        }
        Err(e) => Err(e),
    }
}

/// [`int`] of an optional argument: `None` stays `None`.
pub(crate) fn opt_int<T: Bounded>(obj: &Bound<'_, PyAny>) -> PyResult<Option<T>> {
    if obj.is_none() {
        Ok(None)
    } else {
        int(obj).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::Bounded;

    #[test]
    fn the_ranges_are_the_types_own() {
        assert_eq!(u16::range(), (0, 65_535));
        assert_eq!(u32::range(), (0, u128::from(u32::MAX)));
        assert_eq!(u64::range(), (0, u128::from(u64::MAX)));
        assert_eq!(<u16 as TryFrom<i128>>::try_from(-1).ok(), None);
    }
}
