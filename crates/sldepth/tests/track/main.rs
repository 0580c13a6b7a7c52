//! `sldepth track` on a small simulated sequence written as a TUM folder: trajectory, `.log`,
//! mesh and JSON; bad input (a missing frame, timestamps out of order) handled without a panic.
//! The fragment and memory-budget tests are in `fragments.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use sl_core::CameraToCamera;
use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_io::depth::{DepthEncoding, write_depth};
use sl_noise::sim::{KinectSimulator, named_scene};

#[path = "../common/mod.rs"]
mod common;
use common::sldepth;

mod bag;
mod fast_motion;
mod fragments;
mod fuse_along;
mod odometry;

/// Runs `sldepth` with `args` (ending in `--json`), which must succeed: its JSON summary and
/// its standard error.
fn sldepth_json(args: &[&str]) -> (serde_json::Value, String) {
    let out = sldepth(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{args:?}: {stderr}");
    (serde_json::from_slice(&out.stdout).unwrap(), stderr)
}

/// `sldepth track --tum SEQ --camera kinect-v1 --voxel-m 0.01 EXTRA --json`, which must
/// succeed: its JSON summary and its standard error.
fn kinect_track_json(seq: &Path, extra: &[&str]) -> (serde_json::Value, String) {
    kinect_track_json_from(&["--tum", seq.to_str().unwrap()], extra)
}

/// [`kinect_track_json`] with the sequence given by `source` (`["--tum", DIR]`, `[DIR]`, ...).
fn kinect_track_json_from(source: &[&str], extra: &[&str]) -> (serde_json::Value, String) {
    let mut args = vec!["track"];
    args.extend_from_slice(source);
    args.extend_from_slice(&["--camera", "kinect-v1", "--voxel-m", "0.01"]);
    args.extend_from_slice(extra);
    args.push("--json");
    sldepth_json(&args)
}

/// The pose lines of a TUM trajectory file (comment lines skipped), as numbers.
fn pose_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// The last frame of [`write_sequence`]'s six is 5 cm from the first (1 cm per frame).
fn assert_moved_5_cm(row: &[f64]) {
    let moved = (row[1] * row[1] + row[2] * row[2] + row[3] * row[3]).sqrt();
    assert!(
        (moved - 0.05).abs() < 0.01,
        "moved {moved} m, expected about 0.05 m"
    );
}

/// Writes `n` frames of the simulated `boxes` scene (640×480 Kinect, the camera turning 1° and
/// moving 1 cm per frame) as a TUM folder: `depth/<t>.png` (5000 units/m) and `depth.txt`.
fn write_sequence(dir: &Path, n: usize) -> Vec<f64> {
    write_sequence_decimated(dir, n, 1)
}

/// [`write_sequence`] with every frame decimated by `every` (every `every`-th pixel of every
/// `every`-th row, as a driver's decimation or a QVGA mode delivers them).
fn write_sequence_decimated(dir: &Path, n: usize, every: usize) -> Vec<f64> {
    write_sequence_through(dir, n, every, &KinectSimulator::kinect_v1().white())
}

/// [`write_sequence_decimated`] through the simulator `sim`.
fn write_sequence_through(dir: &Path, n: usize, every: usize, sim: &KinectSimulator) -> Vec<f64> {
    let scene = named_scene("boxes").unwrap();
    let step = CameraToCamera::from_isometry(Isometry3::from_parts(
        Translation3::new(0.01, 0.0, 0.0),
        UnitQuaternion::from_scaled_axis(Vector3::y() * 1f64.to_radians()),
    ));
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let mut list = String::from("# depth maps\n# timestamp filename\n");
    let mut pose = scene.pose;
    let mut stamps = Vec::new();
    for i in 0..n {
        let t = 100.0 + i as f64 / 30.0;
        let truth = scene.scene.render(&scene.intrinsics, &pose).depth;
        let depth = sim.apply(&truth, i as u64);
        let depth = sl_testkit::decimate(&depth, every);
        let name = format!("depth/{t:.6}.png");
        write_depth(dir.join(&name), &depth, &DepthEncoding::tum()).unwrap();
        list.push_str(&format!("{t:.6} {name}\n"));
        stamps.push(t);
        pose = pose * step;
    }
    std::fs::write(dir.join("depth.txt"), list).unwrap();
    stamps
}

/// Frames a whole fraction of the camera's size (here 320×240 for the 640×480 `kinect-v1`) are
/// the same sensor decimated: tracked with the camera scaled and the sensor's noise kept, said
/// on standard error; a size that is no such fraction is still an error.
#[test]
fn track_treats_frames_a_fraction_of_the_camera_as_decimated() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence_decimated(&seq, 6, 2);
    let traj = tmp.path().join("traj.txt");
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--camera",
        "kinect-v1",
        "--output",
        traj.to_str().unwrap(),
        "--voxel-m",
        "0.01",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("1/2 of the camera's 640x480"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["lost"], 0);
    let rows = pose_rows(&traj);
    assert_moved_5_cm(&rows[rows.len() - 1]);
    // Frames that are no whole fraction of the camera (another aspect ratio) are an error.
    let seq2 = tmp.path().join("seq2");
    write_sequence(&seq2, 2);
    let cam = tmp.path().join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width": 1000, "height": 480, "intrinsic_matrix": [580, 0, 0, 0, 580, 0, 499.5, 239.5, 1]}"#,
    )
    .unwrap();
    let out = sldepth(&[
        "track",
        "--tum",
        seq2.to_str().unwrap(),
        "--camera",
        cam.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("640x480 but the camera is 1000x480"), "{err}");
}

#[test]
fn track_writes_trajectory_log_mesh_and_json() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let stamps = write_sequence(&seq, 6);
    let (traj, log, mesh) = (
        tmp.path().join("traj.txt"),
        tmp.path().join("traj.log"),
        tmp.path().join("mesh.ply"),
    );
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--camera",
        "kinect-v1",
        "--output",
        traj.to_str().unwrap(),
        "--output-log",
        log.to_str().unwrap(),
        "--mesh",
        mesh.to_str().unwrap(),
        "--voxel-m",
        "0.01",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], 6);
    assert_eq!(v["lost"], 0);
    assert_eq!(v["reference"], "model");
    // Relocalisation against keyframes is on unless `--no-keyframes`.
    assert_eq!(v["keyframes"], true);
    assert!(v["track_ms_median"].as_f64().unwrap() > 0.0);
    assert!(v["integrate_ms_median"].as_f64().unwrap() > 0.0);
    // The whole pipeline per frame but the file's reading: the preparation (lens model, noise
    // measurement, prefilter) plus the step. Every frame's sum is at least its step, so the
    // medians keep that order.
    let (prepare, step, frame) = (
        v["prepare_ms_median"].as_f64().unwrap(),
        v["step_ms_median"].as_f64().unwrap(),
        v["frame_ms_median"].as_f64().unwrap(),
    );
    assert!(prepare > 0.0 && step > 0.0, "{prepare} {step}");
    assert!(frame >= step, "frame {frame} ms < step {step} ms");
    assert!(v["vertices"].as_u64().unwrap() > 1000);
    // The instruction set the tracker ran with: this CPU's widest.
    assert_eq!(v["isa"], sl_core::Isa::detect().effective().name());
    // One pose line per frame, with the input's timestamps; the camera moved 1 cm per frame
    // along its x axis.
    let rows = pose_rows(&traj);
    assert_eq!(rows.len(), 6);
    for (r, t) in rows.iter().zip(&stamps) {
        assert_eq!(r.len(), 8);
        assert!((r[0] - t).abs() < 1e-6);
    }
    assert_moved_5_cm(&rows[5]);
    let entries = sl_io::trajectory::read_open3d_log(&log).unwrap();
    assert_eq!(entries.len(), 6);
    let m = sl_io::read_mesh_ply(&mesh).unwrap();
    assert!(m.vertex_count() > 1000);
}

/// A sensor three times noisier than the camera's model (σ_D 0.2 px behind the Kinect's 0.07,
/// realistic correlated noise): each raw frame's measured noise sets the prefilter's range
/// kernel, as it sets the tracker's weights (a frame smoothed for 0.07 px keeps most of its
/// error); with `--model-noise-only` the camera's σ_D is used, as before the measurement.
#[test]
fn track_smooths_a_noisier_sensors_frames_for_their_measured_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let mut sensor = sl_core::SensorModel::kinect_v1();
    sensor.sigma_d_px = 0.2;
    write_sequence_through(&seq, 4, 1, &KinectSimulator::with_sensor(sensor));
    let run = |extra: &[&str]| kinect_track_json(&seq, extra).0;
    let measured = run(&[]);
    assert_eq!(measured["lost"], 0, "{measured}");
    let scale = measured["noise_scale_median"].as_f64().unwrap();
    let sigma = measured["prefilter_sigma_d_px_median"].as_f64().unwrap();
    // (0.2² + 1/768) / (0.07² + 1/768) = 6.7.
    assert!((4.0..9.0).contains(&scale), "{measured}");
    assert!((0.15..0.25).contains(&sigma), "{measured}");
    let model = run(&["--model-noise-only"]);
    assert_eq!(model["prefilter_sigma_d_px_median"].as_f64(), Some(0.07));
    let none = run(&["--prefilter", "none"]);
    assert!(none["prefilter_sigma_d_px_median"].is_null(), "{none}");
}

/// A frame of another size than the sequence's camera is the same error under every layout:
/// under `--tum` the TUM preset's lens model used to refuse it first, and the frame was skipped
/// as unreadable while `--7scenes` and `--o3d` stopped.
#[test]
fn track_stops_at_a_frame_of_another_size_with_a_lens_model_too() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 3);
    let list = std::fs::read_to_string(seq.join("depth.txt")).unwrap();
    let second = list.lines().filter(|l| !l.starts_with('#')).nth(1).unwrap();
    let name = second.split_whitespace().nth(1).unwrap();
    let odd = sl_core::DepthImage::from_image(sl_core::Image::from_fn(320, 200, |_, _| 2.0f32));
    write_depth(seq.join(name), &odd, &DepthEncoding::tum()).unwrap();
    // No `--camera`: the folder's TUM preset, with its lens model (`--lens auto`).
    let err = track_tum_fails(&seq, &tmp.path().join("traj.txt"));
    assert!(err.contains("320x200 but the camera is 640x480"), "{err}");
}

/// Runs `sldepth track --tum seq --output traj`, checks that it fails without writing `traj`,
/// and returns its standard error.
fn track_tum_fails(seq: &Path, traj: &Path) -> String {
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--output",
        traj.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{err}");
    assert!(!traj.exists(), "{err}");
    err
}

#[test]
fn track_skips_a_missing_frame_and_rejects_unordered_timestamps() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 4);
    // A frame listed but absent: logged, marked in the trajectory, the rest tracked.
    let mut list = std::fs::read_to_string(seq.join("depth.txt")).unwrap();
    list.push_str("200.000000 depth/missing.png\n");
    std::fs::write(seq.join("depth.txt"), &list).unwrap();
    let traj = tmp.path().join("traj.txt");
    let (v, stderr) = kinect_track_json(&seq, &["--output", traj.to_str().unwrap()]);
    assert_eq!(v["skipped"], 1);
    assert!(stderr.contains("missing.png"));
    let text = std::fs::read_to_string(&traj).unwrap();
    assert!(text.lines().any(|l| l.starts_with("# 200.000000 skipped")));
    // Timestamps out of order: a clear error naming the line, no output.
    list.push_str("150.000000 depth/also-missing.png\n");
    std::fs::write(seq.join("depth.txt"), &list).unwrap();
    let traj2 = tmp.path().join("traj2.txt");
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--output",
        traj2.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("out of order"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!traj2.exists());
}

/// `sldepth fuse --tum` reads a folder as TUM ships it (`depth.txt`, no `associations.txt`)
/// with its `groundtruth.txt`, and takes the camera from the folder's name: `tum-fr1` unless
/// the name says freiburg2 or freiburg3.
#[test]
fn fuse_reads_a_tum_folder_with_depth_txt_and_picks_the_camera_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, preset) in [
        ("seq", "tum-fr1"),
        ("rgbd_dataset_freiburg3_office", "tum-fr3"),
    ] {
        let seq = tmp.path().join(name);
        let stamps = write_sequence(&seq, 3);
        // Ground truth: the simulated poses are not needed for the command to run; identity
        // poses 10 ms after each frame exercise the association.
        let mut gt = String::from("# timestamp tx ty tz qx qy qz qw\n");
        for t in &stamps {
            gt.push_str(&format!("{:.6} 0 0 0 0 0 0 1\n", t + 0.01));
        }
        std::fs::write(seq.join("groundtruth.txt"), gt).unwrap();
        let out = sldepth(&[
            "fuse",
            "--tum",
            seq.to_str().unwrap(),
            "--voxel-m",
            "0.02",
            "--json",
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(
            stderr.contains(&format!("camera `{preset}`")),
            "{name}: {stderr}"
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["frames"], 3, "{name}");
        assert!(v["vertices"].as_u64().unwrap() > 1000, "{name}");
    }
}

/// With a camera preset that has a published lens distortion (`tum-fr1`), `--lens auto` (the
/// default) resamples every frame into the pinhole image; `--lens none` and presets without a
/// lens model leave the frames as they are. The JSON summary says which.
#[test]
fn track_undistorts_frames_of_a_camera_with_a_lens_model() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 3);
    for (camera, lens, want) in [
        ("tum-fr1", "auto", true),
        ("tum-fr1", "none", false),
        ("kinect-v1", "auto", false),
    ] {
        let traj = tmp.path().join(format!("{camera}-{lens}.txt"));
        let out = sldepth(&[
            "track",
            "--tum",
            seq.to_str().unwrap(),
            "--camera",
            camera,
            "--lens",
            lens,
            "--output",
            traj.to_str().unwrap(),
            "--voxel-m",
            "0.01",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{camera} {lens}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["undistorted"], want, "{camera} {lens}");
        assert_eq!(v["frames"], 3);
    }
}

/// `--rolling-shutter-ms auto` (the default) models the camera preset's readout against the
/// fused model (the Kinect-class presets' 30 ms, the TUM folder's implied `tum-fr1` too), none
/// for a preset without one or frame to frame; a number is taken as given, anything else is an
/// error. The JSON says which readout was modelled.
#[test]
fn track_models_the_presets_rolling_shutter_against_the_model() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 3);
    for (extra, want) in [
        (&["--camera", "kinect-v1"][..], 30.0),
        (&[][..], 30.0),
        (&["--camera", "icl-nuim"][..], 0.0),
        (&["--camera", "kinect-v1", "--frame-to-frame"][..], 0.0),
        (
            &["--camera", "kinect-v1", "--rolling-shutter-ms", "12.5"][..],
            12.5,
        ),
        (&["--rolling-shutter-ms", "0"][..], 0.0),
    ] {
        let mut args = vec!["track", "--tum", seq.to_str().unwrap(), "--voxel-m", "0.01"];
        args.extend_from_slice(extra);
        args.push("--json");
        let (v, stderr) = sldepth_json(&args);
        assert_eq!(v["rolling_shutter_ms"].as_f64(), Some(want), "{extra:?}");
        assert_eq!(v["frames"], 3);
        let said = stderr.contains("rolling shutter (30 ms readout");
        assert_eq!(said, want == 30.0, "{extra:?}");
    }
    // An Open3D folder (`depth/`): the `ros-default` (a Kinect-class preset) without a camera
    // file, none with one (a camera file says nothing of its shutter).
    let o3d_readout = |seq: &Path| {
        let dir = seq.to_str().unwrap();
        let (v, _) = sldepth_json(&[
            "track",
            "--o3d",
            dir,
            "--depth-scale",
            "5000",
            "--voxel-m",
            "0.01",
            "--json",
        ]);
        v["rolling_shutter_ms"].as_f64()
    };
    assert_eq!(o3d_readout(&seq), Some(30.0));
    std::fs::write(
        seq.join("camera.json"),
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [580, 0, 0, 0, 580, 0, 319.5, 239.5, 1]}"#,
    )
    .unwrap();
    assert_eq!(o3d_readout(&seq), Some(0.0));
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--rolling-shutter-ms",
        "fast",
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("must be `auto` or milliseconds"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `fuse --tum` picks the `tum-fr1` preset for a folder that does not name another sensor and,
/// with `--lens auto` (the default), undistorts every frame with its lens model before fusing;
/// `--lens none` fuses the frames as they are. Both meshes are built, and they differ.
#[test]
fn fuse_undistorts_the_frames_of_a_tum_folder_by_default() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 2);
    let mut pose_lines = String::new();
    for t in [100.0, 100.0 + 1.0 / 30.0] {
        pose_lines.push_str(&format!("{t:.6} 0 0 0 0 0 0 1\n"));
    }
    std::fs::write(seq.join("groundtruth.txt"), pose_lines).unwrap();
    let mut vertices = Vec::new();
    for (lens, want) in [("auto", true), ("none", false)] {
        let out = sldepth(&[
            "fuse",
            "--tum",
            seq.to_str().unwrap(),
            "--lens",
            lens,
            "--voxel-m",
            "0.02",
            "--json",
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{lens}: {stderr}");
        assert_eq!(stderr.contains("tum-fr1` lens model"), want, "{stderr}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["undistorted"], want, "{lens}");
        vertices.push(v["vertices"].as_u64().unwrap());
    }
    assert!(vertices.iter().all(|&n| n > 1000), "{vertices:?}");
    assert_ne!(vertices[0], vertices[1]);
}

/// A sequence none of whose frames can be read is an error that writes nothing (it exited 0
/// with an empty mesh and trajectory); an output that is one of the inputs (here the frame
/// list) is refused before any work; a frame list written with a UTF-8 byte-order mark reads.
#[test]
fn track_refuses_an_unreadable_sequence_and_outputs_over_its_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 3);
    let traj = tmp.path().join("traj.txt");
    let list = seq.join("depth.txt");
    let before = std::fs::read(&list).unwrap();
    // The output names the frame list: refused, the list unchanged.
    let out = sldepth(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--output",
        list.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("is an input of this command"), "{err}");
    assert_eq!(std::fs::read(&list).unwrap(), before);
    // With a byte-order mark the list reads as before.
    let mut bom = b"\xef\xbb\xbf".to_vec();
    bom.extend_from_slice(&before);
    std::fs::write(&list, &bom).unwrap();
    let (v, err) = sldepth_json(&[
        "track",
        "--tum",
        seq.to_str().unwrap(),
        "--output",
        traj.to_str().unwrap(),
        "--voxel-m",
        "0.01",
        "--json",
    ]);
    assert_eq!(v["tracked"], 3, "{err}");
    // Every frame cut short: an error, and no trajectory.
    std::fs::remove_file(&traj).unwrap();
    for e in std::fs::read_dir(seq.join("depth")).unwrap() {
        let p = e.unwrap().path();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..100]).unwrap();
    }
    let err = track_tum_fails(&seq, &traj);
    assert!(err.contains("none of the 3 frames could be read"), "{err}");
    assert!(err.contains("truncated"), "{err}");
}

/// A sequence with no depth at all tracks nothing, and `--json` says so: the per-tracked-frame
/// timings are null rather than a median of nothing printed as 0.
#[test]
fn track_json_has_no_timings_of_frames_it_never_tracked() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let mut list = String::from("# timestamp filename\n");
    for i in 0..3 {
        let t = 100.0 + f64::from(i) / 30.0;
        let file = format!("depth/{t:.6}.png");
        let empty = sl_core::DepthImage::invalid(640, 480);
        write_depth(seq.join(&file), &empty, &DepthEncoding::tum()).unwrap();
        list.push_str(&format!("{t:.6} {file}\n"));
    }
    std::fs::write(seq.join("depth.txt"), list).unwrap();
    let (v, _) = kinect_track_json(&seq, &[]);
    assert_eq!(v["frames"], 3);
    assert_eq!(v["tracked"], 0);
    for key in [
        "track_ms_median_tracked",
        "integrate_ms_median",
        "raycast_ms_median",
    ] {
        assert!(v[key].is_null(), "{key}: {}", v[key]);
    }
    assert!(v["step_ms_median"].as_f64().unwrap() >= 0.0);
}

/// A sequence folder without a frame is an error naming the folder and the files it should
/// hold (it said only "no depth frames in the sequence").
#[test]
fn track_names_the_files_an_empty_sequence_folder_lacks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("empty-scene");
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    // Files of other names do not count as frames.
    std::fs::write(dir.join("frame-000000.color.png"), b"").unwrap();
    std::fs::write(dir.join("depth.txt"), "# timestamp filename\n").unwrap();
    let d = dir.to_str().unwrap();
    for (source, says) in [
        (
            "--7scenes",
            vec![
                format!("--7scenes {d}: no depth frames in the folder"),
                "frame-NNNNNN.depth.png".to_string(),
            ],
        ),
        (
            "--o3d",
            vec![format!("--o3d {d}: no depth images in {d}/depth")],
        ),
        (
            "--tum",
            vec![format!(
                "--tum {d}: {d}/depth.txt lists no depth frames (expected lines `TIME DEPTH_FILE`)"
            )],
        ),
    ] {
        let out = sldepth(&["track", source, d]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{source}: {err}");
        for s in &says {
            assert!(
                err.contains(s.as_str()),
                "{source}: expected {s:?} in {err}"
            );
        }
    }
    // A sequence with frames and --max-frames 0 has none left: the error says which option.
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 1);
    let out = sldepth(&["track", "--tum", seq.to_str().unwrap(), "--max-frames", "0"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--max-frames 0: no frame left"), "{err}");
}

/// An Open3D-style folder whose images are numbered without zero padding (`8.png` … `11.png`)
/// is tracked in the order of its numbers: sorted by bytes (`10, 11, 8, 9`) the camera seemed
/// to jump back 3 cm at the third frame, a trajectory shuffled without a word.
#[test]
fn track_takes_unpadded_frame_numbers_in_their_order() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 4);
    let o3d = tmp.path().join("o3d");
    std::fs::create_dir_all(o3d.join("depth")).unwrap();
    let list = std::fs::read_to_string(seq.join("depth.txt")).unwrap();
    let names = list.lines().filter(|l| !l.starts_with('#'));
    for (i, line) in names.enumerate() {
        let name = line.split_whitespace().nth(1).unwrap();
        let to = o3d.join("depth").join(format!("{}.png", 8 + i));
        std::fs::copy(seq.join(name), to).unwrap();
    }
    let traj = tmp.path().join("traj.txt");
    let args = [
        "track",
        "--o3d",
        o3d.to_str().unwrap(),
        "--camera",
        "kinect-v1",
        "--depth-scale",
        "5000",
        "--voxel-m",
        "0.01",
        "--output",
        traj.to_str().unwrap(),
        "--json",
    ];
    let (v, _) = sldepth_json(&args);
    assert_eq!(v["lost"], 0, "{v}");
    // 1 cm per frame, away from the first.
    let rows = pose_rows(&traj);
    assert_eq!(rows.len(), 4);
    for (i, r) in rows.iter().enumerate() {
        let moved = (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
        assert!(
            (moved - 0.01 * i as f64).abs() < 0.004,
            "frame {i} moved {moved} m from the first, expected {} m",
            0.01 * i as f64
        );
    }
}

/// An Open3D-style folder whose images are named by their times, written with as few decimals
/// as they need (Python's `str(stamp.to_sec())`), is tracked in time order and stamped with
/// them: by the numbers in the names, `100.1` came before `100.0333` (a trajectory shuffled
/// without a word, stamped 0, 1, 2, … so no ground truth could be matched to it).
#[test]
fn track_takes_the_times_frame_names_state() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let stamps = write_sequence(&seq, 4);
    let o3d = tmp.path().join("o3d");
    std::fs::create_dir_all(o3d.join("depth")).unwrap();
    let names = ["100.0", "100.0333", "100.0667", "100.1"];
    for (i, t) in stamps.iter().enumerate() {
        let from = seq.join("depth").join(format!("{t:.6}.png"));
        std::fs::copy(from, o3d.join("depth").join(format!("{}.png", names[i]))).unwrap();
    }
    let traj = tmp.path().join("traj.txt");
    let (v, _) = kinect_track_json_from(
        &[o3d.to_str().unwrap()],
        &["--depth-scale", "5000", "--output", traj.to_str().unwrap()],
    );
    assert_eq!(v["lost"], 0, "{v}");
    let rows = pose_rows(&traj);
    let times: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(times, [100.0, 100.0333, 100.0667, 100.1]);
    for (i, r) in rows.iter().enumerate() {
        let moved = (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
        assert!(
            (moved - 0.01 * i as f64).abs() < 0.004,
            "frame {i} moved {moved} m from the first, expected {} m",
            0.01 * i as f64
        );
    }
}

/// A frame that measures far noisier than any sensor, here every frame of a sensor with
/// σ_D 0.2 px read at 200 times its depth scale (a wrong `--depth-scale`: about 20 px of
/// disparity noise), is tracked with the largest σ_D a sensor model may have: the run stopped
/// at the first frame on "model: invalid sensor model: disparity noise 1.65e1 px must be in
/// [0, 10]" before, naming neither the option nor the measurement.
#[test]
fn track_goes_on_past_frames_noisier_than_any_sensor_model() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let mut sensor = sl_core::SensorModel::kinect_v1();
    sensor.sigma_d_px = 0.2;
    write_sequence_through(&seq, 3, 1, &KinectSimulator::with_sensor(sensor).white());
    let (v, stderr) = kinect_track_json(&seq, &["--depth-scale", "1e6"]);
    assert_eq!(v["frames"], 3, "{v}");
    assert_eq!(v["skipped"], 0, "{v}");
    assert!(!stderr.contains("invalid sensor model"), "{stderr}");
    let sigma = v["prefilter_sigma_d_px_median"].as_f64().unwrap();
    assert_eq!(sigma, sl_core::sensor::MAX_SIGMA_D_PX, "{v}");
}

/// `sldepth track DIR` reads the layout from the folder: a TUM folder tracks exactly as with
/// `--tum`, the same frames written as an Open3D-style `depth/` folder are found by name, and a
/// folder of neither kind is an error that says what was looked for.
#[test]
fn track_reads_the_layout_of_a_folder_given_without_an_option() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    write_sequence(&seq, 4);
    let (traj_opt, traj_pos) = (tmp.path().join("opt.txt"), tmp.path().join("pos.txt"));
    let (j_opt, _) = kinect_track_json(&seq, &["--output", traj_opt.to_str().unwrap()]);
    let track_folder = |extra: &[&str]| kinect_track_json_from(&[seq.to_str().unwrap()], extra).0;
    let j_pos = track_folder(&["--output", traj_pos.to_str().unwrap()]);
    assert_eq!(j_pos["tracked"], j_opt["tracked"]);
    assert_eq!(
        std::fs::read_to_string(&traj_pos).unwrap(),
        std::fs::read_to_string(&traj_opt).unwrap()
    );
    // Without depth.txt the same images are an Open3D-style folder (its depth scale is
    // millimetres unless given), timed by their names (`100.033333.png`): the same trajectory.
    std::fs::remove_file(seq.join("depth.txt")).unwrap();
    let traj_o3d = tmp.path().join("o3d.txt");
    let j_o3d = track_folder(&[
        "--depth-scale",
        "5000",
        "--output",
        traj_o3d.to_str().unwrap(),
    ]);
    assert_eq!(j_o3d["tracked"], 4, "{j_o3d}");
    assert_eq!(
        std::fs::read_to_string(&traj_o3d).unwrap(),
        std::fs::read_to_string(&traj_opt).unwrap()
    );
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = sldepth(&["track", empty.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("cannot tell the sequence's layout"),
        "{stderr}"
    );
    let both = sldepth(&[
        "track",
        seq.to_str().unwrap(),
        "--tum",
        seq.to_str().unwrap(),
    ]);
    assert!(!both.status.success());
}

/// `sldepth fuse DIR` reads the layout from the folder as `track DIR` does: a TUM folder fuses
/// as with `--tum`, and an Open3D-style folder (a `depth` folder and one `.log` beside it) as
/// with `--o3d-log LOG --depth-dir DIR/depth`; a second `.log` makes it ambiguous, an error.
#[test]
fn fuse_reads_the_layout_of_a_folder_given_without_an_option() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    let stamps = write_sequence(&seq, 3);
    let mut gt = String::from("# timestamp tx ty tz qx qy qz qw\n");
    let mut log = String::new();
    for (i, t) in stamps.iter().enumerate() {
        gt.push_str(&format!("{t:.6} 0 0 0 0 0 0 1\n"));
        log.push_str(&format!(
            "{i} {i} {}\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
            i + 1
        ));
    }
    std::fs::write(seq.join("groundtruth.txt"), gt).unwrap();
    let fuse_json = |source: &[&str]| -> serde_json::Value {
        let mut args = vec!["fuse"];
        args.extend_from_slice(source);
        args.extend_from_slice(&["--voxel-m", "0.02", "--json"]);
        sldepth_json(&args).0
    };
    let dir = seq.to_str().unwrap();
    let (by_dir, by_tum) = (fuse_json(&[dir]), fuse_json(&["--tum", dir]));
    assert_eq!(by_dir["frames"], 3);
    assert_eq!(by_dir["vertices"], by_tum["vertices"]);
    // The same frames as an Open3D-style folder: no depth.txt, a trajectory log beside depth/.
    std::fs::remove_file(seq.join("depth.txt")).unwrap();
    std::fs::write(seq.join("trajectory.log"), &log).unwrap();
    let depth_dir = seq.join("depth");
    let log_path = seq.join("trajectory.log");
    let by_log = fuse_json(&[
        "--o3d-log",
        log_path.to_str().unwrap(),
        "--depth-dir",
        depth_dir.to_str().unwrap(),
        "--depth-scale",
        "5000",
    ]);
    let by_dir = fuse_json(&[dir, "--depth-scale", "5000"]);
    assert_eq!(by_dir["frames"], 3);
    assert_eq!(by_dir["vertices"], by_log["vertices"]);
    // A log shorter than the depth folder: the image without an entry is skipped, and said.
    let two_entries: String = log.lines().take(10).map(|l| format!("{l}\n")).collect();
    std::fs::write(&log_path, two_entries).unwrap();
    let (short, stderr) = sldepth_json(&["fuse", dir, "--depth-scale", "5000", "--json"]);
    assert_eq!(short["frames"], 2);
    assert!(
        stderr.contains("note: 1 depth images of") && stderr.contains("(2 entries)"),
        "{stderr}"
    );
    std::fs::write(&log_path, &log).unwrap();
    // Of several .log files, trajectory.log (as Open3D's Redwood sample ships it beside its
    // odometry.log); without one of that name, none is guessed.
    std::fs::write(seq.join("other.log"), "0 1 3\n").unwrap();
    let both = fuse_json(&[dir, "--depth-scale", "5000"]);
    assert_eq!(both["vertices"], by_log["vertices"]);
    std::fs::rename(&log_path, seq.join("odometry.log")).unwrap();
    let out = sldepth(&["fuse", dir, "--depth-scale", "5000"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("needs one .log trajectory")
            && stderr.contains("found 2 .log files: odometry.log, other.log"),
        "{stderr}"
    );
}
