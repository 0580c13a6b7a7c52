//! `sldepth.Tracker`: noise-weighted camera tracking against the model being fused (sl-track
//! and sl-tsdf), the loop `sldepth track` runs, one frame per call.

use numpy::PyArray2;
use std::sync::Mutex;

use pyo3::prelude::*;
use sl_core::nalgebra::Isometry3;
use sl_core::{Camera, Undistorter};
use sl_filter::Prefilter;
use sl_track::{Reconstruction, ReconstructionConfig, WeightMode};
use sl_tsdf::{Mesh, MeshConfig};

use crate::arrays::{check_camera, depth_input, pose_array};
use crate::camera::PyCamera;
use crate::errors::value_error;
use crate::threads::compute_locked;
use crate::tsdf::PyMesh;

/// A join as Python sees it: (fragment, into, 4×4 transform).
type Join<'py> = (usize, usize, Bound<'py, PyArray2<f64>>);

/// A tracked frame as Python sees it: (4×4 camera-to-world pose, status).
type TrackedFrame<'py> = (Bound<'py, PyArray2<f64>>, &'static str);

/// The prefilter named `name` (`"multiscale"`, `"single"` or `"none"`; the names and filters
/// of `sldepth track --prefilter`, one `sl_filter::Prefilter` for both).
fn parse_prefilter(name: &str) -> PyResult<Prefilter> {
    name.parse().map_err(value_error)
}

/// Tracks a sequence of depth frames (a list of float32 metre arrays, or uint16 with
/// ``depth_scale``) in a map that does not change: ``volume``, a ``TsdfVolume`` fused
/// beforehand (from another recording of the place, or at a data set's reference poses; fuse
/// it with ``weight="inv-z4"``, the default, whose weights the tracker's model variances
/// assume). Each frame is aligned to the map's raycast from the last tracked pose, as
/// ``Tracker`` aligns frames to the model it is building, but nothing is fused. The first frame
/// is anchored at ``start_pose`` ((4, 4) camera-to-world). Returns one ``(pose, status)`` per
/// frame, as ``Tracker.track`` does. ``weighting``, ``prefilter`` and ``model_scale`` as for
/// ``Tracker``; each raw frame's noise is measured against the camera's model before the
/// prefilter, which then smooths it, and the tracker weighs it, for that noise (as ``Tracker``
/// with ``estimate_noise=True``); frames are used as given otherwise (undistort them first with ``undistort``
/// for a camera with a lens model). With a map fused at a data set's reference poses, the
/// distance of the tracked poses from those poses is how far the reference is from the poses
/// that align its frames: 7-Scenes' KinectFusion poses about 5 mm ATE, the floor of any depth
/// tracker's error against them (docs/bench/track.md, "Session 28").
#[pyfunction]
#[pyo3(signature = (volume, camera, frames, start_pose, depth_scale = None, *, weighting = "inv-var", prefilter = "multiscale", model_scale = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn track_in_map<'py>(
    py: Python<'py>,
    volume: &crate::tsdf::PyTsdfVolume,
    camera: &PyCamera,
    frames: Vec<Bound<'py, PyAny>>,
    start_pose: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    weighting: &str,
    prefilter: &str,
    #[pyo3(from_py_with = crate::reals::model_scale)] model_scale: Option<f64>,
) -> PyResult<Vec<TrackedFrame<'py>>> {
    let camera = camera.inner;
    let start = crate::arrays::pose_input(start_pose)?;
    let prefilter = parse_prefilter(prefilter)?;
    let mut cfg = ReconstructionConfig::default_for(camera.sensor);
    cfg.tracker.weighting = WeightMode::parse(weighting).map_err(value_error)?;
    let (min_depth_m, max_depth_m) =
        volume.read(py, |v| (v.params().min_depth_m, v.params().max_depth_m))?;
    cfg.tsdf.min_depth_m = min_depth_m;
    cfg.tsdf.max_depth_m = max_depth_m;
    cfg.model_scale = model_scale;
    let inputs = frames
        .iter()
        .map(|f| depth_input(f, depth_scale))
        .collect::<PyResult<Vec<_>>>()?;
    let mut views = Vec::with_capacity(inputs.len());
    for input in &inputs {
        let view = input.view()?;
        check_camera(&view, &camera)?;
        views.push(view);
    }
    let mut meter = cfg.tracker.noise_meter();
    let results = volume
        .read(py, |map| -> Result<_, String> {
            // Each raw frame's noise against the camera's model (the prefilter hides it): the
            // frame is smoothed and tracked with it, as `Tracker.track` does.
            let mut frames = Vec::with_capacity(views.len());
            for v in &views {
                let scale = meter.measure(*v, &camera).map_err(|e| e.to_string())?;
                let sensor = camera.sensor.with_variance_scale(scale);
                let depth = prefilter
                    .apply(*v, &sensor)
                    .map_err(|e| e.to_string())?
                    .unwrap_or_else(|| v.to_image());
                frames.push((depth, Some(scale)));
            }
            let frames = frames.iter().map(|(d, s)| (d, *s));
            sl_track::track_in_map_with_noise(camera, &cfg, map, start, frames)
                .map_err(|e| e.to_string())
        })?
        .map_err(value_error)?;
    results
        .iter()
        .map(|r| Ok((pose_array(py, &r.pose.to_matrix())?, r.status.as_str())))
        .collect()
}

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
/// ``filter``'s default with its coarse passes 2 and 4 px apart, not its third 8 px apart,
/// which cost frames at faster motion; it removes real sensors' spatially correlated error),
/// ``"single"`` (the adaptive filter's single pass) or ``"none"``; ``lens``: ``"auto"``
/// (default) resamples every frame into the ideal pinhole image first when the camera has a
/// lens model (``camera.lens``: the ``tum-fr1``/``tum-fr2`` presets), as ``sldepth track
/// --lens auto`` does (TUM fr1/rpy: ATE 4.31 → 2.95 cm); ``"none"`` uses the frames as given;
/// ``new_fragment_after_s``: after this many seconds of frames that could be aligned but were
/// lost, a new fragment starts (its own volume and world frame, its first camera; ``fragment``,
/// ``frame_fragments``, ``extract_mesh(fragment=k)``), as ``sldepth track
/// --new-fragment-after-s``; ``None`` never starts one. The fragment that stayed lost is tried
/// every sixth frame interval; when the camera comes back to it, tracking goes on there and the
/// newer fragment is joined to it (``joins``). ``rolling_shutter_ms``: the sensor's
/// rolling-shutter readout time, milliseconds (first row to last), as ``sldepth track
/// --rolling-shutter-ms``: each row is aligned from its own pose and frames are fused moved to
/// the middle of their readout; ``None`` (default): ``camera.rolling_shutter_ms`` (30 for the
/// Kinect-class presets, 0 for explicit intrinsics) when tracking against the model, 0 frame
/// to frame; 0: a global shutter; at most the frame interval (33.3 ms at 30 Hz). On TUM
/// fr1/rpy-200 the Kinect's readout keeps every 2nd, 3rd or 4th frame alone tracked (a global
/// shutter loses 0, 4 and 4 frames). ``keyframes``: when every other attempt on a frame fails,
/// align it against earlier frames kept at spread poses (default; as ``sldepth track``,
/// ``--no-keyframes`` turns it off): a camera lost in a fast turn is found again where it looks
/// at something it saw before (TUM fr1/rpy every 4th frame: 7 lost frames → none).
/// ``memory_budget_bytes``: what the model's blocks may hold, all fragments together with the
/// meshes kept of the finished ones (default 4 GiB). ``when_model_full``: what happens when a
/// frame's blocks do not fit in it, as ``sldepth track --when-model-full``: ``"continue"``
/// (default) hands the full fragment over (its mesh is kept, see below) and goes on in a new
/// fragment with a fresh volume in the *same* world frame, fusing that frame there (a
/// continuation, listed in ``joins`` with the identity transform; its mesh overlaps the one
/// before where the camera saw the same surfaces); ``"stop-fusing"``: the model is full from
/// then on (``model_full``), the next frames are tracked against the frame before and not
/// fused. A fresh volume (a fragment's or a continuation's) that cannot hold even its first
/// frame (the meshes kept leave too little) tries every next frame until one fits, tracking
/// against the frame before meanwhile. A full fragment's mesh must fit in what the
/// budget leaves once its volume is dropped (making it holds both, as ``extract_mesh()`` of a
/// full model does). A finished
/// fragment's mesh is made when it finishes, within what the budget leaves, and kept (its bytes
/// taken from the budget); one that does not fit is not kept, and ``extract_mesh(fragment=k)``
/// says so. One tracker may be used from several Python threads: its calls take turns.
#[pyclass(name = "Tracker", module = "sldepth", frozen)]
#[derive(Debug)]
pub struct PyTracker {
    camera: Camera,
    state: Mutex<TrackerState>,
}

/// What a [`PyTracker`] guards.
#[derive(Debug)]
struct TrackerState {
    rec: Reconstruction,
    /// Each frame is smoothed with this prefilter for its measured noise.
    prefilter: Prefilter,
    undistorter: Option<Undistorter>,
    /// Why the last frame was lost (or its attempts failed before a recovery).
    last_failure: Option<String>,
    /// The last frame's weakest-direction σ, metres (NaN when not checked).
    last_weakest_sigma_m: f64,
    /// Measures each raw frame's noise against the camera's model (`estimate_noise`).
    noise_meter: Option<sl_planes::NoiseMeter>,
    /// The last raw frame's pixel variance over the model's (1 within it or not measured).
    last_noise_scale: f64,
    /// The meshes of the finished fragments, by index (`None`: not finished; an error: the
    /// mesh did not fit in the budget).
    finished: Vec<Option<Result<Mesh, String>>>,
    /// Fragments that rejoined the one before: (fragment, into, 4×4 transform into its world).
    joins: Vec<(usize, usize, sl_core::nalgebra::Matrix4<f64>)>,
    /// Per finished fragment, the fragment it continues (`Fragment::continues`).
    continues: Vec<Option<usize>>,
    /// The fragment of every frame given to `track`.
    frame_fragments: Vec<usize>,
}

impl TrackerState {
    /// A continuation that rejoined an older fragment (`join`) shares its world frame with the
    /// fragments it continues, from `from` back to the first of them: their kept meshes move
    /// into the rejoined fragment's world, and the first is joined there (its poses follow in
    /// `track_sequence`), so one continuous track stays in one world.
    fn join_continued(&mut self, from: usize, join: &sl_track::FragmentJoin) {
        let continues = &self.continues;
        let chain: Vec<usize> =
            sl_track::continued_chain(from, |k| continues.get(k).copied().flatten()).collect();
        for &k in &chain {
            if let Some(Some(Ok(mesh))) = self.finished.get_mut(k) {
                mesh.transform(join.transform.isometry());
            }
        }
        if let Some(&first) = chain.last()
            && !self.joins.iter().any(|&(f, _, _)| f == first)
        {
            self.joins
                .push((first, join.into, join.transform.to_matrix()));
        }
    }
}

/// The odometry pose of a frame: a (4, 4) rigid matrix, or `None` (also for a matrix holding
/// NaN, as `RosBag.tf_lookup` gives where the odometry has no pose).
fn odometry_input(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Isometry3<f64>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let nan = obj
        .call_method0("tolist")
        .and_then(|l| l.extract::<Vec<Vec<f64>>>())
        .is_ok_and(|m| m.iter().flatten().any(|v| v.is_nan()));
    if nan {
        return Ok(None);
    }
    let pose = crate::arrays::pose_input(obj).map_err(|e| value_error(format!("odometry: {e}")))?;
    Ok(Some(*pose.isometry()))
}

/// Bytes a tracker holds against its `memory_budget_bytes`: the fragments' volumes and the
/// meshes it keeps of the finished ones (reserved in `rec`).
fn held_bytes(rec: &Reconstruction) -> usize {
    rec.memory_bytes() + rec.reserved_bytes()
}

/// The message of a tracker whose lock holder panicked (no call of this crate should).
const POISONED: &str = "the tracker is unusable: a call on it failed midway";

impl PyTracker {
    /// Runs `f` on the tracker's state with the GIL released (a call on another thread
    /// finishes first).
    fn with_state<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&TrackerState) -> T + Send,
    ) -> PyResult<T> {
        py.detach(|| self.state.lock().map(|s| f(&s)).map_err(|_| POISONED))
            .map_err(value_error)
    }
}

#[pymethods]
impl PyTracker {
    #[new]
    #[pyo3(signature = (camera, *, weighting = "inv-var", frame_to_model = true, voxel_m = 0.004, model_scale = None, prefilter = "multiscale", lens = "auto", new_fragment_after_s = Some(1.0), rolling_shutter_ms = None, estimate_noise = true, keyframes = true, memory_budget_bytes = 4usize << 30, when_model_full = "continue", odometry_drift = 0.05, odometry_min_sigma_m = 0.005, odometry_min_sigma_deg = 0.5))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        camera: &PyCamera,
        weighting: &str,
        frame_to_model: bool,
        #[pyo3(from_py_with = crate::reals::voxel_m)] voxel_m: f64,
        #[pyo3(from_py_with = crate::reals::model_scale)] model_scale: Option<f64>,
        prefilter: &str,
        lens: &str,
        #[pyo3(from_py_with = crate::reals::new_fragment_after_s)] new_fragment_after_s: Option<
            f64,
        >,
        #[pyo3(from_py_with = crate::reals::rolling_shutter_ms)] rolling_shutter_ms: Option<f64>,
        estimate_noise: bool,
        keyframes: bool,
        #[pyo3(from_py_with = crate::ints::int)] memory_budget_bytes: usize,
        when_model_full: &str,
        odometry_drift: f64,
        odometry_min_sigma_m: f64,
        odometry_min_sigma_deg: f64,
    ) -> PyResult<Self> {
        let new_volume_when_full = match when_model_full {
            "continue" => true,
            "stop-fusing" => false,
            other => {
                return Err(value_error(format!(
                    "unknown when_model_full {other:?}: use \"continue\" or \"stop-fusing\""
                )));
            }
        };
        let readout_s = match rolling_shutter_ms {
            Some(ms) => ms / 1000.0,
            None if frame_to_model => camera.rolling_shutter_readout_s(),
            None => 0.0,
        };
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
        let prefilter = parse_prefilter(prefilter)?;
        let mut cfg = ReconstructionConfig::default_for(camera.sensor);
        cfg.tracker.weighting = WeightMode::parse(weighting).map_err(value_error)?;
        cfg.tsdf.voxel_m = voxel_m;
        cfg.tsdf.trunc_m = 5.0 * voxel_m;
        cfg.frame_to_model = frame_to_model;
        cfg.model_scale = model_scale;
        cfg.new_fragment_after_s = new_fragment_after_s.filter(|s| !s.is_infinite());
        cfg.tracker.rolling_shutter_readout_s = readout_s;
        cfg.tracker.estimate_noise = estimate_noise;
        cfg.tracker.keyframe_relocalisation = keyframes;
        cfg.tsdf.memory_budget_bytes = memory_budget_bytes;
        cfg.new_volume_when_full = new_volume_when_full;
        cfg.tracker.odometry_drift = odometry_drift;
        cfg.tracker.odometry_rotation_drift = odometry_drift;
        cfg.tracker.odometry_min_sigma_m = odometry_min_sigma_m;
        cfg.tracker.odometry_min_sigma_deg = odometry_min_sigma_deg;
        let noise_meter = estimate_noise.then(|| cfg.tracker.noise_meter());
        let rec = Reconstruction::new(camera, cfg).map_err(value_error)?;
        Ok(Self {
            camera,
            state: Mutex::new(TrackerState {
                rec,
                prefilter,
                undistorter,
                last_failure: None,
                last_weakest_sigma_m: f64::NAN,
                noise_meter,
                last_noise_scale: 1.0,
                finished: Vec::new(),
                joins: Vec::new(),
                continues: Vec::new(),
                frame_fragments: Vec::new(),
            }),
        })
    }

    /// Tracks one depth frame (float32 metres, or uint16 with ``depth_scale``), fuses it when
    /// tracked, and returns ``(pose, status)``. ``timestamp_s``: the frame's time in seconds
    /// (any origin, increasing); with it, frames the recording dropped are predicted across
    /// (the time since the previous frame in whole 1/30 s intervals); without it, the frame
    /// follows the previous one by one interval. ``odometry``: the camera's pose in an
    /// odometry's frame at this frame ((4, 4), camera to odometry: a robot's wheel odometry,
    /// another tracker's estimate, ``RosBag.tf_lookup``'s), whose motion since the last tracked
    /// frame predicts this one and is the prior of its alignment (σ from ``odometry_drift`` and
    /// the floors given to the constructor): where the depth leaves a direction free (a
    /// corridor's axis, a single wall) the pose takes the odometry's instead of the frame being
    /// lost; elsewhere the depth decides. None, or a matrix with NaN: no odometry for this frame.
    #[pyo3(signature = (depth, depth_scale = None, *, timestamp_s = None, odometry = None))]
    fn track<'py>(
        &self,
        py: Python<'py>,
        depth: &Bound<'py, PyAny>,
        #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
        #[pyo3(from_py_with = crate::reals::timestamp_s)] timestamp_s: Option<f64>,
        odometry: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<TrackedFrame<'py>> {
        let odometry = odometry_input(odometry)?;
        let input = depth_input(depth, depth_scale)?;
        let view = input.view()?;
        check_camera(&view, &self.camera)?;
        let result = compute_locked(py, &self.state, |guard| -> Result<_, String> {
            let TrackerState {
                rec,
                prefilter,
                undistorter,
                noise_meter,
                last_noise_scale,
                ..
            } = guard;
            let undistorted = match undistorter {
                Some(u) => Some(u.apply(view).map_err(|e| e.to_string())?),
                None => None,
            };
            let view = undistorted.as_ref().map_or(view, |d| d.view());
            // The raw frame's noise against the camera's model (the prefilter hides it).
            if let Some(m) = noise_meter {
                let s = m.measure(view, &self.camera).map_err(|e| e.to_string())?;
                *last_noise_scale = s;
                rec.set_noise_scale(Some(s));
            }
            // The prefilter's range kernel follows the frame's measured noise.
            let sensor = self.camera.sensor.with_variance_scale(*last_noise_scale);
            let depth = prefilter
                .apply(view, &sensor)
                .map_err(|e| e.to_string())?
                .unwrap_or_else(|| view.to_image());
            rec.set_odometry(odometry);
            let step = rec.step(&depth, timestamp_s).map_err(|e| e.to_string())?;
            let state = &mut *guard;
            // A finished fragment's volume becomes its mesh at once (about 0.4 times the
            // volume's bytes on TUM fr1/rpy), made within what the budget leaves beside the
            // volumes still held and the meshes kept (the finished volume is counted in the
            // extraction's own budget), and then taken from the budget.
            if let Some(f) = step.finished {
                // A full model's fragment handed over to a continuation: its mesh must fit in
                // what the budget leaves once its volume is dropped (making it holds both at
                // once, as `extract_mesh()` of a full model does); the continuation gets the
                // rest.
                let freed = if step.continued == Some(f.index) {
                    f.volume.memory_bytes()
                } else {
                    0
                };
                let budget = state
                    .rec
                    .config()
                    .tsdf
                    .memory_budget_bytes
                    .saturating_sub(held_bytes(&state.rec))
                    .saturating_add(freed);
                let kept = match f.volume.extract_mesh_within(&MeshConfig::default(), budget) {
                    Ok(mut mesh) => {
                        // A fragment that rejoined the one before is kept in that one's
                        // world frame (a continuation's is already in it: the identity).
                        if let Some(j) = &f.joined {
                            mesh.transform(j.transform.isometry());
                        }
                        state.rec.reserve_bytes(mesh.memory_bytes());
                        Ok(mesh)
                    }
                    Err(e) => Err(format!(
                        "fragment {}'s mesh was not kept: {e} (memory_budget_bytes)",
                        f.index
                    )),
                };
                let rejoin = f.rejoin();
                drop(f.volume);
                if state.finished.len() <= f.index {
                    state.finished.resize_with(f.index + 1, || None);
                    state.continues.resize(f.index + 1, None);
                }
                state.finished[f.index] = Some(kept);
                state.continues[f.index] = f.continues;
                if let Some(j) = f.joined {
                    state.joins.push((f.index, j.into, j.transform.to_matrix()));
                }
                if let (Some(j), Some(p)) = (rejoin, f.continues) {
                    state.join_continued(p, &j);
                }
            }
            let fragment = state.rec.fragment();
            state.frame_fragments.push(fragment);
            state.last_failure = step.result.failure.clone();
            state.last_weakest_sigma_m = step.result.weakest_sigma_m;
            Ok(step.result)
        })
        .map_err(|_| value_error(POISONED))?
        .map_err(value_error)?;
        Ok((
            pose_array(py, &result.pose.to_matrix())?,
            result.status.as_str(),
        ))
    }

    /// Bytes the tracker holds against ``memory_budget_bytes``: the volumes of the current and
    /// the suspended fragment and the meshes kept of the finished ones.
    #[getter]
    fn memory_bytes(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_state(py, |s| held_bytes(&s.rec))
    }

    /// Why the current fragment's model is full (``None`` while it is not): a frame's blocks
    /// did not fit in ``memory_budget_bytes`` and no continuation took over
    /// (``when_model_full="stop-fusing"``, or a fresh volume that could not hold its first
    /// frame: it takes the next frame that fits, and this is ``None`` again); from that frame
    /// on, frames are tracked against the frame before and not fused, and ``extract_mesh``
    /// holds the frames before it.
    #[getter]
    fn model_full(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.with_state(py, |s| s.rec.model_full().map(str::to_owned))
    }

    /// Why the last frame was lost, or why the attempts before its recovery failed (for
    /// instance ``"degenerate view: …"`` for a single wall); ``None`` when the first attempt
    /// succeeded.
    #[getter]
    fn last_failure(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.with_state(py, |s| s.last_failure.clone())
    }

    /// The rolling-shutter readout the tracker models, milliseconds (0: a global shutter).
    #[getter]
    fn rolling_shutter_ms(&self, py: Python<'_>) -> PyResult<f64> {
        self.with_state(py, |s| {
            s.rec.config().tracker.rolling_shutter_readout_s * 1e3
        })
    }

    /// The last frame's standard deviation of the pose along its least-constrained direction,
    /// metres, from the sensor model and the frame's planes (``inf`` for a single plane; a
    /// frame is lost above the motion prior's 10.9 mm): of the frame alone, and once it is
    /// aligned, of the part of it that overlaps the reference (the larger is reported).
    #[getter]
    fn last_weakest_sigma_m(&self, py: Python<'_>) -> PyResult<f64> {
        self.with_state(py, |s| s.last_weakest_sigma_m)
    }

    /// The last frame's disparity-error variance over the camera's model, measured on the raw
    /// frame's own 16×16- and 32×32-pixel patches (before the prefilter) as ``extract_planes`` does; the
    /// frame was tracked with that noise (its weights, gates and degenerate-view checks). 1
    /// when within the model, before any frame, or with ``estimate_noise=False``.
    #[getter]
    fn last_noise_scale(&self, py: Python<'_>) -> PyResult<f64> {
        self.with_state(py, |s| s.last_noise_scale)
    }

    /// The σ_D, disparity pixels, the last frame was smoothed for before tracking: the
    /// camera's, or a noisier raw frame's measured one (``last_noise_scale``), so that the
    /// prefilter's range kernel follows the frame's own noise. ``None`` with
    /// ``prefilter="none"`` or before any frame.
    #[getter]
    fn last_prefilter_sigma_d_px(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        let sensor = self.camera.sensor;
        self.with_state(py, move |s| {
            (s.prefilter != Prefilter::Off && !s.frame_fragments.is_empty())
                .then(|| sensor.sigma_d_for_variance_scale(s.last_noise_scale))
        })
    }

    /// The index of the current fragment: 0 until tracking stays lost for
    /// ``new_fragment_after_s`` seconds of frames that could be aligned, then 1, … (each
    /// fragment has its own volume and world frame, its first camera; the poses ``track``
    /// returns are in the frame of the fragment they belong to).
    #[getter]
    fn fragment(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_state(py, |s| s.rec.fragment())
    }

    /// The fragment of every frame given to ``track``, in order (a list of ints).
    #[getter]
    fn frame_fragments(&self, py: Python<'_>) -> PyResult<Vec<usize>> {
        self.with_state(py, |s| s.frame_fragments.clone())
    }

    /// The finished fragments that ended by rejoining the fragment before them (the camera came
    /// back where that one was lost), or that continue a full one (``when_model_full``, the
    /// identity): a list of ``(fragment, into, transform)`` with ``transform`` the (4, 4)
    /// float64 matrix from ``fragment``'s world frame to ``into``'s (``transform @ pose`` is a
    /// pose of ``fragment`` in ``into``'s world). When a continuation rejoins, the first of
    /// the fragments it continues (their world frame is one) is listed as joined there too,
    /// and their kept meshes are moved into that world.
    #[getter]
    fn joins<'py>(&self, py: Python<'py>) -> PyResult<Vec<Join<'py>>> {
        self.with_state(py, |s| s.joins.clone())?
            .iter()
            .map(|(f, into, m)| Ok((*f, *into, pose_array(py, m)?)))
            .collect()
    }

    /// The mesh of everything fused into fragment ``fragment`` (marching cubes): ``None``
    /// (default) the current one, another index a finished fragment's (extracted when it
    /// finished; a fragment that rejoined the one before is in that one's world frame).
    #[pyo3(signature = (fragment = None))]
    fn extract_mesh(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = crate::ints::opt_int)] fragment: Option<usize>,
    ) -> PyResult<PyMesh> {
        let mesh = compute_locked(py, &self.state, |state| -> Result<_, String> {
            match fragment {
                Some(f) if f != state.rec.fragment() => {
                    match state.finished.get(f).and_then(Option::as_ref) {
                        Some(kept) => kept.clone(),
                        None => Err(format!(
                            "fragment {f} is neither finished nor the current one ({})",
                            state.rec.fragment()
                        )),
                    }
                }
                _ => state
                    .rec
                    .volume_with_waiting_frame()
                    .map(|v| v.extract_mesh(&MeshConfig::default()))
                    .map_err(|e| e.to_string()),
            }
        })
        .map_err(|_| value_error(POISONED))?
        .map_err(value_error)?;
        PyMesh::from_mesh(py, mesh)
    }
}
