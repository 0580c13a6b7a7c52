//! Floating-point TIFF depth: read by what the file stores, written back the same way, no
//! depth where the value is not a positive finite number, and bounded like every decoder.

use std::path::Path;

use sl_core::{DepthImage, Image};
use sl_io::depth::{FLOAT_UNITS_PER_M, depth_format_of_file, write_raw_depth};
use sl_io::{
    DepthEncoding, DepthFormat, IoError, RawDepth, ReadConfig, read_depth, read_raw_depth,
    write_depth,
};
use tiff::encoder::{TiffEncoder, colortype};

/// A float grey TIFF written by the `tiff` crate itself (as ROS tools and OpenCV write them).
fn write_f32_tiff(path: &Path, w: u32, h: u32, values: &[f32]) {
    let f = std::fs::File::create(path).unwrap();
    TiffEncoder::new(f)
        .unwrap()
        .write_image::<colortype::Gray32Float>(w, h, values)
        .unwrap();
}

/// A 12×8 slanted plane from 0.7 to 3.9 m with every 7th pixel invalid.
fn plane() -> DepthImage {
    DepthImage::from_image(Image::from_fn(12, 8, |x, y| {
        if (x + 3 * y) % 7 == 0 {
            0.0
        } else {
            0.7 + 3.2 * (x + 12 * y) as f32 / 96.0
        }
    }))
}

#[test]
fn float_tiff_round_trips_exactly_and_keeps_its_encoding() {
    let dir = tempfile::tempdir().unwrap();
    let depth = plane();
    let path = dir.path().join("d.tif");
    write_depth(&path, &depth, &DepthEncoding::tiff_f32(FLOAT_UNITS_PER_M)).unwrap();
    // Read without a format, as `tiff` and as `tiff-f32`: the same metres, bit for bit.
    for options in [
        ReadConfig::default(),
        ReadConfig::default().with_format(DepthFormat::Tiff),
        ReadConfig::default().with_format(DepthFormat::TiffF32),
    ] {
        let loaded = read_depth(&path, &options).unwrap();
        assert_eq!(loaded.encoding, DepthEncoding::tiff_f32(1.0));
        assert_eq!(loaded.depth, depth);
    }
    assert_eq!(
        depth_format_of_file(&path, None).unwrap(),
        DepthFormat::TiffF32
    );
    // Written back in the encoding it was read in, the file holds the same floats.
    let loaded = read_depth(&path, &ReadConfig::default()).unwrap();
    let again = dir.path().join("again.tif");
    write_depth(&again, &loaded.depth, &loaded.encoding).unwrap();
    assert_eq!(
        read_depth(&again, &ReadConfig::default()).unwrap().depth,
        depth
    );
    // At 1000 units per metre the file holds millimetres as floats, read back at that scale.
    let mm = dir.path().join("mm.tif");
    write_depth(&mm, &depth, &DepthEncoding::tiff_f32(1000.0)).unwrap();
    let back = read_depth(&mm, &ReadConfig::default().with_scale(1000.0)).unwrap();
    for (a, b) in back.depth.data().iter().zip(depth.data()) {
        assert!((a - b).abs() <= 1e-6 * b.max(1.0), "{a} vs {b}");
    }
    // Read without the scale, the same file is metres: 1000 times too deep, as stored.
    let as_m = read_depth(&mm, &ReadConfig::default()).unwrap();
    assert!((as_m.depth.data()[1] / depth.data()[1] - 1000.0).abs() < 1e-3);
}

#[test]
fn float_values_that_are_no_depth_read_as_zero() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ros.tiff");
    let values = [
        1.5,
        f32::NAN,
        -2.0,
        f32::INFINITY,
        0.0,
        f32::NEG_INFINITY,
        2.25,
        f32::MIN_POSITIVE,
    ];
    write_f32_tiff(&path, 4, 2, &values);
    let m = read_depth(&path, &ReadConfig::default()).unwrap();
    assert_eq!(
        m.depth.data(),
        &[1.5, 0.0, 0.0, 0.0, 0.0, 0.0, 2.25, f32::MIN_POSITIVE]
    );
    assert_eq!(m.depth.valid_count(), 3);
    // A value that divides below the smallest f32 is no depth either (never a denormal zero
    // counted as valid).
    let tiny = read_depth(&path, &ReadConfig::default().with_scale(1e6)).unwrap();
    assert_eq!(tiny.depth.data()[7], 0.0);
    assert_eq!(tiny.depth.data()[0], 1.5e-6);
}

#[test]
fn float64_tiff_is_read_as_f32_metres() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d64.tif");
    let f = std::fs::File::create(&path).unwrap();
    TiffEncoder::new(f)
        .unwrap()
        .write_image::<colortype::Gray64Float>(3, 1, &[0.5f64, f64::NAN, 4.125])
        .unwrap();
    let loaded = read_depth(&path, &ReadConfig::default()).unwrap();
    assert_eq!(loaded.depth.data(), &[0.5, 0.0, 4.125]);
    assert_eq!(loaded.encoding.format, DepthFormat::TiffF32);
}

#[test]
fn integer_and_float_tiffs_are_told_apart() {
    let dir = tempfile::tempdir().unwrap();
    let depth = plane();
    let f32_path = dir.path().join("f.tif");
    let u16_path = dir.path().join("u.tif");
    write_depth(&f32_path, &depth, &DepthEncoding::tiff_f32(1.0)).unwrap();
    write_depth(&u16_path, &depth, &DepthEncoding::tiff(1000.0)).unwrap();
    // A 16-bit TIFF is still read as one.
    let u = read_depth(&u16_path, &ReadConfig::default()).unwrap();
    assert_eq!(u.encoding, DepthEncoding::tiff(1000.0));
    assert_eq!(
        depth_format_of_file(&u16_path, None).unwrap(),
        DepthFormat::Tiff
    );
    // ... but not when float depth is asked for.
    let e = read_depth(
        &u16_path,
        &ReadConfig::default().with_format(DepthFormat::TiffF32),
    )
    .unwrap_err();
    assert!(matches!(e, IoError::UnsupportedImage { .. }), "{e}");
    assert!(e.to_string().contains("tiff-f32"), "{e}");
    // Float depth has no raw integers, read or written.
    let e = read_raw_depth(&f32_path, &ReadConfig::default()).unwrap_err();
    assert!(matches!(e, IoError::UnsupportedImage { .. }), "{e}");
    assert!(e.to_string().contains("f.tif"), "{e}");
    let raw = RawDepth {
        values: Image::filled(2, 2, 1000u16),
        encoding: DepthEncoding::tiff_f32(1.0),
    };
    let e = write_raw_depth(dir.path().join("raw.tif"), &raw).unwrap_err();
    assert!(matches!(e, IoError::Format { .. }), "{e}");
    // A float depth encoding other than 0 for no depth is refused.
    let e = write_depth(
        dir.path().join("s.tif"),
        &depth,
        &DepthEncoding::tiff_f32(1.0).with_invalid_value(u16::MAX),
    )
    .unwrap_err();
    assert!(matches!(e, IoError::Format { .. }), "{e}");
    // The format's names.
    assert_eq!("tiff-f32".parse::<DepthFormat>(), Ok(DepthFormat::TiffF32));
    assert_eq!(
        "TIFF_FLOAT".parse::<DepthFormat>(),
        Ok(DepthFormat::TiffF32)
    );
    assert_eq!(DepthFormat::TiffF32.name(), "tiff-f32");
    assert!(DepthFormat::NAMES.contains(&"tiff-f32"));
}

/// A little-endian float grey TIFF header declaring `w`×`h` pixels in one strip at offset 8 of
/// `data_len` bytes, followed by `data_len` bytes of zeros (fewer than it declares, for a
/// truncated file).
fn crafted_float_tiff(w: u32, h: u32, data_len: u32, present: usize) -> Vec<u8> {
    let entries: [(u16, u16, u32); 10] = [
        (256, 4, w),        // ImageWidth, LONG
        (257, 4, h),        // ImageLength
        (258, 3, 32),       // BitsPerSample, SHORT
        (259, 3, 1),        // Compression: none
        (262, 3, 1),        // Photometric: black is zero
        (273, 4, 0),        // StripOffsets (patched below)
        (277, 3, 1),        // SamplesPerPixel
        (278, 4, h),        // RowsPerStrip
        (279, 4, data_len), // StripByteCounts
        (339, 3, 3),        // SampleFormat: IEEE float
    ];
    let ifd_len = 2 + entries.len() * 12 + 4;
    let data_offset = (8 + ifd_len) as u32;
    let mut b = Vec::new();
    b.extend_from_slice(b"II*\0");
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        let value = if tag == 273 { data_offset } else { value };
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        if kind == 3 {
            b.extend_from_slice(&(value as u16).to_le_bytes());
            b.extend_from_slice(&[0, 0]);
        } else {
            b.extend_from_slice(&value.to_le_bytes());
        }
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.resize(b.len() + present, 0);
    b
}

#[test]
fn float_tiff_headers_are_not_trusted() {
    let dir = tempfile::tempdir().unwrap();
    // The crafted header itself is right: a complete 3×2 file reads as 6 pixels of no depth.
    let ok = dir.path().join("ok.tif");
    std::fs::write(&ok, crafted_float_tiff(3, 2, 24, 24)).unwrap();
    let loaded = read_depth(&ok, &ReadConfig::default()).unwrap();
    assert_eq!((loaded.depth.width(), loaded.depth.height()), (3, 2));
    assert_eq!(loaded.encoding.format, DepthFormat::TiffF32);
    // 60000 × 60000 pixels declared in a 140-byte file: refused from the header.
    let bomb = dir.path().join("bomb.tif");
    std::fs::write(&bomb, crafted_float_tiff(60_000, 60_000, u32::MAX, 16)).unwrap();
    let e = read_depth(&bomb, &ReadConfig::default()).unwrap_err();
    assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
    // A file that ends inside its pixels: an error naming the file, not a panic.
    let short = dir.path().join("short.tif");
    std::fs::write(&short, crafted_float_tiff(64, 64, 64 * 64 * 4, 100)).unwrap();
    let e = read_depth(&short, &ReadConfig::default()).unwrap_err();
    assert!(e.to_string().contains("short.tif"), "{e}");
}
