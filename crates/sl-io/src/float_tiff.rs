//! Single-channel floating-point TIFF depth (32-bit, read and written; 64-bit, read) through
//! the `tiff` crate, which the `image` crate uses inside but whose float grey images it does
//! not decode (its `DynamicImage` has no float grey type). This is how ROS depth images
//! (`32FC1`, metres, NaN for no depth), OpenCV's `cv2.imwrite` of a float array and renderers
//! store depth.
//!
//! Decoding is bounded as for the other rasters: the size the header declares is checked
//! against [`Limits`] before anything is allocated, the decoder's own buffers are capped by the
//! same decoded-bytes budget, and an allocation the process cannot make is an error, not an
//! abort.

use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek};
use std::path::Path;

use sl_core::Image;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::SampleFormat;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::{BUDGET_OPTION, Limits};
use crate::raster::check_writable_size;

/// The sample layout of a TIFF file, as far as depth is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TiffSamples {
    /// One floating-point sample per pixel, of this many bits (32 or 64).
    FloatGrey(u8),
    /// Anything else (16-bit integer grey included): the `image` crate's reader takes it.
    Other,
}

fn tiff_error(path: &Path, e: tiff::TiffError) -> IoError {
    match e {
        tiff::TiffError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            IoError::Decode {
                path: path.to_path_buf(),
                message: format!("the file ends before its image data does (truncated?): {io}"),
            }
        }
        tiff::TiffError::IoError(io) => IoError::io(path, io),
        tiff::TiffError::LimitsExceeded => IoError::too_large(
            path,
            format!(
                "the TIFF's buffers exceed the decode limits (the bytes a decoder may allocate \
                 grow with {BUDGET_OPTION})"
            ),
        ),
        other => IoError::Decode {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    }
}

/// The `tiff` crate's limits for `limits`: its decoding buffers within the decoded-bytes
/// budget, its tag values within the default 1 MiB.
fn decoder_limits(limits: &Limits) -> tiff::decoder::Limits {
    let budget = usize::try_from(limits.max_decoded_bytes).unwrap_or(usize::MAX);
    let mut l = tiff::decoder::Limits::default();
    l.decoding_buffer_size = budget;
    l.intermediate_buffer_size = l.intermediate_buffer_size.min(budget);
    l
}

fn decoder<R: Read + Seek>(path: &Path, reader: R, limits: &Limits) -> Result<Decoder<R>> {
    Ok(Decoder::new(reader)
        .map_err(|e| tiff_error(path, e))?
        .with_limits(decoder_limits(limits)))
}

fn samples_of<R: Read + Seek>(path: &Path, dec: &mut Decoder<R>) -> Result<TiffSamples> {
    let colour = dec.colortype().map_err(|e| tiff_error(path, e))?;
    let layout = dec.image_buffer_layout().map_err(|e| tiff_error(path, e))?;
    Ok(match (colour, layout.sample_format) {
        (tiff::ColorType::Gray(bits @ (32 | 64)), SampleFormat::IEEEFP) => {
            TiffSamples::FloatGrey(bits)
        }
        _ => TiffSamples::Other,
    })
}

/// What `path`'s first image holds, from its header alone. A file the `tiff` crate cannot
/// parse is [`TiffSamples::Other`]: the `image` crate's reader then reports it in its words.
pub(crate) fn tiff_samples(path: &Path, limits: &Limits) -> Result<TiffSamples> {
    let f = File::open(path).map_err(|e| IoError::io(path, e))?;
    let Ok(mut dec) = decoder(path, BufReader::new(f), limits) else {
        return Ok(TiffSamples::Other);
    };
    Ok(samples_of(path, &mut dec).unwrap_or(TiffSamples::Other))
}

/// Decodes a single-channel 32- or 64-bit float TIFF into `f32` values as stored (64-bit
/// values rounded to the nearest `f32`).
pub(crate) fn decode_float_grey(path: &Path, limits: &Limits) -> Result<Image<f32>> {
    let f = File::open(path).map_err(|e| IoError::io(path, e))?;
    let mut dec = decoder(path, BufReader::new(f), limits)?;
    let (w, h) = dec.dimensions().map_err(|e| tiff_error(path, e))?;
    limits
        .check_pixels(u64::from(w), u64::from(h))
        .map_err(|m| IoError::too_large(path, m))?;
    let bits = match samples_of(path, &mut dec)? {
        TiffSamples::FloatGrey(bits) => bits,
        TiffSamples::Other => {
            return Err(IoError::UnsupportedImage {
                path: path.to_path_buf(),
                found: "a TIFF that is not single-channel floating point".into(),
                expected: "32- or 64-bit float single-channel (grey) depth image".into(),
            });
        }
    };
    let (w, h) = (w as usize, h as usize);
    let n = w.saturating_mul(h);
    // Room for the decoded samples, asked for before the decoder allocates them.
    let bytes = n.saturating_mul(usize::from(bits / 8));
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(bytes).map_err(|_| {
        IoError::too_large(
            path,
            format!("{w}x{h} pixels: not enough memory for the image"),
        )
    })?;
    drop(probe);
    let values: Vec<f32> = match dec.read_image().map_err(|e| tiff_error(path, e))? {
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        _ => {
            return Err(IoError::Decode {
                path: path.to_path_buf(),
                message: "the TIFF decoder returned integer samples for a float image".into(),
            });
        }
    };
    if values.len() < n {
        return Err(IoError::Decode {
            path: path.to_path_buf(),
            message: format!(
                "{} samples decoded for a {w}x{h} image (truncated?)",
                values.len()
            ),
        });
    }
    let mut values = values;
    values.truncate(n);
    Image::from_vec(w, h, values).map_err(|e| IoError::core(path, None, e))
}

/// Writes `values` (row-major, `width * height`) as an uncompressed single-channel 32-bit
/// float TIFF, atomically (assembled in memory first: the encoder needs `Seek`).
pub(crate) fn write_float_grey(
    path: &Path,
    width: usize,
    height: usize,
    values: &[f32],
) -> Result<()> {
    let (w, h) = check_writable_size(path, width, height)?;
    let mut buf = Cursor::new(Vec::with_capacity(values.len() * 4 + 1024));
    tiff::encoder::TiffEncoder::new(&mut buf)
        .and_then(|mut enc| enc.write_image::<tiff::encoder::colortype::Gray32Float>(w, h, values))
        .map_err(|e| tiff_error(path, e))?;
    let encoded = buf.into_inner();
    write_atomic(path, |out| out.write_all(&encoded))
}
