//! Camera tracking (issue 13): `sl_track::Tracker` on a simulated sequence with a known
//! trajectory and on the real 7-Scenes and ICL sequences (their poses as reference), with the
//! sensor-model weights (`inv-var`) and uniform weights, frame-to-model (the fused volume's
//! raycast) and frame-to-frame. ATE is the RMS position error after Horn's rigid alignment over
//! the tracked frames (lost frames have no pose; their count is reported beside it).
//!
//! Checks (simulated sequence only, where the truth is exact): every frame tracked, the
//! frame-to-model inv-var trajectory within 1 cm / 0.5° (one frame's pose noise is well under a
//! millimetre from ~30 k points; 1 cm fails on any wrong association, which is centimetres
//! off), and inv-var at least as accurate as uniform up to the spread of a 20-frame run (×1.5).
//! A simulated camera sliding along a single wall must be lost at every frame, the first too
//! (the degenerate-view check); the real sequences' weakest-direction σ is reported beside the bound.
//! With an odometry (`odometry`) the wall and a bare corridor are tracked, at the odometry's
//! position along the direction the depth leaves free.
//! Simulated rooms and corridors (`rooms`): lost frames reported, no wrong step checked with a
//! steady and with a shaken camera, and the reported σ checked against the errors it claims to
//! bound. Fragments (`fragments`): a
//! simulated camera that jumps while lost and comes back is joined back with every pose right;
//! TUM fr1/rpy-200 with the lens covered over a span of frames, with and without fragments.
//! The real sequences are reported, not checked: the targets (no lost frame on
//! fr1/rpy, ATE at most half of Open3D dense SLAM's) are not met yet (docs/bench/track.md).
//! Beside them, the frames tracked in a map fused at the reference poses: what the reference
//! itself disagrees with its frames, the floor of any depth tracker's ATE against it.

use anyhow::Result;
use sl_core::nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera, CameraToWorld, DepthImage, SensorModel};
use sl_noise::sim::{KinectSimulator, named_scene};
use sl_track::{ModelReference, Tracker, TrackerConfig, WeightMode};
use sl_tsdf::{RaycastConfig, TsdfConfig, TsdfVolume};

use super::Context;

mod faster;
mod fragments;
mod odometry;
mod rooms;

/// Tracks `frames`; `None` for a lost frame.
fn track(
    cam: &Camera,
    frames: &[&DepthImage],
    weighting: WeightMode,
    model: bool,
) -> Result<Vec<Option<CameraToWorld>>> {
    Ok(track_with_sigma(cam, frames, weighting, model)?.0)
}

/// [`track`], with each frame's weakest-direction σ (`FrameResult::weakest_sigma_m`).
fn track_with_sigma(
    cam: &Camera,
    frames: &[&DepthImage],
    weighting: WeightMode,
    model: bool,
) -> Result<(Vec<Option<CameraToWorld>>, Vec<f64>)> {
    let k = cam.intrinsics;
    let mut cfg = TrackerConfig::default();
    cfg.weighting = weighting;
    let mut tracker = Tracker::new(*cam, cfg)?;
    let mut vcfg = TsdfConfig::default();
    vcfg.voxel_m = 0.008;
    vcfg.trunc_m = 0.04;
    let mut volume = TsdfVolume::new(vcfg)?;
    let mut reference = ModelReference::new(
        &k,
        ModelReference::default_scale(cam),
        RaycastConfig::default(),
    )?;
    let mut out = Vec::new();
    let mut sigmas = Vec::new();
    for d in frames {
        let r = tracker.track(d, reference.maps())?;
        sigmas.push(r.weakest_sigma_m);
        if r.status.is_tracked() {
            if model {
                volume.integrate(*d, &k, &r.pose)?;
                reference.update_from_frame(&volume, &r.pose, &cam.sensor, d, &k)?;
            }
            out.push(Some(r.pose));
        } else {
            out.push(None);
        }
    }
    Ok((out, sigmas))
}

/// The frames tracked in a map fused beforehand at the reference poses (`sl_track::track_in_map`,
/// the volume of [`track_with_sigma`]), from the first reference pose: how far the reference
/// poses are from the ones that align the frames to the reference's own map, the least ATE a
/// depth tracker can be shown to have against that reference.
fn track_in_reference_map(
    cam: &Camera,
    frames: &[&DepthImage],
    reference: &[CameraToWorld],
    weighting: WeightMode,
) -> Result<Vec<Option<CameraToWorld>>> {
    let mut cfg = sl_track::ReconstructionConfig::default_for(cam.sensor);
    cfg.tracker.weighting = weighting;
    cfg.tsdf.voxel_m = 0.008;
    cfg.tsdf.trunc_m = 0.04;
    let mut map = TsdfVolume::new(cfg.tsdf)?;
    for (d, p) in frames.iter().zip(reference) {
        map.integrate(*d, &cam.intrinsics, p)?;
    }
    let start = *reference
        .first()
        .ok_or_else(|| anyhow::anyhow!("no frames"))?;
    Ok(
        sl_track::track_in_map(*cam, &cfg, &map, start, frames.iter().copied())?
            .into_iter()
            .map(|r| r.status.is_tracked().then_some(r.pose))
            .collect(),
    )
}

/// ATE RMSE (m) after Horn's rigid alignment of the estimated positions to the true ones,
/// over the frames with an estimate.
fn ate_m(truth: &[CameraToWorld], est: &[Option<CameraToWorld>]) -> f64 {
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = truth
        .iter()
        .zip(est)
        .filter_map(|(t, e)| e.map(|e| (e.translation(), t.translation())))
        .collect();
    if pairs.len() < 3 {
        return f64::NAN;
    }
    let n = pairs.len() as f64;
    let ma = pairs.iter().map(|p| p.0).sum::<Vector3<f64>>() / n;
    let mb = pairs.iter().map(|p| p.1).sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = pairs
        .iter()
        .map(|(a, b)| (a - ma) * (b - mb).transpose())
        .sum();
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return f64::NAN;
    };
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    let t = mb - r * ma;
    (pairs
        .iter()
        .map(|(a, b)| (r * a + t - b).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt()
}

/// The median over consecutive tracked frames of the error of the step between them (the
/// translation of `(truth step)⁻¹ · (estimated step)`), metres; NaN without such a pair.
fn median_step_error_m(truth: &[CameraToWorld], est: &[Option<CameraToWorld>]) -> f64 {
    let errors: Vec<f64> = truth
        .windows(2)
        .zip(est.windows(2))
        .filter_map(|(t, e)| {
            let (Some(e0), Some(e1)) = (e[0], e[1]) else {
                return None;
            };
            let t = t[0].isometry().inverse() * t[1].isometry();
            let e = e0.isometry().inverse() * e1.isometry();
            Some((t.inverse() * e).translation.vector.norm())
        })
        .collect();
    if errors.is_empty() {
        return f64::NAN;
    }
    sl_eval::trajectory::ErrorStats::of(&errors).median
}

/// The simulated sequence of the sl-track tests: `boxes` at 320×240, 1.5° and 1.5 cm per frame,
/// `n` frames with noise seeds from `seed`.
fn simulated(n: usize, seed: u64) -> Result<(Camera, Vec<CameraToWorld>, Vec<DepthImage>)> {
    let scene = named_scene("boxes")?;
    let k = scene.intrinsics.scaled(0.5)?;
    let sim = KinectSimulator::kinect_v1().white();
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.015, 0.002, 0.004),
        UnitQuaternion::from_scaled_axis(
            Vector3::new(0.2, 1.0, 0.1).normalize() * 1.5f64.to_radians(),
        ),
    ));
    let (mut poses, mut frames, mut pose) = (Vec::new(), Vec::new(), scene.pose);
    for i in 0..n {
        frames.push(sim.apply(&scene.scene.render(&k, &pose).depth, seed + i as u64));
        poses.push(pose);
        pose = pose * step;
    }
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    Ok((cam, poses, frames))
}

/// Runs the experiment.
pub fn run(ctx: &mut Context) -> Result<()> {
    let mut md = String::from(
        "ATE = RMS position error after Horn alignment over the tracked frames; *lost* = frames \
         without a pose. 8 mm voxels for the model. Real sequences with Open3D side by side: \
         docs/bench/track.md.\n\n| sequence | reference | weights | frames | lost | ATE (mm) |\n|---|---|---|---|---|---|\n",
    );
    let (cam, truth, frames) = simulated(20, 11)?;
    let refs: Vec<&DepthImage> = frames.iter().collect();
    let mut sim_ate = Vec::new();
    for (model, name) in [(true, "model"), (false, "frame")] {
        for w in [WeightMode::InvVar, WeightMode::Uniform] {
            let est = track(&cam, &refs, w, model)?;
            let lost = est.iter().filter(|e| e.is_none()).count();
            let ate = ate_m(&truth, &est);
            md.push_str(&format!(
                "| simulated boxes | {name} | {} | {} | {lost} | {:.2} |\n",
                w.name(),
                est.len(),
                ate * 1e3
            ));
            ctx.row(
                "track-sim",
                &format!("ate-{name}-{}", w.name()),
                ate * 1e3,
                "mm",
            );
            let median_step = median_step_error_m(&truth, &est);
            ctx.row(
                "track-sim",
                &format!("median-step-{name}-{}", w.name()),
                median_step * 1e3,
                "mm",
            );
            sim_ate.push((model, w, lost, ate, median_step));
        }
    }
    let m_iv = sim_ate[0];
    let m_u = sim_ate[1];
    ctx.check(
        "simulated: every frame tracked (all four configurations)",
        sim_ate.iter().all(|s| s.2 == 0),
        format!("lost {:?}", sim_ate.iter().map(|s| s.2).collect::<Vec<_>>()),
    );
    ctx.check(
        "simulated: frame-to-model inv-var ATE below 1 cm",
        m_iv.3 < 0.01,
        format!("{:.2} mm", m_iv.3 * 1e3),
    );
    // The steps, not the trajectory: one step's error stays in every later pose, so the ATE of
    // 20 frames measures the first bad step (since session 40 uniform weights' first step is
    // aligned to the first frame, 0.3 mm off, where inverse-variance weights' is 3.6 mm off
    // against the one-frame model: ATE 0.64 against 1.43 mm; docs/bench/track.md).
    ctx.check(
        "simulated: inv-var median step error at most 1.5x uniform's (frame to model)",
        m_iv.4 <= 1.5 * m_u.4,
        format!(
            "{:.2} mm vs {:.2} mm (ATE {:.2} vs {:.2} mm)",
            m_iv.4 * 1e3,
            m_u.4 * 1e3,
            m_iv.3 * 1e3,
            m_u.3 * 1e3
        ),
    );
    let quick = ctx.quick();
    let real = [
        sl_testkit::seven_scenes_sequence(if quick { 15 } else { 50 }),
        sl_testkit::icl_sequence(5),
    ];
    let mut degenerate = String::new();
    for seq in real.into_iter().flatten() {
        let truth: Vec<CameraToWorld> = seq.frames.iter().map(|f| f.1).collect();
        let refs: Vec<&DepthImage> = seq.frames.iter().map(|f| &f.0).collect();
        // One table row and one number of the report per run.
        let mut report = |label: &str, key: &str, w: WeightMode, est: &[Option<CameraToWorld>]| {
            let lost = est.iter().filter(|e| e.is_none()).count();
            let ate = ate_m(&truth, est);
            md.push_str(&format!(
                "| {} | {label} | {} | {} | {lost} | {:.1} |\n",
                seq.name,
                w.name(),
                est.len(),
                ate * 1e3
            ));
            ctx.row(
                &format!("track-{}", seq.name),
                &format!("ate-{key}-{}", w.name()),
                ate * 1e3,
                "mm",
            );
        };
        for w in [WeightMode::InvVar, WeightMode::Uniform] {
            let est = track_in_reference_map(&seq.camera, &refs, &truth, w)?;
            report("map fused at the reference poses", "reference-map", w, &est);
        }
        for (model, name) in [(true, "model"), (false, "frame")] {
            for w in [WeightMode::InvVar, WeightMode::Uniform] {
                let (est, sigmas) = track_with_sigma(&seq.camera, &refs, w, model)?;
                if model && w == WeightMode::InvVar {
                    degenerate.push_str(&sigma_row(seq.name, &sigmas));
                }
                report(name, name, w, &est);
            }
        }
    }
    md.push_str(&degenerate_views(ctx, &degenerate)?);
    md.push_str(&odometry::run_section(ctx)?);
    md.push_str(&rooms::run(ctx)?);
    md.push_str(&fragments::run_section(ctx)?);
    md.push_str(&faster::run_section(ctx)?);
    ctx.section("Camera tracking (issue 13)", md);
    Ok(())
}

/// A table row of the weakest-direction σ of a run's frames (NaN ones, where the check did
/// not run, left out).
fn sigma_row(name: &str, sigmas: &[f64]) -> String {
    let mut v: Vec<f64> = sigmas.iter().copied().filter(|s| !s.is_nan()).collect();
    v.sort_by(f64::total_cmp);
    let (med, max) = match v.len() {
        0 => (f64::NAN, f64::NAN),
        n => (v[n / 2], v[n - 1]),
    };
    let over = v.iter().filter(|&&s| s > prior_sigma_m()).count();
    format!(
        "| {name} | {} | {:.2} | {:.2} | {over} |\n",
        v.len(),
        med * 1e3,
        max * 1e3
    )
}

/// The σ of the tracker's motion prior, the degenerate-view bound, metres.
fn prior_sigma_m() -> f64 {
    TrackerConfig::default().motion_prior_sigma_m()
}

/// The degenerate-view check: a simulated camera sliding along a single wall (every frame
/// must be lost, the first too) and the real sequences' weakest-direction σ against the
/// bound (`rows`, reported).
fn degenerate_views(ctx: &mut Context, rows: &str) -> Result<String> {
    let scene = named_scene("wall")?;
    let k = scene.intrinsics.scaled(0.5)?;
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    let slide = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.01, 0.0, 0.0),
        UnitQuaternion::identity(),
    ));
    let mut pose = scene.pose;
    let mut frames = Vec::new();
    for i in 0..6u64 {
        frames.push(
            KinectSimulator::kinect_v1()
                .simulate(&scene.scene, &k, &pose, i)
                .depth,
        );
        pose = pose * slide;
    }
    let refs: Vec<&DepthImage> = frames.iter().collect();
    let (est, sigmas) = track_with_sigma(&cam, &refs, WeightMode::InvVar, true)?;
    let lost = est.iter().filter(|e| e.is_none()).count();
    ctx.check(
        "degenerate view: a camera sliding along a single wall is lost, its first frame too",
        lost == est.len(),
        format!("{lost} of {} frames lost", est.len()),
    );
    Ok(format!(
        "\n**Degenerate views** (`TrackerConfig::degenerate_check`): the pose's σ along its \
         least-constrained direction from the sensor model with the normals of the frame's \
         planes, against the motion prior's σ ({:.1} mm); after an alignment, the same for the \
         frame's inliers of the reference. Simulated wall, the camera sliding 1 cm per frame: \
         {lost} of {} frames lost (σ {}; the first frame waits for a view that pins the pose). \
         Real sequences, frame to model, inv-var (σ in mm, the larger of the frame's and its \
         overlap's; *over* = frames above the bound):\n\n\
         | sequence | frames | median σ | max σ | over |\n|---|---|---|---|---|\n{rows}",
        prior_sigma_m() * 1e3,
        est.len(),
        if sigmas.iter().all(|s| s.is_infinite()) {
            "∞"
        } else {
            "finite"
        }
    ))
}
