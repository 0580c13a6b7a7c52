//! Plane extraction on 640×480 frames, one thread (target ≤ 3.3 ms per frame).
//!
//! Real frames from `../shared/data` (TUM fr1/rpy, 7-Scenes, NYU raw disparity, Open3D's TUM
//! sample); when that directory is absent, simulated Kinect frames (`sl-noise`) instead. The
//! global rayon pool is limited to one thread, and the extractor itself is sequential.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::{Camera, DepthImage, DisparityImage, Intrinsics};
use sl_planes::{PlaneConfig, PlaneExtractor};

enum Input {
    Depth(DepthImage),
    Disparity(DisparityImage),
}

fn frames() -> Vec<(String, Input, Camera)> {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let mut out = Vec::new();
    let cam = |f: f64, fy: f64, cx: f64, cy: f64| {
        Camera::from_intrinsics(
            Intrinsics::new(640, 480, f, fy, cx, cy).unwrap(),
            None,
            None,
        )
        .unwrap()
    };
    let read = |p: PathBuf, s: f64| {
        sl_io::read_depth(p, &sl_io::ReadOptions::default().with_scale(s))
            .ok()
            .map(|l| l.depth)
    };
    if data.exists() {
        if let Ok(mut files) = sl_io::trajectory::list_depth_files(data.join("tum-fr1-rpy/depth")) {
            files.sort();
            if let Some(d) = files.first().and_then(|f| read(f.clone(), 5000.0)) {
                out.push((
                    "tum-fr1-rpy".into(),
                    Input::Depth(d),
                    cam(517.3, 516.5, 318.6, 255.3),
                ));
            }
        }
        if let Some(d) = read(
            data.join("7scenes-redkitchen/frame-000150.depth.png"),
            1000.0,
        ) {
            out.push((
                "7scenes".into(),
                Input::Depth(d),
                cam(585.0, 585.0, 320.0, 240.0),
            ));
        }
        if let Ok(raw) = sl_io::read_nyu_raw(data.join("open3d-testdata/nyu-raw-disparity.pgm")) {
            let disp = sl_io::depth::nyu_raw_to_disparity(&raw, sl_io::depth::NYU_DOFF);
            let c = Camera {
                intrinsics: sl_io::depth::nyu_intrinsics(),
                sensor: sl_io::depth::nyu_sensor_model(),
            };
            out.push(("nyu-raw".into(), Input::Disparity(disp), c));
        }
        if let Some(d) = read(data.join("open3d-testdata/tum-depth.png"), 5000.0) {
            out.push((
                "open3d-tum".into(),
                Input::Depth(d),
                cam(525.0, 525.0, 319.5, 239.5),
            ));
        }
    }
    if out.is_empty() {
        eprintln!("../shared/data not found: benchmarking simulated frames");
        let sim = sl_noise::sim::KinectSimulator::kinect_v1();
        for name in ["three-planes", "corridor", "boxes"] {
            let ns = sl_noise::sim::named_scene(name).unwrap();
            let f = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 1);
            let c = Camera {
                intrinsics: ns.intrinsics,
                sensor: sim.sensor,
            };
            out.push((format!("sim-{name}"), Input::Depth(f.depth), c));
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    // One worker thread for anything that would use rayon (the extractor is sequential).
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let mut g = c.benchmark_group("planes-1-thread");
    g.sample_size(40);
    for (name, input, cam) in frames() {
        let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
        g.bench_function(&name, |b| {
            b.iter(|| match &input {
                Input::Depth(d) => black_box(ex.extract_depth(black_box(d), &cam).unwrap()),
                Input::Disparity(d) => black_box(ex.extract_disparity(black_box(d), &cam).unwrap()),
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
