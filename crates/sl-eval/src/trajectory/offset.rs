//! The clock offset between an estimated trajectory and its ground truth, measured from the
//! trajectories themselves.
//!
//! A camera's frame timestamps and a motion-capture system's need not run on the same clock,
//! or a frame's timestamp may mark the end of its readout rather than its exposure. During
//! fast motion every pose is then compared with a ground-truth pose from another instant, and
//! the error is mostly the offset times the angular speed. [`estimate_time_offset`] tries the
//! offsets of a grid and keeps the one under which the estimate's orientations agree best with
//! the ground truth's: the poses associated as for the ATE, the estimate's orientations turned
//! by the one rotation of the world that fits them best (orthogonal Procrustes: the polar
//! factor of `Σ R_gt·R_estᵀ`), and the RMS of the angles left. Orientations need no alignment
//! of the positions, a lever arm between the ground truth's markers and the camera does not
//! touch them, and they change fastest in the hand-held turns where an offset matters. (The RPE
//! is no measure of it: under a constant angular velocity a delayed pair of poses has the same
//! relative motion.) The ground truth must give the camera's orientation (as TUM's does): a
//! constant rotation between its body and the camera is not fitted. What it finds is the offset
//! that makes *this estimate* agree best: a tracker's own error comes with it, so it says how
//! the clocks relate only for a good estimate of a fast, varied motion.

use sl_core::nalgebra::{Matrix3, Vector3};

use super::{StampedPose, TrajectoryConfig, associate, sorted, sorted_estimate};
use crate::error::{EvalError, Result};

/// The grid of clock offsets [`estimate_time_offset`] tries.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct OffsetSearch {
    /// Offsets from `-max_s` to `max_s` are tried, seconds.
    pub max_s: f64,
    /// Spacing of the tried offsets, seconds.
    pub step_s: f64,
}

impl Default for OffsetSearch {
    /// ±100 ms in steps of 1 ms.
    fn default() -> Self {
        Self {
            max_s: 0.1,
            step_s: 0.001,
        }
    }
}

/// Most offsets [`OffsetSearch`] may try (each costs one RPE evaluation).
pub const MAX_OFFSETS_TRIED: usize = 100_001;

impl OffsetSearch {
    /// Checks the grid: a positive, finite step and range within
    /// [`super::MAX_OFFSET_S`], at most [`MAX_OFFSETS_TRIED`] offsets.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_s.is_finite()
            && self.max_s >= 0.0
            && self.max_s <= super::MAX_OFFSET_S
            && self.step_s.is_finite()
            && self.step_s > 0.0)
        {
            return Err(EvalError::InvalidParameter(format!(
                "offset search ±{} s in steps of {} s: the range must be within ±{} s and the \
                 step positive",
                sl_core::Compact(self.max_s),
                sl_core::Compact(self.step_s),
                super::MAX_OFFSET_S
            )));
        }
        if self.max_s / self.step_s > (MAX_OFFSETS_TRIED / 2) as f64 {
            return Err(EvalError::InvalidParameter(format!(
                "offset search ±{} s in steps of {} s tries more than {MAX_OFFSETS_TRIED} offsets",
                self.max_s, self.step_s
            )));
        }
        Ok(())
    }

    /// The offsets tried, increasing, zero included.
    fn offsets(&self) -> Vec<f64> {
        let n = (self.max_s / self.step_s).floor() as i64;
        (-n..=n).map(|k| k as f64 * self.step_s).collect()
    }
}

/// The result of [`estimate_time_offset`].
#[derive(Debug, Clone, PartialEq)]
pub struct TimeOffset {
    /// The offset to add to the estimate's timestamps (as [`TrajectoryConfig::offset_s`]),
    /// seconds: the tried offset with the smallest orientation error (the smallest in
    /// magnitude among equal ones).
    pub offset_s: f64,
    /// RMS orientation error at that offset, degrees.
    pub rotation_rmse_deg: f64,
    /// RMS orientation error at no offset, degrees (NaN when it could not be evaluated).
    pub rotation_rmse_at_zero_deg: f64,
    /// Poses associated at the offset found.
    pub matched: usize,
    /// Every offset tried that could be evaluated, with its RMS orientation error (s, degrees).
    pub curve: Vec<(f64, f64)>,
}

/// The clock offset of `est` against `gt` (see the module docs): the RMS orientation error,
/// after the best rotation of the world, of the poses associated within `config.max_gap_s`
/// (its own `offset_s` replaced by each tried offset), for every offset of `search`. Fails
/// when no tried offset associates three poses.
pub fn estimate_time_offset(
    est: &[StampedPose],
    gt: &[StampedPose],
    config: &TrajectoryConfig,
    search: &OffsetSearch,
) -> Result<TimeOffset> {
    config.validate()?;
    search.validate()?;
    let gt = sorted(gt, "ground-truth")?;
    let mut curve = Vec::new();
    let mut best: Option<(f64, f64, usize)> = None;
    let mut at_zero = f64::NAN;
    for offset in search.offsets() {
        let cfg = TrajectoryConfig {
            offset_s: offset,
            ..*config
        };
        let est = sorted_estimate(est, &cfg)?;
        let pairs = associate(&gt, &est, cfg.max_gap_s);
        let Some(v) = orientation_rmse_deg(&gt, &est, &pairs) else {
            continue;
        };
        curve.push((offset, v));
        if offset == 0.0 {
            at_zero = v;
        }
        let better = match best {
            None => true,
            Some((o, b, _)) => v < b || (v == b && offset.abs() < o.abs()),
        };
        if better {
            best = Some((offset, v, pairs.len()));
        }
    }
    match best {
        Some((offset_s, rotation_rmse_deg, matched)) => Ok(TimeOffset {
            offset_s,
            rotation_rmse_deg,
            rotation_rmse_at_zero_deg: at_zero,
            matched,
            curve,
        }),
        None => Err(EvalError::InvalidParameter(format!(
            "no offset within ±{} s associates three estimated poses with the ground truth \
             within {} s: did you pass the right files?",
            sl_core::Compact(search.max_s),
            sl_core::Compact(config.max_gap_s)
        ))),
    }
}

/// RMS angle, degrees, between the ground truth's orientations and the estimate's turned by
/// the world rotation that fits them best (`None` below three pairs).
fn orientation_rmse_deg(
    gt: &[StampedPose],
    est: &[StampedPose],
    pairs: &[(usize, usize)],
) -> Option<f64> {
    if pairs.len() < 3 {
        return None;
    }
    let world = best_world_rotation(gt, est, pairs)?;
    let sum_sq: f64 = pairs
        .iter()
        .map(|&(i, j)| orientation_error_rad(&world, &gt[i], &est[j]).powi(2))
        .sum();
    Some((sum_sq / pairs.len() as f64).sqrt().to_degrees())
}

/// The rotation of the world that turns the estimate's orientations of `pairs` nearest to the
/// ground truth's (the polar factor of `Σ R_gt·R_estᵀ`, with the reflection fix); `None` when
/// its decomposition fails.
pub(super) fn best_world_rotation(
    gt: &[StampedPose],
    est: &[StampedPose],
    pairs: &[(usize, usize)],
) -> Option<Matrix3<f64>> {
    let m: Matrix3<f64> = pairs
        .iter()
        .map(|&(i, j)| rotation(&gt[i]) * rotation(&est[j]).transpose())
        .sum();
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    d[(2, 2)] = (u * v_t).determinant().signum();
    Some(u * d * v_t)
}

/// The angle, radians, between a ground-truth orientation and an estimated one turned by
/// `world`.
pub(super) fn orientation_error_rad(
    world: &Matrix3<f64>,
    gt: &StampedPose,
    est: &StampedPose,
) -> f64 {
    angle(&(rotation(gt).transpose() * world * rotation(est)))
}

/// A pose's orientation as a matrix.
fn rotation(p: &StampedPose) -> Matrix3<f64> {
    *p.1.isometry().rotation.to_rotation_matrix().matrix()
}

/// The angle of a rotation matrix, radians, from both its sine (the skew part) and its cosine
/// (the trace): exact near zero, where `acos` of the trace loses half the digits, and never NaN
/// for a matrix rounded slightly off a rotation.
fn angle(r: &Matrix3<f64>) -> f64 {
    let s = 0.5
        * Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        )
        .norm();
    let c = 0.5 * (r.trace() - 1.0);
    s.atan2(c)
}
