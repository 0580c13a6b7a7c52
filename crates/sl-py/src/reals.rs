//! Number arguments that refuse a bool: Python's `True` and `False` are the integers 1 and 0
//! (`bool` subclasses `int`, and NumPy's `bool_` converts to a float), so pyo3 takes `True` as
//! 1.0 where a float is expected and as 1 where an integer is. [`is_bool`] tells the callers,
//! which raise `TypeError` naming the argument in the message itself (pyo3 names it only in a
//! note, which `str(e)` does not show).

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyBool;

/// Whether `obj` is a Python or NumPy bool.
pub(crate) fn is_bool(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(true);
    }
    let numpy_bool = obj.py().import("numpy")?.getattr("bool_")?;
    obj.is_instance(&numpy_bool)
}

/// `obj` as a float; a bool is a `TypeError` naming the argument `name`.
pub(crate) fn real(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if is_bool(obj)? {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a number, not a bool ({obj})"
        )));
    }
    obj.extract()
}
