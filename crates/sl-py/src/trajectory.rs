//! Trajectories: TUM-format files in and out (`sl_io::trajectory`), and their accuracy against
//! ground truth with the TUM benchmark's definitions (`sl_eval::trajectory`), as `sldepth
//! eval-traj` reports it.

use numpy::{IntoPyArray, PyArray1, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sl_core::CameraToWorld;
use sl_eval::trajectory::{
    DeltaUnit, ErrorStats, OffsetSearch, StampedPose, TrajectoryConfig, ate, rpe,
};
use sl_io::trajectory::TimedPose;

use crate::arrays::{pose_input, poses_array};
use crate::errors::{io_error, value_error};

/// Timestamps (N,) and poses (N, 4, 4) as NumPy arrays.
type Trajectory<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray3<f64>>);

/// Reads a trajectory file: TUM format (``timestamp tx ty tz qx qy qz qw`` per line,
/// camera-to-world, ``#`` comments; e.g. a sequence's ``groundtruth.txt`` or ``sldepth track
/// --output``), or an Open3D ``.log`` (entries ``i i n``, each pose stamped with its frame
/// number ``i``, as ``sldepth track`` stamps a folder's frames without timestamps; a pairwise
/// registration log raises ``OSError``): ``(timestamps_s, poses)``, float64 arrays (N,) and
/// (N, 4, 4), sorted by time.
#[pyfunction]
pub(crate) fn read_trajectory<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
) -> PyResult<Trajectory<'py>> {
    let poses = sl_io::trajectory::read_trajectory(&path).map_err(io_error)?;
    let times: Vec<f64> = poses.iter().map(|p| p.timestamp).collect();
    let matrices: Vec<_> = poses.iter().map(|p| p.pose.to_matrix()).collect();
    Ok((times.into_pyarray(py), poses_array(py, &matrices)))
}

/// Timestamps and poses from Python: one finite timestamp per (4, 4) camera-to-world pose.
fn stamped(
    what: &str,
    timestamps_s: Vec<f64>,
    poses: &Bound<'_, PyAny>,
) -> PyResult<Vec<StampedPose>> {
    let poses: Vec<CameraToWorld> = poses
        .try_iter()
        .map_err(|_| value_error(format!("{what} poses must be an (N, 4, 4) array")))?
        .map(|p| pose_input(&p?))
        .collect::<PyResult<_>>()?;
    if poses.len() != timestamps_s.len() {
        return Err(value_error(format!(
            "{what}: {} timestamps for {} poses",
            timestamps_s.len(),
            poses.len()
        )));
    }
    Ok(timestamps_s.into_iter().zip(poses).collect())
}

/// Writes a trajectory as a TUM file (atomically), ``timestamps_s`` (N,) and ``poses``
/// (N, 4, 4) camera-to-world, e.g. those of ``track_sequence``.
#[pyfunction]
pub(crate) fn write_trajectory(
    path: std::path::PathBuf,
    timestamps_s: Vec<f64>,
    poses: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let poses: Vec<TimedPose> = stamped("trajectory", timestamps_s, poses)?
        .into_iter()
        .map(|(timestamp, pose)| TimedPose { timestamp, pose })
        .collect();
    sl_io::trajectory::write_tum_trajectory(&path, &poses).map_err(io_error)
}

/// The estimated and the ground-truth trajectory of an evaluation, checked.
type Trajectories = (Vec<StampedPose>, Vec<StampedPose>);

fn estimate_and_truth(
    timestamps_s: Vec<f64>,
    poses: &Bound<'_, PyAny>,
    gt_timestamps_s: Vec<f64>,
    gt_poses: &Bound<'_, PyAny>,
) -> PyResult<Trajectories> {
    Ok((
        stamped("estimated", timestamps_s, poses)?,
        stamped("ground-truth", gt_timestamps_s, gt_poses)?,
    ))
}

fn stats_dict<'py>(py: Python<'py>, s: &ErrorStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rmse", s.rmse)?;
    d.set_item("mean", s.mean)?;
    d.set_item("median", s.median)?;
    d.set_item("std", s.std)?;
    d.set_item("min", s.min)?;
    d.set_item("max", s.max)?;
    Ok(d)
}

/// The accuracy of an estimated trajectory against ground truth, with the TUM RGB-D benchmark's
/// definitions (as ``sldepth eval-traj --json``): ``ate_m``, the absolute trajectory error after
/// Horn's rigid alignment (no scale) of the poses matched by nearest timestamp within
/// ``max_gap_s``; ``rpe``, the relative pose error over ``delta`` frames or seconds
/// (``delta_unit``), ``translation_m`` and ``rotation_deg``. Each error is a dict of ``rmse``,
/// ``mean``, ``median``, ``std``, ``min``, ``max``. Timestamps in seconds, poses (N, 4, 4)
/// camera-to-world (``read_trajectory``, ``track_sequence``). ``offset_s`` is added to the
/// estimate's timestamps first (``estimate_time_offset`` measures it). ``per_pose``: each
/// matched pose's error after the ATE's alignment, in the estimate's time order, as float64
/// arrays ``timestamps_s`` (the estimate's own, before ``offset_s``), ``gt_timestamps_s``,
/// ``translation_m`` and ``rotation_deg`` (the orientation's error after the rotation of the
/// world that fits the orientations best), to see where a trajectory goes wrong.
#[pyfunction]
#[pyo3(signature = (timestamps_s, poses, gt_timestamps_s, gt_poses, *, max_gap_s = 0.02, delta = 1.0, delta_unit = "frames", offset_s = 0.0))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate_trajectory<'py>(
    py: Python<'py>,
    timestamps_s: Vec<f64>,
    poses: &Bound<'py, PyAny>,
    gt_timestamps_s: Vec<f64>,
    gt_poses: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = crate::reals::max_gap_s)] max_gap_s: f64,
    #[pyo3(from_py_with = crate::reals::delta)] delta: f64,
    delta_unit: &str,
    #[pyo3(from_py_with = crate::reals::offset_s)] offset_s: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let (est, gt) = estimate_and_truth(timestamps_s, poses, gt_timestamps_s, gt_poses)?;
    let mut config = TrajectoryConfig::default();
    config.max_gap_s = max_gap_s;
    config.delta = delta;
    config.delta_unit = DeltaUnit::parse(delta_unit).map_err(value_error)?;
    config.offset_s = offset_s;
    let a = ate(&est, &gt, &config).map_err(value_error)?;
    let r = rpe(&est, &gt, &config).map_err(value_error)?;
    let out = PyDict::new(py);
    out.set_item("poses_estimated", a.estimated)?;
    out.set_item("poses_ground_truth", a.ground_truth)?;
    out.set_item("poses_matched", a.matched)?;
    out.set_item("max_gap_s", config.max_gap_s)?;
    out.set_item("offset_s", config.offset_s)?;
    out.set_item("ate_m", stats_dict(py, &a.stats_m)?)?;
    let pp = PyDict::new(py);
    let column = |f: fn(&sl_eval::trajectory::PoseError) -> f64| -> Vec<f64> {
        a.per_pose.iter().map(f).collect()
    };
    pp.set_item("timestamps_s", column(|e| e.timestamp_s).into_pyarray(py))?;
    pp.set_item(
        "gt_timestamps_s",
        column(|e| e.ground_truth_timestamp_s).into_pyarray(py),
    )?;
    pp.set_item(
        "translation_m",
        column(|e| e.translation_m).into_pyarray(py),
    )?;
    pp.set_item("rotation_deg", column(|e| e.rotation_deg).into_pyarray(py))?;
    out.set_item("per_pose", pp)?;
    let rp = PyDict::new(py);
    rp.set_item("delta", config.delta)?;
    rp.set_item("delta_unit", config.delta_unit.name())?;
    rp.set_item("pairs", r.pairs)?;
    rp.set_item("max_gap_s", r.max_gap_s)?;
    rp.set_item("translation_m", stats_dict(py, &r.translation_m)?)?;
    rp.set_item("rotation_deg", stats_dict(py, &r.rotation_deg)?)?;
    out.set_item("rpe", rp)?;
    Ok(out)
}

/// The clock offset of an estimated trajectory against its ground truth (as ``sldepth eval-traj
/// --estimate-offset``): every offset within ``±max_s`` in steps of ``step_s`` is added to the
/// estimate's timestamps, the poses matched within ``max_gap_s``, the estimate's orientations
/// turned by the rotation of the world that fits them best, and the offset with the smallest
/// RMS angle left is returned: a dict of ``offset_s`` (pass it to ``evaluate_trajectory``),
/// ``rotation_rmse_deg``, ``rotation_rmse_at_zero_deg``, ``matched`` and ``curve`` (a list of
/// ``(offset_s, rmse_deg)``).
#[pyfunction]
#[pyo3(signature = (timestamps_s, poses, gt_timestamps_s, gt_poses, *, max_gap_s = 0.02, max_s = 0.1, step_s = 0.001))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn estimate_time_offset<'py>(
    py: Python<'py>,
    timestamps_s: Vec<f64>,
    poses: &Bound<'py, PyAny>,
    gt_timestamps_s: Vec<f64>,
    gt_poses: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = crate::reals::max_gap_s)] max_gap_s: f64,
    #[pyo3(from_py_with = crate::reals::max_s)] max_s: f64,
    #[pyo3(from_py_with = crate::reals::step_s)] step_s: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let (est, gt) = estimate_and_truth(timestamps_s, poses, gt_timestamps_s, gt_poses)?;
    let mut config = TrajectoryConfig::default();
    config.max_gap_s = max_gap_s;
    let mut search = OffsetSearch::default();
    search.max_s = max_s;
    search.step_s = step_s;
    let f = py
        .detach(|| sl_eval::trajectory::estimate_time_offset(&est, &gt, &config, &search))
        .map_err(value_error)?;
    let out = PyDict::new(py);
    out.set_item("offset_s", f.offset_s)?;
    out.set_item("rotation_rmse_deg", f.rotation_rmse_deg)?;
    out.set_item("rotation_rmse_at_zero_deg", f.rotation_rmse_at_zero_deg)?;
    out.set_item("matched", f.matched)?;
    out.set_item("curve", f.curve)?;
    Ok(out)
}
