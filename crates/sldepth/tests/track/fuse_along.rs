//! `sldepth fuse DIR --trajectory FILE`: a raw recording tracked, then fused again along the
//! trajectory `track` wrote (its TUM file or its `.log`), in a folder with no poses of its own.

use super::{kinect_track_json, sldepth_json, write_sequence};
use crate::common::sldepth;

#[test]
fn fuse_follows_the_trajectory_track_wrote() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 4);
    let (txt, log) = (tmp.path().join("t.txt"), tmp.path().join("t.log"));
    let (track, _) = kinect_track_json(
        &seq,
        &[
            "--output",
            txt.to_str().unwrap(),
            "--output-log",
            log.to_str().unwrap(),
        ],
    );
    assert_eq!(track["lost"], 0);
    let dir = seq.to_str().unwrap();
    let fuse = |traj: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "fuse",
            dir,
            "--trajectory",
            traj.to_str().unwrap(),
            "--camera",
            "kinect-v1",
            "--voxel-m",
            "0.01",
        ];
        args.extend_from_slice(extra);
        args.push("--json");
        sldepth_json(&args)
    };
    // The folder has no groundtruth.txt: without --trajectory there is nothing to fuse along.
    assert!(
        !sldepth(&["fuse", dir, "--camera", "kinect-v1"])
            .status
            .success()
    );
    let (by_txt, _) = fuse(&txt, &[]);
    let (by_log, _) = fuse(&log, &[]);
    assert_eq!(by_txt["frames"], 4);
    assert_eq!(by_log["frames"], 4);
    // The two files hold the same poses (the TUM file to 6 and 7 decimals, the .log to 9).
    let (a, b) = (
        by_txt["vertices"].as_f64().unwrap(),
        by_log["vertices"].as_f64().unwrap(),
    );
    assert!(a > 1000.0 && (a - b).abs() < 0.01 * a, "{a} {b}");
    // A frame the trajectory has no pose for (a frame `track` lost: a comment line) is
    // skipped, and said.
    let text = std::fs::read_to_string(&txt).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let last = lines.len() - 1;
    lines[last] = format!("# {} lost: test", lines[last]);
    std::fs::write(&txt, lines.join("\n")).unwrap();
    let (three, stderr) = fuse(&txt, &[]);
    assert_eq!(three["frames"], 3);
    assert!(
        stderr.contains("note: 1 depth frames of") && stderr.contains("have no pose in"),
        "{stderr}"
    );
    // --trajectory replaces a folder's poses: with a frame list or an Open3D log it is an
    // error, as is a trajectory of another recording.
    for other in [["--frames", "list.txt"], ["--o3d-log", "a.log"]] {
        let out = sldepth(&[
            "fuse",
            "--trajectory",
            txt.to_str().unwrap(),
            other[0],
            other[1],
        ]);
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("cannot be used with"), "{stderr}");
    }
    // --max-gap-s widens the match: the first pose, moved 0.4 s after the last frame, poses
    // no frame at the default 20 ms, and every frame within 0.6 s.
    let first = lines.iter().find(|l| !l.starts_with('#')).unwrap();
    let moved = format!("100.5 {}\n", first.split_once(' ').unwrap().1);
    std::fs::write(&txt, &moved).unwrap();
    let out = sldepth(&["fuse", dir, "--trajectory", txt.to_str().unwrap()]);
    assert!(!out.status.success());
    let (wide, _) = fuse(&txt, &["--max-gap-s", "0.6"]);
    assert_eq!(wide["frames"], 4);
    for bad in ["0", "-1", "NaN", "1e9"] {
        let opt = format!("--max-gap-s={bad}");
        let out = sldepth(&["fuse", dir, "--trajectory", txt.to_str().unwrap(), &opt]);
        assert!(!out.status.success(), "{bad}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("--max-gap-s"), "{bad}: {stderr}");
    }
    std::fs::write(&txt, "900.5 0 0 0 0 0 0 1\n").unwrap();
    let out = sldepth(&["fuse", dir, "--trajectory", txt.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("gives none of the 4 depth frames"),
        "{stderr}"
    );
}
