//! Hand-computed ATE / RPE cases, invariance under a rigid change of world frame, the
//! association rules and input errors.

use sl_core::CameraToWorld;
use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::*;

fn pose(t: [f64; 3], yaw_deg: f64) -> CameraToWorld {
    CameraToWorld::from_isometry(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
    ))
}

/// A wiggly trajectory of `n` poses, 30 Hz.
fn wiggly(n: usize) -> Vec<StampedPose> {
    (0..n)
        .map(|i| {
            let s = i as f64 * 0.1;
            let iso = Isometry3::new(
                Vector3::new(s.sin(), 0.3 * s, (0.7 * s).cos()),
                Vector3::new(0.2 * s.cos(), 0.5 * s, 0.1 * s),
            );
            (1000.0 + i as f64 / 30.0, CameraToWorld::from_isometry(iso))
        })
        .collect()
}

#[test]
fn a_rigidly_moved_trajectory_has_zero_ate_and_rpe() {
    let gt = wiggly(60);
    let t = Isometry3::new(Vector3::new(3.0, -1.0, 0.5), Vector3::new(0.4, -0.3, 1.1));
    let est: Vec<StampedPose> = gt
        .iter()
        .map(|(s, p)| (*s, CameraToWorld::from_isometry(t * p.isometry())))
        .collect();
    let cfg = TrajectoryConfig::default();
    let a = ate(&est, &gt, &cfg).unwrap();
    assert_eq!((a.matched, a.estimated, a.ground_truth), (60, 60, 60));
    assert!(
        a.stats_m.rmse < 1e-9 && a.stats_m.max < 1e-9,
        "{:?}",
        a.stats_m
    );
    // The alignment found is the inverse of the applied motion.
    let back = a.alignment.isometry() * t;
    assert!(back.translation.vector.norm() < 1e-9 && back.rotation.angle() < 1e-9);
    let r = rpe(&est, &gt, &cfg).unwrap();
    assert_eq!(r.pairs, 58); // i = 0..=57 (j = 59, the last pose, is skipped as in TUM)
    // acos((tr R − 1)/2) near 1 resolves angles only down to √(2·ε_f64) ≈ 2·10⁻⁸ rad.
    assert!(
        r.translation_m.max < 1e-9 && r.rotation_deg.max < 1e-5,
        "{r:?}"
    );
    let per_s = TrajectoryConfig {
        delta: 1.0,
        delta_unit: DeltaUnit::Seconds,
        ..cfg
    };
    let r = rpe(&est, &gt, &per_s).unwrap();
    assert!(r.pairs > 20 && r.translation_m.max < 1e-9);
}

#[test]
fn hand_worked_three_pose_ate() {
    // Ground truth on the x axis; the middle estimate 0.3 m off in y. After the best rigid
    // alignment (a translation by −0.1 m in y; rotations about x change nothing) the errors
    // are 0.1, 0.2 and 0.1 m.
    let gt = vec![
        (0.0, pose([0.0, 0.0, 0.0], 0.0)),
        (0.1, pose([1.0, 0.0, 0.0], 0.0)),
        (0.2, pose([2.0, 0.0, 0.0], 0.0)),
    ];
    let est = vec![
        (0.0, pose([0.0, 0.0, 0.0], 5.0)),
        (0.1, pose([1.0, 0.3, 0.0], 0.0)),
        (0.2, pose([2.0, 0.0, 0.0], -3.0)),
    ];
    let a = ate(&est, &gt, &TrajectoryConfig::default()).unwrap();
    let s = a.stats_m;
    assert_eq!(s.count, 3);
    assert!((s.rmse - 0.02f64.sqrt()).abs() < 1e-12, "{s:?}");
    assert!((s.mean - 0.4 / 3.0).abs() < 1e-12);
    assert!((s.median - 0.1).abs() < 1e-12);
    assert!((s.max - 0.2).abs() < 1e-12 && (s.min - 0.1).abs() < 1e-12);
    // Per pose, in time order: the same distances. (The ground truth is a line, so the
    // alignment may turn the estimate half a turn about it; the orientations' errors are
    // tested on a trajectory that pins the alignment, below.)
    let per: Vec<(f64, f64, f64)> = a
        .per_pose
        .iter()
        .map(|p| (p.timestamp_s, p.ground_truth_timestamp_s, p.translation_m))
        .collect();
    assert_eq!(per.len(), 3);
    for (got, want) in per.iter().zip([(0.0, 0.1), (0.1, 0.2), (0.2, 0.1)]) {
        assert_eq!((got.0, got.1), (want.0, want.0), "{per:?}");
        assert!((got.2 - want.1).abs() < 1e-12, "{per:?}");
    }
}

/// A camera that keeps one orientation while it moves, estimated with the right positions and
/// four orientations turned about its y axis by ±7.5° and ±30°: the turns cancel in the
/// orientations' fit of the world (its rotation is the identity), so each pose's rotation error
/// is its own turn, and the ATE is zero.
#[test]
fn hand_worked_per_pose_rotation_errors() {
    let facing = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1);
    let gt: Vec<StampedPose> = wiggly(30)
        .into_iter()
        .map(|(s, p)| {
            let iso = Isometry3::from_parts(p.isometry().translation, facing);
            (s, CameraToWorld::from_isometry(iso))
        })
        .collect();
    let turns = [(4, 7.5), (11, -7.5), (20, 30.0), (25, -30.0)];
    let turn_of = |i: usize| turns.iter().find(|t| t.0 == i).map_or(0.0, |t| t.1);
    let est: Vec<StampedPose> = gt
        .iter()
        .enumerate()
        .map(|(i, (s, p))| {
            let turn =
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), f64::to_radians(turn_of(i)));
            let mut iso = *p.isometry();
            iso.rotation *= turn;
            (*s, CameraToWorld::from_isometry(iso))
        })
        .collect();
    let a = ate(&est, &gt, &TrajectoryConfig::default()).unwrap();
    assert!(a.stats_m.max < 1e-9);
    for (i, p) in a.per_pose.iter().enumerate() {
        let want = turn_of(i).abs();
        assert!((p.rotation_deg - want).abs() < 1e-6, "pose {i}: {p:?}");
    }
}

/// The per-pose errors of a rigidly moved trajectory are all zero, one per matched pose, in
/// the estimate's time order and with its own timestamps (before a clock offset), however
/// the estimate was ordered.
#[test]
fn per_pose_errors_follow_the_estimates_own_clock() {
    let gt = wiggly(40);
    let t = Isometry3::new(Vector3::new(-2.0, 0.5, 1.0), Vector3::new(0.1, 0.7, -0.4));
    // 25 ms late, listed backwards.
    let est: Vec<StampedPose> = gt
        .iter()
        .rev()
        .map(|(s, p)| (s + 0.025, CameraToWorld::from_isometry(t * p.isometry())))
        .collect();
    let cfg = TrajectoryConfig {
        offset_s: -0.025,
        ..TrajectoryConfig::default()
    };
    let a = ate(&est, &gt, &cfg).unwrap();
    assert_eq!(a.per_pose.len(), 40);
    for (p, (s, _)) in a.per_pose.iter().zip(&gt) {
        assert_eq!(p.timestamp_s, s + 0.025);
        assert_eq!(p.ground_truth_timestamp_s, *s);
        assert!(p.translation_m < 1e-9 && p.rotation_deg < 1e-5, "{p:?}");
    }
}

#[test]
fn a_constant_world_offset_is_removed_by_the_alignment_but_scale_is_not() {
    let gt = wiggly(40);
    let shifted: Vec<StampedPose> = gt
        .iter()
        .map(|(s, p)| {
            let mut iso = *p.isometry();
            iso.translation.vector += Vector3::new(0.5, 0.0, -0.2);
            (*s, CameraToWorld::from_isometry(iso))
        })
        .collect();
    let cfg = TrajectoryConfig::default();
    assert!(ate(&shifted, &gt, &cfg).unwrap().stats_m.rmse < 1e-9);
    // Positions scaled by 1.1 about their centroid: no rigid motion removes that, and the
    // residual of each pose is 0.1 of its distance from the centroid.
    let n = gt.len() as f64;
    let c = gt
        .iter()
        .fold(Vector3::zeros(), |a, (_, p)| a + p.translation())
        / n;
    let scaled: Vec<StampedPose> = gt
        .iter()
        .map(|(s, p)| {
            let mut iso = *p.isometry();
            iso.translation.vector = c + (p.translation() - c) * 1.1;
            (*s, CameraToWorld::from_isometry(iso))
        })
        .collect();
    let expect = (gt
        .iter()
        .map(|(_, p)| (0.1 * (p.translation() - c).norm()).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let got = ate(&scaled, &gt, &cfg).unwrap().stats_m.rmse;
    assert!((got - expect).abs() < 1e-9, "{got} vs {expect}");
}

#[test]
fn hand_worked_rpe_translation_and_rotation() {
    // Four poses 1 m apart on x at 10 Hz; the second estimate is 0.3 m off in y. Per frame the
    // pairs are (0, 1) and (1, 2) ((2, 3) ends at the last pose, which TUM skips); each
    // relative motion is off by 0.3 m.
    let gt: Vec<StampedPose> = (0..4)
        .map(|i| (0.1 * i as f64, pose([i as f64, 0.0, 0.0], 0.0)))
        .collect();
    let mut est = gt.clone();
    est[1].1 = pose([1.0, 0.3, 0.0], 0.0);
    let r = rpe(&est, &gt, &TrajectoryConfig::default()).unwrap();
    assert_eq!(r.pairs, 2);
    assert!(
        (r.translation_m.rmse - 0.3).abs() < 1e-12,
        "{:?}",
        r.translation_m
    );
    assert!(r.rotation_deg.max < 1e-9);
    assert!((r.max_gap_s - 0.2).abs() < 1e-12);

    // Estimates yawed by 10° more at every pose: each relative rotation is off by 10°, and
    // E = Δ_est⁻¹·Δ_gt has translation R₀ᵀ(R₁ − I)(t₀ − t₁), of length 2·sin(θ₁/2)·1 m with
    // θ₁ = 10°·(i + 1) the yaw of the pair's second pose.
    let gt: Vec<StampedPose> = (0..6)
        .map(|i| (0.1 * i as f64, pose([i as f64, 0.0, 0.0], 0.0)))
        .collect();
    let est: Vec<StampedPose> = (0..6)
        .map(|i| (0.1 * i as f64, pose([i as f64, 0.0, 0.0], 10.0 * i as f64)))
        .collect();
    let r = rpe(&est, &gt, &TrajectoryConfig::default()).unwrap();
    assert_eq!(r.pairs, 4);
    assert!((r.rotation_deg.min - 10.0).abs() < 1e-9 && (r.rotation_deg.max - 10.0).abs() < 1e-9);
    let expect: Vec<f64> = (1..=4)
        .map(|j| 2.0 * (10f64 * j as f64 / 2.0).to_radians().sin())
        .collect();
    let e = ErrorStats::of(&expect);
    assert!((r.translation_m.rmse - e.rmse).abs() < 1e-12);
    assert!((r.translation_m.max - e.max).abs() < 1e-12);

    // Per second with delta 0.3 s: pairs (0, 3), (1, 4); (2, 5) ends at the last pose.
    let cfg = TrajectoryConfig {
        delta: 0.3,
        delta_unit: DeltaUnit::Seconds,
        ..TrajectoryConfig::default()
    };
    let r = rpe(&est, &gt, &cfg).unwrap();
    assert_eq!(r.pairs, 2);
    assert!((r.rotation_deg.mean - 30.0).abs() < 1e-9);
}

#[test]
fn association_is_greedy_by_time_difference_within_the_gap() {
    let p = pose([0.0; 3], 0.0);
    let gt = vec![(0.0, p), (0.015, p), (1.0, p)];
    let est = vec![(0.01, p), (0.99, p), (2.0, p)];
    // 0.01 is closer to 0.015 (5 ms) than to 0.0 (10 ms); 2.0 has no partner.
    assert_eq!(associate(&gt, &est, 0.02), vec![(1, 0), (2, 1)]);
    // A gap of 10 ms excludes the 10 ms pair but not the 5 ms one.
    assert_eq!(associate(&gt, &est, 0.006), vec![(1, 0)]);
    // Each pose at most once: two estimates near one ground-truth stamp.
    let est = vec![(0.001, p), (0.002, p)];
    assert_eq!(associate(&gt, &est, 0.02), vec![(0, 0), (1, 1)]);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let gt = wiggly(10);
    let cfg = TrajectoryConfig::default();
    // Empty, too short, no overlap.
    assert!(ate(&[], &gt, &cfg).is_err());
    assert!(rpe(&gt[..1], &gt, &cfg).is_err());
    let late: Vec<StampedPose> = gt.iter().map(|(s, p)| (s + 100.0, *p)).collect();
    assert!(ate(&late, &gt, &cfg).is_err());
    assert!(rpe(&late, &gt, &cfg).is_err());
    // Duplicate and non-finite timestamps.
    let mut dup = gt.clone();
    dup[3].0 = dup[2].0;
    assert!(ate(&dup, &gt, &cfg).is_err());
    let mut nan = gt.clone();
    nan[0].0 = f64::NAN;
    assert!(rpe(&gt, &nan, &cfg).is_err());
    // Bad configuration.
    let bad = TrajectoryConfig {
        max_gap_s: -1.0,
        ..cfg
    };
    assert!(ate(&gt, &gt, &bad).is_err());
    let bad = TrajectoryConfig { delta: 1.5, ..cfg };
    assert!(bad.validate().is_err());
    assert!(DeltaUnit::parse("minutes").is_err());
    // Unordered input is sorted first.
    let mut rev = gt.clone();
    rev.reverse();
    assert!(ate(&rev, &gt, &cfg).unwrap().stats_m.rmse < 1e-12);
}

/// A camera turning about varying axes at up to ~100 °/s: its ground truth sampled at 1 kHz,
/// and its poses at 25 Hz frame stamps `lag_s` later than the instants they show.
fn turning_camera(lag_s: f64) -> (Vec<StampedPose>, Vec<StampedPose>) {
    let at = |t: f64| {
        let iso = Isometry3::new(
            Vector3::new(0.1 * t.sin(), 0.05 * t, 0.02 * (2.0 * t).cos()),
            Vector3::new(
                0.6 * (1.3 * t).sin(),
                1.2 * (0.9 * t).cos(),
                0.8 * (1.7 * t).sin(),
            ),
        );
        CameraToWorld::from_isometry(iso)
    };
    let gt = (0..6000)
        .map(|i| {
            let t = 100.0 + i as f64 * 0.001;
            (t, at(t))
        })
        .collect();
    let est = (0..140)
        .map(|i| {
            let t = 100.2 + i as f64 * 0.04;
            (t + lag_s, at(t))
        })
        .collect();
    (gt, est)
}

#[test]
fn a_clock_offset_is_found_and_undone() {
    let (gt, est) = turning_camera(0.02);
    let cfg = TrajectoryConfig::default();
    let found = estimate_time_offset(&est, &gt, &cfg, &OffsetSearch::default()).unwrap();
    assert!((found.offset_s + 0.02).abs() < 1e-9, "{found:?}");
    assert!(found.rotation_rmse_deg < 1e-5, "{found:?}");
    assert_eq!(found.matched, 140);
    // The 20 ms lag at tens of degrees a second costs about a degree per pose.
    assert!(found.rotation_rmse_at_zero_deg > 0.5, "{found:?}");
    assert_eq!(found.curve.len(), 201);
    // Applied, the ATE and RPE vanish; without it they do not.
    let shifted = TrajectoryConfig {
        offset_s: found.offset_s,
        ..cfg
    };
    assert!(ate(&est, &gt, &shifted).unwrap().stats_m.rmse < 1e-9);
    assert!(rpe(&est, &gt, &shifted).unwrap().rotation_deg.max < 1e-5);
    let unshifted = ate(&est, &gt, &cfg).unwrap();
    assert!(unshifted.stats_m.rmse > 1e-4);
    // The per-pose orientation errors are the offset search's: their RMS at no offset.
    let rms = (unshifted
        .per_pose
        .iter()
        .map(|p| p.rotation_deg.powi(2))
        .sum::<f64>()
        / unshifted.per_pose.len() as f64)
        .sqrt();
    assert!(
        (rms - found.rotation_rmse_at_zero_deg).abs() < 1e-9,
        "{rms} {found:?}"
    );
    // The same lag the other way, and none.
    let (gt, est) = turning_camera(-0.035);
    let found = estimate_time_offset(&est, &gt, &cfg, &OffsetSearch::default()).unwrap();
    assert!((found.offset_s - 0.035).abs() < 1e-9, "{found:?}");
    let (gt, est) = turning_camera(0.0);
    let found = estimate_time_offset(&est, &gt, &cfg, &OffsetSearch::default()).unwrap();
    assert_eq!(found.offset_s, 0.0);
    // A different world frame for the estimate changes nothing.
    let t = Isometry3::new(Vector3::new(3.0, -1.0, 0.5), Vector3::new(0.4, -0.3, 1.1));
    let (gt, est) = turning_camera(0.02);
    let moved: Vec<StampedPose> = est
        .iter()
        .map(|(s, p)| (*s, CameraToWorld::from_isometry(t * p.isometry())))
        .collect();
    let found = estimate_time_offset(&moved, &gt, &cfg, &OffsetSearch::default()).unwrap();
    assert!((found.offset_s + 0.02).abs() < 1e-9, "{found:?}");
}

#[test]
fn bad_offsets_are_errors() {
    let (gt, est) = turning_camera(0.0);
    let bad = |offset_s: f64| TrajectoryConfig {
        offset_s,
        ..TrajectoryConfig::default()
    };
    for o in [f64::NAN, f64::INFINITY, 61.0, -61.0] {
        assert!(ate(&est, &gt, &bad(o)).is_err(), "{o}");
        assert!(rpe(&est, &gt, &bad(o)).is_err(), "{o}");
    }
    let cfg = TrajectoryConfig::default();
    for (max_s, step_s) in [
        (0.1, 0.0),
        (0.1, -1.0),
        (f64::NAN, 0.001),
        (100.0, 0.1),
        (1.0, 1e-9),
    ] {
        let s = OffsetSearch { max_s, step_s };
        assert!(
            estimate_time_offset(&est, &gt, &cfg, &s).is_err(),
            "{max_s} {step_s}"
        );
    }
    // Offsets that move the estimate off the ground truth's time span are skipped; none left
    // is an error.
    let far = OffsetSearch {
        max_s: 50.0,
        step_s: 10.0,
    };
    let found = estimate_time_offset(&est, &gt, &cfg, &far).unwrap();
    assert_eq!(found.offset_s, 0.0);
    assert_eq!(found.curve.len(), 1);
    let late: Vec<StampedPose> = est.iter().map(|(s, p)| (s + 30.0, *p)).collect();
    assert!(estimate_time_offset(&late, &gt, &cfg, &OffsetSearch::default()).is_err());
}

#[test]
fn a_pair_is_a_pose_and_a_strictly_later_one() {
    let gt = wiggly(60);
    let msg = |delta: f64, delta_unit: DeltaUnit| -> String {
        let cfg = TrajectoryConfig {
            delta,
            delta_unit,
            ..TrajectoryConfig::default()
        };
        rpe(&gt, &gt, &cfg).unwrap_err().to_string()
    };
    // So long that `i + delta` rounds to `delta`, whose nearest pose by TUM's bisection is the
    // first: each pose was paired with pose 0 (an RPE of the trajectory run backwards).
    for unit in [DeltaUnit::Frames, DeltaUnit::Seconds] {
        let e = msg(1e20, unit);
        assert!(
            e.contains("only 0 pose pairs 1e20") && e.contains(unit.name()),
            "{e}"
        );
        assert!(e.contains("too short a trajectory for delta = 1e20"), "{e}");
    }
    // Shorter than the poses' 1/30 s spacing: each pose was its own pair, an RPE of 0.
    let e = msg(0.001, DeltaUnit::Seconds);
    assert!(
        e.contains("delta = 0.001 seconds is shorter than the spacing"),
        "{e}"
    );
    // Just over half the spacing pairs neighbours, as before.
    let cfg = TrajectoryConfig {
        delta: 0.02,
        delta_unit: DeltaUnit::Seconds,
        ..TrajectoryConfig::default()
    };
    assert_eq!(rpe(&gt, &gt, &cfg).unwrap().pairs, 58);
}
