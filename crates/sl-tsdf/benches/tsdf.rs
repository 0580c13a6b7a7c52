//! Criterion benchmarks of the two stages of `sl-tsdf`: integration (per frame) and marching
//! cubes, at 4 mm voxels and 2 cm truncation, on the five ICL-NUIM living-room frames and the
//! first 50 7-Scenes red-kitchen frames from `../shared/data` — or, when the data is absent, on
//! simulated 640×480 frames of an analytic room.
//!
//! Run: `cargo bench -p sl-tsdf --bench tsdf`. The Open3D comparison is
//! `docs/bench/open3d_tsdf.py` (same frames and parameters).
#![allow(clippy::expect_used)] // benchmark setup on fixed inputs

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::nalgebra::{Isometry3, Point3, Vector3};
use sl_core::{CameraToWorld, DepthImage, Intrinsics};
use sl_noise::sim::{Plane, Scene, Sphere};
use sl_tsdf::{MeshConfig, TsdfConfig, TsdfVolume};

struct Sequence {
    name: &'static str,
    k: Intrinsics,
    frames: Vec<(DepthImage, CameraToWorld)>,
}

/// A real sequence of `sl-testkit` (poses and camera of its dataset).
fn real(seq: Option<sl_testkit::PosedSequence>) -> Option<Sequence> {
    seq.map(|s| Sequence {
        name: s.name,
        k: s.camera.intrinsics,
        frames: s.frames,
    })
}

/// A 4×3×2.5 m room with a few spheres, seen by 10 cameras moving along a wall.
fn simulated() -> Sequence {
    let mut scene = Scene::new();
    for (n, d) in [
        (Vector3::x(), 2.0),
        (-Vector3::x(), 2.0),
        (Vector3::z(), 3.0),
        (Vector3::y(), 1.2),
        (-Vector3::y(), 1.3),
    ] {
        scene.add(Plane::from_normal_offset(n, d).expect("valid plane"));
    }
    scene.add(Sphere::new(Point3::new(0.3, 0.5, 1.8), 0.35).expect("valid sphere"));
    scene.add(Sphere::new(Point3::new(-0.8, 0.9, 2.2), 0.3).expect("valid sphere"));
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).expect("valid intrinsics");
    let frames = (0..10)
        .map(|i| {
            let pose = CameraToWorld::from_isometry(Isometry3::new(
                Vector3::new(-0.5 + 0.1 * i as f64, 0.0, -0.5),
                Vector3::new(0.0, 0.05 * i as f64 - 0.2, 0.0),
            ));
            (scene.render(&k, &pose).depth, pose)
        })
        .collect();
    Sequence {
        name: "simulated",
        k,
        frames,
    }
}

fn params() -> TsdfConfig {
    let mut config = TsdfConfig::default();
    config.voxel_m = 0.004;
    config.trunc_m = 0.02;
    config.max_depth_m = 4.0;
    config
}

fn fuse(seq: &Sequence) -> TsdfVolume {
    let mut vol = TsdfVolume::new(params()).expect("valid parameters");
    for (d, p) in &seq.frames {
        vol.integrate(d, &seq.k, p)
            .expect("integration within budget");
    }
    vol
}

fn bench(c: &mut Criterion) {
    // Whichever real sequences are present; simulated frames when there are none.
    let mut seqs: Vec<Sequence> = [
        real(sl_testkit::icl_sequence(usize::MAX)),
        real(sl_testkit::seven_scenes_sequence(50)),
    ]
    .into_iter()
    .flatten()
    .collect();
    if seqs.is_empty() {
        eprintln!("skipping real data: ../shared/data not found; benchmarking simulated frames");
        seqs.push(simulated());
    }
    for seq in &seqs {
        let n = seq.frames.len();
        let mut g = c.benchmark_group(format!("tsdf/{}", seq.name));
        g.sample_size(10);
        // The whole sequence into a fresh volume (allocation included): divide by the frame
        // count for the per-frame time.
        g.bench_function(format!("integrate_{n}_frames"), |b| {
            b.iter(|| black_box(fuse(seq)).block_count())
        });
        let vol = fuse(seq);
        g.bench_function("extract_mesh", |b| {
            b.iter(|| black_box(vol.extract_mesh(&MeshConfig::default())).triangle_count())
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
