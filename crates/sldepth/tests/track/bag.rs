//! `sldepth track REC.bag`: a ROS 1 bag's depth topic tracked as the same frames in a folder
//! are, its camera from the `camera_info` beside the topic, its frames stamped with their
//! images' header stamps.

use std::path::Path;

use sl_io::depth::{ReadConfig, read_depth};
use sl_testkit::rosbag_writer::{Conn, Msg, camera_info, image, write_bag};

use super::{kinect_track_json_from, sldepth, sldepth_json, write_sequence};

const DEPTH: Conn = (0, "/camera/depth/image", "sensor_msgs/Image");
const INFO: Conn = (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo");
const RGB: Conn = (2, "/camera/rgb/image_color", "sensor_msgs/Image");

/// The frames of the TUM folder `seq` (stamped `stamps`) as a bag the way TUM's bags hold them:
/// `32FC1` metres, stamped by their headers, received 25 ms later; a `camera_info` of the
/// Kinect's 580 px; an RGB topic beside.
fn bag_of(seq: &Path, stamps: &[f64], bag: &Path, compression: &str) {
    let msgs = bag_messages(seq, stamps);
    write_bag(bag, &[DEPTH, INFO, RGB], &msgs, compression, 2).unwrap();
}

/// A 4-frame TUM folder `seq` under `dir`, its stamps, and the trajectory `track` writes for
/// it (`folder.txt`).
fn tracked_sequence(dir: &Path) -> (std::path::PathBuf, Vec<f64>, std::path::PathBuf) {
    let seq = dir.join("seq");
    let stamps = write_sequence(&seq, 4);
    let traj = dir.join("folder.txt");
    kinect_track_json_from(
        &["--tum", seq.to_str().unwrap()],
        &["--output", traj.to_str().unwrap()],
    );
    (seq, stamps, traj)
}

/// `sldepth fuse ARGS` with the Kinect's camera at 10 mm voxels into `mesh`: its JSON and
/// standard error.
fn fuse_json(args: &[&str], mesh: &Path) -> (serde_json::Value, String) {
    let mut all = vec!["fuse"];
    all.extend_from_slice(args);
    all.extend_from_slice(&[
        "--camera",
        "kinect-v1",
        "--voxel-m",
        "0.01",
        "--output",
        mesh.to_str().unwrap(),
        "--json",
    ]);
    sldepth_json(&all)
}

/// The messages of [`bag_of`].
fn bag_messages(seq: &Path, stamps: &[f64]) -> Vec<Msg> {
    let mut msgs = Vec::new();
    for t in stamps {
        let file = seq.join("depth").join(format!("{t:.6}.png"));
        let d = read_depth(&file, &ReadConfig::default().with_scale(5000.0))
            .unwrap()
            .depth;
        let bytes: Vec<u8> = d.data().iter().flat_map(|v| v.to_le_bytes()).collect();
        let secs = t.floor() as u32;
        let nsecs = ((t - t.floor()) * 1e9).round() as u32;
        let received = (secs, nsecs + 25_000_000);
        let w = d.width() as u32;
        let h = d.height() as u32;
        msgs.push(Msg {
            conn: 0,
            time: received,
            data: image((secs, nsecs), w, h, "32FC1", false, &bytes, 0),
        });
        msgs.push(Msg {
            conn: 1,
            time: received,
            data: camera_info(w, h, 580.0, "plumb_bob", &[0.0; 5], 0),
        });
        msgs.push(Msg {
            conn: 2,
            time: received,
            data: image((secs, nsecs), 1, 1, "rgb8", false, &[1, 2, 3], 0),
        });
    }
    msgs
}

/// The bag's trajectory is the folder's, line for line (the same depths, the headers' stamps
/// rather than the 25-ms-later record times), with bz2 and lz4 chunks alike; without
/// `--camera` the bag's `camera_info` is the camera; a topic that is not depth is refused.
#[test]
fn track_reads_a_ros_bag_as_the_folder_of_its_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let (seq, stamps, folder_traj) = tracked_sequence(tmp.path());
    let folder = std::fs::read_to_string(&folder_traj).unwrap();
    for compression in ["bz2", "lz4"] {
        let bag = tmp.path().join(format!("rec-{compression}.bag"));
        bag_of(&seq, &stamps, &bag, compression);
        let traj = tmp.path().join(format!("{compression}.txt"));
        let (v, stderr) = kinect_track_json_from(
            &[bag.to_str().unwrap()],
            &["--output", traj.to_str().unwrap()],
        );
        assert_eq!(v["tracked"], 4, "{v}");
        assert!(
            stderr.contains("tracking /camera/depth/image (4 frames, 32FC1 metres)"),
            "{stderr}"
        );
        assert_eq!(
            std::fs::read_to_string(&traj).unwrap(),
            folder,
            "{compression}"
        );
    }
    let bag = tmp.path().join("rec-lz4.bag");
    // `info` lists the topics and the one `track` takes.
    let (v, _) = sldepth_json(&["info", bag.to_str().unwrap(), "--json"]);
    assert_eq!(v["depth_topic"], "/camera/depth/image", "{v}");
    assert_eq!(v["topics"][1]["messages"], 4, "{v}");
    assert_eq!(v["topics"][0]["type"], "sensor_msgs/CameraInfo", "{v}");
    let (v, stderr) = sldepth_json(&[
        "track",
        bag.to_str().unwrap(),
        "--voxel-m",
        "0.01",
        "--json",
    ]);
    assert_eq!(v["tracked"], 4, "{v}");
    assert!(
        stderr.contains(
            "camera from /camera/depth/camera_info with the Kinect's noise model (fx 580, 640x480)"
        ),
        "{stderr}"
    );
    let out = sldepth(&[
        "track",
        bag.to_str().unwrap(),
        "--topic",
        "/camera/rgb/image_color",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("/camera/rgb/image_color are not depth"),
        "{err}"
    );
    let out = sldepth(&["track", bag.to_str().unwrap(), "--topic", "/none"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no topic \"/none\" (the bag has /camera/depth/camera_info, /camera/depth/image, /camera/rgb/image_color)"), "{err}");
    // A bag is no depth map, and has no poses of its own to fuse at: each said, with what
    // reads it.
    let labels = tmp.path().join("l.png");
    let out = sldepth(&[
        "planes",
        bag.to_str().unwrap(),
        "-o",
        labels.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("a ROS bag is a recording, not one depth map"),
        "{err}"
    );
    let mesh = tmp.path().join("m.ply");
    let out = sldepth(&[
        "fuse",
        bag.to_str().unwrap(),
        "--output",
        mesh.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("say what poses the recording's frames: a trajectory (--trajectory FILE")
            && err.contains("or its own transforms (--tf WORLD_FRAME"),
        "{err}"
    );
    // Along the trajectory `track` wrote: each message posed by its stamp, the mesh the
    // folder's along the same trajectory, byte for byte.
    let fuse_along = |source: &[&str], mesh: &Path| {
        let mut args = source.to_vec();
        args.extend_from_slice(&["--trajectory", folder_traj.to_str().unwrap()]);
        fuse_json(&args, mesh)
    };
    let folder_mesh = tmp.path().join("folder.ply");
    let (by_bag, stderr) = fuse_along(&[bag.to_str().unwrap()], &mesh);
    let (by_folder, _) = fuse_along(&["--tum", seq.to_str().unwrap()], &folder_mesh);
    assert_eq!(by_bag["frames"], 4, "{stderr}");
    assert!(
        stderr.contains("fusing /camera/depth/image (4 frames, 32FC1 metres)"),
        "{stderr}"
    );
    assert_eq!(by_bag["vertices"], by_folder["vertices"]);
    assert_eq!(
        std::fs::read(&mesh).unwrap(),
        std::fs::read(&folder_mesh).unwrap()
    );
    // A frame without a pose within 20 ms of its stamp is skipped, and said.
    let two: String = folder
        .lines()
        .filter(|l| !l.starts_with('#'))
        .take(2)
        .map(|l| format!("{l}\n"))
        .collect();
    let short = tmp.path().join("short.txt");
    std::fs::write(&short, two).unwrap();
    let (v, stderr) = sldepth_json(&[
        "fuse",
        bag.to_str().unwrap(),
        "--trajectory",
        short.to_str().unwrap(),
        "--voxel-m",
        "0.01",
        "--json",
    ]);
    assert_eq!(v["frames"], 2, "{v}");
    assert!(
        stderr.contains("note: 2 frames of")
            && stderr.contains("(within 0.02 s of its stamp (--max-gap-s))"),
        "{stderr}"
    );
    let out = sldepth(&[
        "track",
        seq.to_str().unwrap(),
        "--topic",
        "/camera/depth/image",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--topic names a topic of a ROS bag"), "{err}");
}

/// A ROS 2 bag (MCAP, zstd chunks, CDR messages) in its folder, and the same messages in
/// SQLite, track as the same frames in a folder do, line for line; `info` names the container.
#[test]
fn track_reads_a_ros2_mcap_bag_as_the_folder_of_its_frames() {
    use sl_testkit::rosbag_writer::{camera_info_cdr, image_cdr, write_mcap};
    let tmp = tempfile::tempdir().unwrap();
    let (seq, stamps, folder_traj) = tracked_sequence(tmp.path());
    let mut msgs = Vec::new();
    for t in &stamps {
        let file = seq.join("depth").join(format!("{t:.6}.png"));
        let d = read_depth(&file, &ReadConfig::default().with_scale(5000.0))
            .unwrap()
            .depth;
        let bytes: Vec<u8> = d.data().iter().flat_map(|v| v.to_le_bytes()).collect();
        let stamp = (t.floor() as u32, ((t - t.floor()) * 1e9).round() as u32);
        let (w, h) = (d.width() as u32, d.height() as u32);
        msgs.push(Msg {
            conn: 1,
            time: stamp,
            data: image_cdr(stamp, w, h, "32FC1", &bytes),
        });
        msgs.push(Msg {
            conn: 2,
            time: stamp,
            data: camera_info_cdr(w, h, 580.0, "plumb_bob", &[0.0; 5]),
        });
    }
    let bag = tmp.path().join("rosbag2_rec");
    std::fs::create_dir(&bag).unwrap();
    std::fs::write(bag.join("metadata.yaml"), "rosbag2_bagfile_information:\n").unwrap();
    let conns: [Conn; 2] = [
        (1, "/camera/depth/image_rect_raw", "sensor_msgs/msg/Image"),
        (2, "/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo"),
    ];
    write_mcap(&bag.join("rosbag2_rec_0.mcap"), &conns, &msgs, "zstd", 3).unwrap();
    let traj = tmp.path().join("mcap.txt");
    let (v, _) = kinect_track_json_from(
        &[bag.to_str().unwrap()],
        &["--output", traj.to_str().unwrap()],
    );
    assert_eq!(v["tracked"], 4, "{v}");
    assert_eq!(
        std::fs::read_to_string(&traj).unwrap(),
        std::fs::read_to_string(&folder_traj).unwrap()
    );
    let (v, _) = sldepth_json(&["info", bag.to_str().unwrap(), "--json"]);
    assert_eq!(v["container"], "MCAP (ROS 2 bag)", "{v}");
    assert_eq!(v["depth_topic"], "/camera/depth/image_rect_raw", "{v}");
    // The same messages in SQLite (`.db3`, Humble's default storage), its file given alone.
    let db3 = tmp.path().join("rec_0.db3");
    sl_testkit::sqlite_writer::write_db3(&db3, 4096, &conns, &msgs).unwrap();
    let traj = tmp.path().join("db3.txt");
    let (v, _) = kinect_track_json_from(
        &[db3.to_str().unwrap()],
        &["--output", traj.to_str().unwrap()],
    );
    assert_eq!(v["tracked"], 4, "{v}");
    assert_eq!(
        std::fs::read_to_string(&traj).unwrap(),
        std::fs::read_to_string(&folder_traj).unwrap()
    );
    let (v, _) = sldepth_json(&["info", db3.to_str().unwrap(), "--json"]);
    assert_eq!(v["container"], "SQLite (ROS 2 bag)", "{v}");
}

/// A RealSense recording as librealsense 2.56+ writes it (SQLite; `compressedDepth` frames in
/// 0.25-mm units; the device and its options as strings): `info` says what `track` will read
/// it with, and `track` reads it so — its depth units, its device's preset at the recorded
/// baseline, each frame stamped with its sensor timestamp from the metadata.
#[test]
fn a_realsense_recording_is_read_with_its_units_device_and_timestamps() {
    use sl_testkit::rosbag_writer::{camera_info_cdr, compressed_image_cdr, string_msg};
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let stamps = write_sequence(&seq, 3);
    let conns: [Conn; 5] = [
        (
            1,
            "/device_0/sensor_0/Depth_0/image/data/compressedDepth",
            "sensor_msgs/msg/CompressedImage",
        ),
        (
            2,
            "/device_0/sensor_0/Depth_0/image/camera_info",
            "sensor_msgs/msg/CameraInfo",
        ),
        (
            3,
            "/device_0/sensor_0/option/Depth_Units/value",
            "std_msgs/msg/String",
        ),
        (4, "/device_0/info", "std_msgs/msg/String"),
        (
            5,
            "/device_0/sensor_0/Depth_0/image/metadata",
            "std_msgs/msg/String",
        ),
    ];
    let text = |s: &str| string_msg(s, true);
    let mut msgs = vec![
        Msg {
            conn: 3,
            time: (0, 0),
            data: text("0.000250"),
        },
        Msg {
            conn: 4,
            time: (0, 0),
            data: text("Name=Intel RealSense D415;Serial Number=7"),
        },
    ];
    for (i, t) in stamps.iter().enumerate() {
        let file = seq.join("depth").join(format!("{t:.6}.png"));
        let d = read_depth(&file, &ReadConfig::default().with_scale(5000.0))
            .unwrap()
            .depth;
        let units: Vec<u16> = d
            .data()
            .iter()
            .map(|z| (z * 4000.0).round() as u16)
            .collect();
        let img = sl_core::Image::from_vec(d.width(), d.height(), units).unwrap();
        let png = tmp.path().join(format!("{i}.png"));
        let data = sl_testkit::rosbag_writer::compressed_depth_data(&png, 0.0, 0.0, &img).unwrap();
        let rec = (0, 1000 + 33_000_000 * i as u32);
        msgs.push(Msg {
            conn: 1,
            time: rec,
            data: compressed_image_cdr(rec, "16UC1; compressedDepth png", &data),
        });
        let (w, h) = (d.width() as u32, d.height() as u32);
        msgs.push(Msg {
            conn: 2,
            time: rec,
            data: camera_info_cdr(w, h, 580.0, "plumb_bob", &[0.0; 5]),
        });
        msgs.push(Msg {
            conn: 5,
            time: rec,
            data: text(&format!("Frame number={i};timestamp={:.3};", t * 1000.0)),
        });
    }
    let db3 = tmp.path().join("rs.db3");
    sl_testkit::sqlite_writer::write_db3(&db3, 4096, &conns, &msgs).unwrap();
    let (v, _) = sldepth_json(&["info", db3.to_str().unwrap(), "--json"]);
    assert_eq!(v["depth_units_per_m"], 4000.0, "{v}");
    assert_eq!(v["realsense"]["device"], "Intel RealSense D415", "{v}");
    assert_eq!(v["camera"]["baseline_m"], 0.055, "{v}");
    assert_eq!(v["camera"]["subpixel_steps"], 32, "{v}");
    let traj = tmp.path().join("rs.txt");
    let (v, stderr) = sldepth_json(&[
        "track",
        db3.to_str().unwrap(),
        "--output",
        traj.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["tracked"], 3, "{v}");
    assert!(
        stderr.contains("16-bit units of 0.25 mm as recorded")
            && stderr.contains("the d415 preset's noise model (Intel RealSense D415) at its 55 mm"),
        "{stderr}"
    );
    let lines: Vec<String> = std::fs::read_to_string(&traj)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect();
    let want: Vec<String> = stamps.iter().map(|t| format!("{t:.6}")).collect();
    assert_eq!(lines, want);
}

/// `fuse REC --tf WORLD`: a bag whose `/tf` holds the camera's poses (world → base, moving,
/// sampled at the frames' stamps) and `/tf_static` the chain to the images' optical frame fuses
/// into the mesh the same poses give as a trajectory file, byte for byte; `info` lists the
/// frames; `track --odometry-tf` takes them as an odometry; transforms that end early leave
/// frames out and say why; unknown frames are named.
#[test]
fn fuse_poses_a_recording_by_its_transforms() {
    use sl_testkit::rosbag_writer::{TfEntry, tf_message};
    let tmp = tempfile::tempdir().unwrap();
    let (seq, stamps, traj) = tracked_sequence(tmp.path());
    let text = std::fs::read_to_string(&traj).unwrap();
    let poses: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(poses.len(), 4);
    let stamp = |t: f64| {
        let secs = t.floor() as u32;
        (secs, ((t - t.floor()) * 1e9).round() as u32)
    };
    const TF: Conn = (3, "/tf", "tf2_msgs/TFMessage");
    const STATIC: Conn = (4, "/tf_static", "tf2_msgs/TFMessage");
    let tf_bag = |n: usize, path: &Path| {
        let mut msgs = bag_messages(&seq, &stamps);
        msgs.push(Msg {
            conn: 4,
            time: stamp(stamps[0]),
            data: tf_message(
                &[TfEntry {
                    stamp: (0, 0),
                    parent: "base".into(),
                    child: "camera_depth_optical_frame".into(),
                    translation: [0.0; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                }],
                false,
            ),
        });
        for (t, p) in stamps.iter().zip(&poses).take(n) {
            msgs.push(Msg {
                conn: 3,
                time: stamp(*t),
                data: tf_message(
                    &[TfEntry {
                        stamp: stamp(*t),
                        parent: "/world".into(),
                        child: "base".into(),
                        translation: [p[1], p[2], p[3]],
                        rotation: [p[4], p[5], p[6], p[7]],
                    }],
                    false,
                ),
            });
        }
        msgs.sort_by_key(|m| m.time);
        write_bag(path, &[DEPTH, INFO, RGB, TF, STATIC], &msgs, "lz4", 3).unwrap();
    };
    let bag = tmp.path().join("tf.bag");
    tf_bag(4, &bag);
    let fuse = |extra: &[&str], mesh: &Path| {
        let mut args = vec![bag.to_str().unwrap()];
        args.extend_from_slice(extra);
        fuse_json(&args, mesh)
    };
    let (by_tf_mesh, by_traj_mesh) = (tmp.path().join("tf.ply"), tmp.path().join("traj.ply"));
    let (by_tf, stderr) = fuse(&["--tf", "world"], &by_tf_mesh);
    assert_eq!(by_tf["frames"], 4, "{stderr}");
    assert!(
        stderr.contains("posing camera_depth_optical_frame in world from 5 transforms"),
        "{stderr}"
    );
    let (by_traj, _) = fuse(&["--trajectory", traj.to_str().unwrap()], &by_traj_mesh);
    assert_eq!(by_tf["vertices"], by_traj["vertices"]);
    assert_eq!(
        std::fs::read(&by_tf_mesh).unwrap(),
        std::fs::read(&by_traj_mesh).unwrap()
    );
    // `info` lists the frames and names the images' frame.
    let (v, _) = sldepth_json(&["info", bag.to_str().unwrap(), "--json"]);
    assert_eq!(v["image_frame"], "camera_depth_optical_frame", "{v}");
    assert_eq!(v["transforms"][0]["frame"], "base", "{v}");
    assert_eq!(v["transforms"][0]["parent"], "world", "{v}");
    assert_eq!(v["transforms"][0]["samples"], 4, "{v}");
    assert_eq!(v["transforms"][1]["static"], true, "{v}");
    // The recording's transforms as a ground truth: the trajectory they were made from
    // matches them exactly, frame by frame.
    let (e, _) = sldepth_json(&[
        "eval-traj",
        traj.to_str().unwrap(),
        bag.to_str().unwrap(),
        "--tf",
        "world",
        "--json",
    ]);
    assert_eq!(e["poses_matched"], 4, "{e}");
    assert!(e["ate_m"]["rmse"].as_f64().unwrap() < 1e-6, "{e}");
    for (gt, tf, what) in [
        (
            bag.to_str().unwrap(),
            None,
            "name the world frame of its transforms with --tf",
        ),
        (
            traj.to_str().unwrap(),
            Some("world"),
            "GT is not a recording",
        ),
    ] {
        let mut args = vec!["eval-traj", traj.to_str().unwrap(), gt];
        if let Some(w) = tf {
            args.extend_from_slice(&["--tf", w]);
        }
        let out = sldepth(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(what), "{err}");
    }
    // The same transforms as an odometry for `track`: every frame predicted by them.
    let (t, stderr) = kinect_track_json_from(&[bag.to_str().unwrap()], &["--odometry-tf", "world"]);
    assert_eq!(t["lost"], 0, "{stderr}");
    assert_eq!(t["odometry"]["frames_with_pose"], 4, "{t}");
    assert_eq!(t["odometry"]["prior_frames"], 3, "{t}");
    assert!(
        stderr.contains("odometry (camera_depth_optical_frame in world from the transforms of"),
        "{stderr}"
    );
    // The moving transform ends after two frames: the last two (33 and 67 ms later) have no
    // pose within 20 ms, and the message says which transform ran out; within 0.1 s they take
    // its last sample.
    tf_bag(2, &bag);
    let (two, stderr) = fuse(&["--tf", "world"], &by_tf_mesh);
    assert_eq!(two["frames"], 2, "{stderr}");
    assert!(
        stderr.contains("note: 2 frames of")
            && stderr.contains("the first: the transform world → base has no sample near"),
        "{stderr}"
    );
    let (wide, _) = fuse(&["--tf", "world", "--max-gap-s", "0.1"], &by_tf_mesh);
    assert_eq!(wide["frames"], 4);
    // Unknown frames are named with the recording's own.
    for (args, what) in [
        (
            ["--tf", "map", "", ""],
            "no transform names \"map\" (--tf); its frames: base, camera_depth_optical_frame, world",
        ),
        (
            ["--tf", "world", "--tf-camera-frame", "cam"],
            "no transform names \"cam\" (the camera's frame)",
        ),
        (
            ["--tf", "camera_depth_optical_frame", "", ""],
            "is the camera's own frame: name the world frame the camera moves in",
        ),
    ] {
        let args: Vec<&str> = args.into_iter().filter(|a| !a.is_empty()).collect();
        let mut all = vec!["fuse", bag.to_str().unwrap()];
        all.extend_from_slice(&args);
        all.extend_from_slice(&["--output", by_tf_mesh.to_str().unwrap()]);
        let out = sldepth(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(what), "{err}");
    }
    // A recording without transforms, and a folder, refuse --tf with what to do instead.
    let plain = tmp.path().join("plain.bag");
    bag_of(&seq, &stamps, &plain, "none");
    for (source, what) in [
        (
            plain.to_str().unwrap(),
            "no transforms (no /tf or /tf_static topic",
        ),
        (seq.to_str().unwrap(), "the source is not a recording"),
    ] {
        let out = sldepth(&[
            "fuse",
            source,
            "--tf",
            "world",
            "--output",
            by_tf_mesh.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(what), "{err}");
    }
}

/// One piece of a recording split by `rosbag record --split`, given alone, is read alone and
/// said to be a piece; its folder reads as the whole recording.
#[test]
fn a_piece_of_a_split_recording_is_said_to_be_one() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let stamps = write_sequence(&seq, 4);
    let msgs = bag_messages(&seq, &stamps);
    let folder = tmp.path().join("split");
    std::fs::create_dir(&folder).unwrap();
    // Two frames (with their camera info and RGB) in each piece.
    for (n, part) in msgs.chunks(6).enumerate() {
        let file = folder.join(format!("rec_{n}.bag"));
        write_bag(&file, &[DEPTH, INFO, RGB], part, "lz4", 2).unwrap();
    }
    let piece = folder.join("rec_1.bag");
    let (v, stderr) = kinect_track_json_from(&[piece.to_str().unwrap()], &[]);
    assert_eq!(v["frames"], 2, "{v}");
    assert!(
        stderr
            .contains("rec_1.bag is piece 2 of 2 of a recording split by `rosbag record --split`")
            && stderr.contains("give its folder"),
        "{stderr}"
    );
    let out = sldepth(&["info", piece.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && err.contains("is piece 2 of 2"),
        "{err}"
    );
    let (v, stderr) = kinect_track_json_from(&[folder.to_str().unwrap()], &[]);
    assert_eq!(v["frames"], 4, "{v}");
    assert!(!stderr.contains("is piece"), "{stderr}");
}

/// A recording whose transforms are remapped under a robot's namespace (`/robot1/tf`): `--tf`
/// alone names the namespace to choose, `--tf-namespace /robot1` fuses by it, and `info` lists
/// the tree.
#[test]
fn fuse_reads_a_namespaced_tree_when_told() {
    use sl_testkit::rosbag_writer::{TfEntry, tf_message};
    let tmp = tempfile::tempdir().unwrap();
    let (seq, stamps, _) = tracked_sequence(tmp.path());
    const TF: Conn = (3, "/robot1/tf", "tf2_msgs/TFMessage");
    let mut msgs = bag_messages(&seq, &stamps);
    for t in &stamps {
        let stamp = (t.floor() as u32, ((t - t.floor()) * 1e9).round() as u32);
        msgs.push(Msg {
            conn: 3,
            time: stamp,
            data: tf_message(
                &[TfEntry {
                    stamp,
                    parent: "world".into(),
                    child: "camera_depth_optical_frame".into(),
                    translation: [0.0, 0.0, 0.0],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                }],
                false,
            ),
        });
    }
    msgs.sort_by_key(|m| m.time);
    let bag = tmp.path().join("robot1.bag");
    write_bag(&bag, &[DEPTH, INFO, RGB, TF], &msgs, "none", 3).unwrap();
    let mesh = tmp.path().join("m.ply");
    for (namespace, what) in [
        (
            None,
            "no transforms on /tf or /tf_static; its trees of transforms are under /robot1",
        ),
        (
            Some("/robot2"),
            "no transforms on /robot2/tf or /robot2/tf_static; its trees of transforms are \
             under /robot1",
        ),
    ] {
        let mut args = vec!["fuse", bag.to_str().unwrap(), "--tf", "world"];
        if let Some(ns) = namespace {
            args.extend_from_slice(&["--tf-namespace", ns]);
        }
        args.extend_from_slice(&["--output", mesh.to_str().unwrap()]);
        let out = sldepth(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(what), "{err}");
    }
    let (v, stderr) = fuse_json(
        &[
            bag.to_str().unwrap(),
            "--tf",
            "world",
            "--tf-namespace",
            "/robot1",
        ],
        &mesh,
    );
    assert_eq!(v["frames"], 4, "{stderr}");
    let (info, _) = sldepth_json(&["info", bag.to_str().unwrap(), "--json"]);
    assert_eq!(info["tf_namespaces"][0], "/robot1", "{info}");
}
