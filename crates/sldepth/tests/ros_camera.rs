//! `--camera` with a ROS camera calibration or a saved `CameraInfo` echo: the intrinsics of
//! its `K`, and its `plumb_bob` distortion undone as a preset's lens is.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use sl_io::DepthEncoding;

mod common;
use common::{s, sldepth};

/// A 640×480 frame of a room corner 1.5–2.6 m away, in millimetres.
fn frame(dir: &Path) -> PathBuf {
    let depth = sl_core::DepthImage::from_image(sl_core::Image::from_fn(640, 480, |x, y| {
        1.5 + (x as f32 - 320.0).abs() / 400.0 + 0.3 * y as f32 / 480.0
    }));
    let p = dir.join("d.png");
    sl_io::write_depth(&p, &depth, &DepthEncoding::png(1000.0)).unwrap();
    p
}

fn run_ok(args: &[&str]) -> (Vec<u8>, String) {
    let o = sldepth(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    (o.stdout, err)
}

#[test]
fn a_ros_camera_file_is_its_intrinsics_and_its_lens() {
    let dir = tempfile::tempdir().unwrap();
    let depth = frame(dir.path());
    // `camera_calibration`'s file with TUM fr1's published calibration: the same cloud as the
    // `tum-fr1` preset, lens undone alike.
    let calibration = dir.path().join("fr1.yaml");
    std::fs::write(
        &calibration,
        "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: \
         [517.3, 0., 318.6, 0., 516.5, 255.3, 0., 0., 1.]\ndistortion_model: plumb_bob\n\
         distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.2624, -0.9531, -0.0054, \
         0.0026, 1.1633]\n",
    )
    .unwrap();
    let (a, b) = (dir.path().join("a.ply"), dir.path().join("b.ply"));
    // Millimetres for both (the preset's own files are TUM's 5000 units per metre).
    let (_, note) = run_ok(&[
        "cloud",
        s(&depth),
        "--camera",
        s(&calibration),
        "--depth-scale",
        "1000",
        "-o",
        s(&a),
    ]);
    assert!(note.contains("plumb_bob model of"), "{note}");
    run_ok(&[
        "cloud",
        s(&depth),
        "--camera",
        "tum-fr1",
        "--depth-scale",
        "1000",
        "-o",
        s(&b),
    ]);
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "the ROS file's cloud differs from the preset's"
    );
    // --lens none keeps the frame as it is.
    let c = dir.path().join("c.ply");
    let (_, quiet) = run_ok(&[
        "cloud",
        s(&depth),
        "--camera",
        s(&calibration),
        "--depth-scale",
        "1000",
        "--lens",
        "none",
        "-o",
        s(&c),
    ]);
    assert!(!quiet.contains("undistorting"), "{quiet}");
    assert!(
        std::fs::read(&a).unwrap() != std::fs::read(&c).unwrap(),
        "--lens none undid the distortion"
    );

    // A ROS 1 `rostopic echo` of the Kinect's CameraInfo (no distortion): the planes of the
    // `kinect-v1` preset, whose intrinsics it holds.
    let echo = dir.path().join("camera_info.yaml");
    std::fs::write(
        &echo,
        "header: \n  seq: 1\n  frame_id: \"/camera_depth_optical_frame\"\nheight: 480\nwidth: \
         640\ndistortion_model: \"plumb_bob\"\nD: [0.0, 0.0, 0.0, 0.0, 0.0]\nK: [580.0, 0.0, \
         319.5, 0.0, 580.0, 239.5, 0.0, 0.0, 1.0]\nbinning_x: 0\nbinning_y: 0\n---\n",
    )
    .unwrap();
    let planes = |camera: &str, out: &str| {
        let labels = dir.path().join(out);
        let (json, _) = run_ok(&[
            "planes",
            s(&depth),
            "--camera",
            camera,
            "-o",
            s(&labels),
            "--json",
        ]);
        let mut v: serde_json::Value = serde_json::from_slice(&json).unwrap();
        v.as_object_mut().unwrap().remove("ms");
        (v, std::fs::read(labels).unwrap())
    };
    let from_echo = planes(s(&echo), "l1.png");
    assert_eq!(from_echo, planes("kinect-v1", "l2.png"));
    assert!(
        from_echo.0["planes"].as_array().unwrap().len() >= 2,
        "the two walls"
    );
}

#[test]
fn a_ros_camera_file_that_is_not_one_camera_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let depth = frame(dir.path());
    let bad = dir.path().join("stereo.yaml");
    std::fs::write(
        &bad,
        "image_width: 640\nimage_height: 480\ncamera_matrix:\n  data: [580, 0, 319.5, 0, 580, \
         239.5, 0, 0, 1]\ndistortion_model: equidistant\ndistortion_coefficients:\n  data: \
         [0.1, 0.01, 0, 0]\n",
    )
    .unwrap();
    let o = sldepth(&["info", s(&depth), "--camera", s(&bad)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("stereo.yaml") && err.contains("equidistant") && !err.contains("panicked"),
        "{err}"
    );
}
