//! Criterion benchmarks of the two stages of `sl-tsdf`: integration (per frame) and marching
//! cubes, at 4 mm voxels and 2 cm truncation, on the five ICL-NUIM living-room frames and the
//! first 50 7-Scenes red-kitchen frames from `../shared/data` — or, when the data is absent, on
//! simulated 640×480 frames of an analytic room.
//!
//! Run: `cargo bench -p sl-tsdf --bench tsdf`. The Open3D comparison is
//! `docs/bench/open3d_tsdf.py` (same frames and parameters).
#![allow(clippy::expect_used)] // benchmark setup on fixed inputs

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::nalgebra::{Matrix4, Point3, Vector3};
use sl_core::{DepthImage, Intrinsics, Pose, pose_from_matrix};
use sl_io::{ReadOptions, read_depth};
use sl_tsdf::synth::AnalyticScene;
use sl_tsdf::{ExtractOptions, TsdfParams, TsdfVolume};

struct Sequence {
    name: &'static str,
    k: Intrinsics,
    frames: Vec<(DepthImage, Pose)>,
}

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
}

fn matrix(nums: &[f64]) -> Option<Pose> {
    (nums.len() == 16)
        .then(|| pose_from_matrix(&Matrix4::from_row_slice(nums)).ok())
        .flatten()
}

fn icl() -> Option<Sequence> {
    let dir = data_dir().join("open3d-testdata/icl-livingroom");
    let log = std::fs::read_to_string(dir.join("odometry.log")).ok()?;
    let lines: Vec<&str> = log.lines().filter(|l| !l.trim().is_empty()).collect();
    let mut frames = Vec::new();
    for (i, chunk) in lines.chunks(5).enumerate() {
        let nums: Vec<f64> = chunk[1..]
            .iter()
            .flat_map(|l| l.split_whitespace())
            .filter_map(|t| t.parse().ok())
            .collect();
        let pose = matrix(&nums)?;
        let depth = read_depth(
            dir.join(format!("depth/{i:05}.png")),
            &ReadOptions::default(),
        )
        .ok()?
        .depth;
        frames.push((depth, pose));
    }
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).ok()?;
    Some(Sequence {
        name: "icl",
        k,
        frames,
    })
}

fn seven_scenes() -> Option<Sequence> {
    let dir = data_dir().join("7scenes-redkitchen");
    let mut frames = Vec::new();
    for i in 150..200 {
        let txt = std::fs::read_to_string(dir.join(format!("frame-{i:06}.pose.txt"))).ok()?;
        let nums: Vec<f64> = txt
            .split_whitespace()
            .filter_map(|t| t.parse().ok())
            .collect();
        let pose = matrix(&nums)?;
        let depth = read_depth(
            dir.join(format!("frame-{i:06}.depth.png")),
            &ReadOptions::default(),
        )
        .ok()?
        .depth;
        frames.push((depth, pose));
    }
    let k = Intrinsics::new(640, 480, 585.0, 585.0, 320.0, 240.0).ok()?;
    Some(Sequence {
        name: "7scenes",
        k,
        frames,
    })
}

/// A 4×3×2.5 m room with a few spheres, seen by 10 cameras moving along a wall.
fn simulated() -> Sequence {
    let mut scene = AnalyticScene::default();
    for (n, d) in [
        (Vector3::x(), 2.0),
        (-Vector3::x(), 2.0),
        (Vector3::z(), 3.0),
        (Vector3::y(), 1.2),
        (-Vector3::y(), 1.3),
    ] {
        scene.planes.push((n, d));
    }
    scene.spheres.push((Point3::new(0.3, 0.5, 1.8), 0.35));
    scene.spheres.push((Point3::new(-0.8, 0.9, 2.2), 0.3));
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).expect("valid intrinsics");
    let frames = (0..10)
        .map(|i| {
            let pose = Pose::new(
                Vector3::new(-0.5 + 0.1 * i as f64, 0.0, -0.5),
                Vector3::new(0.0, 0.05 * i as f64 - 0.2, 0.0),
            );
            (scene.render(&k, &pose), pose)
        })
        .collect();
    Sequence {
        name: "simulated",
        k,
        frames,
    }
}

fn params() -> TsdfParams {
    TsdfParams {
        voxel_m: 0.004,
        trunc_m: 0.02,
        max_depth_m: 4.0,
        ..TsdfParams::default()
    }
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
    let mut seqs: Vec<Sequence> = [icl(), seven_scenes()].into_iter().flatten().collect();
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
            b.iter(|| black_box(vol.extract_mesh(&ExtractOptions::default())).triangle_count())
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
