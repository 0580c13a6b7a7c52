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

/// A ScanNet export (`depth/<n>.png`, `pose/<n>.txt`, `intrinsic/intrinsic_depth.txt`, no
/// `.log`) is fused from its folder alone, its `-inf` pose left out and counted, and tracked
/// with the camera of its 4x4 intrinsic matrix.
#[test]
fn a_scannet_export_fuses_and_tracks_from_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scene0000_00");
    for sub in ["depth", "pose", "intrinsic"] {
        std::fs::create_dir_all(scan.join(sub)).unwrap();
    }
    let frame = testdata("three-planes-seed3-depth.png");
    let identity = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
    for i in 0..3 {
        std::fs::copy(&frame, scan.join("depth").join(format!("{i}.png"))).unwrap();
        let pose = if i == 1 {
            "-inf -inf -inf -inf\n".repeat(4)
        } else {
            identity.to_owned()
        };
        std::fs::write(scan.join("pose").join(format!("{i}.txt")), pose).unwrap();
    }
    std::fs::write(
        scan.join("intrinsic/intrinsic_depth.txt"),
        "577.590698 0.000000 318.905426 0.000000\n0.000000 578.729797 242.683609 0.000000\n\
         0.000000 0.000000 1.000000 0.000000\n0.000000 0.000000 0.000000 1.000000\n",
    )
    .unwrap();
    let dir_arg = path_str(&scan);
    let mesh = dir.path().join("mesh.ply");
    let o = sldepth(&[
        "fuse",
        dir_arg,
        "--voxel-m",
        "0.02",
        "--output",
        path_str(&mesh),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(json_of(&o)["frames"], 2, "{err}");
    assert!(err.contains("note: 1 depth frames have no pose"), "{err}");
    assert!(mesh.is_file());
    // The same frames through the explicit option.
    let o = sldepth(&["fuse", "--scannet", dir_arg, "--voxel-m", "0.02", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(json_of(&o)["frames"], 2);
    // Tracking reads the folder as an Open3D-style one, with the ScanNet camera (an identical
    // frame three times: no motion).
    let traj = dir.path().join("traj.txt");
    let o = sldepth(&[
        "track",
        dir_arg,
        "--voxel-m",
        "0.02",
        "--output",
        path_str(&traj),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(json_of(&o)["frames"], 3);
    // With the camera a 640x480 Kinect preset instead (focal 580, not 577.6), fusion is not
    // the same: the folder's own matrix was used.
    let o = sldepth(&["fuse", dir_arg, "--voxel-m", "0.02", "--json"]);
    let own = json_of(&o)["vertices"].clone();
    let o = sldepth(&[
        "fuse",
        dir_arg,
        "--voxel-m",
        "0.02",
        "--json",
        "--camera",
        "kinect-v1",
    ]);
    assert_ne!(json_of(&o)["vertices"], own);
}

/// TUM frames copied into an Open3D-style folder (no `depth.txt`) are read as millimetres, five
/// times too deep: `track` and `fuse` say so at the first frame, as the single-file commands do.
#[test]
fn a_sequence_read_at_the_wrong_scale_is_said_to_be() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("copied");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let mm = testdata("floor-seed1-depth.png");
    let depth = sl_io::depth::read_depth(&mm, &sl_io::depth::ReadConfig::default())
        .unwrap()
        .depth;
    for i in 0..2 {
        let frame = seq.join("depth").join(format!("{i}.png"));
        sl_io::depth::write_depth(&frame, &depth, &sl_io::depth::DepthEncoding::png(5000.0))
            .unwrap();
    }
    let o = sldepth(&["track", path_str(&seq), "--voxel-m", "0.02", "--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("0.png: median depth") && err.contains("--depth-scale"),
        "{err}"
    );
    let o = sldepth(&[
        "track",
        path_str(&seq),
        "--voxel-m",
        "0.02",
        "--json",
        "--depth-scale",
        "5000",
    ]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("median depth"));
}

/// The vertex count and the mean y of a PLY mesh's vertices.
fn mean_y(ply: &Path) -> (usize, f64) {
    let mesh = sl_io::ply::read_ply(ply).unwrap().into_mesh();
    assert!(mesh.vertex_count() > 0);
    let sum: f64 = mesh.positions.iter().map(|p| f64::from(p.y)).sum();
    (mesh.vertex_count(), sum / mesh.vertex_count() as f64)
}

/// One of ICL-NUIM's TUM-format folders (associations depth first with frame numbers, its
/// `*.gt.freiburg` beside them) is told from a TUM folder: the `icl-nuim-tum` camera, and the
/// trajectory and meshes of `track` and `fuse` in the data set's y-up frame — the same frames
/// in a TUM folder give the same meshes mirrored in y.
#[test]
fn an_icl_nuim_tum_folder_is_tracked_and_fused_in_its_own_frame() {
    let dir = tempfile::tempdir().unwrap();
    let mm = testdata("figure-walls-seed2-depth.png");
    let depth = sl_io::depth::read_depth(&mm, &sl_io::depth::ReadConfig::default())
        .unwrap()
        .depth;
    let identity = "0 0 0 0 0 0 1";
    let make = |name: &str, icl: bool| {
        let seq = dir.path().join(name);
        std::fs::create_dir_all(seq.join("depth")).unwrap();
        let (mut list, mut gt) = (String::new(), String::new());
        for i in 0..3 {
            let frame = seq.join("depth").join(format!("{i}.png"));
            sl_io::depth::write_depth(&frame, &depth, &sl_io::depth::DepthEncoding::png(5000.0))
                .unwrap();
            if icl {
                list.push_str(&format!("{i} depth/{i}.png {i} rgb/{i}.png\n"));
            } else {
                list.push_str(&format!("{i} depth/{i}.png\n"));
            }
            gt.push_str(&format!("{i} {identity}\n"));
        }
        let (list_name, gt_name) = if icl {
            ("associations.txt", "livingRoom0.gt.freiburg")
        } else {
            ("depth.txt", "groundtruth.txt")
        };
        std::fs::write(seq.join(list_name), list).unwrap();
        std::fs::write(seq.join(gt_name), gt).unwrap();
        seq
    };
    let icl = make("living_room_traj0_frei_png", true);
    let tum = make("tum", false);
    let run = |seq: &Path, what: &str, extra: &[&str]| -> (Output, std::path::PathBuf) {
        let mesh = seq.with_extension(format!("{what}.ply"));
        let mut args = vec![what, path_str(seq), "--voxel-m", "0.02"];
        args.extend_from_slice(extra);
        let out_flag = if what == "track" {
            "--mesh"
        } else {
            "--output"
        };
        let mesh_str = mesh.to_str().unwrap().to_owned();
        args.extend_from_slice(&[out_flag, &mesh_str]);
        let o = sldepth(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (o, mesh)
    };
    let traj = dir.path().join("icl.txt");
    let (o, icl_track) = run(&icl, "track", &["--output", path_str(&traj)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("camera `icl-nuim-tum` for this ICL-NUIM TUM-format folder")
            && err.contains("one of ICL-NUIM's TUM-format folders"),
        "{err}"
    );
    let text = std::fs::read_to_string(&traj).unwrap();
    assert!(text.contains("# in the data set's y-up frame"), "{text}");
    // Stamped with the frame numbers, as its ground truth.
    let stamps: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(stamps, ["0.000000", "1.000000", "2.000000"], "{text}");
    // The same frames and camera as a TUM folder: the mesh mirrored in y.
    let (_, tum_track) = run(&tum, "track", &["--camera", "icl-nuim-tum"]);
    let (a, b) = (mean_y(&icl_track), mean_y(&tum_track));
    // (The scene's mean y is not 0 itself, so the mirror shows.)
    assert!(b.1.abs() > 0.05, "{b:?}");
    assert!(a.0 == b.0 && (a.1 + b.1).abs() < 1e-5, "{a:?} {b:?}");
    // `fuse` reads the *.gt.freiburg and writes its mesh in the same frame.
    let (o, icl_fuse) = run(&icl, "fuse", &[]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("its ground truth (y up)"));
    let (_, tum_fuse) = run(&tum, "fuse", &["--camera", "icl-nuim-tum"]);
    let (a, b) = (mean_y(&icl_fuse), mean_y(&tum_fuse));
    assert!(a.0 == b.0 && (a.1 + b.1).abs() < 1e-5, "{a:?} {b:?}");
}

/// Open3D's Redwood sample as Open3D ships it: `depth/`, `trajectory.log` beside
/// `odometry.log`, the camera in `camera_primesense.json`; fused from the folder with the
/// trajectory and that camera, and a `.log` written as `*-traj.txt` (Redwood's name) read as a
/// `.log` by `eval-traj`. Without a camera file the folder takes Open3D's PrimeSenseDefault.
#[test]
fn an_open3d_redwood_sample_fuses_from_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("SampleRedwoodRGBDImages");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let frame = testdata("figure-walls-seed2-depth.png");
    let mut log = String::new();
    for i in 0..5 {
        std::fs::copy(&frame, seq.join("depth").join(format!("{i:05}.png"))).unwrap();
        log.push_str(&format!(
            "{i} {i} 3\n1 0 0 {}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
            0.01 * i as f64
        ));
    }
    std::fs::write(seq.join("trajectory.log"), &log).unwrap();
    // The pairwise odometry beside it is not a trajectory of camera poses.
    std::fs::write(
        seq.join("odometry.log"),
        "0 1 3\n1 0 0 0.01\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    let fuse = |extra: &[&str]| -> (serde_json::Value, String) {
        let mut args = vec!["fuse", path_str(&seq), "--voxel-m", "0.02", "--json"];
        args.extend_from_slice(extra);
        let o = sldepth(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        (json_of(&o), err)
    };
    let (v, err) = fuse(&[]);
    assert_eq!(v["frames"], 5, "{err}");
    assert!(err.contains("camera `ros-default`"), "{err}");
    let (default, _) = fuse(&["--camera", "ros-default"]);
    assert_eq!(v["vertices"], default["vertices"]);
    std::fs::write(
        seq.join("camera_primesense.json"),
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [550, 0, 0, 0, 550, 0, 319.5, 239.5, 1]}"#,
    )
    .unwrap();
    let (own, err) = fuse(&[]);
    assert!(!err.contains("camera `ros-default`"), "{err}");
    assert_ne!(own["vertices"], default["vertices"]);
    // eval-traj: the trajectory against itself written under Redwood's name.
    let traj = dir.path().join("livingroom1-traj.txt");
    std::fs::write(&traj, &log).unwrap();
    let o = sldepth(&[
        "eval-traj",
        path_str(&seq.join("trajectory.log")),
        path_str(&traj),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = json_of(&o);
    assert_eq!(v["poses_matched"], 5, "{v}");
    assert_eq!(v["ate_m"]["rmse"].as_f64(), Some(0.0), "{v}");
}

/// A TUM-layout folder with the ETH3D SLAM benchmark's `calibration.txt` (`fx fy cx cy`) is
/// tracked and its frames read with that camera, and none of a TUM Kinect's lens model or
/// rolling shutter; `--camera` still wins.
#[test]
fn an_eth3d_folder_takes_its_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("sofa_1");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let mm = testdata("figure-walls-seed2-depth.png");
    let depth = sl_io::depth::read_depth(&mm, &sl_io::depth::ReadConfig::default())
        .unwrap()
        .depth;
    let mut list = String::new();
    for i in 0..3 {
        let name = format!("depth/{}.png", 10 + i);
        sl_io::depth::write_depth(
            seq.join(&name),
            &depth,
            &sl_io::depth::DepthEncoding::png(5000.0),
        )
        .unwrap();
        list.push_str(&format!("{}.037 {name}\n", 10 + i));
    }
    std::fs::write(seq.join("depth.txt"), list).unwrap();
    std::fs::write(seq.join("calibration.txt"), "560.5 560.5 320.2 240.1\n").unwrap();
    let o = sldepth(&["track", path_str(&seq), "--voxel-m", "0.02", "--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("calibration.txt (640x480, fx 560.5 px)"),
        "{err}"
    );
    assert!(!err.contains("lens model"), "{err}");
    let v = json_of(&o);
    assert_eq!(
        (v["frames"].as_u64(), v["rolling_shutter_ms"].as_f64()),
        (Some(3), Some(0.0))
    );
    // One frame on its own: the folder's scale and calibration.
    let frame = seq.join("depth/10.png");
    let o = sldepth(&[
        "cloud",
        path_str(&frame),
        "--output",
        path_str(&dir.path().join("c.ply")),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("the camera of its calibration.txt"),
        "{err}"
    );
    let o = sldepth(&[
        "track",
        path_str(&seq),
        "--camera",
        "tum-fr1",
        "--voxel-m",
        "0.02",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && !err.contains("calibration.txt"),
        "{err}"
    );
}

/// A frame opened on its own in a sequence folder takes the camera `track DIR` takes for the
/// folder: a 7-Scenes-layout frame the `camera-intrinsics.txt` of its scene (3DMatch keeps it
/// above `seq-01/`), a frame of an Open3D RealSense recording (848×480) its
/// `camera_intrinsic.json`, where the default 640×480 camera refused it. A camera file that
/// gives the intrinsics alone leaves the sensor to the Kinect's defaults, so the frame's depth
/// steps are not judged against it (a D435's 1/32-px steps would look 2.7 times too deep).
#[test]
fn a_frame_takes_its_sequence_folders_camera() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("sun3d-scene");
    let seq = scene.join("seq-01");
    std::fs::create_dir_all(&seq).unwrap();
    let frame = seq.join("frame-000000.depth.png");
    std::fs::copy(testdata("floor-seed1-depth.png"), &frame).unwrap();
    std::fs::write(
        scene.join("camera-intrinsics.txt"),
        "550 0 320\n0 550 240\n0 0 1\n",
    )
    .unwrap();
    let json = dir.path().join("same.json");
    std::fs::write(
        &json,
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [550, 0, 0, 0, 550, 0, 320, 240, 1]}"#,
    )
    .unwrap();
    let cloud = |extra: &[&str], out: &str| -> (Vec<u8>, String) {
        let ply = dir.path().join(out);
        let mut args = vec!["cloud", path_str(&frame), "--output", path_str(&ply)];
        args.extend_from_slice(extra);
        let o = sldepth(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        (std::fs::read(&ply).unwrap(), err)
    };
    let (implied, note) = cloud(&[], "a.ply");
    assert!(
        note.contains("the camera of its camera-intrinsics.txt (fx 550 px)"),
        "{note}"
    );
    let (given, note) = cloud(&["--camera", path_str(&json)], "b.ply");
    assert!(!note.contains("camera-intrinsics"), "{note}");
    assert_eq!(implied, given, "the scene's camera, as if given");

    // Open3D's RealSense recorder: depth/ and camera_intrinsic.json.
    let rs = dir.path().join("realsense");
    std::fs::create_dir_all(rs.join("depth")).unwrap();
    let frame = rs.join("depth/000000.png");
    let o = sldepth(&[
        "simulate",
        "--scene",
        "boxes",
        "--seed",
        "3",
        "--camera",
        "d435",
        "--output",
        path_str(&frame),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let planes = || {
        sldepth(&[
            "planes",
            path_str(&frame),
            "--output",
            path_str(&dir.path().join("labels.png")),
        ])
    };
    let o = planes();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("848x480"), "{err}");
    std::fs::write(
        rs.join("camera_intrinsic.json"),
        r#"{"width": 848, "height": 480, "intrinsic_matrix": [426, 0, 0, 0, 426, 0, 424, 240, 1]}"#,
    )
    .unwrap();
    let o = planes();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("the camera of its camera_intrinsic.json (fx 426 px)"),
        "{err}"
    );
    assert!(!err.contains("depth steps"), "{err}");
}

/// A camera JSON that states its sensor (`baseline_m` and `subpixel`, as `sldepth` writes one)
/// is trusted for the depth-steps scale check, as a preset is; one that gives the intrinsics
/// alone is not (its Kinect baseline and 1/8-px steps are assumed, and a RealSense frame would
/// look 2.7–5 times too deep against them).
#[test]
fn a_camera_json_that_states_its_sensor_judges_the_depth_steps() {
    let dir = tempfile::tempdir().unwrap();
    let frame = |scale: &str| {
        let p = dir.path().join(format!("floor-{scale}.png"));
        let o = sldepth(&[
            "simulate",
            "--scene",
            "floor",
            "--seed",
            "3",
            "--camera",
            "d435",
            "--depth-scale",
            scale,
            "--output",
            path_str(&p),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        p
    };
    let (right, deep) = (frame("1000"), frame("2500"));
    let k =
        r#""width": 848, "height": 480, "intrinsic_matrix": [426, 0, 0, 0, 426, 0, 424, 240, 1]"#;
    let full = dir.path().join("full.json");
    std::fs::write(
        &full,
        format!(r#"{{{k}, "baseline_m": 0.05, "subpixel": 32}}"#),
    )
    .unwrap();
    let bare = dir.path().join("bare.json");
    std::fs::write(&bare, format!("{{{k}}}")).unwrap();
    let note = |f: &Path, camera: &Path| {
        let o = sldepth(&["info", path_str(f), "--camera", path_str(camera)]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        err
    };
    // Read as millimetres, the frame stored at 2500 units per metre is 2.5 times too deep: its
    // depths stay inside the range check's 0.5–5 m, its steps say so.
    let n = note(&deep, &full);
    assert!(
        n.contains("depth steps") && n.contains("2.5 times too deep"),
        "{n}"
    );
    assert!(
        !note(&right, &full).contains("note"),
        "at the right scale: no note"
    );
    assert!(
        !note(&deep, &bare).contains("depth steps"),
        "intrinsics alone: not judged"
    );
}
