//! Reference checks on the real frames of `../shared/data` (see its README). Expected values
//! were read independently (OpenCV / NumPy) from the same files.

use sl_core::{DepthImage, Intrinsics};
use sl_io::depth::{NYU_DOFF, NYU_FB_PX_M, TUM_UNITS_PER_M, nyu_raw_to_disparity};
use sl_io::ply::{PlyData, PlyFormat, read_ply, write_ply};
use sl_io::trajectory::list_depth_files;
use sl_io::{
    DEFAULT_MAX_DT_S, DepthEncoding, DepthFormat, IoError, ReadConfig, read_7scenes_intrinsics,
    read_7scenes_sequence, read_camera_json, read_depth, read_nyu_raw, read_open3d_log_frames,
    read_raw_depth, read_rgb, read_tum_sequence, write_depth,
};

use crate::data_dir;

fn assert_frame(
    depth: &DepthImage,
    valid: std::ops::RangeInclusive<usize>,
    z_m: std::ops::RangeInclusive<f32>,
) {
    assert_eq!((depth.width(), depth.height()), (640, 480));
    let s = depth.stats().expect("valid pixels");
    assert!(
        valid.contains(&s.valid_pixels),
        "valid {} not in {valid:?}",
        s.valid_pixels
    );
    assert!(
        *z_m.start() <= s.min && s.max <= *z_m.end(),
        "depth {}..{} m not in {z_m:?}",
        s.min,
        s.max
    );
}

fn close(a: f32, b: f64) -> bool {
    (f64::from(a) - b).abs() < 1e-6
}

#[test]
fn tum_fr1_rpy_depth_and_trajectory() {
    let Some(data) = data_dir() else { return };
    let dir = data.join("tum-fr1-rpy");
    let seq = read_tum_sequence(&dir, DEFAULT_MAX_DT_S).unwrap();
    assert_eq!(
        seq.frames.len(),
        30,
        "every associated depth frame has a pose within 20 ms"
    );
    assert!(seq.without_pose.is_empty());
    assert!(
        seq.frames
            .windows(2)
            .all(|w| w[0].timestamp < w[1].timestamp)
    );
    // Ground-truth line nearest to the first depth frame (4.4 ms away).
    let f0 = &seq.frames[0];
    assert_eq!(f0.timestamp, Some(1305031229.528784));
    let t = f0.pose.translation();
    assert!(
        (t.x - 1.2989).abs() < 1e-9 && (t.y - 0.688).abs() < 1e-9 && (t.z - 1.5734).abs() < 1e-9
    );
    let q = f0.pose.rotation().coords;
    let n = (0.6817f64.powi(2) + 0.5533f64.powi(2) + 0.018f64.powi(2) + 0.4784f64.powi(2)).sqrt();
    let sign = q.x.signum() / 0.6817f64.signum();
    assert!((q.x - sign * 0.6817 / n).abs() < 1e-9 && (q.w - sign * -0.4784 / n).abs() < 1e-9);
    // A tolerance shorter than the pose gaps leaves frames without a pose, and reports them.
    let strict = read_tum_sequence(&dir, 0.001).unwrap();
    assert_eq!(strict.frames.len() + strict.without_pose.len(), 30);
    assert!(!strict.without_pose.is_empty());

    let opts = ReadConfig::default().with_scale(TUM_UNITS_PER_M);
    let first = read_depth(&f0.depth_path, &opts).unwrap();
    assert_eq!(first.encoding, DepthEncoding::tum());
    assert_frame(&first.depth, 217_962..=217_962, 0.7358..=2.8138);
    let s = first.depth.stats().unwrap();
    assert!(close(s.min, 0.7358) && close(s.max, 2.8138) && close(s.median, 1.2204));
    assert!(close(first.depth.get(300, 240).unwrap(), 6147.0 / 5000.0));
    for f in &seq.frames {
        let d = read_depth(&f.depth_path, &opts).unwrap().depth;
        assert_frame(&d, 150_000..=300_000, 0.5..=4.5);
    }
    // Writing in the input's encoding reproduces the stored integers.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tum.png");
    write_depth(&out, &first.depth, &first.encoding).unwrap();
    assert_eq!(
        read_raw_depth(&out, &opts).unwrap(),
        read_raw_depth(&f0.depth_path, &opts).unwrap()
    );
}

#[test]
fn open3d_testdata_frames() {
    let Some(data) = data_dir() else { return };
    let dir = data.join("open3d-testdata");
    let tum = read_depth(
        dir.join("tum-depth.png"),
        &ReadConfig::default().with_scale(5000.0),
    )
    .unwrap();
    assert_frame(&tum.depth, 248_250..=248_250, 1.464..=9.331);
    let med = tum.depth.stats().unwrap().median;
    assert!(close(med, 12075.0 / 5000.0) && (0.5..=4.0).contains(&med));
    assert!(close(tum.depth.get(320, 240).unwrap(), 10920.0 / 5000.0));

    let person = read_depth(dir.join("person-depth.png"), &ReadConfig::default()).unwrap();
    assert_eq!(person.encoding, DepthEncoding::png(1000.0));
    assert_frame(&person.depth, 256_497..=256_497, 0.649..=2.485);
    assert!(close(person.depth.get(320, 240).unwrap(), 0.766));

    let rgb = read_rgb(dir.join("tum-color.png")).unwrap();
    assert_eq!((rgb.width(), rgb.height()), (640, 480));
    assert_eq!(rgb.get(0, 0), Some(&[158, 161, 157]));
    let nyu_rgb = read_rgb(dir.join("nyu-color.ppm")).unwrap();
    assert_eq!(nyu_rgb.get(0, 0), Some(&[220, 248, 235]));
    assert_eq!(nyu_rgb.get(320, 240), Some(&[98, 102, 112]));
    // A colour image is not a depth map.
    let e = read_depth(dir.join("tum-color.png"), &ReadConfig::default()).unwrap_err();
    assert!(
        matches!(e, IoError::UnsupportedImage { .. }) && e.to_string().contains("tum-color.png"),
        "{e}"
    );
}

#[test]
fn nyu_raw_disparity() {
    let Some(data) = data_dir() else { return };
    let path = data.join("open3d-testdata/nyu-raw-disparity.pgm");
    let raw = read_nyu_raw(&path).unwrap();
    assert_eq!(raw.dimensions(), (640, 480));
    assert_eq!(raw.data().iter().filter(|v| **v == 2047).count(), 22_199);
    assert_eq!(
        (raw.data().iter().min(), raw.get(320, 240)),
        (Some(&839), Some(&977))
    );
    let loaded = read_depth(&path, &ReadConfig::default()).unwrap();
    assert_eq!(loaded.encoding.format, DepthFormat::NyuRaw);
    assert_frame(&loaded.depth, 285_001..=285_001, 0.5..=10.0);
    let s = loaded.depth.stats().unwrap();
    assert!(close(s.min, 351.3 / (1092.5 - 839.0)) && close(s.max, 351.3 / (1092.5 - 1040.0)));
    assert!(close(loaded.depth.get(320, 240).unwrap(), 351.3 / 115.5));
    let disp = nyu_raw_to_disparity(&raw, NYU_DOFF);
    assert_eq!(disp.get(320, 240), Some(115.5 / 8.0));
    assert_eq!(disp.valid_count(), 285_001);
    assert!((NYU_FB_PX_M / f64::from(disp.get(320, 240).unwrap()) - 351.3 / 115.5).abs() < 1e-9);
    // Writing in the input's encoding reproduces the raw values.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("nyu.pgm");
    write_depth(&out, &loaded.depth, &loaded.encoding).unwrap();
    assert_eq!(read_nyu_raw(&out).unwrap(), raw);
    assert_eq!(
        std::fs::metadata(&out).unwrap().len(),
        std::fs::metadata(&path).unwrap().len()
    );
}

#[test]
fn icl_livingroom_camera_and_log() {
    let Some(data) = data_dir() else { return };
    let dir = data.join("open3d-testdata/icl-livingroom");
    let cam = read_camera_json(dir.join("camera.json")).unwrap();
    assert_eq!(
        cam.intrinsics,
        Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap()
    );
    assert_eq!(
        (
            cam.sensor.focal_px,
            cam.sensor.baseline_m,
            cam.sensor.subpixel_steps
        ),
        (525.0, 0.075, 8)
    );
    // The camera file round-trips through our writer (which adds the sensor keys).
    let tmp = tempfile::tempdir().unwrap();
    sl_io::write_camera_json(tmp.path().join("camera.json"), &cam).unwrap();
    assert_eq!(
        read_camera_json(tmp.path().join("camera.json")).unwrap(),
        cam
    );
    let frames = read_open3d_log_frames(dir.join("odometry.log"), dir.join("depth")).unwrap();
    assert_eq!(frames.len(), 5);
    assert!(frames[4].depth_path.ends_with("00004.png"));
    let t0 = frames[0].pose.translation();
    assert_eq!((t0.x, t0.y, t0.z), (2.0, 2.0, -0.3));
    let t4 = frames[4].pose.translation();
    assert!((t4.x - 2.00124).abs() < 1e-9 && (t4.z + 0.305411).abs() < 1e-9);
    for f in &frames {
        let d = read_depth(&f.depth_path, &ReadConfig::default()).unwrap();
        assert_frame(&d.depth, 200_000..=300_000, 0.5..=5.0);
    }
    let d0 = read_depth(&frames[0].depth_path, &ReadConfig::default())
        .unwrap()
        .depth;
    assert_eq!(d0.valid_count(), 267_129);
    assert!(close(d0.get(320, 240).unwrap(), 2.195));
    // Back-projected cloud of a real frame, through PLY and back, both encodings.
    let points = d0.to_points(&cam.intrinsics).unwrap();
    let z: Vec<f32> = points.iter().map(|p| p.z).collect();
    let cloud = PlyData::from_points(&points).with_scalar("z_m", z);
    assert_eq!(cloud.vertex_count(), 267_129);
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
        let p = tmp.path().join(format!("cloud-{format}.ply"));
        write_ply(&p, &cloud, format).unwrap();
        assert_eq!(read_ply(&p).unwrap(), cloud, "{format}");
    }
}

#[test]
fn seven_scenes_sequence() {
    let Some(data) = data_dir() else { return };
    let dir = data.join("7scenes-redkitchen");
    let k = read_7scenes_intrinsics(dir.join("camera-intrinsics.txt")).unwrap();
    assert_eq!(
        k,
        Intrinsics::new(640, 480, 585.0, 585.0, 320.0, 240.0).unwrap()
    );
    let frames = read_7scenes_sequence(&dir).unwrap();
    assert_eq!(frames.len(), 50);
    assert!(frames[0].depth_path.ends_with("frame-000150.depth.png"));
    assert!(frames[49].depth_path.ends_with("frame-000199.depth.png"));
    let t = frames[0].pose.translation();
    assert!(
        (t.x + 0.91287065).abs() < 1e-9
            && (t.y + 0.34388667).abs() < 1e-9
            && (t.z - 0.75986093).abs() < 1e-9
    );
    let first = read_depth(&frames[0].depth_path, &ReadConfig::default()).unwrap();
    // These frames mark missing depth with 0 (none holds 65535), so the encoding reports 0.
    assert_eq!(first.encoding, DepthEncoding::png(1000.0));
    assert_frame(&first.depth, 270_326..=270_326, 0.939..=2.857);
    assert!(close(first.depth.get(320, 240).unwrap(), 1.556));
    for f in &frames {
        let d = read_depth(&f.depth_path, &ReadConfig::default()).unwrap();
        assert_frame(&d.depth, 200_000..=300_000, 0.5..=5.0);
    }
}

#[test]
fn pcl_floor_box_tiff() {
    let Some(data) = data_dir() else { return };
    let dir = data.join("pcl-floor-box");
    let files: Vec<_> = list_depth_files(&dir)
        .unwrap()
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with("_depth.tiff"))
        .collect();
    assert_eq!(files.len(), 3);
    for f in &files {
        let d = read_depth(f, &ReadConfig::default()).unwrap();
        assert_eq!(d.encoding, DepthEncoding::tiff(1000.0));
        assert_frame(&d.depth, 250_000..=290_000, 0.5..=2.5);
    }
    let first = read_depth(&files[0], &ReadConfig::default()).unwrap();
    assert_frame(&first.depth, 271_575..=271_575, 0.671..=1.713);
    assert!(close(first.depth.get(320, 240).unwrap(), 0.854));
    // The colour TIFF next to it is rejected as depth, and reads as colour.
    let rgb = dir.join("frame_20121214T142256.332395_rgb.tiff");
    let e = read_depth(&rgb, &ReadConfig::default()).unwrap_err();
    assert!(matches!(e, IoError::UnsupportedImage { .. }), "{e}");
    assert_eq!(read_rgb(&rgb).unwrap().dimensions(), (640, 480));
    // Round trip in the input's encoding.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("floor.tiff");
    write_depth(&out, &first.depth, &first.encoding).unwrap();
    let o = ReadConfig::default();
    assert_eq!(
        read_raw_depth(&out, &o).unwrap(),
        read_raw_depth(&files[0], &o).unwrap()
    );
}
