//! Tracking simulated Kinect sequences with known trajectories: recovered within the noise,
//! frame-to-model and frame-to-frame, the sensor-model weighting against uniform weights, and
//! frames that cannot be tracked reported lost (never given a wrong pose). One test binary,
//! its tests in modules by topic; the simulated sequences and helpers several of them use are
//! here.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera, CameraToWorld, DepthImage, Intrinsics, SensorModel};
use sl_noise::sim::{HandHeldPath, KinectSimulator, named_scene};
use sl_track::{
    ModelReference, Reconstruction, ReconstructionConfig, TrackStatus, Tracker, TrackerConfig,
    WeightMode,
};
use sl_tsdf::{RaycastConfig, TsdfConfig, TsdfVolume};

mod accuracy;
mod fixed_map;
mod fragments;
mod lost;
mod odometry;
mod reference;
mod rolling_shutter;
mod weak_directions;

/// A half-resolution Kinect (320×240) and the `boxes` scene (boxes, a sphere and a cylinder on
/// a floor before a wall, 1.3–3.6 m) seen along a trajectory that turns 1.5° and moves 1.5 cm
/// per frame (45 °/s and 0.45 m/s at 30 Hz).
fn sequence(n: usize, seed: u64) -> (Camera, Vec<CameraToWorld>, Vec<DepthImage>) {
    sequence_in("boxes", n, seed)
}

/// [`sequence`] in the named scene `name`.
fn sequence_in(name: &str, n: usize, seed: u64) -> (Camera, Vec<CameraToWorld>, Vec<DepthImage>) {
    let scene = named_scene(name).unwrap();
    let k = scene.intrinsics.scaled(0.5).unwrap();
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    let sim = KinectSimulator::kinect_v1().white();
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.015, 0.002, 0.004),
        UnitQuaternion::from_scaled_axis(
            Vector3::new(0.2, 1.0, 0.1).normalize() * 1.5f64.to_radians(),
        ),
    ));
    let mut poses = Vec::new();
    let mut frames = Vec::new();
    let mut pose = scene.pose;
    for i in 0..n {
        let truth = scene.scene.render(&k, &pose).depth;
        frames.push(sim.apply(&truth, seed + i as u64));
        poses.push(pose);
        pose = pose * step;
    }
    (cam, poses, frames)
}

/// The `wall` scene seen by a 320×240 Kinect (realistic noise) from a camera sliding 1 cm per
/// frame along it: the camera, the true poses and `n` frames.
fn wall_slide(n: u64) -> (Camera, Vec<CameraToWorld>, Vec<DepthImage>) {
    let scene = named_scene("wall").unwrap();
    let k = scene.intrinsics.scaled(0.5).unwrap();
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    let sim = KinectSimulator::kinect_v1();
    let slide = CameraToCamera::from_isometry(Isometry3::translation(0.01, 0.0, 0.0));
    let mut pose = scene.pose;
    let (mut truth, mut frames) = (Vec::new(), Vec::new());
    for i in 0..n {
        frames.push(sim.simulate(&scene.scene, &k, &pose, i).depth);
        truth.push(pose);
        pose = pose * slide;
    }
    (cam, truth, frames)
}

/// Camera preset `name`, the realistic simulator for it and the prefilter `sldepth track`
/// applies to its frames.
fn realistic_preset(name: &str) -> (Camera, KinectSimulator, sl_filter::MultiScale) {
    let cam = Camera::preset(name).unwrap();
    let sim = KinectSimulator::with_sensor(cam.sensor).with_noise(
        sl_noise::sim::NoiseModel::Realistic(sl_noise::sim::RealisticNoise::for_camera(name)),
    );
    (cam, sim, sl_filter::MultiScale::default_for(&cam.sensor))
}

/// Per-frame translation (m) and rotation (°) errors of the estimated poses against the truth,
/// both expressed relative to the first frame.
fn errors(truth: &[CameraToWorld], est: &[CameraToWorld]) -> Vec<(f64, f64)> {
    let t0 = truth[0].isometry().inverse();
    let e0 = est[0].isometry().inverse();
    truth
        .iter()
        .zip(est)
        .map(|(t, e)| {
            let rel_t = t0 * t.isometry();
            let rel_e = e0 * e.isometry();
            let d = rel_t.inverse() * rel_e;
            (d.translation.vector.norm(), d.rotation.angle().to_degrees())
        })
        .collect()
}

/// An empty volume of 1 cm voxels with a fixed 5 cm band: coarse enough for the small
/// simulated sequences to fuse and render quickly.
fn coarse_volume() -> TsdfVolume {
    let mut cfg = TsdfConfig::default();
    cfg.voxel_m = 0.01;
    cfg.trunc_m = 0.05;
    TsdfVolume::new(cfg).unwrap()
}

/// Tracks the frames; with `model` against the fused volume's raycast, else frame to frame.
fn track(
    cam: &Camera,
    frames: &[DepthImage],
    cfg: TrackerConfig,
    model: bool,
) -> (Vec<CameraToWorld>, Vec<TrackStatus>) {
    let k: Intrinsics = cam.intrinsics;
    let mut tracker = Tracker::new(*cam, cfg).unwrap();
    let mut volume = coarse_volume();
    let mut reference = ModelReference::new(
        &k,
        ModelReference::default_scale(cam),
        RaycastConfig::default(),
    )
    .unwrap();
    let (mut poses, mut status) = (Vec::new(), Vec::new());
    for d in frames {
        let r = tracker.track(d, reference.maps()).unwrap();
        if r.status.is_tracked() && model {
            volume.integrate(d, &k, &r.pose).unwrap();
            reference
                .update_from_frame(&volume, &r.pose, &cam.sensor, d, &k)
                .unwrap();
        }
        poses.push(r.pose);
        status.push(r.status);
    }
    (poses, status)
}

fn rms(v: &[(f64, f64)]) -> (f64, f64) {
    let n = v.len() as f64;
    (
        (v.iter().map(|e| e.0 * e.0).sum::<f64>() / n).sqrt(),
        (v.iter().map(|e| e.1 * e.1).sum::<f64>() / n).sqrt(),
    )
}

/// Runs a reconstruction over `frames` (timestamps one frame interval apart): per frame the
/// status, pose and fragment, the fragments handed over on the way, and those left at the end.
#[allow(clippy::type_complexity)]
fn reconstruct(
    cam: Camera,
    cfg: ReconstructionConfig,
    frames: &[&DepthImage],
) -> (
    Vec<(TrackStatus, CameraToWorld, usize)>,
    Vec<sl_track::Fragment>,
    Vec<sl_track::Fragment>,
) {
    let dt = cfg.tracker.frame_interval_s;
    let mut rec = Reconstruction::new(cam, cfg).unwrap();
    let (mut out, mut finished) = (Vec::new(), Vec::new());
    for (i, d) in frames.iter().enumerate() {
        let step = rec.step(d, Some(i as f64 * dt)).unwrap();
        finished.extend(step.finished);
        out.push((step.result.status, step.result.pose, step.fragment));
    }
    (out, finished, rec.finish().unwrap())
}

/// The camera step of `cameras_track` through the corridor: 1 cm and 1° per frame.
fn corridor_step() -> CameraToCamera {
    CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.01, 0.002, 0.004),
        UnitQuaternion::from_scaled_axis(
            Vector3::new(0.2, 1.0, 0.1).normalize() * 1f64.to_radians(),
        ),
    ))
}
