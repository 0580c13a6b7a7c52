//! Options and helpers shared by the subcommands: loading a depth map with its camera, saving
//! in the input's encoding, JSON output.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{Context, Result, bail};
use clap::builder::PossibleValuesParser;
use sl_core::{Camera, DepthImage};
use sl_io::Limits;
use sl_io::depth::{
    DEFAULT_UNITS_PER_M, DepthEncoding, DepthFormat, MAX_UNITS_PER_M, MIN_UNITS_PER_M, ReadConfig,
};

static LIMITS: OnceLock<Limits> = OnceLock::new();

/// Sets the limits of this run (from `--max-memory`); the first call wins.
pub fn set_limits(limits: Limits) {
    let _ = LIMITS.set(limits);
}

/// The limits of this run ([`Limits::default`] unless `--max-memory` was given).
pub fn limits() -> Limits {
    LIMITS.get().copied().unwrap_or_default()
}

/// Parses a byte count: digits with an optional K, M, G or T suffix (powers of 1024; `KiB`,
/// `MB`, ... are read the same way).
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    if unit.starts_with(['.', ',']) {
        return Err(format!(
            "{s:?}: a byte count is a whole number of units (1536M, not 1.5G)"
        ));
    }
    let n: u64 = num
        .parse()
        .map_err(|_| format!("{s:?} is not a byte count (e.g. 512M, 8G, 1073741824)"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err(format!("{s:?}: unknown unit (use K, M, G or T)")),
    };
    n.checked_mul(1u64 << shift)
        .ok_or_else(|| format!("{s:?} is too large"))
}

/// Parses `--max-memory`: a byte count ([`parse_bytes`]) of at least
/// [`sl_io::limits::MIN_MEMORY_BYTES`] (16 MiB: below it no frame could be read; refused, not
/// silently raised).
pub fn parse_memory(s: &str) -> std::result::Result<u64, String> {
    let n = parse_bytes(s)?;
    let min = sl_io::limits::MIN_MEMORY_BYTES;
    if n < min {
        return Err(format!(
            "{s:?} ({n} bytes) is below the minimum budget of {}M ({min} bytes)",
            min >> 20
        ));
    }
    Ok(n)
}

/// A number for a message, compact whatever its size: as Rust prints it (`0.04`, `-3`, `NaN`)
/// for magnitudes from 1e-4 to below 1e6, in scientific notation (`1e300`, `-2.5e-7`) beyond
/// them, where `{}` would print a `1e300` as a 301-digit decimal.
pub fn num<T>(v: T) -> String
where
    T: Copy + Into<f64> + std::fmt::Display + std::fmt::LowerExp,
{
    let a = v.into().abs();
    if a.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Checks a `--depth-scale` value: finite and within what a 16-bit depth file can mean.
pub fn check_depth_scale(s: f64) -> Result<()> {
    if !(MIN_UNITS_PER_M..=MAX_UNITS_PER_M).contains(&s) {
        bail!(
            "--depth-scale {}: must be between {} and {} units per metre \
             (1000 = millimetres, 5000 = TUM)",
            num(s),
            num(MIN_UNITS_PER_M),
            num(MAX_UNITS_PER_M)
        );
    }
    Ok(())
}

/// Checks a numeric option: finite and within `range` (inclusive), else an error naming the
/// option and the valid range (the numbers printed by [`num`]).
pub fn check_range(name: &str, v: f64, range: std::ops::RangeInclusive<f64>) -> Result<()> {
    if !range.contains(&v) {
        bail!(
            "{name} {}: must be a number from {} to {}",
            num(v),
            num(*range.start()),
            num(*range.end())
        );
    }
    Ok(())
}

/// Checks an output name before any work: its extension is one of `exts` (case-insensitive),
/// and it is a new name or an existing regular file (see `sl_io::atomic::check_output`).
pub fn check_output(option: &str, path: &Path, exts: &[&str]) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !exts.contains(&ext.as_str()) {
        bail!(
            "{option} {}: unknown output format {}; use a file name ending in {}",
            path.display(),
            if ext.is_empty() {
                "(no extension)".to_string()
            } else {
                format!(".{ext}")
            },
            exts.iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    sl_io::atomic::check_output(path).with_context(|| format!("{option} {}", path.display()))?;
    Ok(())
}

/// An existing file's identity: device and inode on Unix (hard links alike), the canonical
/// path elsewhere.
#[cfg(unix)]
fn file_identity(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt as _;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn file_identity(path: &Path) -> Option<PathBuf> {
    path.canonicalize().ok()
}

/// Refuses an output that is one of the command's inputs (the same file under any name or
/// hard link): written atomically, it would replace the input — a frame list turned into a
/// trajectory, a depth frame into a rendering — and the next run would read garbage.
pub fn check_outputs_spare_inputs<'a>(
    outputs: &[(&str, Option<&Path>)],
    inputs: impl IntoIterator<Item = &'a Path>,
) -> Result<()> {
    let existing: Vec<_> = outputs
        .iter()
        .filter_map(|(opt, p)| p.and_then(|p| file_identity(p).map(|id| (*opt, p, id))))
        .collect();
    if existing.is_empty() {
        return Ok(());
    }
    for input in inputs {
        let Some(id) = file_identity(input) else {
            continue;
        };
        if let Some((opt, path, _)) = existing.iter().find(|(_, _, o)| *o == id) {
            bail!(
                "{opt} {} is an input of this command ({}): writing it would replace the \
                 input; name another output file",
                path.display(),
                input.display()
            );
        }
    }
    Ok(())
}

/// The files a sequence command reads besides its depth frames: a TUM folder's lists and ground
/// truth, a 7-Scenes folder's poses and intrinsics, and `others` (a camera file, a frame list, a
/// log), none of which an output may replace.
pub fn sequence_files(
    tum: Option<&Path>,
    seven_scenes: Option<&Path>,
    others: impl IntoIterator<Item = PathBuf>,
) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = others.into_iter().collect();
    if let Some(dir) = tum {
        for n in [
            "depth.txt",
            "associations.txt",
            "groundtruth.txt",
            "rgb.txt",
        ] {
            files.push(dir.join(n));
        }
        // An ICL-NUIM folder's `*.gt.freiburg`, an ETH3D folder's calibration.
        files.push(sl_io::sequence::tum_ground_truth_of(dir));
        files.push(dir.join(sl_io::sequence::TUM_CALIBRATION_FILE));
    }
    if let Some(dir) = seven_scenes {
        // Its camera file, the scene's above it in 3DMatch's layout.
        files.extend(sl_io::sequence::camera_file_of(
            dir,
            sl_io::sequence::SequenceLayout::SevenScenes,
        ));
        if let Ok(entries) = std::fs::read_dir(dir) {
            files.extend(
                entries
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| {
                        p.file_name()
                            .and_then(|n| n.to_str())
                            .is_some_and(|n| n.ends_with(".pose.txt"))
                    }),
            );
        }
    }
    files
}

/// Checks that no two outputs of one command name the same file (`-o x.png --truth x.png` would
/// otherwise keep only the last one written). Names are compared after resolving their
/// directories, so `./x.png` and `x.png` are the same file; an unresolvable directory is left to
/// the write to report.
pub fn check_distinct_outputs(outputs: &[(&str, Option<&Path>)]) -> Result<()> {
    let key = |p: &Path| -> PathBuf {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        match (dir.canonicalize(), p.file_name()) {
            (Ok(d), Some(name)) => d.join(name),
            _ => p.to_path_buf(),
        }
    };
    let given: Vec<(&str, &Path, PathBuf)> = outputs
        .iter()
        .filter_map(|(opt, p)| p.map(|p| (*opt, p, key(p))))
        .collect();
    for (i, (opt_a, path_a, key_a)) in given.iter().enumerate() {
        if let Some((opt_b, _, _)) = given[i + 1..].iter().find(|(_, _, k)| k == key_a) {
            bail!(
                "{opt_a} and {opt_b} both name {}: give each output its own file",
                path_a.display()
            );
        }
    }
    Ok(())
}

/// Extensions of depth outputs.
pub const DEPTH_EXTS: [&str; 4] = ["png", "tif", "tiff", "pgm"];

/// The encoding to write a depth output in: the output's extension picks the container (a
/// `.png` keeps SUN RGB-D's bit rotation when the input had it), the rest (scale, invalid
/// value) follows `input`. A `.pgm` is NYU raw Kinect disparity, the one PGM depth encoding
/// there is: only a NYU raw input is written as one (any other would silently change from
/// depth units to disparity); a NYU raw input written as `.png` or `.tif` is in millimetres.
/// A float TIFF input written as `.tif` stays float at its scale, as `.png` becomes millimetres.
pub fn output_encoding(path: &Path, input: &DepthEncoding) -> Result<DepthEncoding> {
    let Some(format) = DepthFormat::from_path(path) else {
        bail!(
            "{}: unknown depth output format; use .png, .tif, .tiff or .pgm",
            path.display()
        );
    };
    Ok(match (format, input.format) {
        (DepthFormat::Png, DepthFormat::Png | DepthFormat::Sun) => *input,
        // A float TIFF input stays float (its scale, metres by default); a 16-bit one 16-bit.
        (DepthFormat::Tiff, DepthFormat::Tiff | DepthFormat::TiffF32) => *input,
        (DepthFormat::NyuRaw, DepthFormat::NyuRaw) => *input,
        (DepthFormat::NyuRaw, f) => bail!(
            "{}: a .pgm is written as NYU raw Kinect disparity, which only a NYU raw input keeps; \
             this input is {} depth at {} units per metre: name a .png or .tif output to write \
             it in its own encoding",
            path.display(),
            f.name(),
            num(input.units_per_m)
        ),
        // Integer files from disparity or float depth: millimetres.
        (f, DepthFormat::NyuRaw | DepthFormat::TiffF32) => DepthEncoding::for_format(f),
        (f, _) => DepthEncoding {
            format: f,
            ..*input
        },
    })
}

/// Input options common to every command that reads a depth map.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InputArgs {
    /// Camera: a preset name (`sldepth cameras` lists them: kinect-v1, tum-fr1, 7-scenes,
    /// nyu-v2, icl-nuim, primesense, d435, oak-d, ...) or a camera JSON file (Open3D
    /// `PinholeCameraIntrinsic` format: `width`, `height`, column-major `intrinsic_matrix`, with
    /// optional `baseline_m` (metres) and `subpixel` (disparity steps per pixel); Open3D's
    /// `PinholeCameraParameters` file is read for its `intrinsic` object), or a ROS camera
    /// calibration `.yaml` (`camera_calibration`'s file, or a `CameraInfo` message saved from
    /// `rostopic echo` / `ros2 topic echo`: its `K`, and its `plumb_bob` distortion undone by
    /// `--lens auto`, with the Kinect sensor model). An existing
    /// file wins over a preset of the same name. Default: for a frame of a sequence folder the
    /// folder's camera, as `track DIR` takes it (a TUM folder's preset or ETH3D's
    /// `calibration.txt`, a 7-Scenes frame's `camera-intrinsics.txt`, its own or its scene's as
    /// 3DMatch keeps it, an Open3D folder's `camera_intrinsic.json` and the like beside
    /// `depth/`); else the `kinect-v1` preset (640x480, f = 580 px, c = (319.5, 239.5),
    /// B = 0.075 m, 1/8 px).
    #[arg(long, value_name = "NAME|FILE", global = true)]
    pub camera: Option<PathBuf>,
    /// Depth units per metre of 16-bit PNG/TIFF depth (1000 = millimetres; 5000 = TUM RGB-D).
    /// Default: 5000 for a frame in the `depth` folder of a TUM folder (beside `depth.txt` or
    /// `associations.txt`; its camera is then the folder's TUM preset unless `--camera` is
    /// given) or with a `--camera tum-*` preset, else 1000; a sequence folder's own scale for
    /// `track` and `fuse`. A floating-point TIFF (ROS `32FC1`, OpenCV's float arrays) is read
    /// in metres unless this says otherwise.
    #[arg(long, value_name = "UNITS_PER_M", global = true)]
    pub depth_scale: Option<f64>,
    /// Depth file format where the extension does not tell: `png`, `tiff` (16-bit, or 32/64-bit
    /// float read as `tiff-f32`: a `.tif` is read by what it stores), `tiff-f32`, `nyu-raw`
    /// (NYU raw Kinect disparity PGM), `sun` (SUN RGB-D bit-rotated PNG; taken without it for a
    /// PNG in a SUN RGB-D sample's `depth` or `depth_bfx` folder, whose `intrinsics.txt` then
    /// gives the camera unless `--camera` is given).
    #[arg(long, value_name = "FORMAT", global = true, value_parser = PossibleValuesParser::new(DepthFormat::NAMES))]
    pub format: Option<String>,
}

/// A depth map with the camera it was taken with and how it was stored.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// Depth in metres, 0 = invalid.
    pub depth: DepthImage,
    /// Camera (from `--camera`; else a sequence folder's camera for its frames, NYU's
    /// calibration for NYU raw disparity, a SUN RGB-D sample's intrinsics, or the `kinect-v1`
    /// preset).
    pub camera: Camera,
    /// The preset the file's place implied without `--camera` (a TUM folder's, 7-Scenes'), for
    /// the lens model of `--lens auto` ([`undistorter`]'s `implied_preset`).
    pub implied_preset: Option<&'static str>,
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

/// The camera of a TUM RGB-D sequence folder: `--camera` when given, else the folder's own
/// `calibration.txt` (the ETH3D SLAM benchmark's `fx fy cx cy`, sized by its first depth frame),
/// else `icl-nuim-tum` for
/// one of ICL-NUIM's TUM-format folders (`sl_io::sequence::icl_nuim_tum_folder`), the `tum-fr2`
/// or `tum-fr3` preset when a component of the folder's path names `freiburg2` / `freiburg3` (as
/// TUM names its downloads, `rgbd_dataset_freiburg2_desk`), else `tum-fr1`, with a note on
/// standard error saying which. The three sensors' focal lengths differ by up to 3.5 %, enough
/// to misalign fused frames.
pub fn tum_camera(dir: &Path, args: &InputArgs) -> Result<Camera> {
    if args.camera.is_some() {
        return load_camera(args);
    }
    // Its own calibration (ETH3D): any camera, no preset.
    if sl_io::sequence::sensor_preset(dir, sl_io::sequence::SequenceLayout::Tum).is_none() {
        let (camera, _) =
            sl_io::sequence::sequence_camera(dir, sl_io::sequence::SequenceLayout::Tum, &limits())
                .with_context(|| format!("reading the camera of {}", dir.display()))?;
        errln!(
            "note: the camera of {} ({}x{}, fx {} px) for this folder, with the Kinect v1 sensor \
             model (--camera overrides it)",
            dir.join(sl_io::sequence::TUM_CALIBRATION_FILE).display(),
            camera.intrinsics.width,
            camera.intrinsics.height,
            num(camera.intrinsics.fx)
        );
        return Ok(camera);
    }
    let preset = sl_io::sequence::tum_preset_name(dir);
    let folder = if sl_io::sequence::icl_nuim_tum_folder(dir) {
        "ICL-NUIM TUM-format folder"
    } else {
        "TUM folder"
    };
    errln!("note: camera `{preset}` for this {folder} (--camera overrides it)");
    Ok(Camera::preset(preset)?)
}

/// The `--lens` option of the commands whose output is 3D geometry (`track`, `fuse`, `motion`,
/// `cloud`).
#[derive(clap::Args, Debug, Clone)]
pub struct LensArgs {
    /// Lens distortion: `auto` resamples every frame into the ideal pinhole image when the
    /// camera is a preset with published distortion (`tum-fr1`, `tum-fr2`: their depth is
    /// registered to the distorted colour image, which bends every surface by up to 6 % at
    /// the corners; nearest neighbour, depth values unchanged), `none` uses the frames as
    /// they are; also a ROS camera file's non-zero `plumb_bob` distortion (`--camera
    /// calib.yaml`). Cameras from a JSON file have no lens model.
    #[arg(long, value_name = "MODE", default_value = "auto", value_parser = ["auto", "none"])]
    pub lens: String,
}

/// The name of the camera preset in effect: `--camera NAME`, or `implied_preset` when no
/// `--camera` is given; `None` for a camera file or when nothing names one.
pub fn preset_name(input: &InputArgs, implied_preset: Option<&str>) -> Option<String> {
    match (&input.camera, implied_preset) {
        (Some(c), _) if c.is_file() => None,
        (Some(c), _) => Some(c.to_string_lossy().into_owned()),
        (None, p) => p.map(str::to_string),
    }
}

/// The undistortion map for `camera` under `--lens`: `Some` only with `--lens auto` and a camera
/// that is a preset with a non-zero lens model (`--camera NAME`, or `implied_preset` when no
/// `--camera` is given, as a TUM folder implies `tum-fr1`). Says so on standard error.
pub fn undistorter(
    lens: &LensArgs,
    input: &InputArgs,
    implied_preset: Option<&str>,
    camera: &Camera,
) -> Option<sl_core::Undistorter> {
    if lens.lens == "none" {
        return None;
    }
    // A ROS camera file's own plumb_bob distortion (an IR camera calibrated with
    // `camera_calibration`: its raw depth image is not rectified).
    if let Some(file) = input
        .camera
        .as_deref()
        .filter(|p| p.is_file() && sl_io::ros_camera::is_ros_camera_file(p))
    {
        let model = sl_io::ros_camera::read_ros_camera(file, &limits())
            .ok()?
            .lens?;
        errln!(
            "note: undistorting the depth with the plumb_bob model of {} (--lens none keeps it \
             as it is)",
            file.display()
        );
        return Some(sl_core::Undistorter::new(&camera.intrinsics, &model));
    }
    let name = preset_name(input, implied_preset)?;
    let model = sl_core::preset::find(&name)
        .ok()
        .and_then(|p| p.lens)
        .filter(|l| !l.is_zero())?;
    errln!(
        "note: undistorting the depth with the `{name}` lens model (--lens none keeps it as it is)"
    );
    Some(sl_core::Undistorter::new(&camera.intrinsics, &model))
}

/// Refuses a path that exists but is not a regular file (a directory, device, FIFO, socket or
/// a symbolic link loop) where a file is read: a camera file that is a directory must not be
/// passed over for a preset without a word.
pub fn refuse_non_file(what: &str, path: &Path) -> Result<()> {
    match (std::fs::metadata(path), std::fs::symlink_metadata(path)) {
        (Ok(m), _) if m.is_file() => Ok(()),
        (Ok(m), _) => bail!(
            "{what} {} exists but is not a regular file ({})",
            path.display(),
            if m.is_dir() {
                "a directory"
            } else {
                "a device, FIFO or socket"
            }
        ),
        // A link whose target is missing or loops.
        (Err(e), Ok(_)) => bail!(
            "{what} {} is a symbolic link that cannot be followed: {e}",
            path.display()
        ),
        (Err(_), Err(_)) => Ok(()),
    }
}

/// A `--camera` value: an existing file is read as camera JSON, or as a ROS camera calibration
/// (`.yaml`/`.yml`: `camera_calibration`'s file or a saved `CameraInfo` echo, the Kinect sensor
/// model with its intrinsics); anything else must name a preset (the error lists them, and
/// says the file does not exist when it looks like a path).
pub fn camera_from_arg(value: &Path) -> Result<Camera> {
    // A directory named like a preset (a folder `d435` of recordings) does not hide the preset;
    // any other name that exists but is no file is an error, not a silent preset lookup.
    let name = value.to_string_lossy();
    if sl_core::preset::find(&name).is_err() {
        refuse_non_file("--camera", value)?;
    }
    if value.is_file() && sl_io::ros_camera::is_ros_camera_file(value) {
        let ros = sl_io::ros_camera::read_ros_camera(value, &limits())
            .with_context(|| format!("reading camera {}", value.display()))?;
        return Camera::from_intrinsics(ros.intrinsics, None, None)
            .with_context(|| format!("reading camera {}", value.display()));
    }
    if value.is_file() {
        return sl_io::camera::read_camera_json_with_limits(value, &limits())
            .with_context(|| format!("reading camera {}", value.display()));
    }
    Camera::preset(&name).map_err(|e| {
        let looks_like_file = name.contains('/')
            || [".json", ".yaml", ".yml", ".txt"]
                .iter()
                .any(|e| name.ends_with(e));
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

/// The camera for frames of `width`×`height` taken by `camera`'s sensor: `camera` itself at its
/// own size; the same sensor decimated (`Camera::resampled`: intrinsics scaled, the sensor's
/// noise model kept) when the frames are its size divided by a whole number from 2 to 8 (a
/// QVGA stream of a VGA sensor, a driver's decimation), said in a note on standard error (once
/// per process: `motion` reads two frames); `None` for any other size.
pub fn camera_for_frames(camera: &Camera, width: usize, height: usize) -> Option<Camera> {
    static NOTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    let k = &camera.intrinsics;
    let (resampled, n) = camera.for_frames(width, height)?;
    if n == 1 {
        return Some(resampled);
    }
    if NOTED.swap(true, std::sync::atomic::Ordering::Relaxed) {
        return Some(resampled);
    }
    errln!(
        "note: the frames are 1/{n} of the camera's {}x{}: taken as the same sensor decimated by \
         {n} (intrinsics scaled, the sensor's noise model kept)",
        k.width,
        k.height
    );
    Some(resampled)
}

/// The camera for a sequence whose first frame is `first` ([`camera_for_frames`] at that
/// frame's size; `camera` unchanged when the frame cannot be read, which the caller reports at
/// the frame), and that frame's depth as read, so the caller need not read it again.
pub fn camera_for_sequence(
    camera: Camera,
    first: Option<&Path>,
    opts: &ReadConfig,
) -> (Camera, Option<DepthImage>) {
    let Some(depth) = first
        .and_then(|p| sl_io::depth::read_depth_with_limits(p, opts, &limits()).ok())
        .map(|l| l.depth)
    else {
        return (camera, None);
    };
    let camera = camera_for_frames(&camera, depth.width(), depth.height()).unwrap_or(camera);
    (camera, Some(depth))
}

/// The depth units per metre of the files of `--camera`'s preset when they are not the
/// millimetres every reader assumes (`tum-fr1/2/3`: 5000), so that `--camera tum-fr1` reads a
/// TUM frame as TUM stores it; `None` for other presets, camera files and no `--camera`.
pub fn preset_depth_scale(args: &InputArgs) -> Option<f64> {
    let name = args.camera.as_deref().filter(|p| !p.is_file())?;
    match sl_core::preset::find(&name.to_string_lossy())
        .ok()?
        .depth_units
    {
        sl_core::preset::DepthUnits::UnitsPerMetre(u) if u != DEFAULT_UNITS_PER_M => Some(u),
        _ => None,
    }
}

/// The scale a sequence's frames are read at without `--depth-scale`: `folder_default` (its
/// layout's), unless its first frame stores float depth, which is metres whatever scale the
/// folder's kind implies.
pub fn frames_default_scale(
    first: Option<&Path>,
    format: Option<DepthFormat>,
    folder_default: Option<f64>,
) -> Option<f64> {
    let float = first.is_some_and(|p| {
        matches!(
            sl_io::depth::depth_format_of_file(p, format),
            Ok(DepthFormat::TiffF32)
        )
    });
    if float {
        Some(sl_io::depth::FLOAT_UNITS_PER_M)
    } else {
        folder_default
    }
}

/// The camera of a frame read from the sequence folder `dir` (in `layout`) without `--camera`:
/// the one `sldepth track DIR` takes for the folder (`sl_io::sequence::sequence_camera`: its
/// camera file — ETH3D's `calibration.txt`, 7-Scenes' or 3DMatch's `camera-intrinsics.txt`, an
/// Open3D folder's `camera_intrinsic.json` and the like — else the preset of its sensor, a TUM
/// folder's by its name), and that preset, with a note on standard error, once per run, that
/// also names the scale the frame was read at (`encoding`: a TUM folder's 5000 unless
/// `--depth-scale` said otherwise; a float TIFF's metres).
fn folder_frame_camera(
    dir: &Path,
    layout: sl_io::sequence::SequenceLayout,
    encoding: &DepthEncoding,
) -> Result<(Camera, Option<&'static str>)> {
    use sl_io::sequence::SequenceLayout;
    static NOTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    let (camera, preset) = sl_io::sequence::sequence_camera(dir, layout, &limits())
        .with_context(|| format!("reading the camera of {}", dir.display()))?;
    if !NOTED.swap(true, std::sync::atomic::Ordering::Relaxed) {
        let which = match (sl_io::sequence::camera_file_of(dir, layout), preset) {
            (Some(file), _) if file.is_file() => format!(
                "the camera of its {} (fx {} px)",
                file.file_name().unwrap_or_default().to_string_lossy(),
                num(camera.intrinsics.fx)
            ),
            (_, Some(p)) => format!("camera `{p}`"),
            (_, None) => "its camera".into(),
        };
        let kind = match layout {
            SequenceLayout::Tum => "TUM",
            SequenceLayout::SevenScenes => "7-Scenes",
            _ => "Open3D-style",
        };
        let scale = match (encoding.format, encoding.units_per_m) {
            (DepthFormat::TiffF32, u) if u == sl_io::depth::FLOAT_UNITS_PER_M => {
                "read as float metres".to_string()
            }
            (DepthFormat::TiffF32, u) => {
                format!("read as float depth at {} units per metre", num(u))
            }
            (_, u) => format!("read at {} units per metre", num(u)),
        };
        errln!(
            "note: a frame of the {kind} folder {}: {which} (--camera overrides it), {scale}",
            dir.display(),
        );
    }
    Ok((camera, preset))
}

/// The camera of a SUN RGB-D sample's frame read without `--camera`: its `intrinsics.txt` at the
/// frame's size (`sl_io::sequence::sun_camera`), with a note on standard error, once per run.
fn sun_frame_camera(sample: &Path, depth: &DepthImage) -> Result<Camera> {
    static NOTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    let camera = sl_io::sequence::sun_camera(sample, depth.width(), depth.height())?;
    if !NOTED.swap(true, std::sync::atomic::Ordering::Relaxed) {
        errln!(
            "note: a frame of the SUN RGB-D sample {}: SUN's bit-rotated millimetres, the \
             camera of its intrinsics.txt (fx {} px) with the Kinect v1 sensor model \
             (--camera and --format override them)",
            sample.display(),
            num(camera.intrinsics.fx)
        );
    }
    Ok(camera)
}

/// Reads a depth map with the options of `args` and checks it against the camera (frames a
/// whole fraction of the camera's size are its sensor decimated, see [`camera_for_frames`]).
pub fn load_depth(path: &Path, args: &InputArgs) -> Result<Loaded> {
    if let Some(s) = args.depth_scale {
        check_depth_scale(s)?;
    }
    let format = parse_format(args)?;
    let mut opts = ReadConfig::default();
    opts.format = format;
    // Without --depth-scale: the file's place (a TUM folder: 5000, sl-io's rule), else the
    // --camera preset's files' scale.
    // A float TIFF (metres, unless --depth-scale says otherwise) takes no preset's scale.
    let scaled = args.depth_scale.is_none()
        && preset_depth_scale(args).is_some()
        && matches!(
            sl_io::depth::depth_format_of_file(path, format),
            Ok(DepthFormat::Png | DepthFormat::Tiff)
        );
    opts.scale_units_per_m = args
        .depth_scale
        .or_else(|| preset_depth_scale(args).filter(|_| scaled));
    let loaded = sl_io::depth::read_depth_with_limits(path, &opts, &limits())?;
    // A frame of a sequence folder (TUM, 7-Scenes, Open3D-style with a camera file) read
    // without --camera: the camera `sldepth track DIR` takes for that folder, and its preset.
    let place = match (&args.camera, loaded.encoding.format) {
        (None, DepthFormat::Png | DepthFormat::Tiff | DepthFormat::TiffF32) => {
            sl_io::sequence::sequence_folder_of_file(path)
        }
        _ => None,
    };
    let folder = match place {
        Some((dir, layout)) => Some(folder_frame_camera(dir, layout, &loaded.encoding)?),
        None => None,
    };
    let implied_preset = folder.and_then(|(_, preset)| preset);
    let mut preset_sensor = sensor_from_preset(args, place);
    let camera = match (&args.camera, loaded.encoding.format, folder) {
        // NYU raw disparity comes with its own calibration (depth camera intrinsics and the
        // f·B of the NYU toolbox conversion), which is the right default for it.
        (None, DepthFormat::NyuRaw, _) => Camera {
            intrinsics: sl_io::depth::nyu_intrinsics(),
            sensor: sl_io::depth::nyu_sensor_model(),
        },
        (None, _, Some((camera, _))) => camera,
        // A SUN RGB-D sample's frame: its own intrinsics.txt.
        (None, DepthFormat::Sun, None) => match sl_io::sequence::sun_folder_of_file(path) {
            Some(sample) => {
                preset_sensor = false;
                sun_frame_camera(sample, &loaded.depth)?
            }
            None => load_camera(args)?,
        },
        _ => load_camera(args)?,
    };
    let k = &camera.intrinsics;
    let Some(camera) = camera_for_frames(&camera, loaded.depth.width(), loaded.depth.height())
    else {
        bail!(
            "{}: depth map is {}x{} but the camera is {}x{} (pass --camera with matching intrinsics)",
            path.display(),
            loaded.depth.width(),
            loaded.depth.height(),
            k.width,
            k.height
        );
    };
    if args.depth_scale.is_none() && loaded.encoding.format != DepthFormat::NyuRaw {
        note_doubtful_depth_scale(
            path,
            &loaded.depth,
            args,
            loaded.encoding.units_per_m,
            preset_sensor.then_some(&camera.sensor),
        );
    }
    Ok(Loaded {
        depth: loaded.depth,
        camera,
        implied_preset,
        encoding: loaded.encoding,
    })
}

/// A note on standard error when a frame read without `--depth-scale` looks stored at another
/// scale than it was read at — the usual cause a TUM RGB-D file (5000 units per metre) read as
/// millimetres, whose surfaces would otherwise come out silently five times too far. Two
/// independent signs, the first that holds is said:
///
/// - its median depth lies outside the camera's range (the `--camera` preset's, else the
///   Kinect's 0.5–5 m);
/// - its depth steps (`sl_noise::analysis`, the paper's `ΔZ = Z²/(q·f·B)`) imply an `f·B` more
///   than [`SCALE_DOUBT_FACTOR`] times the camera's (`sensor`) or less than its inverse: depths
///   read at `k` times their scale imply `k·f·B`, however near the scene. This catches a
///   close-range recording read five times too deep, which stays inside the range. Only a frame
///   whose steps grow as `Z²` is judged so (rendered or filtered depth is not), and only
///   against a known sensor, a preset's or a camera JSON's stated one (`sensor` is `None`
///   otherwise, see [`sensor_from_preset`]): a camera file that gives intrinsics alone takes
///   the Kinect's baseline and 1/8-px steps, which would make a RealSense D4xx frame (1/32 px)
///   look 2.7–5 times too deep.
pub fn note_doubtful_depth_scale(
    path: &Path,
    depth: &sl_core::DepthImage,
    args: &InputArgs,
    units_per_m: f64,
    sensor: Option<&sl_core::SensorModel>,
) {
    let preset = args
        .camera
        .as_deref()
        .filter(|p| !p.is_file())
        .map(|p| p.to_string_lossy().into_owned())
        .unwrap_or_else(|| "kinect-v1".into());
    let Ok(p) = sl_core::preset::find(&preset).or_else(|_| sl_core::preset::find("kinect-v1"))
    else {
        return;
    };
    let hint = if units_per_m != DEFAULT_UNITS_PER_M {
        format!(
            " (read at {} units per metre; millimetre files need --depth-scale 1000)",
            num(units_per_m)
        )
    } else {
        " (TUM RGB-D files store 5000 units per metre)".to_string()
    };
    // Every 7th pixel is plenty for a median.
    let mut z: Vec<f32> = depth
        .data()
        .iter()
        .step_by(7)
        .copied()
        .filter(|&v| v > 0.0 && v.is_finite())
        .collect();
    if z.len() < 16 {
        return;
    }
    let mid = z.len() / 2;
    let median = f64::from(*z.select_nth_unstable_by(mid, f32::total_cmp).1);
    if median > p.max_depth_m || median < p.min_depth_m {
        // A camera file has no range of its own: the Kinect's is the yardstick then.
        let whose = match args.camera.as_deref().filter(|c| c.is_file()) {
            Some(file) => format!(
                "a Kinect-class camera's (`{}`, for {})",
                p.name,
                file.display()
            ),
            None => format!("the `{}` camera's", p.name),
        };
        errln!(
            "note: {}: median depth {median:.2} m, outside {whose} {}–{} m: is \
             --depth-scale right?{hint}",
            path.display(),
            p.min_depth_m,
            p.max_depth_m
        );
        return;
    }
    let Some(sensor) = sensor else {
        return;
    };
    if let Some(ratio) = doubtful_fb_ratio(depth, sensor) {
        let how = if ratio > 1.0 {
            format!("{ratio:.1} times too deep")
        } else {
            format!("{:.1} times too shallow", 1.0 / ratio)
        };
        errln!(
            "note: {}: its depth steps (which grow as Z²/(q·f·B)) imply f·B = {:.1} px·m against \
             the camera's {:.1}: the depths look {how}; is --depth-scale right?{hint}",
            path.display(),
            ratio * sensor.fb(),
            sensor.fb()
        );
    }
}

/// Whether the camera's sensor model (baseline, disparity sub-pixel steps) is known rather than
/// assumed: a `--camera` preset name, or without `--camera` the preset of the sequence folder
/// `folder` (its layout and camera file, `sl_io::sequence::camera_file_of`) when it has no
/// camera file, or the `kinect-v1` default; or a camera JSON (`--camera FILE`, a folder's
/// `camera_intrinsic.json`, ...) that states `baseline_m` and `subpixel`
/// (`sl_io::camera::camera_json_states_sensor`). Other camera files give the intrinsics alone,
/// the Kinect's sensor filled in.
pub fn sensor_from_preset(
    args: &InputArgs,
    folder: Option<(&Path, sl_io::sequence::SequenceLayout)>,
) -> bool {
    let stated = |f: &Path| {
        f.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
            && sl_io::camera::camera_json_states_sensor(f, &limits()).unwrap_or(false)
    };
    match &args.camera {
        Some(c) => !c.is_file() || stated(c),
        None => folder
            .and_then(|(dir, layout)| sl_io::sequence::camera_file_of(dir, layout))
            .filter(|f| f.is_file())
            .is_none_or(|f| stated(&f)),
    }
}

/// The frame's implied `f·B` over the camera's (`sl_noise::analysis::ResolutionAnalysis::fb_ratio`)
/// when it lies beyond [`SCALE_DOUBT_FACTOR`] either way; `None` when it does not, or when the
/// frame's depth is not quantised like the model's.
fn doubtful_fb_ratio(depth: &sl_core::DepthImage, sensor: &sl_core::SensorModel) -> Option<f64> {
    let ratio = sl_noise::analysis::analyze(depth, sensor)
        .ok()?
        .fb_ratio(sensor)?;
    (!(1.0 / SCALE_DOUBT_FACTOR..=SCALE_DOUBT_FACTOR).contains(&ratio)).then_some(ratio)
}

/// How far a frame's implied `f·B` may lie from its camera's before
/// [`note_doubtful_depth_scale`] doubts the scale: real frames at their scale give 0.89–1.12
/// times the camera's (calibration off by a few percent), a file read at another data set's
/// scale 5 times or a fifth. 2 leaves the first alone and catches any scale error of 2× or
/// more.
pub const SCALE_DOUBT_FACTOR: f64 = 2.0;

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

/// The camera of the sequence folder `dir` in `layout`: `--camera` when given, else the
/// folder's camera file or its layout's preset (`sl_io::sequence::sequence_camera`, the rule
/// Python's `sequence_camera` gives too). A camera file that is not a regular file is an error.
pub fn folder_camera(
    args: &InputArgs,
    dir: &Path,
    layout: sl_io::sequence::SequenceLayout,
) -> Result<Camera> {
    if args.camera.is_some() {
        return load_camera(args);
    }
    if let Some(p) = sl_io::sequence::camera_file_of(dir, layout) {
        refuse_non_file("camera file", &p)?;
    }
    let (camera, preset) = sl_io::sequence::sequence_camera(dir, layout, &limits())
        .with_context(|| format!("reading the camera of {}", dir.display()))?;
    // A folder without a camera file: say which preset stands in, as for a TUM folder.
    if layout == sl_io::sequence::SequenceLayout::Open3d
        && let Some(p) = preset
    {
        errln!(
            "note: camera `{p}` (Open3D's PrimeSenseDefault, as Open3D takes a folder without \
             intrinsics) for {}: no camera file in it (--camera overrides it)",
            dir.display()
        );
    }
    Ok(camera)
}

/// The layout of a sequence folder given without one (`sldepth track DIR`, `sldepth fuse DIR`):
/// what `sl_io::sequence::SequenceLayout::infer` reads from it, or why there is none.
pub fn sequence_layout(dir: &Path) -> Result<sl_io::sequence::SequenceLayout> {
    // (A recording is taken as one by the callers before they ask for a folder's layout.)
    if !dir.is_dir() {
        bail!(
            "{}: not a folder (give a sequence folder: TUM, 7-Scenes or Open3D-style)",
            dir.display()
        );
    }
    Ok(sl_io::sequence::SequenceLayout::infer(dir)?)
}

/// The frames of a recording's transforms, for messages: sorted, each escaped (a name may
/// hold control characters), at most 24 of them and how many more.
pub fn frame_list(tree: &sl_io::rosbag::TfTree) -> String {
    const SHOWN: usize = 24;
    let mut names: Vec<String> = tree
        .frames()
        .into_iter()
        .flat_map(|f| [f.frame, f.parent])
        .collect();
    names.sort();
    names.dedup();
    let more = names.len().saturating_sub(SHOWN);
    let mut list: Vec<String> = names
        .iter()
        .take(SHOWN)
        .map(|n| n.escape_debug().to_string())
        .collect();
    if more > 0 {
        list.push(format!("and {more} more"));
    }
    list.join(", ")
}

#[cfg(test)]
mod tests {
    use super::{doubtful_fb_ratio, num, parse_bytes};

    /// A close-range frame (0.6–1.0 m, disparity-quantised to 1/8 px, stored in whole units)
    /// read five times too deep stays inside the Kinect's range, but its depth steps imply five
    /// times the camera's f·B; read at its scale, or a fifth too shallow, it is judged right.
    #[test]
    fn a_frame_read_at_another_scale_is_told_by_its_depth_steps() {
        let sensor = sl_core::Camera::kinect_v1().sensor;
        let (w, h) = (320usize, 240usize);
        let frame = |units_per_m: f64, read_at: f64| {
            let data: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let z = 0.6 + 0.4 * (x / w as f64) + 0.05 * (y / h as f64);
                    let d = (sensor.fb() / z * 8.0).round() / 8.0;
                    ((sensor.fb() / d * units_per_m).round() / read_at) as f32
                })
                .collect();
            sl_core::DepthImage::from_vec(w, h, data).unwrap()
        };
        assert_eq!(doubtful_fb_ratio(&frame(1000.0, 1000.0), &sensor), None);
        assert_eq!(doubtful_fb_ratio(&frame(5000.0, 5000.0), &sensor), None);
        let deep = doubtful_fb_ratio(&frame(5000.0, 1000.0), &sensor).unwrap();
        assert!((deep - 5.0).abs() < 0.5, "{deep}");
        // Rounded to a fixed 1 mm step instead (filtered or rendered depth): not judged.
        let flat = sl_core::DepthImage::from_vec(
            w,
            h,
            (0..w * h)
                .map(|i| (3.0 + 0.001 * (i % 1500) as f64) as f32)
                .collect(),
        )
        .unwrap();
        assert_eq!(doubtful_fb_ratio(&flat, &sensor), None);
    }

    /// Whole numbers of bytes or of K, M, G, T (powers of 1024); a fraction says what to write.
    #[test]
    fn byte_counts_are_whole_numbers_of_units() {
        assert_eq!(parse_bytes(" 100M "), Ok(100 << 20));
        assert_eq!(parse_bytes("2GiB"), Ok(2 << 30));
        assert_eq!(parse_bytes("1073741824"), Ok(1 << 30));
        for fraction in ["1.5G", "0.5M", "1,5G"] {
            let e = parse_bytes(fraction).unwrap_err();
            assert!(e.contains("whole number") && e.contains("1536M"), "{e}");
        }
        assert!(parse_bytes("3X").unwrap_err().contains("unknown unit"));
    }

    #[test]
    fn numbers_in_messages_are_compact_at_any_size() {
        assert_eq!(num(0.04), "0.04");
        assert_eq!(num(-3.0), "-3");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(1e-4), "0.0001");
        assert_eq!(num(999_999.0), "999999");
        assert_eq!(num(1e6), "1e6");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(-1e300), "-1e300");
        assert_eq!(num(2.5e-7), "2.5e-7");
        assert_eq!(num(f64::NAN), "NaN");
        assert_eq!(num(f64::NEG_INFINITY), "-inf");
        // An `f32` option prints as the `f32` it was parsed into.
        assert_eq!(num(1e30_f32), "1e30");
    }
}
