//! Integration tests of `sl-planes`: synthetic planes through the Kinect noise model. One test
//! binary, its tests in modules by topic; the cameras, simulated rooms and helpers several of
//! them use are here.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_core::nalgebra::Vector3;
use sl_core::{Camera, DepthImage, Image, Intrinsics, SensorModel};
use sl_eval::planes::segcomp;
use sl_noise::sim::KinectSimulator;
use sl_planes::{Plane, PlaneConfig, PlaneExtractor};

mod borders;
mod measured_noise;
mod merging;
mod sparse_frames;
mod synthetic;
mod threads;
mod uncertainty;

/// A 160x120 camera (focal length `f`) with the Kinect sensor model (f·B = 43.5 px·m).
fn small_camera(f: f64) -> Camera {
    Camera {
        intrinsics: Intrinsics::new(160, 120, f, f, 79.5, 59.5).unwrap(),
        sensor: SensorModel::kinect_v1(),
    }
}

fn cfg_small() -> PlaneConfig {
    let mut c = PlaneConfig::default();
    c.min_pixels = 200;
    c.min_piece_pixels = 64;
    c
}

/// Exact depth of the nearest of `planes` (see [`sl_testkit::render_planes`]).
fn render(k: &Intrinsics, planes: &[Plane], max_z: f64) -> (DepthImage, Image<u16>) {
    sl_testkit::render_planes(k, planes, max_z)
}

fn noisy(truth: &DepthImage, seed: u64) -> DepthImage {
    KinectSimulator::kinect_v1().white().apply(truth, seed)
}

/// Seeded random room `seed` of the simulator through its own camera (the Kinect sensor model
/// at the room's focal length), with the realistic noise: the depth and the camera.
fn simulated_room(seed: u64) -> (DepthImage, Camera) {
    let room = sl_noise::sim::room_scene(seed).unwrap();
    let k = room.intrinsics;
    let cam = room_camera(k);
    let truth = room.scene.render(&k, &room.pose).depth;
    (
        KinectSimulator::with_sensor(cam.sensor).apply(&truth, seed),
        cam,
    )
}

/// A simulated room's camera: its intrinsics with the Kinect sensor model at its focal length.
fn room_camera(k: Intrinsics) -> Camera {
    Camera {
        intrinsics: k,
        sensor: SensorModel {
            focal_px: k.fx,
            ..SensorModel::kinect_v1()
        },
    }
}

/// Room `seed` of the room benchmark through its own camera, and its planes (defaults).
fn extract_room(seed: u64) -> (sl_noise::sim::SimulatedFrame, sl_planes::PlaneSegmentation) {
    extract_room_with(seed, None, 0.0, &PlaneConfig::default())
}

/// Room `seed` through `camera` (its own when `None`) with a low-frequency disparity
/// distortion of `distortion_px` at the image corner (`RealisticNoise::distortion_px`),
/// extracted with `cfg`.
fn extract_room_with(
    seed: u64,
    camera: Option<Camera>,
    distortion_px: f64,
    cfg: &PlaneConfig,
) -> (sl_noise::sim::SimulatedFrame, sl_planes::PlaneSegmentation) {
    let room = sl_noise::sim::room_scene(seed).unwrap();
    let cam = camera.unwrap_or_else(|| room_camera(room.intrinsics));
    let mut noise = sl_noise::sim::RealisticNoise::default();
    noise.distortion_px = distortion_px;
    let frame = KinectSimulator::with_sensor(cam.sensor)
        .with_noise(sl_noise::sim::NoiseModel::Realistic(noise))
        .simulate(&room.scene, &cam.intrinsics, &room.pose, seed);
    let seg = PlaneExtractor::new(*cfg)
        .unwrap()
        .extract_depth(&frame.depth, &cam)
        .unwrap();
    (frame, seg)
}

/// Per plane, the surface (ground-truth label) most of its pixels lie on, and whether at least
/// 90 % of them do.
fn majority_surfaces(
    frame: &sl_noise::sim::SimulatedFrame,
    seg: &sl_planes::PlaneSegmentation,
) -> Vec<(u16, bool)> {
    seg.planes
        .iter()
        .map(|p| {
            let mut counts = std::collections::HashMap::<u16, usize>::new();
            for (&l, &t) in seg.labels.data().iter().zip(frame.labels.data()) {
                if l == p.id {
                    *counts.entry(t).or_default() += 1;
                }
            }
            let (t, n) = counts.into_iter().max_by_key(|&(_, n)| n).unwrap();
            (t, n * 10 >= p.pixels * 9)
        })
        .collect()
}

/// Whether two planes lie mostly on the same surface.
fn two_planes_on_one_surface(majority: &[(u16, bool)]) -> bool {
    let mut unique: Vec<u16> = majority.iter().map(|m| m.0).collect();
    unique.sort_unstable();
    unique.dedup();
    unique.len() != majority.len()
}
