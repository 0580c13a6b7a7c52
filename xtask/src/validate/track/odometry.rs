//! Tracking with an odometry (`sl_track::Reconstruction::set_odometry`, `sldepth track
//! --odometry`): the two views the depth cannot pin — a camera sliding along a single wall and
//! one moving along a bare corridor (the `corridor` scene cut at 3.5 m, its end wall gone) —
//! tracked as `sldepth track` does (frame to model), without and with an odometry that is 3 %
//! short along the motion and, in the corridor, drifts 3 mm a frame sideways.
//!
//! **Checks**: without the odometry every frame is lost (degenerate views); with it every
//! frame is tracked, along the free direction at the odometry's position (its data are
//! projected out there, so within 0.5 mm of the odometry), and across it at the depth's
//! (within 2 mm of the truth; the corridor's sideways drift of the odometry, 27 mm by the last
//! frame, is not taken).

use anyhow::Result;
use sl_core::nalgebra::{Isometry3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToCamera, CameraToWorld, DepthImage, SensorModel};
use sl_noise::sim::{KinectSimulator, named_scene};
use sl_track::{Reconstruction, ReconstructionConfig};

use super::super::Context;

/// Frames of `scene` (320×240 Kinect) along `step` per frame, depth beyond `max_depth_m` cut.
fn frames_of(
    name: &str,
    step: Vector3<f64>,
    max_depth_m: f64,
    n: usize,
) -> Result<(Camera, Vec<CameraToWorld>, Vec<DepthImage>)> {
    let scene = named_scene(name)?;
    let k = scene.intrinsics.scaled(0.5)?;
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    let sim = KinectSimulator::kinect_v1();
    let mut pose = scene.pose;
    let (mut truth, mut frames) = (Vec::new(), Vec::new());
    for i in 0..n {
        let mut depth = sim.simulate(&scene.scene, &k, &pose, i as u64).depth;
        for z in depth.data_mut() {
            if *z > max_depth_m as f32 {
                *z = 0.0;
            }
        }
        frames.push(depth);
        truth.push(pose);
        pose = pose * CameraToCamera::from_isometry(Isometry3::translation(step.x, step.y, step.z));
    }
    Ok((cam, truth, frames))
}

/// Tracks `frames` (timestamps one frame interval apart) with `odometry` (camera-to-odometry
/// per frame) when given: per frame the pose, `None` when lost.
fn run(
    cam: Camera,
    frames: &[DepthImage],
    odometry: Option<&[Isometry3<f64>]>,
) -> Result<Vec<Option<CameraToWorld>>> {
    let mut cfg = ReconstructionConfig::default_for(cam.sensor);
    cfg.tsdf.voxel_m = 0.008;
    let dt = cfg.tracker.frame_interval_s;
    let mut rec = Reconstruction::new(cam, cfg)?;
    let mut out = Vec::new();
    for (i, d) in frames.iter().enumerate() {
        rec.set_odometry(odometry.map(|o| o[i]));
        let r = rec.step(d, Some(i as f64 * dt))?.result;
        out.push(r.status.is_tracked().then_some(r.pose));
    }
    Ok(out)
}

pub(super) fn run_section(ctx: &mut Context) -> Result<String> {
    let mut md = String::from(
        "\n**With an odometry** (`Reconstruction::set_odometry`, `sldepth track --odometry`): \
         views the depth cannot pin, tracked frame to model without and with an odometry 3 % \
         short along the motion (in the corridor also drifting 3 mm a frame sideways, which \
         the walls contradict). Errors relative to the first frame, mm: *along* the free \
         direction against the odometry's position, *across* against the truth.\n\n\
         | view | frames | lost without | lost with | along − odometry (max) | across − truth (max) |\n\
         |---|---|---|---|---|---|\n",
    );
    let n = 8;
    // The wall: its plane leaves the slide along camera x free. The corridor: its walls, floor
    // and ceiling leave the motion along its axis (camera z) free once the end wall is cut.
    let views = [
        (
            "wall, sliding 1 cm a frame",
            "wall",
            Vector3::x(),
            0.0,
            10.0,
        ),
        (
            "bare corridor, 1 cm a frame along it",
            "corridor",
            Vector3::z(),
            0.003,
            3.5,
        ),
    ];
    let mut all_ok = true;
    let mut detail = Vec::new();
    for (label, scene, axis, sideways, cut) in views {
        let (cam, truth, frames) = frames_of(scene, axis * 0.01, cut, n)?;
        let lost_without = run(cam, &frames, None)?
            .iter()
            .filter(|p| p.is_none())
            .count();
        // The odometry in a frame of its own: the camera's motion, 3 % short, with a sideways
        // drift along camera x (the corridor's) and the frame turned about z.
        let odom_frame = Isometry3::from_parts(
            Vector3::new(1.0, 2.0, 0.3).into(),
            UnitQuaternion::from_scaled_axis(Vector3::z() * 0.7),
        );
        let odometry: Vec<Isometry3<f64>> = (0..n)
            .map(|i| {
                let i = i as f64;
                let moved = axis * (0.0097 * i) + Vector3::x() * (sideways * i);
                odom_frame * Isometry3::translation(moved.x, moved.y, moved.z)
            })
            .collect();
        let with = run(cam, &frames, Some(&odometry))?;
        let lost_with = with.iter().filter(|p| p.is_none()).count();
        let (mut along_max, mut across_max) = (0.0f64, 0.0f64);
        if let Some(Some(first)) = with.first() {
            for (i, p) in with.iter().enumerate() {
                let Some(p) = p else { continue };
                let rel = first.isometry().inverse() * p.isometry();
                let truth_rel = truth[0].isometry().inverse() * truth[i].isometry();
                let t = rel.translation.vector;
                let along = t.dot(&axis) - 0.0097 * i as f64;
                let across = (t - axis * t.dot(&axis))
                    - (truth_rel.translation.vector
                        - axis * truth_rel.translation.vector.dot(&axis));
                along_max = along_max.max(along.abs());
                across_max = across_max.max(across.norm());
            }
        }
        ctx.row(
            "track-odometry",
            &format!("{scene}-along-max"),
            along_max * 1e3,
            "mm",
        );
        ctx.row(
            "track-odometry",
            &format!("{scene}-across-max"),
            across_max * 1e3,
            "mm",
        );
        md.push_str(&format!(
            "| {label} | {n} | {lost_without} | {lost_with} | {:.2} | {:.2} |\n",
            along_max * 1e3,
            across_max * 1e3
        ));
        all_ok &= lost_without == n && lost_with == 0 && along_max < 5e-4 && across_max < 2e-3;
        detail.push(format!(
            "{scene}: lost {lost_without} → {lost_with}, along {:.2} mm, across {:.2} mm",
            along_max * 1e3,
            across_max * 1e3
        ));
    }
    ctx.check(
        "odometry: a wall and a bare corridor, lost without it, are tracked with it at its position along the free direction and the depth's across",
        all_ok,
        detail.join("; "),
    );
    Ok(md)
}
