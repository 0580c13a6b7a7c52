//! Recordings made through a ROS driver carry no device name; their noise model comes from the
//! baseline the driver states in a `CameraInfo`'s projection matrix (`P[3] = −f·B`):
//! `realsense2_camera`'s `infra2`, `openni_camera`'s projector. Bags written here as those
//! drivers lay them out (topic names and values as the drivers publish them).

use sl_io::Limits;
use sl_io::rosbag::{PairKind, RosBag};
use sl_testkit::rosbag_writer::{
    Conn, Msg, camera_info, camera_info_cdr, camera_info_cdr_tx, camera_info_tx, image, image_cdr,
    write_bag, write_mcap,
};

/// A D435's infrared focal length at 848×480 and its stereo baseline.
const IR_F: f64 = 426.0;
const D435_B: f64 = 0.0501;
/// Its colour camera's focal length at 640×480 (the aligned depth's intrinsics).
const COLOUR_F: f64 = 615.0;

fn depth_pixels() -> Vec<u8> {
    (0..12u16).flat_map(|p| (1000 + p).to_le_bytes()).collect()
}

/// One message on each of `conns` at second 1; `infos` gives each `CameraInfo` connection's
/// message.
fn messages(depth_conns: &[u32], infos: &[(u32, Vec<u8>)]) -> Vec<Msg> {
    let mut msgs: Vec<Msg> = depth_conns
        .iter()
        .map(|&conn| Msg {
            conn,
            time: (1, 0),
            data: image((1, 0), 4, 3, "16UC1", false, &depth_pixels(), 0),
        })
        .collect();
    msgs.extend(infos.iter().map(|(conn, data)| Msg {
        conn: *conn,
        time: (1, 0),
        data: data.clone(),
    }));
    msgs
}

fn open(path: &std::path::Path) -> RosBag {
    RosBag::open(path, &Limits::default()).unwrap()
}

/// `realsense2_camera` (ROS 1): `depth/image_rect_raw` at the infrared focal length and
/// `aligned_depth_to_color/image_raw` at the colour camera's, with `Tx = 0` in both; the
/// baseline in `infra2/camera_info`. Both depth topics get the D400 model at the infrared
/// pair's `f·B`, whatever image the depth was registered to.
#[test]
fn realsense2_camera_recordings_take_the_baseline_of_infra2() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rs.bag");
    let conns: [Conn; 6] = [
        (0, "/camera/depth/image_rect_raw", "sensor_msgs/Image"),
        (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo"),
        (
            2,
            "/camera/aligned_depth_to_color/image_raw",
            "sensor_msgs/Image",
        ),
        (
            3,
            "/camera/aligned_depth_to_color/camera_info",
            "sensor_msgs/CameraInfo",
        ),
        (4, "/camera/infra1/camera_info", "sensor_msgs/CameraInfo"),
        (5, "/camera/infra2/camera_info", "sensor_msgs/CameraInfo"),
    ];
    let infos = [
        (1, camera_info(4, 3, IR_F, "plumb_bob", &[0.0; 5], 0)),
        (3, camera_info(4, 3, COLOUR_F, "plumb_bob", &[0.0; 5], 0)),
        (4, camera_info(4, 3, IR_F, "plumb_bob", &[0.0; 5], 0)),
        (
            5,
            camera_info_tx(4, 3, IR_F, "plumb_bob", &[0.0; 5], 0, -IR_F * D435_B),
        ),
    ];
    write_bag(&path, &conns, &messages(&[0, 2], &infos), "none", 10).unwrap();
    let mut bag = open(&path);
    for (topic, fx) in [(conns[0].1, IR_F), (conns[2].1, COLOUR_F)] {
        let recorded = bag.recorded_baseline(topic).unwrap().unwrap();
        assert_eq!(recorded.topic, "/camera/infra2/camera_info");
        assert_eq!(recorded.kind, PairKind::StereoCamera);
        assert!((recorded.baseline_m - D435_B).abs() < 1e-12);
        let cam = bag.depth_camera(topic).unwrap();
        assert_eq!(cam.camera.intrinsics.fx, fx);
        let s = cam.camera.sensor;
        assert_eq!(s.subpixel_steps, 32);
        assert_eq!(s.focal_px, IR_F);
        assert!((s.baseline_m - D435_B).abs() < 1e-12);
        // σ_Z at 2 m is the infrared pair's, Z²σ_D/(f·B), not one at the colour focal length.
        let want = 4.0 * s.sigma_d_px / (IR_F * D435_B);
        assert!((s.sigma_z(2.0) - want).abs() < 1e-12 * want);
        assert!(
            cam.sensor_source.contains("50.1 mm baseline")
                && cam.sensor_source.contains("/camera/infra2/camera_info"),
            "{}",
            cam.sensor_source
        );
    }
}

/// `openni_camera` (a Kinect under `openni_launch`) publishes the projector as the right
/// camera: the Kinect's model (1/8 px) at the device's own baseline.
#[test]
fn openni_recordings_take_the_baseline_of_the_projector() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("openni.bag");
    let conns: [Conn; 3] = [
        (0, "/camera/depth/image_raw", "sensor_msgs/Image"),
        (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo"),
        (2, "/camera/projector/camera_info", "sensor_msgs/CameraInfo"),
    ];
    let infos = [
        (1, camera_info(4, 3, 570.3, "plumb_bob", &[0.0; 5], 0)),
        (
            2,
            camera_info_tx(4, 3, 570.3, "plumb_bob", &[0.0; 5], 0, -570.3 * 0.0757),
        ),
    ];
    write_bag(&path, &conns, &messages(&[0], &infos), "none", 10).unwrap();
    let mut bag = open(&path);
    let cam = bag.depth_camera(conns[0].1).unwrap();
    assert_eq!(cam.camera.sensor.subpixel_steps, 8);
    assert!((cam.camera.sensor.baseline_m - 0.0757).abs() < 1e-12);
    assert!(
        cam.sensor_source
            .starts_with("the Kinect's noise model at the 75.7 mm"),
        "{}",
        cam.sensor_source
    );
}

/// No right camera (every `Tx` is 0), pairs that disagree, a right camera in another device's
/// namespace, or one nested deeper: the Kinect's model at the recorded focal length, as before.
#[test]
fn without_one_agreeing_pair_beside_the_depth_the_kinect_model_stays() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, Vec<(Conn, f64)>); 4] = [
        ("none", vec![((2, "/camera/infra1/camera_info", ""), 0.0)]),
        (
            "disagree",
            vec![
                ((2, "/camera/infra2/camera_info", ""), -IR_F * 0.050),
                ((3, "/camera/right/camera_info", ""), -IR_F * 0.120),
            ],
        ),
        (
            "other-device",
            vec![((2, "/camera2/infra2/camera_info", ""), -IR_F * 0.050)],
        ),
        (
            "nested",
            vec![((2, "/camera/stereo/infra2/camera_info", ""), -IR_F * 0.050)],
        ),
    ];
    for (name, extra) in cases {
        let path = dir.path().join(format!("{name}.bag"));
        let mut conns: Vec<Conn> = vec![
            (0, "/camera/depth/image_rect_raw", "sensor_msgs/Image"),
            (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo"),
        ];
        let mut infos = vec![(1, camera_info(4, 3, IR_F, "plumb_bob", &[0.0; 5], 0))];
        for ((id, topic, _), tx) in extra {
            conns.push((id, topic, "sensor_msgs/CameraInfo"));
            infos.push((
                id,
                camera_info_tx(4, 3, IR_F, "plumb_bob", &[0.0; 5], 0, tx),
            ));
        }
        write_bag(&path, &conns, &messages(&[0], &infos), "none", 10).unwrap();
        let mut bag = open(&path);
        assert_eq!(bag.recorded_baseline(conns[0].1).unwrap(), None, "{name}");
        let cam = bag.depth_camera(conns[0].1).unwrap();
        assert_eq!(cam.camera.sensor.subpixel_steps, 8, "{name}");
        assert_eq!(cam.sensor_source, "the Kinect's noise model", "{name}");
    }
}

/// The ROS 2 driver (`realsense2_camera` 4.x, `/camera/camera/...`) in MCAP: the same rule
/// through CDR.
#[test]
fn ros2_realsense2_camera_recordings_in_mcap_take_the_same_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rs.mcap");
    let conns: [Conn; 3] = [
        (
            1,
            "/camera/camera/depth/image_rect_raw",
            "sensor_msgs/msg/Image",
        ),
        (
            2,
            "/camera/camera/depth/camera_info",
            "sensor_msgs/msg/CameraInfo",
        ),
        (
            3,
            "/camera/camera/infra2/camera_info",
            "sensor_msgs/msg/CameraInfo",
        ),
    ];
    let msgs = vec![
        Msg {
            conn: 1,
            time: (1, 0),
            data: image_cdr((1, 0), 4, 3, "16UC1", &depth_pixels()),
        },
        Msg {
            conn: 2,
            time: (1, 0),
            data: camera_info_cdr(4, 3, IR_F, "plumb_bob", &[0.0; 5]),
        },
        Msg {
            conn: 3,
            time: (1, 0),
            data: camera_info_cdr_tx(4, 3, IR_F, "plumb_bob", &[0.0; 5], -IR_F * D435_B),
        },
    ];
    write_mcap(&path, &conns, &msgs, "", 10).unwrap();
    let mut bag = open(&path);
    let cam = bag.depth_camera(conns[0].1).unwrap();
    assert_eq!(cam.camera.sensor.subpixel_steps, 32);
    assert!((cam.camera.sensor.baseline_m - D435_B).abs() < 1e-12);
}
