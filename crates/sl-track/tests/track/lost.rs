//! Frames that cannot be tracked: reported lost with the last good pose and why, tracking
//! resumed or relocalised at a keyframe afterwards, and views that leave a direction free (a
//! single wall, a bare corridor) lost as degenerate rather than given a pose.

use super::*;

/// A blank frame (no valid depth) and a frame of another scene cannot be tracked: both are
/// reported lost with the last good pose, nothing is fused, and the next frame of the
/// sequence is found again (relocalised) at the right pose.
#[test]
fn untrackable_frames_are_lost_and_tracking_resumes() {
    let (cam, truth, mut frames) = sequence(12, 3);
    frames[5] = DepthImage::invalid(cam.intrinsics.width, cam.intrinsics.height);
    // A frame of the corridor scene (a different place) in place of frame 8.
    let other = named_scene("corridor").unwrap();
    let corridor = other.scene.render(&cam.intrinsics, &other.pose).depth;
    frames[8] = KinectSimulator::kinect_v1().white().apply(&corridor, 99);
    let mut cfg = TrackerConfig::default();
    cfg.plane_fallback = false;
    let (est, status) = track(&cam, &frames, cfg, true);
    eprintln!("{status:?}");
    assert_eq!(status[5], TrackStatus::Lost);
    assert_eq!(status[6], TrackStatus::Relocalised);
    assert_eq!(status[8], TrackStatus::Lost);
    assert_eq!(status[9], TrackStatus::Relocalised);
    assert_eq!(est[5], est[4], "a lost frame keeps the last good pose");
    assert_eq!(est[8], est[7]);
    let e = errors(&truth, &est);
    for i in [6, 7, 9, 10, 11] {
        assert!(e[i].0 < 0.01 && e[i].1 < 0.5, "frame {i}: {:?}", e[i]);
    }
}

/// A camera that comes back to a view it saw before, far from where tracking was lost, is found
/// again at the keyframe of that view (`TrackerConfig::keyframe_relocalisation`): frames 0–12
/// (1.5° and 1.5 cm a frame), then frame 12 again with the lens covered (lost), then frames 3,
/// 4, 5 — 13.5° and 14 cm from the last good pose, beyond what an alignment from it may
/// correct. Without keyframes they stay lost; with them frame 3 is relocalised and the next
/// ones tracked, within a centimetre and half a degree of the truth. A frame of another place
/// is lost either way.
#[test]
fn a_camera_back_at_an_earlier_view_is_relocalised_at_its_keyframe() {
    let (cam, truth, frames) = sequence(13, 5);
    let covered = DepthImage::invalid(cam.intrinsics.width, cam.intrinsics.height);
    let other = named_scene("corridor").unwrap();
    let corridor = other.scene.render(&cam.intrinsics, &other.pose).depth;
    let elsewhere = KinectSimulator::kinect_v1().white().apply(&corridor, 98);
    let order: Vec<Option<usize>> = (0..13)
        .map(Some)
        .chain([None, Some(3), Some(4), Some(5)])
        .collect();
    let seq: Vec<DepthImage> = order
        .iter()
        .map(|o| o.map_or_else(|| covered.clone(), |i| frames[i].clone()))
        .chain(std::iter::once(elsewhere))
        .collect();
    for keyframes in [false, true] {
        let mut cfg = TrackerConfig::default();
        cfg.plane_fallback = false;
        cfg.keyframe_relocalisation = keyframes;
        let (est, status) = track(&cam, &seq, cfg, true);
        assert!(status[..13].iter().all(|s| s.is_tracked()), "{status:?}");
        assert_eq!(status[13], TrackStatus::Lost);
        assert_eq!(status[17], TrackStatus::Lost, "another place: {status:?}");
        if !keyframes {
            assert_eq!(status[14], TrackStatus::Lost, "{status:?}");
            continue;
        }
        assert_eq!(status[14], TrackStatus::Relocalised, "{status:?}");
        assert!(status[15..17].iter().all(|s| s.is_tracked()), "{status:?}");
        for (j, i) in [(14, 3), (15, 4), (16, 5)] {
            let e = errors(&[truth[0], truth[i]], &[est[0], est[j]])[1];
            assert!(e.0 < 0.01 && e.1 < 0.5, "frame {j} (truth {i}): {e:?}");
        }
    }
}

/// A lost frame says why every attempt failed: the alignment from the prediction, then the
/// plane-based fallback (here a frame of another place, whose planes no motion from the last
/// frame explains).
#[test]
fn a_lost_frame_reports_why_the_plane_fallback_failed_too() {
    let (cam, _, mut frames) = sequence(6, 3);
    let other = named_scene("corridor").unwrap();
    let corridor = other.scene.render(&cam.intrinsics, &other.pose).depth;
    frames[5] = KinectSimulator::kinect_v1().white().apply(&corridor, 99);
    let mut tracker = Tracker::new(cam, TrackerConfig::default()).unwrap();
    let results: Vec<_> = frames
        .iter()
        .map(|d| tracker.track(d, None).unwrap())
        .collect();
    assert!(results[..5].iter().all(|r| r.status.is_tracked()));
    let lost = &results[5];
    assert_eq!(lost.status, TrackStatus::Lost, "{:?}", lost.failure);
    let why = lost.failure.as_deref().unwrap_or("");
    let (alignment, fallback) = why.split_once("; plane fallback: ").unwrap_or(("", ""));
    assert!(!alignment.is_empty() && !fallback.is_empty(), "{why}");
    // Without the fallback only the alignment's reason.
    let mut cfg = TrackerConfig::default();
    cfg.plane_fallback = false;
    let mut tracker = Tracker::new(cam, cfg).unwrap();
    let last = frames
        .iter()
        .map(|d| tracker.track(d, None).unwrap())
        .last()
        .unwrap();
    assert_eq!(last.status, TrackStatus::Lost);
    assert!(!last.failure.unwrap_or_default().contains("plane fallback"));
}

/// A camera sliding along a wall, 1 cm per frame, sees one plane: nothing in the depth pins
/// the motion along the wall, so every frame is lost as a degenerate view — the first too (a
/// model of one wall cannot anchor the frames after it: the tracker waits for a view that pins
/// the pose), the others with the last good pose. Before session 12 they were reported tracked
/// with the pose stuck. The `boxes` frames, with planes facing three ways, have a finite
/// weakest σ under the motion prior's; disabling the check gives the old behaviour back.
#[test]
fn a_single_wall_is_a_degenerate_view() {
    let (cam, _, frames) = wall_slide(4);
    let mut tracker = Tracker::new(cam, TrackerConfig::default()).unwrap();
    let first = tracker.track(&frames[0], None).unwrap();
    assert_eq!(first.status, TrackStatus::Lost, "{:?}", first.failure);
    assert!(
        first
            .failure
            .as_deref()
            .unwrap_or("")
            .starts_with("first frame")
    );
    assert!(tracker.last_good_pose().is_none());
    for d in &frames[1..] {
        let r = tracker.track(d, None).unwrap();
        assert_eq!(r.status, TrackStatus::Lost, "{:?}", r.failure);
        assert_eq!(r.pose, first.pose);
        assert!(r.weakest_sigma_m.is_infinite(), "{}", r.weakest_sigma_m);
        assert!(r.failure.as_deref().unwrap_or("").contains("degenerate"));
    }
    let mut cfg = TrackerConfig::default();
    cfg.degenerate_check = false;
    let mut unchecked = Tracker::new(cam, cfg).unwrap();
    let r = unchecked.track(&frames[0], None).unwrap();
    assert_eq!(r.status, TrackStatus::Initialised);
    let r = unchecked.track(&frames[1], None).unwrap();
    assert!(r.weakest_sigma_m.is_nan());
    // The boxes: constrained every way, the weakest direction known to a few millimetres.
    let (cam, _, frames) = sequence(2, 5);
    let mut tracker = Tracker::new(cam, TrackerConfig::default()).unwrap();
    tracker.track(&frames[0], None).unwrap();
    let r = tracker.track(&frames[1], None).unwrap();
    assert_eq!(r.status, TrackStatus::Tracked);
    // Tracked, so below the bound (the larger of the frame's σ and its overlap's with the last
    // frame, whose own noise doubles the variance): finite, and not zero.
    let prior = TrackerConfig::default().motion_prior_sigma_m();
    assert!(
        r.weakest_sigma_m > 0.0 && r.weakest_sigma_m < prior,
        "{} vs {prior}",
        r.weakest_sigma_m
    );
}

/// A bare corridor — floor, ceiling and two walls, its end beyond the range — leaves the
/// position along it free, and a view of it must not anchor a model. OAK-D frames at their full
/// 1280×800, realistic noise, prefiltered as `sldepth track` does. The walls' near ends, at
/// 0.6 m by the image border, give samples on no plane whose own normals tilt 6–16° toward the
/// camera: by the invalid pixels beyond the walls' ends, on the creases with the ceiling, and
/// elsewhere by noise shared across the block matcher's window. σ_Z is small there, and before
/// the structure check left such normals out (or paired them with a normal one window away)
/// 2 to 23 of them pinned the corridor's axis to about 2 mm: a tracked sequence drifted 2.6 m
/// along it while reported tracked (docs/bench/track.md, session 24).
#[test]
fn a_bare_corridor_is_a_degenerate_view_at_full_resolution() {
    let scene = named_scene("corridor").unwrap();
    let (cam, sim, filter) = realistic_preset("oak-d");
    // Views 0, 3, …, 12 of the corridor camera.
    let step = corridor_step();
    let prior = TrackerConfig::default().motion_prior_sigma_m();
    let mut pose = scene.pose;
    for i in 0..=12u64 {
        if i % 3 == 0 {
            let truth = scene.scene.render(&cam.intrinsics, &pose).depth;
            let with_end = filter.apply(&sim.apply(&truth, 100 + i)).unwrap();
            let mut bare = with_end.clone();
            // The end wall (4.5 m) out of range.
            for z in bare.data_mut() {
                if *z > 4.0 {
                    *z = 0.0;
                }
            }
            let first = |d: &DepthImage| {
                Tracker::new(cam, TrackerConfig::default())
                    .unwrap()
                    .track(d, None)
                    .unwrap()
            };
            let r = first(&bare);
            assert_eq!(
                r.status,
                TrackStatus::Lost,
                "view {i}: σ {} m",
                r.weakest_sigma_m
            );
            assert!(
                r.weakest_sigma_m > prior,
                "view {i}: {} vs {prior}",
                r.weakest_sigma_m
            );
            // With the end wall the view pins every direction.
            let r = first(&with_end);
            assert_eq!(
                r.status,
                TrackStatus::Initialised,
                "view {i}: {:?}",
                r.failure
            );
        }
        pose = pose * step;
    }
}

/// Rectangular simulated rooms of the room benchmark seen through a D435 (room 3003) and a
/// D415 (room 3004), tracked as `rooms_track --camera` does (frame to model, the tracker's
/// defaults): the view turns to mostly one wall, and the plane fallback's two frames cannot
/// tell the camera's own turn from the room turned by about 180°. Against the model the
/// camera's turn fails the degenerate-overlap check, while the turned room lands on another
/// part of the model, passes and even fits better. A pose from such a candidate was 2.2–2.7 m
/// and 180° off (session 84, before the rule that the planes' best must pass and every other
/// candidate fit clearly worse); every step reported tracked must be right within the room
/// benchmark's 2 cm and 1°.
#[test]
fn a_room_turned_by_180_degrees_is_not_taken_for_the_camera() {
    for (seed, preset, frames) in [(3003u64, "d435", 20u64), (3004, "d415", 12)] {
        let room = sl_noise::sim::room_scene(seed).unwrap();
        let (cam, sim) = room.camera_and_simulator(Some(preset)).unwrap();
        let k = cam.intrinsics;
        let mut tracker = Tracker::new(cam, TrackerConfig::default()).unwrap();
        let mut vcfg = TsdfConfig::default();
        vcfg.voxel_m = 0.008;
        vcfg.trunc_m = 0.04;
        vcfg.truncation = sl_tsdf::Truncation::sensor_adaptive(cam.sensor);
        let mut volume = TsdfVolume::new(vcfg).unwrap();
        let mut reference = ModelReference::new(
            &k,
            ModelReference::default_scale(&cam),
            RaycastConfig::default(),
        )
        .unwrap();
        let mut path = HandHeldPath::new(seed, 0.0);
        let mut pose = room.pose;
        let mut last: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
        let (mut fused, mut tracked) = (0usize, 0usize);
        for i in 0..frames {
            let d = sim.simulate(&room.scene, &k, &pose, seed * 1000 + i).depth;
            let model = if fused > 1 { reference.maps() } else { None };
            let r = tracker.track(&d, model).unwrap();
            if r.status.is_tracked() {
                volume.integrate(&d, &k, &r.pose).unwrap();
                fused += 1;
                tracked += 1;
                reference
                    .update_from_frame(&volume, &r.pose, &tracker.frame_sensor(), &d, &k)
                    .unwrap();
                if let Some((t, e)) = last {
                    let off = (t.inverse() * pose.isometry()).inverse()
                        * (e.inverse() * r.pose.isometry());
                    let (m, deg) = (
                        off.translation.vector.norm(),
                        off.rotation.angle().to_degrees(),
                    );
                    assert!(
                        m <= 0.02 && deg <= 1.0,
                        "room {seed} ({preset}) frame {i} {}: step off by {:.1} mm / {deg:.1}°",
                        r.status.as_str(),
                        m * 1e3
                    );
                }
                last = Some((*pose.isometry(), *r.pose.isometry()));
            }
            pose = path.advance(&pose);
        }
        assert!(tracked >= 3, "room {seed}: {tracked} frames tracked");
    }
}
