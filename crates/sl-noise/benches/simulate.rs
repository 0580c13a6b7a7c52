//! Benchmarks: simulate a 640×480 Kinect frame; analyse a frame.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use sl_noise::analysis::analyze;
use sl_noise::sim::{KinectSimulator, named_scene};

fn bench(c: &mut Criterion) {
    let realistic = KinectSimulator::kinect_v1();
    let sim = KinectSimulator::kinect_v1().white();
    for name in ["floor", "figure-walls", "boxes"] {
        let ns = named_scene(name).unwrap();
        c.bench_function(&format!("simulate realistic {name} 640x480"), |b| {
            b.iter(|| realistic.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 42))
        });
    }
    for name in ["floor", "boxes", "relief"] {
        let ns = named_scene(name).unwrap();
        c.bench_function(&format!("render {name} 640x480"), |b| {
            b.iter(|| ns.scene.render(&ns.intrinsics, &ns.pose))
        });
        c.bench_function(&format!("simulate {name} 640x480"), |b| {
            b.iter(|| sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 42))
        });
    }
    let ns = named_scene("floor").unwrap();
    let frame = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 42);
    c.bench_function("apply sensor 640x480", |b| {
        b.iter(|| sim.apply(&frame.truth, 42))
    });
    c.bench_function("apply realistic sensor 640x480", |b| {
        b.iter(|| realistic.apply(&frame.truth, 42))
    });
    c.bench_function("analyze floor 640x480", |b| {
        b.iter(|| analyze(&frame.depth, &sim.sensor).unwrap())
    });
    c.bench_function("algorithm1", |b| b.iter(sl_noise::algorithm1::algorithm1));
}

criterion_group!(benches, bench);
criterion_main!(benches);
