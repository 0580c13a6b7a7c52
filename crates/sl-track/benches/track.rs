//! Tracking one 640×480 frame, a rolling-shutter frame's rectification, and the whole
//! per-frame step (track + integrate + raycast), on simulated Kinect frames of the `boxes` scene
//! (1° and 1 cm between frames); real frames need `sldepth track` on `../shared/data` (see the
//! validate report).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera, DepthImage, SensorModel};
use sl_noise::sim::{KinectSimulator, named_scene};
use sl_track::rolling_shutter::Rectifier;
use sl_track::{ModelReference, Tracker, TrackerConfig};
use sl_tsdf::{RaycastConfig, TsdfConfig, TsdfVolume};

fn frames(n: usize) -> (Camera, Vec<DepthImage>) {
    let scene = named_scene("boxes").unwrap();
    let k = scene.intrinsics;
    let sim = KinectSimulator::kinect_v1().white();
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.01, 0.0, 0.0),
        UnitQuaternion::from_scaled_axis(Vector3::y() * 1f64.to_radians()),
    ));
    let mut pose = scene.pose;
    let mut out = Vec::new();
    for i in 0..n {
        out.push(sim.apply(&scene.scene.render(&k, &pose).depth, i as u64));
        pose = pose * step;
    }
    (
        Camera {
            intrinsics: k,
            sensor: SensorModel::kinect_v1(),
        },
        out,
    )
}

fn bench(c: &mut Criterion) {
    let (cam, fr) = frames(2);
    let k = cam.intrinsics;
    let mut g = c.benchmark_group("track-640x480");
    g.sample_size(20);
    // Frame to frame: the reference is frame 0; each iteration tracks frame 1 from scratch.
    g.bench_function("track-frame-to-frame", |b| {
        b.iter(|| {
            let mut t = Tracker::new(cam, TrackerConfig::default()).unwrap();
            t.track(&fr[0], None).unwrap();
            black_box(t.track(black_box(&fr[1]), None).unwrap())
        })
    });
    // A rolling-shutter frame moved to the middle of its readout (`Reconstruction` does this
    // before fusing when `TrackerConfig::rolling_shutter_readout_s` > 0): 1° and 1 cm of motion
    // per frame interval, a 0.9-interval readout.
    let motion = Isometry3::from_parts(
        Translation3::new(0.01, 0.0, 0.0),
        UnitQuaternion::from_scaled_axis(Vector3::y() * 1f64.to_radians()),
    );
    let mut rectifier = Rectifier::default();
    let mut moved = DepthImage::invalid(k.width, k.height);
    g.bench_function("rectify-rolling-shutter", |b| {
        b.iter(|| rectifier.rectify(black_box(&fr[1]), &k, &motion, 0.9, &mut moved))
    });
    // The whole step against the model: track frame 1 against frame 0's raycast, integrate it
    // and raycast the model for the next frame (the set-up, frame 0, is inside the loop too),
    // the model rendered as `sldepth track` renders it (`ModelReference`, half resolution,
    // hinted by the frame just fused).
    let mut tcfg = TsdfConfig::default();
    tcfg.voxel_m = 0.008;
    tcfg.trunc_m = 0.04;
    // Once per instruction set this CPU has (`TrackerConfig::isa`, `TsdfConfig::isa`): the
    // same poses and volume on every one, so only the time differs.
    for isa in sl_core::Isa::ALL.into_iter().filter(|i| i.is_supported()) {
        let mut tcfg = tcfg;
        tcfg.isa = isa;
        let mut track_cfg = TrackerConfig::default();
        track_cfg.isa = isa;
        let name = format!("step-track-integrate-raycast-8mm-{isa}");
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut t = Tracker::new(cam, track_cfg).unwrap();
                let mut vol = TsdfVolume::new(tcfg).unwrap();
                let mut reference = ModelReference::new(
                    &k,
                    ModelReference::default_scale(&cam),
                    RaycastConfig::default(),
                )
                .unwrap();
                let r0 = t.track(&fr[0], None).unwrap();
                vol.integrate(&fr[0], &k, &r0.pose).unwrap();
                reference
                    .update_from_frame(&vol, &r0.pose, &cam.sensor, &fr[0], &k)
                    .unwrap();
                let r1 = t.track(&fr[1], reference.maps()).unwrap();
                vol.integrate(&fr[1], &k, &r1.pose).unwrap();
                reference
                    .update_from_frame(&vol, &r1.pose, &cam.sensor, &fr[1], &k)
                    .unwrap();
                black_box(r1)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
