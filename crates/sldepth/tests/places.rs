//! A frame read where a data set keeps it, without options: a TUM folder's frame at TUM's scale
//! with the folder's camera and lens, a SUN RGB-D sample's frame in SUN's format with its own
//! intrinsics; the options still win.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::Output;

mod common;
use common::{sldepth, testdata};

fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap()
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A TUM frame is read as TUM stores it without `--depth-scale`: in the `depth` folder of a TUM
/// folder at 5000 units per metre with the camera its folder implies (a note says both), or at
/// the `--camera tum-fr1` preset's 5000; elsewhere, at 1000. `--depth-scale` still wins.
#[test]
fn a_tum_frame_is_read_at_tums_scale() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("rgbd_dataset_freiburg2_desk");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let frame = seq.join("depth").join("1.png");
    // The committed floor frame (millimetres) rewritten at 5000 units per metre.
    let mm = testdata("floor-seed1-depth.png");
    let depth = sl_io::depth::read_depth(&mm, &sl_io::depth::ReadConfig::default())
        .unwrap()
        .depth;
    sl_io::depth::write_depth(&frame, &depth, &sl_io::depth::DepthEncoding::png(5000.0)).unwrap();
    let median = |args: &[&str]| -> (f64, String) {
        let o = sldepth(args);
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{stderr}");
        (json_of(&o)["z_median_m"].as_f64().unwrap(), stderr)
    };
    let (truth, _) = median(&["info", path_str(&mm), "--json"]);
    let (alone, _) = median(&["info", path_str(&frame), "--json"]);
    assert!((alone - 5.0 * truth).abs() < 0.01, "{alone} vs {truth}");
    std::fs::write(seq.join("depth.txt"), "1.0 depth/1.png\n").unwrap();
    let (in_folder, note) = median(&["info", path_str(&frame), "--json"]);
    assert!((in_folder - truth).abs() < 0.001, "{in_folder} vs {truth}");
    assert!(
        note.contains("camera `tum-fr2`") && note.contains("5000 units per metre"),
        "{note}"
    );
    // The folder's preset brings its lens model, as `track DIR` takes it.
    let ply = dir.path().join("cloud.ply");
    let o = sldepth(&["cloud", path_str(&frame), "--output", path_str(&ply)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("with the `tum-fr2` lens model"),
        "{err}"
    );
    let (given, _) = median(&["info", path_str(&frame), "--json", "--depth-scale", "1000"]);
    assert!((given - 5.0 * truth).abs() < 0.01, "{given}");
    std::fs::remove_file(seq.join("depth.txt")).unwrap();
    let (preset, _) = median(&["info", path_str(&frame), "--json", "--camera", "tum-fr1"]);
    assert!((preset - truth).abs() < 0.001, "{preset} vs {truth}");
}

/// A SUN RGB-D sample's frame (`depth/` beside `intrinsics.txt` and `image/`) is read as SUN's
/// bit-rotated millimetres with the sample's own intrinsics, without `--format` or `--camera`.
#[test]
fn a_sun_rgbd_frame_is_read_with_its_sample() {
    let dir = tempfile::tempdir().unwrap();
    let sample = dir.path().join("NYU0001");
    std::fs::create_dir_all(sample.join("depth")).unwrap();
    std::fs::create_dir_all(sample.join("image")).unwrap();
    std::fs::write(
        sample.join("intrinsics.txt"),
        "518.857901 0 284.582449\n0 519.469611 208.736166\n0 0 1\n",
    )
    .unwrap();
    let mm = testdata("floor-seed1-depth.png");
    let depth = sl_io::depth::read_depth(&mm, &sl_io::depth::ReadConfig::default())
        .unwrap()
        .depth;
    let frame = sample.join("depth").join("NYU0001.png");
    sl_io::depth::write_depth(&frame, &depth, &sl_io::depth::DepthEncoding::sun()).unwrap();
    let info = |p: &Path| {
        let o = sldepth(&["info", path_str(p), "--json"]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        (json_of(&o)["z_median_m"].as_f64().unwrap(), err)
    };
    let (truth, _) = info(&mm);
    let (sun, note) = info(&frame);
    assert!((sun - truth).abs() < 0.001, "{sun} vs {truth}");
    assert!(
        note.contains("SUN RGB-D sample") && note.contains("fx 518.857901"),
        "{note}"
    );
}
