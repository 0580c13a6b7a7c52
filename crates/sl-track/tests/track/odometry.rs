//! An odometry given with the frames (`Tracker::set_odometry`): its motion predicts each
//! frame and is the prior of the alignment, so a direction the depth leaves free takes the
//! odometry's value instead of losing the frame, while the depth keeps deciding where it pins
//! the pose.

use super::*;

/// The odometry's camera poses for `truth`: in a frame of its own (`odom` ≠ world), with its
/// translation scaled by `1 + scale_error` (a wheel radius off by that much), so its error
/// grows with the distance travelled as a real odometry's does.
fn odometry_of(truth: &[CameraToWorld], scale_error: f64) -> Vec<Isometry3<f64>> {
    let odom_in_world = Isometry3::from_parts(
        Translation3::new(2.0, -1.0, 0.3),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.1, 0.5, -0.2)),
    );
    let world_to_odom = odom_in_world.inverse();
    let first = *truth[0].isometry();
    truth
        .iter()
        .map(|t| {
            let mut moved = first.inverse() * t.isometry();
            moved.translation.vector *= 1.0 + scale_error;
            world_to_odom * first * moved
        })
        .collect()
}

/// Tracks `frames` frame to frame, giving each its odometry pose when `odometry` is given.
fn track_with(
    cam: &Camera,
    frames: &[DepthImage],
    odometry: Option<&[Isometry3<f64>]>,
    cfg: TrackerConfig,
) -> Vec<sl_track::FrameResult> {
    let mut tracker = Tracker::new(*cam, cfg).unwrap();
    frames
        .iter()
        .enumerate()
        .map(|(i, d)| {
            tracker.set_odometry(odometry.map(|o| o[i]));
            tracker.track(d, None).unwrap()
        })
        .collect()
}

/// A camera sliding along a single wall, 1 cm per frame: without odometry every frame is a
/// degenerate view (`lost::a_single_wall_is_a_degenerate_view`); with an odometry that
/// understates the distance by 3 % every frame is tracked, the motion along the wall is the
/// odometry's (0.3 mm a frame short) and everything else the wall's.
#[test]
fn a_wall_the_depth_cannot_pin_along_is_tracked_with_odometry() {
    let (cam, truth, frames) = wall_slide(8);
    let without = track_with(&cam, &frames, None, TrackerConfig::default());
    assert!(without.iter().all(|r| r.status == TrackStatus::Lost));
    let odometry = odometry_of(&truth, -0.03);
    let with = track_with(&cam, &frames, Some(&odometry), TrackerConfig::default());
    assert_eq!(with[0].status, TrackStatus::Initialised);
    assert!(with[0].odometry_sigma_m.is_nan());
    for (i, r) in with.iter().enumerate().skip(1) {
        assert!(r.status.is_tracked(), "frame {i}: {:?}", r.failure);
        // The wall leaves its own plane free: the weak direction is the odometry's.
        assert!(r.odometry_sigma_m.is_finite() && r.odometry_sigma_m < 0.01);
        assert!(
            r.weakest_sigma_m.is_nan() || r.weakest_sigma_m > r.odometry_sigma_m,
            "frame {i}: {} against {}",
            r.weakest_sigma_m,
            r.odometry_sigma_m
        );
    }
    let est: Vec<CameraToWorld> = with.iter().map(|r| r.pose).collect();
    let e = errors(&truth, &est);
    for (i, (t, r)) in e.iter().enumerate() {
        // 3 % of 7 cm is 2.1 mm; the wall's own noise adds a little across it.
        assert!(*t < 0.003 && *r < 0.2, "frame {i}: {t} m, {r}°");
    }
    // Along the wall the pose is the odometry's, 0.3 mm a frame short (70 × 0.97 mm): the
    // wall's noise, fixed to the camera, does not pull it back towards the last frame.
    for (i, p) in est.iter().enumerate() {
        let slid = (truth[0].isometry().inverse() * p.isometry())
            .translation
            .vector
            .x;
        let odometry_says = 0.0097 * i as f64;
        assert!(
            (slid - odometry_says).abs() < 2e-4,
            "frame {i}: {slid} m along the wall, the odometry {odometry_says}"
        );
    }
}

/// Where the depth pins the pose (the `boxes` frames), the odometry's prior (σ 5 mm + 5 % of
/// the distance a frame) is weak beside the frame's information: an odometry as good as it
/// says (5 % off) changes the poses by a fraction of a millimetre, and one four times worse
/// than it says (20 %, 27 mm off alone at the last frame) by about a millimetre.
#[test]
fn where_the_depth_pins_the_pose_the_odometry_changes_little() {
    let (cam, truth, frames) = sequence(10, 7);
    let plain = track_with(&cam, &frames, None, TrackerConfig::default());
    let pose = |rs: &[sl_track::FrameResult]| rs.iter().map(|r| r.pose).collect::<Vec<_>>();
    let rms_plain = rms(&errors(&truth, &pose(&plain)));
    for (scale_error, bound_m) in [(0.05, 0.0006), (0.20, 0.0015)] {
        let odometry = odometry_of(&truth, scale_error);
        let with = track_with(&cam, &frames, Some(&odometry), TrackerConfig::default());
        assert!(with.iter().all(|r| r.status.is_tracked()));
        let rms_with = rms(&errors(&truth, &pose(&with)));
        eprintln!("rms without {rms_plain:?}, with a {scale_error} odometry {rms_with:?}");
        assert!(rms_with.0 < bound_m && rms_with.1 < 0.1, "{rms_with:?}");
    }
}

/// Frames with no depth while the camera moves on (a covered lens for 4 frames, 6 cm and 6°):
/// with odometry (5 % off) the frame after the gap is predicted by it and tracked at once; its
/// pose is the depth's, within a few millimetres of the truth.
#[test]
fn the_odometry_carries_the_prediction_across_lost_frames() {
    let (cam, truth, mut frames) = sequence(12, 3);
    for f in &mut frames[5..9] {
        *f = DepthImage::invalid(cam.intrinsics.width, cam.intrinsics.height);
    }
    let mut cfg = TrackerConfig::default();
    cfg.plane_fallback = false;
    cfg.keyframe_relocalisation = false;
    // Without it (and without the plane fallback and keyframes, which would search for the
    // view) the camera is beyond what an alignment from the last good pose may correct.
    let without = track_with(&cam, &frames, None, cfg);
    assert!(without[5..].iter().all(|r| r.status == TrackStatus::Lost));
    let odometry = odometry_of(&truth, 0.05);
    let with = track_with(&cam, &frames, Some(&odometry), cfg);
    let status: Vec<TrackStatus> = with.iter().map(|r| r.status).collect();
    assert!(
        status[5..9].iter().all(|s| *s == TrackStatus::Lost),
        "{status:?}"
    );
    assert_eq!(status[9], TrackStatus::Relocalised, "{status:?}");
    assert!(status[10..].iter().all(|s| s.is_tracked()), "{status:?}");
    let est: Vec<CameraToWorld> = with.iter().map(|r| r.pose).collect();
    let e = errors(&truth, &est);
    for i in [9, 10, 11] {
        assert!(e[i].0 < 0.006 && e[i].1 < 0.3, "frame {i}: {:?}", e[i]);
    }
}

/// A bare corridor: the `corridor` scene with everything beyond 3.5 m cut away (its end wall,
/// 4.1–4.4 m off, is what pins the axis), the camera moving 1 cm a frame along it. Without
/// odometry no frame pins the motion along the axis (degenerate views, lost); with one 5 %
/// short and drifting 3 mm a frame sideways, every frame is tracked, at the odometry's position
/// along the axis and the walls' across it.
#[test]
fn a_bare_corridor_is_tracked_along_its_axis_with_odometry() {
    let scene = named_scene("corridor").unwrap();
    let k = scene.intrinsics.scaled(0.5).unwrap();
    let cam = Camera {
        intrinsics: k,
        sensor: SensorModel::kinect_v1(),
    };
    let sim = KinectSimulator::kinect_v1().white();
    let axis_step = CameraToCamera::from_isometry(Isometry3::translation(0.0, 0.0, 0.01));
    let mut pose = scene.pose;
    let (mut truth, mut frames) = (Vec::new(), Vec::new());
    for i in 0..10u64 {
        let mut depth = sim.apply(&scene.scene.render(&k, &pose).depth, i);
        for z in depth.data_mut() {
            if *z > 3.5 {
                *z = 0.0;
            }
        }
        frames.push(depth);
        truth.push(pose);
        pose = pose * axis_step;
    }
    let without = track_with(&cam, &frames, None, TrackerConfig::default());
    let lost = without
        .iter()
        .filter(|r| r.status == TrackStatus::Lost)
        .count();
    eprintln!("without odometry: {lost} of 10 lost");
    assert!(
        lost >= 9,
        "{:?}",
        without.iter().map(|r| r.status).collect::<Vec<_>>()
    );
    // The odometry: 5 % short along the axis, and drifting 3 mm a frame sideways (camera x),
    // which the walls contradict.
    let odometry: Vec<Isometry3<f64>> = (0..10)
        .map(|i| {
            let i = f64::from(i);
            Isometry3::translation(0.003 * i, 0.0, 0.0095 * i)
        })
        .collect();
    let with = track_with(&cam, &frames, Some(&odometry), TrackerConfig::default());
    assert!(
        with.iter().all(|r| r.status.is_tracked()),
        "{:?}",
        with.iter().map(|r| &r.failure).collect::<Vec<_>>()
    );
    for (i, r) in with.iter().enumerate() {
        // The first frame is the world's origin; the camera moves along its own z.
        let rel = with[0].pose.isometry().inverse() * r.pose.isometry();
        let t = rel.translation.vector;
        // Along the axis the odometry's 9.5 mm a frame; across it the walls' (the odometry's
        // sideways drift, 27 mm by the last frame, is not taken).
        assert!((t.z - 0.0095 * i as f64).abs() < 3e-4, "frame {i}: {t:?}");
        assert!(t.x.abs() < 1e-3 && t.y.abs() < 1e-3, "frame {i}: {t:?}");
        assert!(rel.rotation.angle().to_degrees() < 0.2, "frame {i}");
    }
}

/// Odometry poses that are no numbers, or a jump of 1e300 m, are no odometry for their frame:
/// it is tracked as without one (no overflow into the alignment), and the next frames as before.
#[test]
fn odometry_that_is_no_number_or_out_of_reach_is_ignored() {
    let (cam, truth, frames) = sequence(6, 7);
    let mut odometry = odometry_of(&truth, 0.0);
    odometry[2].translation.vector.x = f64::NAN;
    odometry[3].translation.vector.x = 1e300;
    let with = track_with(&cam, &frames, Some(&odometry), TrackerConfig::default());
    assert!(with.iter().all(|r| r.status.is_tracked()));
    assert!(with[2].odometry_sigma_m.is_nan() && with[3].odometry_sigma_m.is_nan());
    assert!(with[5].odometry_sigma_m.is_finite());
    let est: Vec<CameraToWorld> = with.iter().map(|r| r.pose).collect();
    for (i, (t, r)) in errors(&truth, &est).iter().enumerate() {
        assert!(*t < 0.003 && *r < 0.2, "frame {i}: {t} m, {r}°");
    }
}
