//! Options named in their own words: each error below used to blame an internal name, print
//! `inf` for a finite number, or do something other than the option's help says (the third
//! audit). Every case is a clean failure (exit 1 or clap's 2) whose message names the option.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{s, sldepth, testdata};

/// A failure with exit code `code` whose standard error contains every needle.
fn assert_fails(o: &Output, code: i32, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.code(), Some(code), "{err}");
    for n in needles {
        assert!(err.contains(n), "expected {n:?} in: {err}");
    }
}

/// A 64x48 camera JSON, f = 60 px.
fn camera_json(dir: &Path) -> PathBuf {
    let p = dir.join("cam.json");
    std::fs::write(
        &p,
        r#"{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 32, 24, 1]}"#,
    )
    .unwrap();
    p
}

/// One 64x48 frame of a wall at 1.5 m, at the identity pose, as a frame list.
fn wall_sequence(dir: &Path) -> (PathBuf, PathBuf) {
    let depth = sl_core::DepthImage::from_vec(64, 48, vec![1.5; 64 * 48]).unwrap();
    sl_io::write_depth(dir.join("d.png"), &depth, &sl_io::DepthEncoding::default()).unwrap();
    let list = dir.join("frames.txt");
    std::fs::write(&list, "d.png 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n").unwrap();
    (list, camera_json(dir))
}

#[test]
fn filter_sigma_s_beyond_the_largest_window_names_the_option_and_the_way_out() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.png");
    let input = testdata("floor-seed1-depth.png");
    let o = sldepth(&["filter", s(&input), s(&out), "--sigma-s", "20"]);
    assert_fails(
        &o,
        1,
        &[
            "--sigma-s 20",
            "ceil(2·σ_s) = 40 px",
            "maximum 32 px",
            "--radius",
        ],
    );
    assert!(!out.exists());
    // With a radius the same σ_s is accepted.
    let o = sldepth(&[
        "filter",
        s(&input),
        s(&out),
        "--sigma-s",
        "20",
        "--radius",
        "3",
        "--single-scale",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn filter_writes_a_pgm_only_for_a_nyu_raw_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.pgm");
    // A millimetre PNG written as .pgm would have become NYU raw disparity, not the input's
    // encoding that the help promises.
    let o = sldepth(&["filter", s(&testdata("floor-seed1-depth.png")), s(&out)]);
    assert_fails(
        &o,
        1,
        &[
            "f.pgm",
            "NYU raw Kinect disparity",
            "this input is png depth at 1000 units per metre",
            ".png or .tif",
        ],
    );
    assert!(!out.exists());
}

#[test]
fn fuse_prints_the_min_weight_as_typed() {
    let dir = tempfile::tempdir().unwrap();
    let (list, cam) = wall_sequence(dir.path());
    let o = sldepth(&[
        "fuse",
        "--frames",
        s(&list),
        "--camera",
        s(&cam),
        "--min-weight",
        "1e300",
    ]);
    assert_fails(
        &o,
        1,
        &["--min-weight 1e300: must be a number from 0 to 1e30"],
    );
    assert!(!String::from_utf8_lossy(&o.stderr).contains("inf"));
}

#[test]
fn fuse_writes_the_mesh_when_the_slice_misses_the_volume() {
    let dir = tempfile::tempdir().unwrap();
    let (list, cam) = wall_sequence(dir.path());
    let mesh = dir.path().join("m.ply");
    let slice = dir.path().join("slice.png");
    let fuse = |slice_m: &str| {
        sldepth(&[
            "fuse",
            "--frames",
            s(&list),
            "--camera",
            s(&cam),
            "-o",
            s(&mesh),
            "--slice-png",
            s(&slice),
            "--slice-m",
            slice_m,
        ])
    };
    // The wall is at z = 1.5 m: z = 10 m crosses no block.
    let o = fuse("10");
    assert_fails(
        &o,
        1,
        &[
            "--slice-png",
            "not written (",
            "m.ply written)",
            "--slice-m 10",
            "no allocated block crosses the plane z = 10 m",
            "the allocated blocks span z from",
        ],
    );
    assert!(std::fs::metadata(&mesh).unwrap().len() > 0);
    assert!(!slice.exists());
    // Through the wall, both are written.
    std::fs::remove_file(&mesh).unwrap();
    let o = fuse("1.5");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(mesh.exists() && slice.exists());
}

#[test]
fn fuse_refuses_a_tum_ground_truth_with_a_repeated_timestamp() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("groundtruth.txt"),
        "# timestamp tx ty tz qx qy qz qw\n\
         100.0 0 0 0 0 0 0 1\n\
         100.1 0 0 0 0 0 0 1\n\
         100.1 1 0 0 0 0 0 1\n",
    )
    .unwrap();
    std::fs::write(d.join("depth.txt"), "100.0 depth/a.png\n").unwrap();
    let o = sldepth(&["fuse", "--tum", s(d)]);
    assert_fails(
        &o,
        1,
        &[
            "groundtruth.txt",
            "timestamp 100.1 s appears twice (also on line 3)",
        ],
    );
    // eval-traj says the same of the same file.
    let gt = d.join("groundtruth.txt");
    let o = sldepth(&["eval-traj", s(&gt), s(&gt)]);
    assert_fails(&o, 1, &["timestamp 100.1 s appears twice"]);
}

#[test]
fn max_memory_below_the_floor_is_refused() {
    let o = sldepth(&["--max-memory", "1", "cameras"]);
    assert_fails(&o, 2, &["--max-memory", "below the minimum budget of 16M"]);
    let o = sldepth(&["--max-memory", "16M", "cameras"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = sldepth(&["--help"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("at least 16M"));
}

#[test]
fn info_on_a_directory_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let o = sldepth(&["info", s(dir.path())]);
    assert_fails(&o, 1, &["is a directory, not a depth file"]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("cannot infer"));
}
