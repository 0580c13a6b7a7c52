//! Camera trajectories of RGB-D datasets, as depth [`Frame`]s with camera-to-world poses.
//!
//! - TUM RGB-D: `groundtruth.txt` (`timestamp tx ty tz qx qy qz qw`, `#` comments) and
//!   `associations.txt` (`rgb_ts rgb_path depth_ts depth_path`, or depth first as ICL-NUIM's
//!   TUM-format archives write it, told by the `depth` folder of its path); each depth frame gets the
//!   ground-truth pose nearest in time, within a maximum difference ([`DEFAULT_MAX_DT_S`]),
//!   or the pose interpolated at its time plus a clock offset ([`associate_interpolated`]).
//! - Open3D `.log`: a line `i j n`, then the four rows of a 4×4 camera-to-world matrix.
//!   [`read_trajectory`] reads either kind as timestamped poses (a `.log` by frame number).
//! - 7-Scenes: one `frame-XXXXXX.pose.txt` (4×4 camera-to-world, row-major) per frame next to
//!   `frame-XXXXXX.depth.png`.
//! - ScanNet's exports: `pose/<n>.txt` (the same 4×4 matrices; `-inf` for a frame without a
//!   pose) for `depth/<n>.png` ([`read_pose_folder_frames`]).
//!
//! All poses follow the `sl_core::pose` convention `X_w = R·X_c + t`; matrices are
//! re-orthonormalised by [`sl_core::pose_from_matrix`], which rejects non-rigid ones.

mod associate;
mod depth_files;
mod frame_list;
mod open3d_log;
mod parse;
mod pose_folder;
mod seven_scenes;
mod stamped;
#[cfg(test)]
mod tests;
mod tum;
mod tum_sequence;

use std::path::PathBuf;

use sl_core::CameraToWorld;

pub use associate::{associate, associate_interpolated, interpolated_pose, nearest_pose};
pub use depth_files::{
    NANOSECOND_DIGITS, list_depth_files, name_timestamp_s, name_timestamps_s, natural_order,
};
pub use frame_list::read_frame_list;
pub use open3d_log::{
    LogEntry, read_open3d_log, read_open3d_log_frames, read_open3d_log_frames_with_limits,
    read_open3d_log_with_limits, write_open3d_log,
};
pub(crate) use parse::check_frames;
pub use pose_folder::read_pose_folder_frames;
pub use seven_scenes::{read_7scenes_sequence, read_7scenes_sequence_with_limits, read_pose_txt};
pub use stamped::{is_open3d_log, read_trajectory, read_trajectory_with_limits};
pub(crate) use tum::association_depth_columns;
pub use tum::{
    Association, read_tum_associations, read_tum_associations_with_limits, read_tum_trajectory,
    read_tum_trajectory_with_limits, timestamp_printer, write_tum_trajectory,
};
pub use tum_sequence::{
    read_tum_sequence, read_tum_sequence_at_offset, read_tum_sequence_with_limits,
};

/// Default largest |depth timestamp − pose timestamp| for TUM association, seconds.
pub const DEFAULT_MAX_DT_S: f64 = 0.02;

/// Largest time, seconds, between a frame and the pose matched to it that a caller should
/// accept (an hour: any recording's poses are nearer than that to its frames, and a larger
/// number is a unit mistake, milliseconds or nanoseconds for seconds).
pub const MAX_GAP_S: f64 = 3600.0;

/// One depth frame with its camera-to-world pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The depth image file.
    pub depth_path: PathBuf,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
    /// Capture time in seconds, when the dataset has one (TUM).
    pub timestamp: Option<f64>,
}

impl Frame {
    /// The camera-to-world pose (the same as the field `pose`).
    #[deprecated(since = "0.1.0", note = "the field `pose` is a `CameraToWorld` now")]
    pub fn camera_to_world(&self) -> CameraToWorld {
        self.pose
    }
}

/// A pose with its timestamp (one line of a TUM trajectory).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedPose {
    /// Seconds.
    pub timestamp: f64,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
}

impl TimedPose {
    /// The camera-to-world pose (the same as the field `pose`).
    #[deprecated(since = "0.1.0", note = "the field `pose` is a `CameraToWorld` now")]
    pub fn camera_to_world(&self) -> CameraToWorld {
        self.pose
    }
}

/// Depth frames matched to poses, and those left without one.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TumSequence {
    /// Frames with a pose within the time tolerance, in association-file order.
    pub frames: Vec<Frame>,
    /// Depth frames (timestamp, path) with no pose within the tolerance.
    pub without_pose: Vec<(f64, PathBuf)>,
}
