//! `sldepth.filter`: the depth filters of sl-filter.

use numpy::PyArray2;
use pyo3::prelude::*;
use sl_filter::{FilterConfig, MAX_RADIUS_PX, Method, MultiScale, Window, multiscale_by_default};

use crate::arrays::{camera_for_depth, depth_array, depth_input};
use crate::camera::{PyCamera, camera_or_default};
use crate::errors::value_error;
use crate::threads::compute;

/// Smooths a depth map (metres) and returns a new float32 (H, W) array; 0 stays invalid.
///
/// ``method``: ``"adaptive"`` (the paper's bilateral filter with range σ_d = k·Z², k from the
/// camera's noise model), ``"bilateral"`` (fixed σ_d), ``"gaussian"``, ``"disparity"`` (bilateral
/// in disparity). ``radius`` (pixels, window 2r+1, default 3, at most 32), ``sigma_s`` (pixels;
/// without ``radius`` the window grows to ceil(2·sigma_s), at most 32), and the
/// method's range parameter (``k_per_m``, ``sigma_d_m`` or ``sigma_disp_px``) override the
/// defaults. ``window``: ``"square"`` (default, the full 2r+1 square) or ``"disc"`` (dx² + dy²
/// ≤ r², OpenCV's ``bilateralFilter`` window, about half the taps). ``depth_scale`` converts
/// uint16 input (units per metre). ``multiscale``: follow the pass with the coarse
/// disparity-domain passes (taps 2, 4 and 8 px apart) that remove real sensors' spatially
/// correlated error; ``None`` (default) means yes for ``"adaptive"`` and ``"disparity"`` and no
/// for ``"gaussian"`` and ``"bilateral"``, as ``sldepth filter`` (``--single-scale``).
/// ``estimate_noise``: measure the frame's disparity noise against the camera's model first (on
/// its 16×16- and 32×32-pixel patches, as ``sldepth filter`` does by default) and, when it is significantly
/// larger, build the range kernels for the measured σ_D (the camera's a floor; explicit range
/// parameters win). Off by default here: it costs 0.2–0.4 ms per 640×480 frame, a third of a
/// 7×7 pass, and ``noise_stats(...)["model_effective_sigma_d_px"]`` measures a sensor once.
/// A frame whose size is the camera's divided by a whole number up to 8 (320×240 for a
/// 640×480 camera) is the camera's sensor decimated (``camera.resampled(1/n)``), as ``sldepth``
/// reads it.
#[pyfunction]
#[pyo3(signature = (depth, camera = None, method = "adaptive", *, radius = None, sigma_s = None, k_per_m = None, sigma_d_m = None, sigma_disp_px = None, window = "square", depth_scale = None, multiscale = None, estimate_noise = false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: Option<&PyCamera>,
    method: &str,
    #[pyo3(from_py_with = crate::ints::opt_int)] radius: Option<usize>,
    #[pyo3(from_py_with = crate::reals::sigma_s)] sigma_s: Option<f64>,
    #[pyo3(from_py_with = crate::reals::k_per_m)] k_per_m: Option<f64>,
    #[pyo3(from_py_with = crate::reals::sigma_d_m)] sigma_d_m: Option<f64>,
    #[pyo3(from_py_with = crate::reals::sigma_disp_px)] sigma_disp_px: Option<f64>,
    window: &str,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    multiscale: Option<bool>,
    estimate_noise: bool,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    if let (None, Some(s)) = (radius, sigma_s) {
        let r = (2.0 * s).ceil();
        if s.is_finite() && r > MAX_RADIUS_PX as f64 {
            return Err(value_error(format!(
                "sigma_s = {}: the window radius it implies, ceil(2·sigma_s) = {} px, exceeds \
                 the maximum {MAX_RADIUS_PX} px; pass radius (at most {MAX_RADIUS_PX}) to keep \
                 this sigma_s in a smaller window",
                sl_core::Compact(s),
                sl_core::Compact(r)
            )));
        }
    }
    let camera = camera_or_default(camera);
    let method = method.parse::<Method>().map_err(value_error)?;
    let mut config = FilterConfig::new(method);
    config.radius_px = radius;
    config.sigma_s_px = sigma_s;
    config.k_per_m = k_per_m;
    config.sigma_d_m = sigma_d_m;
    config.sigma_disp_px = sigma_disp_px;
    config.window = window.parse::<Window>().map_err(value_error)?;
    // Checked before any work, with the camera's own model.
    config.build(&camera.sensor).map_err(value_error)?;
    let input = depth_input(depth, depth_scale)?;
    let view = input.view()?;
    let camera = camera_for_depth(&view, &camera, "depth")?;
    let multiscale = multiscale.unwrap_or_else(|| multiscale_by_default(method));
    let out = compute(py, || -> Result<_, String> {
        let scale = if estimate_noise {
            sl_planes::frame_noise_scale(view, &camera, &sl_planes::PlaneConfig::default())
                .map_err(|e| format!("measuring the frame's noise: {e}"))?
        } else {
            1.0
        };
        let sensor = camera.sensor.with_variance_scale(scale);
        let f = config.build(&sensor).map_err(|e| e.to_string())?;
        if multiscale {
            let m = MultiScale {
                base: f,
                ..MultiScale::default_for(&sensor)
            };
            m.apply(view).map_err(|e| e.to_string())
        } else {
            f.apply(view).map_err(|e| e.to_string())
        }
    })
    .map_err(value_error)?;
    depth_array(py, out)
}
