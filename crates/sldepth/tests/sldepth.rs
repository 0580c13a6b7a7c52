//! End-to-end tests of the `sldepth` binary, including the regression tests over the seeded
//! synthetic frames in `testdata/` (regenerate them with `cargo xtask gen-testdata`).

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{sldepth, testdata};

fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "sldepth failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap_or_default()
}

/// `sldepth simulate` of `scene` with `options` into `dir/name`, which it returns.
/// The JSON `sldepth` prints for `args` followed by `extra`.
fn json_of_run(args: &[&str], extra: &[&str]) -> serde_json::Value {
    json_of(&sldepth(&[args, extra].concat()))
}

fn simulated(dir: &Path, name: &str, scene: &str, options: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["simulate", "--scene", scene, "--output", path_str(&out)];
    args.extend_from_slice(options);
    let o = sldepth(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

#[test]
fn info_reports_size_and_depth_range() {
    let p = testdata("floor-seed1-depth.png");
    let v = json_of(&sldepth(&["info", path_str(&p), "--json"]));
    assert_eq!(v["width"], 640);
    assert_eq!(v["height"], 480);
    let valid = v["valid_pixels"].as_u64().unwrap_or(0);
    assert!(valid > 200_000, "valid {valid}");
    let (zmin, zmed, zmax) = (
        v["z_min_m"].as_f64().unwrap_or(0.0),
        v["z_median_m"].as_f64().unwrap_or(0.0),
        v["z_max_m"].as_f64().unwrap_or(0.0),
    );
    // The floor scene spans about 0.8 to 3.9 m.
    assert!(zmin > 0.7 && zmin < 0.9, "zmin {zmin}");
    assert!(zmax > 3.5 && zmax < 4.5, "zmax {zmax}");
    assert!(zmin < zmed && zmed < zmax);
}

/// Regression over the committed floor frame: the analysis recovers the simulator's
/// f·B = 580 px × 0.075 m = 43.5 px·m within 1 %, its 1/8 px steps, and a slope near 2.
#[test]
fn analyze_recovers_the_simulated_sensor_from_testdata() {
    let p = testdata("floor-seed1-depth.png");
    let v = json_of(&sldepth(&["analyze", path_str(&p), "--json"]));
    let fb = v["fb_px_m"].as_f64().unwrap_or(0.0);
    assert!((fb - 43.5).abs() / 43.5 < 0.01, "fb {fb}");
    assert_eq!(v["subpixel_steps"], 8);
    let slope = v["slope"].as_f64().unwrap_or(0.0);
    assert!((1.9..=2.1).contains(&slope), "slope {slope}");
    assert!(v["unique_depths"].as_u64().unwrap_or(0) > 200);
}

/// Regression: simulating the same scene and seed again gives exactly the committed frame
/// (the committed frames are the paper's white-noise model).
#[test]
fn simulate_reproduces_committed_frames() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    for (scene, seed) in [("floor", "1"), ("figure-walls", "2"), ("three-planes", "3")] {
        let labels = dir.path().join(format!("{scene}-labels.png"));
        let out = simulated(
            dir.path(),
            &format!("{scene}.png"),
            scene,
            &[
                "--noise",
                "white",
                "--seed",
                seed,
                "--labels",
                path_str(&labels),
            ],
        );
        let read = |p: &Path| {
            sl_io::depth::read_depth(p, &sl_io::depth::ReadConfig::default())
                .unwrap_or_else(|e| panic!("{e}"))
                .depth
        };
        let fresh = read(&out);
        let committed = read(&testdata(&format!("{scene}-seed{seed}-depth.png")));
        assert_eq!(
            fresh, committed,
            "{scene} seed {seed} differs from testdata/"
        );
        let l1 = sl_io::rgb::read_gray16(&labels).unwrap_or_else(|e| panic!("{e}"));
        let l2 = sl_io::rgb::read_gray16(testdata(&format!("{scene}-seed{seed}-labels.png")))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(l1, l2);
    }
}

/// The default simulator is the realistic one: `noise-stats` finds its error correlated
/// between neighbours and occlusion bands beside the figure; the white model's error is not
/// correlated. Against the camera's model, both are within it, and a sensor simulated twice as
/// noisy as the camera says measures about 3.4 times its pixel variance.
#[test]
fn simulate_realistic_by_default_and_noise_stats_measures_it() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let stats_sigma = |noise: &str, sigma: &str| {
        let out = simulated(
            dir.path(),
            &format!("{noise}-{sigma}.png"),
            "figure-walls",
            &["--noise", noise, "--sigma-d-px", sigma],
        );
        let o = sldepth(&["noise-stats", path_str(&out), "--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap_or_else(|e| panic!("{e}"))
    };
    let stats = |noise: &str| stats_sigma(noise, "0.07");
    let real = stats("realistic");
    let white = stats("white");
    let scale = |v: &serde_json::Value| v["model_variance_scale"].as_f64().unwrap_or(f64::NAN);
    assert_eq!(scale(&real), 1.0, "{}", real["model_variance_scale"]);
    assert_eq!(scale(&white), 1.0, "{}", white["model_variance_scale"]);
    let model_sigma = real["model_effective_sigma_d_px"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!((model_sigma - 0.07).abs() < 1e-12, "{model_sigma}");
    let noisier = stats_sigma("realistic", "0.14");
    assert!((2.5..4.5).contains(&scale(&noisier)), "{noisier}");
    let sigma = noisier["model_effective_sigma_d_px"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!((0.11..0.17).contains(&sigma), "{sigma}");
    let acf1 = |v: &serde_json::Value| v["acf"][0]["x"].as_f64().unwrap_or(f64::NAN);
    assert!(acf1(&real) > 0.5, "realistic ρ_x(1) = {}", acf1(&real));
    assert!(acf1(&white).abs() < 0.2, "white ρ_x(1) = {}", acf1(&white));
    let left = |v: &serde_json::Value| v["occlusion"]["left"]["widths"]["count"].as_u64();
    assert!(left(&real).unwrap_or(0) > 100, "{}", real["occlusion"]);
    assert_eq!(left(&white), Some(0));
}

/// The text report of a frame without occlusion bands (the white model makes none) says so,
/// rather than printing the NaN statistics of no runs.
#[test]
fn noise_stats_text_says_no_band_rather_than_nan() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let out = simulated(
        dir.path(),
        "white.png",
        "figure-walls",
        &["--noise", "white"],
    );
    let o = sldepth(&["noise-stats", path_str(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(!text.contains("NaN"), "{text}");
    assert!(
        text.contains("occlusion bands  left of foreground: no band;"),
        "{text}"
    );
}

/// `--min-return` drops weak returns; `--reflectance` darkens one surface, which then drops out
/// where its return falls below the bound; bad specifications are errors that name them.
#[test]
fn simulate_drops_out_dark_and_far_surfaces_with_min_return() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let out = dir.path().join("boxes.png");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "simulate",
            "--scene",
            "boxes",
            "-o",
            path_str(&out),
            "--json",
        ];
        args.extend_from_slice(extra);
        sldepth(&args)
    };
    let valid = |extra: &[&str]| {
        let o = run(extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v = json_of(&o);
        v["valid_pixels"].as_u64().unwrap_or(0)
    };
    let (all, bound, dark) = (
        valid(&[]),
        valid(&["--min-return", "0.04"]),
        valid(&["--min-return", "0.04", "--reflectance", "1=0.1"]),
    );
    assert!(all > bound && bound > dark, "{all} {bound} {dark}");
    let v = json_of(&run(&["--min-return", "0.04", "--reflectance", "1=0.1"]));
    assert_eq!(v["min_return"], 0.04);
    assert_eq!(v["surfaces"][0]["reflectance"], 0.1);
    // The default bound, 0 (off), is also the white model's, as in Python.
    assert!(valid(&["--noise", "white", "--min-return", "0"]) > 0);
    for (bad, says) in [
        (vec!["--reflectance", "1=2"], "must be in [0, 1]"),
        (vec!["--reflectance", "x"], "expected LABEL=R"),
        (vec!["--reflectance", "999=0.5"], "no surface 999"),
        // Labels are 16-bit: beyond them a well-formed LABEL=R names no surface either.
        (vec!["--reflectance", "65536=0.5"], "no surface 65536"),
        (vec!["--reflectance=-1=0.5"], "no surface -1"),
        (
            vec![
                "--reflectance",
                "123456789012345678901234567890123456789012=0.5",
            ],
            "no surface 123456789012345678901234567890123456789012 (the scene has labels 1..=",
        ),
        (vec!["--reflectance", "1.5=0.5"], "expected LABEL=R"),
        (vec!["--reflectance", "1=dark"], "expected LABEL=R"),
        (
            vec!["--min-return=-1"],
            "--min-return -1: must be a finite number >= 0",
        ),
        (
            vec!["--noise", "white", "--min-return", "0.04"],
            "realistic model",
        ),
        // Without the bound, or with the white model, nothing reads a reflectance: an error
        // saying why rather than a reflectance the JSON shows and the frame ignores.
        (
            vec!["--reflectance", "1=0.1"],
            "--reflectance has no effect without a positive --min-return",
        ),
        (
            vec!["--reflectance", "1=0.1", "--min-return", "0"],
            "--reflectance has no effect without a positive --min-return",
        ),
        (
            vec!["--reflectance", "1=0.1", "--noise", "white"],
            "--reflectance has no effect with --noise white",
        ),
        (
            vec![
                "--reflectance",
                "1=0.1",
                "--noise",
                "white",
                "--min-return",
                "0",
            ],
            "--reflectance has no effect with --noise white",
        ),
        (
            vec!["--reflectance", "1=0.1", "--min-return=-1"],
            "--min-return -1: must be",
        ),
    ] {
        let o = run(&bad);
        assert!(!o.status.success(), "{bad:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{bad:?}: {err}");
    }
}

#[test]
fn cloud_writes_one_point_per_valid_pixel() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let p = testdata("three-planes-seed3-depth.png");
    let ply = dir.path().join("cloud.ply");
    let o = sldepth(&["cloud", path_str(&p), "--output", path_str(&ply)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info = json_of(&sldepth(&["info", path_str(&p), "--json"]));
    let data = sl_io::ply::read_ply(&ply).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        data.positions.len() as u64,
        info["valid_pixels"].as_u64().unwrap_or(0)
    );
    // Every point is in front of the camera within the sensor's range.
    assert!(data.positions.iter().all(|p| p[2] > 0.4 && p[2] < 5.1));
}

/// `cloud --camera tum-fr1` undistorts the frame with the preset's lens model by default: the
/// resampled image loses the pixels whose rays leave the distorted image, so fewer points come
/// out than with `--lens none` (one per valid pixel), and the points lie in front of the camera.
#[test]
fn cloud_undistorts_with_the_lens_of_a_preset() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let p = testdata("three-planes-seed3-depth.png");
    let info = json_of(&sldepth(&["info", path_str(&p), "--json"]));
    let valid = info["valid_pixels"].as_u64().unwrap_or(0);
    let mut counts = Vec::new();
    for lens in ["auto", "none"] {
        let ply = dir.path().join(format!("cloud-{lens}.ply"));
        let o = sldepth(&[
            "cloud",
            path_str(&p),
            "--camera",
            "tum-fr1",
            // A millimetre file (a `tum-*` camera alone reads TUM's 5000 units per metre).
            "--depth-scale",
            "1000",
            "--lens",
            lens,
            "--output",
            path_str(&ply),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let data = sl_io::ply::read_ply(&ply).unwrap_or_else(|e| panic!("{e}"));
        assert!(data.positions.iter().all(|p| p[2] > 0.4 && p[2] < 5.1));
        counts.push(data.positions.len() as u64);
    }
    assert_eq!(counts[1], valid);
    assert!(
        counts[0] < valid && counts[0] > valid / 2,
        "{counts:?} of {valid}"
    );
}

#[test]
fn errors_name_the_file_and_problem() {
    let o = sldepth(&["info", "/nonexistent/depth.png"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("/nonexistent/depth.png"), "{err}");

    let p = testdata("floor-seed1-depth.png");
    let o = sldepth(&["info", path_str(&p), "--format", "jpeg"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("jpeg"));

    let o = sldepth(&["simulate", "--scene", "moon", "--output", "/tmp/x.png"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("floor"));
}

#[test]
fn help_names_units() {
    for cmd in ["info", "analyze", "simulate", "cloud"] {
        let o = sldepth(&[cmd, "--help"]);
        assert!(o.status.success());
        let help = String::from_utf8_lossy(&o.stdout);
        assert!(help.contains("UNITS_PER_M"), "{cmd}: {help}");
    }
}

/// The defaults `simulate --help` quotes for the realistic model are the library's.
#[test]
fn simulate_help_quotes_the_realistic_defaults() {
    use sl_noise::sim::realistic::{DEFAULT_SPECKLE_PX, DEFAULT_WINDOW_X, DEFAULT_WINDOW_Y};
    let o = sldepth(&["simulate", "--help"]);
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout);
    let window = format!("(default {DEFAULT_WINDOW_X}x{DEFAULT_WINDOW_Y}");
    let speckle = format!("(default {DEFAULT_SPECKLE_PX})");
    assert!(help.contains(&window), "{window} not in {help}");
    assert!(help.contains(&speckle), "{speckle} not in {help}");
}

/// `fuse` on a committed frame with an identity pose: a mesh whose vertices lie at the frame's
/// depths, the JSON fields the issue names, and a clear error past the memory budget.
#[test]
fn fuse_meshes_a_frame_and_refuses_past_the_budget() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let depth = testdata("three-planes-seed3-depth.png");
    let list = dir.path().join("frames.txt");
    let identity = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    std::fs::write(&list, format!("{} {identity}\n", depth.display()))
        .unwrap_or_else(|e| panic!("{e}"));
    let mesh = dir.path().join("mesh.ply");
    let v = json_of(&sldepth(&[
        "fuse",
        "--frames",
        path_str(&list),
        "--voxel-m",
        "0.01",
        "--output",
        path_str(&mesh),
        "--json",
    ]));
    for key in [
        "frames",
        "integrate_ms_median",
        "extract_ms",
        "vertices",
        "triangles",
        "blocks",
        "memory_bytes",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["frames"], 1);
    let data = sl_io::ply::read_ply(&mesh).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        data.positions.len() as u64,
        v["vertices"].as_u64().unwrap_or(0)
    );
    assert_eq!(
        data.faces.len() as u64,
        v["triangles"].as_u64().unwrap_or(0)
    );
    assert!(data.faces.len() > 1000, "{} triangles", data.faces.len());
    // The scene's surfaces are 0.5 to 3.5 m in front of the camera (identity pose: world = camera).
    // At silhouettes marching cubes may close the surface up to one truncation band behind the
    // farthest observed (noisy) depth: the default band there is max(5 voxels, 3σ_Z(Z)).
    let frame = sl_io::depth::read_depth(&depth, &sl_io::depth::ReadConfig::default())
        .unwrap_or_else(|e| panic!("{e}"))
        .depth;
    let z_max = frame.data().iter().fold(0.0f32, |m, &z| m.max(z)).min(4.0);
    let band = (3.0 * sl_core::SensorModel::kinect_v1().sigma_z(f64::from(z_max))).max(0.05);
    let far = f64::from(z_max) + band + 0.01;
    assert!(
        data.positions
            .iter()
            .all(|p| p[2] > 0.45 && f64::from(p[2]) < far),
        "vertices beyond {far} m"
    );

    let o = sldepth(&[
        "fuse",
        "--frames",
        path_str(&list),
        "--voxel-m",
        "0.01",
        "--memory-budget-bytes",
        "100000",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr).to_lowercase();
    assert!(err.contains("budget"), "{err}");
}

/// A reader that closes the pipe early ends the program quietly, not with a panic.
#[test]
fn closed_stdout_is_not_a_panic() {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_sldepth"))
        .args(["cameras", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader is gone before the first byte
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
}

/// A full disk on stdout is a clean error with a non-zero exit.
#[test]
fn full_stdout_is_a_clean_error() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("skipping: no /dev/full on this system");
        return;
    };
    let out = Command::new(env!("CARGO_BIN_EXE_sldepth"))
        .args(["info", path_str(&testdata("floor-seed1-depth.png"))])
        .stdout(full)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("No space left"), "{stderr}");
}

/// `--camera` takes a preset name; an unknown one is told the valid names.
#[test]
fn camera_presets_by_name() {
    let ok = sldepth(&[
        "info",
        path_str(&testdata("floor-seed1-depth.png")),
        "--camera",
        "kinect-v1",
        "--json",
    ]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let bad = sldepth(&[
        "info",
        path_str(&testdata("floor-seed1-depth.png")),
        "--camera",
        "kinect-v9",
    ]);
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success());
    assert!(
        stderr.contains("tum-fr1") && stderr.contains("d435"),
        "{stderr}"
    );
    let list = json_of(&sldepth(&["cameras", "--json"]));
    let names: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    for n in [
        "kinect-v1",
        "tum-fr1",
        "7-scenes",
        "nyu-v2",
        "icl-nuim",
        "primesense",
        "d415",
        "d435",
        "d455",
        "oak-d",
    ] {
        assert!(names.contains(&n), "{n} missing from {names:?}");
    }
}

/// `sldepth filter` runs the multi-scale filter by default for the sensor-model methods and the
/// single pass when asked (or for the classic methods), and says so in its JSON.
#[test]
fn filter_is_multiscale_by_default_and_single_scale_on_request() {
    let input = testdata("three-planes-seed3-depth.png");
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec!["filter", path_str(&input), path_str(&out), "--json"];
        args.extend_from_slice(extra);
        let v = json_of(&sldepth(&args));
        (
            std::fs::read(&out).unwrap(),
            v["multiscale_dilations"].clone(),
        )
    };
    let (default, dil) = run("default.png", &[]);
    assert_eq!(dil, serde_json::json!([2, 4, 8]));
    let (multi, _) = run("multi.png", &["--multiscale"]);
    assert_eq!(default, multi);
    let (single, dil) = run("single.png", &["--single-scale"]);
    assert!(dil.is_null());
    assert_ne!(default, single);
    let (_, dil) = run("gauss.png", &["--method", "gaussian"]);
    assert!(dil.is_null());
    let both = sldepth(&[
        "filter",
        path_str(&input),
        path_str(&dir.path().join("x.png")),
        "--multiscale",
        "--single-scale",
    ]);
    assert!(!both.status.success());
}

/// A frame a whole fraction of the camera's size (a 320×240 decimation of a 640×480 testdata
/// frame) is the camera's sensor decimated: the single-frame commands take it with a note and
/// find the same planes as at full resolution; any other size stays an error.
#[test]
fn a_decimated_frame_is_the_same_sensor() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let p = testdata("three-planes-seed3-depth.png");
    let full = sl_io::read_depth(&p, &sl_io::ReadConfig::default())
        .unwrap_or_else(|e| panic!("{e}"))
        .depth;
    let write = |name: &str, depth: &sl_core::DepthImage| {
        let path = dir.path().join(name);
        sl_io::depth::write_depth(&path, depth, &sl_io::depth::DepthEncoding::default())
            .unwrap_or_else(|e| panic!("{e}"));
        path
    };
    let decimated = sl_testkit::decimate(&full, 2);
    let half = write("half.png", &decimated);
    let labels = dir.path().join("labels.png");
    let planes = |path: &Path| {
        let o = sldepth(&[
            "planes",
            path_str(path),
            "--camera",
            "kinect-v1",
            "--output",
            path_str(&labels),
            "--json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (json_of(&o), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (at_full, _) = planes(&p);
    let (at_half, note) = planes(&half);
    assert!(note.contains("1/2 of the camera's 640x480"), "{note}");
    let count = |v: &serde_json::Value| v["planes"].as_array().map_or(0, Vec::len);
    assert!(count(&at_full) >= 3);
    assert_eq!(count(&at_half), count(&at_full));
    // 320×200 (the decimated frame's first 200 rows) is no whole fraction of 640×480.
    let rows = decimated.data()[..320 * 200].to_vec();
    let odd = write(
        "odd.png",
        &sl_core::DepthImage::from_vec(320, 200, rows).unwrap_or_else(|e| panic!("{e}")),
    );
    let o = sldepth(&[
        "planes",
        path_str(&odd),
        "--camera",
        "kinect-v1",
        "--output",
        path_str(&labels),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("320x200 but the camera is 640x480"));
}

/// A frame of uniform random depth measures a disparity error far above `--threshold-px`: no
/// plane, `noise_beyond_threshold` in the JSON, every unexplained region's reason, and a line
/// in the text output that names the threshold. A simulated frame says `false`.
#[test]
fn planes_of_a_frame_noisier_than_the_threshold_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let random = sl_core::DepthImage::from_image(sl_core::Image::from_fn(640, 480, |_, _| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        0.5 + 4.0 * (state >> 40) as f32 / (1u64 << 24) as f32
    }));
    let path = dir.path().join("random.png");
    sl_io::depth::write_depth(&path, &random, &sl_io::depth::DepthEncoding::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let labels = dir.path().join("labels.png");
    let base = [
        "planes",
        path_str(&path),
        "--camera",
        "kinect-v1",
        "--output",
        path_str(&labels),
    ];
    let v = json_of_run(&base, &["--json", "--explain"]);
    assert_eq!(v["noise_beyond_threshold"], true, "{v}");
    assert_eq!(v["planes"].as_array().map(Vec::len), Some(0), "{v}");
    let regions = v["unlabelled"].as_array().cloned().unwrap_or_default();
    assert!(!regions.is_empty(), "{v}");
    assert!(
        regions
            .iter()
            .all(|r| r["reason"] == "NoiseBeyondThreshold"),
        "{v}"
    );
    let text = sldepth(&base);
    assert!(text.status.success());
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("no plane extracted") && text.contains("--threshold-px 0.5"),
        "{text}"
    );
    let p = testdata("three-planes-seed3-depth.png");
    let v = json_of_run(
        &[
            "planes",
            path_str(&p),
            "--camera",
            "kinect-v1",
            "--output",
            path_str(&labels),
        ],
        &["--json"],
    );
    assert_eq!(v["noise_beyond_threshold"], false, "{v}");
}

/// The switches of the disparity method are refused with `--method metric-ransac`, naming the
/// switch, instead of being ignored.
#[test]
fn disparity_switches_are_refused_with_metric_ransac() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let p = testdata("three-planes-seed3-depth.png");
    let labels = dir.path().join("labels.png");
    let base = [
        "planes",
        path_str(&p),
        "--camera",
        "kinect-v1",
        "--output",
        path_str(&labels),
        "--method",
        "metric-ransac",
    ];
    assert!(sldepth(&base).status.success());
    for extra in [
        &["--explain"][..],
        &["--give-back-taken-in"],
        &["--refine-seams"],
        &["--no-split-creases"],
        &["--model-noise-only"],
        &["--max-normal-sigma-deg", "2"],
    ] {
        let o = sldepth(&[&base[..], extra].concat());
        assert!(!o.status.success(), "{extra:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(extra[0]) && err.contains("--method disparity"),
            "{extra:?}: {err}"
        );
    }
}

/// A fronto-parallel wall `z_m` away, `size` pixels, written as a 16-bit PNG of `units_per_m`
/// into `dir/name`.
fn write_wall(dir: &Path, name: &str, size: (usize, usize), z_m: f32, units_per_m: f64) -> PathBuf {
    let p = dir.join(name);
    let wall = sl_core::DepthImage::from_image(sl_core::Image::from_fn(size.0, size.1, |_, _| z_m));
    sl_io::depth::write_depth(&p, &wall, &sl_io::depth::DepthEncoding::png(units_per_m))
        .unwrap_or_else(|e| panic!("{e}"));
    p
}

/// A frame stored at another scale than the one it is read at (a TUM file, 5000 units per
/// metre, read as millimetres) gets a note: its median depth lies beyond the camera's range.
/// Given the right `--depth-scale`, no note.
#[test]
fn a_depth_scale_that_puts_the_frame_out_of_range_is_noted() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let p = write_wall(dir.path(), "tum-like.png", (64, 48), 2.0, 5000.0);
    let camera = dir.path().join("cam.json");
    std::fs::write(
        &camera,
        r#"{"width": 64, "height": 48, "intrinsic_matrix": [58, 0, 0, 0, 58, 0, 31.5, 23.5, 1]}"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let run = |extra: &[&str]| {
        let mut args = vec!["info", path_str(&p), "--camera", path_str(&camera)];
        args.extend_from_slice(extra);
        let o = sldepth(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let noted = run(&[]);
    assert!(
        noted.contains("median depth 10.00 m") && noted.contains("--depth-scale"),
        "{noted}"
    );
    assert!(!run(&["--depth-scale", "5000"]).contains("note:"));
}

/// A frame whose surfaces all lie beyond `fuse --max-depth-m` fuses into an empty mesh, and the
/// command says why instead of writing 0 vertices without a word.
#[test]
fn an_empty_fused_mesh_names_the_depth_bound() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let far = write_wall(dir.path(), "far.png", (640, 480), 6.0, 1000.0);
    let list = dir.path().join("frames.txt");
    std::fs::write(
        &list,
        format!("{} 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n", far.display()),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let ply = dir.path().join("m.ply");
    let o = sldepth(&["fuse", "--frames", path_str(&list), "-o", path_str(&ply)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("the mesh is empty") && stderr.contains("--max-depth-m 4"),
        "{stderr}"
    );
}

/// `sldepth filter` measures the frame's noise against the camera's model: a frame simulated
/// twice as noisy as the Kinect camera says is filtered for the σ_D it measures (about
/// 0.14 px); at the model's noise, or with `--model-noise-only`, for the camera's 0.07 px.
#[test]
fn filter_follows_the_frames_own_noise() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let raw = |sigma: &str| {
        simulated(
            dir.path(),
            &format!("raw-{sigma}.png"),
            "floor",
            &["--sigma-d-px", sigma],
        )
    };
    let out = dir.path().join("out.png");
    let filtered = |raw: &Path, extra: &[&str]| {
        json_of_run(&["filter", path_str(raw), path_str(&out), "--json"], extra)
    };
    let noisier = raw("0.14");
    let noisy = filtered(&noisier, &[]);
    let scale = noisy["noise_scale"].as_f64().unwrap_or(f64::NAN);
    let sigma = noisy["sigma_d_px"].as_f64().unwrap_or(f64::NAN);
    assert!((2.5..4.5).contains(&scale), "{noisy}");
    assert!((0.11..0.17).contains(&sigma), "{noisy}");
    let plain = filtered(&noisier, &["--model-noise-only"]);
    assert_eq!(plain["noise_scale"].as_f64(), Some(1.0));
    assert_eq!(plain["sigma_d_px"].as_f64(), Some(0.07));
    // The adaptive filter's k follows σ_D.
    let k = |v: &serde_json::Value| v["k_per_m"].as_f64().unwrap_or(f64::NAN);
    assert!(
        (k(&noisy) / k(&plain) - sigma / 0.07).abs() < 1e-6,
        "{noisy} {plain}"
    );
    let nominal = filtered(&raw("0.07"), &[]);
    assert_eq!(nominal["noise_scale"].as_f64(), Some(1.0));
}

/// `fuse` measures the first frame's noise: frames of a sensor three times noisier than the
/// camera's model get the band of their own σ_D, and so fewer spurious surfaces ("foam") than
/// with the camera's band; at the model's noise nothing changes.
#[test]
fn fuse_band_follows_the_first_frames_own_noise() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let identity = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    let list = |sigma: &str| {
        let mut text = String::new();
        for seed in 0..4 {
            let p = simulated(
                dir.path(),
                &format!("floor-{sigma}-{seed}.png"),
                "floor",
                &["--sigma-d-px", sigma, "--seed", &seed.to_string()],
            );
            text.push_str(&format!("{} {identity}\n", p.display()));
        }
        let l = dir.path().join(format!("frames-{sigma}.txt"));
        std::fs::write(&l, text).unwrap_or_else(|e| panic!("{e}"));
        l
    };
    let fused = |l: &Path, extra: &[&str]| {
        json_of_run(
            &[
                "fuse",
                "--frames",
                path_str(l),
                "--voxel-m",
                "0.01",
                "--json",
            ],
            extra,
        )
    };
    let noisier = list("0.2");
    let measured = fused(&noisier, &[]);
    let scale = measured["noise_scale"].as_f64().unwrap_or(f64::NAN);
    let sigma = measured["band_sigma_d_px"].as_f64().unwrap_or(f64::NAN);
    // (0.2² + 1/768) / (0.07² + 1/768) = 6.7.
    assert!((5.0..8.5).contains(&scale), "{measured}");
    assert!((0.17..0.23).contains(&sigma), "{measured}");
    let model = fused(&noisier, &["--model-noise-only"]);
    assert_eq!(model["noise_scale"].as_f64(), Some(1.0));
    assert_eq!(model["band_sigma_d_px"].as_f64(), Some(0.07));
    let verts = |v: &serde_json::Value| v["vertices"].as_u64().unwrap_or(0);
    assert!(
        verts(&measured) * 10 < verts(&model) * 9,
        "measured band {} vertices, camera's band {}",
        verts(&measured),
        verts(&model)
    );
    let nominal = fused(&list("0.07"), &[]);
    assert_eq!(nominal["noise_scale"].as_f64(), Some(1.0));
}

/// `fuse --prefilter` takes the names `track --prefilter` takes: `none` is the default, a bare
/// `--prefilter` is the single adaptive pass (its meaning before it took a name), and
/// `multiscale` adds the coarse passes, which change the mesh.
#[test]
fn fuse_prefilter_names_the_filters_track_uses() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let identity = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    let mut text = String::new();
    for seed in 0..2 {
        let p = simulated(
            dir.path(),
            &format!("walls-{seed}.png"),
            "figure-walls",
            &["--seed", &seed.to_string()],
        );
        text.push_str(&format!("{} {identity}\n", p.display()));
    }
    let list = dir.path().join("frames.txt");
    std::fs::write(&list, text).unwrap_or_else(|e| panic!("{e}"));
    let fused = |name: &str, extra: &[&str]| {
        let ply = dir.path().join(format!("{name}.ply"));
        let args = [
            "fuse",
            "--frames",
            path_str(&list),
            "--voxel-m",
            "0.01",
            "-o",
            path_str(&ply),
        ];
        // The flag goes before `--json`, so a bare `--prefilter` is followed by an option.
        let v = json_of_run(&[&args[..], extra].concat(), &["--json"]);
        let bytes = std::fs::read(&ply).unwrap_or_else(|e| panic!("{}: {e}", ply.display()));
        (v, bytes)
    };
    let (default, default_ply) = fused("default", &[]);
    let (none, none_ply) = fused("none", &["--prefilter", "none"]);
    let (bare, bare_ply) = fused("bare", &["--prefilter"]);
    let (single, single_ply) = fused("single", &["--prefilter", "single"]);
    let (multi, multi_ply) = fused("multi", &["--prefilter", "multiscale"]);
    for (v, name) in [
        (&default, "none"),
        (&none, "none"),
        (&bare, "single"),
        (&single, "single"),
        (&multi, "multiscale"),
    ] {
        assert_eq!(v["prefilter"].as_str(), Some(name), "{v}");
    }
    assert_eq!(default_ply, none_ply);
    assert_eq!(bare_ply, single_ply);
    assert_ne!(single_ply, none_ply);
    assert_ne!(multi_ply, single_ply);
    let o = sldepth(&["fuse", "--frames", path_str(&list), "--prefilter", "median"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("multiscale, single, none"), "{err}");
}

/// `fuse` on a sequence folder with no frames names the option and the folder.
#[test]
fn fuse_names_the_folder_that_had_no_frames() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("tempdir: {e}"));
    let out = dir.path().join("mesh.ply");
    let o = sldepth(&[
        "fuse",
        "--7scenes",
        path_str(dir.path()),
        "--output",
        path_str(&out),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--7scenes") && err.contains(path_str(dir.path())),
        "{err}"
    );
    assert!(!out.exists());
}
