//! End-to-end tests of `sldepth motion` on real frames: an estimate the two frames cannot
//! decide is reported as undetermined, with the alignments they could not rule out.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::sldepth;

/// TUM fr1/rpy-200 frames 70 and 78 (20° apart): the planes propose rotations the frames cannot
/// tell apart. The command fails as undetermined (no pose printed), and says how many
/// alignments were left; `--json` lists them, and one is the camera's 20° turn. (The frames as
/// recorded: undistorted, `--lens auto`, this pair is decided.)
#[test]
fn motion_lists_the_alignments_two_frames_cannot_tell_apart() {
    let Some((tum, entries)) = sl_testkit::tum_rpy_200_depth_list("the motion candidates test")
    else {
        return;
    };
    let (a, b) = (tum.join(&entries[70].1), tum.join(&entries[78].1));
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let common = [
        "--camera",
        "tum-fr1",
        "--depth-scale",
        "5000",
        "--lens",
        "none",
    ];
    let mut args = vec!["motion", a, b];
    args.extend_from_slice(&common);
    let text = sldepth(&args);
    assert!(!text.status.success());
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(stdout.contains("motion undetermined"), "{stdout}");
    assert!(stdout.contains("cannot tell apart"), "{stdout}");
    args.push("--json");
    let out = sldepth(&args);
    assert!(!out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["determined"], false, "{v}");
    assert!(v["reason"].as_str().unwrap().contains("ambiguous"), "{v}");
    let candidates = v["candidates"].as_array().unwrap();
    assert!((2..=3).contains(&candidates.len()), "{v}");
    let angles: Vec<f64> = candidates
        .iter()
        .map(|c| c["rotation_deg"].as_f64().unwrap())
        .collect();
    // The camera turned 20.3° (motion capture); the others are 70–110° away from that.
    assert!(angles.iter().any(|d| (d - 20.3).abs() < 3.0), "{angles:?}");
    for c in candidates {
        assert_eq!(c["rotation"].as_array().unwrap().len(), 9, "{c}");
        assert_eq!(c["translation_m"].as_array().unwrap().len(), 3, "{c}");
    }
}
