//! Diagnostic: how well a sequence's reference poses agree with its own frames. Fuses every
//! frame at its reference pose (the multi-scale prefilter of `sldepth track`, the default
//! `TsdfConfig`), then tracks the frames one after the other against that model (its raycast
//! from the last tracked pose, as `Reconstruction` does) and prints, per frame, the tracked
//! pose's error in camera axes and how well each pose explains the frame: the mean `|Δz|`
//! between the frame and the model rendered at full resolution from the reference pose and
//! from the tracked pose (pixels valid in both and within 3 cm). The tracking is
//! [`sl_track::track_in_map`]. A tracker that aligns the
//! frames to the reference's own map can score no better, against that reference, than the
//! reference's disagreement with the data (docs/bench/track.md, "Session 28").
//!
//! `--causal` tracks each frame in the map of the frames before it (fused at their reference
//! poses as the tracking goes): what a tracker would do with a perfect map of what it has seen,
//! to tell errors of the map built along the way from errors of the alignment (it prints
//! nothing per frame; use `--output`).
//!
//! `cargo run --release -p sl-track --example gt_model_probe -- 7scenes|tum [FRAMES]
//! [--uniform] [--no-prefilter] [--causal] [--output TRAJ.txt]` (needs `SLDEPTH_DATA`; `--output` writes
//! the tracked poses in TUM format with the frame index as timestamp, for `sldepth eval-traj`).

use sl_core::CameraToWorld;
use sl_filter::MultiScale;
use sl_track::{ReconstructionConfig, WeightMode, track_in_map};
use sl_tsdf::TsdfVolume;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |f: &str| args.iter().any(|a| a == f);
    let output = args
        .iter()
        .position(|a| a == "--output")
        .and_then(|i| args.get(i + 1));
    let mut plain = args
        .iter()
        .enumerate()
        .filter(|(i, a)| !a.starts_with("--") && (*i == 0 || args[i - 1] != "--output"))
        .map(|(_, a)| a.as_str());
    let which = plain.next().unwrap_or("7scenes");
    let n: usize = plain.next().map_or(Ok(50), str::parse)?;
    let seq = match which {
        "tum" => sl_testkit::tum_rpy_200_sequence(n),
        _ => sl_testkit::seven_scenes_sequence(n),
    }
    .ok_or("no data (set SLDEPTH_DATA)")?;
    let camera = seq.camera;
    let k = camera.intrinsics;
    let mut cfg = ReconstructionConfig::default_for(camera.sensor);
    if flag("--uniform") {
        cfg.tracker.weighting = WeightMode::Uniform;
    }
    let filter = (!flag("--no-prefilter")).then(|| MultiScale::default_for(&camera.sensor));
    let frames = seq
        .frames
        .iter()
        .map(|(d, p)| {
            Ok((
                match &filter {
                    Some(f) => f.apply(d)?,
                    None => d.clone(),
                },
                *p,
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut volume = TsdfVolume::new(cfg.tsdf)?;
    let rc = cfg.raycast_config();
    let mut out = match output {
        Some(p) => Some(std::io::BufWriter::new(std::fs::File::create(p)?)),
        None => None,
    };
    if flag("--causal") {
        // Each frame tracked in the map of the frames before it, fused at their reference
        // poses (what a tracker would have built with perfect poses).
        let mut model = cfg.model_reference(&camera)?;
        let mut tracker = sl_track::Tracker::new(camera, cfg.tracker)?;
        tracker.set_initial_pose(frames[0].1);
        for (i, (d, reference)) in frames.iter().enumerate() {
            let r = if i == 0 {
                tracker.track(d, None)?
            } else {
                let from = tracker.last_good_pose().unwrap_or(*reference);
                model.update(&volume, &from, &camera.sensor)?;
                tracker.track(d, model.maps())?
            };
            volume.integrate(d, &k, reference)?;
            if let Some(o) = out.as_mut() {
                write_pose(o, i, &r.pose)?;
            }
        }
        return Ok(());
    }
    for (d, p) in &frames {
        volume.integrate(d, &k, p)?;
    }
    let start = frames.first().ok_or("no frames")?.1;
    let results = track_in_map(camera, &cfg, &volume, start, frames.iter().map(|f| &f.0))?;
    let mut better = 0;
    for (i, ((d, reference), r)) in frames.iter().zip(&results).enumerate() {
        let fit = |pose: &CameraToWorld| -> Result<f64> {
            let render = volume.raycast(pose, &k, &rc)?;
            let (mut s, mut n) = (0.0f64, 0usize);
            for (a, b) in d.data().iter().zip(render.depth.data()) {
                if *a > 0.0 && *b > 0.0 && (a - b).abs() < 0.03 {
                    s += f64::from(a - b).abs();
                    n += 1;
                }
            }
            Ok(s / n.max(1) as f64 * 1e3)
        };
        let (at_reference, at_tracked) = (fit(reference)?, fit(&r.pose)?);
        better += usize::from(at_tracked < at_reference);
        let e = reference.isometry().inverse() * r.pose.isometry();
        let t = e.translation.vector * 1e3;
        println!(
            "{i:3} {:>11}: error ({:6.2}, {:6.2}, {:6.2}) mm {:.3}°; mean |dz| {at_reference:.3} mm \
             at the reference pose, {at_tracked:.3} mm at the tracked pose",
            r.status.as_str(),
            t.x,
            t.y,
            t.z,
            e.rotation.angle().to_degrees()
        );
        if let Some(o) = out.as_mut() {
            write_pose(o, i, &r.pose)?;
        }
    }
    println!(
        "the tracked pose explains its frame better than the reference pose in {better} of {} frames",
        frames.len()
    );
    Ok(())
}

/// One line of a TUM trajectory, the frame index as its timestamp.
fn write_pose(o: &mut impl std::io::Write, i: usize, pose: &CameraToWorld) -> Result<()> {
    let (p, q) = (pose.isometry().translation.vector, pose.isometry().rotation);
    writeln!(
        o,
        "{i}.000000 {} {} {} {} {} {} {}",
        p.x, p.y, p.z, q.i, q.j, q.k, q.w
    )?;
    Ok(())
}
