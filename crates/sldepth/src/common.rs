//! Options and helpers shared by the subcommands: loading a depth map with its camera, saving
//! in the input's encoding, JSON output.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::builder::PossibleValuesParser;
use sl_core::{Camera, DepthImage};
use sl_io::depth::{DepthEncoding, DepthFormat, ReadOptions};

/// Input options common to every command that reads a depth map.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InputArgs {
    /// Camera: a preset name (`sldepth cameras` lists them: kinect-v1, tum-fr1, 7-scenes,
    /// nyu-v2, icl-nuim, primesense, d435, oak-d, ...) or a camera JSON file (Open3D
    /// `PinholeCameraIntrinsic` format: `width`, `height`, column-major `intrinsic_matrix`, with
    /// optional `baseline_m` (metres) and `subpixel` (disparity steps per pixel)). An existing
    /// file wins over a preset of the same name. Default: the `kinect-v1` preset (640x480,
    /// f = 580 px, c = (319.5, 239.5), B = 0.075 m, 1/8 px).
    #[arg(long, value_name = "NAME|FILE", global = true)]
    pub camera: Option<PathBuf>,
    /// Depth units per metre of 16-bit PNG/TIFF depth (1000 = millimetres, the default;
    /// 5000 = TUM RGB-D).
    #[arg(long, value_name = "UNITS_PER_M", global = true)]
    pub depth_scale: Option<f64>,
    /// Depth file format where the extension does not tell: `png`, `tiff`, `nyu-raw` (NYU raw
    /// Kinect disparity PGM), `sun` (SUN RGB-D bit-rotated PNG).
    #[arg(long, value_name = "FORMAT", global = true, value_parser = PossibleValuesParser::new(DepthFormat::NAMES))]
    pub format: Option<String>,
}

/// A depth map with the camera it was taken with and how it was stored.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// Depth in metres, 0 = invalid.
    pub depth: DepthImage,
    /// Camera (from `--camera`, or the `kinect-v1` preset).
    pub camera: Camera,
    /// The file's encoding, to write results back the same way.
    pub encoding: DepthEncoding,
}

/// The camera of `--camera` (a file, else a preset name), or the `kinect-v1` preset.
pub fn load_camera(args: &InputArgs) -> Result<Camera> {
    match &args.camera {
        Some(p) => camera_from_arg(p),
        None => Ok(Camera::kinect_v1()),
    }
}

/// A `--camera` value: an existing file is read as camera JSON; anything else must name a
/// preset (the error lists them, and says the file does not exist when it looks like a path).
pub fn camera_from_arg(value: &Path) -> Result<Camera> {
    if value.is_file() {
        return sl_io::camera::read_camera_json(value)
            .with_context(|| format!("reading camera {}", value.display()));
    }
    let name = value.to_string_lossy();
    Camera::preset(&name).map_err(|e| {
        let looks_like_file = name.contains('/') || name.ends_with(".json");
        if looks_like_file {
            anyhow::anyhow!("--camera {name}: no such file, and not a preset ({e})")
        } else {
            anyhow::anyhow!("--camera: {e}")
        }
    })
}

/// Parses `--format`.
pub fn parse_format(args: &InputArgs) -> Result<Option<DepthFormat>> {
    args.format
        .as_deref()
        .map(|s| s.parse::<DepthFormat>().map_err(|e| anyhow::anyhow!("{e}")))
        .transpose()
}

/// Reads a depth map with the options of `args` and checks it against the camera.
pub fn load_depth(path: &Path, args: &InputArgs) -> Result<Loaded> {
    if let Some(s) = args.depth_scale
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--depth-scale must be a positive number of units per metre, got {s}");
    }
    let format = parse_format(args)?;
    let opts = ReadOptions {
        format,
        scale_units_per_m: args.depth_scale,
    };
    let loaded = sl_io::depth::read_depth(path, &opts)?;
    let camera = match (&args.camera, loaded.encoding.format) {
        // NYU raw disparity comes with its own calibration (depth camera intrinsics and the
        // f·B of the NYU toolbox conversion), which is the right default for it.
        (None, DepthFormat::NyuRaw) => Camera {
            intrinsics: sl_io::depth::nyu_intrinsics(),
            sensor: sl_io::depth::nyu_sensor_model(),
        },
        _ => load_camera(args)?,
    };
    let k = &camera.intrinsics;
    if loaded.depth.width() != k.width || loaded.depth.height() != k.height {
        bail!(
            "{}: depth map is {}x{} but the camera is {}x{} (pass --camera with matching intrinsics)",
            path.display(),
            loaded.depth.width(),
            loaded.depth.height(),
            k.width,
            k.height
        );
    }
    Ok(Loaded {
        depth: loaded.depth,
        camera,
        encoding: loaded.encoding,
    })
}

/// Writes a depth map in the given encoding (atomically).
pub fn save_depth(path: &Path, depth: &DepthImage, encoding: &DepthEncoding) -> Result<()> {
    sl_io::depth::write_depth(path, depth, encoding)
        .with_context(|| format!("writing {}", path.display()))
}

/// Prints a JSON value on one line to standard output.
pub fn print_json(value: &serde_json::Value) -> Result<()> {
    outln!("{value}")?;
    Ok(())
}

/// Rounds to `digits` decimals for human-friendly JSON.
pub fn round_to(v: f64, digits: i32) -> f64 {
    let p = 10f64.powi(digits);
    (v * p).round() / p
}
