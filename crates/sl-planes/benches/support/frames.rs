//! The benchmark frames: real 640×480 frames from `../shared/data` (TUM fr1/rpy, 7-Scenes, NYU
//! raw disparity, Open3D's TUM sample), or simulated Kinect frames (`sl-noise`) when that
//! directory is absent. Shared by `benches/planes.rs` and `examples/planes_timing.rs`.
#![allow(dead_code)]

use sl_core::{Camera, DepthImage, DisparityImage};

/// One input frame.
pub enum Input {
    Depth(DepthImage),
    Disparity(DisparityImage),
}

/// `(name, input, camera)` of the benchmark frames: one per source, and two scenes of the
/// randomised room benchmark (issue 12: a room and a corridor, realistic noise).
pub fn frames() -> Vec<(String, Input, Camera)> {
    let mut out = load(1);
    out.extend(rooms());
    out
}

/// Two scenes of the room benchmark (`sl_noise::sim::room_scene`), realistic noise.
pub fn rooms() -> Vec<(String, Input, Camera)> {
    [0u64, 2]
        .into_iter()
        .map(|seed| {
            let rs = sl_noise::sim::room_scene(seed).unwrap();
            let mut sensor = sl_core::SensorModel::kinect_v1();
            sensor.focal_px = rs.intrinsics.fx;
            let sim = sl_noise::sim::KinectSimulator::with_sensor(sensor);
            let f = sim.simulate(&rs.scene, &rs.intrinsics, &rs.pose, seed);
            let c = Camera {
                intrinsics: rs.intrinsics,
                sensor,
            };
            (format!("room-{seed}"), Input::Depth(f.depth), c)
        })
        .collect()
}

/// Up to `per_source` frames of each real source (or the simulated frames), with names
/// `source/index`.
pub fn load(per_source: usize) -> Vec<(String, Input, Camera)> {
    let mut out = Vec::new();
    let depth = |f: sl_testkit::RealFrame| (f.name, Input::Depth(f.depth), f.camera);
    out.extend(sl_testkit::tum_rpy(per_source).into_iter().map(depth));
    out.extend(sl_testkit::seven_scenes(per_source).into_iter().map(depth));
    if let Ok(data) = sl_testkit::data_dir()
        && let Ok(raw) = sl_io::read_nyu_raw(data.join("open3d-testdata/nyu-raw-disparity.pgm"))
    {
        let disp = sl_io::depth::nyu_raw_to_disparity(&raw, sl_io::depth::NYU_DOFF);
        let c = Camera {
            intrinsics: sl_io::depth::nyu_intrinsics(),
            sensor: sl_io::depth::nyu_sensor_model(),
        };
        out.push(("nyu-raw".into(), Input::Disparity(disp), c));
    }
    out.extend(sl_testkit::open3d_tum().map(depth));
    if per_source > 1 {
        out.extend(sl_testkit::person().map(depth));
        out.extend(sl_testkit::floor_scan(per_source).into_iter().map(depth));
    }
    if per_source > 1 || out.is_empty() {
        let sim = sl_noise::sim::KinectSimulator::kinect_v1().white();
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
        let sim = sl_noise::sim::KinectSimulator::kinect_v1().white();
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
