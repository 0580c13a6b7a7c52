//! ROS 2 bags in SQLite (`.db3`) and RealSense recordings: depth, camera and the RealSense
//! sensor's options read back from files this test writes by the formats' specifications, and
//! malformed files refused with errors.

use sl_io::Limits;
use sl_io::rosbag::{DepthEncodingKind, RosBag, is_bag_file};
use sl_testkit::rosbag_writer::{
    Conn, Msg, camera_info, camera_info_cdr, compressed_image_cdr, float32_msg, image, image_cdr,
    key_value_msg, string_msg,
};
use sl_testkit::sqlite_writer::write_db3;

const DEPTH: Conn = (1, "/camera/depth/image_rect_raw", "sensor_msgs/msg/Image");
const INFO: Conn = (2, "/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo");
const W: u32 = 64;
const H: u32 = 40;

/// The millimetres of frame `i` at pixel `p` (0 at pixel 7: no depth).
fn mm(i: u32, p: u32) -> u16 {
    if p == 7 {
        0
    } else {
        (800 + 7 * i + p % 500) as u16
    }
}

/// 30 depth frames of 64×40 (5 KB each: they overflow pages up to 4 KB) with a camera info
/// each, recorded 20 ms after their stamps; frames 3 and 4 written in swapped order.
fn messages() -> Vec<Msg> {
    let mut msgs = Vec::new();
    for i in 0..30u32 {
        let px: Vec<u8> = (0..W * H).flat_map(|p| mm(i, p).to_le_bytes()).collect();
        msgs.push(Msg {
            conn: 1,
            time: (300 + i, 20_000_000),
            data: image_cdr((300 + i, 0), W, H, "16UC1", &px),
        });
        msgs.push(Msg {
            conn: 2,
            time: (300 + i, 20_000_000),
            data: camera_info_cdr(W, H, 52.5, "plumb_bob", &[0.0; 5]),
        });
    }
    msgs.swap(6, 8);
    msgs
}

/// Every page size the format allows a bag to have (512 B: interior pages over dozens of
/// leaves, every frame in an overflow chain; 64 KiB: one page per few frames) reads the same
/// frames in time order, with their stamps and the camera beside them; a ROS 2 bag's folder
/// opens as its one `.db3`.
#[test]
fn db3_bags_give_their_depth_frames_and_camera() {
    let dir = tempfile::tempdir().unwrap();
    for page_size in [512, 1024, 4096, 65_536] {
        let folder = dir.path().join(format!("ros2-{page_size}"));
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(
            folder.join("metadata.yaml"),
            "rosbag2_bagfile_information:\n",
        )
        .unwrap();
        let file = folder.join("ros2_0.db3");
        write_db3(&file, page_size, &[DEPTH, INFO], &messages()).unwrap();
        assert!(is_bag_file(&folder) && is_bag_file(&file));
        let mut bag = RosBag::open(&folder, &Limits::default()).unwrap();
        assert_eq!(bag.container(), "SQLite (ROS 2 bag)");
        let topics = bag.topics();
        assert_eq!(topics.len(), 2);
        assert_eq!(topics[1].message_type, "sensor_msgs/Image");
        assert_eq!(topics[1].messages, 30);
        let topic = bag.depth_topic(None).unwrap();
        assert_eq!(topic, DEPTH.1);
        let frames = bag.messages(&topic).unwrap();
        assert_eq!(frames.len(), 30);
        for (i, m) in frames.iter().enumerate() {
            let i = i as u32;
            assert!((m.record_time_s - (300.02 + f64::from(i))).abs() < 1e-9);
            let d = bag.read_depth(m, 1000.0, 1.0).unwrap();
            assert_eq!(d.kind, DepthEncodingKind::U16);
            assert_eq!(d.stamp_s, f64::from(300 + i), "page {page_size}");
            assert_eq!(
                (d.depth.width(), d.depth.height()),
                (W as usize, H as usize)
            );
            for p in [0, 7, 1999, W * H - 1] {
                let want = f32::from(mm(i, p)) / 1000.0;
                assert_eq!(
                    d.depth.data()[p as usize],
                    want,
                    "page {page_size} frame {i}"
                );
            }
        }
        let cam = bag.depth_camera(&topic).unwrap();
        assert_eq!(cam.camera_info_topic, INFO.1);
        assert_eq!(cam.camera.intrinsics.fx, 52.5);
        assert_eq!(cam.sensor_source, "the Kinect's noise model");
        assert_eq!(bag.depth_units_per_m(&topic).unwrap(), 1000.0);
    }
}

/// Files that are not whole SQLite bags: cut anywhere, a page that points at itself, a row
/// larger than the budget, newest writes still in a `-wal` file, a bag split in two files,
/// another database.
#[test]
fn malformed_db3_bags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a.db3");
    write_db3(&file, 512, &[DEPTH, INFO], &messages()).unwrap();
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.db3");
    // Cut short anywhere: an error when opened or when a frame is read, never a panic.
    for at in (0..bytes.len()).step_by(397) {
        std::fs::write(&cut, &bytes[..at]).unwrap();
        let read = RosBag::open(&cut, &Limits::default()).and_then(|mut b| {
            let t = b.depth_topic(None)?;
            for m in b.messages(&t)? {
                b.read_depth(&m, 1000.0, 1.0)?;
            }
            Ok(())
        });
        assert!(read.is_err(), "cut at {at}");
    }
    // The root page of the messages table made an interior page whose right-most child is
    // itself: a walk that would never end.
    let root = {
        let b = RosBag::open(&file, &Limits::default()).unwrap();
        drop(b);
        // The schema's second row names the messages table's root; find it as the last
        // interior page (kind 5) of the file.
        (0..bytes.len() / 512)
            .rev()
            .find(|&p| bytes[p * 512] == 0x05)
            .unwrap()
    };
    let mut looped = bytes.clone();
    let at = root * 512 + 8;
    looped[at..at + 4].copy_from_slice(&(root as u32 + 1).to_be_bytes());
    let looping = dir.path().join("loop.db3");
    std::fs::write(&looping, &looped).unwrap();
    let e = RosBag::open(&looping, &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("visits a page twice"), "{e}");
    // A frame larger than the decoded-bytes budget is refused before it is read.
    let mut small = Limits::default();
    small.max_decoded_bytes = 4000;
    let mut bag = RosBag::open(&file, &small).unwrap();
    let m = bag.messages(DEPTH.1).unwrap()[0];
    let e = bag.read_depth(&m, 1000.0, 1.0).unwrap_err();
    assert!(matches!(e, sl_io::IoError::TooLarge { .. }), "{e}");
    // Topic rows that add up to more than the budget (each overflows into its own chain; a
    // hostile file could point them all at one) are refused before they are read.
    let long: &'static str = Box::leak(format!("/{}", "t".repeat(2000)).into_boxed_str());
    let topics = dir.path().join("topics.db3");
    write_db3(
        &topics,
        512,
        &[(1, long, "a/msg/B"), (2, long, "a/msg/B")],
        &[],
    )
    .unwrap();
    assert!(RosBag::open(&topics, &Limits::default()).is_ok());
    let e = RosBag::open(&topics, &small).unwrap_err();
    assert!(e.to_string().contains("schema or topic rows of"), "{e}");
    // Written in WAL mode with its newest pages still in the -wal file.
    let mut wal = bytes.clone();
    wal[18] = 2;
    wal[19] = 2;
    let wal_file = dir.path().join("w.db3");
    std::fs::write(&wal_file, &wal).unwrap();
    assert!(RosBag::open(&wal_file, &Limits::default()).is_ok());
    std::fs::write(dir.path().join("w.db3-wal"), b"pages").unwrap();
    let e = RosBag::open(&wal_file, &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("-wal file"), "{e}");
    // A folder of both storages.
    let mixed = dir.path().join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    std::fs::write(mixed.join("metadata.yaml"), "").unwrap();
    std::fs::copy(&file, mixed.join("mixed_0.db3")).unwrap();
    std::fs::write(mixed.join("mixed_1.mcap"), b"").unwrap();
    let e = RosBag::open(&mixed, &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("both .mcap and .db3"), "{e}");
    // An SQLite database that is not a bag, and a .db3 that is not SQLite.
    let mut other = bytes.clone();
    let i = other.windows(6).position(|w| w == b"topics").unwrap();
    other[i..i + 6].copy_from_slice(b"tapics");
    let other_file = dir.path().join("other.db3");
    std::fs::write(&other_file, &other).unwrap();
    let e = RosBag::open(&other_file, &Limits::default()).unwrap_err();
    assert!(
        e.to_string()
            .contains("without the topics and messages tables"),
        "{e}"
    );
    std::fs::write(&other_file, b"not a database at all").unwrap();
    let e = RosBag::open(&other_file, &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("an SQLite one"), "{e}");
}

/// The 16-bit depth of a RealSense frame in a PNG of `image_transport`'s `compressedDepth`.
fn compressed(values: &[u16]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let img = sl_core::Image::from_vec(W as usize, H as usize, values.to_vec()).unwrap();
    sl_testkit::rosbag_writer::compressed_depth_data(&dir.path().join("q.png"), 0.0, 0.0, &img)
        .unwrap()
}

/// RealSense recordings as librealsense writes them: up to 2.55 a ROS 1 bag (`mono16` under
/// `/device_0/sensor_0/Depth_0/image/data`, the camera under `…/info/camera_info` with a
/// "Brown Conrady" lens, options as `Float32`, the device's name as `KeyValue`s, the sensor
/// timestamp in the header); since 2.56 a `.db3` (`compressedDepth`, the camera under
/// `…/image/camera_info`, options and names as `key=value` strings, the sensor timestamp in
/// the metadata). Both give the depth units (0.25 mm here, an L515's), the device's preset at
/// the recorded baseline, and the sensor's timestamps.
#[test]
fn realsense_recordings_give_their_units_device_and_timestamps() {
    let dir = tempfile::tempdir().unwrap();
    let units: Vec<u16> = (0..W * H).map(|p| 4000 + (p % 100) as u16).collect();
    let px: Vec<u8> = units.iter().flat_map(|v| v.to_le_bytes()).collect();
    let depth1: Conn = (
        0,
        "/device_0/sensor_0/Depth_0/image/data",
        "sensor_msgs/Image",
    );
    let info1: Conn = (
        1,
        "/device_0/sensor_0/Depth_0/info/camera_info",
        "sensor_msgs/CameraInfo",
    );
    let unit1: Conn = (
        2,
        "/device_0/sensor_0/option/Depth_Units/value",
        "std_msgs/Float32",
    );
    let base1: Conn = (
        3,
        "/device_0/sensor_0/option/Stereo Baseline/value",
        "std_msgs/Float32",
    );
    let name1: Conn = (4, "/device_0/info", "diagnostic_msgs/KeyValue");
    let at = |conn, t: u32, data| Msg {
        conn,
        time: (0, t),
        data,
    };
    let mut msgs = vec![
        at(4, 0, key_value_msg("Serial Number", "0123")),
        at(4, 0, key_value_msg("Name", "Intel RealSense D435I")),
        at(2, 0, float32_msg(0.00025)),
        at(3, 0, float32_msg(49.9)),
        at(
            1,
            0,
            camera_info(W, H, 380.5, "Brown Conrady", &[0.0; 5], 0),
        ),
    ];
    for i in 0..3u32 {
        msgs.push(at(
            0,
            1000 + i * 33_000_000,
            image(
                (1_700_000_000, 5_000_000 * i),
                W,
                H,
                "mono16",
                false,
                &px,
                0,
            ),
        ));
    }
    let bag1 = dir.path().join("rs.bag");
    sl_testkit::rosbag_writer::write_bag(
        &bag1,
        &[depth1, info1, unit1, base1, name1],
        &msgs,
        "lz4",
        4,
    )
    .unwrap();
    let depth2: Conn = (
        1,
        "/device_0/sensor_0/Depth_0/image/data/compressedDepth",
        "sensor_msgs/msg/CompressedImage",
    );
    let info2: Conn = (
        2,
        "/device_0/sensor_0/Depth_0/image/camera_info",
        "sensor_msgs/msg/CameraInfo",
    );
    let unit2: Conn = (
        3,
        "/device_0/sensor_0/option/Depth_Units/value",
        "std_msgs/msg/String",
    );
    let base2: Conn = (
        4,
        "/device_0/sensor_0/option/Stereo_Baseline/value",
        "std_msgs/msg/String",
    );
    let name2: Conn = (5, "/device_0/info", "std_msgs/msg/String");
    let meta2: Conn = (
        6,
        "/device_0/sensor_0/Depth_0/image/metadata",
        "std_msgs/msg/String",
    );
    let mut msgs = vec![
        at(
            5,
            0,
            string_msg("Name=Intel RealSense D435I;Serial Number=0123", true),
        ),
        at(3, 0, string_msg("0.000250", true)),
        at(4, 0, string_msg("49.900000", true)),
    ];
    for i in 0..3u32 {
        let t = 1000 + i * 33_000_000;
        msgs.push(at(
            1,
            t,
            compressed_image_cdr((0, t), "16UC1; compressedDepth png", &compressed(&units)),
        ));
        msgs.push(at(
            2,
            t,
            camera_info_cdr(W, H, 380.5, "plumb_bob", &[0.0; 5]),
        ));
        let text = format!(
            "Frame number={i};timestamp_domain=System Time;timestamp={}.500000;",
            1_700_000_000_000u64 + 5 * u64::from(i)
        );
        msgs.push(at(6, t, string_msg(&text, true)));
    }
    let bag2 = dir.path().join("rs.db3");
    write_db3(
        &bag2,
        4096,
        &[depth2, info2, unit2, base2, name2, meta2],
        &msgs,
    )
    .unwrap();
    for (path, topic) in [(&bag1, depth1.1), (&bag2, depth2.1)] {
        let mut bag = RosBag::open(path, &Limits::default()).unwrap();
        assert_eq!(bag.depth_topic(None).unwrap(), topic);
        let rs = bag.realsense(topic).unwrap().unwrap();
        assert_eq!(rs.device_name.as_deref(), Some("Intel RealSense D435I"));
        assert_eq!(rs.depth_units_m, Some(0.00025));
        assert!((rs.stereo_baseline_m.unwrap() - 0.0499).abs() < 1e-12);
        assert_eq!(bag.depth_units_per_m(topic).unwrap(), 4000.0);
        let cam = bag.depth_camera(topic).unwrap();
        assert_eq!(cam.camera.intrinsics.fx, 380.5);
        assert_eq!(cam.camera.sensor.focal_px, 380.5);
        assert_eq!(cam.camera.sensor.subpixel_steps, 32);
        assert!((cam.camera.sensor.baseline_m - 0.0499).abs() < 1e-12);
        assert_eq!(
            cam.sensor_source,
            "the d435 preset's noise model (Intel RealSense D435I) at the recorded 49.9 mm baseline"
        );
        let frames = bag.messages(topic).unwrap();
        let times = bag.realsense_frame_times(topic, &frames).unwrap();
        for (i, m) in frames.iter().enumerate() {
            let d = bag.read_depth(m, 4000.0, 1.0).unwrap();
            assert_eq!(d.depth.data()[1], 4001.0 / 4000.0);
            // 2.55: the header stamp; 2.56: the metadata's timestamp (ms), in seconds.
            let t = times[i].unwrap_or(d.stamp_s);
            let want =
                1_700_000_000.0 + 0.005 * i as f64 + if times[i].is_some() { 0.0005 } else { 0.0 };
            assert!((t - want).abs() < 1e-6, "{} frame {i}: {t}", path.display());
        }
    }
    // A camera without a recorded baseline or known device: the Kinect's model.
    let plain = dir.path().join("plain.db3");
    let msgs = vec![
        at(
            1,
            5,
            compressed_image_cdr((0, 5), "16UC1; compressedDepth png", &compressed(&units)),
        ),
        at(2, 5, camera_info_cdr(W, H, 380.5, "plumb_bob", &[0.0; 5])),
    ];
    write_db3(&plain, 4096, &[depth2, info2], &msgs).unwrap();
    let mut bag = RosBag::open(&plain, &Limits::default()).unwrap();
    assert_eq!(bag.realsense(depth2.1).unwrap(), Some(Default::default()));
    assert_eq!(bag.depth_units_per_m(depth2.1).unwrap(), 1000.0);
    assert_eq!(
        bag.depth_camera(depth2.1).unwrap().sensor_source,
        "the Kinect's noise model"
    );
}

/// A ROS 2 bag split into several files (`ros2 bag record --max-bag-size`): its folder reads as
/// one recording, the files in the natural order of their names (`_2` before `_10`) and the
/// messages in time order across them, for SQLite and MCAP alike; one of its files alone is
/// that file's part.
#[test]
fn a_bag_split_into_files_reads_as_one_recording() {
    let dir = tempfile::tempdir().unwrap();
    let msgs = messages();
    // Files 0, 2 and 10 (their names out of lexical order), ten frames each.
    let groups: Vec<Vec<Msg>> = msgs.chunks(20).map(<[Msg]>::to_vec).collect();
    for storage in ["db3", "mcap"] {
        let folder = dir.path().join(format!("split-{storage}"));
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(
            folder.join("metadata.yaml"),
            "rosbag2_bagfile_information:\n",
        )
        .unwrap();
        for (g, n) in groups.iter().zip([0, 2, 10]) {
            let file = folder.join(format!("split_{n}.{storage}"));
            if storage == "db3" {
                write_db3(&file, 1024, &[DEPTH, INFO], g).unwrap();
            } else {
                sl_testkit::rosbag_writer::write_mcap(&file, &[DEPTH, INFO], g, "zstd", 4).unwrap();
            }
        }
        let mut bag = RosBag::open(&folder, &Limits::default()).unwrap();
        assert_eq!(bag.files(), 3);
        assert_eq!(bag.path(), folder.as_path());
        assert_eq!(bag.topics()[1].messages, 30, "{storage}");
        let frames = bag.messages(DEPTH.1).unwrap();
        assert_eq!(frames.len(), 30);
        for (i, m) in frames.iter().enumerate() {
            let d = bag.read_depth(m, 1000.0, 1.0).unwrap();
            assert_eq!(d.stamp_s, 300.0 + i as f64, "{storage}");
            assert_eq!(d.depth.data()[1999], f32::from(mm(i as u32, 1999)) / 1000.0);
        }
        let one = RosBag::open(
            folder.join(format!("split_2.{storage}")),
            &Limits::default(),
        )
        .unwrap();
        assert_eq!((one.files(), one.topics()[1].messages), (1, 10));
        // The frame limit counts every file's messages.
        let mut few = Limits::default();
        few.max_frames = 25;
        let mut bag = RosBag::open(&folder, &few).unwrap();
        let e = bag.messages(DEPTH.1).unwrap_err();
        assert!(matches!(e, sl_io::IoError::TooLarge { .. }), "{e}");
    }
}

/// A RealSense device no preset models gets the Kinect's model, said with the device's name;
/// an L515 (a LiDAR camera: time of flight, no disparity) is said to be one.
#[test]
fn a_realsense_device_without_a_preset_is_named_in_its_noise_model() {
    let dir = tempfile::tempdir().unwrap();
    let px: Vec<u8> = (0..W * H).flat_map(|_| 4000u16.to_le_bytes()).collect();
    let conns: [Conn; 3] = [
        (
            0,
            "/device_0/sensor_0/Depth_0/image/data",
            "sensor_msgs/Image",
        ),
        (
            1,
            "/device_0/sensor_0/Depth_0/info/camera_info",
            "sensor_msgs/CameraInfo",
        ),
        (4, "/device_0/info", "diagnostic_msgs/KeyValue"),
    ];
    for (name, said) in [
        (
            "Intel RealSense L515",
            "though the Intel RealSense L515 is a LiDAR camera (time of flight)",
        ),
        (
            "Intel RealSense T265",
            "no preset models the Intel RealSense T265",
        ),
    ] {
        let msgs = vec![
            Msg {
                conn: 4,
                time: (0, 0),
                data: key_value_msg("Name", name),
            },
            Msg {
                conn: 1,
                time: (0, 0),
                data: camera_info(W, H, 380.5, "plumb_bob", &[0.0; 5], 0),
            },
            Msg {
                conn: 0,
                time: (0, 1000),
                data: image((1, 0), W, H, "16UC1", false, &px, 0),
            },
        ];
        let path = dir.path().join("rs.bag");
        sl_testkit::rosbag_writer::write_bag(&path, &conns, &msgs, "none", 4).unwrap();
        let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
        let cam = bag.depth_camera(conns[0].1).unwrap();
        assert!(
            cam.sensor_source.starts_with("the Kinect's noise model"),
            "{}",
            cam.sensor_source
        );
        assert!(cam.sensor_source.contains(said), "{}", cam.sensor_source);
    }
}
