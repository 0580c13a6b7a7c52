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

/// Exact depth of the nearest of `planes` (camera coordinates) at every pixel, with labels
/// (1-based plane index); pixels beyond `max_z` are left invalid.
pub fn render(k: &Intrinsics, planes: &[Plane], max_z: f64) -> (DepthImage, Image<u16>) {
    let mut depth = vec![0f32; k.width * k.height];
    let mut labels = vec![0u16; k.width * k.height];
    for y in 0..k.height {
        for x in 0..k.width {
            let mut best = f64::INFINITY;
            for (i, p) in planes.iter().enumerate() {
                if let Some(z) = p.depth_at(k, x as f64, y as f64)
                    && z < best
                    && z <= max_z
                {
                    best = z;
                    labels[y * k.width + x] = i as u16 + 1;
                }
            }
            if best.is_finite() {
                depth[y * k.width + x] = best as f32;
            }
        }
    }
    (
        DepthImage::from_vec(k.width, k.height, depth).unwrap(),
        Image::from_vec(k.width, k.height, labels).unwrap(),
    )
}

pub fn noisy(truth: &DepthImage, seed: u64) -> DepthImage {
    KinectSimulator::kinect_v1().white().apply(truth, seed)
}
