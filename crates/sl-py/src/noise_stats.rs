//! `noise_stats`: the real-noise statistics of a depth map (σ_D per depth band, residual
//! autocorrelation, terrace widths, occlusion bands; `sl_noise::stats`), on the planes
//! `sl-planes` finds or on labels the caller gives, as `sldepth noise-stats --json` reports them.

use numpy::{PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyModule;
use sl_core::Image;
use sl_noise::stats::{NoiseStatsConfig, noise_stats as stats};
use sl_planes::{PlaneConfig, extract_planes, frame_noise_scale};

use crate::arrays::{camera_for_depth, depth_input};
use crate::camera::{PyCamera, camera_or_default};
use crate::errors::value_error;
use crate::threads::compute;

/// `labels` as a uint16 (H, W) array, or a `ValueError` naming the argument (pyo3's own
/// conversion error says neither which argument nor what it wants).
fn labels_input<'py>(obj: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArray2<'py, u16>> {
    let Ok(arr) = obj.cast::<PyUntypedArray>() else {
        return Err(value_error(format!(
            "labels must be a uint16 NumPy array of shape (H, W) (0 = no region), got {}",
            obj.get_type()
                .name()
                .map_or_else(|_| "?".into(), |n| n.to_string())
        )));
    };
    if arr.ndim() != 2 {
        return Err(value_error(format!(
            "labels must be 2-D (H, W), got an array of shape {:?}",
            arr.shape()
        )));
    }
    obj.extract::<PyReadonlyArray2<'py, u16>>().map_err(|_| {
        let dtype = arr
            .dtype()
            .str()
            .map_or_else(|_| "?".into(), |d| d.to_string());
        value_error(format!(
            "labels must be uint16 (H, W) (0 = no region, as extract_planes returns them), got \
             dtype {dtype}; convert with labels.astype(numpy.uint16)"
        ))
    })
}

/// The noise statistics of a depth map with planar regions, as a dict with the keys of
/// ``sldepth noise-stats --json``: ``sigma_d_px`` (median RMS disparity residual of 64-px tiles
/// of the regions after an affine fit, pixels), ``bands`` (σ_D per depth band), ``acf``
/// (residual autocorrelation at lags 1, 2, 4, 8, 16 px along x and y), ``terraces`` (widths of
/// runs of equal depth; the histogram's ``bin_upper_px`` ends with ``None``, its open bin),
/// ``occlusion`` (invalid bands left and right of foreground objects, with the projector
/// shadow the geometry predicts, and ``by_shadow``: the edges, and those with a band, per bin
/// of predicted shadow), ``invalid_fraction``, ``regions``,
/// ``pixels``, ``fb_px_m`` (the camera's f·B the disparities were computed with, px·m). Values
/// that could not be measured are ``None``. ``labels`` (uint16 (H, W),
/// 0 = none) gives the planar regions; by default they are the planes ``extract_planes`` finds
/// with at least ``min_plane_pixels`` sensor pixels. Against the camera's own model:
/// ``model_sigma_d_px`` (its σ_D), ``model_variance_scale`` (how many times the model's pixel
/// variance the frame's patches measure, 1 when within it; ``PlaneExtractor::noise_scale``) and
/// ``model_effective_sigma_d_px`` (the σ_D that variance means).
#[pyfunction]
#[pyo3(signature = (depth, camera = None, labels = None, *, min_plane_pixels = 2000, depth_scale = None))]
pub(crate) fn noise_stats<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: Option<&PyCamera>,
    labels: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = crate::ints::int)] min_plane_pixels: usize,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let camera = camera_or_default(camera);
    let input = depth_input(depth, depth_scale)?;
    let view = input.view()?;
    let camera = camera_for_depth(&view, &camera, "depth")?;
    let labels = labels
        .filter(|l| !l.is_none())
        .map(labels_input)
        .transpose()?;
    let given = match &labels {
        Some(l) => {
            let (h, w) = (l.shape()[0], l.shape()[1]);
            if (w, h) != (view.width(), view.height()) {
                return Err(value_error(format!(
                    "labels are {w}x{h} (W x H), the depth map {}x{}",
                    view.width(),
                    view.height()
                )));
            }
            Some(
                Image::from_vec(w, h, l.as_array().iter().copied().collect())
                    .map_err(value_error)?,
            )
        }
        None => None,
    };
    let json = compute(py, || -> Result<String, String> {
        let regions = match given {
            Some(l) => l,
            None => {
                let mut cfg = PlaneConfig::default();
                cfg.min_pixels = min_plane_pixels.max(3);
                extract_planes(view, &camera, &cfg)
                    .map_err(|e| format!("extracting planes: {e}"))?
                    .labels
            }
        };
        let opts = NoiseStatsConfig::for_camera(&camera);
        let s = stats(&view.to_image(), camera.sensor.fb(), &regions, &opts)
            .map_err(|e| e.to_string())?;
        let scale = frame_noise_scale(view, &camera, &PlaneConfig::default())
            .map_err(|e| format!("measuring the noise against the camera's model: {e}"))?;
        let mut v = serde_json::to_value(&s).map_err(|e| e.to_string())?;
        if let Some(o) = v.as_object_mut() {
            let sensor = camera.sensor;
            o.insert("fb_px_m".into(), sensor.fb().into());
            o.insert("model_sigma_d_px".into(), sensor.sigma_d_px.into());
            o.insert("model_variance_scale".into(), scale.into());
            o.insert(
                "model_effective_sigma_d_px".into(),
                sensor.sigma_d_for_variance_scale(scale).into(),
            );
        }
        serde_json::to_string(&v).map_err(|e| e.to_string())
    })
    .map_err(value_error)?;
    PyModule::import(py, "json")?.call_method1("loads", (json,))
}
