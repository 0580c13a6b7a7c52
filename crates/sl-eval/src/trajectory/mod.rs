//! Trajectory accuracy with the TUM RGB-D benchmark's definitions (Sturm et al., IROS 2012,
//! and its tools `evaluate_ate.py` / `evaluate_rpe.py`): the absolute trajectory error after
//! Horn's closed-form rigid alignment ([`ate`]) and the relative pose error over a fixed
//! delta in frames or seconds ([`rpe`](fn@rpe)), on poses matched by nearest timestamp
//! ([`associate`](fn@associate)), optionally after shifting the estimate's clock
//! ([`TrajectoryConfig::offset_s`], which [`estimate_time_offset`] can measure).
//!
//! Trajectories are `(timestamp_s, CameraToWorld)` lists in any order; timestamps must be
//! finite and distinct within a trajectory (an error otherwise, never a panic).

use sl_core::CameraToWorld;

use crate::error::{EvalError, Result};

mod align;
mod associate;
mod offset;
mod rpe;
mod stats;

pub use align::{AteResult, PoseError, ate};
pub use associate::associate;
pub use offset::{MAX_OFFSETS_TRIED, OffsetSearch, TimeOffset, estimate_time_offset};
pub use rpe::{DeltaUnit, RpeResult, rpe};
pub use stats::ErrorStats;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests;

/// One pose of a trajectory: timestamp (seconds) and camera-to-world pose.
pub type StampedPose = (f64, CameraToWorld);

/// How two trajectories are compared.
///
/// Defaults: TUM's maximum timestamp gap of 0.02 s for the ATE association, an RPE delta
/// of one frame and no clock offset.
///
/// `#[non_exhaustive]`: start from [`TrajectoryConfig::default`] and assign the fields you need.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TrajectoryConfig {
    /// Largest timestamp difference of an associated pair (ATE), seconds (`evaluate_ate.py
    /// --max_difference`).
    pub max_gap_s: f64,
    /// The RPE pair distance, in [`TrajectoryConfig::delta_unit`]s.
    pub delta: f64,
    /// Unit of [`TrajectoryConfig::delta`].
    pub delta_unit: DeltaUnit,
    /// Seconds added to the estimated trajectory's timestamps before it is associated with the
    /// ground truth (`evaluate_ate.py --offset`, evo's `--t_offset`): for a camera whose frame
    /// timestamps lag the ground truth's clock, a negative offset. At most
    /// [`MAX_OFFSET_S`] either way.
    pub offset_s: f64,
}

/// Largest clock offset [`TrajectoryConfig::offset_s`] accepts, seconds.
pub const MAX_OFFSET_S: f64 = 60.0;

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self {
            max_gap_s: 0.02,
            delta: 1.0,
            delta_unit: DeltaUnit::Frames,
            offset_s: 0.0,
        }
    }
}

impl TrajectoryConfig {
    /// Checks the configuration.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_gap_s.is_finite() && self.max_gap_s > 0.0) {
            return Err(EvalError::InvalidParameter(format!(
                "max_gap_s = {} must be positive and finite",
                sl_core::Compact(self.max_gap_s)
            )));
        }
        if !(self.delta.is_finite() && self.delta > 0.0) {
            return Err(EvalError::InvalidParameter(format!(
                "delta = {} must be positive and finite",
                sl_core::Compact(self.delta)
            )));
        }
        if !(self.offset_s.is_finite() && self.offset_s.abs() <= MAX_OFFSET_S) {
            return Err(EvalError::InvalidParameter(format!(
                "offset_s = {} must be finite and at most {MAX_OFFSET_S} s either way",
                sl_core::Compact(self.offset_s)
            )));
        }
        if self.delta_unit == DeltaUnit::Frames && self.delta.fract() != 0.0 {
            return Err(EvalError::InvalidParameter(format!(
                "delta = {} frames must be a whole number",
                sl_core::Compact(self.delta)
            )));
        }
        Ok(())
    }
}

/// Largest position coordinate a trajectory may have, metres (10⁹ m: a million kilometres; UTM
/// or ECEF coordinates of a robot are within it).
pub const MAX_POSITION_M: f64 = 1e9;

/// The estimated trajectory sorted by timestamp and moved onto the ground truth's clock by
/// `config.offset_s`, after checking it.
pub(crate) fn sorted_estimate(
    est: &[StampedPose],
    config: &TrajectoryConfig,
) -> Result<Vec<StampedPose>> {
    on_truth_clock(sorted(est, "estimated")?, config)
}

/// The estimate `v`, already sorted by [`sorted`], moved onto the ground truth's clock by
/// `config.offset_s`.
pub(crate) fn on_truth_clock(
    mut v: Vec<StampedPose>,
    config: &TrajectoryConfig,
) -> Result<Vec<StampedPose>> {
    if config.offset_s != 0.0 {
        for p in &mut v {
            p.0 += config.offset_s;
        }
        // Adding the same value keeps the order but may round two near stamps together.
        if let Some(w) = v.windows(2).find(|w| w[0].0 >= w[1].0) {
            return Err(EvalError::InvalidParameter(format!(
                "estimated trajectory: two timestamps become equal at {} s after the {} s clock \
                 offset",
                sl_core::Compact(w[0].0),
                sl_core::Compact(config.offset_s)
            )));
        }
    }
    Ok(v)
}

/// The trajectory sorted by timestamp, after checking the timestamps and poses.
pub(crate) fn sorted(traj: &[StampedPose], name: &str) -> Result<Vec<StampedPose>> {
    let mut v = traj.to_vec();
    for (t, p) in &v {
        let iso = p.isometry();
        if !t.is_finite() {
            return Err(EvalError::InvalidParameter(format!(
                "{name} trajectory: timestamp {t} is not finite"
            )));
        }
        if !(iso.translation.vector.iter().all(|c| c.is_finite())
            && iso.rotation.coords.iter().all(|c| c.is_finite()))
        {
            return Err(EvalError::InvalidParameter(format!(
                "{name} trajectory: the pose at {} s is not finite",
                sl_core::Compact(*t)
            )));
        }
        let far = iso.translation.vector.amax();
        if far > MAX_POSITION_M {
            return Err(EvalError::InvalidParameter(format!(
                "{name} trajectory: the position at {} s is {far:e} m from the origin, beyond \
                 {MAX_POSITION_M:e} m (the alignment's sums of squares would overflow long before \
                 any camera got there: metres expected)",
                sl_core::Compact(*t)
            )));
        }
    }
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let Some(w) = v.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(EvalError::InvalidParameter(format!(
            "{name} trajectory: timestamp {} s appears twice",
            w[0].0
        )));
    }
    Ok(v)
}
