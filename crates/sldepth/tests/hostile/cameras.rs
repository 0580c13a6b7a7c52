//! Cameras: huge, absurd, misspelt or missing camera files and sensor numbers.

use super::*;

#[test]
fn huge_camera_is_refused_at_load_before_simulate_allocates() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim.png");
    for side in [65536, 16384] {
        let cam = camera_json(dir.path(), side, side, 500.0);
        let o = run_bounded(&[
            "simulate",
            "--scene",
            "floor",
            "--camera",
            s(&cam),
            "-o",
            s(&out),
        ]);
        assert_typed_error(&o, &["too large", &format!("{side}x{side}")]);
        assert!(!out.exists());
    }
}

#[test]
fn absurd_camera_numbers_are_refused_with_the_valid_range() {
    let dir = tempfile::tempdir().unwrap();
    let cam = camera_json(dir.path(), 640, 480, 1e308);
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&cam),
    ]);
    assert_typed_error(&o, &["fx", "must be in [1, 1e7] pixels"]);
}

/// A camera file that misspells a sensor key is refused by every command that reads it, naming
/// the key: `"baseline": 0.2` used to be ignored and the Kinect's 75 mm used without a word.
#[test]
fn a_misspelt_camera_sensor_key_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let cam = dir.path().join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [580, 0, 0, 0, 580, 0, 319.5, 239.5, 1], "baseline": 0.2}"#,
    )
    .unwrap();
    let depth = testdata("floor-seed1-depth.png");
    for cmd in ["info", "analyze", "noise-stats"] {
        let o = run(&[cmd, s(&depth), "--camera", s(&cam)]);
        assert_typed_error(
            &o,
            &["cam.json", "unknown key \"baseline\"", "`baseline_m`"],
        );
    }
}

/// A camera the prefilter cannot serve is named with its numbers compact: a 1e-300 m baseline
/// was printed as a 300-digit decimal.
#[test]
fn track_names_an_absurd_camera_compactly() {
    let dir = tempfile::tempdir().unwrap();
    let cam = dir.path().join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 32, 24, 1], "baseline_m": 1e-300}"#,
    )
    .unwrap();
    let seq = dir.path().join("seq");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let depth = sl_core::DepthImage::from_vec(64, 48, vec![1.5; 64 * 48]).unwrap();
    sl_io::write_depth(
        seq.join("depth/0.png"),
        &depth,
        &sl_io::DepthEncoding::default(),
    )
    .unwrap();
    let o = run(&["track", "--o3d", s(&seq), "--camera", s(&cam)]);
    assert_typed_error(&o, &["B = 1e-300 m", "--prefilter none skips it"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("0000000000"), "{stderr}");
}

/// A camera file that is a directory is an error, not a silent fall-back to the default
/// camera; a focal length below one pixel, a sub-pixel count beyond any matcher's and an
/// absurd trajectory position are refused with their range.
#[test]
fn a_camera_that_is_no_file_and_absurd_sensor_numbers_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // Its frame `d.png` (64x48 at 1.5 m).
    small_sequence(dir.path());
    let log_dir = dir.path().join("o3d");
    std::fs::create_dir_all(log_dir.join("camera.json")).unwrap();
    std::fs::create_dir_all(log_dir.join("depth")).unwrap();
    std::fs::copy(dir.path().join("d.png"), log_dir.join("depth/0.png")).unwrap();
    std::fs::write(
        log_dir.join("traj.log"),
        "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    let mesh = dir.path().join("m.ply");
    let o = run(&[
        "fuse",
        "--o3d-log",
        s(&log_dir.join("traj.log")),
        "--depth-dir",
        s(&log_dir.join("depth")),
        "-o",
        s(&mesh),
    ]);
    assert_typed_error(&o, &["camera.json", "not a regular file"]);
    assert!(!mesh.exists());
    // A folder named like a preset does not hide the preset.
    std::fs::create_dir(dir.path().join("kinect-v1")).unwrap();
    let o = Command::new(bin())
        .current_dir(dir.path())
        .args([
            "info",
            s(&testdata("floor-seed1-depth.png")),
            "--camera",
            "kinect-v1",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tiny = camera_json(dir.path(), 640, 480, 1e-300);
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&tiny),
    ]);
    assert_typed_error(&o, &["fx", "must be in [1, 1e7] pixels"]);
    let q = dir.path().join("q.json");
    std::fs::write(
        &q,
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 320, 240, 1], "subpixel": 4294967295}"#,
    )
    .unwrap();
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&q),
    ]);
    assert_typed_error(&o, &["sub-pixel steps", "1..=256"]);
    let far = dir.path().join("far.txt");
    let near = dir.path().join("near.txt");
    let pose = |t: f64, x: f64| format!("{t} {x} 0 0 0 0 0 1\n");
    std::fs::write(
        &far,
        pose(1.0, 1e200) + &pose(2.0, 2e200) + &pose(3.0, 3e200),
    )
    .unwrap();
    std::fs::write(&near, pose(1.0, 0.0) + &pose(2.0, 0.1) + &pose(3.0, 0.2)).unwrap();
    let o = run(&["eval-traj", s(&far), s(&near)]);
    assert_typed_error(&o, &["from the origin", "beyond 1e9 m"]);
}
