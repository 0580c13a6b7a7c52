//! `sldepth track --odometry FILE`: a camera sliding along a single wall, which the depth cannot
//! pin along the wall, tracked with an odometry that says how far it went.

use super::*;

/// Writes `n` frames of the simulated `wall` scene (320×240 Kinect) with the camera sliding
/// 1 cm per frame along the wall, as a TUM folder, and the odometry of that motion (3 % short)
/// as a TUM trajectory in a frame of its own, sampled at 100 Hz: the frames' timestamps.
fn write_wall_slide(dir: &Path, n: usize) -> (Vec<f64>, std::path::PathBuf) {
    let scene = named_scene("wall").unwrap();
    let k = scene.intrinsics.scaled(0.5).unwrap();
    let sim = KinectSimulator::kinect_v1();
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let mut list = String::from("# depth maps\n# timestamp filename\n");
    let mut stamps = Vec::new();
    for i in 0..n {
        let t = 100.0 + i as f64 / 30.0;
        let pose = scene.pose
            * CameraToCamera::from_isometry(Isometry3::translation(0.01 * i as f64, 0.0, 0.0));
        let depth = sim.simulate(&scene.scene, &k, &pose, i as u64).depth;
        let name = format!("depth/{t:.6}.png");
        write_depth(dir.join(&name), &depth, &DepthEncoding::tum()).unwrap();
        list.push_str(&format!("{t:.6} {name}\n"));
        stamps.push(t);
    }
    std::fs::write(dir.join("depth.txt"), list).unwrap();
    // The odometry: 0.3 m/s × 0.97 along its own y axis (the camera's x turned into it).
    let odometry = dir.join("odometry.txt");
    let mut text = String::from("# timestamp tx ty tz qx qy qz qw (camera to odometry)\n");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let mut t = 99.9;
    while t < 100.0 + n as f64 / 30.0 + 0.1 {
        let y = 0.3 * 0.97 * (t - 100.0).max(0.0);
        // The camera's x is the odometry's y: a quarter turn about z.
        text.push_str(&format!("{t:.3} 1.0 {y:.6} 0.5 0 0 {h} {h}\n"));
        t += 0.01;
    }
    std::fs::write(&odometry, text).unwrap();
    (stamps, odometry)
}

/// Without the odometry every frame is a degenerate view (lost, no pose written); with it every
/// frame is tracked, its position along the wall the odometry's (3 % short of the truth), and
/// the JSON says how many frames took a direction from it.
#[test]
fn track_takes_the_direction_a_wall_leaves_free_from_the_odometry() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("wall");
    let (stamps, odometry) = write_wall_slide(&seq, 6);
    let traj = dir.path().join("traj.txt");
    let traj_s = traj.to_str().unwrap();
    let (plain, _) = kinect_track_json(&seq, &["--output", traj_s]);
    assert_eq!(plain["lost"], 6, "{plain}");
    assert!(plain["odometry"].is_null());
    assert!(pose_rows(&traj).is_empty());
    let (json, stderr) = kinect_track_json(
        &seq,
        &["--output", traj_s, "--odometry", odometry.to_str().unwrap()],
    );
    assert_eq!(json["lost"], 0, "{json}\n{stderr}");
    let o = &json["odometry"];
    assert_eq!(o["frames_with_pose"], 6, "{o}");
    assert_eq!(o["prior_frames"], 5, "{o}");
    assert_eq!(o["weak_direction_from_odometry"], 5, "{o}");
    assert!(stderr.contains("6 frames predicted by it"), "{stderr}");
    let rows = pose_rows(&traj);
    assert_eq!(rows.len(), 6);
    for (i, (row, t)) in rows.iter().zip(&stamps).enumerate() {
        assert!((row[0] - t).abs() < 1e-6);
        // The first camera is the world frame: the slide is along its x, 9.7 mm a frame.
        let (x, y, z) = (row[1], row[2], row[3]);
        let want = 0.0097 * i as f64;
        assert!(
            (x - want).abs() < 5e-4 && y.abs() < 2e-3 && z.abs() < 2e-3,
            "frame {i}: ({x}, {y}, {z}), the odometry {want}"
        );
    }
}

/// Bad odometry options are refused before any frame is tracked: frames without timestamps,
/// `--odometry-tf` on a folder, numbers out of range, an empty file.
#[test]
fn track_refuses_odometry_it_cannot_use() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("wall");
    let (_, odometry) = write_wall_slide(&seq, 2);
    let fails = |extra: &[&str]| -> String {
        let mut args = vec![
            "track",
            "--tum",
            seq.to_str().unwrap(),
            "--camera",
            "kinect-v1",
        ];
        args.extend_from_slice(extra);
        let out = sldepth(&args);
        assert!(!out.status.success(), "{extra:?} succeeded");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let odo = odometry.to_str().unwrap();
    let e = fails(&["--odometry-tf", "odom"]);
    assert!(
        e.contains("--odometry-tf reads a recording's transforms"),
        "{e}"
    );
    let e = fails(&["--odometry", odo, "--odometry-drift", "1.5"]);
    assert!(e.contains("--odometry-drift"), "{e}");
    let e = fails(&["--odometry", odo, "--odometry-min-sigma-m", "0"]);
    assert!(e.contains("--odometry-min-sigma-m"), "{e}");
    let empty = dir.path().join("empty.txt");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let e = fails(&["--odometry", empty.to_str().unwrap()]);
    assert!(e.contains("no poses"), "{e}");
    let e = fails(&["--odometry", odo, "--odometry-tf", "odom"]);
    assert!(e.contains("cannot be used with"), "{e}");
}
