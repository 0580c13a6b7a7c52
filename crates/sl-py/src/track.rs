//! `sldepth.Tracker`: noise-weighted camera tracking against the model being fused (sl-track
//! and sl-tsdf), the loop `sldepth track` runs, one frame per call.

use numpy::PyArray2;
use pyo3::prelude::*;
use sl_core::{Camera, CameraToWorld, Undistorter};
use sl_filter::MultiScale;
use sl_track::{ModelReference, Tracker, TrackerConfig, WeightMode};
use sl_tsdf::{MeshConfig, RaycastConfig, Truncation, TsdfConfig, TsdfVolume};

use crate::arrays::{check_camera, depth_input, pose_array};
use crate::camera::PyCamera;
use crate::errors::value_error;
use crate::threads::compute;
use crate::tsdf::PyMesh;

/// Tracks a depth camera through a sequence and fuses every tracked frame (1/Z⁴ weights,
/// sensor-adaptive truncation): ``track(depth)`` returns ``(pose, status)`` with ``pose`` the
/// (4, 4) float64 camera-to-world matrix (the first frame is the identity) and ``status`` one
/// of ``"initialised"``, ``"tracked"``, ``"tracked-against-frame"``, ``"recovered"``,
/// ``"relocalised"``, ``"lost"`` (a lost frame gets the last good pose and is not fused —
/// never a silently wrong pose).
///
/// ``weighting``: ``"inv-var"`` (residuals weighted by the sensor model's variance, default) or
/// ``"uniform"``; ``frame_to_model``: track against the raycast of the fused model (default)
/// or against the previous frame; ``voxel_m``: the model's voxel size; ``model_scale``: the
/// fraction of the camera's resolution the model is rendered at for tracking (default
/// ``None``: one pixel per 4 of the sensor's, 0.25 for a 640×480 Kinect, as ``sldepth track
/// --model-scale``); ``prefilter``: the smoothing of every frame before
/// tracking and fusion, as ``sldepth track --prefilter``: ``"multiscale"`` (default:
/// ``filter``'s default, which removes real sensors' spatially correlated error),
/// ``"single"`` (the adaptive filter's single pass) or ``"none"``; ``lens``: ``"auto"``
/// (default) resamples every frame into the ideal pinhole image first when the camera has a
/// lens model (``camera.lens``: the ``tum-fr1``/``tum-fr2`` presets), as ``sldepth track
/// --lens auto`` does (TUM fr1/rpy: ATE 4.31 → 2.95 cm); ``"none"`` uses the frames as given.
#[pyclass(name = "Tracker", module = "sldepth")]
#[derive(Debug)]
pub struct PyTracker {
    camera: Camera,
    tracker: Tracker,
    volume: TsdfVolume,
    model: ModelReference,
    frame_to_model: bool,
    prefilter: Option<MultiScale>,
    undistorter: Option<Undistorter>,
    /// Why the last frame was lost (or its attempts failed before a recovery).
    last_failure: Option<String>,
    /// The last frame's weakest-direction σ, metres (NaN when not checked).
    last_weakest_sigma_m: f64,
}

#[pymethods]
impl PyTracker {
    #[new]
    #[pyo3(signature = (camera, *, weighting = "inv-var", frame_to_model = true, voxel_m = 0.004, model_scale = None, prefilter = "multiscale", lens = "auto"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        camera: &PyCamera,
        weighting: &str,
        frame_to_model: bool,
        voxel_m: f64,
        model_scale: Option<f64>,
        prefilter: &str,
        lens: &str,
    ) -> PyResult<Self> {
        let undistorter = match lens {
            "auto" => camera
                .lens
                .filter(|l| !l.is_zero())
                .map(|l| Undistorter::new(&camera.inner.intrinsics, &l)),
            "none" => None,
            other => {
                return Err(value_error(format!(
                    "unknown lens {other:?}: use \"auto\" or \"none\""
                )));
            }
        };
        let camera = camera.inner;
        let default = MultiScale::default_for(&camera.sensor);
        let prefilter = match prefilter {
            "multiscale" => Some(default),
            // The single pass is the multi-scale filter without its coarse passes.
            "single" => Some(MultiScale {
                dilations: Vec::new(),
                ..default
            }),
            "none" => None,
            other => {
                return Err(value_error(format!(
                    "unknown prefilter {other:?}: use \"multiscale\", \"single\" or \"none\""
                )));
            }
        };
        let mut cfg = TrackerConfig::default();
        cfg.weighting = WeightMode::parse(weighting).map_err(value_error)?;
        let mut tracker = Tracker::new(camera, cfg).map_err(value_error)?;
        tracker.set_initial_pose(CameraToWorld::identity());
        let mut params = TsdfConfig::default();
        params.voxel_m = voxel_m;
        params.trunc_m = 5.0 * voxel_m;
        params.truncation = Truncation::sensor_adaptive(camera.sensor);
        let volume = TsdfVolume::new(params).map_err(value_error)?;
        let mut raycast_config = RaycastConfig::default();
        raycast_config.min_depth_m = params.min_depth_m;
        raycast_config.max_depth_m = params.max_depth_m;
        let model_scale = model_scale.unwrap_or_else(|| ModelReference::default_scale(&camera));
        let model = ModelReference::new(&camera.intrinsics, model_scale, raycast_config)
            .map_err(value_error)?;
        Ok(Self {
            camera,
            tracker,
            volume,
            model,
            frame_to_model,
            prefilter,
            undistorter,
            last_failure: None,
            last_weakest_sigma_m: f64::NAN,
        })
    }

    /// Tracks one depth frame (float32 metres, or uint16 with ``depth_scale``), fuses it when
    /// tracked, and returns ``(pose, status)``. ``timestamp_s``: the frame's time in seconds
    /// (any origin, increasing); with it, frames the recording dropped are predicted across
    /// (the time since the previous frame in whole 1/30 s intervals); without it, the frame
    /// follows the previous one by one interval.
    #[pyo3(signature = (depth, depth_scale = None, *, timestamp_s = None))]
    fn track<'py>(
        &mut self,
        py: Python<'py>,
        depth: &Bound<'py, PyAny>,
        depth_scale: Option<f64>,
        timestamp_s: Option<f64>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, &'static str)> {
        let input = depth_input(depth, depth_scale)?;
        let view = input.view()?;
        check_camera(&view, &self.camera)?;
        let k = self.camera.intrinsics;
        let sensor = self.camera.sensor;
        let Self {
            tracker,
            volume,
            model,
            frame_to_model,
            prefilter,
            undistorter,
            ..
        } = self;
        let result = compute(py, || -> Result<_, String> {
            let undistorted = match undistorter {
                Some(u) => Some(u.apply(view).map_err(|e| e.to_string())?),
                None => None,
            };
            let view = undistorted.as_ref().map_or(view, |d| d.view());
            let depth = match prefilter {
                Some(f) => f.apply(view).map_err(|e| e.to_string())?,
                None => view.to_image(),
            };
            let r = match timestamp_s {
                Some(t) => tracker.track_at(&depth, model.maps(), t),
                None => tracker.track(&depth, model.maps()),
            }
            .map_err(|e| e.to_string())?;
            if r.status.is_tracked() {
                volume
                    .integrate(&depth, &k, &r.pose)
                    .map_err(|e| e.to_string())?;
                if *frame_to_model {
                    model
                        .update_from_frame(volume, &r.pose, &sensor, &depth, &k)
                        .map_err(|e| e.to_string())?;
                }
            }
            Ok(r)
        })
        .map_err(value_error)?;
        self.last_failure = result.failure.clone();
        self.last_weakest_sigma_m = result.weakest_sigma_m;
        Ok((
            pose_array(py, &result.pose.to_matrix())?,
            result.status.as_str(),
        ))
    }

    /// Why the last frame was lost, or why the attempts before its recovery failed (for
    /// instance ``"degenerate view: …"`` for a single wall); ``None`` when the first attempt
    /// succeeded.
    #[getter]
    fn last_failure(&self) -> Option<String> {
        self.last_failure.clone()
    }

    /// The last frame's standard deviation of the pose along its least-constrained direction,
    /// metres, from the sensor model and the frame's planes (``inf`` for a single plane; a
    /// frame is lost above the motion prior's 10.9 mm): of the frame alone, and once it is
    /// aligned, of the part of it that overlaps the reference (the larger is reported).
    #[getter]
    fn last_weakest_sigma_m(&self) -> f64 {
        self.last_weakest_sigma_m
    }

    /// The mesh of everything fused so far (marching cubes).
    fn extract_mesh(&self, py: Python<'_>) -> PyResult<PyMesh> {
        let volume = &self.volume;
        let mesh = compute(py, || volume.extract_mesh(&MeshConfig::default()));
        PyMesh::from_mesh(py, mesh)
    }
}
