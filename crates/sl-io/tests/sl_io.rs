//! Integration tests of `sl-io`: file round trips, reference checks on the real frames under
//! `../shared/data` (skipped with a message when absent), and fuzz-style robustness tests.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

#[path = "sl_io/float_tiff.rs"]
mod float_tiff;
#[path = "sl_io/fuzz.rs"]
mod fuzz;
#[path = "sl_io/real_data.rs"]
mod real_data;
#[path = "sl_io/ros_camera.rs"]
mod ros_camera;
#[path = "sl_io/rosbag.rs"]
mod rosbag;
#[path = "sl_io/rosbag_db3.rs"]
mod rosbag_db3;
#[path = "sl_io/rosbag_stereo.rs"]
mod rosbag_stereo;
#[path = "sl_io/rosbag_tf.rs"]
mod rosbag_tf;
#[path = "sl_io/round_trip.rs"]
mod round_trip;

/// The shared data directory, or `None` (after printing why) when absent.
pub fn data_dir() -> Option<PathBuf> {
    sl_testkit::data_dir_or_skip("sl-io real-data tests")
}
