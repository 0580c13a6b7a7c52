//! Reference tests over the real frames in `../shared/data` (skipped when absent).

use sl_core::SensorModel;
use sl_noise::analysis::{FbSource, ResolutionAnalysis, analyze};

fn report(name: &str, a: &ResolutionAnalysis) {
    eprintln!(
        "{name}: unique {} slope {:.4} robust {:.4} c {:.6}/m (median {:.6}) fB implied {:.3} used {:?} ({:?}) sub-pixel {:?} (mode {:?}, max {:?}, nominal-fB count {:?}) far from {:.3} m ({} pairs)",
        a.unique_depths,
        a.slope,
        a.slope_robust,
        a.quantum_per_m,
        a.quantum_median_per_m,
        a.fb_px_m.unwrap_or(f64::NAN),
        a.fb_used_px_m,
        a.fb_source,
        a.subpixel_steps,
        a.subpixel_steps_mode,
        a.subpixel_steps_max,
        a.subpixel_steps_nominal,
        a.far_range_min_m,
        a.far_pairs
    );
}

/// Analyse a frame with the nominal intrinsics of its data set (f from the README, B 75 mm,
/// q = 8) and check the paper's claims: slope ≈ 2, eight disparity steps per pixel.
fn check(rel: &str, units_per_m: f64, focal_px: f64) -> Option<ResolutionAnalysis> {
    let dir = sl_testkit::data_dir_or_skip("sl-noise real-frame tests")?;
    let path = dir.join(rel);
    if !path.exists() {
        eprintln!("skipping: {} not found", path.display());
        return None;
    }
    let depth = sl_testkit::read_depth(&path, Some(units_per_m)).unwrap();
    let sensor = SensorModel {
        focal_px,
        ..SensorModel::kinect_v1()
    };
    let a = analyze(&depth, &sensor).unwrap();
    report(rel, &a);
    assert!(
        (1.9..=2.1).contains(&a.slope),
        "{rel}: OLS slope {}",
        a.slope
    );
    assert!(
        (1.8..=2.2).contains(&a.slope_robust),
        "{rel}: robust slope {}",
        a.slope_robust
    );
    assert_eq!(a.fb_source, FbSource::Implied);
    assert_eq!(a.subpixel_steps, Some(8), "{rel}");
    Some(a)
}

#[test]
fn tum_frame_slope_near_two() {
    check("open3d-testdata/tum-depth.png", 5000.0, 525.0);
}

#[test]
fn person_frame_slope_near_two() {
    check("open3d-testdata/person-depth.png", 1000.0, 525.0);
}

#[test]
fn floor_scans_slope_near_two() {
    let Some(dir) = sl_testkit::data_dir_or_skip("sl-noise real-frame tests") else {
        return;
    };
    let mut frames: Vec<_> = std::fs::read_dir(dir.join("pcl-floor-box"))
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    frames.retain(|p| p.to_string_lossy().ends_with("_depth.tiff"));
    frames.sort();
    if frames.is_empty() {
        eprintln!("skipping: no pcl-floor-box/*_depth.tiff");
    }
    for p in frames {
        let rel = format!("pcl-floor-box/{}", p.file_name().unwrap().to_string_lossy());
        check(&rel, 1000.0, 525.0);
    }
}

#[test]
fn tum_sequence_and_7scenes_first_frames() {
    let Some(dir) = sl_testkit::data_dir_or_skip("sl-noise real-frame tests") else {
        return;
    };
    for (sub, suffix, units, f) in [
        ("tum-fr1-rpy/depth", ".png", 5000.0, 517.3),
        ("7scenes-redkitchen", ".depth.png", 1000.0, 585.0),
    ] {
        let mut frames: Vec<_> = std::fs::read_dir(dir.join(sub))
            .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        frames.retain(|p| p.to_string_lossy().ends_with(suffix));
        frames.sort();
        for p in frames.iter().take(3) {
            let rel = p.strip_prefix(&dir).unwrap().to_string_lossy().to_string();
            check(&rel, units, f);
        }
    }
}

/// The NYU raw Kinect disparity frame: a P5 PGM whose 16-bit values are little-endian (against
/// the PGM spec), 2047 = invalid, metres = 351.3 / (1092.5 − raw). Its depths are continuous
/// (no 1 mm rounding by the device), so the analysis rounds them to 1 mm like a Kinect driver.
#[test]
fn nyu_raw_disparity_frame() {
    let Some(dir) = sl_testkit::data_dir_or_skip("sl-noise real-frame tests") else {
        return;
    };
    let path = dir.join("open3d-testdata/nyu-raw-disparity.pgm");
    let Ok(bytes) = std::fs::read(&path) else {
        eprintln!("skipping: {} not found", path.display());
        return;
    };
    // Header: "P5", width, height, maxval, separated by whitespace, then one whitespace byte.
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 && i < bytes.len() {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).to_string());
    }
    assert_eq!(fields[0], "P5");
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    let body = &bytes[i + 1..];
    assert!(body.len() >= 2 * w * h);
    let data: Vec<f32> = body[..2 * w * h]
        .chunks_exact(2)
        .map(|c| {
            let raw = f64::from(u16::from_le_bytes([c[0], c[1]]));
            if raw >= 2047.0 || raw >= 1092.5 {
                0.0
            } else {
                (351.3 / (1092.5 - raw)) as f32
            }
        })
        .collect();
    let depth = sl_core::DepthImage::from_vec(w, h, data).unwrap();
    let a = analyze(
        &depth,
        &SensorModel {
            focal_px: 582.6,
            ..SensorModel::kinect_v1()
        },
    )
    .unwrap();
    report("nyu-raw-disparity.pgm", &a);
    assert!((1.9..=2.1).contains(&a.slope), "OLS slope {}", a.slope);
    // q·f·B of the NYU conversion is 351.3 px·m.
    assert!(
        (a.fb_px_m.unwrap() * 8.0 / 351.3 - 1.0).abs() < 0.01,
        "{:?}",
        a.fb_px_m
    );
    assert_eq!(a.subpixel_steps, Some(8));
}
