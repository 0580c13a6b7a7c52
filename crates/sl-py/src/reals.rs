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

/// The float types of the arguments: a bool is refused in each (`Option`: `None` stays `None`).
pub(crate) trait Real: Sized {
    /// `obj` as this type; a bool is a `TypeError` naming the argument `name`.
    fn from_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Self>;
}

impl Real for f64 {
    fn from_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Self> {
        real(obj, name)
    }
}

impl Real for f32 {
    fn from_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Self> {
        if is_bool(obj)? {
            return real(obj, name).map(|v| v as f32);
        }
        obj.extract()
    }
}

impl<T: Real> Real for Option<T> {
    fn from_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Self> {
        if obj.is_none() {
            Ok(None)
        } else {
            T::from_arg(obj, name).map(Some)
        }
    }
}

/// One converter per float argument name, for `#[pyo3(from_py_with = crate::reals::NAME)]`:
/// [`Real::from_arg`] with the name in the message (`from_py_with` is not told the name).
macro_rules! named_reals {
    ($($name:ident),* $(,)?) => {$(
        #[doc = concat!("The float argument `", stringify!($name), "` ([`Real::from_arg`]).")]
        pub(crate) fn $name<T: Real>(obj: &Bound<'_, PyAny>) -> PyResult<T> {
            T::from_arg(obj, stringify!($name))
        }
    )*};
}

named_reals!(
    baseline_m,
    bend_px_per_px2,
    coord_m,
    cx,
    cy,
    delta,
    depth_scale,
    factor,
    fx,
    fy,
    k_per_m,
    log_sigma_px,
    log_threshold_px,
    max_depth_m,
    max_gap_s,
    max_normal_sigma_deg,
    max_s,
    min_depth_m,
    min_weight,
    model_scale,
    new_fragment_after_s,
    offset_s,
    rolling_shutter_ms,
    sigma_d_m,
    sigma_d_px,
    sigma_disp_px,
    sigma_s,
    step_s,
    threshold_px,
    timestamp_s,
    trunc_m,
    trunc_sigmas,
    voxel_m,
);
