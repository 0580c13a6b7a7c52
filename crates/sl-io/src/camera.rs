//! Camera files: Open3D `PinholeCameraIntrinsic` JSON (with optional sensor-model keys) and
//! plain 3×3 intrinsic matrices such as 7-Scenes' `camera-intrinsics.txt`.
//!
//! The JSON format is Open3D's:
//!
//! ```json
//! {
//!   "width": 640, "height": 480,
//!   "intrinsic_matrix": [fx, 0, 0, 0, fy, 0, cx, cy, 1],
//!   "baseline_m": 0.075, "subpixel": 8, "sigma_d_px": 0.07
//! }
//! ```
//!
//! `intrinsic_matrix` is the 3×3 matrix `K` in **column-major** order. The last three keys are
//! ours and optional (defaults: the Kinect's 0.075 m, 8 steps, σ_D 0.07 px), so any Open3D camera
//! file reads. Open3D's `PinholeCameraParameters` files (an `intrinsic` object of this form
//! beside an `extrinsic` pose) read as their intrinsic object. A fourth optional key,
//! `sensor_focal_px`, is written only when the sensor's focal length differs from `fx` (it
//! defaults to `fx`). Other keys (the metadata other tools write
//! beside Open3D's three) are ignored, except one that names a sensor quantity in another
//! spelling (`baseline`, `baseline_mm`, `sigma_d`, `sub_pixel`, ...): that is refused, since
//! ignoring it would leave the Kinect default in its place without a word.

use std::path::Path;

use serde::{Deserialize, Serialize};
use sl_core::camera::{KINECT_BASELINE_M, KINECT_SUBPIXEL_STEPS};
use sl_core::sensor::DEFAULT_SIGMA_D_PX;
use sl_core::{Camera, Intrinsics, SensorModel};

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::text::read_text;

/// Largest camera file we read (they are a few hundred bytes).
const MAX_CAMERA_BYTES: u64 = 1 << 20;

/// Default image size for intrinsics files that do not state it (7-Scenes, Kinect v1).
pub const DEFAULT_WIDTH: usize = 640;
/// Default image height, see [`DEFAULT_WIDTH`].
pub const DEFAULT_HEIGHT: usize = 480;

/// How far from zero the fixed entries of `K` may be (skew, bottom row).
const MATRIX_TOLERANCE: f64 = 1e-9;

#[derive(Debug, Serialize, Deserialize)]
#[serde(
    expecting = "a camera object with `width`, `height` and `intrinsic_matrix` \
                     (9 numbers, column-major)"
)]
struct CameraJson {
    width: usize,
    height: usize,
    intrinsic_matrix: [f64; 9],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    baseline_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    subpixel: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_d_px: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sensor_focal_px: Option<f64>,
}

/// The optional sensor keys of a camera file.
const SENSOR_KEYS: [&str; 4] = ["baseline_m", "subpixel", "sigma_d_px", "sensor_focal_px"];

/// Parts of a key that name one of the sensor quantities of [`SENSOR_KEYS`].
const SENSOR_KEY_STEMS: [&str; 5] = ["baseline", "subpixel", "sub_pixel", "sigma", "sensor_focal"];

/// Refuses a key of `keys` (a JSON object's) that is not one of ours but names a sensor
/// quantity (`baseline`, `sigma_d`): a misspelt sensor key would otherwise be ignored and the
/// Kinect default used in its place.
fn check_sensor_key_spelling(
    path: &Path,
    keys: &serde_json::Map<String, serde_json::Value>,
) -> Result<()> {
    let misspelt = keys.keys().find(|k| {
        let lower = k.to_ascii_lowercase();
        !SENSOR_KEYS.contains(&k.as_str()) && SENSOR_KEY_STEMS.iter().any(|s| lower.contains(s))
    });
    match misspelt {
        Some(k) => Err(IoError::malformed(
            path,
            format!(
                "unknown key {k:?}: the sensor keys are `baseline_m` (metres), `subpixel` \
                 (disparity steps per pixel), `sigma_d_px` (pixels) and `sensor_focal_px` \
                 (pixels); a misspelt one would leave the Kinect default in its place"
            ),
        )),
        None => Ok(()),
    }
}

/// The camera object of a camera file, its sensor keys' spelling checked: the file's own
/// top-level object, or for Open3D's `PinholeCameraParameters` (what
/// `open3d.io.write_pinhole_camera_parameters` writes: the camera's `extrinsic` pose beside an
/// `intrinsic` object, and no `intrinsic_matrix` at the top) its `intrinsic` object, with the
/// sensor keys of the top level where it has none of its own. The extrinsic pose is not a
/// property of the camera and is not read.
fn camera_object(path: &Path, value: serde_json::Value) -> Result<serde_json::Value> {
    use serde_json::Value;
    let Value::Object(mut top) = value else {
        return Ok(value);
    };
    check_sensor_key_spelling(path, &top)?;
    if top.contains_key("intrinsic_matrix") {
        return Ok(Value::Object(top));
    }
    let Some(Value::Object(mut inner)) = top.remove("intrinsic") else {
        return Ok(Value::Object(top));
    };
    check_sensor_key_spelling(path, &inner)?;
    for key in SENSOR_KEYS {
        if let Some(v) = top.remove(key) {
            inner.entry(key).or_insert(v);
        }
    }
    Ok(Value::Object(inner))
}

/// Refuses intrinsics whose principal point lies outside their own image (the pixels' extent,
/// `[-0.5, width - 0.5]` × `[-0.5, height - 0.5]` with pixel centres at whole coordinates): a
/// depth camera's lies near the image centre, and one outside is the calibration of another
/// image size (a 1280×720 `K`, c = (640, 360), read as the assumed 640×480), which every
/// command would otherwise use without a word.
fn check_principal_point(path: &Path, k: &Intrinsics) -> Result<()> {
    let within = |c: f64, side: usize| (-0.5..=side as f64 - 0.5).contains(&c);
    let inside = within(k.cx, k.width) && within(k.cy, k.height);
    if inside {
        return Ok(());
    }
    Err(IoError::malformed(
        path,
        format!(
            "principal point ({}, {}) px lies outside the {}x{} image: intrinsics of another \
             image size?",
            sl_core::Compact(k.cx),
            sl_core::Compact(k.cy),
            k.width,
            k.height
        ),
    ))
}

/// Builds intrinsics from a row-major 3×3 `K`, checking the zero pattern and that the
/// principal point lies in the image.
pub(crate) fn intrinsics_from_k(
    path: &Path,
    width: usize,
    height: usize,
    k: [[f64; 3]; 3],
) -> Result<Intrinsics> {
    let fixed = [
        ("K[0][1] (skew)", k[0][1], 0.0),
        ("K[1][0]", k[1][0], 0.0),
        ("K[2][0]", k[2][0], 0.0),
        ("K[2][1]", k[2][1], 0.0),
        ("K[2][2]", k[2][2], 1.0),
    ];
    for (name, v, want) in fixed {
        if !v.is_finite() || (v - want).abs() > MATRIX_TOLERANCE {
            return Err(IoError::malformed(
                path,
                format!(
                    "intrinsic matrix entry {name} is {}, expected {want} (no skew, K[2] = [0, 0, 1])",
                    sl_core::Compact(v)
                ),
            ));
        }
    }
    let intrinsics = Intrinsics::new(width, height, k[0][0], k[1][1], k[0][2], k[1][2])
        .map_err(|e| IoError::core(path, None, e))?;
    check_principal_point(path, &intrinsics)?;
    Ok(intrinsics)
}

/// Reads an Open3D `PinholeCameraIntrinsic` JSON file into a [`Camera`]; the sensor model comes
/// from the optional `baseline_m`, `subpixel`, `sigma_d_px` and `sensor_focal_px` keys, with
/// Kinect defaults.
pub fn read_camera_json(path: impl AsRef<Path>) -> Result<Camera> {
    read_camera_json_with_limits(path, &Limits::default())
}

/// [`read_camera_json`] with explicit [`Limits`]: a camera whose image would exceed
/// [`Limits::max_pixels`] is refused here, before any command allocates a frame of its size.
pub fn read_camera_json_with_limits(path: impl AsRef<Path>, limits: &Limits) -> Result<Camera> {
    let path = path.as_ref();
    let json = parse_camera_json(path, limits)?;
    let m = json.intrinsic_matrix;
    // Column-major: m[col * 3 + row].
    let k = [[m[0], m[3], m[6]], [m[1], m[4], m[7]], [m[2], m[5], m[8]]];
    limits
        .check_pixels(json.width as u64, json.height as u64)
        .map_err(|m| IoError::too_large(path, m))?;
    let intrinsics = intrinsics_from_k(path, json.width, json.height, k)?;
    let sensor = SensorModel::new(
        json.sensor_focal_px.unwrap_or(intrinsics.fx),
        json.baseline_m.unwrap_or(KINECT_BASELINE_M),
        json.subpixel.unwrap_or(KINECT_SUBPIXEL_STEPS),
        json.sigma_d_px.unwrap_or(DEFAULT_SIGMA_D_PX),
    )
    .map_err(|e| IoError::core(path, None, e))?;
    Ok(Camera { intrinsics, sensor })
}

/// Whether a camera JSON states its sensor — both `baseline_m` and `subpixel`, as
/// [`write_camera_json`] writes them — rather than giving the intrinsics alone, with the
/// Kinect's baseline and 1/8-px steps assumed by [`read_camera_json`]. A tool that judges a
/// frame's depth steps against the sensor (the depth-scale check of `sldepth`) may trust only
/// a stated one: a RealSense's 1/32-px steps against an assumed Kinect look 2.7–5 times too
/// deep. Errors as [`read_camera_json_with_limits`].
pub fn camera_json_states_sensor(path: impl AsRef<Path>, limits: &Limits) -> Result<bool> {
    let json = parse_camera_json(path.as_ref(), limits)?;
    Ok(json.baseline_m.is_some() && json.subpixel.is_some())
}

/// The keys of a camera JSON file (its `intrinsic` object for Open3D's
/// `PinholeCameraParameters`), read within `limits`.
fn parse_camera_json(path: &Path, limits: &Limits) -> Result<CameraJson> {
    let text = read_text(
        path,
        MAX_CAMERA_BYTES.min(limits.max_text_bytes),
        limits.max_text_lines,
    )?;
    let json_error = |source| IoError::Json {
        path: path.to_path_buf(),
        source,
    };
    let value = camera_object(path, serde_json::from_str(&text).map_err(json_error)?)?;
    serde_json::from_value(value).map_err(json_error)
}

/// The JSON text [`write_camera_json`] writes.
pub fn camera_to_json(camera: &Camera) -> String {
    let k = &camera.intrinsics;
    let s = &camera.sensor;
    let json = CameraJson {
        width: k.width,
        height: k.height,
        intrinsic_matrix: [k.fx, 0.0, 0.0, 0.0, k.fy, 0.0, k.cx, k.cy, 1.0],
        baseline_m: Some(s.baseline_m),
        subpixel: Some(s.subpixel_steps),
        sigma_d_px: Some(s.sigma_d_px),
        sensor_focal_px: (s.focal_px != k.fx).then_some(s.focal_px),
    };
    // Serialising plain numbers into a String cannot fail; fall back to an empty object.
    serde_json::to_string_pretty(&json).unwrap_or_else(|_| "{}".into())
}

/// Writes a camera as Open3D JSON plus the sensor keys, atomically; [`read_camera_json`] reads
/// it back exactly.
pub fn write_camera_json(path: impl AsRef<Path>, camera: &Camera) -> Result<()> {
    let path = path.as_ref();
    camera
        .intrinsics
        .validate()
        .and_then(|_| camera.sensor.validate())
        .map_err(|e| IoError::core(path, None, e))?;
    // What the reader would refuse is not written.
    check_principal_point(path, &camera.intrinsics)?;
    let text = camera_to_json(camera);
    write_atomic(path, |w| {
        w.write_all(text.as_bytes())?;
        w.write_all(b"\n")
    })
}

/// Reads a plain-text 3×3 intrinsic matrix (row-major, whitespace-separated, e.g. 7-Scenes'
/// `camera-intrinsics.txt`), or a 4×4 one whose top-left 3×3 is it (ScanNet's
/// `intrinsic_depth.txt`), for an image of `width`×`height` pixels.
pub fn read_intrinsics_txt(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
) -> Result<Intrinsics> {
    let path = path.as_ref();
    let values = read_camera_numbers(
        path,
        width,
        height,
        16,
        "more than 16 numbers in a 3x3 (or 4x4) intrinsic matrix",
    )?;
    let n = match values.len() {
        9 => 3,
        16 => 4,
        other => {
            return Err(IoError::malformed(
                path,
                format!("found {other} numbers, a 3x3 intrinsic matrix needs 9 (a 4x4 one 16)"),
            ));
        }
    };
    let at = |r: usize, c: usize| values[r * n + c];
    let k = [
        [at(0, 0), at(0, 1), at(0, 2)],
        [at(1, 0), at(1, 1), at(1, 2)],
        [at(2, 0), at(2, 1), at(2, 2)],
    ];
    intrinsics_from_k(path, width, height, k)
}

/// The numbers of a small camera text file for frames of `width`×`height` pixels (checked
/// against the default limits first), whitespace-separated on any number of lines, `#` lines
/// being comments; more than `max` is an error saying `too_many`, naming the line.
fn read_camera_numbers(
    path: &Path,
    width: usize,
    height: usize,
    max: usize,
    too_many: &str,
) -> Result<Vec<f64>> {
    let limits = Limits::default();
    limits
        .check_pixels(width as u64, height as u64)
        .map_err(|m| IoError::too_large(path, m))?;
    let text = read_text(
        path,
        MAX_CAMERA_BYTES.min(limits.max_text_bytes),
        limits.max_text_lines,
    )?;
    let mut values = Vec::with_capacity(max);
    for (i, line) in crate::text::text_lines(&text).enumerate() {
        if line.trim_start().starts_with('#') {
            continue;
        }
        for tok in line.split_whitespace() {
            let v: f64 = tok
                .parse()
                .map_err(|_| IoError::parse(path, i + 1, format!("{tok:?} is not a number")))?;
            if values.len() == max {
                return Err(IoError::parse(path, i + 1, too_many));
            }
            values.push(v);
        }
    }
    Ok(values)
}

/// Reads a pinhole camera written as the four numbers `fx fy cx cy` (pixels; on one line or
/// several, `#` lines are comments), as the ETH3D SLAM benchmark's `calibration.txt` holds the
/// intrinsics of its undistorted images, for frames of `width`×`height` pixels.
pub fn read_fx_fy_cx_cy_txt(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
) -> Result<Intrinsics> {
    let path = path.as_ref();
    let v = read_camera_numbers(
        path,
        width,
        height,
        4,
        "more than the four numbers fx fy cx cy",
    )?;
    let [fx, fy, cx, cy] = <[f64; 4]>::try_from(v.as_slice()).map_err(|_| {
        IoError::malformed(
            path,
            format!("found {} numbers, expected the four fx fy cx cy", v.len()),
        )
    })?;
    intrinsics_from_k(
        path,
        width,
        height,
        [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
    )
}

/// Reads 7-Scenes' `camera-intrinsics.txt`, assuming the Kinect's 640×480 frames
/// ([`DEFAULT_WIDTH`]×[`DEFAULT_HEIGHT`]).
pub fn read_7scenes_intrinsics(path: impl AsRef<Path>) -> Result<Intrinsics> {
    read_intrinsics_txt(path, DEFAULT_WIDTH, DEFAULT_HEIGHT)
}

/// Reads a camera file of either kind: `.json` (Open3D + sensor keys) or a 3×3 matrix text file
/// (640×480 assumed, Kinect sensor defaults).
pub fn read_camera(path: impl AsRef<Path>) -> Result<Camera> {
    let path = path.as_ref();
    let is_json = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        read_camera_json(path)
    } else {
        let k = read_7scenes_intrinsics(path)?;
        Camera::from_intrinsics(k, None, None).map_err(|e| IoError::core(path, None, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_round_trip_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cam.json");
        let mut cam = Camera::paper_kinect();
        cam.intrinsics.cx = 318.6;
        cam.intrinsics.fy = 516.5;
        cam.sensor.baseline_m = 0.0751;
        cam.sensor.sigma_d_px = 0.05;
        write_camera_json(&p, &cam).unwrap();
        assert_eq!(read_camera_json(&p).unwrap(), cam);
        cam.sensor.focal_px = 590.0;
        write_camera_json(&p, &cam).unwrap();
        assert_eq!(read_camera_json(&p).unwrap(), cam);
    }

    /// A file `write_camera_json` wrote states its sensor; Open3D's intrinsics alone, or one of
    /// the two keys, do not.
    #[test]
    fn a_json_states_its_sensor_with_both_keys() {
        let dir = tempfile::tempdir().unwrap();
        let lim = Limits::default();
        let p = dir.path().join("cam.json");
        write_camera_json(&p, &Camera::kinect_v1()).unwrap();
        assert!(camera_json_states_sensor(&p, &lim).unwrap());
        let k = r#""width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1]"#;
        for (extra, stated) in [
            ("", false),
            (r#", "baseline_m": 0.05"#, false),
            (r#", "subpixel": 32"#, false),
            (r#", "baseline_m": 0.05, "subpixel": 32"#, true),
        ] {
            std::fs::write(&p, format!("{{{k}{extra}}}")).unwrap();
            assert_eq!(
                camera_json_states_sensor(&p, &lim).unwrap(),
                stated,
                "{extra}"
            );
        }
        std::fs::write(&p, "{").unwrap();
        assert!(camera_json_states_sensor(&p, &lim).is_err());
    }

    #[test]
    fn open3d_file_without_sensor_keys() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cam.json");
        std::fs::write(
            &p,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525.0, 0, 0, 0, 525.0, 0, 319.5, 239.5, 1]}"#,
        )
        .unwrap();
        let cam = read_camera_json(&p).unwrap();
        assert_eq!(
            cam.intrinsics,
            Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap()
        );
        assert_eq!(cam.sensor.focal_px, 525.0);
        assert_eq!(cam.sensor.baseline_m, KINECT_BASELINE_M);
        assert_eq!(cam.sensor.subpixel_steps, 8);
    }

    /// Open3D's `PinholeCameraParameters` (the intrinsic object nested beside an extrinsic
    /// pose) reads as its intrinsic object; sensor keys may sit at either level. It was refused
    /// as "missing field `width`".
    #[test]
    fn open3d_pinhole_camera_parameters_read_their_intrinsics() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("params.json");
        std::fs::write(
            &p,
            r#"{"class_name": "PinholeCameraParameters",
                "extrinsic": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.5, 0, 0, 1],
                "intrinsic": {"width": 640, "height": 480,
                              "intrinsic_matrix": [525.0, 0, 0, 0, 526.0, 0, 319.5, 239.5, 1]},
                "baseline_m": 0.05, "version_major": 1, "version_minor": 0}"#,
        )
        .unwrap();
        let cam = read_camera_json(&p).unwrap();
        assert_eq!(
            cam.intrinsics,
            Intrinsics::new(640, 480, 525.0, 526.0, 319.5, 239.5).unwrap()
        );
        assert_eq!(cam.sensor.baseline_m, 0.05);
        // A misspelt sensor key at the top level is still refused.
        std::fs::write(
            &p,
            r#"{"intrinsic": {"width": 640, "height": 480,
                "intrinsic_matrix": [525.0, 0, 0, 0, 525.0, 0, 319.5, 239.5, 1]},
                "baseline": 0.05}"#,
        )
        .unwrap();
        let e = read_camera_json(&p).unwrap_err().to_string();
        assert!(e.contains("unknown key \"baseline\""), "{e}");
        // An `intrinsic` that is not an object is no camera.
        std::fs::write(&p, r#"{"intrinsic": [1, 2, 3]}"#).unwrap();
        let e = read_camera_json(&p).unwrap_err().to_string();
        assert!(e.contains("params.json") && e.contains("width"), "{e}");
    }

    #[test]
    fn bad_json_names_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.json");
        for text in [
            "{",
            r#"{"width": 640}"#,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5]}"#,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 3, 525, 0, 319.5, 239.5, 1]}"#,
            r#"{"width": 0, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1]}"#,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1], "baseline_m": -1}"#,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1], "subpixel": 0}"#,
        ] {
            std::fs::write(&p, text).unwrap();
            let err = read_camera_json(&p).unwrap_err();
            assert!(err.to_string().contains("bad.json"), "{err}");
        }
    }

    /// A sensor key in another spelling is refused (it was ignored, and the Kinect's 75 mm
    /// baseline used without a word); other tools' metadata keys are still ignored.
    #[test]
    fn misspelt_sensor_keys_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cam.json");
        let k = r#""width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1]"#;
        for key in [
            "baseline",
            "baseline_mm",
            "Sigma_D",
            "sub_pixel",
            "sensor_focal",
        ] {
            std::fs::write(&p, format!(r#"{{{k}, "{key}": 0.2}}"#)).unwrap();
            let err = read_camera_json(&p).unwrap_err().to_string();
            assert!(err.contains("cam.json"), "{err}");
            assert!(err.contains(&format!("unknown key \"{key}\"")), "{err}");
            assert!(err.contains("`baseline_m` (metres)"), "{err}");
        }
        // Azure Kinect recordings' Open3D intrinsics carry such metadata.
        std::fs::write(
            &p,
            format!(r#"{{{k}, "color_mode": "MJPG_720P", "serial_number_": "x", "stream_length_usec": 1}}"#),
        )
        .unwrap();
        assert_eq!(
            read_camera_json(&p).unwrap().sensor.baseline_m,
            KINECT_BASELINE_M
        );
        // Not a camera object at all: the message says what one is, not an internal type name.
        std::fs::write(&p, "null").unwrap();
        let err = read_camera_json(&p).unwrap_err().to_string();
        assert!(
            err.contains("expected a camera object with `width`"),
            "{err}"
        );
        assert!(!err.contains("CameraJson"), "{err}");
    }

    /// A principal point outside the image the file describes is refused, naming it: it was
    /// used without a word (a 7-Scenes-style matrix of a 1280x720 camera read as 640x480).
    #[test]
    fn principal_point_outside_the_image_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cam.json");
        for (cx, cy) in [
            (5000.0, 239.5),
            (-300.0, 239.5),
            (319.5, 480.0),
            (319.5, -0.75),
        ] {
            std::fs::write(
                &p,
                format!(
                    r#"{{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, {cx}, {cy}, 1]}}"#
                ),
            )
            .unwrap();
            let err = read_camera_json(&p).unwrap_err().to_string();
            assert!(err.contains("cam.json"), "{err}");
            assert!(
                err.contains(&format!(
                    "principal point ({cx}, {cy}) px lies outside the 640x480 image"
                )),
                "{err}"
            );
        }
        // The image's edges are inside.
        std::fs::write(
            &p,
            r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, -0.5, 479.5, 1]}"#,
        )
        .unwrap();
        assert!(read_camera_json(&p).is_ok());
        let t = dir.path().join("camera-intrinsics.txt");
        std::fs::write(&t, "912 0 640\n0 912 360\n0 0 1\n").unwrap();
        let err = read_7scenes_intrinsics(&t).unwrap_err().to_string();
        assert!(
            err.contains("(640, 360) px lies outside the 640x480 image"),
            "{err}"
        );
        let mut cam = Camera::kinect_v1();
        cam.intrinsics.cx = 700.0;
        assert!(write_camera_json(&p, &cam).is_err());
    }

    #[test]
    fn matrix_txt() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("camera-intrinsics.txt");
        std::fs::write(&p, " 5.85e+02\t 0.0\t 3.2e+02\t\n 0 585 240\n 0 0 1\n").unwrap();
        let k = read_7scenes_intrinsics(&p).unwrap();
        assert_eq!(
            (k.width, k.height, k.fx, k.fy, k.cx, k.cy),
            (640, 480, 585.0, 585.0, 320.0, 240.0)
        );
        std::fs::write(&p, "585 0 320\n0 585 x\n0 0 1\n").unwrap();
        match read_7scenes_intrinsics(&p).unwrap_err() {
            IoError::Parse { line, .. } => assert_eq!(line, 2),
            other => panic!("unexpected {other}"),
        }
        std::fs::write(&p, "585 0 320\n0 585 240\n").unwrap();
        assert!(read_7scenes_intrinsics(&p).is_err());
        std::fs::write(&p, "585 0 320\n0 585 240\n0 0 1 1\n").unwrap();
        assert!(read_7scenes_intrinsics(&p).is_err());
    }
}
