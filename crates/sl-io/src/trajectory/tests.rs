//! Tests of the trajectory files: round trips and error lines of each format, pose association
//! by time, 7-Scenes folders and the order of numbered names.

use sl_core::nalgebra::{Isometry3, Vector3};

use super::*;
use crate::error::IoError;
use crate::limits::Limits;

fn c2w(t: Vector3<f64>, r: Vector3<f64>) -> CameraToWorld {
    CameraToWorld::from_isometry(Isometry3::new(t, r))
}

#[test]
fn timestamps_print_with_microseconds_unless_that_repeats_one() {
    let tum = [1305031229.528784, 1305031229.564442];
    let p = timestamp_printer(&tum);
    assert_eq!(p(tum[0]), "1305031229.528784");
    let close = [1e9, 1e9 + 2.4e-7, 1e9 + 4.8e-7];
    let p = timestamp_printer(&close);
    let printed: Vec<String> = close.iter().map(|&t| p(t)).collect();
    assert_eq!(printed[0], "1000000000.000000000");
    assert!(
        printed[1] != printed[0] && printed[2] != printed[1],
        "{printed:?}"
    );
    let tiny = [0.0, 5e-324];
    let p = timestamp_printer(&tiny);
    assert!(p(tiny[1]).parse::<f64>().unwrap() == 5e-324 && p(tiny[0]) != p(tiny[1]));
}

fn tp(t: f64) -> TimedPose {
    TimedPose {
        timestamp: t,
        pose: c2w(Vector3::new(t, 0.0, 0.0), Vector3::zeros()),
    }
}

#[test]
fn nearest_within_tolerance() {
    let poses = [tp(1.0), tp(1.01), tp(1.02), tp(2.0)];
    assert_eq!(nearest_pose(&poses, 1.012, 0.02).unwrap().timestamp, 1.01);
    assert_eq!(nearest_pose(&poses, 1.016, 0.02).unwrap().timestamp, 1.02);
    assert_eq!(nearest_pose(&poses, 0.99, 0.02).unwrap().timestamp, 1.0);
    assert_eq!(nearest_pose(&poses, 2.015, 0.02).unwrap().timestamp, 2.0);
    assert!(nearest_pose(&poses, 1.5, 0.02).is_none());
    assert!(nearest_pose(&[], 1.5, 0.02).is_none());
    let seq = associate(
        &[(1.011, "a".into()), (1.5, "b".into())],
        &[tp(2.0), tp(1.0), tp(1.01)],
        0.02,
    );
    assert_eq!(seq.frames.len(), 1);
    assert_eq!(seq.frames[0].pose.translation().x, 1.01);
    assert_eq!(seq.without_pose, vec![(1.5, PathBuf::from("b"))]);
}

#[test]
fn interpolated_between_the_bracketing_poses() {
    // Translation t along x, rotation 10·t degrees about z at time t.
    let at = |t: f64| TimedPose {
        timestamp: t,
        pose: c2w(
            Vector3::new(t, 0.0, 0.0),
            Vector3::new(0.0, 0.0, (10.0 * t).to_radians()),
        ),
    };
    let poses = [at(1.0), at(1.01), at(1.02), at(2.0)];
    // Exactly at a sample: that pose, bit for bit.
    assert_eq!(interpolated_pose(&poses, 1.01, 0.02), Some(poses[1].pose));
    // Between two samples: linear translation, rotation along the arc.
    let p = interpolated_pose(&poses, 1.0125, 0.02).unwrap();
    assert!((p.translation().x - 1.0125).abs() < 1e-12);
    let angle = p.isometry().rotation.angle().to_degrees();
    assert!((angle - 10.125).abs() < 1e-9, "{angle}");
    // A gap in the capture is not bridged; outside the trajectory there is no pose.
    assert!(interpolated_pose(&poses, 1.5, 0.02).is_none());
    assert!(interpolated_pose(&poses, 1.5, 1.0).is_some());
    assert!(interpolated_pose(&poses, 0.99, 0.02).is_none());
    assert!(interpolated_pose(&poses, 2.01, 0.02).is_none());
    assert!(interpolated_pose(&poses, f64::NAN, 0.02).is_none());
    assert!(interpolated_pose(&[], 1.0, 0.02).is_none());
    // Association at an offset: the pose 5 ms before each stamp, unsorted poses sorted.
    let seq = associate_interpolated(
        &[(1.0175, "a".into()), (1.5, "b".into()), (1.0, "c".into())],
        &[at(1.02), at(2.0), at(1.0), at(1.01)],
        -0.005,
        0.02,
    );
    assert_eq!(seq.frames.len(), 1);
    assert_eq!(seq.frames[0].depth_path, PathBuf::from("a"));
    assert_eq!(seq.frames[0].timestamp, Some(1.0175));
    assert!((seq.frames[0].pose.translation().x - 1.0125).abs() < 1e-12);
    assert_eq!(
        seq.without_pose,
        vec![(1.5, PathBuf::from("b")), (1.0, PathBuf::from("c"))]
    );
}

#[test]
fn tum_round_trip_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("gt.txt");
    let poses: Vec<TimedPose> = (0..5)
        .map(|i| TimedPose {
            timestamp: 100.0 + f64::from(i) * 0.01,
            pose: c2w(
                Vector3::new(1.0, -2.0, 0.5 * f64::from(i)),
                Vector3::new(0.1, 0.2 * f64::from(i), -0.3),
            ),
        })
        .collect();
    write_tum_trajectory(&p, &poses).unwrap();
    let back = read_tum_trajectory(&p).unwrap();
    assert_eq!(back.len(), 5);
    for (a, b) in back.iter().zip(&poses) {
        assert!((a.timestamp - b.timestamp).abs() < 1e-6);
        assert!((a.pose.to_matrix() - b.pose.to_matrix()).abs().max() < 1e-8);
    }
    std::fs::write(&p, "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0\n").unwrap();
    match read_tum_trajectory(&p).unwrap_err() {
        IoError::Parse { line, .. } => assert_eq!(line, 3),
        e => panic!("{e}"),
    }
    std::fs::write(&p, "1 0 0 0 0 0 0 0\n").unwrap();
    let e = read_tum_trajectory(&p).unwrap_err();
    assert!(matches!(e, IoError::Core { line: Some(1), .. }), "{e}");
    assert!(e.to_string().contains("gt.txt:1"), "{e}");
    // A repeated timestamp (in any order) names both lines.
    std::fs::write(
        &p,
        "# c\n2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n",
    )
    .unwrap();
    let e = read_tum_trajectory(&p).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 4, .. }), "{e}");
    assert!(
        e.to_string()
            .contains("timestamp 2 s appears twice (also on line 2)"),
        "{e}"
    );
}

#[test]
fn tum_folder_at_a_clock_offset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Poses every 10 ms moving 1 m/s along x; depth frames at 1.015 and 1.5 s.
    let poses: Vec<TimedPose> = (0..10)
        .map(|i| {
            let t = 1.0 + f64::from(i) * 0.01;
            TimedPose {
                timestamp: t,
                pose: c2w(Vector3::new(t, 0.0, 0.0), Vector3::zeros()),
            }
        })
        .collect();
    write_tum_trajectory(d.join("groundtruth.txt"), &poses).unwrap();
    std::fs::write(
        d.join("depth.txt"),
        "# depth\n1.015 depth/a.png\n1.5 depth/b.png\n",
    )
    .unwrap();
    let limits = Limits::default();
    let seq = read_tum_sequence_at_offset(d, -0.0075, 0.02, &limits).unwrap();
    assert_eq!(seq.frames.len(), 1);
    assert!((seq.frames[0].pose.translation().x - 1.0075).abs() < 1e-6);
    assert_eq!(seq.without_pose.len(), 1);
    assert!(read_tum_sequence_at_offset(d, f64::NAN, 0.02, &limits).is_err());
    assert!(read_tum_sequence_at_offset(d, 0.0, 0.0, &limits).is_err());
}

#[test]
fn open3d_log_round_trip_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.log");
    let poses = vec![
        c2w(Vector3::new(2.0, 2.0, -0.3), Vector3::zeros()),
        c2w(Vector3::new(1.0, 0.0, 0.5), Vector3::new(0.0, 0.3, 0.1)),
    ];
    write_open3d_log(&p, &poses).unwrap();
    let back = read_open3d_log(&p).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[1].metadata, [1, 1, 2]);
    for (a, b) in back.iter().zip(&poses) {
        assert!((a.pose.to_matrix() - b.to_matrix()).abs().max() < 1e-9);
    }
    std::fs::write(&p, "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n").unwrap();
    assert!(matches!(
        read_open3d_log(&p).unwrap_err(),
        IoError::Parse { line: 1, .. }
    ));
    std::fs::write(&p, "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n0 -1 1\n").unwrap();
    assert!(read_open3d_log(&p).is_err());
    std::fs::write(&p, "0 0 1\n2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n").unwrap();
    assert!(matches!(
        read_open3d_log(&p).unwrap_err(),
        IoError::Core { line: Some(1), .. }
    ));
}

#[test]
fn seven_scenes_directory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let id = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
    std::fs::write(d.join("frame-000002.pose.txt"), id).unwrap();
    std::fs::write(
        d.join("frame-000001.pose.txt"),
        "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    std::fs::write(d.join("frame-000001.depth.png"), b"").unwrap();
    let err = read_7scenes_sequence(d).unwrap_err();
    assert!(err.to_string().contains("frame-000002.depth.png"), "{err}");
    std::fs::write(d.join("frame-000002.depth.png"), b"").unwrap();
    let frames = read_7scenes_sequence(d).unwrap();
    assert_eq!(frames.len(), 2);
    assert!(frames[0].depth_path.ends_with("frame-000001.depth.png"));
    assert_eq!(frames[0].pose.translation().x, 0.5);
    std::fs::write(
        d.join("frame-000002.pose.txt"),
        "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0\n",
    )
    .unwrap();
    assert!(read_7scenes_sequence(d).is_err());
}

/// Numbers in names sort as numbers: unpadded frames in the order they were recorded, not
/// `10, 11, 8, 9` (a silently shuffled trajectory before); padded ones as by bytes.
#[test]
fn numbered_names_sort_as_numbers() {
    let sorted = |names: &[&str]| {
        let mut v: Vec<std::ffi::OsString> = names.iter().map(Into::into).collect();
        v.sort_by(|a, b| natural_order(a, b));
        v.into_iter()
            .map(|s| s.into_string().unwrap())
            .collect::<Vec<_>>()
    };
    assert_eq!(
        sorted(&["10.png", "9.png", "100.png", "8.png", "11.png"]),
        ["8.png", "9.png", "10.png", "11.png", "100.png"]
    );
    assert_eq!(
        sorted(&["frame-000010.depth.png", "frame-000009.depth.png"]),
        ["frame-000009.depth.png", "frame-000010.depth.png"]
    );
    assert_eq!(
        sorted(&["b2", "a10", "a9", "a", "a09", "a9x", "2b"]),
        ["2b", "a", "a09", "a9", "a9x", "a10", "b2"]
    );
    assert_eq!(
        sorted(&["1305031229.564442.png", "1305031229.528784.png"]),
        ["1305031229.528784.png", "1305031229.564442.png"]
    );
    // Digit runs beyond any integer type compare too.
    assert_eq!(
        sorted(&[
            "99999999999999999999999.png",
            "100000000000000000000000.png"
        ]),
        [
            "99999999999999999999999.png",
            "100000000000000000000000.png"
        ]
    );
    let dir = tempfile::tempdir().unwrap();
    for i in [8, 9, 10, 11] {
        std::fs::write(dir.path().join(format!("{i}.png")), b"").unwrap();
    }
    let names: Vec<String> = list_depth_files(dir.path())
        .unwrap()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["8.png", "9.png", "10.png", "11.png"]);
}

/// Names that state times sort by time, even written with as few decimals as they need
/// (Python's `str(stamp.to_sec())`): by their digit runs `…229.62879` came after
/// `…229.664358`, and 172 of TUM fr1/rpy-200's frames renamed so were out of order. Frame
/// numbers, and a folder where one name is not a time, sort by name.
#[test]
fn names_that_are_times_sort_by_time() {
    let names = |dir: &std::path::Path| -> Vec<String> {
        list_depth_files(dir)
            .unwrap()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect()
    };
    let dir = tempfile::tempdir().unwrap();
    for n in [
        "1305031229.664358",
        "1305031229.62879",
        "1305031229.7",
        "1305031229.596617",
    ] {
        std::fs::write(dir.path().join(format!("{n}.png")), b"").unwrap();
    }
    assert_eq!(
        names(dir.path()),
        [
            "1305031229.596617.png",
            "1305031229.62879.png",
            "1305031229.664358.png",
            "1305031229.7.png"
        ]
    );
    // One name that is not a time: every name sorts by its numbers, as before.
    std::fs::write(dir.path().join("notes.png"), b"").unwrap();
    assert_eq!(
        names(dir.path())[..2],
        ["1305031229.7.png", "1305031229.62879.png"]
    );

    // Nanoseconds: 19 digits from 2001 on; the fraction keeps its digits.
    let ns = std::path::Path::new("1305031229664358000.png");
    let t = name_timestamp_s(ns).unwrap();
    assert_eq!(format!("{t:.6}"), "1305031229.664358");
    for not_a_time in [
        "000042.png",
        "42.png",
        "frame-000042.depth.png",
        "0999999999999999999.png",
        "1305031229.png",
        ".5.png",
        "5..png",
        "1.2.3.png",
        "1e9.png",
        "1305031229.66a.png",
    ] {
        assert_eq!(
            name_timestamp_s(std::path::Path::new(not_a_time)),
            None,
            "{not_a_time}"
        );
    }
    assert_eq!(
        name_timestamp_s(std::path::Path::new("0.033.tif")),
        Some(0.033)
    );
    assert_eq!(name_timestamps_s(&[]), None);
}
