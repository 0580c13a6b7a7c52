//! `sldepth track`: where was the camera — track a raw depth recording (no poses given) with
//! `sl_track::Tracker`, fuse every tracked frame into a TSDF (1/Z⁴ weights) and write the
//! trajectory and, with `--mesh`, the mesh.
//!
//! Trajectory output (`--output`, TUM format `timestamp tx ty tz qx qy qz qw`, camera to
//! world): one line per input frame. A frame that could not be tracked gets a comment line
//! `# <timestamp> lost: <reason>` (an unreadable frame `# <timestamp> skipped: <reason>`)
//! instead of a pose — TUM tools skip comments, so a lost frame is missing from the
//! evaluation rather than given a wrong pose. An Open3D-style folder whose file names are times
//! (`1305031102.160407.png`, or nanoseconds: `sl_io::trajectory::name_timestamp_s`) is stamped
//! with them; frames without timestamps (7-Scenes, and Open3D folders of frame numbers) use
//! their index as the timestamp. The tracker is given the time between frames
//! (`Tracker::track_at`): the frames' timestamps, else one 1/30 s interval per frame of the
//! folder.
//! `--output-log` writes the tracked frames as an Open3D `.log` (metadata `i i n`, `i` the
//! frame index; lost frames are left out and listed in the JSON).
//!
//! A TUM-layout folder that stamps its frames with their numbers
//! (`sl_io::sequence::tum_stamps_are_frame_numbers`) has them taken as one frame interval each.
//! One of ICL-NUIM's TUM-format folders (`sl_io::sequence::icl_nuim_tum_folder`) does, and
//! renders with the image y axis up: its trajectories and meshes are written in that frame
//! (`CameraToWorld::y_reflected`, `Mesh::reflect_y`), as its `*.gt.freiburg`, so they compare
//! with the data set's ground truth and meshes directly.
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

mod config;
mod fragments;
pub mod odometry;
mod prepare;
mod report;
mod source;
mod trajectory_text;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use sl_filter::Prefilter;
use sl_io::depth::ReadConfig;
use sl_track::{Reconstruction, WeightMode};
use sl_tsdf::DepthLookup;

use crate::common::{
    InputArgs, LensArgs, check_depth_scale, check_output, check_range, limits, parse_format,
};
use fragments::FragmentOut;
use prepare::FramePrep;
use report::Tally;
use trajectory_text::Row;

/// Options of `sldepth track`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The sequence folder, its layout read from what it holds: a TUM folder when it has
    /// `depth.txt` or `associations.txt` (as --tum), a 7-Scenes folder when it has
    /// `frame-*.depth.png` (as --7scenes), an Open3D-style folder when it has a `depth` folder
    /// (as --o3d). Or name the layout with one of those options. Or a robot recording, a ROS 1
    /// bag (`.bag`, or the folder of a recording's `rosbag record --split` pieces, NAME_0.bag,
    /// NAME_1.bag, ...), a ROS 2 bag in MCAP or SQLite (`.mcap`, `.db3`, or the bag's folder) or a
    /// RealSense recording (librealsense's `.bag` or `.db3`): its depth topic (--topic, else
    /// the one image topic holding depth: 16UC1 millimetres or 32FC1 metres), stamped with its
    /// images' header stamps (a RealSense recording's: the sensor's timestamps), with the
    /// camera of the `camera_info` topic beside it unless --camera is given (a RealSense
    /// recording's depth units, device and stereo baseline chosen as recorded).
    #[arg(value_name = "DIR|BAG", group = "source")]
    pub sequence: Option<PathBuf>,
    /// The depth topic of a ROS bag (`/camera/depth/image_raw`); by default the one image
    /// topic whose images hold depth.
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// Set from the source, not an option: the ROS bag given as the sequence.
    #[arg(skip)]
    pub bag: Option<PathBuf>,
    /// A TUM RGB-D sequence folder as TUM ships it: `depth.txt` (or `associations.txt` when
    /// present) and the depth PNGs; the RGB images are not needed. Depth scale 5000 units/m
    /// and the `tum-fr1`, `tum-fr2` or `tum-fr3` camera, whichever the folder's name says
    /// (fr1 when it names none), unless given. One of ICL-NUIM's TUM-format folders
    /// (associations depth first, frame numbers) takes the `icl-nuim-tum` camera, its frame
    /// numbers as frames 1/30 s apart, and gets its trajectory and mesh in its y-up frame.
    #[arg(long, value_name = "DIR", group = "source")]
    pub tum: Option<PathBuf>,
    /// A 7-Scenes sequence folder (`frame-XXXXXX.depth.png`, millimetres; poses are not read);
    /// the `7-scenes` camera (fx = fy = 585, c = (320, 240)) unless given.
    #[arg(long = "7scenes", value_name = "DIR", group = "source")]
    pub seven_scenes: Option<PathBuf>,
    /// An Open3D-style folder: depth images in `DIR/depth` (sorted by name, numbers as numbers:
    /// `9.png` before `10.png`; when every name is a time, `1305031102.2.png` or 19-digit
    /// nanoseconds, in time order and stamped with it; millimetres, float TIFF metres, unless
    /// --depth-scale) and an
    /// optional `DIR/camera.json` (or `camera_intrinsic.json`, `intrinsic.json`,
    /// `camera_primesense.json`, as Open3D's tools name it); without one, the camera Open3D
    /// takes for such a folder, `ros-default` (PrimeSenseDefault, 525 px).
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
    /// When a fragment's model reaches the memory budget (--max-memory): `continue` (default)
    /// goes on in a new fragment with a fresh volume in the same world frame (same trajectory,
    /// its mesh to the next `.fragment-k` name; meshes overlap where the camera came back),
    /// `stop-fusing` tracks the rest against the frame before and fuses nothing more. Either
    /// way, a fresh volume whose first frame alone needs more than the budget skips it and
    /// takes the next frame that fits.
    #[arg(long, value_name = "WHAT", default_value = "continue", value_parser = ["continue", "stop-fusing"])]
    pub when_model_full: String,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
    /// Print one diagnostic line per frame on standard error (residual, inliers,
    /// conditioning, the fallback taken).
    #[arg(long)]
    pub verbose: bool,
    /// Set from the source, not an option: the folder is one of ICL-NUIM's TUM-format archives,
    /// rendered with y up, so the trajectories and meshes are written in its frame
    /// (`sl_io::sequence::icl_nuim_tum_folder`).
    #[arg(skip)]
    pub data_y_up: bool,
    #[command(flatten)]
    pub odometry: odometry::OdometryArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth track`.
pub fn run(mut args: Args) -> Result<()> {
    source::resolve_layout(&mut args)?;
    check_args(&args)?;
    let weighting = WeightMode::parse(&args.weighting)?;
    if args.topic.is_some() && args.bag.is_none() {
        bail!("--topic names a topic of a ROS bag; the sequence is not one (give REC.bag)");
    }
    let (mut frames, camera, default_scale, mut bag) = match &args.bag {
        Some(path) => {
            let given = args
                .input
                .camera
                .as_deref()
                .map(crate::common::camera_from_arg)
                .transpose()?;
            let b = crate::recording::load(path, args.topic.as_deref(), given, "tracking")?;
            (
                b.frames,
                b.camera,
                b.default_scale,
                Some((b.reader, b.lens)),
            )
        }
        None => {
            let (frames, camera, scale) = source::load_source(&args)?;
            (frames, camera, scale, None)
        }
    };
    // Frames stamped with their numbers (ICL-NUIM's TUM-format folders, which render with y up).
    let frame_numbers = source::stamps_and_frame(&mut args);
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
        source::source_files(&args)
            .iter()
            .map(PathBuf::as_path)
            .chain(frames.iter().map(|f| f.depth_path.as_path())),
    )?;
    let mut odometry = odometry::load(
        &args,
        bag.as_mut().map(|(reader, _)| reader),
        frame_numbers,
        &frames,
    )?;
    let mut read_opts = ReadConfig::default();
    read_opts.format = parse_format(&args.input)?;
    let default_scale = crate::common::frames_default_scale(
        frames.first().map(|f| f.depth_path.as_path()),
        read_opts.format,
        Some(default_scale),
    )
    .unwrap_or(default_scale);
    read_opts.scale_units_per_m = Some(args.input.depth_scale.unwrap_or(default_scale));
    // Frames a whole fraction of the camera's size are its sensor decimated; any other size
    // is reported per frame below. The first frame, read for its size, is not read again.
    let (camera, first_depth, first_stamp) = match &mut bag {
        Some((reader, _)) => {
            let scale = read_opts.scale_units_per_m.unwrap_or(default_scale);
            match reader.read(0, scale) {
                (Ok(d), stamp) => {
                    let camera = crate::common::camera_for_frames(&camera, d.width(), d.height())
                        .unwrap_or(camera);
                    (camera, Some(d), stamp)
                }
                // Reported at the frame, as an unreadable file is.
                (Err(_), _) => (camera, None, None),
            }
        }
        None => {
            let (camera, first) = crate::common::camera_for_sequence(
                camera,
                frames.first().map(|f| f.depth_path.as_path()),
                &read_opts,
            );
            (camera, first, None)
        }
    };
    // A folder of TUM frames read as millimetres is five times too deep: say so at the first.
    if let (None, Some(d), Some(f)) = (args.input.depth_scale, &first_depth, frames.first()) {
        let preset_sensor = crate::common::sensor_from_preset(&args.input, source::folder(&args));
        crate::common::note_doubtful_depth_scale(
            &f.depth_path,
            d,
            &args.input,
            default_scale,
            preset_sensor.then_some(&camera.sensor),
        );
    }
    let k = camera.intrinsics;
    limits()
        .check_pixels(k.width as u64, k.height as u64)
        .map_err(|m| anyhow::anyhow!("camera: {m}"))?;
    // After the size check: the map holds one index per pixel.
    let implied = source::implied_preset(&args);
    let bag_lens = bag.as_ref().and_then(|(_, lens)| *lens);
    let undistort = match bag_lens {
        Some(lens) if args.lens.lens != "none" => {
            errln!(
                "note: undistorting the depth with the plumb_bob model of the bag's camera_info \
                 (--lens none keeps it as it is)"
            );
            Some(sl_core::Undistorter::new(&camera.intrinsics, &lens))
        }
        _ => crate::common::undistorter(&args.lens, &args.input, implied, &camera),
    };
    let prefilter = args.prefilter;
    prepare::check_prefilter(prefilter, &camera)?;
    if args.new_fragment_after_s.is_nan() || args.new_fragment_after_s <= 0.0 {
        bail!(
            "--new-fragment-after-s must be positive (inf: never), got {}",
            crate::common::num(args.new_fragment_after_s)
        );
    }
    let cfg = config::reconstruction_config(&args, &camera, weighting, implied)?;
    // The raw frames' noise against the camera's model (the prefilter hides it).
    let noise_meter = (!args.model_noise_only).then(|| cfg.tracker.noise_meter());
    let mut prep = FramePrep::new(
        read_opts,
        first_depth.map(|d| (d, first_stamp)),
        bag.map(|(reader, _)| reader),
        camera,
        undistort,
        prefilter,
        noise_meter,
    );
    let mut rec = Reconstruction::new(camera, cfg)?;

    let bar = progress_bar(frames.len(), args.json);
    let mut rows: Vec<(f64, Row)> = Vec::with_capacity(frames.len());
    let mut tally = Tally::default();
    // Meshes that could not be written (the run goes on; it fails once the trajectories are).
    let mut mesh_errors: Vec<String> = Vec::new();
    // Per fragment: its first frame, and its mesh once written.
    let mut fragments: Vec<FragmentOut> = vec![FragmentOut::starting_at(0)];
    let wall = Instant::now();
    for (i, f) in frames.iter().enumerate() {
        let (raw, stamp) = prep.read(i, f);
        // A bag frame's stamp is its image header's, read with it.
        let stamp = stamp.or(f.timestamp);
        let t = stamp.unwrap_or(i as f64);
        // A frame of another size is a wrong camera, not an unreadable frame: the same error
        // whatever the layout, before the lens model or the prefilter would refuse it as a
        // skip.
        if let Ok(d) = &raw {
            prep.check_size(f, d)?;
        }
        let prepared = Instant::now();
        let depth = match prep.prepare(raw, &mut rec) {
            Ok(d) => d,
            Err(e) => {
                errln!(
                    "warning: skipping frame {i} ({}): {e}",
                    f.depth_path.display()
                );
                tally.skipped_frames.push(i);
                rows.push((t, Row::Skipped(e.to_string().replace('\n', " "))));
                bar.inc(1);
                continue;
            }
        };
        let prepare = prepared.elapsed().as_secs_f64() * 1e3;
        // The tracker is told how many frame intervals passed: from the timestamps of a TUM
        // recording (frames its driver dropped), else one per frame of the folder, so an
        // unreadable frame skipped above is a longer step rather than a surprise.
        let interval_s = rec.config().tracker.frame_interval_s;
        let time_s = match stamp {
            Some(n) if frame_numbers => n * interval_s,
            Some(t) => t,
            None => i as f64 * interval_s,
        };
        if let Some(o) = odometry.as_mut() {
            rec.set_odometry(o.pose_at(stamp));
        }
        let step = rec
            .step(&depth, Some(time_s))
            .with_context(|| format!("tracking {}", f.depth_path.display()))?;
        fragments::note_step(&args, i, &step, &rec, &mut fragments, &mut mesh_errors);
        rows.push((t, tally.record(i, step, prepare, args.verbose)));
        bar.set_message(format!("{} lost", tally.lost_frames.len()));
        bar.inc(1);
    }
    bar.finish_and_clear();
    tally.wall_s = wall.elapsed().as_secs_f64();
    if let Some(o) = &odometry {
        o.note();
        tally.odometry_poses = Some((o.found, o.missing));
    }
    if !frames.is_empty() && tally.skipped_frames.len() == frames.len() {
        bail!(
            "none of the {} frames could be read (each is named above); nothing was written",
            frames.len()
        );
    }

    fragments::mesh_finished(&args, rec.finish()?, &mut fragments, &mut mesh_errors);
    trajectory_text::write_trajectories(&args, &rows, &fragments)?;
    report::print(
        &args,
        &cfg,
        frames.len(),
        &tally,
        &prep,
        &fragments,
        &mesh_errors,
    )?;
    if !mesh_errors.is_empty() {
        bail!(
            "{} (the trajectory and everything else were written)",
            mesh_errors.join("; ")
        );
    }
    Ok(())
}

/// The checks of `args` that need no input: output names, option ranges, the depth scale.
fn check_args(args: &Args) -> Result<()> {
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
    Ok(())
}

/// The progress bar of `len` frames on standard error (hidden with `--json` or when standard
/// error is not a terminal).
fn progress_bar(len: usize, json: bool) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    if !std::io::stderr().is_terminal() || json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "tracking {bar:40} {pos}/{len} frames, {per_sec}, {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}
