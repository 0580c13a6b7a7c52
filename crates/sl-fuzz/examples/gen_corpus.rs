//! Writes the seed corpus of the fuzz targets into `fuzz/corpus/<target>/` from
//! project-generated data (small synthetic frames, cameras, trajectories and meshes written by
//! sl-io's own writers). Run: `cargo run -p sl-fuzz --example gen_corpus`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use sl_core::nalgebra::Isometry3;
use sl_core::{Camera, CameraToWorld, DepthImage, Image};
use sl_io::depth::{DepthEncoding, write_depth};
use sl_io::ply::{PlyData, PlyFormat, write_ply};

fn ramp(w: usize, h: usize) -> DepthImage {
    DepthImage::from_image(Image::from_fn(w, h, |x, y| {
        if (x + 2 * y) % 5 == 0 {
            0.0
        } else {
            0.8 + 0.01 * (x + w * y) as f32
        }
    }))
}

fn put(root: &Path, target: &str, name: &str, bytes: &[u8]) {
    let dir = root.join(target);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(name), bytes).unwrap();
}

/// Writes with an sl-io writer into a temporary file and returns the bytes.
fn bytes_of(ext: &str, write: impl FnOnce(&Path)) -> Vec<u8> {
    let dir = std::env::temp_dir().join(format!("sl-fuzz-gen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("seed.{ext}"));
    write(&p);
    let b = std::fs::read(&p).unwrap();
    std::fs::remove_file(&p).unwrap();
    b
}

/// A tiny frame in the encoding of `sl_fuzz::tiny_frame` (16-bit millimetres).
fn frame_bytes(w: u8, h: u8, f: u8, depth: impl Fn(usize, usize) -> u16) -> Vec<u8> {
    let mut b = vec![0, w - 1, h - 1, f];
    for y in 0..usize::from(h) {
        for x in 0..usize::from(w) {
            b.extend_from_slice(&depth(x, y).to_le_bytes());
        }
    }
    b
}

/// Depth (mm) at pixel `(x, y)` of a 24×24 camera with f = 240.5 px (`tiny_frame`'s focal
/// byte 120; a Kinect-like depth noise of a few millimetres at 1 m) looking into three faces
/// that meet 1 m ahead, their normals 37° off the axis and 120° apart around it, the camera
/// moved by `dx` metres along x.
fn corner_depth_mm(x: usize, y: usize, dx: f64) -> u16 {
    let (f, c) = (240.5, 11.5);
    let r = [(x as f64 - c) / f, (y as f64 - c) / f, 1.0];
    let faces = [[0.6, 0.0, -0.8], [-0.3, 0.52, -0.8], [-0.3, -0.52, -0.8]];
    let t = faces
        .iter()
        .map(|n| {
            // n·(P0 − O) / n·r with P0 = (0, 0, 1), O = (dx, 0, 0).
            (n[2] - n[0] * dx) / (n[0] * r[0] + n[1] * r[1] + n[2] * r[2])
        })
        .filter(|t| *t > 0.0)
        .fold(f64::INFINITY, f64::min);
    (t * 1000.0).round() as u16
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus");
    let d = ramp(8, 6);
    for (target, ext, enc) in [
        ("depth_png", "png", DepthEncoding::png(1000.0)),
        ("depth_png", "png", DepthEncoding::seven_scenes()),
        ("depth_tiff", "tif", DepthEncoding::tiff(5000.0)),
        ("depth_pgm", "pgm", DepthEncoding::nyu_raw()),
        ("depth_sun", "png", DepthEncoding::sun()),
    ] {
        let b = bytes_of(ext, |p| write_depth(p, &d, &enc).unwrap());
        put(
            &root,
            target,
            &format!("ramp-{}.{ext}", enc.invalid_value),
            &b,
        );
    }
    // Float depth in a TIFF (metres, as ROS and OpenCV write it).
    let b = bytes_of("tif", |p| {
        write_depth(p, &d, &DepthEncoding::tiff_f32(1.0)).unwrap()
    });
    put(&root, "depth_tiff", "ramp-f32.tif", &b);
    put(
        &root,
        "depth_pgm",
        "p6.ppm",
        b"P6 2 1 255\n\x01\x02\x03\x04\x05\x06",
    );

    let cam = Camera::kinect_v1();
    let b = bytes_of("json", |p| sl_io::write_camera_json(p, &cam).unwrap());
    put(&root, "camera_json", "kinect.json", &b);
    put(
        &root,
        "camera_json",
        "open3d.json",
        br#"{"width": 64, "height": 48, "intrinsic_matrix": [52.5, 0, 0, 0, 52.5, 0, 31.5, 23.5, 1]}"#,
    );
    // ROS camera calibrations (the same target reads its bytes as YAML too).
    put(
        &root,
        "camera_json",
        "ros1-camera-info.yaml",
        b"header: \n  seq: 1\n  frame_id: \"/camera_depth_optical_frame\"\nheight: 48\nwidth: 64\n\
          distortion_model: \"plumb_bob\"\nD: [0.0, 0.0, 0.0, 0.0, 0.0]\n\
          K: [52.5, 0.0, 31.5, 0.0, 52.5, 23.5, 0.0, 0.0, 1.0]\nbinning_x: 0\nbinning_y: 0\n---\n",
    );
    put(
        &root,
        "camera_json",
        "ost.yaml",
        b"image_width: 64\nimage_height: 48\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [ 52.5, 0., \
          31.5, 0., 52.5,\n      23.5, 0., 0., 1. ]\ndistortion_model: plumb_bob\n\
          distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [ -0.1, 0.2, 0., 0., 0. ]\n",
    );
    // ROS 1 bags: two 4×3 depth frames (16-bit millimetres, big-endian in the second, a padded
    // row), an infrared mono16 stream and the camera info beside them, in bz2 and lz4 chunks.
    {
        use sl_testkit::rosbag_writer::{Msg, camera_info, image, write_bag};
        let conns = [
            (0, "/camera/depth/image_raw", "sensor_msgs/Image"),
            (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo"),
            (2, "/camera/ir/image", "sensor_msgs/Image"),
        ];
        let mut msgs = Vec::new();
        for i in 0..2u32 {
            let mm: Vec<u8> = (0..12u16)
                .flat_map(|p| {
                    let v = if p == 5 { 0 } else { 1000 + p };
                    if i == 1 {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    }
                })
                .collect();
            let t = (100 + i, 0);
            msgs.push(Msg {
                conn: 0,
                time: t,
                data: image(t, 4, 3, "16UC1", i == 1, &mm, 2),
            });
            msgs.push(Msg {
                conn: 2,
                time: t,
                data: image(t, 4, 3, "mono16", false, &mm, 0),
            });
            msgs.push(Msg {
                conn: 1,
                time: t,
                data: camera_info(4, 3, 3.5, "plumb_bob", &[0.1, 0.0, 0.0, 0.0, 0.0], 0),
            });
        }
        for compression in ["bz2", "lz4"] {
            let b = bytes_of("bag", |p| {
                write_bag(p, &conns, &msgs, compression, 3).unwrap()
            });
            put(&root, "rosbag", &format!("kinect-{compression}.bag"), &b);
        }
        // `compressedDepth`: the configuration header, then a 16-bit PNG of millimetres; and
        // the same with the RVL codec (runs of zeros and of values).
        let png = bytes_of("png", |p| {
            write_depth(p, &ramp(4, 3), &DepthEncoding::png(1000.0)).unwrap()
        });
        let mm: Vec<u16> = (0..48u16)
            .map(|i| if i % 7 < 2 { 0 } else { 900 + 13 * i })
            .collect();
        let rvl =
            sl_testkit::rosbag_writer::rvl_encode(&sl_core::Image::from_vec(8, 6, mm).unwrap());
        for (codec, image, name) in [
            ("png", png, "compressed-depth.bag"),
            ("rvl", rvl, "compressed-depth-rvl.bag"),
        ] {
            let mut data = [0u8; 12].to_vec();
            data.extend_from_slice(&image);
            let mut m = Vec::new();
            for v in [0u32, 100, 0, 0] {
                m.extend_from_slice(&v.to_le_bytes());
            }
            let format = format!("16UC1; compressedDepth {codec}");
            m.extend_from_slice(&(format.len() as u32).to_le_bytes());
            m.extend_from_slice(format.as_bytes());
            m.extend_from_slice(&(data.len() as u32).to_le_bytes());
            m.extend_from_slice(&data);
            let conns = [(
                0,
                "/camera/depth/image_raw/compressedDepth",
                "sensor_msgs/CompressedImage",
            )];
            let msgs = [Msg {
                conn: 0,
                time: (100, 0),
                data: m,
            }];
            let b = bytes_of("bag", |p| write_bag(p, &conns, &msgs, "none", 1).unwrap());
            put(&root, "rosbag", name, &b);
        }
        // A ROS 2 bag in MCAP: two CDR depth frames and the camera info, in zstd chunks.
        let conns = [
            (1, "/camera/depth/image_rect_raw", "sensor_msgs/msg/Image"),
            (2, "/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo"),
        ];
        let mut msgs = Vec::new();
        for i in 0..2u32 {
            let mm: Vec<u8> = (0..12u16).flat_map(|p| (1000 + p).to_le_bytes()).collect();
            let t = (100 + i, 0);
            msgs.push(Msg {
                conn: 1,
                time: t,
                data: sl_testkit::rosbag_writer::image_cdr(t, 4, 3, "16UC1", &mm),
            });
            msgs.push(Msg {
                conn: 2,
                time: t,
                data: sl_testkit::rosbag_writer::camera_info_cdr(4, 3, 3.5, "plumb_bob", &[0.0; 5]),
            });
        }
        let b = bytes_of("mcap", |p| {
            sl_testkit::rosbag_writer::write_mcap(p, &conns, &msgs, "zstd", 2).unwrap()
        });
        put(&root, "rosbag", "ros2-zstd.mcap", &b);
        // A `realsense2_camera` recording: depth and its camera info (`Tx = 0`), and the
        // baseline in `infra2/camera_info`'s projection matrix (`P[3] = −f·B`).
        let conns = [
            (0, "/camera/depth/image_rect_raw", "sensor_msgs/Image"),
            (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo"),
            (2, "/camera/infra2/camera_info", "sensor_msgs/CameraInfo"),
        ];
        let mm: Vec<u8> = (0..12u16).flat_map(|p| (1000 + p).to_le_bytes()).collect();
        let msgs = [
            Msg {
                conn: 0,
                time: (100, 0),
                data: image((100, 0), 4, 3, "16UC1", false, &mm, 0),
            },
            Msg {
                conn: 1,
                time: (100, 0),
                data: camera_info(4, 3, 426.0, "plumb_bob", &[0.0; 5], 0),
            },
            Msg {
                conn: 2,
                time: (100, 0),
                data: sl_testkit::rosbag_writer::camera_info_tx(
                    4,
                    3,
                    426.0,
                    "plumb_bob",
                    &[0.0; 5],
                    0,
                    -426.0 * 0.05,
                ),
            },
        ];
        let b = bytes_of("bag", |p| write_bag(p, &conns, &msgs, "none", 3).unwrap());
        put(&root, "rosbag", "realsense2-camera.bag", &b);
        // Transforms beside depth, in ROS 1 and in CDR: a moving `world → base` (two samples)
        // and a static `base → camera_depth_optical_frame`.
        for cdr in [false, true] {
            use sl_testkit::rosbag_writer::{TfEntry, tf_message};
            let tf = |t: (u32, u32), parent: &str, child: &str, x: f64| TfEntry {
                stamp: t,
                parent: parent.into(),
                child: child.into(),
                translation: [x, 0.0, 0.5],
                rotation: [0.0, 0.0, 0.0, 1.0],
            };
            let ty = if cdr {
                "tf2_msgs/msg/TFMessage"
            } else {
                "tf2_msgs/TFMessage"
            };
            let conns = [
                (
                    1,
                    "/camera/depth/image_rect_raw",
                    if cdr {
                        "sensor_msgs/msg/Image"
                    } else {
                        "sensor_msgs/Image"
                    },
                ),
                (3, "/tf", ty),
                (4, "/tf_static", ty),
            ];
            let mut msgs = Vec::new();
            for i in 0..2u32 {
                let mm: Vec<u8> = (0..12u16).flat_map(|p| (1000 + p).to_le_bytes()).collect();
                let t = (100 + i, 0);
                msgs.push(Msg {
                    conn: 3,
                    time: t,
                    data: tf_message(&[tf(t, "world", "base", f64::from(i))], cdr),
                });
                msgs.push(Msg {
                    conn: 1,
                    time: t,
                    data: if cdr {
                        sl_testkit::rosbag_writer::image_cdr(t, 4, 3, "16UC1", &mm)
                    } else {
                        image(t, 4, 3, "16UC1", false, &mm, 0)
                    },
                });
            }
            msgs.push(Msg {
                conn: 4,
                time: (101, 0),
                data: tf_message(
                    &[tf((0, 0), "base", "camera_depth_optical_frame", 0.0)],
                    cdr,
                ),
            });
            let (ext, name) = if cdr {
                ("mcap", "tf.mcap")
            } else {
                ("bag", "tf.bag")
            };
            let b = bytes_of(ext, |p| {
                if cdr {
                    sl_testkit::rosbag_writer::write_mcap(p, &conns, &msgs, "", 2).unwrap()
                } else {
                    write_bag(p, &conns, &msgs, "none", 2).unwrap()
                }
            });
            put(&root, "rosbag", name, &b);
        }
        // A RealSense recording in SQLite (librealsense 2.56+): 512-byte pages (interior pages,
        // overflow chains), the sensor's options as strings, frames' metadata.
        let rs = |n, t, ty| (n, t, ty);
        let conns = [
            rs(
                1,
                "/device_0/sensor_0/Depth_0/image/data",
                "sensor_msgs/msg/Image",
            ),
            rs(
                2,
                "/device_0/sensor_0/Depth_0/image/camera_info",
                "sensor_msgs/msg/CameraInfo",
            ),
            rs(
                3,
                "/device_0/sensor_0/option/Depth_Units/value",
                "std_msgs/msg/String",
            ),
            rs(4, "/device_0/info", "std_msgs/msg/String"),
            rs(
                5,
                "/device_0/sensor_0/Depth_0/image/metadata",
                "std_msgs/msg/String",
            ),
        ];
        let text = |s: &str| sl_testkit::rosbag_writer::string_msg(s, true);
        let mut msgs = vec![
            Msg {
                conn: 3,
                time: (0, 0),
                data: text("0.001000"),
            },
            Msg {
                conn: 4,
                time: (0, 0),
                data: text("Name=Intel RealSense D435;Serial Number=1"),
            },
        ];
        for i in 0..4u32 {
            let mm: Vec<u8> = (0..320u16).flat_map(|p| (1000 + p).to_le_bytes()).collect();
            let t = (0, 1000 + i * 33_000_000);
            msgs.push(Msg {
                conn: 1,
                time: t,
                data: sl_testkit::rosbag_writer::image_cdr(t, 20, 16, "16UC1", &mm),
            });
            msgs.push(Msg {
                conn: 2,
                time: t,
                data: sl_testkit::rosbag_writer::camera_info_cdr(
                    20,
                    16,
                    15.0,
                    "plumb_bob",
                    &[0.0; 5],
                ),
            });
            msgs.push(Msg {
                conn: 5,
                time: t,
                data: text(&format!(
                    "Frame number={i};timestamp={}.5;",
                    1_700_000_000_000u64 + 33 * u64::from(i)
                )),
            });
        }
        let b = bytes_of("db3", |p| {
            sl_testkit::sqlite_writer::write_db3(p, 512, &conns, &msgs).unwrap()
        });
        put(&root, "rosbag", "realsense-512.db3", &b);
    }
    put(
        &root,
        "intrinsics_txt",
        "7scenes.txt",
        b"585 0 320\n0 585 240\n0 0 1\n",
    );
    put(
        &root,
        "intrinsics_txt",
        "pose.txt",
        b"1 0 0 0.1\n0 1 0 0.2\n0 0 1 0.3\n0 0 0 1\n",
    );

    let poses: Vec<sl_io::TimedPose> = (0..4)
        .map(|i| sl_io::TimedPose {
            timestamp: 1.0 + f64::from(i) * 0.03,
            pose: CameraToWorld::from_isometry(Isometry3::translation(
                0.01 * f64::from(i),
                0.0,
                0.0,
            )),
        })
        .collect();
    let b = bytes_of("txt", |p| {
        sl_io::trajectory::write_tum_trajectory(p, &poses).unwrap()
    });
    put(&root, "tum_trajectory", "groundtruth.txt", &b);
    put(
        &root,
        "tum_associations",
        "associations.txt",
        b"# rgb depth\n1.0 rgb/1.png 1.01 depth/1.png\n1.03 rgb/2.png 1.04 depth/2.png\n",
    );
    let plain: Vec<CameraToWorld> = poses.iter().map(|p| p.pose).collect();
    let b = bytes_of("log", |p| {
        sl_io::trajectory::write_open3d_log(p, &plain).unwrap()
    });
    put(&root, "open3d_log", "trajectory.log", &b);
    put(
        &root,
        "frame_list",
        "frames.txt",
        b"# path and row-major pose\nd/0.png 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\nd/1.png 1 0 0 0.1 0 1 0 0 0 0 1 0 0 0 0 1 # moved\n",
    );

    put(
        &root,
        "tum_depth_list",
        "depth.txt",
        b"# depth maps\n# timestamp filename\n1305031102.160407 depth/1305031102.160407.png\n1305031102.194330 depth/1305031102.194330.png\n",
    );

    let cloud = PlyData::from_positions(vec![[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.2]])
        .with_colors(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255]])
        .with_scalar("confidence", vec![0.5, 1.0, 2.0]);
    let mesh =
        PlyData::mesh(cloud.positions.clone(), vec![[0, 1, 2]])
            .with_normals(vec![[0.0, 0.0, -1.0]; 3]);
    for (name, data, format) in [
        ("cloud-bin.ply", &cloud, PlyFormat::BinaryLittleEndian),
        ("cloud-ascii.ply", &cloud, PlyFormat::Ascii),
        ("mesh-bin.ply", &mesh, PlyFormat::BinaryLittleEndian),
        ("mesh-ascii.ply", &mesh, PlyFormat::Ascii),
    ] {
        let b = bytes_of("ply", |p| write_ply(p, data, format).unwrap());
        put(&root, "ply", name, &b);
    }

    // Algorithm targets: a wall, a slanted floor with a step, and a frame with holes.
    let wall = frame_bytes(16, 12, 10, |_, _| 1500);
    let floor = frame_bytes(16, 12, 10, |x, y| {
        900 + 40 * y as u16 + if x > 8 { 100 } else { 0 }
    });
    let holes = frame_bytes(12, 12, 8, |x, y| if (x * y) % 3 == 0 { 0 } else { 2000 });
    for (name, f) in [("wall", &wall), ("floor", &floor), ("holes", &holes)] {
        for (i, method) in [0u8, 1, 2, 3].iter().enumerate() {
            if i == 0 || name == "floor" {
                let mut b = vec![*method, 2, 16, 3, 0, 0];
                b.extend_from_slice(f);
                put(&root, "filter", &format!("{name}-{method}"), &b);
            }
        }
        put(&root, "planes", name, f);
        let mut tsdf = vec![4, 5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0];
        tsdf.extend_from_slice(f);
        put(&root, "tsdf", name, &tsdf);
    }
    for (name, f) in [("wall", &wall), ("floor", &floor), ("holes", &holes)] {
        let mut b = vec![2, 2, 4, 0];
        b.extend_from_slice(f);
        put(&root, "multiscale", name, &b);
        put(
            &root,
            "noise_stats",
            name,
            &[&[0u8, 8, 4, 64][..], f].concat(),
        );
    }
    // Tracking: three faces meeting in a corner (a view that pins every direction of the pose)
    // seen by a still camera, and by one moving 1 cm a frame along x, frame to model
    // and frame to frame with a rolling shutter; a single plane (degenerate) for the other
    // path.
    let corner = |dx: f64| frame_bytes(24, 24, 120, |x, y| corner_depth_mm(x, y, dx));
    let body = |f: &[u8]| f[4..].to_vec();
    let still = [corner(0.0), body(&corner(0.0)), body(&corner(0.0))].concat();
    let moving = [
        corner(0.0),
        body(&corner(0.01)),
        body(&corner(0.02)),
        body(&corner(0.03)),
    ]
    .concat();
    let single = [floor.clone(), body(&floor), body(&floor)].concat();
    // Head: mode (bit 0 frame to frame, bit 1 rolling shutter), enlargement − 1, timestamps.
    for (name, mode, enlarge, frames) in [
        ("still-corner", 0u8, 7u8, &still),
        ("moving-corner", 0, 7, &moving),
        ("moving-corner-f2f-rs", 3, 7, &moving),
        ("still-floor", 0, 0, &single),
    ] {
        let head = [mode, enlarge, 1, 2, 3, 4, 0, 0];
        put(&root, "track", name, &[&head[..], frames].concat());
    }
    let mut pair = floor.clone();
    pair.extend_from_slice(&floor);
    put(&root, "motion", "floor-floor", &pair);
    let mut pair = wall.clone();
    pair.extend_from_slice(&floor);
    put(&root, "motion", "wall-floor", &pair);
    println!("wrote the seed corpus under {}", root.display());
}
