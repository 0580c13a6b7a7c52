//! Criterion benchmark of [`TsdfVolume::raycast_into`]: one 640×480 rendering of the volume
//! fused from the five ICL-NUIM living-room frames of `../shared/data` (the default
//! `TsdfConfig`, 4 mm voxels), seen from the last frame's pose — or, when the data is absent,
//! of a simulated room fused from ten frames — plain and hinted by the last frame's depth
//! ([`TsdfVolume::raycast_hinted_into`], as the tracker renders its model).
//!
//! Run: `cargo bench -p sl-tsdf --bench raycast`.
#![allow(clippy::expect_used)] // benchmark setup on fixed inputs

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::nalgebra::{Isometry3, Point3, Vector3};
use sl_core::{CameraToWorld, DepthImage, Intrinsics};
use sl_noise::sim::{Plane, Scene, Sphere};
use sl_tsdf::{Raycast, RaycastConfig, TsdfConfig, TsdfVolume};

/// A 3×2.2×2.5 m room with two spheres, seen by ten cameras moving along a wall.
fn simulated() -> (&'static str, Intrinsics, Vec<(DepthImage, CameraToWorld)>) {
    let mut scene = Scene::new();
    for (n, d) in [
        (Vector3::x(), 1.5),
        (-Vector3::x(), 1.5),
        (Vector3::z(), 2.5),
        (Vector3::y(), 1.0),
        (-Vector3::y(), 1.2),
    ] {
        scene.add(Plane::from_normal_offset(n, d).expect("valid plane"));
    }
    scene.add(Sphere::new(Point3::new(0.3, 0.5, 1.8), 0.35).expect("valid sphere"));
    scene.add(Sphere::new(Point3::new(-0.6, 0.4, 2.0), 0.3).expect("valid sphere"));
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).expect("valid intrinsics");
    let frames = (0..10)
        .map(|i| {
            let pose = CameraToWorld::from_isometry(Isometry3::new(
                Vector3::new(-0.4 + 0.08 * i as f64, 0.0, -0.3),
                Vector3::new(0.0, 0.05 * i as f64 - 0.2, 0.0),
            ));
            (scene.render(&k, &pose).depth, pose)
        })
        .collect();
    ("simulated", k, frames)
}

fn bench(c: &mut Criterion) {
    let (name, k, frames) = match sl_testkit::icl_sequence(usize::MAX) {
        Some(s) => (s.name, s.camera.intrinsics, s.frames),
        None => {
            eprintln!(
                "skipping real data: ../shared/data not found; benchmarking a simulated room"
            );
            simulated()
        }
    };
    let mut vol = TsdfVolume::new(TsdfConfig::default()).expect("valid parameters");
    for (d, p) in &frames {
        vol.integrate(d, &k, p).expect("integration within budget");
    }
    let (last_depth, pose) = frames.last().expect("frames");
    let pose = *pose;
    let config = RaycastConfig::default();
    let mut out = Raycast::default();
    vol.raycast_into(&pose, &k, &config, &mut out)
        .expect("raycast");
    eprintln!(
        "{name}: {} blocks, raycast {}x{} with {} hits",
        vol.block_count(),
        k.width,
        k.height,
        out.hit_count()
    );
    let mut g = c.benchmark_group(format!("raycast/{name}"));
    g.sample_size(20);
    g.bench_function(format!("{}x{}", k.width, k.height), |b| {
        b.iter(|| {
            vol.raycast_into(&pose, &k, &config, &mut out)
                .expect("raycast");
            black_box(out.weights[0])
        })
    });
    g.bench_function(format!("{}x{}-hinted", k.width, k.height), |b| {
        b.iter(|| {
            vol.raycast_hinted_into(&pose, &k, &config, Some(last_depth), &mut out)
                .expect("raycast");
            black_box(out.weights[0])
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
