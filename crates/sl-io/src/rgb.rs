//! 8-bit colour and 16-bit label images: reading colour frames for overlays, writing plots,
//! overlays, normal renderings and label maps.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use image::ExtendedColorType;
use sl_core::Image;

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::pnm::{PnmKind, read_pnm};
use crate::raster::{decode_rgb8, write_png_l16, write_png_u8};

/// Reads a colour image as 8-bit RGB: PNG and TIFF (any bit depth or channel layout; grey is
/// replicated, alpha dropped, 16-bit scaled to 8), and binary PPM/PGM (`P6`/`P5`, maxval up to
/// 65535, scaled to 0..=255). The format is recognised from the file's content.
pub fn read_rgb(path: impl AsRef<Path>) -> Result<Image<[u8; 3]>> {
    read_rgb_with_limits(path, &Limits::default())
}

/// [`read_rgb`] within `limits` (the size is checked from the header before decoding).
pub fn read_rgb_with_limits(path: impl AsRef<Path>, limits: &Limits) -> Result<Image<[u8; 3]>> {
    let path = path.as_ref();
    let mut magic = [0u8; 2];
    let n = File::open(path)
        .and_then(|mut f| f.read(&mut magic))
        .map_err(|e| IoError::io(path, e))?;
    if n == 2 && (magic == *b"P5" || magic == *b"P6") {
        read_pnm_rgb(path, limits)
    } else {
        decode_rgb8(path, limits)
    }
}

fn read_pnm_rgb(path: &Path, limits: &Limits) -> Result<Image<[u8; 3]>> {
    let (header, bytes) = read_pnm(path, limits)?;
    let maxval = header.maxval;
    let scale = |v: u32| -> u8 {
        // Round to nearest; values above maxval (malformed but harmless) saturate.
        (((v.min(maxval) * 255) + maxval / 2) / maxval) as u8
    };
    let samples: Vec<u8> = if header.bytes_per_sample() == 1 {
        bytes.iter().map(|&b| scale(u32::from(b))).collect()
    } else {
        // PNM stores 16-bit samples big-endian.
        bytes
            .chunks_exact(2)
            .map(|b| scale(u32::from(u16::from_be_bytes([b[0], b[1]]))))
            .collect()
    };
    let pixels: Vec<[u8; 3]> = match header.kind {
        PnmKind::Rgb => samples
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
        PnmKind::Gray => samples.iter().map(|&g| [g, g, g]).collect(),
    };
    Image::from_vec(header.width, header.height, pixels).map_err(|e| IoError::core(path, None, e))
}

/// Writes an 8-bit RGB PNG atomically (plots, overlays, normal renderings).
pub fn write_rgb_png(path: impl AsRef<Path>, image: &Image<[u8; 3]>) -> Result<()> {
    let bytes: Vec<u8> = image.data().iter().flatten().copied().collect();
    write_png_u8(
        path.as_ref(),
        image.width(),
        image.height(),
        &bytes,
        ExtendedColorType::Rgb8,
    )
}

/// Writes an 8-bit grey PNG atomically (masks, confidence maps).
pub fn write_gray8_png(path: impl AsRef<Path>, image: &Image<u8>) -> Result<()> {
    write_png_u8(
        path.as_ref(),
        image.width(),
        image.height(),
        image.data(),
        ExtendedColorType::L8,
    )
}

/// Writes a 16-bit grey PNG atomically (plane / surface label images; raw values, no scaling).
pub fn write_gray16_png(path: impl AsRef<Path>, image: &Image<u16>) -> Result<()> {
    write_png_l16(path.as_ref(), image.width(), image.height(), image.data())
}

/// Reads a 16-bit grey PNG or TIFF as raw values (label images written by
/// [`write_gray16_png`]); any other layout is [`IoError::UnsupportedImage`].
pub fn read_gray16(path: impl AsRef<Path>) -> Result<Image<u16>> {
    let path = path.as_ref();
    let container = match crate::depth::DepthFormat::from_path(path) {
        Some(crate::depth::DepthFormat::Tiff) => crate::raster::Container::Tiff,
        _ => crate::raster::Container::Png,
    };
    crate::raster::decode_l16(path, container, &Limits::default())
}
