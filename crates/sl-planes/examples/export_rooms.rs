//! Writes the frames of the randomised room benchmark (issue 12) for peer libraries:
//! `cargo run --release -p sl-planes --example export_rooms -- DIR [FIRST COUNT]` writes, per
//! scene `NN` (seeds `FIRST..FIRST + COUNT`, default the benchmark's `0..60`),
//! `NN-depth.png` (16-bit, millimetres, 0 = invalid), `NN-labels.png` (16-bit ground-truth
//! surface labels) and a line `NN fx fy cx cy` of `DIR/cameras.txt`; `docs/bench/planes_peers.py
//! --rooms DIR` scores peers on them with the same SegComp rules as `cargo xtask validate`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::fmt::Write as _;
use std::path::PathBuf;

use sl_core::Image;
use sl_noise::sim::{KinectSimulator, ROOM_BENCHMARK_SEEDS, room_scene};

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).expect("usage: export_rooms DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let mut cams = String::new();
    let arg = |i: usize, default: u64| {
        std::env::args()
            .nth(i)
            .map_or(default, |a| a.parse().expect("seed numbers"))
    };
    let (first, count) = (arg(2, 0), arg(3, ROOM_BENCHMARK_SEEDS));
    for seed in first..first + count {
        let rs = room_scene(seed).unwrap();
        let mut sensor = sl_core::SensorModel::kinect_v1();
        sensor.focal_px = rs.intrinsics.fx;
        let f = KinectSimulator::with_sensor(sensor).simulate(
            &rs.scene,
            &rs.intrinsics,
            &rs.pose,
            seed,
        );
        let (w, h) = (f.depth.width(), f.depth.height());
        let mm: Vec<u16> = f
            .depth
            .data()
            .iter()
            .map(|&z| (z * 1000.0).round().clamp(0.0, 65535.0) as u16)
            .collect();
        sl_io::write_gray16_png(
            dir.join(format!("{seed:02}-depth.png")),
            &Image::from_vec(w, h, mm).unwrap(),
        )
        .unwrap();
        sl_io::write_gray16_png(dir.join(format!("{seed:02}-labels.png")), &f.labels).unwrap();
        let k = rs.intrinsics;
        let _ = writeln!(cams, "{seed:02} {} {} {} {}", k.fx, k.fy, k.cx, k.cy);
    }
    std::fs::write(dir.join("cameras.txt"), cams).unwrap();
}
