//! ROS camera calibrations and saved `CameraInfo` echoes, in the shapes ROS writes them, and
//! the files a camera reader must refuse.

use sl_core::Intrinsics;
use sl_io::IoError;
use sl_io::Limits;
use sl_io::ros_camera::{MAX_ROS_CAMERA_BYTES, is_ros_camera_file, read_ros_camera};

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `camera_calibration`'s `ost.yaml` for a Kinect IR camera: flow lists over several lines.
const CALIBRATION: &str = "\
image_width: 640
image_height: 480
camera_name: depth_B00362708472045B
camera_matrix:
  rows: 3
  cols: 3
  data: [ 582.62448167737955, 0., 313.04475870804731, 0., 582.69103270988637,
      238.44389626620386, 0., 0., 1. ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [ -0.0991, 0.2317, 0.0001, -0.0012, -0.1405 ]
rectification_matrix:
  rows: 3
  cols: 3
  data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]
projection_matrix:
  rows: 3
  cols: 4
  data: [ 582.62, 0., 313.04, 0., 0., 582.69, 238.44, 0., 0., 0., 1., 0. ]
";

/// `rostopic echo -n 1 /camera/depth/camera_info` (ROS 1), as openni_launch publishes it.
const ROS1_ECHO: &str = "\
header: 
  seq: 42
  stamp: 
    secs: 1305031229
    nsecs: 528784000
  frame_id: \"/openni_depth_optical_frame\"
height: 480
width: 640
distortion_model: \"plumb_bob\"
D: [0.0, 0.0, 0.0, 0.0, 0.0]
K: [525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0]
R: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
P: [525.0, 0.0, 319.5, 0.0, 0.0, 525.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0]
binning_x: 0
binning_y: 0
roi: 
  x_offset: 0
  y_offset: 0
  height: 0
  width: 0
  do_rectify: False
---
";

/// `ros2 topic echo --once /camera/depth/camera_info` (ROS 2, realsense2_camera): block lists.
const ROS2_ECHO: &str = "\
header:
  stamp:
    sec: 1700000000
    nanosec: 12345
  frame_id: camera_depth_optical_frame
height: 480
width: 848
distortion_model: plumb_bob
d:
- 0.0
- 0.0
- 0.0
- 0.0
- 0.0
k:
- 426.0
- 0.0
- 423.5
- 0.0
- 426.0
- 239.5
- 0.0
- 0.0
- 1.0
r:
- 1.0
- 0.0
- 0.0
- 0.0
- 1.0
- 0.0
- 0.0
- 0.0
- 1.0
binning_x: 0
binning_y: 0
roi:
  x_offset: 0
  y_offset: 0
  height: 0
  width: 0
  do_rectify: false
---
";

#[test]
fn ros_calibrations_and_camera_info_echoes_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits::default();
    let cal = read_ros_camera(write(&dir, "ost.yaml", CALIBRATION), &limits).unwrap();
    // The file's numbers as written (more digits than an f64 literal should carry).
    let n = |t: &str| t.parse::<f64>().unwrap();
    assert_eq!(
        cal.intrinsics,
        Intrinsics::new(
            640,
            480,
            n("582.62448167737955"),
            n("582.69103270988637"),
            n("313.04475870804731"),
            n("238.44389626620386")
        )
        .unwrap()
    );
    assert_eq!(cal.distortion_model, "plumb_bob");
    let lens = cal.lens.expect("a non-zero plumb_bob distortion");
    assert_eq!(
        [lens.k1, lens.k2, lens.p1, lens.p2, lens.k3],
        [-0.0991, 0.2317, 0.0001, -0.0012, -0.1405]
    );

    let ros1 = read_ros_camera(write(&dir, "info.yml", ROS1_ECHO), &limits).unwrap();
    assert_eq!(
        ros1.intrinsics,
        Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap()
    );
    assert_eq!(ros1.lens, None, "zero coefficients: nothing to undo");

    let ros2 = read_ros_camera(write(&dir, "info2.yaml", ROS2_ECHO), &limits).unwrap();
    assert_eq!(
        ros2.intrinsics,
        Intrinsics::new(848, 480, 426.0, 426.0, 423.5, 239.5).unwrap()
    );
    assert_eq!(ros2.lens, None);
    // Only the first document of an echo of several messages is read.
    let two = format!("{ROS1_ECHO}{}", ROS1_ECHO.replace("525.0", "600.0"));
    let first = read_ros_camera(write(&dir, "two.yaml", &two), &limits).unwrap();
    assert_eq!(first.intrinsics.fx, 525.0);

    assert!(is_ros_camera_file(std::path::Path::new("a/ost.YAML")));
    assert!(!is_ros_camera_file(std::path::Path::new("cam.json")));
}

fn refused(dir: &tempfile::TempDir, name: &str, text: &str, needle: &str) -> IoError {
    let e = read_ros_camera(write(dir, name, text), &Limits::default()).unwrap_err();
    let m = e.to_string();
    assert!(m.contains(name), "{m}");
    assert!(m.contains(needle), "expected {needle:?} in: {m}");
    e
}

#[test]
fn camera_files_that_are_not_one_camera_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    refused(
        &dir,
        "no_k.yaml",
        "image_width: 640\nimage_height: 480\n",
        "no intrinsic matrix",
    );
    refused(
        &dir,
        "no_size.yaml",
        "K: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n",
        "no image size",
    );
    refused(
        &dir,
        "short_k.yaml",
        &ROS1_ECHO.replace("0.0, 0.0, 1.0]\nR", "0.0]\nR"),
        "needs 9",
    );
    refused(
        &dir,
        "uncalibrated.yaml",
        &ROS1_ECHO.replace("height: 480", "height: 0"),
        "uncalibrated",
    );
    refused(
        &dir,
        "skew.yaml",
        &ROS1_ECHO.replace("K: [525.0, 0.0,", "K: [525.0, 3.0,"),
        "skew",
    );
    refused(
        &dir,
        "binned.yaml",
        &ROS1_ECHO.replace("binning_x: 0", "binning_x: 2"),
        "binning_x",
    );
    refused(
        &dir,
        "roi.yaml",
        &ROS1_ECHO.replace("  height: 0\n  width: 0", "  height: 240\n  width: 320"),
        "region of interest",
    );
    refused(
        &dir,
        "rational.yaml",
        &CALIBRATION.replace("plumb_bob", "rational_polynomial"),
        "rational_polynomial",
    );
    refused(
        &dir,
        "nan.yaml",
        &ROS1_ECHO.replace("K: [525.0,", "K: [.nan,"),
        "not a finite number",
    );
    refused(&dir, "tabs.yaml", "K: [1, 2\n\t- x: {", "not YAML");
    // Anchors and aliases: a few hundred bytes that a loader would expand beyond memory.
    let mut bomb = String::from("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n");
    for i in 0..9 {
        let prev = (b'a' + i) as char;
        let next = (b'a' + i + 1) as char;
        bomb.push_str(&format!(
            "{next}: &{next} [{}]\n",
            vec![format!("*{prev}"); 10].join(", ")
        ));
    }
    refused(&dir, "bomb.yaml", &bomb, "anchors");
    refused(&dir, "alias.yaml", "K: *x\n", "YAML");
    let deep = format!("K: {}1{}\n", "[".repeat(40), "]".repeat(40));
    refused(&dir, "deep.yaml", &deep, "nested more than");
    // Too large a file for a camera, and too large an image for the budget.
    let big = format!(
        "{ROS1_ECHO}#{}\n",
        "x".repeat(MAX_ROS_CAMERA_BYTES as usize)
    );
    let e = refused(&dir, "big.yaml", &big, "");
    assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
    let e = refused(
        &dir,
        "huge.yaml",
        &ROS1_ECHO
            .replace("height: 480", "height: 65536")
            .replace("width: 640", "width: 65536"),
        "",
    );
    assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
}
