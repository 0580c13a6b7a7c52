//! The benchmark frames: real 640×480 frames from `../shared/data` (TUM fr1/rpy, 7-Scenes, NYU
//! raw disparity, Open3D's TUM sample), or simulated Kinect frames (`sl-noise`) when that
//! directory is absent. Shared by `benches/planes.rs` and `examples/planes_timing.rs`.
#![allow(dead_code)]

use std::path::PathBuf;

use sl_core::{Camera, DepthImage, DisparityImage, Intrinsics};

/// One input frame.
pub enum Input {
    Depth(DepthImage),
    Disparity(DisparityImage),
}

fn cam(f: f64, fy: f64, cx: f64, cy: f64) -> Camera {
    Camera::from_intrinsics(
        Intrinsics::new(640, 480, f, fy, cx, cy).unwrap(),
        None,
        None,
    )
    .unwrap()
}

fn read(p: PathBuf, s: f64) -> Option<DepthImage> {
    sl_io::read_depth(p, &sl_io::ReadOptions::default().with_scale(s))
        .ok()
        .map(|l| l.depth)
}

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
}

/// `(name, input, camera)` of the benchmark frames: one per source.
pub fn frames() -> Vec<(String, Input, Camera)> {
    load(1)
}

/// Up to `per_source` frames of each real source (or the simulated frames), with names
/// `source/index`.
pub fn load(per_source: usize) -> Vec<(String, Input, Camera)> {
    let data = data_dir();
    let mut out = Vec::new();
    let suffix = |name: &str, i: usize| {
        if per_source == 1 {
            name.to_string()
        } else {
            format!("{name}/{i:02}")
        }
    };
    if data.exists() {
        if let Ok(mut files) = sl_io::trajectory::list_depth_files(data.join("tum-fr1-rpy/depth")) {
            files.sort();
            for (i, f) in files.iter().take(per_source).enumerate() {
                if let Some(d) = read(f.clone(), 5000.0) {
                    out.push((
                        suffix("tum-fr1-rpy", i),
                        Input::Depth(d),
                        cam(517.3, 516.5, 318.6, 255.3),
                    ));
                }
            }
        }
        for i in 0..per_source.min(50) {
            let p = data.join(format!("7scenes-redkitchen/frame-{:06}.depth.png", 150 + i));
            if let Some(d) = read(p, 1000.0) {
                out.push((
                    suffix("7scenes", i),
                    Input::Depth(d),
                    cam(585.0, 585.0, 320.0, 240.0),
                ));
            }
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
        if per_source > 1 {
            if let Some(d) = read(data.join("open3d-testdata/person-depth.png"), 1000.0) {
                out.push((
                    "person".into(),
                    Input::Depth(d),
                    cam(525.0, 525.0, 319.5, 239.5),
                ));
            }
            if let Ok(mut files) = std::fs::read_dir(data.join("pcl-floor-box")).map(|r| {
                r.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.to_string_lossy().ends_with("_depth.tiff"))
                    .collect::<Vec<_>>()
            }) {
                files.sort();
                for (i, f) in files.iter().enumerate() {
                    if let Some(d) = read(f.clone(), 1000.0) {
                        out.push((
                            format!("pcl-floor-box/{i:02}"),
                            Input::Depth(d),
                            cam(525.0, 525.0, 320.0, 240.0),
                        ));
                    }
                }
            }
        }
    }
    if per_source > 1 || out.is_empty() {
        let sim = sl_noise::sim::KinectSimulator::kinect_v1();
        for name in sl_noise::sim::SCENE_NAMES.iter().filter(|_| per_source > 1) {
            let ns = sl_noise::sim::named_scene(name).unwrap();
            let f = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 7);
            let c = Camera {
                intrinsics: ns.intrinsics,
                sensor: sim.sensor,
            };
            out.push((format!("sim/{name}"), Input::Depth(f.depth), c));
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
