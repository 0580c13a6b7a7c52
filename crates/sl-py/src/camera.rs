//! `sldepth.Camera`: pinhole intrinsics plus the disparity noise model.

use pyo3::prelude::*;
use sl_core::{Camera, Intrinsics, SensorModel, preset};

use crate::errors::value_error;

/// A depth camera: pinhole intrinsics (pixels) and the disparity noise model
/// (``σ_Z = Z²·σ_D/(f·B)``).
///
/// ``Camera(width, height, fx, fy, cx, cy, baseline_m=0.075, subpixel=8, sigma_d_px=0.07)`` takes
/// Open3D-style intrinsics; ``Camera.preset("kinect-v1")`` one of ``Camera.presets()``. Ranges
/// (``ValueError`` outside them): at most 16,777,216 pixels (the default memory budget's frame),
/// ``fx``, ``fy`` in [1, 1e7] px, ``baseline_m`` in (0, 10], ``subpixel`` in 1..256,
/// ``sigma_d_px`` in [0, 10] (0: a noise-free camera).
#[pyclass(name = "Camera", module = "sldepth", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyCamera {
    pub(crate) inner: Camera,
    /// The lens distortion of the images, when the preset publishes one (TUM fr1/fr2).
    pub(crate) lens: Option<sl_core::LensDistortion>,
    /// The preset it was made from (kept by `resampled`), or the preset of the sensor of a
    /// sequence folder's camera file (`sequence_camera`); `None` for explicit intrinsics.
    pub(crate) preset_name: Option<String>,
}

/// Refuses a camera whose frames would exceed the default memory budget of `sl_io::Limits`
/// (the command line's `--max-memory` default; `read_depth(max_memory_bytes=…)` reads larger
/// files, but no algorithm takes a camera beyond this): every frame of it is allocated by the
/// algorithms, several times over by the tracker.
fn check_size(camera: Camera) -> PyResult<Camera> {
    let k = &camera.intrinsics;
    let limits = sl_io::Limits::default();
    limits
        .check_pixels(k.width as u64, k.height as u64)
        .map_err(|_| {
            value_error(format!(
                "camera of {}x{} pixels: over the limit of {} pixels per frame",
                k.width, k.height, limits.max_pixels
            ))
        })?;
    Ok(camera)
}

impl PyCamera {
    /// `camera` as Python sees it, with the lens model and rolling shutter of `preset`: the preset
    /// it is, or the one whose sensor it has (a sequence folder's camera file).
    pub(crate) fn wrap(camera: Camera, preset: Option<&str>) -> PyResult<Self> {
        let found = preset.map(preset::find).transpose().map_err(value_error)?;
        Ok(Self {
            inner: check_size(camera)?,
            lens: found.and_then(|p| p.lens),
            preset_name: found.map(|p| p.name.to_owned()),
        })
    }

    /// The preset's rolling-shutter readout, seconds (0 for explicit intrinsics).
    pub(crate) fn rolling_shutter_readout_s(&self) -> f64 {
        self.preset_name
            .as_deref()
            .and_then(|n| preset::find(n).ok())
            .map_or(0.0, |p| p.rolling_shutter_readout_s)
    }
}

#[pymethods]
impl PyCamera {
    #[new]
    #[pyo3(signature = (width, height, fx, fy, cx, cy, *, baseline_m = 0.075, subpixel = 8, sigma_d_px = sl_core::sensor::DEFAULT_SIGMA_D_PX))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        #[pyo3(from_py_with = crate::ints::int)] width: usize,
        #[pyo3(from_py_with = crate::ints::int)] height: usize,
        #[pyo3(from_py_with = crate::reals::fx)] fx: f64,
        #[pyo3(from_py_with = crate::reals::fy)] fy: f64,
        #[pyo3(from_py_with = crate::reals::cx)] cx: f64,
        #[pyo3(from_py_with = crate::reals::cy)] cy: f64,
        #[pyo3(from_py_with = crate::reals::baseline_m)] baseline_m: f64,
        #[pyo3(from_py_with = crate::ints::int)] subpixel: u32,
        #[pyo3(from_py_with = crate::reals::sigma_d_px)] sigma_d_px: f64,
    ) -> PyResult<Self> {
        let intrinsics = Intrinsics::new(width, height, fx, fy, cx, cy).map_err(value_error)?;
        let sensor = SensorModel::new(fx, baseline_m, subpixel, sigma_d_px).map_err(value_error)?;
        Ok(Self {
            inner: check_size(Camera { intrinsics, sensor })?,
            lens: None,
            preset_name: None,
        })
    }

    /// The camera of a named preset (``"kinect-v1"``, ``"tum-fr1"``, ``"d435"``, …; see
    /// ``Camera.presets()``). An unknown name raises ``ValueError`` listing the known ones.
    #[staticmethod]
    fn preset(name: &str) -> PyResult<Self> {
        let found = preset::find(name).map_err(value_error)?;
        Ok(Self {
            inner: Camera::preset(found.name).map_err(value_error)?,
            lens: found.lens,
            preset_name: Some(found.name.to_owned()),
        })
    }

    /// The camera of a camera file, as ``sldepth --camera FILE`` reads it: an Open3D
    /// ``PinholeCameraIntrinsic`` JSON (with optional ``baseline_m``, ``subpixel``,
    /// ``sigma_d_px``), or a ROS camera calibration ``.yaml``/``.yml`` (``camera_calibration``'s
    /// file, or a ``CameraInfo`` saved from ``rostopic echo`` / ``ros2 topic echo``: its ``K``,
    /// the Kinect sensor model, and its non-zero ``plumb_bob`` distortion as ``lens``, which
    /// ``undistort`` then undoes). A file that is not one camera raises ``OSError`` naming it.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Self> {
        let limits = sl_io::Limits::default();
        let (camera, lens) = if sl_io::ros_camera::is_ros_camera_file(&path) {
            let ros =
                crate::threads::compute(py, || sl_io::ros_camera::read_ros_camera(&path, &limits))
                    .map_err(crate::errors::io_error)?;
            let camera =
                Camera::from_intrinsics(ros.intrinsics, None, None).map_err(value_error)?;
            (camera, ros.lens)
        } else if path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
        {
            let camera = crate::threads::compute(py, || {
                sl_io::camera::read_camera_json_with_limits(&path, &limits)
            })
            .map_err(crate::errors::io_error)?;
            (camera, None)
        } else {
            return Err(value_error(format!(
                "{}: a camera file is .json (Open3D) or .yaml (ROS)",
                path.display()
            )));
        };
        Ok(Self {
            inner: check_size(camera)?,
            lens,
            preset_name: None,
        })
    }

    /// The names of every preset.
    #[staticmethod]
    fn presets() -> Vec<&'static str> {
        preset::names().collect()
    }

    /// The name of the preset this camera was made from, or whose sensor (lens model, rolling
    /// shutter) a sequence folder's camera file was recorded with (``sequence_camera``);
    /// ``None`` for explicit intrinsics.
    #[getter]
    fn preset_name(&self) -> Option<&str> {
        self.preset_name.as_deref()
    }

    /// The depth sensor's rolling-shutter readout, milliseconds (first row to last), from the
    /// preset (30, an estimate, for the Kinect v1 / PrimeSense-class presets; 0 for a global
    /// shutter, ``icl-nuim``'s rendered images and explicit intrinsics). ``Tracker`` models it
    /// when tracking against the fused model.
    #[getter]
    fn rolling_shutter_ms(&self) -> f64 {
        self.rolling_shutter_readout_s() * 1e3
    }

    /// The lens distortion ``(k1, k2, p1, p2, k3)`` (OpenCV's order) of the preset's images (or
    /// of a ROS camera file's, ``Camera.from_file``), or ``None`` (pinhole). ``tum-fr1`` /
    /// ``tum-fr2`` depth is registered to the distorted colour image:
    /// ``sldepth.undistort(depth, camera)`` resamples it into the pinhole image.
    #[getter]
    fn lens(&self) -> Option<(f64, f64, f64, f64, f64)> {
        self.lens.map(|l| (l.k1, l.k2, l.p1, l.p2, l.k3))
    }

    /// Image width, pixels.
    #[getter]
    fn width(&self) -> usize {
        self.inner.intrinsics.width
    }
    /// Image height, pixels.
    #[getter]
    fn height(&self) -> usize {
        self.inner.intrinsics.height
    }
    /// Focal length x, pixels.
    #[getter]
    fn fx(&self) -> f64 {
        self.inner.intrinsics.fx
    }
    /// Focal length y, pixels.
    #[getter]
    fn fy(&self) -> f64 {
        self.inner.intrinsics.fy
    }
    /// Principal point x, pixels.
    #[getter]
    fn cx(&self) -> f64 {
        self.inner.intrinsics.cx
    }
    /// Principal point y, pixels.
    #[getter]
    fn cy(&self) -> f64 {
        self.inner.intrinsics.cy
    }
    /// Projector–camera baseline, metres.
    #[getter]
    fn baseline_m(&self) -> f64 {
        self.inner.sensor.baseline_m
    }
    /// Disparity sub-pixel steps per pixel (8 = 1/8 px).
    #[getter]
    fn subpixel(&self) -> u32 {
        self.inner.sensor.subpixel_steps
    }
    /// Disparity noise σ_D, pixels.
    #[getter]
    fn sigma_d_px(&self) -> f64 {
        self.inner.sensor.sigma_d_px
    }
    /// ``f·B``, pixel·metres.
    #[getter]
    fn fb(&self) -> f64 {
        self.inner.sensor.fb()
    }

    /// Depth noise σ_Z at depth ``z_m`` (metres): ``z²·σ_D/(f·B)``; NaN for a depth that is not
    /// a positive finite number (no measurement has one).
    fn sigma_z(&self, z_m: f64) -> f64 {
        if z_m > 0.0 && z_m.is_finite() {
            self.inner.sensor.sigma_z(z_m)
        } else {
            f64::NAN
        }
    }

    /// Disparity (pixels) of depth ``z_m`` (metres): ``f·B/Z``.
    fn depth_to_disparity(&self, z_m: f64) -> f64 {
        self.inner.sensor.depth_to_disparity(z_m)
    }

    /// Depth (metres) of disparity ``d_px`` (pixels): ``f·B/D``.
    fn disparity_to_depth(&self, d_px: f64) -> f64 {
        self.inner.sensor.disparity_to_depth(d_px)
    }

    /// Focal length of the sensor's own images, pixels: ``fx`` unless the camera was
    /// ``resampled``.
    #[getter]
    fn sensor_focal_px(&self) -> f64 {
        self.inner.sensor.focal_px
    }

    /// The same sensor seen through images resampled by ``factor`` (``0.5``: the 320×240
    /// frames of a 640×480 sensor, a QVGA mode or a decimating driver): the intrinsics are
    /// scaled, the sensor's noise model (``sigma_z``, its focal length, its block-matching
    /// window) is kept, so the tracker and the plane extractor weigh the decimated frames as
    /// the same sensor's. The lens model, if any, is kept (it acts on normalised
    /// coordinates). A ``factor`` that is not positive raises ``ValueError``.
    fn resampled(
        &self,
        #[pyo3(from_py_with = crate::reals::factor)] factor: f64,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: check_size(self.inner.resampled(factor).map_err(value_error)?)?,
            lens: self.lens,
            preset_name: self.preset_name.clone(),
        })
    }

    /// The 3×3 intrinsic matrix as nested lists (``numpy.array(cam.intrinsic_matrix())``).
    fn intrinsic_matrix(&self) -> [[f64; 3]; 3] {
        let k = &self.inner.intrinsics;
        [[k.fx, 0.0, k.cx], [0.0, k.fy, k.cy], [0.0, 0.0, 1.0]]
    }

    fn __repr__(&self) -> String {
        let (k, s) = (&self.inner.intrinsics, &self.inner.sensor);
        // A camera made from a preset says so: it carries the preset's lens model and
        // rolling-shutter readout, and is not equal to one made from the same numbers.
        let preset = self
            .preset_name
            .as_deref()
            .map_or_else(String::new, |p| format!(", preset={p:?}"));
        // Numbers compact (a 1e-300 m baseline is not 300 digits), each still a Python float
        // literal.
        let c = sl_core::Compact;
        format!(
            "Camera(width={}, height={}, fx={}, fy={}, cx={}, cy={}, baseline_m={}, subpixel={}, sigma_d_px={}{preset})",
            k.width,
            k.height,
            c(k.fx),
            c(k.fy),
            c(k.cx),
            c(k.cy),
            c(s.baseline_m),
            s.subpixel_steps,
            c(s.sigma_d_px)
        )
    }
}

/// The Python camera argument, or the `kinect-v1` default.
pub(crate) fn camera_or_default(camera: Option<&PyCamera>) -> Camera {
    camera.map_or_else(Camera::kinect_v1, |c| c.inner)
}

/// Resamples a depth map (metres) taken through the camera's lens into the ideal pinhole image
/// of the same intrinsics (nearest neighbour: depth is never blended across an edge; values
/// unchanged; 0 where the ray leaves the image) and returns a new float32 (H, W) array. A
/// camera without a lens model (``camera.lens is None``) returns an unchanged copy. For TUM
/// fr1/fr2 (``Camera.preset("tum-fr1")``) this is what ``sldepth track`` does by default
/// (TUM fr1/rpy ATE 4.3 → 3.0 cm).
#[pyfunction]
#[pyo3(signature = (depth, camera, *, depth_scale = None))]
pub(crate) fn undistort<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: &PyCamera,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<Bound<'py, numpy::PyArray2<f32>>> {
    let input = crate::arrays::depth_input(depth, depth_scale)?;
    let view = input.view()?;
    crate::arrays::check_camera(&view, &camera.inner)?;
    let k = camera.inner.intrinsics;
    let lens = camera.lens;
    let out = crate::threads::compute(py, || match lens {
        Some(l) => sl_core::Undistorter::new(&k, &l).apply(view),
        None => Ok(view.to_image()),
    })
    .map_err(value_error)?;
    crate::arrays::depth_array(py, out)
}
