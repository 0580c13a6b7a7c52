//! `sldepth track`: where was the camera — track a raw depth recording (no poses given) with
//! `sl_track::Tracker`, fuse every tracked frame into a TSDF (1/Z⁴ weights) and write the
//! trajectory and, with `--mesh`, the mesh.
//!
//! Trajectory output (`--output`, TUM format `timestamp tx ty tz qx qy qz qw`, camera to
//! world): one line per input frame. A frame that could not be tracked gets a comment line
//! `# <timestamp> lost: <reason>` (an unreadable frame `# <timestamp> skipped: <reason>`)
//! instead of a pose — TUM tools skip comments, so a lost frame is missing from the
//! evaluation rather than given a wrong pose. Frames without timestamps (7-Scenes, Open3D
//! folders) use their index as the timestamp. The tracker is given the time between frames
//! (`Tracker::track_at`): TUM's timestamps, else one 1/30 s interval per frame of the folder.
//! `--output-log` writes the tracked frames as an Open3D `.log` (metadata `i i n`, `i` the
//! frame index; lost frames are left out and listed in the JSON).
//!
//! Fragments (`sl_track::Reconstruction`): when frames that could be aligned keep failing for
//! `--new-fragment-after-s` (default 1 s), the recording goes on in a new fragment with its own
//! volume and world frame (its first camera); when the camera comes back to the lost fragment,
//! tracking goes on there and the newer fragment is joined to it. One trajectory per world
//! frame: fragment 0's (with the fragments joined to it, moved into its frame) to the given
//! `--output` and `--output-log`, any other fragment's to the same names with `.fragment-k`
//! before the extension; each fragment's mesh to `--mesh` / `.fragment-k` (in the world of the
//! fragment it joined), written as soon as the fragment is handed over. In a trajectory the
//! frames of other worlds are comment lines `# <timestamp> in fragment <k>`; the JSON lists the
//! fragments.
//!
//! Frames whose size is the camera's divided by a whole number (320×240 for a 640×480 preset:
//! a QVGA stream, a driver's decimation) are tracked as that sensor decimated
//! (`common::camera_for_frames`, `Camera::resampled`: intrinsics scaled, the sensor's noise
//! model and block-matching window kept), with a note on standard error, as in every command
//! that reads depth. A camera JSON says the same with `sensor_focal_px`.

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use sl_core::{Camera, CameraToWorld, WorldToWorld};
use sl_filter::Prefilter;
use sl_io::depth::{ReadConfig, read_depth_with_limits};
use sl_io::sequence::SequenceFrame;
use sl_track::{Reconstruction, ReconstructionConfig, TrackStatus, WeightMode};
use sl_tsdf::{DepthLookup, MeshConfig, Truncation};

use crate::common::{
    InputArgs, LensArgs, camera_from_arg, check_depth_scale, check_output, check_range, limits,
    parse_format, print_json, round_to,
};

/// Options of `sldepth track`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A TUM RGB-D sequence folder as TUM ships it: `depth.txt` (or `associations.txt` when
    /// present) and the depth PNGs; the RGB images are not needed. Depth scale 5000 units/m
    /// and the `tum-fr1`, `tum-fr2` or `tum-fr3` camera, whichever the folder's name says
    /// (fr1 when it names none), unless given.
    #[arg(long, value_name = "DIR", group = "source")]
    pub tum: Option<PathBuf>,
    /// A 7-Scenes sequence folder (`frame-XXXXXX.depth.png`, millimetres; poses are not read);
    /// the `7-scenes` camera (fx = fy = 585, c = (320, 240)) unless given.
    #[arg(long = "7scenes", value_name = "DIR", group = "source")]
    pub seven_scenes: Option<PathBuf>,
    /// An Open3D-style folder: depth images in `DIR/depth` (sorted by name, numbers as numbers:
    /// `9.png` before `10.png`; millimetres unless --depth-scale) and an optional
    /// `DIR/camera.json`.
    #[arg(long, value_name = "DIR", group = "source")]
    pub o3d: Option<PathBuf>,
    /// Use only the first N frames.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// Trajectory output, TUM format (camera to world; lost frames as `#` comment lines).
    #[arg(long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Trajectory output, Open3D `.log` (tracked frames only).
    #[arg(long, value_name = "FILE")]
    pub output_log: Option<PathBuf>,
    /// Write the fused mesh (binary PLY) at the end.
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// Voxel edge of the fused volume, metres.
    #[arg(long, value_name = "M", default_value_t = 0.004)]
    pub voxel_m: f64,
    /// A fixed truncation band, metres. Default, as `sldepth fuse`: per observation
    /// max(5 voxels, 3·σ_Z(Z)) up to 12 cm (the sensor-adaptive band).
    #[arg(long, value_name = "M")]
    pub trunc_m: Option<f64>,
    /// Ignore depths beyond this for fusion, metres.
    #[arg(long, value_name = "M", default_value_t = 4.0)]
    pub max_depth_m: f64,
    /// Where a voxel reads the frame's depth, as for `sldepth fuse`: `nearest` (default) or
    /// `bilinear`. Bilinear fuses surfaces seen at grazing angles without a staircase (on a
    /// simulated corridor the model's normals no longer lean 4° towards the camera) but takes
    /// 1.6-2x as long to integrate, and the tracker's conditioning test was calibrated on
    /// nearest-pixel models (docs/bench/track.md, "Session 26").
    #[arg(long, value_name = "MODE", default_value = "nearest", value_parser = PossibleValuesParser::new(DepthLookup::NAMES).try_map(|s| s.parse::<DepthLookup>()))]
    pub depth_lookup: DepthLookup,
    /// Residual weighting of the tracker: `inv-var` (the sensor model's variance, default) or
    /// `uniform`.
    #[arg(long, value_name = "MODE", default_value = "inv-var")]
    pub weighting: String,
    /// Track each frame against the previous tracked frame instead of the fused model's
    /// raycast (frame-to-model, the default). Neither loses a frame of TUM fr1/rpy-200 or
    /// 7-Scenes; frame to frame is less accurate on TUM fr1/rpy-200 (ATE 3.08 against 2.86
    /// cm), more accurate on 7-Scenes (0.47 against 0.67 cm) and about half as costly per
    /// frame (docs/bench/track.md, sessions 33 and 57).
    #[arg(long)]
    pub frame_to_frame: bool,
    /// Render the fused model for tracking at this fraction of the camera's resolution, in
    /// (0, 1]. Default: one pixel per 4 pixels of the sensor along each axis (0.25 for a
    /// 640x480 Kinect, 0.5 for its 320x240 stream): the sensor resolves no detail finer than
    /// its ~9x11-pixel block-matching window; the raycast costs a small part of a
    /// full-resolution one with the same accuracy on TUM fr1/rpy and 7-Scenes
    /// (docs/bench/track.md); 1 renders at full resolution.
    #[arg(long, value_name = "FRACTION")]
    pub model_scale: Option<f64>,
    /// The finest pyramid level the tracker aligns: 0 = full resolution (default), 1 = half,
    /// 2 = quarter. Level 1 makes a step about 1.5x cheaper at the same accuracy on TUM
    /// fr1/rpy and 7-Scenes, but is 2-3x less accurate on simulated sequences with known poses
    /// (docs/bench/track.md).
    #[arg(long, value_name = "LEVEL", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=5))]
    pub finest_level: u8,
    /// Smooth every frame before tracking and fusing it: `multiscale` (default: the default
    /// filter of `sldepth filter` with its coarse passes 2 and 4 px apart, not its third 8 px
    /// apart, which cost frames at faster motion; it removes the spatially correlated error of
    /// real sensors: on 7-Scenes it lowers the frame-to-frame ATE from 1.30 to 0.73 cm,
    /// elsewhere the trajectories are as accurate as raw), `single` (the adaptive filter's single 7×7
    /// pass) or `none`. The range kernel follows each raw frame's measured noise (see
    /// `--model-noise-only`).
    #[arg(long, value_name = "FILTER", default_value = "multiscale", value_parser = PossibleValuesParser::new(Prefilter::NAMES).try_map(|s| s.parse::<Prefilter>()))]
    pub prefilter: Prefilter,
    #[command(flatten)]
    pub lens: LensArgs,
    /// The sensor's rolling-shutter readout time, milliseconds (first image row to last), or
    /// `auto` (default): the camera preset's readout when tracking against the fused model (30
    /// ms, an estimate, for the Kinect v1 / PrimeSense-class presets and the data sets they
    /// recorded: `--tum`, `--7scenes`; 0 for a camera JSON file, `icl-nuim` and the
    /// global-shutter active-stereo presets), 0 frame to frame (there it made TUM fr1/rpy-200's
    /// ATE worse, 3.19 → 3.69 cm). With a readout each row is aligned from its own pose on the
    /// constant-velocity path from the last tracked frame, frames are fused moved to the middle
    /// of their readout, and a pose is the camera's at that middle. 0: a global shutter. At most
    /// the frame interval (33.3 ms at 30 Hz). Frame to model on TUM fr1/rpy-200 (motion
    /// capture): RPE 5.1 → 4.5 mm and 0.65 → 0.60° per frame, ATE 2.80 → 2.83 cm, and every
    /// 2nd, 3rd or 4th frame alone (2–4× the motion) tracked with no frame lost (global
    /// shutter: 0, 4 and 4 lost since session 62's keyframes); on 7-Scenes, whose reference poses come from a
    /// global-shutter tracker, the ATE against them rises from 0.60 to 0.66 cm. It costs about
    /// 1–3 ms per frame (docs/bench/track.md, sessions 19, 20 and 44)
    #[arg(long, value_name = "MS|auto", default_value = "auto")]
    pub rolling_shutter_ms: String,
    /// No plane-based fallback when ICP fails.
    #[arg(long)]
    pub no_plane_fallback: bool,
    /// No relocalisation against keyframes (earlier frames kept at spread poses) when every
    /// other attempt fails: a lost camera is then only found again near its last good pose.
    /// With them, TUM fr1/rpy taken every 4th frame (up to 13° per step) loses no frame and
    /// stays one fragment (without: 7 lost, a second fragment; docs/bench/track.md, session 62).
    #[arg(long)]
    pub no_keyframes: bool,
    /// Track every frame with the camera's noise model as given. By default each raw frame's
    /// disparity noise is measured on its own 16×16- and 32×32-pixel patches (before the prefilter) and,
    /// when it is significantly larger than the model's, the frame is smoothed and tracked
    /// with it (the prefilter's range kernel, the tracker's weights, gates and degenerate-view
    /// checks): a sensor noisier than its preset or camera JSON says is otherwise smoothed too
    /// little and tracked with its uncertainty understated. The camera's σ_D is a floor.
    #[arg(long)]
    pub model_noise_only: bool,
    /// Instruction set of the tracker's and the fusion's inner loops, for benchmarks:
    /// `portable`, `avx2` or `avx512` (default: the widest this CPU supports; one it does not
    /// support falls back to the widest it does). Every choice gives the same trajectory and mesh, bit for bit. The
    /// prefilter's kernels always use the widest.
    #[arg(long, value_parser = ["portable", "avx2", "avx512"])]
    pub isa: Option<String>,
    /// Start a new fragment (its own volume, mesh and world frame: its first camera) after
    /// this many seconds of frames that could be aligned but were lost (the camera has left the
    /// place where tracking was lost); frames without depth or with a degenerate view do not
    /// count. When the camera comes back to the lost fragment, tracking goes on there and the
    /// newer fragment is joined to it (its poses go into the older one's trajectory). Fragment
    /// 0 goes to --output/--output-log/--mesh, fragment k to the same names with `.fragment-k`
    /// before the extension. `inf`: never.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub new_fragment_after_s: f64,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
    /// Print one diagnostic line per frame on standard error (residual, inliers,
    /// conditioning, the fallback taken).
    #[arg(long)]
    pub verbose: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

/// `--rolling-shutter-ms` in seconds: the number given, or with `auto` the readout of the
/// camera's preset (`--camera NAME`, else `implied`, the one the source implies) when tracking
/// against the model, else 0. Says so on standard error when it models one.
fn rolling_shutter_readout_s(args: &Args, implied: Option<&str>) -> Result<f64> {
    let value = args.rolling_shutter_ms.trim();
    if !value.eq_ignore_ascii_case("auto") {
        let ms: f64 = value.parse().map_err(|_| {
            anyhow::anyhow!("--rolling-shutter-ms must be `auto` or milliseconds, got {value:?}")
        })?;
        // The range is the tracker's to check (at most the frame interval).
        return Ok(ms / 1000.0);
    }
    if args.frame_to_frame {
        return Ok(0.0);
    }
    let Some(name) = crate::common::preset_name(&args.input, implied) else {
        return Ok(0.0);
    };
    let readout_s = sl_core::preset::find(&name).map_or(0.0, |p| p.rolling_shutter_readout_s);
    if readout_s > 0.0 {
        errln!(
            "note: modelling the `{name}` rolling shutter ({:.0} ms readout; --rolling-shutter-ms 0 for a global shutter)",
            readout_s * 1e3
        );
    }
    Ok(readout_s)
}

/// The files of the chosen source besides its depth frames, which no output may replace.
fn source_files(args: &Args) -> Vec<PathBuf> {
    let o3d_camera = args.o3d.as_ref().map(|d| d.join("camera.json"));
    crate::common::sequence_files(
        args.tum.as_deref(),
        args.seven_scenes.as_deref(),
        o3d_camera.into_iter().chain(args.input.camera.clone()),
    )
}

/// The frames, the camera and the default depth scale of the chosen source.
fn load_source(args: &Args) -> Result<(Vec<SequenceFrame>, Camera, f64)> {
    let lim = limits();
    let camera = |default_preset: &str, file: Option<PathBuf>| -> Result<Camera> {
        if let Some(c) = &args.input.camera {
            return camera_from_arg(c);
        }
        if let Some(p) = &file {
            crate::common::refuse_non_file("camera file", p)?;
        }
        match file {
            Some(p) if p.is_file() => {
                let is_json = p
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("json"));
                if is_json {
                    sl_io::camera::read_camera_json_with_limits(&p, &lim)
                } else {
                    sl_io::camera::read_camera(&p)
                }
                .with_context(|| format!("reading camera {}", p.display()))
            }
            _ => Ok(Camera::preset(default_preset)?),
        }
    };
    // A folder without a frame: an error naming the folder and what was looked for in it.
    if let Some(dir) = &args.tum {
        let frames = sl_io::sequence::read_tum_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            let assoc = dir.join("associations.txt");
            let (list, line) = if assoc.is_file() {
                (assoc, "RGB_TIME RGB_FILE DEPTH_TIME DEPTH_FILE")
            } else {
                (dir.join("depth.txt"), "TIME DEPTH_FILE")
            };
            bail!(
                "--tum {}: {} lists no depth frames (expected lines `{line}`)",
                dir.display(),
                list.display()
            );
        }
        Ok((frames, crate::common::tum_camera(dir, &args.input)?, 5000.0))
    } else if let Some(dir) = &args.seven_scenes {
        let frames = sl_io::sequence::read_7scenes_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            bail!(
                "--7scenes {}: no depth frames in the folder (expected 7-Scenes files named \
                 frame-NNNNNN.depth.png, e.g. frame-000000.depth.png)",
                dir.display()
            );
        }
        Ok((
            frames,
            camera("7-scenes", Some(dir.join("camera-intrinsics.txt")))?,
            1000.0,
        ))
    } else if let Some(dir) = &args.o3d {
        let frames = sl_io::sequence::read_open3d_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            let sub = dir.join("depth");
            bail!(
                "--o3d {}: no depth images in {} (expected .png, .tif, .tiff or .pgm files)",
                dir.display(),
                if sub.is_dir() { sub } else { dir.clone() }.display()
            );
        }
        Ok((
            frames,
            camera("kinect-v1", Some(dir.join("camera.json")))?,
            1000.0,
        ))
    } else {
        bail!("give the sequence with --tum DIR, --7scenes DIR or --o3d DIR")
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// One output row: a pose or why there is none.
enum Row {
    /// A pose in the world frame of the fragment.
    Pose(CameraToWorld, usize),
    Lost(String),
    Skipped(String),
}

/// The fragment whose world frame fragment `f`'s poses are written in, and the transform there.
fn world_of(f: usize, fragments: &[FragmentOut]) -> (usize, Option<WorldToWorld>) {
    match fragments.get(f).and_then(|o| o.joined) {
        Some(j) => (j.into, Some(j.transform)),
        None => (f, None),
    }
}

/// The pose of a row of fragment `f` in the world of fragment `world`, if it belongs there.
fn pose_in(
    p: &CameraToWorld,
    f: usize,
    world: usize,
    fragments: &[FragmentOut],
) -> Option<CameraToWorld> {
    match world_of(f, fragments) {
        (w, t) if w == world => Some(t.map_or(*p, |t| t * *p)),
        _ => None,
    }
}

/// The TUM trajectory in fragment `world`'s frame: its poses and those of the fragments that
/// rejoined it, the other frames as comments.
fn tum_text(rows: &[(f64, Row)], world: usize, fragments: &[FragmentOut]) -> String {
    let mut s = String::from("# sldepth track: timestamp tx ty tz qx qy qz qw (camera to world)\n");
    if world > 0 {
        let _ = writeln!(
            s,
            "# fragment {world}: its own world frame (its first camera); not registered to the other fragments"
        );
    }
    // Timestamps closer than a microsecond keep enough digits to stay distinct (the file is
    // read back by `eval-traj`, which refuses a repeated timestamp).
    let stamps: Vec<f64> = rows.iter().map(|(t, _)| *t).collect();
    let stamp = sl_io::trajectory::timestamp_printer(&stamps);
    for (t, row) in rows {
        let t = stamp(*t);
        match row {
            Row::Pose(p, f) => match pose_in(p, *f, world, fragments) {
                None => {
                    let _ = writeln!(s, "# {t} in fragment {f}");
                }
                Some(p) => {
                    let tr = p.translation();
                    let q = p.rotation();
                    let _ = writeln!(
                        s,
                        "{t} {:.6} {:.6} {:.6} {:.7} {:.7} {:.7} {:.7}",
                        tr.x, tr.y, tr.z, q.i, q.j, q.k, q.w
                    );
                }
            },
            Row::Lost(why) => {
                let _ = writeln!(s, "# {t} lost: {why}");
            }
            Row::Skipped(why) => {
                let _ = writeln!(s, "# {t} skipped: {why}");
            }
        }
    }
    s
}

/// The Open3D `.log` of the tracked frames in fragment `world`'s frame.
fn log_text(rows: &[(f64, Row)], world: usize, fragments: &[FragmentOut]) -> String {
    let n = rows.len();
    let mut s = String::new();
    for (i, (_, row)) in rows.iter().enumerate() {
        if let Row::Pose(p, f) = row
            && let Some(p) = pose_in(p, *f, world, fragments)
        {
            let m = p.to_matrix();
            let _ = writeln!(s, "{i} {i} {n}");
            for r in 0..4 {
                let _ = writeln!(
                    s,
                    "{:.9} {:.9} {:.9} {:.9}",
                    m[(r, 0)],
                    m[(r, 1)],
                    m[(r, 2)],
                    m[(r, 3)]
                );
            }
        }
    }
    s
}

/// The file of fragment `fragment`: `path` itself for fragment 0, else `stem.fragment-k.ext`.
fn fragment_path(path: &Path, fragment: usize) -> PathBuf {
    if fragment == 0 {
        return path.to_path_buf();
    }
    let stem = path.file_stem().map_or_else(
        || "output".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    let name = match path.extension() {
        Some(e) => format!("{stem}.fragment-{fragment}.{}", e.to_string_lossy()),
        None => format!("{stem}.fragment-{fragment}"),
    };
    path.with_file_name(name)
}

/// What the run did with one fragment.
struct FragmentOut {
    first_frame: usize,
    tracked: usize,
    /// The fragment it rejoined and the transform into that one's world.
    joined: Option<sl_track::FragmentJoin>,
    mesh: Option<WrittenMesh>,
    /// Frames fused into its volume.
    fused: usize,
    /// Its volume's blocks and their memory, bytes (what `--max-memory` bounds).
    blocks: usize,
    model_bytes: usize,
    /// The frame whose fusion found its model full (the memory budget reached).
    model_full_at: Option<usize>,
}

impl FragmentOut {
    fn starting_at(first_frame: usize) -> Self {
        Self {
            first_frame,
            tracked: 0,
            joined: None,
            mesh: None,
            fused: 0,
            blocks: 0,
            model_bytes: 0,
            model_full_at: None,
        }
    }

    fn finish(&mut self, done: &sl_track::Fragment, mesh: Option<WrittenMesh>) {
        self.tracked = done.tracked_frames;
        self.joined = done.joined;
        self.mesh = mesh;
        self.fused = done.volume.frame_count();
        self.blocks = done.volume.block_count();
        self.model_bytes = done.volume.memory_bytes();
    }
}

/// A fragment's mesh as written.
struct WrittenMesh {
    path: PathBuf,
    vertices: usize,
    triangles: usize,
}

/// Writes the mesh of a finished fragment (when `--mesh` was given). A mesh that cannot be
/// made or written (over the memory budget, a full disk) is said on standard error and kept
/// in `errors`: the run goes on, its trajectories are written, and it fails at the end.
fn write_fragment_mesh(
    args: &Args,
    fragment: &sl_track::Fragment,
    budget_bytes: usize,
    errors: &mut Vec<String>,
) -> Option<WrittenMesh> {
    match try_write_fragment_mesh(args, fragment, budget_bytes) {
        Ok(mesh) => mesh,
        Err(e) => {
            let e = format!("fragment {}'s mesh not written: {e:#}", fragment.index);
            errln!("error: {e}");
            errors.push(e);
            None
        }
    }
}

/// [`write_fragment_mesh`], failing.
fn try_write_fragment_mesh(
    args: &Args,
    fragment: &sl_track::Fragment,
    budget_bytes: usize,
) -> Result<Option<WrittenMesh>> {
    let Some(p) = &args.mesh else {
        return Ok(None);
    };
    let mut mesh = fragment
        .volume
        .extract_mesh_within(&MeshConfig::default(), budget_bytes)?;
    // A fragment that rejoined the one before is written in that one's world frame.
    if let Some(j) = &fragment.joined {
        mesh.transform(j.transform.isometry());
    }
    let path = fragment_path(p, fragment.index);
    sl_tsdf::io::write_mesh_ply(&path, &mesh, sl_io::ply::PlyFormat::BinaryLittleEndian)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(Some(WrittenMesh {
        path,
        vertices: mesh.vertex_count(),
        triangles: mesh.triangle_count(),
    }))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    sl_io::atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

/// Runs `sldepth track`.
pub fn run(args: Args) -> Result<()> {
    for (opt, path, exts) in [
        ("--output", &args.output, &["txt"][..]),
        ("--output-log", &args.output_log, &["log"][..]),
        ("--mesh", &args.mesh, &["ply"][..]),
    ] {
        if let Some(p) = path {
            check_output(opt, p, exts)?;
        }
    }
    check_range("--voxel-m", args.voxel_m, 1e-4..=1.0)?;
    if let Some(m) = args.model_scale {
        check_range("--model-scale", m, 1e-3..=1.0)?;
    }
    check_range("--max-depth-m", args.max_depth_m, 0.2..=100.0)?;
    if let Some(s) = args.input.depth_scale {
        check_depth_scale(s)?;
    }
    let weighting = WeightMode::parse(&args.weighting)?;
    let (mut frames, camera, default_scale) = load_source(&args)?;
    if let Some(n) = args.max_frames {
        frames.truncate(n);
    }
    if frames.is_empty() {
        // The source has frames (`load_source` refuses an empty one): --max-frames took them.
        bail!("--max-frames 0: no frame left to track (give 1 or more)");
    }
    crate::common::check_outputs_spare_inputs(
        &[
            ("--output", args.output.as_deref()),
            ("--output-log", args.output_log.as_deref()),
            ("--mesh", args.mesh.as_deref()),
        ],
        source_files(&args)
            .iter()
            .map(PathBuf::as_path)
            .chain(frames.iter().map(|f| f.depth_path.as_path())),
    )?;
    let mut read_opts = ReadConfig::default();
    read_opts.format = parse_format(&args.input)?;
    read_opts.scale_units_per_m = Some(args.input.depth_scale.unwrap_or(default_scale));
    // Frames a whole fraction of the camera's size are its sensor decimated; any other size
    // is reported per frame below. The first frame, read for its size, is not read again.
    let (camera, mut first_depth) = crate::common::camera_for_sequence(
        camera,
        frames.first().map(|f| f.depth_path.as_path()),
        &read_opts,
    );
    let k = camera.intrinsics;
    limits()
        .check_pixels(k.width as u64, k.height as u64)
        .map_err(|m| anyhow::anyhow!("camera: {m}"))?;
    // After the size check: the map holds one index per pixel.
    // The preset the source implies when no `--camera` is given: a TUM folder's, 7-Scenes', or
    // the `kinect-v1` default of an Open3D folder without `camera.json`.
    let implied = if let Some(dir) = &args.tum {
        Some(crate::common::tum_preset(dir))
    } else if args.seven_scenes.is_some() {
        Some("7-scenes")
    } else {
        args.o3d
            .as_ref()
            .filter(|dir| !dir.join("camera.json").is_file())
            .map(|_| "kinect-v1")
    };
    let undistort = crate::common::undistorter(&args.lens, &args.input, implied, &camera);
    let prefilter = args.prefilter;
    // A camera the prefilter cannot serve (a baseline or focal length so extreme that its range
    // kernel leaves the supported range) is the camera's fault, not every frame's: say so once,
    // before any frame is read.
    if let Some(f) = prefilter.filter_for(&camera.sensor) {
        f.validate().with_context(|| {
            format!(
                "--prefilter {} for this camera (f = {} px, B = {} m, sigma_d = {} px); --prefilter none skips it",
                prefilter.name(),
                crate::common::num(camera.sensor.focal_px),
                crate::common::num(camera.sensor.baseline_m),
                crate::common::num(camera.sensor.sigma_d_px)
            )
        })?;
    }
    if args.new_fragment_after_s.is_nan() || args.new_fragment_after_s <= 0.0 {
        bail!(
            "--new-fragment-after-s must be positive (inf: never), got {}",
            crate::common::num(args.new_fragment_after_s)
        );
    }
    let mut cfg = ReconstructionConfig::default_for(camera.sensor);
    cfg.tracker.weighting = weighting;
    cfg.tracker.plane_fallback = !args.no_plane_fallback;
    cfg.tracker.keyframe_relocalisation = !args.no_keyframes;
    cfg.tracker.estimate_noise = !args.model_noise_only;
    cfg.tracker.finest_level = usize::from(args.finest_level);
    cfg.tracker.rolling_shutter_readout_s = rolling_shutter_readout_s(&args, implied)?;
    if let Some(isa) = args.isa.as_deref().and_then(sl_core::Isa::from_name) {
        cfg.tracker.isa = isa;
        cfg.tsdf.isa = isa;
    }
    cfg.tsdf.voxel_m = args.voxel_m;
    cfg.tsdf.trunc_m = args.trunc_m.unwrap_or(5.0 * args.voxel_m);
    cfg.tsdf.truncation = match args.trunc_m {
        Some(_) => Truncation::Fixed,
        None => Truncation::sensor_adaptive(camera.sensor),
    };
    cfg.tsdf.max_depth_m = args.max_depth_m;
    cfg.tsdf.depth_lookup = args.depth_lookup;
    // The volume's share (`Limits::tsdf_budget_bytes`), so that the mesh of a full model fits
    // beside it at the end (`Limits::mesh_budget_bytes`).
    cfg.tsdf.memory_budget_bytes = limits().tsdf_budget_bytes;
    cfg.frame_to_model = !args.frame_to_frame;
    cfg.model_scale = args.model_scale;
    cfg.new_fragment_after_s = args
        .new_fragment_after_s
        .is_finite()
        .then_some(args.new_fragment_after_s);
    let params = cfg.tsdf;
    // The raw frames' noise against the camera's model (the prefilter hides it).
    let mut noise_meter = (!args.model_noise_only).then(|| cfg.tracker.noise_meter());
    let mut noise_scales = Vec::new();
    // The σ_D each frame was smoothed for (the prefilter follows the measured noise).
    let mut prefilter_sigmas = Vec::new();
    let mut rec = Reconstruction::new(camera, cfg)?;
    let mut raycast_ms = Vec::new();
    let mut step_ms = Vec::new();
    // Per frame read: its preparation (lens model, noise measurement, prefilter), and that
    // with the step (every stage of the pipeline but reading the file).
    let (mut prepare_ms, mut frame_ms) = (Vec::new(), Vec::new());
    let mut track_ms_tracked = Vec::new();

    let bar = indicatif::ProgressBar::new(frames.len() as u64);
    if !std::io::stderr().is_terminal() || args.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "tracking {bar:40} {pos}/{len} frames, {per_sec}, {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut rows: Vec<(f64, Row)> = Vec::with_capacity(frames.len());
    let (mut track_ms, mut integrate_ms) = (Vec::new(), Vec::new());
    let mut counts = [0usize; 6];
    let mut lost_frames = Vec::new();
    let mut skipped_frames = Vec::new();
    // Meshes that could not be written (the run goes on; it fails once the trajectories are).
    let mut mesh_errors: Vec<String> = Vec::new();
    // Per fragment: its first frame, and its mesh once written.
    let mut fragments: Vec<FragmentOut> = vec![FragmentOut::starting_at(0)];
    let wall = Instant::now();
    let debug = args.verbose;
    for (i, f) in frames.iter().enumerate() {
        let t = f.timestamp.unwrap_or(i as f64);
        let raw = match first_depth.take() {
            Some(d) => Ok(d),
            None => read_depth_with_limits(&f.depth_path, &read_opts, &limits())
                .map(|l| l.depth)
                .map_err(anyhow::Error::from),
        };
        // A frame of another size is a wrong camera, not an unreadable frame: the same error
        // whatever the layout, before the lens model or the prefilter would refuse it as a
        // skip.
        if let Ok(d) = &raw
            && (d.width() != k.width || d.height() != k.height)
        {
            bail!(
                "{}: depth map is {}x{} but the camera is {}x{} (every frame of a sequence has the camera's size; --camera names the camera)",
                f.depth_path.display(),
                d.width(),
                d.height(),
                k.width,
                k.height
            );
        }
        let prepared = Instant::now();
        let depth = match raw
            .and_then(|d| match &undistort {
                Some(u) => Ok(u.apply(&d)?),
                None => Ok(d),
            })
            .map(|d| {
                let scale = noise_meter
                    .as_mut()
                    .and_then(|m| m.measure(&d, &camera).ok());
                noise_scales.extend(scale);
                rec.set_noise_scale(scale);
                (d, scale.unwrap_or(1.0))
            })
            .and_then(|(d, scale)| {
                let sensor = camera.sensor.with_variance_scale(scale);
                if prefilter != Prefilter::Off {
                    prefilter_sigmas.push(sensor.sigma_d_px);
                }
                // The range kernel follows the frame's measured noise, as `sldepth filter`.
                Ok(prefilter.apply(&d, &sensor)?.unwrap_or(d))
            }) {
            Ok(d) => d,
            Err(e) => {
                errln!(
                    "warning: skipping frame {i} ({}): {e}",
                    f.depth_path.display()
                );
                skipped_frames.push(i);
                rows.push((t, Row::Skipped(e.to_string().replace('\n', " "))));
                bar.inc(1);
                continue;
            }
        };
        let prepare = prepared.elapsed().as_secs_f64() * 1e3;
        // The tracker is told how many frame intervals passed: from the timestamps of a TUM
        // recording (frames its driver dropped), else one per frame of the folder, so an
        // unreadable frame skipped above is a longer step rather than a surprise.
        let time_s = f
            .timestamp
            .unwrap_or(i as f64 * rec.config().tracker.frame_interval_s);
        let step = rec
            .step(&depth, Some(time_s))
            .with_context(|| format!("tracking {}", f.depth_path.display()))?;
        if step.fragment >= fragments.len() {
            fragments.push(FragmentOut::starting_at(i));
            errln!(
                "frame {i}: lost for over {} s, fragment {} starts",
                args.new_fragment_after_s,
                step.fragment
            );
        }
        if let Some(done) = &step.finished {
            // Meshed beside the volumes still held (the current fragment's and a suspended
            // one's), within the volume-and-mesh share.
            let budget = limits()
                .mesh_budget_bytes
                .saturating_sub(rec.memory_bytes());
            let mesh = write_fragment_mesh(&args, done, budget, &mut mesh_errors);
            if let Some(out) = fragments.get_mut(done.index) {
                out.finish(done, mesh);
            }
            if done.index > step.fragment {
                errln!(
                    "frame {i}: back in fragment {}; fragment {} ({} frames) rejoins it{}",
                    step.fragment,
                    done.index,
                    done.tracked_frames,
                    if done.joined.is_some() {
                        ""
                    } else {
                        " (no frame with a pose in both: kept in its own world frame)"
                    }
                );
            }
        }
        if let Some(why) = &step.model_full {
            errln!(
                "warning: frame {i}: fragment {}'s model is full, {why}: --max-memory, --voxel-m. Its next frames are tracked against the frame before and not fused; its mesh holds the frames before this one",
                step.fragment
            );
            if let Some(out) = fragments.get_mut(step.fragment) {
                out.model_full_at.get_or_insert(i);
            }
        }
        let r = step.result;
        let tm = step.timings;
        track_ms.push(tm.track_ms);
        counts[r.status as usize] += 1;
        if debug {
            errln!(
                "frame {i}: {} ovl {:.3} inl {:.3} rms {:.4} m ({:.2}σ) cond {:.2e} weakest σ {:.2} mm it {} {:.1} ms {}",
                r.status.as_str(),
                r.overlap_fraction,
                r.inlier_fraction,
                r.rms_m,
                r.rms_normalised,
                r.condition,
                r.weakest_sigma_m * 1e3,
                r.iterations,
                tm.track_ms,
                r.failure.as_deref().unwrap_or("")
            );
        }
        if r.status.is_tracked() {
            track_ms_tracked.push(tm.track_ms);
            integrate_ms.extend(tm.integrate_ms);
            raycast_ms.extend(tm.raycast_ms);
            rows.push((t, Row::Pose(r.pose, step.fragment)));
        } else {
            lost_frames.push(i);
            let why = r.failure.unwrap_or_default();
            rows.push((t, Row::Lost(why)));
        }
        step_ms.push(tm.step_ms);
        prepare_ms.push(prepare);
        frame_ms.push(prepare + tm.step_ms);
        bar.set_message(format!("{} lost", lost_frames.len()));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let wall_s = wall.elapsed().as_secs_f64();
    if !frames.is_empty() && skipped_frames.len() == frames.len() {
        bail!(
            "none of the {} frames could be read (each is named above); nothing was written",
            frames.len()
        );
    }

    // Each mesh within the volume-and-mesh share but what the fragments still to mesh hold.
    let left = rec.finish()?;
    let mut held: usize = left.iter().map(|f| f.volume.memory_bytes()).sum();
    let whole = limits().mesh_budget_bytes;
    for done in left {
        held -= done.volume.memory_bytes();
        let budget = whole.saturating_sub(held);
        let mesh = write_fragment_mesh(&args, &done, budget, &mut mesh_errors);
        if let Some(out) = fragments.get_mut(done.index) {
            out.finish(&done, mesh);
        }
    }
    // One trajectory per world frame: fragment 0's, and each fragment's that rejoined none.
    for (index, out) in fragments.iter().enumerate() {
        if out.joined.is_some() {
            continue;
        }
        if let Some(p) = &args.output {
            write_text(
                &fragment_path(p, index),
                &tum_text(&rows, index, &fragments),
            )?;
        }
        if let Some(p) = &args.output_log {
            write_text(
                &fragment_path(p, index),
                &log_text(&rows, index, &fragments),
            )?;
        }
    }
    // Tracked frames in no model: their fragment's model had reached the memory budget.
    let unfused_frames: usize = fragments
        .iter()
        .map(|f| f.tracked.saturating_sub(f.fused))
        .sum();
    // The JSON's vertex and triangle counts are fragment 0's (the whole run's when there is
    // one fragment).
    let mesh_size = fragments
        .first()
        .and_then(|f| f.mesh.as_ref())
        .map(|m| (m.vertices, m.triangles));
    let (tm, im) = (median(&track_ms), median(&integrate_ms));
    let median_or_null = |v: &[f64]| (!v.is_empty()).then(|| round_to(median(v), 3));
    if args.json {
        let fragments_json = fragments
            .iter()
            .enumerate()
            .map(|(index, f)| {
                let world = world_of(index, &fragments).0;
                serde_json::json!({
                    "index": index,
                    "first_frame": f.first_frame,
                    "tracked": f.tracked,
                    "fused": f.fused,
                    "blocks": f.blocks,
                    "model_bytes": f.model_bytes,
                    "model_full_at_frame": f.model_full_at,
                    "joined_into": f.joined.map(|j| j.into),
                    "world": world,
                    "output": args.output.as_ref().map(|p| fragment_path(p, world).display().to_string()),
                    "mesh": f.mesh.as_ref().map(|m| m.path.display().to_string()),
                    "vertices": f.mesh.as_ref().map(|m| m.vertices),
                })
            })
            .collect::<Vec<_>>();
        print_json(&serde_json::json!({
            "frames": frames.len(),
            "tracked": frames.len() - lost_frames.len() - skipped_frames.len(),
            "lost": lost_frames.len(),
            "lost_frames": lost_frames,
            "skipped": skipped_frames.len(),
            "skipped_frames": skipped_frames,
            // Tracked but not fused: their fragment's model had reached the memory budget.
            "unfused": unfused_frames,
            "recovered": counts[TrackStatus::Recovered as usize],
            "relocalised": counts[TrackStatus::Relocalised as usize],
            "tracked_against_frame": counts[TrackStatus::TrackedAgainstFrame as usize],
            "reference": if args.frame_to_frame { "frame" } else { "model" },
            "prefilter": args.prefilter.name(),
            // The median σ_D, disparity pixels, the frames were smoothed for: the camera's, or
            // a noisier frame's measured one (null without a prefilter).
            "prefilter_sigma_d_px_median": (!prefilter_sigmas.is_empty())
                .then(|| round_to(median(&prefilter_sigmas), 4)),
            "undistorted": undistort.is_some(),
            "rolling_shutter_ms": round_to(cfg.tracker.rolling_shutter_readout_s * 1e3, 3),
            // Null when no frame was tracked (nothing was raycast, tracked or fused).
            "raycast_ms_median": median_or_null(&raycast_ms),
            "step_ms_median": round_to(median(&step_ms), 3),
            // Per frame read: the lens model, the noise measurement and the prefilter; and
            // those with the step (the whole pipeline but reading the file).
            "prepare_ms_median": round_to(median(&prepare_ms), 3),
            "frame_ms_median": round_to(median(&frame_ms), 3),
            "weighting": weighting.name(),
            "keyframes": cfg.tracker.keyframe_relocalisation,
            // The instruction set the tracker's pass ran with (the fusion's loops use it when
            // it is AVX-512, else their portable code).
            "isa": cfg.tracker.isa.effective().name(),
            "track_ms_median": round_to(tm, 3),
            "track_ms_median_tracked": median_or_null(&track_ms_tracked),
            "integrate_ms_median": median_or_null(&integrate_ms),
            // The raw frames' pixel variance over the camera's model (1: within it).
            "noise_scale_median": (!noise_scales.is_empty()).then(|| round_to(median(&noise_scales), 3)),
            "noise_scaled_frames": noise_scales.iter().filter(|&&s| s > 1.0).count(),
            "wall_s": round_to(wall_s, 3),
            "voxel_m": params.voxel_m,
            "trunc_m": params.trunc_m,
            "truncation": params.truncation.name(),
            "depth_lookup": params.depth_lookup.name(),
            "vertices": mesh_size.map(|m| m.0),
            "triangles": mesh_size.map(|m| m.1),
            "fragments": fragments_json,
            "output": args.output.as_ref().map(|p| p.display().to_string()),
            "mesh": args.mesh.as_ref().map(|p| p.display().to_string()),
            "mesh_errors": mesh_errors,
        }))?;
    } else {
        errln!(
            "tracked {} of {} frames ({} lost, {} skipped); track {:.1} ms, integrate {:.1} ms per frame (median)",
            frames.len() - lost_frames.len() - skipped_frames.len(),
            frames.len(),
            lost_frames.len(),
            skipped_frames.len(),
            tm,
            im
        );
        if fragments.len() > 1 {
            errln!(
                "{} fragments (tracked frames: {:?}; rejoined: {:?})",
                fragments.len(),
                fragments.iter().map(|f| f.tracked).collect::<Vec<_>>(),
                fragments
                    .iter()
                    .enumerate()
                    .filter_map(|(k, f)| f.joined.map(|j| (k, j.into)))
                    .collect::<Vec<_>>()
            );
        }
        if unfused_frames > 0 {
            errln!(
                "{unfused_frames} tracked frames not fused: the model reached the memory budget (--max-memory)"
            );
        }
        let noisier: Vec<f64> = noise_scales.iter().copied().filter(|&s| s > 1.0).collect();
        if !noisier.is_empty() {
            errln!(
                "{} frames noisier than the camera's model (their median pixel variance ×{:.2}): tracked with their own noise",
                noisier.len(),
                median(&noisier)
            );
        }
    }
    if !mesh_errors.is_empty() {
        bail!(
            "{} (the trajectory and everything else were written)",
            mesh_errors.join("; ")
        );
    }
    Ok(())
}
