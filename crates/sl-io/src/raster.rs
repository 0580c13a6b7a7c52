//! Bounded decoding and atomic encoding of PNG / TIFF rasters through the `image` crate.

use std::fs::File;
use std::io::{BufReader, Cursor, Write};
use std::path::Path;

use image::codecs::png::{CompressionType, FilterType, PngDecoder, PngEncoder};
use image::codecs::tiff::{TiffDecoder, TiffEncoder};
use image::{ColorType, DynamicImage, ExtendedColorType, ImageDecoder, ImageEncoder, ImageError};
use sl_core::Image;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::{BUDGET_OPTION, Limits, MAX_SIDE};

/// Raster containers we decode ourselves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Container {
    Png,
    Tiff,
}

/// Converts an `image` error into an [`IoError`] naming `path`.
pub(crate) fn image_error(path: &Path, e: ImageError) -> IoError {
    match e {
        ImageError::Limits(l) => IoError::too_large(
            path,
            format!(
                "{l} (decode limits: at most {MAX_SIDE} px per side, a fixed bound; the pixels \
                 and bytes a decoder may allocate grow with {BUDGET_OPTION})"
            ),
        ),
        ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            IoError::Decode {
                path: path.to_path_buf(),
                message: format!("the file ends before its image data does (truncated?): {io}"),
            }
        }
        ImageError::IoError(io) => IoError::io(path, io),
        other => {
            let message = other.to_string();
            // The decoders report a short file in their own words.
            let truncated = ["unexpected end of file", "failed to fill whole buffer"]
                .iter()
                .any(|m| message.to_ascii_lowercase().contains(m));
            IoError::Decode {
                path: path.to_path_buf(),
                message: if truncated {
                    format!("the file ends before its image data does (truncated?): {message}")
                } else {
                    message
                },
            }
        }
    }
}

/// Human description of a colour type, for error messages.
pub(crate) fn describe(ct: ColorType) -> String {
    let bits = ct.bits_per_pixel() / u16::from(ct.channel_count().max(1));
    let layout = match ct {
        ColorType::L8 | ColorType::L16 => "single-channel (grey)",
        ColorType::La8 | ColorType::La16 => "grey+alpha (2 channels)",
        ColorType::Rgb8 | ColorType::Rgb16 | ColorType::Rgb32F => "RGB (3 channels)",
        ColorType::Rgba8 | ColorType::Rgba16 | ColorType::Rgba32F => "RGBA (4 channels)",
        _ => "unknown layout",
    };
    format!("{bits}-bit {layout}")
}

fn open(path: &Path) -> Result<BufReader<File>> {
    let f = File::open(path).map_err(|e| IoError::io(path, e))?;
    Ok(BufReader::new(f))
}

/// The width and height a PNG or TIFF file's header declares, nothing decoded; for sizing a
/// camera, checked against `limits`.
pub(crate) fn image_size(path: &Path, limits: &Limits) -> Result<(usize, usize)> {
    let (w, h) = image::ImageReader::new(open(path)?)
        .with_guessed_format()
        .map_err(|e| IoError::io(path, e))?
        .into_dimensions()
        .map_err(|e| image_error(path, e))?;
    limits
        .check_pixels(u64::from(w), u64::from(h))
        .map_err(|m| IoError::too_large(path, m))?;
    Ok((w as usize, h as usize))
}

/// Decodes a 16-bit single-channel PNG or TIFF; any other layout is
/// [`IoError::UnsupportedImage`].
pub(crate) fn decode_l16(path: &Path, container: Container, limits: &Limits) -> Result<Image<u16>> {
    let reader = open(path)?;
    match container {
        Container::Png => {
            let dec = PngDecoder::with_limits(reader, limits.image_limits())
                .map_err(|e| image_error(path, e))?;
            read_l16(path, dec, limits)
        }
        Container::Tiff => {
            // A TIFF of another sample format (32-bit float or integer depth) fails here, in
            // the decoder's words; say what is expected.
            let mut dec = TiffDecoder::new(reader).map_err(|e| match e {
                image::ImageError::Unsupported(u) => {
                    unsupported_l16(path, format!("a TIFF this reader cannot decode ({u})"))
                }
                other => image_error(path, other),
            })?;
            dec.set_limits(limits.image_limits())
                .map_err(|e| image_error(path, e))?;
            read_l16(path, dec, limits)
        }
    }
}

/// Decodes a 16-bit single-channel PNG held in `bytes` (errors name `path`, where they came
/// from): a ROS `compressedDepth` image.
pub(crate) fn decode_png_l16_bytes(
    path: &Path,
    bytes: &[u8],
    limits: &Limits,
) -> Result<Image<u16>> {
    let dec = PngDecoder::with_limits(Cursor::new(bytes), limits.image_limits())
        .map_err(|e| image_error(path, e))?;
    read_l16(path, dec, limits)
}

/// Decodes a 16-bit grey image into a buffer allocated here: a header within a raised budget
/// (see [`Limits`]) whose pixels this process cannot address is an error
/// ([`IoError::TooLarge`], [`probe_room`]), not an abort on allocation failure. The buffer is
/// zero-allocated (`vec!`: pages are committed only as the decoder writes rows, so a truncated
/// file with a huge header touches little memory) and the pixels go straight into the `u16`
/// buffer of the result (native-endian samples, as `ImageDecoder::read_image` writes them).
fn read_l16(path: &Path, dec: impl ImageDecoder, limits: &Limits) -> Result<Image<u16>> {
    check_dimensions(path, &dec, limits)?;
    check_l16(path, dec.color_type())?;
    let (w, h) = dec.dimensions();
    let (w, h) = (w as usize, h as usize);
    probe_room(path, &dec)?;
    let mut px = vec![0u16; w.saturating_mul(h)];
    dec.read_image(bytemuck::cast_slice_mut(&mut px))
        .map_err(|e| image_error(path, e))?;
    Image::from_vec(w, h, px).map_err(|e| IoError::core(path, None, e))
}

/// Fails with [`IoError::TooLarge`] when this process cannot allocate the decoded image the
/// header announces (the decoder's own allocation would abort the process instead): an
/// allocation of that size is tried and given back.
fn probe_room(path: &Path, dec: &impl ImageDecoder) -> Result<()> {
    let bytes = usize::try_from(dec.total_bytes()).unwrap_or(usize::MAX);
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(bytes).map_err(|_| {
        let (w, h) = dec.dimensions();
        IoError::too_large(
            path,
            format!("{w}x{h} pixels: not enough memory for the image"),
        )
    })
}

/// Checks the size a decoder read from the header against [`Limits::max_pixels`], before
/// anything is decoded.
fn check_dimensions(path: &Path, dec: &impl ImageDecoder, limits: &Limits) -> Result<()> {
    let (w, h) = dec.dimensions();
    limits
        .check_pixels(u64::from(w), u64::from(h))
        .map_err(|m| IoError::too_large(path, m))
}

fn unsupported_l16(path: &Path, found: String) -> IoError {
    IoError::UnsupportedImage {
        path: path.to_path_buf(),
        found,
        expected: "16-bit single-channel (grey) depth image".into(),
    }
}

fn check_l16(path: &Path, ct: ColorType) -> Result<()> {
    if ct == ColorType::L16 {
        Ok(())
    } else {
        Err(unsupported_l16(path, describe(ct)))
    }
}

/// Decodes any PNG or TIFF the `image` crate understands and converts it to 8-bit RGB.
pub(crate) fn decode_rgb8(path: &Path, limits: &Limits) -> Result<Image<[u8; 3]>> {
    let mut reader = image::ImageReader::new(open(path)?)
        .with_guessed_format()
        .map_err(|e| IoError::io(path, e))?;
    if reader.format().is_none() {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            message: "unrecognised image format (supported: PNG, TIFF, binary PPM/PGM)".into(),
        });
    }
    reader.limits(limits.image_limits());
    let dec = reader.into_decoder().map_err(|e| image_error(path, e))?;
    check_dimensions(path, &dec, limits)?;
    probe_room(path, &dec)?;
    let img = DynamicImage::from_decoder(dec)
        .map_err(|e| image_error(path, e))?
        .into_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    Image::from_vec(w, h, data).map_err(|e| IoError::core(path, None, e))
}

/// Checks that an image can be written: non-empty and at most [`MAX_SIDE`] per side.
pub(crate) fn check_writable_size(path: &Path, width: usize, height: usize) -> Result<(u32, u32)> {
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        return Err(IoError::invalid_data(
            path,
            format!("cannot write a {width}x{height} image (each side must be in 1..={MAX_SIDE})"),
        ));
    }
    Ok((width as u32, height as u32))
}

fn png_encoder(w: &mut dyn Write) -> PngEncoder<&mut dyn Write> {
    // Fast deflate + adaptive filtering: depth maps compress well with it and it is several
    // times faster than the default level (see benches/io.rs).
    PngEncoder::new_with_quality(w, CompressionType::Fast, FilterType::Adaptive)
}

/// Writes `values` (row-major, `width * height`) as a 16-bit grey PNG, atomically.
pub(crate) fn write_png_l16(
    path: &Path,
    width: usize,
    height: usize,
    values: &[u16],
) -> Result<()> {
    let (w, h) = check_writable_size(path, width, height)?;
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
    write_atomic(path, |out| {
        png_encoder(out)
            .write_image(&bytes, w, h, ExtendedColorType::L16)
            .map_err(std::io::Error::other)
    })
}

/// Writes 8-bit pixels (`channels` 1 or 3) as a PNG, atomically.
pub(crate) fn write_png_u8(
    path: &Path,
    width: usize,
    height: usize,
    bytes: &[u8],
    color: ExtendedColorType,
) -> Result<()> {
    let (w, h) = check_writable_size(path, width, height)?;
    write_atomic(path, |out| {
        png_encoder(out)
            .write_image(bytes, w, h, color)
            .map_err(std::io::Error::other)
    })
}

/// Writes `values` as an uncompressed 16-bit grey TIFF, atomically. The TIFF encoder needs
/// `Seek`, so the file is assembled in memory first.
pub(crate) fn write_tiff_l16(
    path: &Path,
    width: usize,
    height: usize,
    values: &[u16],
) -> Result<()> {
    let (w, h) = check_writable_size(path, width, height)?;
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut buf = Cursor::new(Vec::with_capacity(bytes.len() + 1024));
    TiffEncoder::new(&mut buf)
        .write_image(&bytes, w, h, ExtendedColorType::L16)
        .map_err(|e| image_error(path, e))?;
    let encoded = buf.into_inner();
    write_atomic(path, |out| out.write_all(&encoded))
}
