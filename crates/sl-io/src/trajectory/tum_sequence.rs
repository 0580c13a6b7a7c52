//! A TUM RGB-D sequence folder read as depth frames with poses: its ground truth and depth frames,
//! matched by nearest time or interpolated at a clock offset.

use std::path::{Path, PathBuf};

#[cfg(doc)] // for the doc links
use super::DEFAULT_MAX_DT_S;
use super::tum::read_tum_trajectory_with_limits;
use super::{TimedPose, TumSequence, associate, associate_interpolated};
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// Reads a TUM sequence directory: `dir/groundtruth.txt` (or the one `*.gt.freiburg` of an
/// ICL-NUIM folder, [`tum_ground_truth_of`](crate::sequence::tum_ground_truth_of)) and the
/// depth frames as TUM ships them (`associations.txt` when present, else `depth.txt`; see
/// [`read_tum_depth_frames`](crate::sequence::read_tum_depth_frames)), matching each depth
/// frame to the nearest ground-truth pose within `max_dt_s` seconds ([`DEFAULT_MAX_DT_S`] =
/// 0.02 s is the usual choice). A non-positive or non-finite tolerance is an error naming
/// `groundtruth.txt`. The poses of one of ICL-NUIM's TUM-format folders (rendered with y up,
/// [`icl_nuim_tum_folder`](crate::sequence::icl_nuim_tum_folder)) come in sldepth's frame
/// ([`sl_core::CameraToWorld::y_reflected`]).
pub fn read_tum_sequence(dir: impl AsRef<Path>, max_dt_s: f64) -> Result<TumSequence> {
    read_tum_sequence_with_limits(dir, max_dt_s, &Limits::default())
}

/// [`read_tum_sequence`] within `limits`.
pub fn read_tum_sequence_with_limits(
    dir: impl AsRef<Path>,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<TumSequence> {
    let (depth, poses) = read_tum_parts(dir.as_ref(), max_dt_s, limits)?;
    Ok(associate(&depth, &poses, max_dt_s))
}

/// [`read_tum_sequence_with_limits`] with each depth frame given the ground-truth pose at its
/// stamp plus `offset_s` ([`associate_interpolated`]; bracketing poses at most `max_gap_s`
/// apart) instead of the nearest one. A non-finite offset or a non-positive gap is an error
/// naming `groundtruth.txt`.
pub fn read_tum_sequence_at_offset(
    dir: impl AsRef<Path>,
    offset_s: f64,
    max_gap_s: f64,
    limits: &Limits,
) -> Result<TumSequence> {
    let dir = dir.as_ref();
    if !offset_s.is_finite() {
        return Err(IoError::Format {
            path: dir.join("groundtruth.txt"),
            message: format!(
                "clock offset {} s must be finite",
                sl_core::Compact(offset_s)
            ),
        });
    }
    let (depth, poses) = read_tum_parts(dir, max_gap_s, limits)?;
    Ok(associate_interpolated(&depth, &poses, offset_s, max_gap_s))
}

/// Depth frames `(timestamp, path)`, as [`associate()`] takes them.
type TimedDepth = Vec<(f64, PathBuf)>;

/// The timestamped depth frames and the ground-truth poses of a TUM folder, after checking the
/// association's time tolerance.
fn read_tum_parts(
    dir: &Path,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<(TimedDepth, Vec<TimedPose>)> {
    let gt_path = crate::sequence::tum_ground_truth_of(dir);
    if !(max_dt_s.is_finite() && max_dt_s > 0.0) {
        return Err(IoError::Format {
            path: gt_path,
            message: format!(
                "maximum time difference {} s must be positive",
                sl_core::Compact(max_dt_s)
            ),
        });
    }
    let mut poses = read_tum_trajectory_with_limits(&gt_path, limits)?;
    // ICL-NUIM renders with y up: its poses into sldepth's frame.
    if crate::sequence::icl_nuim_tum_folder(dir) {
        for p in &mut poses {
            p.pose = p.pose.y_reflected();
        }
    }
    let depth: TimedDepth = crate::sequence::read_tum_depth_frames(dir, limits)?
        .into_iter()
        .filter_map(|f| Some((f.timestamp?, f.depth_path)))
        .collect();
    Ok((depth, poses))
}
