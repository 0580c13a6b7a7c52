//! Diagnostic: how the tracker does in a *perfect* map of the simulated `corridor` (Kinect v1,
//! 640×480, exact rendered depth, no noise): the 30 frames of `cameras_track`'s path (1 cm and
//! 1° per frame) are fused at their true poses, up to `--max-depth=M` metres (default 6, so the
//! end wall 4.5 m away is in the map), with the default `TsdfConfig`; then
//!
//! * `errors` (default): the map raycast from frames 5, 15 and 25 against the exact depth,
//!   along the surface normal, as mean and RMS per bin of depth (0.5 m) and of the cosine between
//!   the ray and the normal — how well the map represents each surface;
//! * `track`: every exact frame tracked in that map ([`sl_track::track_in_map`], from the true
//!   first pose), each frame's error in camera axes with the tracker's diagnostics. Options:
//!   `--scale=S` renders the map at that fraction of the camera's resolution (default: the
//!   tracker's default, a quarter), `--uniform` weights residuals uniformly, `--drop=L,…` removes
//!   the pixels of these surface labels from the frames (1 floor, 2 ceiling, 3 left wall,
//!   4 right wall, 5 end wall; the map keeps them).
//!
//! Session 55 (docs/bench/track.md): with exact data and this map, the inverse-variance
//! weighting leaves frames 3–10 mm off along the corridor's axis where uniform weights stay
//! within 0.3 mm.
//!
//! ```text
//! cargo run --release -p sl-track --example corridor_model_probe -- [errors|track] \
//!     [--max-depth=M] [--scale=S] [--uniform] [--drop=L,…]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

use std::collections::BTreeMap;

use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera, CameraToWorld};
use sl_noise::sim::named_scene;
use sl_track::{ReconstructionConfig, WeightMode, track_in_map};
use sl_tsdf::TsdfVolume;

/// Frames on the path.
const FRAMES: usize = 30;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| args.iter().find_map(|a| a.strip_prefix(name));
    let camera = Camera::preset("kinect-v1").unwrap();
    let k = camera.intrinsics;
    let scene = named_scene("corridor").unwrap();
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.01, 0.002, 0.004),
        UnitQuaternion::from_scaled_axis(
            Vector3::new(0.2, 1.0, 0.1).normalize() * 1f64.to_radians(),
        ),
    ));
    let mut poses: Vec<CameraToWorld> = vec![scene.pose];
    while poses.len() < FRAMES {
        let next = *poses.last().unwrap() * step;
        poses.push(next);
    }
    let mut cfg = ReconstructionConfig::default_for(camera.sensor);
    cfg.tsdf.max_depth_m = value("--max-depth=").map_or(6.0, |m| m.parse().unwrap());
    let renders: Vec<_> = poses.iter().map(|p| scene.scene.render(&k, p)).collect();
    let mut map = TsdfVolume::new(cfg.tsdf).unwrap();
    for (r, p) in renders.iter().zip(&poses) {
        map.integrate(&r.depth, &k, p).unwrap();
    }

    if args.iter().any(|a| a == "track") {
        cfg.model_scale = value("--scale=").map(|s| s.parse().unwrap());
        if args.iter().any(|a| a == "--uniform") {
            cfg.tracker.weighting = WeightMode::Uniform;
        }
        let drop: Vec<u16> = value("--drop=")
            .map(|s| s.split(',').map(|v| v.parse().unwrap()).collect())
            .unwrap_or_default();
        let frames: Vec<_> = renders
            .iter()
            .map(|r| {
                let mut d = r.depth.clone();
                for (z, l) in d.data_mut().iter_mut().zip(r.labels.data()) {
                    if drop.contains(l) {
                        *z = 0.0;
                    }
                }
                d
            })
            .collect();
        let results = track_in_map(camera, &cfg, &map, poses[0], &frames).unwrap();
        for (i, (r, p)) in results.iter().zip(&poses).enumerate() {
            let e = p.isometry().inverse() * r.pose.isometry();
            let t = e.translation.vector * 1e3;
            println!(
                "{i:2} {:<22} error ({:+.2}, {:+.2}, {:+.2}) mm {:.3}°, rms {:.2} mm, cond {:.1e}, weakest σ {:.1} mm",
                r.status.as_str(),
                t.x,
                t.y,
                t.z,
                e.rotation.angle().to_degrees(),
                r.rms_m * 1e3,
                r.condition,
                r.weakest_sigma_m * 1e3
            );
        }
        return;
    }

    // `errors`: (depth bin, cosine bin) → (Σ e, Σ e², n), e along the normal in metres.
    let raycast = cfg.raycast_config();
    let mut bins = BTreeMap::<(u32, u32), (f64, f64, usize)>::new();
    for i in [5, 15, 25] {
        let truth = &renders[i];
        let ray = map.raycast(&poses[i], &k, &raycast).unwrap();
        for (p, ((&zt, &zr), n)) in truth
            .depth
            .data()
            .iter()
            .zip(ray.depth.data())
            .zip(truth.normals.data())
            .enumerate()
        {
            if !(zt > 0.0 && zr > 0.0 && (zr - zt).abs() < 0.05) {
                continue;
            }
            let (u, v) = ((p % k.width) as f64, (p / k.width) as f64);
            let d = Vector3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
            let n = Vector3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
            let cos = (n.dot(&d) / d.norm()).abs();
            // The hit moves along the ray by (zr − zt)·|d|; its component along the normal.
            let e = f64::from(zr - zt) * d.norm() * cos;
            let bin = ((f64::from(zt) * 2.0) as u32, (cos * 10.0) as u32);
            let s = bins.entry(bin).or_default();
            s.0 += e;
            s.1 += e * e;
            s.2 += 1;
        }
    }
    println!("| depth (m) | cos(ray, normal) | pixels | mean (mm) | RMS (mm) |");
    println!("|---|---|---|---|---|");
    for ((zb, cb), (s, s2, n)) in bins {
        if n < 200 {
            continue;
        }
        println!(
            "| {:.2} | {:.2} | {n} | {:+.3} | {:.3} |",
            (f64::from(zb) + 0.5) / 2.0,
            (f64::from(cb) + 0.5) / 10.0,
            1e3 * s / n as f64,
            1e3 * (s2 / n as f64).sqrt()
        );
    }
}
