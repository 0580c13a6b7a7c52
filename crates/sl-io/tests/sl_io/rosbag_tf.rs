//! Transforms in recordings (`/tf`, `/tf_static`): read from ROS 1 bags (`tf2_msgs/TFMessage`
//! and ROS 1 `tf`'s `tf/tfMessage`) and ROS 2 MCAP bags (CDR), looked up at the depth frames'
//! stamps in the image headers' frame; malformed and contradictory transforms refused.

use sl_core::nalgebra::{Point3, UnitQuaternion, Vector3};
use sl_io::Limits;
use sl_io::rosbag::{RosBag, TfLookupError};
use sl_testkit::rosbag_writer::{Conn, Msg, TfEntry, image, image_cdr, tf_message};

/// The camera's optical frame in its link: z forward (the link's x), x right (−y), y down (−z).
fn optical_in_link() -> [f64; 4] {
    let r = UnitQuaternion::from_basis_unchecked(&[
        Vector3::new(0.0, -1.0, 0.0),
        Vector3::new(0.0, 0.0, -1.0),
        Vector3::new(1.0, 0.0, 0.0),
    ]);
    [r.i, r.j, r.k, r.w]
}

fn entry(stamp: (u32, u32), parent: &str, child: &str, t: [f64; 3], q: [f64; 4]) -> TfEntry {
    TfEntry {
        stamp,
        parent: parent.into(),
        child: child.into(),
        translation: t,
        rotation: q,
    }
}

/// Three depth frames at 100.05, 101.05, 102.05 s in `camera_depth_optical_frame`; the robot's
/// base moves 1 m along the world's x per second from 100 s (samples every 0.1 s, the world
/// frame named `/world` as ROS 1's `tf` wrote it), and the static chain
/// `base → camera_link → camera_depth_optical_frame` on `/tf_static`.
fn messages(cdr: bool) -> Vec<Msg> {
    let mut msgs = Vec::new();
    for i in 0..=25u32 {
        let stamp = (100 + i / 10, (i % 10) * 100_000_000);
        let x = f64::from(i) * 0.1;
        msgs.push(Msg {
            conn: 1,
            time: stamp,
            data: tf_message(
                &[entry(
                    stamp,
                    "/world",
                    "base",
                    [x, 0.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                )],
                cdr,
            ),
        });
    }
    msgs.push(Msg {
        conn: 2,
        time: (100, 0),
        data: tf_message(
            &[
                entry(
                    (0, 0),
                    "base",
                    "camera_link",
                    [0.0, 0.0, 0.5],
                    [0.0, 0.0, 0.0, 1.0],
                ),
                entry(
                    (0, 0),
                    "camera_link",
                    "camera_depth_optical_frame",
                    [0.0; 3],
                    optical_in_link(),
                ),
            ],
            cdr,
        ),
    });
    for i in 0..3u32 {
        let px: Vec<u8> = (0..12u16).flat_map(|_| 1500u16.to_le_bytes()).collect();
        let stamp = (100 + i, 50_000_000);
        msgs.push(Msg {
            conn: 0,
            time: stamp,
            data: if cdr {
                image_cdr(stamp, 4, 3, "16UC1", &px)
            } else {
                image(stamp, 4, 3, "16UC1", false, &px, 0)
            },
        });
    }
    msgs.sort_by_key(|m| m.time);
    msgs
}

/// Checks what a recording of [`messages`] gives: the tree, the image frame, and the camera's
/// pose at each frame's stamp.
fn check(bag: &mut RosBag) {
    assert_eq!(bag.tf_topics(), ["/tf", "/tf_static"]);
    let tree = bag.transforms().unwrap();
    assert_eq!((tree.samples(), tree.skipped()), (28, 0));
    let frames = tree.frames();
    let names: Vec<&str> = frames.iter().map(|f| f.frame.as_str()).collect();
    assert_eq!(names, ["base", "camera_depth_optical_frame", "camera_link"]);
    assert!(!frames[0].is_static && frames[1].is_static);
    assert_eq!((frames[0].first_s, frames[0].last_s), (100.0, 102.5));
    let topic = bag.depth_topic(None).unwrap();
    let depth = bag.messages(&topic).unwrap();
    let frame = bag.image_frame_id(&depth[0]).unwrap();
    assert_eq!(frame, "camera_depth_optical_frame");
    for (i, m) in depth.iter().enumerate() {
        let stamp = bag.read_depth(m, 1000.0, 1.0).unwrap().stamp_s;
        let pose = tree.lookup("world", &frame, stamp, 0.02).unwrap();
        // The base at x = stamp − 100 (interpolated between samples 0.1 s apart), the camera
        // 0.5 m above it, looking along the world's x with the image's y down.
        let x = stamp - 100.0;
        assert!((stamp - (100.05 + i as f64)).abs() < 1e-9);
        assert!((pose * Point3::origin() - Point3::new(x, 0.0, 0.5)).norm() < 1e-9);
        assert!((pose.rotation * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!((pose.rotation * Vector3::y() + Vector3::z()).norm() < 1e-12);
    }
    // After the last sample (102.5 s) by more than the gap: no pose, and the error says why.
    let e = tree.lookup("world", &frame, 102.6, 0.02).unwrap_err();
    assert!(matches!(e, TfLookupError::NoSample { .. }), "{e}");
    assert!(e.to_string().contains("world → base"), "{e}");
    // A time that is not a number has no pose, not even a static frame's or a frame's in
    // itself.
    for (target, f) in [
        ("world", frame.as_str()),
        ("base", "camera_link"),
        ("base", "base"),
    ] {
        let e = tree.lookup(target, f, f64::NAN, 0.02).unwrap_err();
        assert!(matches!(e, TfLookupError::TimeNotFinite(_)), "{e}");
    }
}

#[test]
fn ros1_bags_give_their_transforms_in_either_tf_message_type() {
    let dir = tempfile::tempdir().unwrap();
    for tf_type in ["tf2_msgs/TFMessage", "tf/tfMessage"] {
        let conns: [Conn; 3] = [
            (0, "/camera/depth/image_raw", "sensor_msgs/Image"),
            (1, "/tf", tf_type),
            (2, "/tf_static", "tf2_msgs/TFMessage"),
        ];
        let path = dir.path().join("tf.bag");
        sl_testkit::rosbag_writer::write_bag(&path, &conns, &messages(false), "lz4", 7).unwrap();
        check(&mut RosBag::open(&path, &Limits::default()).unwrap());
    }
}

#[test]
fn mcap_bags_give_their_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let conns: [Conn; 3] = [
        (0, "/camera/depth/image_rect_raw", "sensor_msgs/msg/Image"),
        (1, "/tf", "tf2_msgs/msg/TFMessage"),
        (2, "/tf_static", "tf2_msgs/msg/TFMessage"),
    ];
    let path = dir.path().join("tf.mcap");
    sl_testkit::rosbag_writer::write_mcap(&path, &conns, &messages(true), "zstd", 5).unwrap();
    check(&mut RosBag::open(&path, &Limits::default()).unwrap());
}

#[test]
fn malformed_and_contradictory_transforms_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let conns: [Conn; 1] = [(1, "/tf", "tf2_msgs/TFMessage")];
    let path = dir.path().join("bad.bag");
    let write = |data: Vec<u8>| {
        let msgs = [Msg {
            conn: 1,
            time: (1, 0),
            data,
        }];
        sl_testkit::rosbag_writer::write_bag(&path, &conns, &msgs, "none", 4).unwrap();
        RosBag::open(&path, &Limits::default())
            .unwrap()
            .transforms()
            .map_err(|e| e.to_string())
    };
    // A count of transforms far beyond the message's bytes.
    let mut huge = tf_message(&[], false);
    huge[..4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = write(huge).unwrap_err();
    assert!(e.contains("cut off"), "{e}");
    // Every cut of a valid message.
    let one = tf_message(
        &[entry(
            (1, 0),
            "w",
            "c",
            [1.0, 2.0, 3.0],
            [0.0, 0.0, 0.0, 1.0],
        )],
        false,
    );
    for at in 0..one.len() {
        assert!(write(one[..at].to_vec()).is_err(), "cut at {at}");
    }
    // A frame with two parents.
    let two = tf_message(
        &[
            entry((1, 0), "w", "c", [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
            entry((1, 0), "v", "c", [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        ],
        false,
    );
    let e = write(two).unwrap_err();
    assert!(e.contains("two parents") && e.contains("/tf"), "{e}");
    // A zero quaternion or NaN is left out and counted, not an error.
    let odd = tf_message(
        &[
            entry((1, 0), "w", "c", [0.0; 3], [0.0; 4]),
            entry((1, 0), "w", "c", [f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
            entry((2, 0), "w", "c", [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        ],
        false,
    );
    let mut bag = {
        let msgs = [Msg {
            conn: 1,
            time: (1, 0),
            data: odd,
        }];
        sl_testkit::rosbag_writer::write_bag(&path, &conns, &msgs, "none", 4).unwrap();
        RosBag::open(&path, &Limits::default()).unwrap()
    };
    let tree = bag.transforms().unwrap();
    assert_eq!((tree.samples(), tree.skipped()), (1, 2));
    // A robot's namespaced tree (`/robot1/tf`) is another tree: not read as /tf is.
    let ns: [Conn; 1] = [(1, "/robot1/tf", "tf2_msgs/TFMessage")];
    let msgs = [Msg {
        conn: 1,
        time: (1, 0),
        data: tf_message(
            &[entry(
                (1, 0),
                "odom",
                "base",
                [0.0; 3],
                [0.0, 0.0, 0.0, 1.0],
            )],
            false,
        ),
    }];
    sl_testkit::rosbag_writer::write_bag(&path, &ns, &msgs, "none", 4).unwrap();
    let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
    assert!(bag.tf_topics().is_empty());
    assert_eq!(bag.transforms().unwrap().samples(), 0);
    // A recording without transforms gives an empty tree.
    let plain = dir.path().join("plain.bag");
    let depth: [Conn; 1] = [(0, "/d", "sensor_msgs/Image")];
    sl_testkit::rosbag_writer::write_bag(&plain, &depth, &[], "none", 4).unwrap();
    let mut bag = RosBag::open(&plain, &Limits::default()).unwrap();
    assert!(bag.tf_topics().is_empty());
    assert_eq!(bag.transforms().unwrap().samples(), 0);
}

/// A multi-robot recording remaps each robot's transforms (`/robot1/tf`, `/robot1/tf_static`):
/// another tree, listed by `tf_namespaces` and read by `transforms_in`, never merged with the
/// root's (here a plain `/tf` of another robot, whose frames share the names).
#[test]
fn namespaced_trees_are_read_apart() {
    let dir = tempfile::tempdir().unwrap();
    let conns: [Conn; 5] = [
        (0, "/camera/depth/image_raw", "sensor_msgs/Image"),
        (1, "/robot1/tf", "tf2_msgs/TFMessage"),
        (2, "/robot1/tf_static", "tf2_msgs/TFMessage"),
        (3, "/tf", "tf2_msgs/TFMessage"),
        (4, "/robot1/camera/tf_stuff", "tf2_msgs/TFMessage"),
    ];
    let mut msgs = messages(false);
    msgs.push(Msg {
        conn: 3,
        time: (100, 0),
        data: tf_message(
            &[entry(
                (100, 0),
                "world",
                "base",
                [9.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            )],
            false,
        ),
    });
    msgs.sort_by_key(|m| m.time);
    let path = dir.path().join("robots.bag");
    sl_testkit::rosbag_writer::write_bag(&path, &conns, &msgs, "none", 7).unwrap();
    let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
    assert_eq!(bag.tf_namespaces(), ["", "/robot1"]);
    assert_eq!(bag.tf_topics(), ["/tf"]);
    assert_eq!(
        bag.tf_topics_in("/robot1/"),
        ["/robot1/tf", "/robot1/tf_static"]
    );
    assert_eq!(bag.tf_topics_in("robot1"), bag.tf_topics_in("/robot1"));
    assert!(bag.tf_topics_in("/robot2").is_empty());
    let root = bag.transforms().unwrap();
    assert_eq!(root.samples(), 1);
    let robot1 = bag.transforms_in("/robot1").unwrap();
    assert_eq!(robot1.samples(), 28);
    let frame = "camera_depth_optical_frame";
    let p = robot1.lookup("world", frame, 100.55, 0.02).unwrap();
    assert!((p.translation.vector.x - 0.55).abs() < 1e-9);
    assert!(matches!(
        root.lookup("world", frame, 100.0, 0.02),
        Err(TfLookupError::UnknownFrame(_))
    ));
}
