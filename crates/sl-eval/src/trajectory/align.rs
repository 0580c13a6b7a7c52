//! The absolute trajectory error: associate, align the estimated positions onto the ground
//! truth with Horn's closed-form rigid motion (no scale, as `evaluate_ate.py`), and measure
//! the distances that remain.

use sl_core::CameraToCamera;
use sl_core::nalgebra::{Matrix3, Point3, Vector3};

use super::offset::{best_world_rotation, orientation_error_rad};
use super::{StampedPose, TrajectoryConfig, associate, on_truth_clock, sorted};
use crate::error::{EvalError, Result};

use super::stats::ErrorStats;

/// The absolute trajectory error of an estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct AteResult {
    /// Translation errors after the alignment, metres.
    pub stats_m: ErrorStats,
    /// Poses of the estimate matched to a ground-truth pose.
    pub matched: usize,
    /// Poses of the estimate.
    pub estimated: usize,
    /// Poses of the ground truth.
    pub ground_truth: usize,
    /// The rigid motion applied to the estimate: `X_gt = T·X_est`.
    pub alignment: CameraToCamera,
    /// Each matched pose's error after the alignment, in the estimate's time order: where a
    /// trajectory goes wrong, not only by how much (evo's per-pose APE).
    pub per_pose: Vec<PoseError>,
}

/// One matched pose's error after the ATE's rigid alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseError {
    /// The estimated pose's timestamp, seconds, as in the estimate (before
    /// [`TrajectoryConfig::offset_s`]).
    pub timestamp_s: f64,
    /// The timestamp of the ground-truth pose it was matched to, seconds.
    pub ground_truth_timestamp_s: f64,
    /// Distance of the aligned estimated camera centre from the ground truth's, metres (the
    /// ATE's error).
    pub translation_m: f64,
    /// Angle between the estimated orientation and the ground truth's, degrees, after the
    /// rotation of the world that fits the estimate's orientations best (as
    /// [`estimate_time_offset`](super::estimate_time_offset) measures them), not after the
    /// ATE's alignment: that one is fitted to positions, which pin its rotation poorly where
    /// the camera barely moves. Not part of the ATE, which compares positions only.
    pub rotation_deg: f64,
}

/// ATE of `est` against `gt` (see the module docs): the positions of the poses associated
/// within `config.max_gap_s` are aligned by the rigid motion minimising the squared distances
/// (Horn / Kabsch through the SVD of the cross-covariance, with the reflection fix), and the
/// remaining distances summarised. Fails with fewer than two associated poses.
pub fn ate(
    est: &[StampedPose],
    gt: &[StampedPose],
    config: &TrajectoryConfig,
) -> Result<AteResult> {
    config.validate()?;
    // The estimate's own stamps, in the same order (the offset keeps the order).
    let est = sorted(est, "estimated")?;
    let stamps: Vec<f64> = est.iter().map(|p| p.0).collect();
    let est = on_truth_clock(est, config)?;
    let gt = sorted(gt, "ground-truth")?;
    if est.len() < 2 || gt.len() < 2 {
        return Err(EvalError::InvalidParameter(format!(
            "the trajectory error needs at least two poses in each trajectory: the estimate holds {}, the ground truth {}",
            est.len(),
            gt.len()
        )));
    }
    let pairs = associate(&gt, &est, config.max_gap_s);
    if pairs.len() < 2 {
        return Err(EvalError::InvalidParameter(format!(
            "only {} of {} estimated poses have a ground-truth pose within {} s: did you pass the right files?",
            pairs.len(),
            est.len(),
            sl_core::Compact(config.max_gap_s)
        )));
    }
    let g: Vec<Point3<f64>> = pairs.iter().map(|&(i, _)| gt[i].1.centre()).collect();
    let e: Vec<Point3<f64>> = pairs.iter().map(|&(_, j)| est[j].1.centre()).collect();
    let (rot, trans) = horn(&e, &g)?;
    let errors: Vec<f64> = e
        .iter()
        .zip(&g)
        .map(|(pe, pg)| (rot * pe.coords + trans - pg.coords).norm())
        .collect();
    let rot = sl_core::nalgebra::Rotation3::from_matrix_unchecked(rot);
    let alignment = CameraToCamera::from_isometry(sl_core::nalgebra::Isometry3::from_parts(
        trans.into(),
        sl_core::nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
    ));
    // Orientations are compared after the world rotation that fits them best, not after the
    // position alignment: where the camera barely moves (TUM's fr1/rpy spans a few
    // centimetres), the positions pin that alignment's rotation to several degrees.
    let world = best_world_rotation(&gt, &est, &pairs).ok_or_else(|| {
        EvalError::InvalidParameter(
            "the orientations' alignment did not converge (non-finite rotations?)".into(),
        )
    })?;
    let mut per_pose: Vec<PoseError> = pairs
        .iter()
        .zip(&errors)
        .map(|(&(i, j), &translation_m)| PoseError {
            timestamp_s: stamps[j],
            ground_truth_timestamp_s: gt[i].0,
            translation_m,
            rotation_deg: orientation_error_rad(&world, &gt[i], &est[j]).to_degrees(),
        })
        .collect();
    per_pose.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    Ok(AteResult {
        stats_m: ErrorStats::of(&errors),
        matched: pairs.len(),
        estimated: est.len(),
        ground_truth: gt.len(),
        alignment,
        per_pose,
    })
}

/// The rotation `R` and translation `t` minimising `Σ |R·model_i + t − data_i|²`.
pub(super) fn horn(
    model: &[Point3<f64>],
    data: &[Point3<f64>],
) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    let n = model.len() as f64;
    let mc = model.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let dc = data.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    // Cross-covariance of data against model: H = U Σ Vᵀ, R = U·diag(1, 1, ±1)·Vᵀ.
    let h = model
        .iter()
        .zip(data)
        .fold(Matrix3::zeros(), |acc, (m, d)| {
            acc + (d.coords - dc) * (m.coords - mc).transpose()
        });
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(EvalError::InvalidParameter(
            "the trajectory alignment did not converge (non-finite positions?)".into(),
        ));
    };
    let mut s = Matrix3::identity();
    if u.determinant() * v_t.determinant() < 0.0 {
        s[(2, 2)] = -1.0;
    }
    let rot = u * s * v_t;
    let trans = dc - rot * mc;
    Ok((rot, trans))
}
