//! The noise model: `analyze` (depth-resolution analysis, the paper's Figure 2) and `simulate`
//! (seeded Kinect frames of named scenes).

use std::collections::HashMap;

use numpy::PyArray2;
use pyo3::exceptions::{PyOverflowError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sl_noise::sim::{KinectSimulator, NoiseModel, RealisticNoise, named_scene};

use crate::arrays::{depth_array, depth_input, image_array};
use crate::camera::{PyCamera, camera_or_default};
use crate::errors::value_error;
use crate::reals::is_bool;
use crate::repr::py_opt;
use crate::threads::compute;

/// The depth-resolution analysis of one depth map (read-only attributes).
#[pyclass(name = "Analysis", module = "sldepth", frozen, get_all)]
#[derive(Debug, Clone)]
pub struct PyAnalysis {
    /// Valid pixels used.
    valid_pixels: usize,
    /// Distinct depth values.
    unique_depths: usize,
    /// OLS slope of ln ΔZ vs ln Z (the model predicts 2).
    slope: f64,
    /// Robust (Theil–Sen) slope.
    slope_robust: f64,
    /// Quantum c of ΔZ ≈ c·Z², per metre.
    quantum_per_m: f64,
    /// Implied f·B, pixel·metres (None when too few far depths).
    fb_px_m: Option<f64>,
    /// Disparity sub-pixel steps per pixel counted from the data (None when undetermined).
    subpixel_steps: Option<u32>,
}

#[pymethods]
impl PyAnalysis {
    fn __repr__(&self) -> String {
        format!(
            "Analysis(unique_depths={}, slope={:.3}, slope_robust={:.3}, quantum_per_m={:.6}, fb_px_m={}, subpixel_steps={})",
            self.unique_depths,
            self.slope,
            self.slope_robust,
            self.quantum_per_m,
            py_opt(self.fb_px_m),
            py_opt(self.subpixel_steps)
        )
    }
}

/// Depth-resolution analysis (the paper's Figure 2): the slope of ln ΔZ vs ln Z over the map's
/// distinct depths, the quantum c of ΔZ ≈ c·Z², the implied f·B and the disparity sub-pixel
/// steps. The map has the camera's size (default the ``kinect-v1`` preset) or that size divided
/// by a whole number (its sensor decimated), as ``sldepth analyze`` reads it.
#[pyfunction]
#[pyo3(signature = (depth, camera = None, *, depth_scale = None))]
pub(crate) fn analyze(
    py: Python<'_>,
    depth: &Bound<'_, PyAny>,
    camera: Option<&PyCamera>,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<PyAnalysis> {
    let camera = camera_or_default(camera);
    let input = depth_input(depth, depth_scale)?;
    let view = input.view()?;
    // The camera's size, or its sensor decimated, as `sldepth analyze` accepts.
    let camera = crate::arrays::camera_for_depth(&view, &camera, "depth")?;
    let image = view.to_image();
    let a = compute(py, || sl_noise::analyze(&image, &camera.sensor)).map_err(value_error)?;
    Ok(PyAnalysis {
        valid_pixels: a.valid_pixels,
        unique_depths: a.unique_depths,
        slope: a.slope,
        slope_robust: a.slope_robust,
        quantum_per_m: a.quantum_per_m,
        fb_px_m: a.fb_px_m,
        subpixel_steps: a.subpixel_steps,
    })
}

/// `min_return`: a finite number >= 0, not a bool (`True` is 1 to Python), checked before the
/// noise model is chosen (a NaN is no drop-out setting of either model).
fn min_return_arg(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    let v = crate::reals::real(obj, "min_return")?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(value_error(format!(
            "min_return = {} must be a finite number >= 0 (0 = off)",
            sl_core::Compact(v)
        )));
    }
    Ok(v)
}

/// `reflectance`: a dict of labels to reflectances, neither of them a bool (`True` would be
/// label 1, or reflectance 1); a label beyond any integer type names no surface (a
/// `ValueError`, not pyo3's `OverflowError`).
fn reflectance_arg(obj: &Bound<'_, PyAny>) -> PyResult<Option<HashMap<i64, f64>>> {
    if obj.is_none() {
        return Ok(None);
    }
    let Ok(dict) = obj.cast::<PyDict>() else {
        // pyo3's TypeError for anything but a dict.
        return obj.extract().map(Some);
    };
    let mut map = HashMap::with_capacity(dict.len());
    for (label, rho) in dict.iter() {
        if is_bool(&label)? {
            return Err(PyTypeError::new_err(format!(
                "reflectance: label {label} is a bool; labels are integers (1.., as in the \
                 labels image)"
            )));
        }
        if is_bool(&rho)? {
            return Err(PyTypeError::new_err(format!(
                "reflectance: the reflectance of label {label} is a bool ({rho}); reflectances \
                 are numbers in [0, 1]"
            )));
        }
        let l = match label.extract::<i64>() {
            Ok(l) => l,
            Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
                return Err(value_error(format!(
                    "no surface {label} (labels are 16-bit: at most 65535)"
                )));
            }
            Err(e) => return Err(e),
        };
        map.insert(l, rho.extract::<f64>()?);
    }
    Ok(Some(map))
}

type SimResult<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u16>>,
);

/// Renders a named scene (``"floor"``, ``"wall"``, ``"three-planes"``, ``"corridor"``, …) through
/// a Kinect-class sensor: returns ``(depth, truth, labels)`` — float32 metres with noise, float32
/// exact metres, uint16 surface labels. Seeded and deterministic. ``camera`` replaces the scene's
/// Kinect intrinsics and noise model. ``noise="realistic"`` (the default, as for ``sldepth
/// simulate``): block-matching-correlated disparity error, quantisation, occlusion bands and
/// drop-outs fitted to real Kinect frames (depth registered to the colour camera for the
/// ``tum-*``, ``ros-default`` and ``icl-nuim`` presets); ``noise="white"``: the paper's idealised
/// independent Gaussian disparity noise (1/8 px, 1 mm), which Algorithm 1 assumes.
/// ``min_return`` (realistic model; 0 = off) drops out pixels whose surface returns less of the
/// pattern than a white surface facing the camera at 1 m times it (``reflectance·cos θ / r²``,
/// r in metres: dark and far surfaces); ``reflectance`` maps surface labels to their infrared
/// reflectance in [0, 1] (every other surface reflects 1), which only that drop-out reads: a
/// ``reflectance`` without a positive ``min_return`` (or with ``noise="white"``) raises
/// ``ValueError``.
#[pyfunction]
#[pyo3(signature = (scene, seed = 0, camera = None, *, noise = "realistic", min_return = 0.0, reflectance = None))]
pub(crate) fn simulate<'py>(
    py: Python<'py>,
    scene: &str,
    #[pyo3(from_py_with = crate::ints::int)] seed: u64,
    camera: Option<&PyCamera>,
    noise: &str,
    #[pyo3(from_py_with = min_return_arg)] min_return: f64,
    #[pyo3(from_py_with = reflectance_arg)] reflectance: Option<HashMap<i64, f64>>,
) -> PyResult<SimResult<'py>> {
    // An unknown name's error lists the scenes.
    let mut named = named_scene(scene).map_err(value_error)?;
    // In label order, so that the first bad entry is the one reported whatever the dict's order.
    let mut entries: Vec<(i64, f64)> = reflectance.unwrap_or_default().into_iter().collect();
    entries.sort_by_key(|e| e.0);
    let any_reflectance = !entries.is_empty();
    for (label, rho) in entries {
        let label = u16::try_from(label).map_err(|_| {
            value_error(format!(
                "no surface {label} (the scene has labels 1..={})",
                named.scene.len()
            ))
        })?;
        named
            .scene
            .set_reflectance(label, rho)
            .map_err(value_error)?;
    }
    let (intrinsics, sim) = match camera {
        Some(c) => (
            c.inner.intrinsics,
            KinectSimulator::with_sensor(c.inner.sensor),
        ),
        None => (named.intrinsics, KinectSimulator::kinect_v1()),
    };
    let model = match noise {
        "realistic" => {
            let mut cfg = RealisticNoise::for_camera(
                camera
                    .and_then(|c| c.preset_name.as_deref())
                    .unwrap_or("kinect-v1"),
            );
            cfg.min_return = min_return;
            cfg.validate().map_err(value_error)?;
            if any_reflectance && min_return == 0.0 {
                return Err(value_error(
                    "reflectance has no effect without a positive min_return: only the \
                     realistic model's drop-out of weak returns reads a reflectance, and \
                     min_return=0 (the default) turns it off",
                ));
            }
            NoiseModel::Realistic(cfg)
        }
        "white" if min_return != 0.0 => {
            return Err(value_error(
                "min_return is a drop-out of the realistic model; the white model has none",
            ));
        }
        "white" if any_reflectance => {
            return Err(value_error(
                "reflectance has no effect with noise=\"white\": only the realistic model's \
                 drop-out of weak returns (a positive min_return) reads a reflectance",
            ));
        }
        "white" => NoiseModel::White,
        other => {
            return Err(value_error(format!(
                "unknown noise model {other:?}; choose \"realistic\" or \"white\""
            )));
        }
    };
    let sim = sim.with_noise(model);
    let frame = compute(py, || {
        sim.simulate(&named.scene, &intrinsics, &named.pose, seed)
    });
    Ok((
        depth_array(py, frame.depth)?,
        depth_array(py, frame.truth)?,
        image_array(py, frame.labels)?,
    ))
}
