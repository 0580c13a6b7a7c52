//! Depth images on disk: 16-bit PNG and TIFF at any scale, floating-point TIFF (ROS `32FC1`,
//! OpenCV's float arrays), NYU Depth v2 raw Kinect disparity (PGM), and SUN RGB-D's bit-rotated
//! PNG.
//!
//! [`read_depth`] returns the depth in metres together with the [`DepthEncoding`] it was stored
//! in, and [`write_depth`] writes any [`DepthImage`] in a given encoding, so a tool can write its
//! output "in the input's encoding and scale".
//!
//! | [`DepthFormat`] | file | stored integer `v` | metres | invalid |
//! |---|---|---|---|---|
//! | `Png` | 16-bit grey PNG | depth units | `v / units_per_m` | 0 and 65535 |
//! | `Tiff` | 16-bit grey TIFF | depth units | `v / units_per_m` | 0 and 65535 |
//! | `TiffF32` | 32-bit float grey TIFF (64-bit read too) | depth units, metres by default | `v / units_per_m` (1) | 0, negative, NaN, ±∞ |
//! | `Sun` | 16-bit grey PNG | `mm` rotated left by 3 bits | `rotr(v, 3) / units_per_m` (1000) | 0 and 65535 |
//! | `NyuRaw` | PGM `P5`, 16-bit **little-endian** | raw disparity, 1/8 px | `351.3 / (1092.5 − v)` | `v ≥ 1093` (2047) |
//!
//! Common scales: 1000 units per metre (millimetres: 7-Scenes, ICL-NUIM, PCL, SUN RGB-D), 5000
//! (TUM RGB-D). Without a scale given, a PNG or TIFF is read at 1000, or at 5000 when it lies
//! in the `depth` folder of a TUM sequence folder
//! ([`depth_scale_of_file`](crate::sequence::depth_scale_of_file)). 7-Scenes marks invalid
//! pixels with 65535 rather than 0; the sentinel a file uses is recorded in
//! [`DepthEncoding::invalid_value`] so that it round-trips.
//!
//! A `.tif` file is read by what it stores: 16-bit integers as `Tiff`, floating point as
//! `TiffF32` (at 1 unit per metre unless a scale is given: ROS and OpenCV keep metres), and
//! written back the same way. Float depth has no integer values, so [`read_raw_depth`] refuses
//! it.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use sl_core::{DepthImage, DisparityImage, Image, Intrinsics, SensorModel};

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::float_tiff::{TiffSamples, decode_float_grey, tiff_samples, write_float_grey};
use crate::limits::Limits;
use crate::pnm::{PnmKind, read_pnm};
use crate::raster::{Container, check_writable_size, decode_l16, write_png_l16, write_tiff_l16};

/// Default depth scale: millimetres.
pub const DEFAULT_UNITS_PER_M: f64 = 1000.0;
/// Default scale of floating-point TIFF depth: metres (ROS `32FC1`, OpenCV, renderers).
pub const FLOAT_UNITS_PER_M: f64 = 1.0;
/// The TUM RGB-D depth scale (value / 5000 = metres).
pub const TUM_UNITS_PER_M: f64 = 5000.0;
/// Smallest depth scale accepted: 1 unit per metre (a 16-bit file then spans 65 km).
pub const MIN_UNITS_PER_M: f64 = 1.0;
/// Largest depth scale accepted: 10⁶ units per metre (micrometres: a 16-bit file spans 65 mm).
/// Outside `MIN_UNITS_PER_M..=MAX_UNITS_PER_M` every stored value would be an invalid or
/// meaningless depth, so the scale is refused instead.
pub const MAX_UNITS_PER_M: f64 = 1e6;
/// The 16-bit value that some datasets (7-Scenes) use for "no depth"; always invalid on read.
pub const INVALID_SENTINEL: u16 = u16::MAX;
/// Largest stored unit that reads back as a valid depth (65535 is the invalid sentinel).
pub const MAX_VALID_UNITS: u16 = u16::MAX - 1;

/// NYU Depth v2 toolbox numerator: metres = `NYU_DEPTH_NUMERATOR / (NYU_DOFF − raw)`.
pub const NYU_DEPTH_NUMERATOR: f64 = 351.3;
/// NYU Depth v2 toolbox disparity offset (`doff` of the ROS kinect model, in raw 1/8-px units).
pub const NYU_DOFF: f64 = 1092.5;
/// Raw value of a pixel without a measurement in NYU raw frames (the Kinect's 2047).
pub const NYU_INVALID_RAW: u16 = 2047;
/// Raw Kinect disparity steps per pixel: the raw value counts 1/8 px.
pub const KINECT_RAW_STEPS_PER_PX: u32 = 8;
/// `f·B` implied by the NYU constants: `351.3 / 8 = 43.9125` px·m (with `D_px = (doff − raw)/8`
/// and `Z = f·B / D_px`, this reproduces the toolbox's depth exactly).
pub const NYU_FB_PX_M: f64 = NYU_DEPTH_NUMERATOR / KINECT_RAW_STEPS_PER_PX as f64;
/// Largest raw value that gives a positive NYU depth (`raw < 1092.5`).
pub const NYU_MAX_VALID_RAW: u16 = 1092;

/// How a depth file stores its values (the container and the value transform).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DepthFormat {
    /// 16-bit single-channel PNG, `units_per_m` units per metre.
    Png,
    /// 16-bit single-channel TIFF, `units_per_m` units per metre.
    Tiff,
    /// Floating-point single-channel TIFF (32-bit; 64-bit is read too), `units_per_m` units per
    /// metre ([`FLOAT_UNITS_PER_M`], metres, unless a scale is given). A `.tif` holding float
    /// samples is read as this whatever format was asked for among `tiff` and `tiff-f32`.
    TiffF32,
    /// NYU Depth v2 raw Kinect disparity: binary PGM, 16-bit little-endian raw values.
    NyuRaw,
    /// SUN RGB-D: 16-bit PNG of millimetres rotated left by 3 bits.
    Sun,
}

impl DepthFormat {
    /// All formats, in the order of their names in [`DepthFormat::NAMES`].
    pub const ALL: [DepthFormat; 5] = [
        Self::Png,
        Self::Tiff,
        Self::TiffF32,
        Self::NyuRaw,
        Self::Sun,
    ];
    /// The accepted names (`--format` values).
    pub const NAMES: [&'static str; 5] = ["png", "tiff", "tiff-f32", "nyu-raw", "sun"];

    /// The canonical name: `png`, `tiff`, `tiff-f32`, `nyu-raw` or `sun`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Png => "png",
            Self::Tiff => "tiff",
            Self::TiffF32 => "tiff-f32",
            Self::NyuRaw => "nyu-raw",
            Self::Sun => "sun",
        }
    }

    /// The format implied by a file extension (case-insensitive): `.png` → `Png`,
    /// `.tif`/`.tiff` → `Tiff` (read as `TiffF32` when it stores floats), `.pgm` → `NyuRaw`.
    /// SUN RGB-D files are ordinary `.png` files and must be named explicitly.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(Self::Png),
            "tif" | "tiff" => Some(Self::Tiff),
            "pgm" => Some(Self::NyuRaw),
            _ => None,
        }
    }

    /// Whether the format stores depth units at a scale (all but `NyuRaw`).
    pub fn has_scale(self) -> bool {
        !matches!(self, Self::NyuRaw)
    }
}

impl fmt::Display for DepthFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error of [`DepthFormat::from_str`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown depth format {0:?} (expected one of: png, tiff, tiff-f32, nyu-raw, sun)")]
pub struct UnknownFormat(pub String);

impl FromStr for DepthFormat {
    type Err = UnknownFormat;

    /// Parses `png`, `tiff` (or `tif`), `tiff-f32` (or `tiff-float`, `tif-f32`), `nyu-raw` (or
    /// `nyu`, `pgm`), `sun` (or `sun-rgbd`), case-insensitively.
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().replace('_', "-").as_str() {
            "png" => Ok(Self::Png),
            "tiff" | "tif" => Ok(Self::Tiff),
            "tiff-f32" | "tif-f32" | "tiff-float" | "tif-float" | "float-tiff" => Ok(Self::TiffF32),
            "nyu-raw" | "nyu" | "pgm" => Ok(Self::NyuRaw),
            "sun" | "sun-rgbd" | "sunrgbd" => Ok(Self::Sun),
            _ => Err(UnknownFormat(s.to_string())),
        }
    }
}

/// Everything needed to write depth back the way a file stored it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthEncoding {
    /// Container and value transform.
    pub format: DepthFormat,
    /// Units per metre (1000 = millimetres, 5000 = TUM; 1 = metres, float TIFF's default).
    /// Ignored by [`DepthFormat::NyuRaw`], whose values are disparities (set to 1000 there).
    pub units_per_m: f64,
    /// The stored value of an invalid pixel: 0 or 65535 (7-Scenes) for PNG/TIFF/SUN, 0 for
    /// float TIFF (whose reader also takes NaN, ±∞ and negative values for no depth),
    /// [`NYU_INVALID_RAW`] for NYU raw. On reading an integer file, 0 and 65535 are *both*
    /// invalid whatever this says; it only decides what [`write_depth`] stores for invalid
    /// pixels.
    pub invalid_value: u16,
}

impl Default for DepthEncoding {
    /// 16-bit PNG, millimetres, 0 = invalid.
    fn default() -> Self {
        Self::png(DEFAULT_UNITS_PER_M)
    }
}

impl DepthEncoding {
    /// 16-bit PNG at `units_per_m`, invalid = 0.
    pub fn png(units_per_m: f64) -> Self {
        Self {
            format: DepthFormat::Png,
            units_per_m,
            invalid_value: 0,
        }
    }

    /// 16-bit TIFF at `units_per_m`, invalid = 0.
    pub fn tiff(units_per_m: f64) -> Self {
        Self {
            format: DepthFormat::Tiff,
            ..Self::png(units_per_m)
        }
    }

    /// Floating-point (32-bit) TIFF at `units_per_m` ([`FLOAT_UNITS_PER_M`] = metres, as ROS
    /// and OpenCV keep float depth), invalid = 0.
    pub fn tiff_f32(units_per_m: f64) -> Self {
        Self {
            format: DepthFormat::TiffF32,
            ..Self::png(units_per_m)
        }
    }

    /// The TUM RGB-D encoding: 16-bit PNG, 5000 units per metre.
    pub fn tum() -> Self {
        Self::png(TUM_UNITS_PER_M)
    }

    /// The 7-Scenes encoding: 16-bit PNG millimetres, invalid = 65535.
    pub fn seven_scenes() -> Self {
        Self::png(DEFAULT_UNITS_PER_M).with_invalid_value(INVALID_SENTINEL)
    }

    /// SUN RGB-D: bit-rotated 16-bit PNG millimetres, invalid = 0.
    pub fn sun() -> Self {
        Self {
            format: DepthFormat::Sun,
            ..Self::png(DEFAULT_UNITS_PER_M)
        }
    }

    /// NYU Depth v2 raw Kinect disparity PGM, invalid = 2047.
    pub fn nyu_raw() -> Self {
        Self {
            format: DepthFormat::NyuRaw,
            units_per_m: DEFAULT_UNITS_PER_M,
            invalid_value: NYU_INVALID_RAW,
        }
    }

    /// The default encoding of a format: 1000 units per metre (float TIFF: metres), the
    /// format's invalid value.
    pub fn for_format(format: DepthFormat) -> Self {
        match format {
            DepthFormat::Png => Self::png(DEFAULT_UNITS_PER_M),
            DepthFormat::Tiff => Self::tiff(DEFAULT_UNITS_PER_M),
            DepthFormat::TiffF32 => Self::tiff_f32(FLOAT_UNITS_PER_M),
            DepthFormat::Sun => Self::sun(),
            DepthFormat::NyuRaw => Self::nyu_raw(),
        }
    }

    /// The same encoding with another invalid value.
    pub fn with_invalid_value(self, invalid_value: u16) -> Self {
        Self {
            invalid_value,
            ..self
        }
    }

    /// The same encoding with another scale.
    pub fn with_units_per_m(self, units_per_m: f64) -> Self {
        Self {
            units_per_m,
            ..self
        }
    }

    /// Smallest depth that survives a round trip, metres.
    pub fn min_depth_m(&self) -> f64 {
        match self.format {
            DepthFormat::NyuRaw => NYU_DEPTH_NUMERATOR / NYU_DOFF,
            DepthFormat::TiffF32 => f64::from(f32::MIN_POSITIVE) / self.units_per_m,
            _ => 1.0 / self.units_per_m,
        }
    }

    /// Largest depth that can be stored, metres (65534 units, or raw 1092 for NYU: 702.6 m; the
    /// largest `f32` for float TIFF).
    pub fn max_depth_m(&self) -> f64 {
        match self.format {
            DepthFormat::NyuRaw => NYU_DEPTH_NUMERATOR / (NYU_DOFF - f64::from(NYU_MAX_VALID_RAW)),
            DepthFormat::TiffF32 => f64::from(f32::MAX) / self.units_per_m,
            _ => f64::from(MAX_VALID_UNITS) / self.units_per_m,
        }
    }

    /// Checks the scale and the invalid value.
    fn validate(&self, path: &Path) -> Result<()> {
        if self.format.has_scale()
            && !(MIN_UNITS_PER_M..=MAX_UNITS_PER_M).contains(&self.units_per_m)
        {
            return Err(IoError::InvalidScale {
                path: path.to_path_buf(),
                units_per_m: self.units_per_m,
            });
        }
        let ok = match self.format {
            DepthFormat::NyuRaw => self.invalid_value > NYU_MAX_VALID_RAW,
            DepthFormat::TiffF32 => self.invalid_value == 0,
            _ => self.invalid_value == 0 || self.invalid_value == INVALID_SENTINEL,
        };
        if !ok {
            return Err(IoError::Format {
                path: path.to_path_buf(),
                message: format!(
                    "invalid value {} cannot mark missing depth in {} (use {})",
                    self.invalid_value,
                    self.format,
                    if self.format == DepthFormat::NyuRaw {
                        "2047"
                    } else if self.format == DepthFormat::TiffF32 {
                        "0"
                    } else {
                        "0 or 65535"
                    }
                ),
            });
        }
        Ok(())
    }

    /// Converts stored integers to metres.
    fn decode(&self, raw: &Image<u16>) -> DepthImage {
        let (w, h) = raw.dimensions();
        let data = match self.format {
            DepthFormat::NyuRaw => raw.data().iter().map(|&v| nyu_raw_value_to_m(v)).collect(),
            DepthFormat::Png | DepthFormat::Tiff | DepthFormat::TiffF32 => {
                let s = self.units_per_m;
                raw.data().iter().map(|&v| units_to_m(v, s)).collect()
            }
            DepthFormat::Sun => {
                let s = self.units_per_m;
                raw.data()
                    .iter()
                    .map(|&v| units_to_m(v.rotate_right(3), s))
                    .collect()
            }
        };
        DepthImage::from_image(rebuild(w, h, data))
    }

    /// Converts metres to stored integers, refusing values that would not round-trip.
    fn encode(&self, path: &Path, depth: &DepthImage) -> Result<Vec<u16>> {
        let w = depth.width().max(1);
        let out_of_range = |i: usize, z: f32| IoError::DepthOutOfRange {
            path: path.to_path_buf(),
            x: i % w,
            y: i / w,
            depth_m: z,
            min_depth_m: self.min_depth_m(),
            max_depth_m: self.max_depth_m(),
        };
        let mut out = Vec::with_capacity(depth.data().len());
        for (i, &z) in depth.data().iter().enumerate() {
            if !(z > 0.0 && z.is_finite()) {
                out.push(self.invalid_value);
                continue;
            }
            let v = match self.format {
                DepthFormat::NyuRaw => {
                    let raw = (NYU_DOFF - NYU_DEPTH_NUMERATOR / f64::from(z)).round();
                    if !(0.0..=f64::from(NYU_MAX_VALID_RAW)).contains(&raw) {
                        return Err(out_of_range(i, z));
                    }
                    raw as u16
                }
                DepthFormat::Png | DepthFormat::Tiff | DepthFormat::TiffF32 | DepthFormat::Sun => {
                    let u = (f64::from(z) * self.units_per_m).round();
                    if !(1.0..=f64::from(MAX_VALID_UNITS)).contains(&u) {
                        return Err(out_of_range(i, z));
                    }
                    let u = u as u16;
                    if self.format == DepthFormat::Sun {
                        u.rotate_left(3)
                    } else {
                        u
                    }
                }
            };
            out.push(v);
        }
        Ok(out)
    }
}

impl fmt::Display for DepthEncoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.format {
            DepthFormat::NyuRaw => write!(
                f,
                "nyu-raw (Kinect raw disparity, invalid {})",
                self.invalid_value
            ),
            DepthFormat::TiffF32 if self.units_per_m == FLOAT_UNITS_PER_M => {
                f.write_str("tiff-f32 (metres, invalid 0 and NaN)")
            }
            DepthFormat::TiffF32 => write!(
                f,
                "tiff-f32 ({} units/m, invalid 0 and NaN)",
                self.units_per_m
            ),
            fmt => write!(
                f,
                "{fmt} ({} units/m, invalid {})",
                self.units_per_m, self.invalid_value
            ),
        }
    }
}

pub(crate) fn units_to_m(v: u16, units_per_m: f64) -> f32 {
    if v == 0 || v == INVALID_SENTINEL {
        0.0
    } else {
        (f64::from(v) / units_per_m) as f32
    }
}

/// Metres of one NYU raw value (0 for `raw ≥ 1093`, which includes the 2047 no-data code).
///
/// The NYU toolbox (`depth_rel2depth_abs.m`) also clamps depths beyond 10 m to 10 m; we do not,
/// since a fabricated depth would distort resolution analyses (Kinect raw values that far out do
/// not occur in practice: the real frame spans 1.39–6.69 m).
pub fn nyu_raw_value_to_m(raw: u16) -> f32 {
    if raw > NYU_MAX_VALID_RAW {
        0.0
    } else {
        (NYU_DEPTH_NUMERATOR / (NYU_DOFF - f64::from(raw))) as f32
    }
}

/// Rebuilds an image of known size from a buffer of the same length.
fn rebuild(w: usize, h: usize, data: Vec<f32>) -> Image<f32> {
    Image::from_vec(w, h, data).unwrap_or_else(|_| Image::filled(w, h, 0.0))
}

/// How [`read_depth`] interprets a file.
///
/// `#[non_exhaustive]`: start from [`ReadConfig::default`] (format from the extension, the
/// scale of the file's place: 1000 units per metre, 5000 in a TUM folder) and set what you need with [`ReadConfig::with_format`] /
/// [`ReadConfig::with_scale`] or by assigning the fields.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct ReadConfig {
    /// The format; `None` infers it from the extension ([`DepthFormat::from_path`]), and a PNG
    /// of a SUN RGB-D sample's `depth` folder is SUN's
    /// ([`crate::sequence::sun_folder_of_file`]).
    pub format: Option<DepthFormat>,
    /// Units per metre for PNG/TIFF/SUN; `None` = the scale of the file's place, 5000 for a
    /// PNG or TIFF in a TUM RGB-D folder's `depth` folder
    /// ([`crate::sequence::depth_scale_of_file`]), else 1000 (millimetres). Must lie in
    /// [`MIN_UNITS_PER_M`]`..=`[`MAX_UNITS_PER_M`]; giving it for `nyu-raw` (which stores
    /// disparity) is an error.
    pub scale_units_per_m: Option<f64>,
}

/// The former name of [`ReadConfig`].
#[deprecated(
    since = "0.1.0",
    note = "renamed `ReadConfig` (every configuration is a `…Config`)"
)]
pub type ReadOptions = ReadConfig;

impl ReadConfig {
    /// The configuration with an explicit format.
    pub fn with_format(self, format: DepthFormat) -> Self {
        Self {
            format: Some(format),
            ..self
        }
    }

    /// The configuration with an explicit scale.
    pub fn with_scale(self, units_per_m: f64) -> Self {
        Self {
            scale_units_per_m: Some(units_per_m),
            ..self
        }
    }

    /// Checks what can be checked before a file is named: a scale outside
    /// [`MIN_UNITS_PER_M`]`..=`[`MAX_UNITS_PER_M`] (zero, negative, not finite), or a scale
    /// with the `nyu-raw` format, is an [`IoError::InvalidConfig`]. The readers make the same
    /// checks per file (with the format inferred from the extension) and report them with the
    /// file's path.
    pub fn validate(&self) -> Result<()> {
        let Some(s) = self.scale_units_per_m else {
            return Ok(());
        };
        if self.format == Some(DepthFormat::NyuRaw) {
            return Err(IoError::InvalidConfig {
                message: "a depth scale does not apply to nyu-raw files (they store Kinect \
                          disparity)"
                    .into(),
            });
        }
        if !(MIN_UNITS_PER_M..=MAX_UNITS_PER_M).contains(&s) {
            return Err(IoError::InvalidConfig {
                message: format!(
                    "invalid depth scale {s:e} units per metre (valid: 1 to 1e6 units per metre)"
                ),
            });
        }
        Ok(())
    }
}

/// A depth map and the encoding it was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedDepth {
    /// Depth in metres, 0 = invalid.
    pub depth: DepthImage,
    /// How the file stored it; pass it to [`write_depth`] to write in the same encoding.
    pub encoding: DepthEncoding,
}

/// The integer values of a depth file, before conversion to metres ([`read_raw_depth`]
/// reads them, [`write_raw_depth`] writes them back as they are).
#[derive(Debug, Clone, PartialEq)]
pub struct RawDepth {
    /// Stored values: PNG/TIFF depth units, SUN millimetres (bit rotation undone), NYU raw
    /// disparity in 1/8 px (byte order fixed).
    pub values: Image<u16>,
    /// The encoding (as [`read_depth`] would report it).
    pub encoding: DepthEncoding,
}

fn resolve_format(path: &Path, format: Option<DepthFormat>) -> Result<DepthFormat> {
    // A PNG of a SUN RGB-D sample's depth folder is SUN's bit-rotated millimetres.
    let by_place = || {
        (DepthFormat::from_path(path) == Some(DepthFormat::Png)
            && crate::sequence::sun_folder_of_file(path).is_some())
        .then_some(DepthFormat::Sun)
    };
    match format
        .or_else(by_place)
        .or_else(|| DepthFormat::from_path(path))
    {
        Some(f) => Ok(f),
        None if crate::rosbag::is_bag_file(path) => Err(IoError::Format {
            path: path.to_path_buf(),
            message: "a ROS bag is a recording, not one depth map: `sldepth track` reads it, \
                      `sldepth info` lists its topics (Python: sldepth.RosBag)"
                .into(),
        }),
        None => match std::fs::symlink_metadata(path) {
            // A path that names nothing: that, not its extension, is what is wrong.
            Err(e) => Err(IoError::io(path, e)),
            Ok(_) => Err(IoError::Format {
                path: path.to_path_buf(),
                message: "cannot infer the depth format from the extension (.png, .tif, .tiff, \
                          .pgm); name it: png, tiff, nyu-raw or sun"
                    .into(),
            }),
        },
    }
}

/// The format [`read_depth`] reads `path` in: `format`, else the one its place and extension
/// imply, a TIFF settled by its samples (floating point → [`DepthFormat::TiffF32`]). Reads a
/// TIFF's header (within the default [`Limits`]), nothing of other files. A caller that turns a
/// camera preset into a depth scale asks this first: float depth carries no preset's scale.
pub fn depth_format_of_file(
    path: impl AsRef<Path>,
    format: Option<DepthFormat>,
) -> Result<DepthFormat> {
    let path = path.as_ref();
    settle_tiff(path, resolve_format(path, format)?, &Limits::default())
}

/// The format a TIFF is read as, by its samples: float grey → `TiffF32`, else `Tiff` (asked for
/// as `tiff-f32`, an integer TIFF is an error). Other formats are returned as they are.
fn settle_tiff(path: &Path, format: DepthFormat, limits: &Limits) -> Result<DepthFormat> {
    if !matches!(format, DepthFormat::Tiff | DepthFormat::TiffF32) {
        return Ok(format);
    }
    match tiff_samples(path, limits)? {
        TiffSamples::FloatGrey(_) => Ok(DepthFormat::TiffF32),
        TiffSamples::Other if format == DepthFormat::TiffF32 => Err(IoError::UnsupportedImage {
            path: path.to_path_buf(),
            found: "a TIFF that is not single-channel floating point".into(),
            expected: "float depth (tiff-f32); a 16-bit TIFF is read as tiff".into(),
        }),
        TiffSamples::Other => Ok(DepthFormat::Tiff),
    }
}

/// Reads a floating-point TIFF into metres: `v / units_per_m` (metres unless a scale is
/// given); 0, negative, NaN and infinite values are no depth.
fn read_float_depth(path: &Path, options: &ReadConfig, limits: &Limits) -> Result<LoadedDepth> {
    let encoding = DepthEncoding::tiff_f32(options.scale_units_per_m.unwrap_or(FLOAT_UNITS_PER_M));
    encoding.validate(path)?;
    let values = decode_float_grey(path, limits)?;
    let (w, h) = values.dimensions();
    let s = encoding.units_per_m;
    let data = values
        .data()
        .iter()
        .map(|&v| float_units_to_m(v, s))
        .collect();
    Ok(LoadedDepth {
        depth: DepthImage::from_image(rebuild(w, h, data)),
        encoding,
    })
}

/// Metres of one float sample at `units_per_m`; 0 (no depth) unless positive and finite, in
/// the file and in metres, and a normal `f32` in metres (no denormal depth).
pub(crate) fn float_units_to_m(v: f32, units_per_m: f64) -> f32 {
    let m = (f64::from(v) / units_per_m) as f32;
    if v > 0.0 && v.is_finite() && m >= f32::MIN_POSITIVE && m.is_finite() {
        m
    } else {
        0.0
    }
}

/// Reads the stored integer values of a depth file (see [`RawDepth`]).
pub fn read_raw_depth(path: impl AsRef<Path>, options: &ReadConfig) -> Result<RawDepth> {
    read_raw_depth_with_limits(path, options, &Limits::default())
}

/// [`read_raw_depth`] within `limits`: the image size is checked from the header, before
/// anything is decoded.
pub fn read_raw_depth_with_limits(
    path: impl AsRef<Path>,
    options: &ReadConfig,
    limits: &Limits,
) -> Result<RawDepth> {
    let path = path.as_ref();
    read_raw_in(
        path,
        file_format(path, options.format, limits)?,
        options,
        limits,
    )
}

/// The format `path` is read in ([`depth_format_of_file`]), a directory refused first: a
/// folder's name has no depth extension, and "cannot infer the format" would send the user
/// looking for a format option.
fn file_format(path: &Path, format: Option<DepthFormat>, limits: &Limits) -> Result<DepthFormat> {
    if path.is_dir() {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            message: "is a directory, not a depth file".into(),
        });
    }
    settle_tiff(path, resolve_format(path, format)?, limits)
}

/// [`read_raw_depth_with_limits`] of a file whose format is settled.
fn read_raw_in(
    path: &Path,
    format: DepthFormat,
    options: &ReadConfig,
    limits: &Limits,
) -> Result<RawDepth> {
    if format == DepthFormat::TiffF32 {
        return Err(IoError::UnsupportedImage {
            path: path.to_path_buf(),
            found: "floating-point TIFF depth".into(),
            expected: "a depth file of integer values (read_depth reads float TIFF depth)".into(),
        });
    }
    let mut encoding = DepthEncoding::for_format(format);
    match (format, options.scale_units_per_m) {
        (DepthFormat::NyuRaw, Some(_)) => {
            return Err(IoError::Format {
                path: path.to_path_buf(),
                message:
                    "a depth scale does not apply to nyu-raw files (they store Kinect disparity)"
                        .into(),
            });
        }
        (_, Some(s)) => encoding.units_per_m = s,
        (DepthFormat::Png | DepthFormat::Tiff, None) => {
            if let Some(s) = crate::sequence::depth_scale_of_file(path) {
                encoding.units_per_m = s;
            }
        }
        (_, None) => {}
    }
    encoding.validate(path)?;
    let values = match format {
        DepthFormat::Png | DepthFormat::Sun => decode_l16(path, Container::Png, limits)?,
        DepthFormat::Tiff | DepthFormat::TiffF32 => decode_l16(path, Container::Tiff, limits)?,
        DepthFormat::NyuRaw => read_nyu_raw_with_limits(path, limits)?,
    };
    let values = match format {
        DepthFormat::Sun => values.map(|v| v.rotate_right(3)),
        _ => values,
    };
    if format.has_scale() && values.data().contains(&INVALID_SENTINEL) {
        encoding.invalid_value = INVALID_SENTINEL;
    }
    Ok(RawDepth { values, encoding })
}

/// Reads a depth file into metres.
///
/// The format comes from `options.format` or the extension; the scale from
/// `options.scale_units_per_m` (default: 5000 for a frame of a TUM RGB-D folder, see
/// [`crate::sequence::depth_scale_of_file`]; else 1000). Non-16-bit or multi-channel images are rejected
/// with [`IoError::UnsupportedImage`]; decoding is bounded by [`crate::limits`].
pub fn read_depth(path: impl AsRef<Path>, options: &ReadConfig) -> Result<LoadedDepth> {
    read_depth_with_limits(path, options, &Limits::default())
}

/// [`read_depth`] within `limits` (see [`read_raw_depth_with_limits`]).
pub fn read_depth_with_limits(
    path: impl AsRef<Path>,
    options: &ReadConfig,
    limits: &Limits,
) -> Result<LoadedDepth> {
    let path = path.as_ref();
    let format = file_format(path, options.format, limits)?;
    if format == DepthFormat::TiffF32 {
        return read_float_depth(path, options, limits);
    }
    let RawDepth { values, encoding } = read_raw_in(path, format, options, limits)?;
    // `values` is already un-rotated for SUN: decode it as a plain PNG at the same scale.
    let plain = DepthEncoding {
        format: if encoding.format == DepthFormat::Sun {
            DepthFormat::Png
        } else {
            encoding.format
        },
        ..encoding
    };
    Ok(LoadedDepth {
        depth: plain.decode(&values),
        encoding,
    })
}

/// Writes `depth` (metres) in `encoding`, atomically.
///
/// Values are rounded to the nearest unit; invalid pixels (0, negative, NaN, infinite) are
/// stored as `encoding.invalid_value`. A valid depth that the encoding cannot hold (it would
/// round to 0 or exceed 65534 units, i.e. [`DepthEncoding::max_depth_m`]: 65535 is the
/// [`INVALID_SENTINEL`], which every reader takes for no depth) is an
/// [`IoError::DepthOutOfRange`] naming the pixel and the valid range — never a silent wrap.
/// To store integers as they are (65535 included), use [`write_raw_depth`].
pub fn write_depth(
    path: impl AsRef<Path>,
    depth: &DepthImage,
    encoding: &DepthEncoding,
) -> Result<()> {
    let path = path.as_ref();
    encoding.validate(path)?;
    check_writable_size(path, depth.width(), depth.height())?;
    if encoding.format == DepthFormat::TiffF32 {
        let s = encoding.units_per_m;
        let values: Vec<f32> = depth
            .data()
            .iter()
            .map(|&z| {
                let v = (f64::from(z) * s) as f32;
                if z > 0.0 && z.is_finite() && v.is_finite() {
                    v
                } else {
                    0.0
                }
            })
            .collect();
        return write_float_grey(path, depth.width(), depth.height(), &values);
    }
    let values = encoding.encode(path, depth)?;
    let (w, h) = (depth.width(), depth.height());
    match encoding.format {
        DepthFormat::Png | DepthFormat::Sun => write_png_l16(path, w, h, &values),
        DepthFormat::Tiff | DepthFormat::TiffF32 => write_tiff_l16(path, w, h, &values),
        DepthFormat::NyuRaw => write_nyu_pgm(path, w, h, &values),
    }
}

/// Writes the stored integers of a depth file as they are, atomically: the inverse of
/// [`read_raw_depth`] (`raw.values` as its [`RawDepth::values`] describes them; SUN values
/// are rotated back on write, NYU raw values written little-endian as NYU stores them).
///
/// Nothing is converted or refused for PNG, TIFF and SUN: every 16-bit value is written,
/// and a 0 or 65535 (the [`INVALID_SENTINEL`] 7-Scenes marks missing depth with) reads back
/// as no depth, whatever `raw.encoding.invalid_value` says. A `TiffF32` encoding is refused:
/// float depth has no integer values ([`write_depth`] writes it).
///
/// # Errors
/// The checks of [`write_depth`] on the encoding (its scale) and the image size; an NYU raw
/// value above 2047 (the Kinect's 11 bits; [`read_nyu_raw`] would refuse the file) is an
/// [`IoError::Format`] naming the pixel; file-system errors.
pub fn write_raw_depth(path: impl AsRef<Path>, raw: &RawDepth) -> Result<()> {
    let path = path.as_ref();
    raw.encoding.validate(path)?;
    let (w, h) = raw.values.dimensions();
    check_writable_size(path, w, h)?;
    let values = raw.values.data();
    match raw.encoding.format {
        DepthFormat::Png => write_png_l16(path, w, h, values),
        DepthFormat::Tiff => write_tiff_l16(path, w, h, values),
        DepthFormat::TiffF32 => Err(IoError::Format {
            path: path.to_path_buf(),
            message: "float TIFF depth has no integer values to write as they are \
                      (write_depth writes it)"
                .into(),
        }),
        DepthFormat::Sun => {
            let rotated: Vec<u16> = values.iter().map(|v| v.rotate_left(3)).collect();
            write_png_l16(path, w, h, &rotated)
        }
        DepthFormat::NyuRaw => {
            if let Some(i) = values.iter().position(|&v| v > NYU_INVALID_RAW) {
                return Err(IoError::Format {
                    path: path.to_path_buf(),
                    message: format!(
                        "raw value {} at pixel ({}, {}) is beyond the Kinect's 11 bits \
                         (0..={NYU_INVALID_RAW})",
                        values[i],
                        i % w,
                        i / w
                    ),
                });
            }
            write_nyu_pgm(path, w, h, values)
        }
    }
}

/// Reads the raw values of an NYU raw-disparity PGM.
///
/// NYU stores 16-bit values **little-endian** although the PGM specification says big-endian
/// (the toolbox applies `swapbytes` after `imread`). Raw Kinect values have 11 bits, so the byte
/// order is checked: if some little-endian value exceeds 2047 but every big-endian one fits, the
/// file was written spec-conformingly and is read big-endian; if neither fits it is rejected.
pub fn read_nyu_raw(path: impl AsRef<Path>) -> Result<Image<u16>> {
    read_nyu_raw_with_limits(path, &Limits::default())
}

/// [`read_nyu_raw`] within `limits`.
pub fn read_nyu_raw_with_limits(path: impl AsRef<Path>, limits: &Limits) -> Result<Image<u16>> {
    let path = path.as_ref();
    let (header, bytes) = read_pnm(path, limits)?;
    if header.kind != PnmKind::Gray || header.bytes_per_sample() != 2 {
        return Err(IoError::UnsupportedImage {
            path: path.to_path_buf(),
            found: format!(
                "{} PNM with maxval {}",
                if header.kind == PnmKind::Gray {
                    "grey"
                } else {
                    "colour"
                },
                header.maxval
            ),
            expected: "16-bit grey PGM (P5, maxval > 255) of raw Kinect disparity".into(),
        });
    }
    let le: Vec<u16> = bytes
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let values = if le.iter().all(|&v| v <= NYU_INVALID_RAW) {
        le
    } else {
        let be: Vec<u16> = le.iter().map(|v| v.swap_bytes()).collect();
        if be.iter().all(|&v| v <= NYU_INVALID_RAW) {
            be
        } else {
            return Err(IoError::malformed(
                path,
                "values exceed the 11-bit Kinect range (0..=2047) in either byte order: not a raw Kinect disparity file (.pgm is read as NYU raw disparity; store depth in 16-bit PNG or TIFF)",
            ));
        }
    };
    Image::from_vec(header.width, header.height, values).map_err(|e| IoError::core(path, None, e))
}

fn write_nyu_pgm(path: &Path, width: usize, height: usize, values: &[u16]) -> Result<()> {
    let mut bytes = Vec::with_capacity(32 + values.len() * 2);
    bytes.extend_from_slice(format!("P5\n{width} {height}\n65535\n").as_bytes());
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    write_atomic(path, |w| w.write_all(&bytes))
}

/// NYU raw values to metres: `351.3 / (1092.5 − raw)`, 0 for `raw ≥ 1093` (incl. 2047).
pub fn nyu_raw_to_depth(raw: &Image<u16>) -> DepthImage {
    let (w, h) = raw.dimensions();
    DepthImage::from_image(rebuild(
        w,
        h,
        raw.data().iter().map(|&v| nyu_raw_value_to_m(v)).collect(),
    ))
}

/// NYU raw values to disparity in pixels with the ROS kinect model `D_px = (doff − raw) / 8`;
/// raw values at or beyond `doff` (incl. 2047) are invalid (0).
///
/// With `doff =` [`NYU_DOFF`] (1092.5), `Z = f·B / D_px` with `f·B =` [`NYU_FB_PX_M`]
/// (351.3 / 8 = 43.9125 px·m) reproduces the NYU toolbox depth exactly; [`nyu_sensor_model`]
/// packages that `f·B`. The ROS `kinect_calibration` default `doff` is about 1090.
pub fn nyu_raw_to_disparity(raw: &Image<u16>, doff: f64) -> DisparityImage {
    let (w, h) = raw.dimensions();
    let steps = f64::from(KINECT_RAW_STEPS_PER_PX);
    let data = raw
        .data()
        .iter()
        .map(|&v| {
            let d = (doff - f64::from(v)) / steps;
            if v != NYU_INVALID_RAW && d > 0.0 {
                d as f32
            } else {
                0.0
            }
        })
        .collect();
    DisparityImage::from_image(rebuild(w, h, data))
}

/// The NYU Depth v2 depth camera (toolbox `camera_params.m`): 640×480, fx 582.62, fy 582.69,
/// cx 313.04, cy 238.44 — the `nyu-v2` preset of [`sl_core::preset`].
pub fn nyu_intrinsics() -> Intrinsics {
    nyu_preset().intrinsics()
}

/// The sensor model implied by the NYU constants (the `nyu-v2` preset): focal length fx of
/// [`nyu_intrinsics`], baseline `NYU_FB_PX_M / fx` (≈ 0.07537 m) so that `f·B = 43.9125` px·m,
/// 8 sub-pixel steps, the default σ_D.
pub fn nyu_sensor_model() -> SensorModel {
    nyu_preset().sensor()
}

fn nyu_preset() -> &'static sl_core::SensorPreset {
    // The preset table is a constant of sl-core; its tests check this entry exists.
    sl_core::preset::PRESETS
        .iter()
        .find(|p| p.name == "nyu-v2")
        .unwrap_or(&sl_core::preset::KINECT_V1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize, scale: f32) -> DepthImage {
        DepthImage::from_image(Image::from_fn(w, h, |x, y| {
            if (x + y) % 7 == 0 {
                0.0
            } else {
                (1 + x + w * y) as f32 * scale
            }
        }))
    }

    /// A path without a depth extension: missing, the error says so; present, it asks for the
    /// format.
    #[test]
    fn a_missing_path_is_said_missing_not_unknown() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("frame_0001");
        let e = read_depth(&missing, &ReadConfig::default()).unwrap_err();
        assert!(
            matches!(&e, IoError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
            "{e}"
        );
        std::fs::write(&missing, b"depth").unwrap();
        let e = read_depth(&missing, &ReadConfig::default()).unwrap_err();
        assert!(
            e.to_string().contains("cannot infer the depth format"),
            "{e}"
        );
    }

    #[test]
    fn format_names_and_extensions() {
        for (f, name) in DepthFormat::ALL.iter().zip(DepthFormat::NAMES) {
            assert_eq!(name.parse::<DepthFormat>().unwrap(), *f);
            assert_eq!(f.to_string(), name);
        }
        assert_eq!("TIF".parse::<DepthFormat>().unwrap(), DepthFormat::Tiff);
        assert!("jpeg".parse::<DepthFormat>().is_err());
        assert_eq!(
            DepthFormat::from_path(Path::new("a/b.PNG")),
            Some(DepthFormat::Png)
        );
        assert_eq!(
            DepthFormat::from_path(Path::new("b.tif")),
            Some(DepthFormat::Tiff)
        );
        assert_eq!(
            DepthFormat::from_path(Path::new("b.tiff")),
            Some(DepthFormat::Tiff)
        );
        assert_eq!(
            DepthFormat::from_path(Path::new("b.pgm")),
            Some(DepthFormat::NyuRaw)
        );
        assert_eq!(DepthFormat::from_path(Path::new("b.jpg")), None);
        assert_eq!(DepthFormat::from_path(Path::new("noext")), None);
    }

    /// A PNG in a TUM folder's `depth` folder (beside `depth.txt` or `associations.txt`) is
    /// read at TUM's 5000 units per metre unless a scale is given; the same file elsewhere, or
    /// in a `depth` folder of a folder that is no TUM sequence, at 1000.
    #[test]
    fn a_tum_folders_frame_is_read_at_its_scale() {
        let dir = tempfile::tempdir().unwrap();
        let seq = dir.path().join("rgbd_dataset_freiburg1_xyz");
        std::fs::create_dir_all(seq.join("depth")).unwrap();
        let frame = seq.join("depth").join("1.png");
        let depth = DepthImage::from_image(Image::from_vec(2, 1, vec![0.0f32, 1.0]).unwrap());
        write_depth(&frame, &depth, &DepthEncoding::png(5000.0)).unwrap();
        let read = |opts: &ReadConfig| read_depth(&frame, opts).unwrap();
        // No depth.txt yet: not a TUM folder.
        assert_eq!(read(&ReadConfig::default()).depth.data()[1], 5.0);
        for index in ["depth.txt", "associations.txt"] {
            std::fs::write(seq.join(index), "").unwrap();
            let loaded = read(&ReadConfig::default());
            assert_eq!(loaded.encoding.units_per_m, 5000.0, "{index}");
            assert_eq!(loaded.depth.data()[1], 1.0, "{index}");
            assert_eq!(
                read(&ReadConfig::default().with_scale(1000.0)).depth.data()[1],
                5.0
            );
            std::fs::remove_file(seq.join(index)).unwrap();
        }
    }

    /// A PNG in a SUN RGB-D sample's `depth` or `depth_bfx` folder (beside `intrinsics.txt`
    /// and `image/`) is read as SUN's bit-rotated millimetres without a format; the same file
    /// elsewhere as a plain PNG, eight times too deep.
    #[test]
    fn a_sun_samples_frame_is_read_as_sun() {
        let dir = tempfile::tempdir().unwrap();
        let sample = dir.path().join("NYU0001");
        for sub in ["depth", "depth_bfx", "image"] {
            std::fs::create_dir_all(sample.join(sub)).unwrap();
        }
        let depth = DepthImage::from_image(Image::from_vec(2, 1, vec![0.0f32, 1.5]).unwrap());
        for sub in ["depth", "depth_bfx"] {
            let frame = sample.join(sub).join("NYU0001.png");
            write_depth(&frame, &depth, &DepthEncoding::sun()).unwrap();
            let plain = read_depth(&frame, &ReadConfig::default()).unwrap();
            assert_eq!(
                plain.encoding.format,
                DepthFormat::Png,
                "no intrinsics.txt yet"
            );
            std::fs::write(
                sample.join("intrinsics.txt"),
                "518.9 0 284.6\n0 519.5 208.7\n0 0 1\n",
            )
            .unwrap();
            let sun = read_depth(&frame, &ReadConfig::default()).unwrap();
            assert_eq!(sun.encoding.format, DepthFormat::Sun);
            assert_eq!(sun.depth.data()[1], 1.5);
            let cam = crate::sequence::sun_camera(&sample, 561, 427).unwrap();
            assert_eq!(cam.intrinsics.fx, 518.9);
            std::fs::remove_file(sample.join("intrinsics.txt")).unwrap();
        }
    }

    #[test]
    fn a_directory_is_said_to_be_one() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["plain", "looks-like.png"] {
            let d = dir.path().join(name);
            std::fs::create_dir(&d).unwrap();
            let e = read_depth(&d, &ReadConfig::default())
                .unwrap_err()
                .to_string();
            assert!(e.contains("is a directory, not a depth file"), "{e}");
            assert!(!e.contains("cannot infer"), "{e}");
        }
    }

    #[test]
    #[allow(clippy::manual_rotate)] // the point is to spell out the toolbox's shifts
    fn sun_rotation_matches_toolbox() {
        // Toolbox: bitor(bitshift(v, -3), bitshift(v, 16 - 3)) on uint16.
        for v in [0u16, 1, 8, 0x1234, 0xfff8, 0xffff, 12345] {
            let toolbox = (v >> 3) | (v << 13);
            assert_eq!(v.rotate_right(3), toolbox);
            assert_eq!(toolbox.rotate_left(3), v);
        }
    }

    #[test]
    fn nyu_constants() {
        assert!((NYU_FB_PX_M - 43.9125).abs() < 1e-12);
        // Disparity model reproduces the toolbox depth.
        let raw = Image::from_vec(4, 1, vec![839u16, 1000, 2047, 1093]).unwrap();
        let z = nyu_raw_to_depth(&raw);
        let d = nyu_raw_to_disparity(&raw, NYU_DOFF);
        for i in 0..2 {
            let zt = 351.3 / (1092.5 - f64::from(raw.data()[i]));
            assert!((f64::from(z.data()[i]) - zt).abs() < 1e-6);
            assert!((NYU_FB_PX_M / f64::from(d.data()[i]) - zt).abs() < 1e-5);
        }
        assert_eq!(&z.data()[2..], &[0.0, 0.0]);
        assert_eq!(&d.data()[2..], &[0.0, 0.0]);
        let s = nyu_sensor_model();
        assert!((s.fb() - NYU_FB_PX_M).abs() < 1e-12);
    }

    #[test]
    fn encode_rejects_out_of_range() {
        let path = Path::new("x.png");
        let mut d = DepthImage::invalid(3, 2);
        d.data_mut()[4] = 14.0; // > 65534 / 5000 = 13.1068 m
        let err = DepthEncoding::tum().encode(path, &d).unwrap_err();
        match &err {
            IoError::DepthOutOfRange {
                x, y, max_depth_m, ..
            } => {
                assert_eq!((*x, *y), (1, 1));
                assert!((max_depth_m - 13.1068).abs() < 1e-9);
            }
            other => panic!("unexpected {other}"),
        }
        assert!(err.to_string().contains("13.1068"), "{err}");
        d.data_mut()[4] = 1e-5;
        assert!(DepthEncoding::default().encode(path, &d).is_err());
        d.data_mut()[4] = 0.1; // nearer than NYU's 0.32 m
        assert!(DepthEncoding::nyu_raw().encode(path, &d).is_err());
    }

    #[test]
    fn encode_decode_round_trip_all_formats() {
        let d = ramp(16, 8, 0.013);
        for enc in [
            DepthEncoding::png(1000.0),
            DepthEncoding::tum(),
            DepthEncoding::seven_scenes(),
            DepthEncoding::tiff(1000.0),
            DepthEncoding::sun(),
        ] {
            let v = enc.encode(Path::new("x"), &d).unwrap();
            let img = Image::from_vec(16, 8, v).unwrap();
            let plain = if enc.format == DepthFormat::Sun {
                img.map(|v| v.rotate_right(3))
            } else {
                img
            };
            let back = DepthEncoding {
                format: DepthFormat::Png,
                ..enc
            }
            .decode(&plain);
            for (a, b) in back.data().iter().zip(d.data()) {
                assert!(
                    (a - b).abs() <= 0.5 / enc.units_per_m as f32 + 1e-6,
                    "{enc}: {a} vs {b}"
                );
                assert_eq!(*a == 0.0, *b == 0.0);
            }
        }
    }

    #[test]
    fn invalid_values_validated() {
        let p = Path::new("x");
        assert!(
            DepthEncoding::png(1000.0)
                .with_invalid_value(7)
                .validate(p)
                .is_err()
        );
        assert!(DepthEncoding::png(0.0).validate(p).is_err());
        assert!(DepthEncoding::png(f64::NAN).validate(p).is_err());
        assert!(DepthEncoding::png(-5.0).validate(p).is_err());
        assert!(
            DepthEncoding::nyu_raw()
                .with_invalid_value(5)
                .validate(p)
                .is_err()
        );
        assert!(DepthEncoding::nyu_raw().validate(p).is_ok());
        assert!(DepthEncoding::seven_scenes().validate(p).is_ok());
    }
}
