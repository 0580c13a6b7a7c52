//! The serialisations of the messages a depth recording needs: `sensor_msgs/Image` (depth as
//! `16UC1`, `mono16` or `32FC1`), `CompressedImage` (`compressedDepth`) and `CameraInfo`.
//!
//! - **ROS 1**: little-endian fields in declaration order; a string or a variable-length array
//!   is a `u32` count and its elements; fixed-length arrays (`K`, `R`, `P`) have no count.
//! - **ROS 2** (CDR, little-endian encapsulation `00 01 00 00`): the same order, every
//!   primitive aligned to its size from the end of the 4-byte encapsulation header, strings
//!   counting their terminating NUL; `std_msgs/Header` has no `seq`.

use std::path::Path;

use sl_core::{DepthImage, Image};

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::ros_camera::CameraInfo;

/// How a message is serialised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Encoding {
    /// ROS 1 (packed, little-endian).
    Ros1,
    /// ROS 2's CDR (aligned, little-endian encapsulation).
    Cdr,
}

/// Reads fields off a serialised message; every read is bounds-checked.
struct Fields<'a> {
    path: &'a Path,
    b: &'a [u8],
    at: usize,
    what: &'static str,
    /// CDR: primitives aligned from `at` = 4, after the encapsulation header.
    cdr: bool,
}

impl<'a> Fields<'a> {
    fn new(path: &'a Path, b: &'a [u8], what: &'static str, encoding: Encoding) -> Result<Self> {
        let cdr = encoding == Encoding::Cdr;
        if cdr {
            // Encapsulation `00 01` is CDR little-endian (`00 00`, big-endian, is not what ROS 2
            // writes on the machines that record depth cameras).
            match b.get(..4) {
                Some([0, 1, _, _]) => {}
                Some([a, k, _, _]) => {
                    return Err(IoError::malformed(
                        path,
                        format!(
                            "a {what} message in CDR encapsulation {a:#04x} {k:#04x}, not \
                             little-endian CDR (0x00 0x01)"
                        ),
                    ));
                }
                _ => {
                    return Err(IoError::malformed(
                        path,
                        format!("a {what} message shorter than its CDR encapsulation header"),
                    ));
                }
            }
        }
        Ok(Self {
            path,
            b,
            at: if cdr { 4 } else { 0 },
            what,
            cdr,
        })
    }

    /// Skips CDR padding up to a multiple of `n` from the encapsulation header's end.
    fn align(&mut self, n: usize) {
        if self.cdr {
            let rel = self.at - 4;
            self.at += (n - rel % n) % n;
        }
    }

    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        let s = super::records::slice_at(self.b, self.at, n).ok_or_else(|| {
            IoError::malformed(
                self.path,
                format!(
                    "a {} message is cut off at its `{field}` ({} bytes, {n} needed from {})",
                    self.what,
                    self.b.len(),
                    self.at
                ),
            )
        })?;
        self.at += n;
        Ok(s)
    }

    fn u8(&mut self, field: &str) -> Result<u8> {
        Ok(self.take(1, field)?[0])
    }

    fn u32(&mut self, field: &str) -> Result<u32> {
        self.align(4);
        let b = self.take(4, field)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn f32(&mut self, field: &str) -> Result<f32> {
        self.align(4);
        let b = self.take(4, field)?;
        Ok(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn f64(&mut self, field: &str) -> Result<f64> {
        self.align(8);
        let b = self.take(8, field)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    fn bytes(&mut self, field: &str) -> Result<&'a [u8]> {
        let n = self.u32(field)? as usize;
        self.take(n, field)
    }

    fn string(&mut self, field: &str) -> Result<String> {
        let cdr = self.cdr;
        let mut s = self.bytes(field)?;
        // CDR counts the terminating NUL.
        if cdr && let Some((0, head)) = s.split_last() {
            s = head;
        }
        Ok(String::from_utf8_lossy(s).into_owned())
    }

    fn f64s(&mut self, n: usize, field: &str) -> Result<Vec<f64>> {
        if n > 0 {
            self.align(8);
        }
        // `take` checks the whole length before anything is allocated.
        let b = self.take(n.saturating_mul(8), field)?;
        Ok(b.chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a)
            })
            .collect())
    }

    /// A `time` (ROS 1: unsigned seconds and nanoseconds) or `builtin_interfaces/Time` (ROS 2:
    /// signed seconds, unsigned nanoseconds), seconds.
    fn stamp(&mut self, field: &str) -> Result<f64> {
        let secs = self.u32(field)?;
        let nsecs = self.u32(field)?;
        let secs = if self.cdr {
            f64::from(secs as i32)
        } else {
            f64::from(secs)
        };
        Ok(secs + f64::from(nsecs) * 1e-9)
    }

    /// `std_msgs/Header`: the stamp, seconds (`seq` and `frame_id` are skipped).
    fn header_stamp_s(&mut self) -> Result<f64> {
        if !self.cdr {
            self.u32("header.seq")?;
        }
        let t = self.stamp("header.stamp")?;
        self.bytes("header.frame_id")?;
        Ok(t)
    }
}

/// How an image message stores depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthEncodingKind {
    /// `16UC1` or `mono16`: unsigned 16-bit units (millimetres by ROS's REP 118), 0 = none.
    U16,
    /// `32FC1`: 32-bit float metres, NaN (or 0) = none.
    F32,
}

impl DepthEncodingKind {
    /// The kind of a `sensor_msgs/Image` encoding string, if it can hold depth.
    pub fn of(encoding: &str) -> Option<Self> {
        match encoding {
            "16UC1" | "mono16" => Some(Self::U16),
            "32FC1" => Some(Self::F32),
            _ => None,
        }
    }
}

/// A decoded depth image message.
pub(super) struct ImageMessage<'a> {
    pub(super) stamp_s: f64,
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) encoding: String,
    pub(super) big_endian: bool,
    pub(super) step: usize,
    pub(super) data: &'a [u8],
}

/// Parses a `sensor_msgs/Image` (its pixels stay in `b`).
pub(super) fn image<'a>(
    path: &'a Path,
    b: &'a [u8],
    encoding: Encoding,
) -> Result<ImageMessage<'a>> {
    let mut f = Fields::new(path, b, "sensor_msgs/Image", encoding)?;
    let stamp_s = f.header_stamp_s()?;
    let height = f.u32("height")? as usize;
    let width = f.u32("width")? as usize;
    let encoding = f.string("encoding")?;
    let big_endian = f.u8("is_bigendian")? != 0;
    let step = f.u32("step")? as usize;
    let data = f.bytes("data")?;
    Ok(ImageMessage {
        stamp_s,
        width,
        height,
        encoding,
        big_endian,
        step,
        data,
    })
}

/// The depth of an image message, metres (0 = none): 16-bit values divided by `units_per_m`,
/// floats divided by `float_units_per_m` (1: metres); within `limits`.
pub(super) fn depth_of(
    path: &Path,
    m: &ImageMessage<'_>,
    units_per_m: f64,
    float_units_per_m: f64,
    limits: &Limits,
) -> Result<DepthImage> {
    let Some(kind) = DepthEncodingKind::of(&m.encoding) else {
        return Err(IoError::malformed(
            path,
            format!(
                "an image of encoding {:?} is not depth (16UC1, mono16 or 32FC1)",
                m.encoding
            ),
        ));
    };
    limits
        .check_pixels(m.width as u64, m.height as u64)
        .map_err(|e| IoError::too_large(path, e))?;
    let bpp = match kind {
        DepthEncodingKind::U16 => 2,
        DepthEncodingKind::F32 => 4,
    };
    let row = m.width * bpp;
    let enough = m.step >= row
        && m.step
            .checked_mul(m.height)
            .is_some_and(|n| n <= m.data.len());
    if !enough {
        return Err(IoError::malformed(
            path,
            format!(
                "a {}x{} {} image with {} bytes a row (step) and {} bytes of data: at least {} \
                 a row and {} in all are needed",
                m.width,
                m.height,
                m.encoding,
                m.step,
                m.data.len(),
                row,
                row * m.height
            ),
        ));
    }
    let mut out = Vec::with_capacity(m.width * m.height);
    for y in 0..m.height {
        let r = &m.data[y * m.step..y * m.step + row];
        match kind {
            DepthEncodingKind::U16 => out.extend(r.chunks_exact(2).map(|c| {
                let v = if m.big_endian {
                    u16::from_be_bytes([c[0], c[1]])
                } else {
                    u16::from_le_bytes([c[0], c[1]])
                };
                crate::depth::units_to_m(v, units_per_m)
            })),
            DepthEncodingKind::F32 => out.extend(r.chunks_exact(4).map(|c| {
                let a = [c[0], c[1], c[2], c[3]];
                let v = if m.big_endian {
                    f32::from_be_bytes(a)
                } else {
                    f32::from_le_bytes(a)
                };
                crate::depth::float_units_to_m(v, float_units_per_m)
            })),
        }
    }
    Image::from_vec(m.width, m.height, out)
        .map(DepthImage::from_image)
        .map_err(|e| IoError::core(path, None, e))
}

/// A `sensor_msgs/CompressedImage` of `image_transport`'s `compressedDepth` plugin.
pub(super) struct CompressedMessage<'a> {
    pub(super) stamp_s: f64,
    /// `"16UC1; compressedDepth png"` (or without ` png`, as older plugins write it), or
    /// `"… compressedDepth rvl"`.
    pub(super) format: String,
    pub(super) data: &'a [u8],
}

/// Parses a `sensor_msgs/CompressedImage` (its bytes stay in `b`).
pub(super) fn compressed_image<'a>(
    path: &'a Path,
    b: &'a [u8],
    encoding: Encoding,
) -> Result<CompressedMessage<'a>> {
    let mut f = Fields::new(path, b, "sensor_msgs/CompressedImage", encoding)?;
    let stamp_s = f.header_stamp_s()?;
    let format = f.string("format")?;
    let data = f.bytes("data")?;
    Ok(CompressedMessage {
        stamp_s,
        format,
        data,
    })
}

/// The depth encoding a `compressedDepth` format string names (`16UC1; compressedDepth png`
/// → `16UC1`), when it is one.
pub(super) fn compressed_depth_encoding(format: &str) -> Option<&str> {
    let (encoding, rest) = format.split_once(';')?;
    rest.trim()
        .starts_with("compressedDepth")
        .then_some(encoding.trim())
}

/// The codec of a `compressedDepth` image, as the plugin's decoder tells it from the format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Codec {
    Png,
    Rvl,
}

impl Codec {
    /// `"… compressedDepth png"`, `"… compressedDepth rvl"`, or a bare `"… compressedDepth"`
    /// (PNG: older plugins name no codec); `None` for another codec.
    fn of(format: &str) -> Option<Self> {
        let (_, rest) = format.split_once(';')?;
        let rest = rest.trim();
        if rest.contains("compressedDepth rvl") {
            Some(Self::Rvl)
        } else if rest.contains("compressedDepth png") || rest == "compressedDepth" {
            Some(Self::Png)
        } else {
            None
        }
    }
}

/// Bytes of the `compressedDepth` configuration header before the PNG or RVL image: the
/// format (`i32`, 0 for inverse depth) and the two depth quantisation parameters (`f32`).
const CONFIG_HEADER_BYTES: usize = 12;

/// The depth of a `compressedDepth` image, metres (0 = none): a `16UC1` image (PNG or RVL) of
/// units divided by `units_per_m`; a `32FC1` one stores inverse depth, `q = a / z + b` as
/// 16-bit values (0 = none), decoded as `z = a / (q − b)` and divided by `float_units_per_m`.
pub(super) fn compressed_depth_of(
    path: &Path,
    m: &CompressedMessage<'_>,
    units_per_m: f64,
    float_units_per_m: f64,
    limits: &Limits,
) -> Result<DepthImage> {
    let encoding = compressed_depth_encoding(&m.format).unwrap_or_default();
    let kind = DepthEncodingKind::of(encoding).ok_or_else(|| {
        IoError::malformed(
            path,
            format!(
                "a compressed image of format {:?} is not compressedDepth depth",
                m.format
            ),
        )
    })?;
    let Some((config, image)) = m.data.split_at_checked(CONFIG_HEADER_BYTES) else {
        return Err(IoError::malformed(
            path,
            "a compressedDepth image shorter than its 12-byte configuration header",
        ));
    };
    let q = match Codec::of(&m.format) {
        Some(Codec::Png) => crate::raster::decode_png_l16_bytes(path, image, limits)?,
        Some(Codec::Rvl) => super::rvl::decode(path, image, limits)?,
        None => {
            return Err(IoError::malformed(
                path,
                format!(
                    "format {:?}: a compressedDepth codec other than png and rvl",
                    m.format
                ),
            ));
        }
    };
    let (w, h) = (q.width(), q.height());
    let values = q.into_vec();
    let out: Vec<f32> = match kind {
        DepthEncodingKind::U16 => values
            .into_iter()
            .map(|v| crate::depth::units_to_m(v, units_per_m))
            .collect(),
        DepthEncodingKind::F32 => {
            let param = |i: usize| {
                f32::from_le_bytes([config[i], config[i + 1], config[i + 2], config[i + 3]])
            };
            let (a, b) = (param(4), param(8));
            values
                .into_iter()
                .map(|v| {
                    if v == 0 {
                        0.0
                    } else {
                        crate::depth::float_units_to_m(a / (f32::from(v) - b), float_units_per_m)
                    }
                })
                .collect()
        }
    };
    Image::from_vec(w, h, out)
        .map(DepthImage::from_image)
        .map_err(|e| IoError::core(path, None, e))
}

/// Parses a `sensor_msgs/CameraInfo` into the fields that make a camera.
pub(super) fn camera_info(path: &Path, b: &[u8], encoding: Encoding) -> Result<CameraInfo> {
    let mut f = Fields::new(path, b, "sensor_msgs/CameraInfo", encoding)?;
    f.header_stamp_s()?;
    let height = f.u32("height")? as usize;
    let width = f.u32("width")? as usize;
    let distortion_model = f.string("distortion_model")?;
    let n = f.u32("D")? as usize;
    let d = f.f64s(n, "D")?;
    let mut k = [0.0; 9];
    for v in &mut k {
        *v = f.f64("K")?;
    }
    f.f64s(9, "R")?;
    let mut projection = [0.0; 12];
    for v in &mut projection {
        *v = f.f64("P")?;
    }
    let binning = (
        f64::from(f.u32("binning_x")?),
        f64::from(f.u32("binning_y")?),
    );
    let mut roi = [0.0; 4];
    // `roi`: x_offset, y_offset, height, width (in that order), do_rectify.
    let (x, y) = (f.u32("roi.x_offset")?, f.u32("roi.y_offset")?);
    let (h, w) = (f.u32("roi.height")?, f.u32("roi.width")?);
    roi[0] = f64::from(x);
    roi[1] = f64::from(y);
    roi[2] = f64::from(w);
    roi[3] = f64::from(h);
    Ok(CameraInfo {
        width,
        height,
        k,
        binning,
        roi,
        distortion_model,
        d,
        projection: Some(projection),
    })
}

/// A `std_msgs/Float32`'s value.
pub(super) fn float32(path: &Path, b: &[u8], encoding: Encoding) -> Result<f32> {
    Fields::new(path, b, "std_msgs/Float32", encoding)?.f32("data")
}

/// A `std_msgs/String`'s text.
pub(super) fn string(path: &Path, b: &[u8], encoding: Encoding) -> Result<String> {
    Fields::new(path, b, "std_msgs/String", encoding)?.string("data")
}

/// A `diagnostic_msgs/KeyValue`'s key and value.
pub(super) fn key_value(path: &Path, b: &[u8], encoding: Encoding) -> Result<(String, String)> {
    let mut f = Fields::new(path, b, "diagnostic_msgs/KeyValue", encoding)?;
    Ok((f.string("key")?, f.string("value")?))
}

/// The stamp (seconds) and frame (`header.frame_id`: a camera driver's optical frame,
/// `camera_depth_optical_frame`) of an image message's header, for a `sensor_msgs/Image` or
/// `CompressedImage` alike (both open with the header); nothing past it is read.
pub(super) fn image_header(path: &Path, b: &[u8], encoding: Encoding) -> Result<(f64, String)> {
    let mut f = Fields::new(path, b, "image", encoding)?;
    if !f.cdr {
        f.u32("header.seq")?;
    }
    let t = f.stamp("header.stamp")?;
    let frame = f.string("header.frame_id")?;
    Ok((t, frame))
}

/// One `geometry_msgs/TransformStamped` of a `tf2_msgs/TFMessage`: the pose of frame `child`
/// in frame `parent` at `stamp_s`, as recorded (not yet checked).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct TransformEntry {
    pub(super) parent: String,
    pub(super) child: String,
    pub(super) stamp_s: f64,
    pub(super) translation: [f64; 3],
    /// `x, y, z, w`, as ROS orders a quaternion.
    pub(super) rotation_xyzw: [f64; 4],
}

/// Parses a `tf2_msgs/TFMessage` (ROS 1's `tf/tfMessage` has the same layout): its
/// `geometry_msgs/TransformStamped[] transforms`. The count is not trusted: each entry is read
/// off the message's own bytes, so a count beyond them is an error after the bytes run out,
/// before anything of its size is allocated.
pub(super) fn transforms(path: &Path, b: &[u8], encoding: Encoding) -> Result<Vec<TransformEntry>> {
    let mut f = Fields::new(path, b, "tf2_msgs/TFMessage", encoding)?;
    let n = f.u32("transforms")?;
    let mut out = Vec::new();
    for _ in 0..n {
        if !f.cdr {
            f.u32("header.seq")?;
        }
        let stamp_s = f.stamp("header.stamp")?;
        let parent = f.string("header.frame_id")?;
        let child = f.string("child_frame_id")?;
        let mut translation = [0.0; 3];
        for v in &mut translation {
            *v = f.f64("transform.translation")?;
        }
        let mut rotation_xyzw = [0.0; 4];
        for v in &mut rotation_xyzw {
            *v = f.f64("transform.rotation")?;
        }
        out.push(TransformEntry {
            parent,
            child,
            stamp_s,
            translation,
            rotation_xyzw,
        });
    }
    Ok(out)
}
