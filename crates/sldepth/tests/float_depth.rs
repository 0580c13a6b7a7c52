//! Floating-point TIFF depth (ROS `32FC1`, OpenCV's `imwrite` of a float array) through the
//! command line: read in metres by every command, written back as float by a `.tif` output,
//! and never given a camera preset's integer scale.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use sl_io::{DepthEncoding, DepthFormat, ReadConfig};

mod common;
use common::{s, sldepth};

/// A 640×480 frame of two walls meeting in a corner 2–3 m away, in metres, every 11th pixel
/// invalid.
fn corner() -> sl_core::DepthImage {
    sl_core::DepthImage::from_image(sl_core::Image::from_fn(640, 480, |x, y| {
        if (x + 5 * y) % 11 == 0 {
            0.0
        } else {
            let dx = (x as f32 - 320.0).abs();
            2.0 + dx / 320.0 + 0.2 * y as f32 / 480.0
        }
    }))
}

fn json_of(out: &std::process::Output) -> serde_json::Value {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    serde_json::from_slice(&out.stdout).unwrap()
}

fn info(path: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["info", s(path), "--json"];
    args.extend_from_slice(extra);
    json_of(&sldepth(&args))
}

#[test]
fn a_float_tiff_is_read_in_metres_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let depth = corner();
    let f32_tif = dir.path().join("ros.tif");
    let mm_png = dir.path().join("mm.png");
    sl_io::write_depth(&f32_tif, &depth, &DepthEncoding::tiff_f32(1.0)).unwrap();
    sl_io::write_depth(&mm_png, &depth, &DepthEncoding::png(1000.0)).unwrap();

    let a = info(&f32_tif, &[]);
    assert!(
        a["encoding"].as_str().unwrap().starts_with("tiff-f32"),
        "{a}"
    );
    let median = a["z_median_m"].as_f64().unwrap();
    assert!((2.4..2.7).contains(&median), "{a}");
    assert_eq!(a["valid_pixels"], info(&mm_png, &[])["valid_pixels"]);
    // A preset whose files are stored at 5000 units per metre (TUM) gives no scale to float
    // depth; --depth-scale does.
    let tum = info(&f32_tif, &["--camera", "tum-fr1"]);
    assert_eq!(tum["z_median_m"], a["z_median_m"], "{tum}");
    let scaled = info(&f32_tif, &["--depth-scale", "1000"]);
    assert!(
        (scaled["z_median_m"].as_f64().unwrap() * 1000.0 - median).abs() < 1e-3,
        "{scaled}"
    );

    // The same planes as the millimetre PNG of the same depths.
    let planes = |p: &Path, name: &str| {
        let labels = dir.path().join(name);
        let out = sldepth(&["planes", s(p), "-o", s(&labels), "--json"]);
        json_of(&out)["planes"].as_array().unwrap().len()
    };
    let n = planes(&f32_tif, "lf.png");
    assert_eq!(n, 2, "two walls");
    assert_eq!(n, planes(&mm_png, "lp.png"));
}

#[test]
fn a_float_tiff_is_filtered_into_a_float_tiff() {
    let dir = tempfile::tempdir().unwrap();
    let depth = corner();
    let input = dir.path().join("in.tif");
    sl_io::write_depth(&input, &depth, &DepthEncoding::tiff_f32(1.0)).unwrap();
    let out_tif = dir.path().join("out.tif");
    let out_png = dir.path().join("out.png");
    for out in [&out_tif, &out_png] {
        let o = sldepth(&["filter", s(&input), s(out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let tif = sl_io::read_depth(&out_tif, &ReadConfig::default()).unwrap();
    assert_eq!(tif.encoding, DepthEncoding::tiff_f32(1.0));
    let png = sl_io::read_depth(&out_png, &ReadConfig::default()).unwrap();
    assert_eq!(png.encoding, DepthEncoding::png(1000.0));
    // The float output keeps what millimetres round away; both are the same filtered depth.
    let mut sub_mm = 0;
    for (f, p) in tif.depth.data().iter().zip(png.depth.data()) {
        assert!((f - p).abs() <= 0.0005 + 1e-6, "{f} vs {p}");
        sub_mm += usize::from((f * 1000.0).fract().abs() > 1e-3);
    }
    assert!(sub_mm > 1000, "float output rounded to millimetres");
    assert_eq!(
        sl_io::depth::depth_format_of_file(&out_tif, None).unwrap(),
        DepthFormat::TiffF32
    );
}
