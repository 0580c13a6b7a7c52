//! Writing then reading every format through real files.

use proptest::prelude::*;
use sl_core::{DepthImage, Image};
use sl_io::depth::{INVALID_SENTINEL, nyu_raw_to_depth};
use sl_io::ply::{PlyData, PlyFormat, read_ply, write_ply};
use sl_io::{
    DepthEncoding, DepthFormat, IoError, ReadConfig, read_depth, read_gray16, read_nyu_raw,
    read_raw_depth, read_rgb, write_depth, write_gray16_png, write_rgb_png,
};

/// A 16×12 frame: a slanted plane between `near` and `far` metres, every 5th pixel invalid.
fn plane(near: f32, far: f32) -> DepthImage {
    DepthImage::from_image(Image::from_fn(16, 12, |x, y| {
        if (x * 7 + y * 3) % 5 == 0 {
            0.0
        } else {
            near + (far - near) * (x + 16 * y) as f32 / (16.0 * 12.0)
        }
    }))
}

fn options(enc: &DepthEncoding) -> ReadConfig {
    let o = ReadConfig::default().with_format(enc.format);
    if enc.format.has_scale() {
        o.with_scale(enc.units_per_m)
    } else {
        o
    }
}

/// Largest |z_read − z_written| the encoding allows at depth `z`.
fn tolerance(enc: &DepthEncoding, z: f32) -> f32 {
    if enc.format == DepthFormat::NyuRaw {
        // Half a raw step on the far side: Z = 351.3 / (1092.5 − raw) with raw off by 0.5.
        let z = f64::from(z);
        (351.3 / (351.3 / z - 0.5) - z) as f32 * 1.001 + 1e-6
    } else {
        (0.5 / enc.units_per_m) as f32 + 1e-6
    }
}

fn all_encodings() -> Vec<(&'static str, DepthEncoding)> {
    vec![
        ("mm.png", DepthEncoding::png(1000.0)),
        ("tum.png", DepthEncoding::tum()),
        ("7scenes.png", DepthEncoding::seven_scenes()),
        ("mm.tiff", DepthEncoding::tiff(1000.0)),
        (
            "tenth-mm.tif",
            DepthEncoding::tiff(10000.0).with_invalid_value(INVALID_SENTINEL),
        ),
        ("sun.png", DepthEncoding::sun()),
        ("nyu.pgm", DepthEncoding::nyu_raw()),
    ]
}

#[test]
fn depth_files_round_trip_in_every_encoding() {
    let dir = tempfile::tempdir().unwrap();
    let depth = plane(0.6, 3.5);
    for (name, enc) in all_encodings() {
        let path = dir.path().join(name);
        write_depth(&path, &depth, &enc).unwrap();
        let loaded = read_depth(&path, &options(&enc)).unwrap();
        // The 7-Scenes sentinel is detected from the file; a 0-invalid file reports 0.
        assert_eq!(loaded.encoding, enc, "{name}");
        assert_eq!(loaded.depth.width(), 16);
        assert_eq!(loaded.depth.valid_count(), depth.valid_count(), "{name}");
        for (a, b) in loaded.depth.data().iter().zip(depth.data()) {
            assert!(
                (a - b).abs() <= tolerance(&enc, *b),
                "{name}: read {a}, wrote {b}"
            );
        }
        // Writing what was read reproduces the stored integers exactly.
        let again = dir.path().join(format!("again-{name}"));
        write_depth(&again, &loaded.depth, &loaded.encoding).unwrap();
        let r1 = read_raw_depth(&path, &options(&enc)).unwrap();
        let r2 = read_raw_depth(&again, &options(&enc)).unwrap();
        assert_eq!(r1, r2, "{name}");
    }
}

/// Stored integers are written as they are, every 16-bit value included: 65535 is no depth to
/// `write_depth` (it refuses a depth of 65535 units, which would read back as the 7-Scenes
/// sentinel) but a legitimate stored value to `write_raw_depth`, and it reads back invalid.
#[test]
fn raw_values_round_trip_as_they_are_65535_included() {
    let dir = tempfile::tempdir().unwrap();
    let values = Image::from_vec(4, 2, vec![0, 1, 1000, 8191, 65534, 65535, 40000, 7]).unwrap();
    for (name, encoding) in [
        ("raw.png", DepthEncoding::png(1000.0)),
        ("raw.tiff", DepthEncoding::tiff(5000.0)),
        ("raw-sun.png", DepthEncoding::sun()),
    ] {
        let path = dir.path().join(name);
        let raw = sl_io::RawDepth {
            values: values.clone(),
            encoding,
        };
        sl_io::write_raw_depth(&path, &raw).unwrap();
        let back = read_raw_depth(&path, &options(&encoding)).unwrap();
        assert_eq!(back.values, values, "{name}");
        // The file holds 65535, so the reader reports the 7-Scenes sentinel.
        assert_eq!(back.encoding.invalid_value, INVALID_SENTINEL, "{name}");
        let depth = read_depth(&path, &options(&encoding)).unwrap().depth;
        let valid: Vec<bool> = depth.data().iter().map(|z| *z > 0.0).collect();
        assert_eq!(
            valid,
            [false, true, true, true, true, false, true, true],
            "{name}"
        );
    }
    // The metric writer refuses the same 65535 units as a depth, naming the valid range.
    let z = DepthImage::from_image(Image::from_vec(1, 1, vec![65.535_f32]).unwrap());
    let e = write_depth(dir.path().join("m.png"), &z, &DepthEncoding::png(1000.0)).unwrap_err();
    assert!(matches!(e, IoError::DepthOutOfRange { .. }), "{e}");
    // NYU raw disparity has 11 bits: a larger value would make the file unreadable.
    let nyu = sl_io::RawDepth {
        values: Image::from_vec(2, 1, vec![700, 2048]).unwrap(),
        encoding: DepthEncoding::nyu_raw(),
    };
    let e = sl_io::write_raw_depth(dir.path().join("n.pgm"), &nyu).unwrap_err();
    assert!(
        e.to_string().contains("raw value 2048 at pixel (1, 0)"),
        "{e}"
    );
    let nyu = sl_io::RawDepth {
        values: Image::from_vec(2, 1, vec![700, 2047]).unwrap(),
        encoding: DepthEncoding::nyu_raw(),
    };
    sl_io::write_raw_depth(dir.path().join("n.pgm"), &nyu).unwrap();
    assert_eq!(
        read_raw_depth(dir.path().join("n.pgm"), &ReadConfig::default())
            .unwrap()
            .values,
        nyu.values
    );
}

#[test]
fn extension_inference_and_sentinel() {
    let dir = tempfile::tempdir().unwrap();
    let depth = plane(1.0, 2.0);
    let png = dir.path().join("d.PNG");
    write_depth(&png, &depth, &DepthEncoding::seven_scenes()).unwrap();
    let raw = read_raw_depth(&png, &ReadConfig::default()).unwrap();
    let invalid = depth.data().iter().filter(|z| **z == 0.0).count();
    assert_eq!(
        raw.values
            .data()
            .iter()
            .filter(|v| **v == INVALID_SENTINEL)
            .count(),
        invalid
    );
    assert_eq!(raw.encoding.invalid_value, INVALID_SENTINEL);
    let pgm = dir.path().join("d.pgm");
    write_depth(&pgm, &depth, &DepthEncoding::nyu_raw()).unwrap();
    assert_eq!(
        read_depth(&pgm, &ReadConfig::default())
            .unwrap()
            .encoding
            .format,
        DepthFormat::NyuRaw
    );
    // Raw NYU values agree with the metres.
    let raw = read_nyu_raw(&pgm).unwrap();
    assert_eq!(
        nyu_raw_to_depth(&raw),
        read_depth(&pgm, &ReadConfig::default()).unwrap().depth
    );
    // Unknown extension without a format, scale on nyu-raw, zero scale: typed errors naming the file.
    let odd = dir.path().join("d.depth");
    std::fs::copy(&png, &odd).unwrap();
    let e = read_depth(&odd, &ReadConfig::default()).unwrap_err();
    assert!(
        matches!(e, IoError::Format { .. }) && e.to_string().contains("d.depth"),
        "{e}"
    );
    assert!(read_depth(&odd, &ReadConfig::default().with_format(DepthFormat::Png)).is_ok());
    let e = read_depth(&pgm, &ReadConfig::default().with_scale(1000.0)).unwrap_err();
    assert!(e.to_string().contains("d.pgm"), "{e}");
    // A scale with an explicit nyu-raw format is refused before any file is named.
    let nyu = ReadConfig::default()
        .with_format(DepthFormat::NyuRaw)
        .with_scale(1000.0);
    assert!(matches!(nyu.validate(), Err(IoError::InvalidConfig { .. })));
    assert!(ReadConfig::default().validate().is_ok());
    assert!(ReadConfig::default().with_scale(5000.0).validate().is_ok());
    // 1e-300 and 1e300 units per metre would make every pixel invalid (issue 15).
    for bad in [0.0, -1.0, f64::INFINITY, f64::NAN, 1e-300, 1e300] {
        let config = ReadConfig::default().with_scale(bad);
        let e = config.validate().unwrap_err();
        assert!(matches!(e, IoError::InvalidConfig { .. }), "{e}");
        let e = read_depth(&png, &config).unwrap_err();
        assert!(matches!(e, IoError::InvalidScale { .. }), "{e}");
        let e =
            write_depth(dir.path().join("z.png"), &depth, &DepthEncoding::png(bad)).unwrap_err();
        assert!(matches!(e, IoError::InvalidScale { .. }), "{e}");
    }
}

#[test]
fn big_pgm_is_big_endian_tolerant() {
    // A spec-conforming (big-endian) raw disparity PGM is recognised by its 11-bit range.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("be.pgm");
    let raw: Vec<u16> = vec![839, 977, 2047, 1000, 1092, 0];
    let mut bytes = b"P5\n3 2\n65535\n".to_vec();
    for v in &raw {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(read_nyu_raw(&path).unwrap().data(), &raw[..]);
    // Values that fit neither order are rejected.
    std::fs::write(&path, b"P5\n1 1\n65535\n\xff\xfe").unwrap();
    assert!(read_nyu_raw(&path).is_err());
    // 8-bit PGM is not raw disparity.
    std::fs::write(&path, b"P5\n1 1\n255\n\x07").unwrap();
    assert!(matches!(
        read_nyu_raw(&path).unwrap_err(),
        IoError::UnsupportedImage { .. }
    ));
}

#[test]
fn wrong_layouts_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rgb = dir.path().join("rgb.png");
    let img = Image::from_fn(5, 4, |x, y| [x as u8 * 40, y as u8 * 60, 7]);
    write_rgb_png(&rgb, &img).unwrap();
    assert_eq!(read_rgb(&rgb).unwrap(), img);
    let e = read_depth(&rgb, &ReadConfig::default()).unwrap_err();
    assert!(matches!(e, IoError::UnsupportedImage { .. }), "{e}");
    assert!(
        e.to_string().contains("rgb.png") && e.to_string().contains("8-bit RGB"),
        "{e}"
    );
    // A PNG named .tiff: the TIFF decoder rejects it with a message naming the file.
    let fake = dir.path().join("fake.tiff");
    std::fs::copy(&rgb, &fake).unwrap();
    let e = read_depth(&fake, &ReadConfig::default()).unwrap_err();
    assert!(e.to_string().contains("fake.tiff"), "{e}");
    // Empty images cannot be written.
    let e = write_depth(
        dir.path().join("e.png"),
        &DepthImage::invalid(0, 3),
        &DepthEncoding::default(),
    )
    .unwrap_err();
    assert!(matches!(e, IoError::InvalidData { .. }), "{e}");
}

#[test]
fn labels_and_colour_files() {
    let dir = tempfile::tempdir().unwrap();
    let labels = Image::from_fn(7, 3, |x, y| (x * 1000 + y) as u16);
    let p = dir.path().join("labels.png");
    write_gray16_png(&p, &labels).unwrap();
    assert_eq!(read_gray16(&p).unwrap(), labels);
    // PPM (8- and 16-bit) and PGM colour input.
    let ppm = dir.path().join("c.ppm");
    std::fs::write(&ppm, b"P6\n# c\n2 1\n255\n\x01\x02\x03\xfa\xfb\xfc").unwrap();
    assert_eq!(
        read_rgb(&ppm).unwrap().data(),
        &[[1, 2, 3], [250, 251, 252]]
    );
    std::fs::write(&ppm, b"P6 1 1 65535\n\xff\xff\x00\x00\x80\x00").unwrap();
    assert_eq!(read_rgb(&ppm).unwrap().data(), &[[255, 0, 128]]);
    std::fs::write(&ppm, b"P5 2 1 255\n\x00\x10").unwrap();
    assert_eq!(read_rgb(&ppm).unwrap().data(), &[[0, 0, 0], [16, 16, 16]]);
}

fn encoding_strategy() -> impl Strategy<Value = DepthEncoding> {
    prop_oneof![
        (100.0f64..10000.0).prop_map(DepthEncoding::png),
        (100.0f64..10000.0)
            .prop_map(|s| DepthEncoding::tiff(s).with_invalid_value(INVALID_SENTINEL)),
        Just(DepthEncoding::sun()),
        Just(DepthEncoding::nyu_raw()),
    ]
}

fn finite_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        -10.0f32..10.0,
        any::<f32>().prop_filter("finite", |v| v.is_finite())
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random clouds and meshes (any finite floats, random triangles and attributes) round-trip
    /// exactly through both PLY encodings.
    #[test]
    fn random_ply_round_trips(
        positions in prop::collection::vec([finite_f32(), finite_f32(), finite_f32()], 1..40),
        raw_faces in prop::collection::vec([any::<u32>(), any::<u32>(), any::<u32>()], 0..30),
        attrs in 0u8..8,
        seed in any::<u8>(),
    ) {
        let n = positions.len();
        let faces: Vec<[u32; 3]> = raw_faces.iter().map(|f| f.map(|i| i % n as u32)).collect();
        let mut data = PlyData::mesh(positions.clone(), faces);
        if attrs & 1 == 1 {
            data = data.with_normals(positions.iter().map(|p| [p[1], p[2], p[0]]).collect());
        }
        if attrs & 2 == 2 {
            data = data.with_colors((0..n).map(|i| [i as u8, seed, 255 - i as u8]).collect());
        }
        if attrs & 4 == 4 {
            data = data.with_scalar("confidence", positions.iter().map(|p| p[0] * 0.5).collect());
        }
        let dir = tempfile::tempdir().unwrap();
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
            let path = dir.path().join(format!("r-{format}.ply"));
            write_ply(&path, &data, format).unwrap();
            prop_assert_eq!(&read_ply(&path).unwrap(), &data);
        }
    }

    /// Any in-range depth survives a file round trip within half a unit; invalid stays invalid.
    #[test]
    fn random_depth_round_trips(enc in encoding_strategy(), seed in prop::collection::vec(0.0f32..1.0, 24)) {
        let lo = enc.min_depth_m().max(0.35) as f32;
        let hi = enc.max_depth_m().min(8.0) as f32;
        let depth = DepthImage::from_image(Image::from_fn(6, 4, |x, y| {
            let u = seed[x + 6 * y];
            if u < 0.2 { 0.0 } else { lo + (hi - lo) * (u - 0.2) / 0.8 }
        }));
        let dir = tempfile::tempdir().unwrap();
        let ext = match enc.format { DepthFormat::Tiff => "tif", DepthFormat::NyuRaw => "pgm", _ => "png" };
        let path = dir.path().join(format!("d.{ext}"));
        write_depth(&path, &depth, &enc).unwrap();
        let back = read_depth(&path, &options(&enc)).unwrap();
        for (a, b) in back.depth.data().iter().zip(depth.data()) {
            prop_assert_eq!(*a == 0.0, *b == 0.0);
            prop_assert!((a - b).abs() <= tolerance(&enc, *b), "{} vs {}", a, b);
        }
    }
}
