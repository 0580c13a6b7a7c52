//! Tracking through the simulated rooms and corridors of the room benchmark: a check that the
//! tracker never silently emits a wrong pose on geometry nobody tuned on.
//!
//! For each seed, `sl_noise::sim::room_scene` (rooms 3–6 × 3.5–7 m with boxes, corridors
//! 1.4–2.2 m wide and 8–14 m long, camera anywhere, f = 520–600 px) is seen along a hand-held
//! path (1.2 cm and 1.2° per frame) through the realistic simulator, tracked frame to model
//! (8 mm voxels, the sensor-adaptive band), and scored: frames lost, and **bad steps** —
//! tracked frames whose motion since the previous tracked frame is off by more than 2 cm or 1°
//! (the real sequences' RPE is 2–6 mm per frame).
//!
//! ```text
//! cargo run --release -p sl-track --example rooms_track -- [FIRST [COUNT [FRAMES]]] [--verbose] [--camera NAME] [--jitter A] [--sim-sigma-d PX] [--prefilter camera|measured] [--resample F | --decimate N]
//! ```
//! Defaults: seeds 3000–3023, 30 frames, each scene's own Kinect-class camera. `--verbose`
//! prints every frame; `--camera NAME` sees every scene through a preset (`d435`, `oak-d`,
//! …: its intrinsics, baseline, sub-pixel step and noise) instead; `--jitter A` shakes the
//! camera: every step gets a seeded random extra motion of up to `A` cm along and `A`° about
//! each axis (uniform), so the constant-velocity prediction misses; `--sim-sigma-d PX` simulates
//! a sensor with that disparity noise while the tracker is given the camera's own model (a
//! sensor noisier than its camera says); `--prefilter camera|measured` smooths every frame
//! before tracking and fusion as `sldepth track` does (its default multi-scale filter; the
//! raw frame's noise measured first and given to the tracker), with the range kernel of the
//! camera's σ_D or, as `sldepth track` since session 51, of the frame's measured σ_D;
//! `--resample F` sees every scene through its camera's image scaled by `F`
//! (`Camera::resampled`: 0.5 is a 320×240 stream of the same sensor), simulated at that size
//! (the realistic noise's correlation window then spans `1/F` times the sensor's pixels);
//! `--decimate N` instead simulates each frame at the sensor's size and averages the disparity
//! of `N × N` blocks (a block with an invalid pixel is invalid): the stream a sensor decimated
//! by `N` delivers, its noise correlated over the sensor's own window. Results:
//! docs/bench/track.md ("Degenerate overlaps", session 39).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

use sl_core::nalgebra::Isometry3;
use sl_noise::sim::{HandHeldPath, room_scene};
use sl_track::{ModelReference, Tracker, TrackerConfig};
use sl_tsdf::{RaycastConfig, Truncation, TsdfConfig, TsdfVolume};

/// A tracked step off by more than this (metres) or [`BAD_STEP_DEG`] is a bad step.
const BAD_STEP_M: f64 = 0.02;
const BAD_STEP_DEG: f64 = 1.0;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let verbose = args.iter().any(|a| a == "--verbose");
    let prefilter = args
        .iter()
        .position(|a| a == "--prefilter")
        .and_then(|i| args.get(i + 1))
        .cloned();
    assert!(
        matches!(prefilter.as_deref(), None | Some("camera" | "measured")),
        "--prefilter camera|measured"
    );
    let preset = args
        .iter()
        .position(|a| a == "--camera")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let jitter: f64 = args
        .iter()
        .position(|a| a == "--jitter")
        .and_then(|i| args.get(i + 1))
        .map_or(0.0, |a| a.parse().unwrap());
    let sim_sigma_d: Option<f64> = args
        .iter()
        .position(|a| a == "--sim-sigma-d")
        .and_then(|i| args.get(i + 1))
        .map(|a| a.parse().unwrap());
    let resample: Option<f64> = args
        .iter()
        .position(|a| a == "--resample")
        .and_then(|i| args.get(i + 1))
        .map(|a| a.parse().unwrap());
    let decimate: Option<usize> = args
        .iter()
        .position(|a| a == "--decimate")
        .and_then(|i| args.get(i + 1))
        .map(|a| a.parse().unwrap());
    let numbers: Vec<u64> = args
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            *i == 0
                || !["--jitter", "--sim-sigma-d", "--resample", "--decimate"]
                    .contains(&args[i - 1].as_str())
        })
        .filter_map(|(_, a)| a.parse().ok())
        .collect();
    let first = numbers.first().copied().unwrap_or(3000);
    let count = numbers.get(1).copied().unwrap_or(24);
    let frames = numbers.get(2).copied().unwrap_or(30) as usize;
    let (mut all_posed, mut all_bad, mut seeds_bad, mut worst_all) = (0, 0, 0, 0.0f64);
    for seed in first..first + count {
        let room = room_scene(seed).unwrap();
        let (cam, sim) = room.camera_and_simulator(preset.as_deref()).unwrap();
        let sensor_k = cam.intrinsics;
        let cam = match (resample, decimate) {
            (Some(f), _) => cam.resampled(f).unwrap(),
            (None, Some(n)) => cam.resampled(1.0 / n as f64).unwrap(),
            (None, None) => cam,
        };
        // A sensor noisier (or quieter) than the camera the tracker is given.
        let sim = match sim_sigma_d {
            Some(sigma) => {
                let mut sensor = cam.sensor;
                sensor.sigma_d_px = sigma;
                let noise = match preset.as_deref() {
                    Some(name) => sl_noise::sim::RealisticNoise::for_camera(name),
                    None => sl_noise::sim::RealisticNoise::default(),
                };
                sl_noise::sim::KinectSimulator::with_sensor(sensor)
                    .with_noise(sl_noise::sim::NoiseModel::Realistic(noise))
            }
            None => sim,
        };
        let k = cam.intrinsics;
        let mut tracker = Tracker::new(cam, TrackerConfig::default()).unwrap();
        let mut meter = TrackerConfig::default().noise_meter();
        let mut vcfg = TsdfConfig::default();
        vcfg.voxel_m = 0.008;
        vcfg.trunc_m = 0.04;
        vcfg.truncation = Truncation::sensor_adaptive(cam.sensor);
        let mut volume = TsdfVolume::new(vcfg).unwrap();
        let mut reference = ModelReference::new(
            &k,
            ModelReference::default_scale(&cam),
            RaycastConfig::default(),
        )
        .unwrap();
        let mut pose = room.pose;
        let mut path = HandHeldPath::new(seed, jitter);
        let (mut lost, mut bad, mut worst) = (0, 0, 0.0f64);
        // The last tracked frame: its true and its estimated pose.
        let mut last: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
        let mut fused = 0usize;
        for i in 0..frames {
            let d = match decimate {
                Some(n) if resample.is_none() => sl_testkit::block_mean(
                    &sim.simulate(&room.scene, &sensor_k, &pose, seed * 1000 + i as u64)
                        .depth,
                    n,
                ),
                _ => {
                    sim.simulate(&room.scene, &k, &pose, seed * 1000 + i as u64)
                        .depth
                }
            };
            // As `sl_track::Reconstruction` does: against the first frame itself while the
            // model holds no more than it.
            let model = if fused > 1 { reference.maps() } else { None };
            let d = match prefilter.as_deref() {
                None => d,
                Some(mode) => {
                    let s = meter.measure(&d, &cam).unwrap();
                    tracker.set_noise_scale(Some(s));
                    let sensor = if mode == "measured" {
                        cam.sensor.with_variance_scale(s)
                    } else {
                        cam.sensor
                    };
                    let smooth = sl_filter::Prefilter::default().apply(&d, &sensor).unwrap();
                    smooth.unwrap_or(d)
                }
            };
            let r = tracker.track(&d, model).unwrap();
            if r.status.is_tracked() {
                // As `Reconstruction` does: the band of the frame's measured noise.
                if volume.frame_count() == 0 {
                    volume.set_band_sensor(tracker.frame_sensor()).unwrap();
                }
                volume.integrate(&d, &k, &r.pose).unwrap();
                fused += 1;
                reference
                    .update_from_frame(&volume, &r.pose, &tracker.frame_sensor(), &d, &k)
                    .unwrap();
                let (err_m, err_deg) = last.map_or((0.0, 0.0), |(t, e)| {
                    let truth = t.inverse() * pose.isometry();
                    let est = e.inverse() * r.pose.isometry();
                    let d = truth.inverse() * est;
                    (d.translation.vector.norm(), d.rotation.angle().to_degrees())
                });
                if err_m > BAD_STEP_M || err_deg > BAD_STEP_DEG {
                    bad += 1;
                }
                worst = worst.max(err_m);
                last = Some((*pose.isometry(), *r.pose.isometry()));
                if verbose {
                    println!(
                        "  {i} {}: step off by {:.1} mm {:.2}°, σ {:.2} mm, inliers {:.3}, noise ×{:.2}",
                        r.status.as_str(),
                        err_m * 1e3,
                        err_deg,
                        r.weakest_sigma_m * 1e3,
                        r.inlier_fraction,
                        tracker.noise_scale()
                    );
                }
            } else {
                lost += 1;
                if verbose {
                    println!("  {i} lost: {}", r.failure.as_deref().unwrap_or(""));
                }
            }
            pose = path.advance(&pose);
        }
        println!(
            "seed {seed} {:?} f {:.0} px: lost {lost} of {frames}, bad steps {bad} (worst step off by {:.1} mm)",
            room.kind,
            k.fx,
            worst * 1e3
        );
        all_posed += frames - lost;
        all_bad += bad;
        seeds_bad += usize::from(bad > 0);
        worst_all = worst_all.max(worst);
    }
    println!(
        "all: {all_posed} of {} frames with a pose, {all_bad} bad steps in {seeds_bad} seeds (worst {:.1} mm)",
        count as usize * frames,
        worst_all * 1e3
    );
}
