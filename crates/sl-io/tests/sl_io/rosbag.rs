//! ROS 1 bags: depth and camera topics read back from bags this test writes by the format's
//! specification (uncompressed, bz2 and lz4 chunks), and malformed bags refused with errors.

use sl_io::Limits;
use sl_io::rosbag::{DepthEncodingKind, RosBag, is_bag_file};
use sl_testkit::rosbag_writer::{Conn, Msg, camera_info, image};

fn write_bag(path: &std::path::Path, conns: &[Conn], msgs: &[Msg], compression: &str, n: usize) {
    sl_testkit::rosbag_writer::write_bag(path, conns, msgs, compression, n).unwrap();
}

const DEPTH: Conn = (0, "/camera/depth/image_raw", "sensor_msgs/Image");
const INFO: Conn = (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo");
const IR: Conn = (2, "/camera/ir/image", "sensor_msgs/Image");

/// Three 4×3 depth frames in millimetres (16UC1), each with an IR image and a camera info,
/// stamped 10 ms before they were recorded.
fn kinect_messages() -> Vec<Msg> {
    let mut msgs = Vec::new();
    for i in 0..3u32 {
        let mm: Vec<u16> = (0..12)
            .map(|p| if p == 5 { 0 } else { 1000 + 10 * i as u16 + p })
            .collect();
        let px: Vec<u8> = mm.iter().flat_map(|v| v.to_le_bytes()).collect();
        let stamp = (100 + i, 0);
        msgs.push(Msg {
            conn: 0,
            time: (100 + i, 10_000_000),
            data: image(stamp, 4, 3, "16UC1", false, &px, 2),
        });
        msgs.push(Msg {
            conn: 2,
            time: (100 + i, 10_000_000),
            data: image(stamp, 4, 3, "mono16", false, &px, 0),
        });
        msgs.push(Msg {
            conn: 1,
            time: (100 + i, 10_000_000),
            data: camera_info(4, 3, 3.5, "plumb_bob", &[0.1, -0.2, 0.0, 0.0, 0.0], 0),
        });
    }
    msgs
}

/// Every compression reads the same frames: the depth topic found by its content (the IR
/// stream's `mono16` is not taken for depth), frames in order with their headers' stamps,
/// millimetres to metres, no depth where 0, rows padded beyond their pixels, and the camera of
/// the topic beside it with its lens model.
#[test]
fn a_bag_gives_its_depth_frames_and_camera() {
    let dir = tempfile::tempdir().unwrap();
    for compression in ["none", "bz2", "lz4"] {
        let path = dir.path().join(format!("{compression}.bag"));
        write_bag(
            &path,
            &[DEPTH, INFO, IR],
            &kinect_messages(),
            compression,
            4,
        );
        assert!(is_bag_file(&path));
        let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
        let topics = bag.topics();
        assert_eq!(topics.len(), 3);
        assert_eq!(topics[0].topic, "/camera/depth/camera_info");
        assert_eq!(topics[1].messages, 3);
        let topic = bag.depth_topic(None).unwrap();
        assert_eq!(topic, "/camera/depth/image_raw", "{compression}");
        let msgs = bag.messages(&topic).unwrap();
        assert_eq!(msgs.len(), 3);
        assert!((msgs[1].record_time_s - 101.01).abs() < 1e-9);
        for (i, m) in msgs.iter().enumerate() {
            let d = bag.read_depth(m, 1000.0, 1.0).unwrap();
            assert_eq!(d.kind, DepthEncodingKind::U16);
            assert_eq!(d.stamp_s, 100.0 + i as f64, "{compression}");
            assert_eq!((d.depth.width(), d.depth.height()), (4, 3));
            let v = d.depth.data();
            assert_eq!(v[5], 0.0);
            assert_eq!(v[11], (1000.0 + 10.0 * i as f64 + 11.0) as f32 / 1000.0);
        }
        let info = bag.camera_info_topic(&topic).unwrap();
        let cam = bag.camera(&info).unwrap();
        assert_eq!((cam.intrinsics.width, cam.intrinsics.fx), (4, 3.5));
        assert!(cam.lens.is_some());
        // An IR stream named for what it is can still be read when asked for.
        assert_eq!(
            bag.depth_topic(Some("/camera/ir/image")).unwrap(),
            "/camera/ir/image"
        );
    }
}

/// A ROS 1 recording split by `rosbag record --split` (`NAME_0.bag`, `NAME_1.bag`, …, as many
/// as it took): its folder reads as one recording, the pieces in number order (`_2` before
/// `_10`) and the messages in time order across them; a folder of bags of other names, or with
/// a piece missing, is not one recording.
#[test]
fn a_ros1_recording_split_into_pieces_reads_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("split");
    std::fs::create_dir(&folder).unwrap();
    let msgs = kinect_messages();
    // Twelve pieces, the first eleven empty of depth but for piece n's share: frames 0, 1, 2
    // in pieces 0, 2 and 10 (out of lexical order), the camera info in each.
    let mut pieces: Vec<Vec<Msg>> = vec![Vec::new(); 12];
    for (frame, piece) in [0usize, 2, 10].into_iter().enumerate() {
        pieces[piece].extend(msgs[3 * frame..3 * frame + 3].iter().cloned());
    }
    for (n, p) in pieces.iter().enumerate() {
        let file = folder.join(format!("rec_2024-05-01-10-00-00_{n}.bag"));
        let p = if p.is_empty() { &msgs[2..3] } else { &p[..] };
        write_bag(&file, &[DEPTH, INFO, IR], p, "lz4", 2);
    }
    assert!(is_bag_file(&folder));
    // The same pieces in a folder of TUM frames: the folder of frames.
    std::fs::write(folder.join("depth.txt"), "").unwrap();
    assert!(!is_bag_file(&folder));
    std::fs::remove_file(folder.join("depth.txt")).unwrap();
    let files = sl_io::rosbag::ros1_split_files(&folder).unwrap();
    assert!(
        files[10].ends_with("rec_2024-05-01-10-00-00_10.bag"),
        "{files:?}"
    );
    let mut bag = RosBag::open(&folder, &Limits::default()).unwrap();
    assert_eq!((bag.files(), bag.container()), (12, "ROS 1 bag"));
    let topic = bag.depth_topic(None).unwrap();
    let frames = bag.messages(&topic).unwrap();
    assert_eq!(frames.len(), 3);
    for (i, m) in frames.iter().enumerate() {
        assert_eq!(
            bag.read_depth(m, 1000.0, 1.0).unwrap().stamp_s,
            100.0 + i as f64
        );
    }
    // Each piece knows it is one: its index among all of them.
    assert_eq!(
        sl_io::rosbag::split_piece_of(&files[10]),
        Some((10, files.clone()))
    );
    // A piece missing, or a bag of another name beside: separate recordings, not one.
    let other = folder.join("other_0.bag");
    std::fs::copy(&files[0], &other).unwrap();
    assert!(!is_bag_file(&folder));
    let e = RosBag::open(&folder, &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("NAME_0.bag, NAME_1.bag"), "{e}");
    std::fs::remove_file(&other).unwrap();
    std::fs::remove_file(&files[5]).unwrap();
    assert!(sl_io::rosbag::ros1_split_files(&folder).is_none());
    // One piece alone is that piece; with a piece missing, no longer one of a recording.
    let one = RosBag::open(&files[2], &Limits::default()).unwrap();
    assert_eq!(one.files(), 1);
    assert_eq!(sl_io::rosbag::split_piece_of(&files[2]), None);
}

/// Float metres (`32FC1`, as TUM's bags hold depth), big-endian pixels, NaN and negative values
/// as no depth; two depth topics are an error listing both.
#[test]
fn float_and_big_endian_depth_and_several_depth_topics() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.bag");
    let z = [1.25f32, f32::NAN, -1.0, 2.5];
    let le: Vec<u8> = z.iter().flat_map(|v| v.to_le_bytes()).collect();
    let be: Vec<u8> = z.iter().flat_map(|v| v.to_be_bytes()).collect();
    let second: Conn = (3, "/camera/depth_registered/image", "sensor_msgs/Image");
    let msgs = vec![
        Msg {
            conn: 0,
            time: (5, 0),
            data: image((5, 0), 2, 2, "32FC1", false, &le, 0),
        },
        Msg {
            conn: 3,
            time: (5, 0),
            data: image((5, 0), 2, 2, "32FC1", true, &be, 0),
        },
    ];
    write_bag(&path, &[DEPTH, second], &msgs, "lz4", 8);
    let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
    let e = bag.depth_topic(None).unwrap_err().to_string();
    assert!(
        e.contains(
            "several depth image topics: /camera/depth/image_raw, /camera/depth_registered/image"
        ),
        "{e}"
    );
    for t in [DEPTH.1, second.1] {
        let m = bag.messages(t).unwrap()[0];
        let d = bag.read_depth(&m, 1000.0, 1.0).unwrap();
        assert_eq!(d.kind, DepthEncodingKind::F32);
        assert_eq!(d.depth.data(), &[1.25, 0.0, 0.0, 2.5], "{t}");
    }
    // No depth topic: the error lists the image topics there are.
    let rgb = dir.path().join("rgb.bag");
    let msgs = vec![Msg {
        conn: 0,
        time: (5, 0),
        data: image((5, 0), 1, 1, "rgb8", false, &[1, 2, 3], 0),
    }];
    write_bag(&rgb, &[DEPTH], &msgs, "none", 8);
    let mut bag = RosBag::open(&rgb, &Limits::default()).unwrap();
    let e = bag.depth_topic(None).unwrap_err().to_string();
    assert!(
        e.contains("no depth image topic") && e.contains("/camera/depth/image_raw"),
        "{e}"
    );
    let m = bag.messages(DEPTH.1).unwrap()[0];
    let e = bag.read_depth(&m, 1000.0, 1.0).unwrap_err().to_string();
    assert!(e.contains("\"rgb8\" is not depth"), "{e}");
}

/// Malformed bags: each an error naming the file, none a panic or an allocation sized from a
/// header.
#[test]
fn malformed_bags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.bag");
    write_bag(&good, &[DEPTH, INFO, IR], &kinect_messages(), "bz2", 4);
    let bytes = std::fs::read(&good).unwrap();
    let open = |b: &[u8], name: &str| -> String {
        let p = dir.path().join(name);
        std::fs::write(&p, b).unwrap();
        let mut bag = match RosBag::open(&p, &Limits::default()) {
            Ok(b) => b,
            Err(e) => return e.to_string(),
        };
        let t = match bag.depth_topic(None) {
            Ok(t) => t,
            Err(e) => return e.to_string(),
        };
        let msgs = match bag.messages(&t) {
            Ok(m) => m,
            Err(e) => return e.to_string(),
        };
        for m in &msgs {
            if let Err(e) = bag.read_depth(m, 1000.0, 1.0) {
                return e.to_string();
            }
        }
        "read".to_string()
    };
    assert_eq!(open(&bytes, "copy.bag"), "read");
    assert!(open(b"#ROSBAG V1.2\nxx", "v1.bag").contains("format 1.x"));
    assert!(open(b"PK\x03\x04", "zip.bag").contains("not a ROS 1 bag"));
    // Cut anywhere, at a record's end too: an error, never a panic or fewer frames.
    for cut in (13..bytes.len()).step_by(97).chain([bytes.len() - 1]) {
        let e = open(&bytes[..cut], "cut.bag");
        assert_ne!(e, "read", "cut at {cut}");
    }
    // Cut just before the last chunk info record: the index is short of a chunk.
    let op6 = b"\x04\0\0\0op=\x06";
    let last = bytes.len() - op6.len() - bytes.windows(8).rev().position(|w| w == op6).unwrap();
    let e = open(&bytes[..last - 4], "short-index.bag");
    assert!(
        e.contains("the bag header says 3 and 3 (a bag cut short)"),
        "{e}"
    );
    // The first chunk info counting one depth message more than the index records after its
    // chunk list (its pairs are `conn, count`; the depth topic's connection is 0).
    let mut miscounted = bytes.clone();
    let record_at = find(&bytes, op6) - 4;
    let header_len =
        u32::from_le_bytes(miscounted[record_at..record_at + 4].try_into().unwrap()) as usize;
    let data_at = record_at + 4 + header_len + 4;
    let n_pairs =
        u32::from_le_bytes(miscounted[data_at - 4..data_at].try_into().unwrap()) as usize / 8;
    for pair in (data_at..data_at + 8 * n_pairs).step_by(8) {
        if miscounted[pair..pair + 4] == 0u32.to_le_bytes() {
            miscounted[pair + 4] += 1;
        }
    }
    let e = open(&miscounted, "miscounted.bag");
    assert!(
        e.contains("messages of /camera/depth/image_raw, its chunk info"),
        "{e}"
    );
    // An unindexed bag (a recording that was not closed).
    let mut unindexed = bytes.clone();
    let at = find(&unindexed, b"index_pos=") + 10;
    unindexed[at..at + 8].copy_from_slice(&0u64.to_le_bytes());
    assert!(open(&unindexed, "open.bag").contains("rosbag reindex"));
    // A chunk claiming 4 GB decompressed is refused before anything is allocated for it.
    let mut bomb = bytes.clone();
    let at = find(&bomb, b"size=") + 5;
    bomb[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = open(&bomb, "bomb.bag");
    assert!(e.contains("budget"), "{e}");
    // A chunk whose size is one byte short of what it decompresses to.
    let mut short = bytes.clone();
    let n = u32::from_le_bytes(short[at..at + 4].try_into().unwrap());
    short[at..at + 4].copy_from_slice(&(n - 1).to_le_bytes());
    let e = open(&short, "short.bag");
    assert!(e.contains("its header says"), "{e}");
    // Corrupt compressed data.
    let mut corrupt = bytes.clone();
    let at = find(&corrupt, b"BZh") + 40;
    for b in &mut corrupt[at..at + 16] {
        *b ^= 0x5a;
    }
    assert_ne!(open(&corrupt, "corrupt.bag"), "read");
    // Binning in the camera info is refused, as in a YAML file.
    let binned = dir.path().join("binned.bag");
    let mut msgs = kinect_messages();
    msgs[2].data = camera_info(4, 3, 3.5, "plumb_bob", &[0.0; 5], 2);
    write_bag(&binned, &[DEPTH, INFO], &msgs, "none", 9);
    let mut bag = RosBag::open(&binned, &Limits::default()).unwrap();
    let e = bag.camera(INFO.1).unwrap_err().to_string();
    assert!(e.contains("binning_x is 2"), "{e}");
    // More frames than the budget allows.
    let mut small = Limits::default();
    small.max_frames = 2;
    let mut bag = RosBag::open(&good, &small).unwrap();
    assert!(
        bag.messages(DEPTH.1)
            .unwrap_err()
            .to_string()
            .contains("more than 2 messages")
    );
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len()).position(|w| w == needle).unwrap()
}

/// A `sensor_msgs/CompressedImage` of `image_transport`'s `compressedDepth`: `format`, then
/// the 12-byte configuration header (format 0, quantisation `a`, `b`) and `values` as a PNG,
/// or RVL when `format` names it.
fn compressed_depth(
    stamp: (u32, u32),
    format: &str,
    a: f32,
    b: f32,
    values: &sl_core::Image<u16>,
) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let data = if format.ends_with("rvl") {
        sl_testkit::rosbag_writer::compressed_depth_rvl_data(a, b, values)
    } else {
        sl_testkit::rosbag_writer::compressed_depth_data(&dir.path().join("q.png"), a, b, values)
            .unwrap()
    };
    let mut m = Vec::new();
    m.extend_from_slice(&3u32.to_le_bytes());
    m.extend_from_slice(&stamp.0.to_le_bytes());
    m.extend_from_slice(&stamp.1.to_le_bytes());
    m.extend_from_slice(&1u32.to_le_bytes());
    m.push(b'd');
    m.extend_from_slice(&(format.len() as u32).to_le_bytes());
    m.extend_from_slice(format.as_bytes());
    m.extend_from_slice(&(data.len() as u32).to_le_bytes());
    m.extend_from_slice(&data);
    m
}

/// `compressedDepth` topics (what a robot records over a network): `16UC1` PNG millimetres,
/// and `32FC1` as quantised inverse depth `q = a/z + b`, decoded as `z = a/(q − b)`; the topic
/// found by its format, its camera info one level up (`…/image_raw/compressedDepth` →
/// `…/camera_info`); the RVL codec too.
#[test]
fn compressed_depth_topics_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let mm = sl_core::Image::from_vec(3, 2, vec![1000u16, 0, 1500, 2000, 2500, 65534]).unwrap();
    let (a, b) = (100.0f32, 20.0f32);
    // Inverse depth of 1 m and 2 m (q = 120, 70) and none.
    let q = sl_core::Image::from_vec(3, 1, vec![120u16, 70, 0]).unwrap();
    let mm_topic: Conn = (
        0,
        "/camera/depth/image_raw/compressedDepth",
        "sensor_msgs/CompressedImage",
    );
    let f_topic: Conn = (
        3,
        "/camera/depth_registered/image/compressedDepth",
        "sensor_msgs/CompressedImage",
    );
    let msgs = vec![
        Msg {
            conn: 0,
            time: (7, 0),
            data: compressed_depth((7, 500), "16UC1; compressedDepth png", 0.0, 0.0, &mm),
        },
        Msg {
            conn: 1,
            time: (7, 0),
            data: camera_info(3, 2, 2.0, "plumb_bob", &[0.0; 5], 0),
        },
        Msg {
            conn: 3,
            time: (7, 0),
            data: compressed_depth((7, 0), "32FC1; compressedDepth", a, b, &q),
        },
    ];
    let path = dir.path().join("c.bag");
    write_bag(&path, &[mm_topic, INFO, f_topic], &msgs, "lz4", 8);
    let mut bag = RosBag::open(&path, &Limits::default()).unwrap();
    let e = bag.depth_topic(None).unwrap_err().to_string();
    assert!(e.contains("several depth image topics"), "{e}");
    let m = bag.messages(mm_topic.1).unwrap()[0];
    let d = bag.read_depth(&m, 1000.0, 1.0).unwrap();
    assert_eq!(d.kind, DepthEncodingKind::U16);
    assert_eq!(d.stamp_s, 7.0 + 500e-9);
    assert_eq!(d.depth.data(), &[1.0, 0.0, 1.5, 2.0, 2.5, 65.534]);
    assert_eq!(bag.camera_info_topic(mm_topic.1).as_deref(), Some(INFO.1));
    let m = bag.messages(f_topic.1).unwrap()[0];
    let d = bag.read_depth(&m, 1000.0, 1.0).unwrap();
    assert_eq!(d.kind, DepthEncodingKind::F32);
    assert_eq!(d.depth.data(), &[1.0, 2.0, 0.0]);
    // RVL, the plugin's other codec, in both encodings; a codec it does not have is refused.
    let rvl = dir.path().join("rvl.bag");
    let msgs = vec![
        Msg {
            conn: 0,
            time: (7, 0),
            data: compressed_depth((7, 0), "16UC1; compressedDepth rvl", 0.0, 0.0, &mm),
        },
        Msg {
            conn: 3,
            time: (7, 0),
            data: compressed_depth((7, 0), "32FC1; compressedDepth rvl", a, b, &q),
        },
        Msg {
            conn: 0,
            time: (8, 0),
            data: compressed_depth((8, 0), "16UC1; compressedDepth jpeg", 0.0, 0.0, &mm),
        },
    ];
    write_bag(&rvl, &[mm_topic, f_topic], &msgs, "none", 8);
    let mut bag = RosBag::open(&rvl, &Limits::default()).unwrap();
    let m = bag.messages(mm_topic.1).unwrap()[0];
    let d = bag.read_depth(&m, 1000.0, 1.0).unwrap();
    assert_eq!(d.kind, DepthEncodingKind::U16);
    assert_eq!(d.depth.data(), &[1.0, 0.0, 1.5, 2.0, 2.5, 65.534]);
    let m = bag.messages(f_topic.1).unwrap()[0];
    let d = bag.read_depth(&m, 1000.0, 1.0).unwrap();
    assert_eq!(d.kind, DepthEncodingKind::F32);
    assert_eq!(d.depth.data(), &[1.0, 2.0, 0.0]);
    let m = bag.messages(mm_topic.1).unwrap()[1];
    let e = bag.read_depth(&m, 1000.0, 1.0).unwrap_err().to_string();
    assert!(
        e.contains("a compressedDepth codec other than png and rvl"),
        "{e}"
    );
}

/// ROS 2 bags in MCAP: CDR messages (aligned, no `seq`, NUL-terminated strings) in chunks of
/// none, zstd and lz4, found through the summary and the message indexes; a ROS 2 bag's
/// folder (`metadata.yaml` beside its one `.mcap`) opens as its file; cut files are refused.
#[test]
fn mcap_bags_give_their_depth_frames_and_camera() {
    use sl_testkit::rosbag_writer::{camera_info_cdr, image_cdr, write_mcap};
    let dir = tempfile::tempdir().unwrap();
    let depth: Conn = (1, "/camera/depth/image_rect_raw", "sensor_msgs/msg/Image");
    let info: Conn = (2, "/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo");
    let mut msgs = Vec::new();
    for i in 0..3u32 {
        let mm: Vec<u8> = (0..12u16)
            .flat_map(|p| (if p == 4 { 0 } else { 900 + 10 * i as u16 + p }).to_le_bytes())
            .collect();
        let t = (200 + i, 40_000_000);
        msgs.push(Msg {
            conn: 1,
            time: (200 + i, 70_000_000),
            data: image_cdr(t, 4, 3, "16UC1", &mm),
        });
        msgs.push(Msg {
            conn: 2,
            time: (200 + i, 70_000_000),
            data: camera_info_cdr(4, 3, 3.5, "plumb_bob", &[0.05, 0.0, 0.0, 0.0, 0.0]),
        });
    }
    for compression in ["", "zstd", "lz4"] {
        let folder = dir.path().join(format!("ros2-{compression}"));
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(
            folder.join("metadata.yaml"),
            "rosbag2_bagfile_information:\n",
        )
        .unwrap();
        let file = folder.join("ros2_0.mcap");
        write_mcap(&file, &[depth, info], &msgs, compression, 3).unwrap();
        assert!(is_bag_file(&folder) && is_bag_file(&file));
        let mut bag = RosBag::open(&folder, &Limits::default()).unwrap();
        assert_eq!(bag.topics()[1].message_type, "sensor_msgs/Image");
        assert_eq!(bag.topics()[1].messages, 3);
        let topic = bag.depth_topic(None).unwrap();
        assert_eq!(topic, depth.1);
        let frames = bag.messages(&topic).unwrap();
        assert_eq!(frames.len(), 3);
        for (i, m) in frames.iter().enumerate() {
            let d = bag.read_depth(m, 1000.0, 1.0).unwrap();
            assert_eq!(d.stamp_s, 200.0 + i as f64 + 0.04, "{compression:?}");
            assert_eq!(d.depth.data()[4], 0.0);
            assert_eq!(
                d.depth.data()[11],
                (900.0 + 10.0 * i as f64 + 11.0) as f32 / 1000.0
            );
        }
        let cam = bag.camera(&bag.camera_info_topic(&topic).unwrap()).unwrap();
        assert_eq!((cam.intrinsics.width, cam.intrinsics.fx), (4, 3.5));
        assert!(cam.lens.is_some());
    }
    // Cut short: the footer is gone, an error that says how to mend it.
    let file = dir.path().join("ros2-zstd").join("ros2_0.mcap");
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() - 10]).unwrap();
    let e = RosBag::open(&cut, &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("mcap recover"), "{e}");
    for at in (8..bytes.len()).step_by(61) {
        std::fs::write(&cut, &bytes[..at]).unwrap();
        assert!(
            RosBag::open(&cut, &Limits::default()).is_err(),
            "cut at {at}"
        );
    }
}
