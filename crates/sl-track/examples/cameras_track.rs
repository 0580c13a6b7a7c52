//! Tracks simulated sequences of the named scenes through camera presets (not only the Kinect)
//! and prints, per camera and scene, the frames lost, the fragments started and the worst error
//! of a frame reported tracked, against the truth. It looks for the cases the unit tests (320×240
//! Kinect frames) do not cover: other focal lengths, baselines and image sizes, full-resolution
//! frames, the realistic noise (docs/bench/track.md, "Session 23").
//!
//! ```text
//! cargo run --release -p sl-track --example cameras_track -- \
//!     [--white | --exact] [--no-prefilter] [--model-noise-only] [--frame-to-frame] \
//!     [--resample=F | --decimate=N] [--max-depth=M] [--bilinear] [--turn-only] [--per-frame] [--seed-offset=N] \
//!     [--uniform] [--drop=L,…] [CAMERAS] [SCENES]
//! ```
//!
//! `CAMERAS` and `SCENES` are comma-separated preset and scene names (defaults:
//! `kinect-v1,primesense,d435,d415,oak-d` and `boxes,figure-walls,corridor`). Each sequence is 30
//! frames of a camera turning 1° and moving 1 cm per frame, seeded; every raw frame's noise is
//! measured against the camera's model and handed to the tracker, and the frame goes through
//! the default prefilter for that noise (as `sldepth track` and Python's `Tracker` do by
//! default) unless `--no-prefilter`; `--model-noise-only` keeps the camera's model (no
//! measurement). Errors are relative to the first frame the tracker anchored its model on
//! (`Initialised`), over the frames of fragment 0 reported tracked. `--resample=F` scales each
//! camera's image by `F` (`Camera::resampled`: the same sensor through a smaller image),
//! simulated at that size (each pixel with the sensor's own noise); `--decimate=N` instead
//! simulates every frame at the sensor's size and averages the disparity of `N × N` blocks
//! (`sl_testkit::block_mean`: the stream of a sensor that decimates by averaging);
//! `--max-depth=M` fuses and renders the model up to `M` metres (default 4: the corridor's end
//! wall, 4.5 m away, is then never in the model); `--bilinear` fuses with
//! `DepthLookup::Bilinear`;
//! `--turn-only` keeps the camera in place, turning only (a corridor's axis is then pinned by
//! nothing the model holds: the defect of session 52, docs/bench/track.md);
//! `--exact` tracks the rendered depth itself (no noise, no quantisation, no drop-outs), to tell
//! the tracker's own errors from the sensor's;
//! `--per-frame` prints every tracked frame's error in camera axes and its diagnostics;
//! `--seed-offset=N` adds `N` to every frame's noise seed (another draw of the same sequence:
//! a drift seen in one draw is a bias only when the other draws share its sign);
//! `--uniform` tracks with uniform residual weights instead of the sensor model's; `--drop=L,…`
//! removes the pixels of these surface labels from every frame before the noise (the scene's
//! parts in the order `named_scene` adds them, from 1: the corridor's floor, ceiling, left wall,
//! right wall, end wall).

use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera};
use sl_filter::Prefilter;
use sl_noise::sim::{KinectSimulator, NoiseModel, RealisticNoise, named_scene};
use sl_track::{Reconstruction, ReconstructionConfig, TrackStatus};

/// Frames per sequence.
const FRAMES: usize = 30;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |f: &str| args.iter().any(|a| a == f);
    let exact = flag("--exact");
    let measure = !flag("--model-noise-only");
    let (white, prefilter, frame_to_model, per_frame) = (
        flag("--white"),
        if flag("--no-prefilter") {
            Prefilter::Off
        } else {
            Prefilter::MultiScale
        },
        !flag("--frame-to-frame"),
        flag("--per-frame"),
    );
    let resample = match args.iter().find_map(|a| a.strip_prefix("--resample=")) {
        Some(f) => Some(f.parse::<f64>()?),
        None => None,
    };
    let decimate = match args.iter().find_map(|a| a.strip_prefix("--decimate=")) {
        Some(n) => Some(n.parse::<usize>()?.max(1)),
        None => None,
    };
    if resample.is_some() && decimate.is_some() {
        return Err("--resample and --decimate exclude each other".into());
    }
    let drop = match args.iter().find_map(|a| a.strip_prefix("--drop=")) {
        Some(labels) => labels
            .split(',')
            .map(str::parse::<u16>)
            .collect::<Result<Vec<_>, _>>()?,
        None => Vec::new(),
    };
    let seed_offset = match args.iter().find_map(|a| a.strip_prefix("--seed-offset=")) {
        Some(n) => n.parse::<u64>()?,
        None => 0,
    };
    let max_depth_m = match args.iter().find_map(|a| a.strip_prefix("--max-depth=")) {
        Some(m) => Some(m.parse::<f64>()?),
        None => None,
    };
    let mut names = args.iter().filter(|a| !a.starts_with("--"));
    let cameras = names
        .next()
        .map_or("kinect-v1,primesense,d435,d415,oak-d", String::as_str);
    let scenes = names
        .next()
        .map_or("boxes,figure-walls,corridor", String::as_str);
    println!(
        "noise {}, prefilter {prefilter}, frame to model {frame_to_model}",
        if exact {
            "none (exact depth)"
        } else if white {
            "white"
        } else {
            "realistic"
        }
    );
    println!(
        "| camera | size | scene | lost | fragments | worst tracked error (mm, °) | median step ms |"
    );
    println!("|---|---|---|---|---|---|---|");
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        if flag("--turn-only") {
            Translation3::identity()
        } else {
            Translation3::new(0.01, 0.002, 0.004)
        },
        UnitQuaternion::from_scaled_axis(
            Vector3::new(0.2, 1.0, 0.1).normalize() * 1.0f64.to_radians(),
        ),
    ));
    for name in cameras.split(',') {
        let sensor_camera = Camera::preset(name)?;
        let camera = match (resample, decimate) {
            (Some(f), _) => sensor_camera.resampled(f)?,
            (None, Some(n)) => sensor_camera.resampled(1.0 / n as f64)?,
            (None, None) => sensor_camera,
        };
        // The camera the frames are rendered and simulated through.
        let render_camera = if decimate.is_some() {
            sensor_camera
        } else {
            camera
        };
        let noise = RealisticNoise::for_camera(name);
        let sim = KinectSimulator::with_sensor(camera.sensor).with_noise(if white {
            NoiseModel::White
        } else {
            NoiseModel::Realistic(noise)
        });
        for scene_name in scenes.split(',') {
            let scene = named_scene(scene_name)?;
            let mut cfg = ReconstructionConfig::default_for(camera.sensor);
            cfg.frame_to_model = frame_to_model;
            if flag("--uniform") {
                cfg.tracker.weighting = sl_track::WeightMode::Uniform;
            }
            if let Some(m) = max_depth_m {
                cfg.tsdf.max_depth_m = m;
            }
            if flag("--bilinear") {
                cfg.tsdf.depth_lookup = sl_tsdf::DepthLookup::Bilinear;
            }
            let dt = cfg.tracker.frame_interval_s;
            let mut meter = measure.then(|| cfg.tracker.noise_meter());
            let mut rec = Reconstruction::new(camera, cfg)?;
            let (mut pose, mut anchor) = (scene.pose, None);
            let (mut lost, mut fragments, mut worst) = (0, 0, (0.0f64, 0.0f64));
            let mut ms = Vec::new();
            for i in 0..FRAMES {
                let rendered = scene.scene.render(&render_camera.intrinsics, &pose);
                let mut truth = rendered.depth;
                if !drop.is_empty() {
                    for (z, l) in truth.data_mut().iter_mut().zip(rendered.labels.data()) {
                        if drop.contains(l) {
                            *z = 0.0;
                        }
                    }
                }
                let mut depth = if exact {
                    truth
                } else {
                    sim.apply(&truth, 100 + seed_offset + i as u64)
                };
                if let Some(n) = decimate {
                    depth = sl_testkit::block_mean(&depth, n);
                }
                // As `sldepth track`: the raw frame's noise against the camera's model (the
                // prefilter hides it), for the tracker and the prefilter's range kernel.
                let scale = match meter.as_mut() {
                    Some(m) => Some(m.measure(&depth, &camera)?),
                    None => None,
                };
                rec.set_noise_scale(scale);
                let sensor = camera.sensor.with_variance_scale(scale.unwrap_or(1.0));
                if let Some(smooth) = prefilter.apply(&depth, &sensor)? {
                    depth = smooth;
                }
                let s = rec.step(&depth, Some(i as f64 * dt))?;
                ms.push(s.timings.step_ms);
                fragments = fragments.max(s.fragment);
                let status = s.result.status;
                if status == TrackStatus::Initialised && anchor.is_none() {
                    anchor = Some((*pose.isometry(), *s.result.pose.isometry()));
                }
                if !status.is_tracked() {
                    lost += 1;
                    if per_frame {
                        println!(
                            "  frame {i} {}: {}",
                            status.as_str(),
                            s.result.failure.as_deref().unwrap_or("")
                        );
                    }
                } else if let (Some((t0, e0)), 0) = (anchor, s.fragment) {
                    let truth_rel = t0.inverse() * pose.isometry();
                    let est_rel = e0.inverse() * s.result.pose.isometry();
                    let e = truth_rel.inverse() * est_rel;
                    worst.0 = worst.0.max(e.translation.vector.norm());
                    worst.1 = worst.1.max(e.rotation.angle().to_degrees());
                    if per_frame {
                        let (r, t) = (&s.result, e.translation.vector * 1e3);
                        println!(
                            "  frame {i} {}: error ({:.1}, {:.1}, {:.1}) mm, inliers {:.3}, weakest σ {:.2} mm",
                            status.as_str(),
                            t.x,
                            t.y,
                            t.z,
                            r.inlier_fraction,
                            r.weakest_sigma_m * 1e3
                        );
                    }
                }
                pose = pose * step;
            }
            ms.sort_by(f64::total_cmp);
            println!(
                "| {name} | {}×{} | {scene_name} | {lost} | {fragments} | {:.1}, {:.2} | {:.1} |",
                camera.intrinsics.width,
                camera.intrinsics.height,
                worst.0 * 1e3,
                worst.1,
                ms[ms.len() / 2]
            );
        }
    }
    Ok(())
}
