//! Shared helpers of the sl-track integration tests: small cameras and synthetic planes.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use sl_core::{Camera, DepthImage, Image, Intrinsics, SensorModel};
use sl_noise::sim::KinectSimulator;
use sl_track::{Plane, PlaneConfig};

/// A 160x120 camera (focal length `f`) with the Kinect sensor model (f·B = 43.5 px·m).
pub fn small_camera(f: f64) -> Camera {
    Camera {
        intrinsics: Intrinsics::new(160, 120, f, f, 79.5, 59.5).unwrap(),
        sensor: SensorModel::kinect_v1(),
    }
}

pub fn cfg_small() -> PlaneConfig {
    let mut c = PlaneConfig::default();
    c.min_pixels = 200;
    c.min_piece_pixels = 64;
    c
}

/// Exact depth of the nearest of `planes` (see [`sl_testkit::render_planes`]).
pub fn render(k: &Intrinsics, planes: &[Plane], max_z: f64) -> (DepthImage, Image<u16>) {
    sl_testkit::render_planes(k, planes, max_z)
}

pub fn noisy(truth: &DepthImage, seed: u64) -> DepthImage {
    KinectSimulator::kinect_v1().white().apply(truth, seed)
}
