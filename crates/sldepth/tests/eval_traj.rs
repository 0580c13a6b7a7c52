//! End-to-end tests of `sldepth eval-traj`: a hand-worked trajectory pair (text and JSON), each
//! pose's error (`--per-pose`), a rigidly moved copy, a clock offset given and measured, and clear errors on bad input.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

mod common;
use common::sldepth;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

/// Four poses 1 m apart on x at 10 Hz, identity rotations; `dy` moves the second in y.
fn four_poses(dy: f64) -> String {
    let mut s = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for i in 0..4 {
        let y = if i == 1 { dy } else { 0.0 };
        s += &format!("{:.6} {i}.0 {y} 0.0 0 0 0 1\n", 100.0 + 0.1 * i as f64);
    }
    s
}

#[test]
fn eval_traj_reports_hand_worked_ate_and_rpe() {
    let dir = tempfile::tempdir().unwrap();
    let gt = write(dir.path(), "gt.txt", &four_poses(0.0));
    let est = write(dir.path(), "est.txt", &four_poses(0.3));
    let o = sldepth(&["eval-traj", &est, &gt, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["poses_matched"], 4);
    // Per frame, pairs (0, 1) and (1, 2) (TUM skips the pair ending at the last pose): each
    // relative motion is 0.3 m off, with no rotation error.
    assert_eq!(j["rpe"]["pairs"], 2);
    assert_eq!(j["rpe"]["translation_m"]["rmse"], 0.3);
    assert_eq!(j["rpe"]["rotation_deg"]["max"], 0.0);
    // ATE: positions (0,0), (1,0.3), (2,0), (3,0) against the x axis. The best rigid alignment
    // is a small rotation plus a shift; its RMSE is below the 0.3 m / √4 = 0.15 m of the
    // unaligned error and above zero.
    let ate = j["ate_m"]["rmse"].as_f64().unwrap();
    assert!(ate > 0.05 && ate < 0.15, "{ate}");
    // Text output names both metrics.
    let o = sldepth(&["eval-traj", &est, &gt]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("ATE") && text.contains("RPE"),
        "{text}"
    );
}

/// `--per-pose`: one line per matched pose, in time order, the displaced pose the largest,
/// matching the JSON's worst pose and `ate_m.max`; a file name that is not `.txt`, or an input,
/// is refused before anything is read.
#[test]
fn eval_traj_writes_each_poses_error() {
    let dir = tempfile::tempdir().unwrap();
    let gt = write(dir.path(), "gt.txt", &four_poses(0.0));
    let est = write(dir.path(), "est.txt", &four_poses(0.3));
    let out = dir.path().join("per-pose.txt");
    let o = sldepth(&[
        "eval-traj",
        &est,
        &gt,
        "--json",
        "--per-pose",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 4, "{text}");
    for (i, r) in rows.iter().enumerate() {
        let t = 100.0 + 0.1 * i as f64;
        assert_eq!(r.len(), 4, "{text}");
        assert!((r[0] - t).abs() < 1e-9 && (r[1] - t).abs() < 1e-9, "{text}");
        // Identity orientations everywhere: no rotation error.
        assert_eq!(r[3], 0.0, "{text}");
    }
    let worst = rows.iter().max_by(|a, b| a[2].total_cmp(&b[2])).unwrap();
    assert!((worst[0] - 100.1).abs() < 1e-9, "{text}");
    let max = j["ate_m"]["max"].as_f64().unwrap();
    assert!((worst[2] - max).abs() < 2e-6, "{text} {max}");
    assert_eq!(j["ate_worst_pose"]["timestamp"], 100.1);
    assert_eq!(j["per_pose"], out.to_str().unwrap());
    // Text mode names the worst pose.
    let o = sldepth(&["eval-traj", &est, &gt]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("largest at the estimate's timestamp 100.100000"),
        "{text}"
    );
    // Refused up front: another format, and an input as the output (left as it was).
    for bad in [dir.path().join("e.csv").to_str().unwrap(), est.as_str()] {
        let o = sldepth(&["eval-traj", &est, &gt, "--per-pose", bad]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("--per-pose"), "{err}");
    }
    assert_eq!(std::fs::read_to_string(&est).unwrap(), four_poses(0.3));
}

#[test]
fn eval_traj_of_a_moved_copy_is_zero_and_per_second_works() {
    let dir = tempfile::tempdir().unwrap();
    let (mut gt, mut est) = (String::new(), String::new());
    for i in 0..90 {
        let s = i as f64 / 30.0;
        let (x, y, z) = (s.sin(), 0.2 * s, (0.5 * s).cos());
        let h = 0.3 * s; // yaw, half angle h/2 in the quaternion
        let (qz, qw) = ((h / 2.0).sin(), (h / 2.0).cos());
        gt += &format!("{s:.6} {x} {y} {z} 0 0 {qz} {qw}\n");
        // The same trajectory in a world frame moved by 2 m in x and turned 90° about z:
        // (x, y) -> (−y + 2, x), yaw + 90°.
        let h2 = h + std::f64::consts::FRAC_PI_2;
        est += &format!(
            "{s:.6} {} {x} {z} 0 0 {} {}\n",
            2.0 - y,
            (h2 / 2.0).sin(),
            (h2 / 2.0).cos()
        );
    }
    let gt = write(dir.path(), "gt.txt", &gt);
    let est = write(dir.path(), "est.txt", &est);
    let o = sldepth(&[
        "eval-traj",
        &est,
        &gt,
        "--json",
        "--delta",
        "1",
        "--delta-unit",
        "seconds",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["poses_matched"], 90);
    assert!(j["ate_m"]["max"].as_f64().unwrap() < 1e-5);
    assert!(j["rpe"]["translation_m"]["max"].as_f64().unwrap() < 1e-5);
    assert_eq!(j["rpe"]["delta_unit"], "seconds");
}

/// A camera yawing back and forth (±60° at 0.5 Hz) while moving along x: its ground truth at
/// 1 kHz and its frames at 25 Hz, stamped `lag_s` after the instants they show.
fn swinging_camera(lag_s: f64) -> (String, String) {
    let line = |stamp: f64, t: f64| {
        let h = 60f64.to_radians() * (std::f64::consts::PI * t).sin();
        format!(
            "{stamp:.6} {} 0 0 0 0 {} {}\n",
            0.1 * t,
            (h / 2.0).sin(),
            (h / 2.0).cos()
        )
    };
    let gt: String = (0..4000)
        .map(|i| {
            let t = i as f64 * 0.001;
            line(100.0 + t, t)
        })
        .collect();
    let est: String = (0..90)
        .map(|i| {
            let t = 0.2 + i as f64 * 0.04;
            line(100.0 + t + lag_s, t)
        })
        .collect();
    (gt, est)
}

#[test]
fn eval_traj_applies_and_measures_a_clock_offset() {
    let dir = tempfile::tempdir().unwrap();
    let (gt, est) = swinging_camera(0.03);
    let gt = write(dir.path(), "gt.txt", &gt);
    let est = write(dir.path(), "est.txt", &est);
    let json = |args: &[&str]| -> serde_json::Value {
        let o = sldepth(args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    // Without the offset, each frame is compared with the pose 30 ms later: up to ~6° off.
    let j = json(&["eval-traj", &est, &gt, "--json"]);
    assert_eq!(j["offset_s"], 0.0);
    assert!(j["offset_estimate"].is_null());
    assert!(
        j["rpe"]["rotation_deg"]["max"].as_f64().unwrap() > 0.5,
        "{j}"
    );
    // Given, the frames meet their instants.
    let j = json(&["eval-traj", &est, &gt, "--json", "--offset-ms", "-30"]);
    assert_eq!(j["offset_s"], -0.03);
    assert!(j["ate_m"]["max"].as_f64().unwrap() < 1e-5, "{j}");
    assert!(
        j["rpe"]["rotation_deg"]["max"].as_f64().unwrap() < 1e-3,
        "{j}"
    );
    // Measured, the same.
    let j = json(&["eval-traj", &est, &gt, "--json", "--estimate-offset"]);
    assert_eq!(j["offset_s"], -0.03, "{j}");
    assert_eq!(j["offset_estimate"]["offset_s"], -0.03);
    assert_eq!(j["offset_estimate"]["matched"], 90);
    assert!(
        j["offset_estimate"]["rotation_rmse_at_zero_deg"]
            .as_f64()
            .unwrap()
            > 1.0
    );
    assert!(j["ate_m"]["max"].as_f64().unwrap() < 1e-5);
    let o = sldepth(&["eval-traj", &est, &gt, "--estimate-offset"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("clock offset -30 ms"), "{text}");
    // Beyond the search range it is not found.
    let j = json(&[
        "eval-traj",
        &est,
        &gt,
        "--json",
        "--estimate-offset",
        "--offset-search-ms",
        "10",
    ]);
    assert_eq!(j["offset_s"], -0.01, "{j}");
}

#[test]
fn eval_traj_errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let gt = write(dir.path(), "gt.txt", &four_poses(0.0));
    let bad = write(dir.path(), "bad.txt", "1.0 0 0 0 0 0 0\n");
    let late = write(
        dir.path(),
        "late.txt",
        "500.0 0 0 0 0 0 0 1\n501.0 0 0 0 0 0 0 1\n502.0 0 0 0 0 0 0 1\n",
    );
    let dup = write(
        dir.path(),
        "dup.txt",
        "100.0 0 0 0 0 0 0 1\n100.0 1 0 0 0 0 0 1\n100.1 1 0 0 0 0 0 1\n",
    );
    let one = write(dir.path(), "one.txt", "100.0 0 0 0 0 0 0 1\n");
    let cases: [(&[&str], &str); 14] = [
        (&["eval-traj", &one, &gt], "at least two poses"),
        (
            &["eval-traj", "/nonexistent/est.txt", &gt],
            "/nonexistent/est.txt",
        ),
        (&["eval-traj", &bad, &gt], "bad.txt"),
        (&["eval-traj", &late, &gt], "right files"),
        (&["eval-traj", &dup, &gt], "twice"),
        (&["eval-traj", &gt, &gt, "--max-gap-s", "0"], "max_gap_s"),
        (
            &["eval-traj", &gt, &gt, "--delta-unit", "minutes"],
            "minutes",
        ),
        (
            &["eval-traj", &gt, &gt, "--offset-ms", "nan"],
            "--offset-ms NaN: must be finite and at most 60000 ms either way",
        ),
        (
            &["eval-traj", &gt, &gt, "--offset-ms", "1e300"],
            "--offset-ms 1e300: must be finite and at most 60000 ms",
        ),
        // Without --estimate-offset the range would be ignored.
        (
            &["eval-traj", &gt, &gt, "--offset-search-ms", "10"],
            "--offset-search-ms applies to --estimate-offset",
        ),
        // A pair is a pose and a strictly later one: a delta so long that `i + delta` rounds
        // paired every pose with the first, one shorter than the spacing each with itself.
        (
            &["eval-traj", &gt, &gt, "--delta", "1e20"],
            "--delta 1e20 frames",
        ),
        (
            &[
                "eval-traj",
                &gt,
                &gt,
                "--delta",
                "1e20",
                "--delta-unit",
                "seconds",
            ],
            "--delta 1e20 seconds",
        ),
        (
            &[
                "eval-traj",
                &gt,
                &gt,
                "--delta",
                "0.001",
                "--delta-unit",
                "s",
            ],
            "delta = 0.001 seconds is shorter than the spacing",
        ),
        (
            &[
                "eval-traj",
                &gt,
                &gt,
                "--estimate-offset",
                "--offset-search-ms",
                "-5",
            ],
            "offset search",
        ),
    ];
    for (args, needle) in cases {
        let o = sldepth(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// Four poses as an Open3D `.log` (entries `i i n`, camera to world), the second moved by `dy`.
fn four_poses_log(dy: f64, second_j: usize) -> String {
    let mut s = String::new();
    for i in 0..4 {
        let y = if i == 1 { dy } else { 0.0 };
        let j = if i == 1 { second_j } else { i };
        s += &format!("{i} {j} 4\n1 0 0 {i}\n0 1 0 {y}\n0 0 1 0\n0 0 0 1\n");
    }
    s
}

/// An Open3D `.log` is read with its frame numbers as timestamps, either side: against the
/// frame-numbered TUM file of the same poses it gives what the TUM pair gives; a pairwise
/// registration log (`i j n`, j ≠ i) is refused, saying why.
#[test]
fn eval_traj_reads_open3d_logs_by_frame_number() {
    let dir = tempfile::tempdir().unwrap();
    let numbered = |dy: f64| -> String {
        let mut s = String::new();
        for i in 0..4 {
            let y = if i == 1 { dy } else { 0.0 };
            s += &format!("{i} {i}.0 {y} 0.0 0 0 0 1\n");
        }
        s
    };
    let gt_txt = write(dir.path(), "gt.txt", &numbered(0.0));
    let est_txt = write(dir.path(), "est.txt", &numbered(0.3));
    let gt_log = write(dir.path(), "gt.log", &four_poses_log(0.0, 1));
    let est_log = write(dir.path(), "est.LOG", &four_poses_log(0.3, 1));
    let run = |est: &str, gt: &str| -> serde_json::Value {
        let o = sldepth(&["eval-traj", est, gt, "--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let reference = run(&est_txt, &gt_txt);
    assert_eq!(reference["poses_matched"], 4);
    assert!(reference["ate_m"]["rmse"].as_f64().unwrap() > 0.05);
    for (est, gt) in [
        (&est_log, &gt_log),
        (&est_txt, &gt_log),
        (&est_log, &gt_txt),
    ] {
        let j = run(est, gt);
        assert_eq!(j["poses_matched"], 4, "{est} {gt}");
        assert_eq!(j["ate_m"], reference["ate_m"], "{est} {gt}");
        assert_eq!(j["rpe"], reference["rpe"], "{est} {gt}");
    }
    let pairwise = write(dir.path(), "odometry.log", &four_poses_log(0.0, 2));
    let o = sldepth(&["eval-traj", &est_txt, &pairwise]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("`1 2 4`") && err.contains("relates two frames"),
        "{err}"
    );
}
