//! The relative pose error over a fixed delta, as `evaluate_rpe.py --fixed_delta`: pairs of
//! estimated poses `delta` frames or seconds apart, each end matched to the nearest
//! ground-truth pose, and the difference of the two relative motions.

use sl_core::nalgebra::Isometry3;

use super::stats::ErrorStats;
use super::{StampedPose, TrajectoryConfig, sorted, sorted_estimate};
use crate::error::{EvalError, Result};

/// Unit of the RPE pair distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeltaUnit {
    /// Poses `delta` places apart in the estimated trajectory (TUM's `f`).
    #[default]
    Frames,
    /// Poses whose timestamps are nearest to `delta` seconds apart (TUM's `s`; `delta = 1`
    /// gives the drift per second).
    Seconds,
}

impl DeltaUnit {
    /// Parses `frames` / `f` and `seconds` / `s`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "frames" | "f" => Ok(Self::Frames),
            "seconds" | "s" => Ok(Self::Seconds),
            other => Err(EvalError::InvalidParameter(format!(
                "unknown delta unit '{other}' (expected frames or seconds)"
            ))),
        }
    }

    /// The name [`DeltaUnit::parse`] reads.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Frames => "frames",
            Self::Seconds => "seconds",
        }
    }
}

/// The relative pose error of an estimate over one delta.
#[derive(Debug, Clone, PartialEq)]
pub struct RpeResult {
    /// Translation errors, metres.
    pub translation_m: ErrorStats,
    /// Rotation errors, degrees.
    pub rotation_deg: ErrorStats,
    /// Pairs compared.
    pub pairs: usize,
    /// The delta, in `unit`s.
    pub delta: f64,
    /// Unit of `delta`.
    pub unit: DeltaUnit,
    /// Largest timestamp difference accepted between an estimated pose and its ground-truth
    /// pose: twice the median ground-truth interval (TUM's rule), seconds.
    pub max_gap_s: f64,
}

/// RPE of `est` against `gt` (see the module docs) with `evaluate_rpe.py`'s definitions:
///
/// * pairs `(i, j)` of estimated poses with `j` the pose whose index (frames) or timestamp
///   (seconds) is nearest to `i`'s plus `delta`, skipping `j` = the last pose (as TUM does)
///   and any `j` not strictly after `i` (a delta shorter than the poses' spacing pairs a pose
///   with itself, one so large that `i + delta` rounds pairs it with the first: neither is a
///   motion); all pairs are used (TUM samples 10 000 when there are more);
/// * each end is matched to the ground-truth pose of nearest timestamp, and the pair is
///   skipped when either is more than twice the median ground-truth interval away;
/// * with relative motions `Δ = P₁⁻¹·P₀`, the error is `E = Δ_est⁻¹·Δ_gt`: its translation
///   length and its rotation angle `acos((tr R − 1)/2)`.
///
/// Fails when fewer than two estimated poses overlap the ground truth or fewer than two pairs
/// remain (the message names `delta` and its unit, and says when the delta is shorter than
/// the poses' spacing).
pub fn rpe(
    est: &[StampedPose],
    gt: &[StampedPose],
    config: &TrajectoryConfig,
) -> Result<RpeResult> {
    config.validate()?;
    let est = sorted_estimate(est, config)?;
    let gt = sorted(gt, "ground-truth")?;
    if est.len() < 2 || gt.len() < 2 {
        return Err(EvalError::InvalidParameter(format!(
            "RPE needs at least two poses in each trajectory ({} estimated, {} ground truth)",
            est.len(),
            gt.len()
        )));
    }
    let stamps_est: Vec<f64> = est.iter().map(|p| p.0).collect();
    let stamps_gt: Vec<f64> = gt.iter().map(|p| p.0).collect();
    // Overlap check: estimated stamps reached back from their nearest ground-truth stamp.
    let mut back: Vec<usize> = stamps_est
        .iter()
        .map(|&t| closest_index(&stamps_est, stamps_gt[closest_index(&stamps_gt, t)]))
        .collect();
    back.sort_unstable();
    back.dedup();
    if back.len() < 2 {
        return Err(EvalError::InvalidParameter(
            "the trajectories' timestamps barely overlap: did you pass the right files?".into(),
        ));
    }
    let n = est.len();
    let index: Vec<f64> = match config.delta_unit {
        DeltaUnit::Frames => (0..n).map(|i| i as f64).collect(),
        DeltaUnit::Seconds => stamps_est.clone(),
    };
    let mut intervals: Vec<f64> = stamps_gt.windows(2).map(|w| w[1] - w[0]).collect();
    intervals.sort_by(f64::total_cmp);
    let m = intervals.len();
    let median = if m % 2 == 1 {
        intervals[m / 2]
    } else {
        0.5 * (intervals[m / 2 - 1] + intervals[m / 2])
    };
    let max_gap_s = 2.0 * median;
    let mut trans = Vec::new();
    let mut rot = Vec::new();
    // Poses whose nearest partner `delta` later is themselves.
    let mut with_itself = 0usize;
    for i in 0..n {
        let j = closest_index(&index, index[i] + config.delta);
        if j == i {
            with_itself += 1;
        }
        if j <= i || j == n - 1 {
            continue;
        }
        let g0 = closest_index(&stamps_gt, stamps_est[i]);
        let g1 = closest_index(&stamps_gt, stamps_est[j]);
        if (stamps_gt[g0] - stamps_est[i]).abs() > max_gap_s
            || (stamps_gt[g1] - stamps_est[j]).abs() > max_gap_s
        {
            continue;
        }
        let rel = |a: &Isometry3<f64>, b: &Isometry3<f64>| b.inverse() * a;
        let d_est = rel(est[i].1.isometry(), est[j].1.isometry());
        let d_gt = rel(gt[g0].1.isometry(), gt[g1].1.isometry());
        let e = d_est.inverse() * d_gt;
        trans.push(e.translation.vector.norm());
        let r = e.rotation.to_rotation_matrix();
        let c = ((r.matrix().trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        rot.push(c.acos());
    }
    if trans.len() < 2 {
        let unit = config.delta_unit.name();
        let delta = sl_core::Compact(config.delta);
        let why = if with_itself > n / 2 {
            format!(
                "delta = {delta} {unit} is shorter than the spacing of the estimated poses, \
                 which pairs most poses with themselves"
            )
        } else {
            format!("too short a trajectory for delta = {delta} {unit}?")
        };
        return Err(EvalError::InvalidParameter(format!(
            "only {} pose pairs {delta} {unit} apart have ground truth: {why}",
            trans.len(),
        )));
    }
    Ok(RpeResult {
        translation_m: ErrorStats::of(&trans),
        rotation_deg: ErrorStats::of(&rot).scaled(180.0 / std::f64::consts::PI),
        pairs: trans.len(),
        delta: config.delta,
        unit: config.delta_unit,
        max_gap_s,
    })
}

/// Index of the value of the sorted, non-empty list `l` closest to `t`, by TUM's bisection
/// (`find_closest_index`): the best difference seen along the search path, the first one on
/// ties.
pub(super) fn closest_index(l: &[f64], t: f64) -> usize {
    let (mut lo, mut hi) = (0usize, l.len());
    let mut best = 0;
    let mut diff = match l.first() {
        Some(v) => (v - t).abs(),
        None => return 0,
    };
    while lo < hi {
        let mid = (lo + hi) / 2;
        let d = (l[mid] - t).abs();
        if d < diff {
            diff = d;
            best = mid;
        }
        if l[mid] == t {
            return mid;
        } else if l[mid] > t {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    best
}
