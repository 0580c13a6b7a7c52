//! NumPy arrays in and out. A C-contiguous, aligned, native-byte-order `float32` (H, W) depth
//! array is borrowed without a copy; `float64`, `uint16` (with a `depth_scale`) and
//! non-contiguous arrays are converted into one new `float32` buffer (one pass over the pixels;
//! about 0.1–0.3 ms for 640×480); misaligned or byte-swapped arrays first get a native copy
//! from NumPy, and a masked array's masked entries become 0 (invalid).
//! Outputs are new arrays that take ownership of the Rust buffer (no copy).

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use sl_core::{Camera, DepthImage, DepthView, Image};

use crate::errors::value_error;

/// A depth map received from Python: borrowed when it already is C-contiguous `float32`.
pub(crate) enum DepthInput<'py> {
    /// The caller's buffer, read in place.
    Borrowed(PyReadonlyArray2<'py, f32>),
    /// A converted copy.
    Owned(DepthImage),
}

impl DepthInput<'_> {
    /// The pixels as a borrowed view.
    pub(crate) fn view(&self) -> PyResult<DepthView<'_>> {
        match self {
            Self::Borrowed(a) => {
                let (h, w) = (a.shape()[0], a.shape()[1]);
                let data = a.as_slice().map_err(value_error)?;
                DepthView::new(w, h, data).map_err(value_error)
            }
            Self::Owned(d) => Ok(d.view()),
        }
    }

    /// Whether the input is read in place (no copy was made).
    pub(crate) fn is_borrowed(&self) -> bool {
        matches!(self, Self::Borrowed(_))
    }
}

fn shape_of(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(usize, usize, String)> {
    let arr = obj.cast::<PyUntypedArray>().map_err(|_| {
        value_error(format!(
            "{name} must be a NumPy array of shape (H, W), got {}",
            obj.get_type()
                .name()
                .map_or_else(|_| "?".into(), |n| n.to_string())
        ))
    })?;
    let dtype = arr.dtype().str()?.to_string();
    if arr.ndim() != 2 {
        return Err(value_error(format!(
            "{name} must be 2-D (H, W), got an array of shape {:?}",
            arr.shape()
        )));
    }
    Ok((arr.shape()[0], arr.shape()[1], dtype))
}

fn owned(h: usize, w: usize, values: impl Iterator<Item = f32>) -> PyResult<DepthInput<'static>> {
    let data: Vec<f32> = values.collect();
    DepthImage::from_vec(w, h, data)
        .map(DepthInput::Owned)
        .map_err(value_error)
}

/// `obj` as an array this module can read in place or convert: a masked array with its masked
/// entries set to 0 (invalid depth), and a misaligned or byte-swapped array copied into native
/// order by NumPy. Anything else is returned as it is.
fn readable<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let py = obj.py();
    let mut obj = obj.clone();
    let masked = py.import("numpy.ma")?.getattr("MaskedArray")?;
    if obj.is_instance(&masked)? {
        obj = obj.call_method1("filled", (0,))?;
    }
    let Ok(arr) = obj.cast::<PyUntypedArray>() else {
        return Ok(obj);
    };
    let native = arr.dtype().getattr("isnative")?.extract::<bool>()?;
    let aligned = obj
        .getattr("flags")?
        .getattr("aligned")?
        .extract::<bool>()?;
    if native && aligned {
        return Ok(obj);
    }
    let dtype = arr.dtype().call_method1("newbyteorder", ("=",))?;
    obj.call_method1("astype", (dtype,))
}

/// Whether [`depth_input`] reads `obj`'s own buffer in place (no copy of any kind).
pub(crate) fn is_borrowed(obj: &Bound<'_, PyAny>, depth_scale: Option<f64>) -> PyResult<bool> {
    let read = readable(obj)?;
    Ok(read.is(obj) && depth_input_readable(&read, "depth", depth_scale)?.is_borrowed())
}

/// The valid range of `depth_scale` for integer depth, as for files (`sl_io`).
fn check_depth_scale(scale: f64) -> PyResult<()> {
    if !(sl_io::depth::MIN_UNITS_PER_M..=sl_io::depth::MAX_UNITS_PER_M).contains(&scale) {
        return Err(value_error(format!(
            "depth_scale {} units per metre is outside 1 to 1e6 (1000 for millimetres, 5000 for \
             TUM)",
            sl_core::Compact(scale)
        )));
    }
    Ok(())
}

/// Reads a depth array in metres (float32/float64), or in sensor units (uint16) with
/// `depth_scale` units per metre.
pub(crate) fn depth_input<'py>(
    obj: &Bound<'py, PyAny>,
    depth_scale: Option<f64>,
) -> PyResult<DepthInput<'py>> {
    depth_input_named(obj, "depth", depth_scale)
}

/// [`depth_input`] of the argument `name` (`depth_a`, `depth_b`), which its errors name.
pub(crate) fn depth_input_named<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    depth_scale: Option<f64>,
) -> PyResult<DepthInput<'py>> {
    depth_input_readable(&readable(obj)?, name, depth_scale)
}

/// [`depth_input`] of an array [`readable`] has prepared.
fn depth_input_readable<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    depth_scale: Option<f64>,
) -> PyResult<DepthInput<'py>> {
    let (h, w, dtype) = shape_of(obj, name)?;
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, f32>>() {
        if depth_scale.is_some() {
            return Err(value_error(format!(
                "depth_scale applies to integer depth; {name} is float, already in metres"
            )));
        }
        if a.is_c_contiguous() {
            return Ok(DepthInput::Borrowed(a));
        }
        return owned(h, w, a.as_array().iter().copied());
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, f64>>() {
        if depth_scale.is_some() {
            return Err(value_error(format!(
                "depth_scale applies to integer depth; {name} is float, already in metres"
            )));
        }
        return owned(h, w, a.as_array().iter().map(|&v| v as f32));
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, u16>>() {
        let Some(scale) = depth_scale else {
            return Err(value_error(format!(
                "{name} is uint16 depth, which needs depth_scale (units per metre: 1000 for \
                 millimetres, 5000 for TUM)"
            )));
        };
        check_depth_scale(scale)?;
        let inv = 1.0 / scale;
        return owned(
            h,
            w,
            a.as_array().iter().map(|&v| (f64::from(v) * inv) as f32),
        );
    }
    Err(value_error(format!(
        "{name} must be float32, float64 (metres) or uint16 (with depth_scale), got dtype {dtype}"
    )))
}

/// A `uint16` depth array's values as they are (masked entries 0), with its `depth_scale`
/// checked as [`depth_input`] checks it; `None` for any other dtype.
pub(crate) fn u16_input(
    obj: &Bound<'_, PyAny>,
    depth_scale: Option<f64>,
) -> PyResult<Option<Image<u16>>> {
    let read = readable(obj)?;
    let (h, w, _) = shape_of(&read, "depth")?;
    let Ok(a) = read.extract::<PyReadonlyArray2<'_, u16>>() else {
        return Ok(None);
    };
    let Some(scale) = depth_scale else {
        return Err(value_error(
            "uint16 depth needs depth_scale (units per metre: 1000 for millimetres, 5000 for TUM)",
        ));
    };
    check_depth_scale(scale)?;
    let values: Vec<u16> = a.as_array().iter().copied().collect();
    Image::from_vec(w, h, values).map(Some).map_err(value_error)
}

/// The camera of a depth map, as `sldepth` reads frames: `camera` at its own size; its sensor
/// decimated (`Camera.resampled(1/n)`: intrinsics scaled, noise model kept) when the map is its
/// size divided by a whole `n` from 2 to 8 (a 320×240 frame of a 640×480 camera); any other
/// size is an error naming the argument `name`.
pub(crate) fn camera_for_depth(
    view: &DepthView<'_>,
    camera: &Camera,
    name: &str,
) -> PyResult<Camera> {
    let k = &camera.intrinsics;
    match camera.for_frames(view.width(), view.height()) {
        Some((c, _)) => Ok(c),
        None => Err(value_error(format!(
            "{name} is {}x{} (W x H) but the camera is {}x{}, nor its size divided by a whole \
             number up to {}; pass a Camera of the depth's size",
            view.width(),
            view.height(),
            k.width,
            k.height,
            sl_core::camera::MAX_DECIMATION
        ))),
    }
}

/// Checks that a depth map has the camera's size.
pub(crate) fn check_camera(view: &DepthView<'_>, camera: &Camera) -> PyResult<()> {
    let k = &camera.intrinsics;
    if view.width() != k.width || view.height() != k.height {
        return Err(value_error(format!(
            "depth is {}x{} (W x H) but the camera is {}x{}; pass a Camera of the depth's size",
            view.width(),
            view.height(),
            k.width,
            k.height
        )));
    }
    Ok(())
}

/// A new (H, W) array that owns `image`'s buffer.
pub(crate) fn image_array<'py, T: numpy::Element>(
    py: Python<'py>,
    image: Image<T>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let (w, h) = image.dimensions();
    let a = Array2::from_shape_vec((h, w), image.into_vec()).map_err(value_error)?;
    Ok(a.into_pyarray(py))
}

/// A new (H, W) float32 array of depth in metres.
pub(crate) fn depth_array<'py>(
    py: Python<'py>,
    depth: DepthImage,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    image_array(py, depth.into_image())
}

/// A new (N, 3) array from rows of three values.
pub(crate) fn rows3_array<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    rows: impl ExactSizeIterator<Item = [T; 3]>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let n = rows.len();
    let flat: Vec<T> = rows.flat_map(|r| r.into_iter()).collect();
    let a = Array2::from_shape_vec((n, 3), flat).map_err(value_error)?;
    Ok(a.into_pyarray(py))
}

/// A 4×4 camera-to-world pose from a NumPy (4, 4) array (any real dtype) or nested lists.
pub(crate) fn pose_input(obj: &Bound<'_, PyAny>) -> PyResult<sl_core::CameraToWorld> {
    if let Ok(arr) = obj.cast::<PyUntypedArray>() {
        let kind: String = arr.dtype().getattr("kind")?.extract()?;
        if !matches!(kind.as_str(), "f" | "i" | "u") {
            return Err(value_error(format!(
                "pose must be a (4, 4) array of real numbers (camera-to-world), got dtype {}",
                arr.dtype().str()?
            )));
        }
    }
    let m: Vec<Vec<f64>> = obj
        .call_method0("tolist")
        .and_then(|l| l.extract())
        .or_else(|_| obj.extract())
        .map_err(|_| value_error("pose must be a (4, 4) array of floats (camera-to-world)"))?;
    if m.len() != 4 || m.iter().any(|r| r.len() != 4) {
        return Err(value_error(
            "pose must be a (4, 4) array of floats (camera-to-world)",
        ));
    }
    let mut flat = [0.0; 16];
    for (i, v) in m.iter().flatten().enumerate() {
        flat[i] = *v;
    }
    sl_core::CameraToWorld::from_row_major(&flat).map_err(value_error)
}

/// A NumPy (N, 4, 4) float64 array of poses' homogeneous matrices (`to_matrix()` of any of the
/// typed poses), in order.
pub(crate) fn poses_array<'py>(
    py: Python<'py>,
    matrices: &[sl_core::nalgebra::Matrix4<f64>],
) -> Bound<'py, numpy::PyArray3<f64>> {
    numpy::ndarray::Array3::from_shape_fn((matrices.len(), 4, 4), |(k, i, j)| matrices[k][(i, j)])
        .into_pyarray(py)
}

/// A NumPy (4, 4) float64 array of a pose's homogeneous matrix (`to_matrix()` of any of the
/// typed poses).
pub(crate) fn pose_array<'py>(
    py: Python<'py>,
    m: &sl_core::nalgebra::Matrix4<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let a = Array2::from_shape_fn((4, 4), |(i, j)| m[(i, j)]);
    Ok(a.into_pyarray(py))
}
