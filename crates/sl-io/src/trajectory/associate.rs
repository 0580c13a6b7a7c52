//! Ground-truth poses for depth frames by time: the nearest pose within a tolerance, or the pose
//! interpolated between the two that bracket a frame's time.

use std::borrow::Cow;
use std::path::PathBuf;

use sl_core::CameraToWorld;

use super::{Frame, TimedPose, TumSequence};

/// The pose nearest in time to `t` within `max_dt_s` (`poses` sorted by timestamp).
pub fn nearest_pose(poses: &[TimedPose], t: f64, max_dt_s: f64) -> Option<&TimedPose> {
    let i = poses.partition_point(|p| p.timestamp < t);
    let before = i.checked_sub(1).and_then(|j| poses.get(j));
    let after = poses.get(i);
    let best = match (before, after) {
        (Some(a), Some(b)) => {
            if (t - a.timestamp).abs() <= (b.timestamp - t).abs() {
                a
            } else {
                b
            }
        }
        (Some(a), None) => a,
        (None, Some(b)) => b,
        (None, None) => return None,
    };
    ((best.timestamp - t).abs() <= max_dt_s).then_some(best)
}

/// `poses` sorted by timestamp (borrowed when they already are).
fn by_time(poses: &[TimedPose]) -> Cow<'_, [TimedPose]> {
    if poses.is_sorted_by(|a, b| a.timestamp <= b.timestamp) {
        Cow::Borrowed(poses)
    } else {
        let mut sorted = poses.to_vec();
        sorted.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
        Cow::Owned(sorted)
    }
}

/// The pose at time `t`, interpolated between the two poses of `poses` (sorted by timestamp)
/// that bracket it: the translation linearly, the rotation along the shortest arc (slerp). A
/// pose exactly at `t` is returned as it is. `None` when `t` lies outside the trajectory or
/// its two bracketing poses are more than `max_gap_s` apart (a gap in the motion capture is
/// not bridged). This is how a clock offset between a camera and its ground truth is undone
/// for a 100-Hz motion capture: the pose at `t + offset_s`, not the nearest one.
pub fn interpolated_pose(poses: &[TimedPose], t: f64, max_gap_s: f64) -> Option<CameraToWorld> {
    if !t.is_finite() {
        return None;
    }
    let i = poses.partition_point(|p| p.timestamp < t);
    let after = poses.get(i)?;
    if after.timestamp == t {
        return Some(after.pose);
    }
    let before = poses.get(i.checked_sub(1)?)?;
    let span = after.timestamp - before.timestamp;
    if !(span > 0.0 && span <= max_gap_s) {
        return None;
    }
    let s = (t - before.timestamp) / span;
    let iso = before.pose.isometry().lerp_slerp(after.pose.isometry(), s);
    Some(CameraToWorld::from_isometry(iso))
}

/// Gives each depth frame `(timestamp, path)` the ground-truth pose at `timestamp + offset_s`
/// ([`interpolated_pose`], bracketing poses at most `max_gap_s` apart); frames without one go
/// to `without_pose`. With `offset_s = 0` this differs from [`associate`] only by up to half
/// the motion capture's period (5 ms at 100 Hz).
pub fn associate_interpolated(
    depth: &[(f64, PathBuf)],
    poses: &[TimedPose],
    offset_s: f64,
    max_gap_s: f64,
) -> TumSequence {
    let poses = by_time(poses);
    let mut seq = TumSequence::default();
    for (t, p) in depth {
        match interpolated_pose(&poses, *t + offset_s, max_gap_s) {
            Some(pose) => seq.frames.push(Frame {
                depth_path: p.clone(),
                pose,
                timestamp: Some(*t),
            }),
            None => seq.without_pose.push((*t, p.clone())),
        }
    }
    seq
}

/// Gives each depth frame `(timestamp, path)` the nearest pose within `max_dt_s`.
pub fn associate(depth: &[(f64, PathBuf)], poses: &[TimedPose], max_dt_s: f64) -> TumSequence {
    let poses = by_time(poses);
    let mut seq = TumSequence::default();
    for (t, p) in depth {
        match nearest_pose(&poses, *t, max_dt_s) {
            Some(tp) => seq.frames.push(Frame {
                depth_path: p.clone(),
                pose: tp.pose,
                timestamp: Some(*t),
            }),
            None => seq.without_pose.push((*t, p.clone())),
        }
    }
    seq
}
