//! `sldepth fuse`: merge registered depth frames into one mesh (paper section 3.3) — a sparse
//! TSDF with the 1/Z⁴ noise weights, then marching cubes.

mod frames;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use sl_core::{Camera, CameraToWorld};
use sl_filter::Prefilter;
use sl_io::depth::ReadConfig;
use sl_io::sequence::SequenceLayout;
use sl_io::trajectory::Frame;
use sl_tsdf::{
    Axis, DepthLookup, MeshConfig, SliceSpec, Truncation, TsdfConfig, TsdfError, TsdfVolume,
    WeightMode,
};

use frames::{Frames, PoseSource, Recording};

use crate::common::{
    InputArgs, LensArgs, check_depth_scale, check_distinct_outputs, check_output, check_range,
    limits, load_camera, parse_format, print_json, round_to,
};

/// Options of `sldepth fuse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The sequence folder, its layout read from what it holds: a TUM folder (`depth.txt` or
    /// `associations.txt`, with `groundtruth.txt`) as --tum, a 7-Scenes folder
    /// (`frame-*.depth.png` with their `.pose.txt`) as --7scenes, an Open3D-style folder (a
    /// `depth` folder and one `.log` trajectory beside it, or `trajectory.log` of several) as
    /// --o3d-log LOG --depth-dir DIR/depth,
    /// a ScanNet export (`depth` and `pose` folders, no `.log`) as --scannet.
    /// A robot recording (a ROS 1 bag, a ROS 2 bag's `.mcap`, `.db3` or folder, a RealSense
    /// recording) is fused along --trajectory, each depth message posed by the trajectory's pose
    /// nearest its stamp, or along its own transforms (--tf).
    #[arg(value_name = "DIR", group = "source")]
    pub sequence: Option<PathBuf>,
    /// The recording given as DIR (set from it: a bag, not a folder of frames).
    #[arg(skip)]
    pub recording: Option<PathBuf>,
    /// The depth topic of a recording (default: the one image topic holding depth).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// A ScanNet scan as its SensReader exports it: `depth/<n>.png` (millimetres) with
    /// `pose/<n>.txt` (4x4 camera-to-world; a frame whose matrix is `-inf`, or that has no pose
    /// file, is left out and counted); its `intrinsic/intrinsic_depth.txt` (or
    /// `intrinsic_depth.txt`) is the camera when --camera is not given.
    #[arg(long, value_name = "DIR", group = "source")]
    pub scannet: Option<PathBuf>,
    /// Frame list: each line is a depth image path (relative to the list's directory) followed
    /// by the 16 numbers of a row-major 4x4 camera-to-world pose in metres; `#` starts a comment.
    #[arg(long, value_name = "LIST", group = "source")]
    pub frames: Option<PathBuf>,
    /// A TUM RGB-D sequence directory as TUM ships it (groundtruth.txt, and associations.txt
    /// or depth.txt); the depth scale defaults to 5000 units/m and the camera to the
    /// `tum-fr1`, `tum-fr2` or `tum-fr3` preset, whichever the folder's name says (fr1
    /// when it names none). One of ICL-NUIM's TUM-format folders (associations depth first,
    /// frame numbers) takes `icl-nuim-tum` and its `*.gt.freiburg` when there is no
    /// groundtruth.txt; its poses are y up, and the mesh is written in its frame.
    #[arg(long, value_name = "DIR", group = "source")]
    pub tum: Option<PathBuf>,
    /// An Open3D trajectory `.log` (camera-to-world); needs --depth-dir. A `camera.json` (or
    /// another name Open3D's tools give it) beside the log is used when --camera is not given,
    /// else `ros-default`, as Open3D takes such a folder.
    #[arg(long, value_name = "FILE", group = "source", requires = "depth_dir")]
    pub o3d_log: Option<PathBuf>,
    /// Directory of the depth images of --o3d-log (sorted by name, numbers as numbers: `9.png`
    /// before `10.png`, as Open3D orders them; names that are all times, in time order; entry
    /// i uses image i).
    #[arg(long, value_name = "DIR")]
    pub depth_dir: Option<PathBuf>,
    /// A 7-Scenes sequence directory (frame-*.depth.png + frame-*.pose.txt); its
    /// camera-intrinsics.txt is used when --camera is not given.
    #[arg(long = "7scenes", value_name = "DIR", group = "source")]
    pub seven_scenes: Option<PathBuf>,
    /// Fuse the sequence folder (DIR, --tum, --7scenes or --scannet) or the recording (DIR:
    /// a bag, each message by its stamp) along this trajectory instead of its own poses: `sldepth track`'s `--output` (a TUM file, or its Open3D
    /// `.log`), or another system's estimate (camera to world). A TUM-format file is matched by
    /// time, each frame to the pose nearest its timestamp within --max-gap-s (frames without
    /// timestamps, as 7-Scenes', by their index, as `track` stamps them); a `.log` by frame
    /// number. Frames without a pose (frames `track` lost) are skipped and counted. The folder
    /// needs no poses of its own: `track DIR --output traj.txt`, then `fuse DIR --trajectory
    /// traj.txt --voxel-m 0.002` re-fuses a raw recording at another resolution.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["frames", "o3d_log"])]
    pub trajectory: Option<PathBuf>,
    /// Fuse a recording along the transforms it holds (`/tf`, `/tf_static`: a motion-capture
    /// system's, a robot's odometry, a SLAM system's map): each depth frame takes the pose of
    /// its image's frame (the `frame_id` of its header, the camera driver's optical frame) in
    /// this frame (`map`, `odom`, `world`) at its stamp, each transform of the chain
    /// interpolated between samples no more than twice its median interval apart (a static
    /// one at any time; beyond a transform's first or last sample, or in a gap of its samples
    /// such as a motion capture's dropout, only its nearest sample within --max-gap-s).
    /// `sldepth info REC` lists the recording's frames.
    #[arg(long, value_name = "WORLD_FRAME", conflicts_with = "trajectory")]
    pub tf: Option<String>,
    /// The camera's optical frame for --tf, where the depth images name none or another one
    /// (ROS's optical frame: z forward, x right, y down, as every ROS camera driver publishes).
    #[arg(long, value_name = "FRAME", requires = "tf")]
    pub tf_camera_frame: Option<String>,
    /// The namespace of the tree of transforms for --tf, in a recording that remapped them
    /// (`/robot1`: `/robot1/tf` and `/robot1/tf_static`; default: `/tf`, `/tf_static`).
    #[arg(long, value_name = "NS", requires = "tf", default_value = "")]
    pub tf_namespace: String,
    /// Largest time, seconds, between a depth frame and the pose it takes, where frames are
    /// matched to poses by time: a TUM folder's `groundtruth.txt`, a TUM-format --trajectory,
    /// a recording's messages. Frames without a pose that near are skipped and counted. The
    /// default is TUM's `associate.py --max_difference`; a trajectory sampled more sparsely
    /// than the frames (a keyframe trajectory, a 10 Hz odometry) needs more, at the price of
    /// fusing frames at a pose up to this far from their own time.
    #[arg(long, value_name = "SECONDS", default_value_t = sl_io::trajectory::DEFAULT_MAX_DT_S)]
    pub max_gap_s: f64,
    /// Use only the first N frames.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// Voxel edge, metres.
    #[arg(long, value_name = "M", default_value_t = 0.004)]
    pub voxel_m: f64,
    /// A fixed truncation band (f_max = -f_min) for every depth, metres. Default: a band per
    /// observation following the sensor noise, max(5 voxels, --trunc-sigmas·σ_Z(Z)) up to
    /// 0.12 m (2 cm up to 2.1 m, 4.3 cm at 3 m, 7.7 cm at 4 m for a Kinect at 4 mm voxels); see
    /// `TsdfConfig`.
    #[arg(long, value_name = "M")]
    pub trunc_m: Option<f64>,
    /// Width of the sensor-adaptive band in σ_Z of the camera's sensor model (3: 99.7 % of
    /// the zero crossings). Ignored with --trunc-m.
    #[arg(long, value_name = "N", default_value_t = 3.0)]
    pub trunc_sigmas: f64,
    /// Observation weight: `inv-z4` (the paper, 1/Z^4), `uniform`, `inv-z2`, or `sensor`
    /// (inverse sensor-model variance with a 1 mm/sqrt(12) floor).
    #[arg(long, value_name = "W", default_value = "inv-z4", value_parser = ["inv-z4", "uniform", "inv-z2", "sensor"])]
    pub weight: String,
    /// Ignore depths beyond this, metres.
    #[arg(long, value_name = "M", default_value_t = 4.0)]
    pub max_depth_m: f64,
    /// Where a voxel reads the frame's depth: `nearest` (the pixel nearest its projection, as
    /// KinectFusion and Open3D do) or `bilinear` (inverse depth interpolated between the four
    /// pixels around it when they lie on one surface: no staircase on surfaces seen at grazing
    /// angles, the pixels' noise averaged; on the paper's relief experiment the surface RMS
    /// error falls from 1.05 to 0.63 mm, on real sequences the fused walls' residual does not
    /// change; integration takes 1.6-2x as long). See `DepthLookup`.
    #[arg(long, value_name = "MODE", default_value = "nearest", value_parser = PossibleValuesParser::new(DepthLookup::NAMES).try_map(|s| s.parse::<DepthLookup>()))]
    pub depth_lookup: DepthLookup,
    /// Skip marching cubes with a corner whose accumulated weight is below this (1 = one
    /// observation at 1 m), from 0 to 1e30.
    #[arg(long, value_name = "W", default_value_t = 0.0)]
    pub min_weight: f64,
    /// Memory the voxel blocks, the candidate blocks of a frame and the mesh extraction may use,
    /// bytes. Default (and maximum): 1/3 of --max-memory for the blocks, 3/4 for the blocks and
    /// the mesh together (extracting a mesh takes about as much memory as its volume). A frame whose blocks would exceed it ends the
    /// fusion there: the mesh of the frames before it is written (nothing when it is the first),
    /// then the command fails.
    #[arg(long, value_name = "BYTES")]
    pub memory_budget_bytes: Option<usize>,
    /// Smooth every frame before fusing it, as `sldepth track --prefilter` names the filters:
    /// `single` (sl-filter's adaptive bilateral filter, σ_d = k·Z², the paper's; what a bare
    /// `--prefilter` means), `multiscale` (that pass, then dilated disparity passes 2 and 4 px
    /// apart, as `sldepth track`'s default, for real sensors' spatially correlated error) or `none`
    /// (default). The range kernel follows the camera's sensor model, or the measured noise
    /// (see --model-noise-only).
    #[arg(long, value_name = "FILTER", default_value = "none", num_args = 0..=1, default_missing_value = "single", value_parser = PossibleValuesParser::new(Prefilter::NAMES).try_map(|s| s.parse::<Prefilter>()))]
    pub prefilter: Prefilter,
    /// Fuse with the camera's noise model as given. By default the first frame's disparity
    /// noise is measured on its own 16×16- and 32×32-pixel patches (as `sldepth planes`, `filter` and
    /// `track` do) and, when it is significantly larger than the model's, the sensor-adaptive
    /// band (and the --prefilter's range kernel) follow the measured σ_D: a sensor noisier than
    /// its preset or camera JSON says otherwise scatters its observations past a band too
    /// narrow for them, and the mesh turns to foam. The camera's σ_D is a floor.
    #[arg(long)]
    pub model_noise_only: bool,
    /// Output mesh (PLY, binary unless --ascii), with normals and a `confidence` scalar.
    #[arg(long, short, value_name = "FILE.ply")]
    pub output: Option<PathBuf>,
    /// Write ASCII PLY.
    #[arg(long)]
    pub ascii: bool,
    /// Cross-section axis (x, y or z) for --slice-png.
    #[arg(long, value_name = "AXIS", default_value = "z", value_parser = ["x", "y", "z"])]
    pub slice_axis: String,
    /// Cross-section plane coordinate, metres.
    #[arg(long, value_name = "M", default_value_t = 0.0)]
    pub slice_m: f64,
    /// Write the cross-section of F (blue behind, red in front of the surface, zero crossing in
    /// black, grey unobserved) as PNG. When no fused block crosses the plane (--slice-axis,
    /// --slice-m) the mesh and --render-png are still written, and the command then fails
    /// saying where the blocks are.
    #[arg(long, value_name = "FILE.png")]
    pub slice_png: Option<PathBuf>,
    /// Write a shaded rendering of the mesh seen from the first frame's camera as PNG.
    #[arg(long, value_name = "FILE.png")]
    pub render_png: Option<PathBuf>,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub lens: LensArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

fn parse_weight(name: &str, camera: &Camera) -> Result<WeightMode> {
    if name == "sensor" {
        return Ok(WeightMode::sensor_variance(camera.sensor));
    }
    Ok(WeightMode::parse(name)?)
}

/// The sequence folder of the chosen source and its layout, whose camera file (if any) gives
/// the camera without `--camera`: `--tum`, `--7scenes`, `--scannet` (Open3D-style), or the
/// folder of `--o3d-log`.
fn source_folder(args: &Args) -> Option<(&Path, SequenceLayout)> {
    let tum = args.tum.as_deref().map(|d| (d, SequenceLayout::Tum));
    let seven = || {
        args.seven_scenes
            .as_deref()
            .map(|d| (d, SequenceLayout::SevenScenes))
    };
    let open3d = || {
        args.scannet
            .as_deref()
            .or_else(|| args.o3d_log.as_deref().and_then(Path::parent))
            .map(|d| (d, SequenceLayout::Open3d))
    };
    tum.or_else(seven).or_else(open3d)
}

/// The files of the chosen source besides its depth frames, which no output may replace.
fn source_files(args: &Args) -> Vec<PathBuf> {
    let given = [
        &args.frames,
        &args.o3d_log,
        &args.input.camera,
        &args.trajectory,
    ]
    .into_iter()
    .flatten()
    .cloned();
    // An Open3D-style folder's (or a ScanNet export's) camera file; a TUM or 7-Scenes folder's
    // is among `sequence_files`' own.
    let open3d_camera = source_folder(args)
        .filter(|(_, layout)| *layout == SequenceLayout::Open3d)
        .and_then(|(dir, layout)| sl_io::sequence::camera_file_of(dir, layout));
    crate::common::sequence_files(
        args.tum.as_deref(),
        args.seven_scenes.as_deref(),
        given.chain(open3d_camera),
    )
}

/// The frames of a posed sequence folder (sl-io's reader, as Python's `read_posed_sequence`).
fn posed_frames(
    dir: &Path,
    layout: SequenceLayout,
    max_gap_s: f64,
) -> Result<sl_io::sequence::PosedFrames> {
    Ok(sl_io::sequence::read_posed_frames(
        dir,
        layout,
        max_gap_s,
        &limits(),
    )?)
}

/// The frames of the chosen sequence folder with the poses of `--trajectory`, and the
/// camera.
fn load_along_trajectory(args: &Args, traj: &Path) -> Result<(Vec<Frame>, Camera, Option<f64>)> {
    let Some((dir, layout)) = source_folder(args) else {
        bail!(
            "--trajectory gives the poses of a sequence folder: give the folder (DIR, --tum, \
             --7scenes or --scannet)"
        );
    };
    let seq = sl_io::sequence::read_frames_along_trajectory(
        dir,
        layout,
        traj,
        args.max_gap_s,
        &limits(),
    )?;
    if seq.without_pose > 0 {
        errln!(
            "note: {} depth frames of {} have no pose in {} and are skipped",
            seq.without_pose,
            dir.display(),
            traj.display()
        );
    }
    let (camera, scale) = match layout {
        SequenceLayout::Tum => (
            crate::common::tum_camera(dir, &args.input)?,
            Some(SequenceLayout::Tum.depth_scale()),
        ),
        _ => (
            crate::common::folder_camera(&args.input, dir, layout)?,
            None,
        ),
    };
    Ok((seq.frames, camera, scale))
}

/// A recording's depth frames, to be posed by `--trajectory` as they are read, its camera, the
/// units of its depth and its lens model.
fn load_recording(
    args: &Args,
    path: &Path,
) -> Result<(Frames, Camera, f64, Option<sl_core::LensDistortion>)> {
    if !path.exists() {
        bail!("{}: No such file or directory", path.display());
    }
    if args.trajectory.is_none() && args.tf.is_none() {
        bail!(
            "{0}: say what poses the recording's frames: a trajectory (--trajectory FILE; \
             `sldepth track {0} --output traj.txt` writes one) or its own transforms (--tf \
             WORLD_FRAME; `sldepth info {0}` lists them); or track and fuse it in one go with \
             `sldepth track {0} --mesh mesh.ply`",
            path.display()
        );
    }
    let given = args
        .input
        .camera
        .as_deref()
        .map(crate::common::camera_from_arg)
        .transpose()?;
    let mut b = crate::recording::load(path, args.topic.as_deref(), given, "fusing")?;
    let poses = match (&args.trajectory, &args.tf) {
        (Some(traj), _) => PoseSource::Trajectory {
            poses: sl_io::trajectory::read_trajectory_with_limits(traj, &limits())?,
            file: traj.clone(),
            by_number: sl_io::trajectory::is_open3d_log(traj),
        },
        (None, Some(world)) => transforms_of(path, &mut b.reader, world, args)?,
        (None, None) => bail!("{}: nothing poses the recording's frames", path.display()),
    };
    let recording = Recording {
        path: path.to_path_buf(),
        reader: b.reader,
        count: b.frames.len(),
        poses,
        max_dt_s: args.max_gap_s,
        without_pose: 0,
        first_stamp: None,
    };
    Ok((
        Frames::Recording(Box::new(recording)),
        b.camera,
        b.default_scale,
        b.lens,
    ))
}

/// The recording's transforms for `--tf WORLD`, checked before any frame is read: both frames
/// in them (the camera's from `--tf-camera-frame` or the depth images' headers), joined.
fn transforms_of(
    path: &Path,
    reader: &mut crate::recording::BagFrames,
    world: &str,
    args: &Args,
) -> Result<PoseSource> {
    let (tree, image_frame) = reader.transforms(&args.tf_namespace)?;
    let camera_frame = crate::recording::tf_camera_frame(
        path,
        &tree,
        world,
        args.tf_camera_frame.as_deref(),
        &image_frame,
        ": fuse it along a trajectory (--trajectory FILE)",
    )?;
    errln!(
        "note: {}: posing {} in {} from {} transforms",
        path.display(),
        camera_frame.escape_debug(),
        world.escape_debug(),
        tree.samples()
    );
    Ok(PoseSource::Transforms {
        tree,
        world: world.to_owned(),
        camera_frame,
        first_miss: None,
    })
}

/// The frames and the camera of the chosen source.
fn load_source(args: &Args) -> Result<(Vec<Frame>, Camera, Option<f64>)> {
    if let Some(traj) = &args.trajectory {
        load_along_trajectory(args, traj)
    } else if let Some(list) = &args.frames {
        let frames = sl_io::trajectory::read_frame_list(list, &limits())?;
        Ok((frames, load_camera(&args.input)?, None))
    } else if let Some(dir) = &args.tum {
        let seq = posed_frames(dir, SequenceLayout::Tum, args.max_gap_s)?;
        if seq.without_pose > 0 {
            errln!(
                "note: {} depth frames have no pose within {} s (--max-gap-s) and are skipped",
                seq.without_pose,
                args.max_gap_s
            );
        }
        let camera = crate::common::tum_camera(dir, &args.input)?;
        Ok((seq.frames, camera, Some(SequenceLayout::Tum.depth_scale())))
    } else if let Some(log) = &args.o3d_log {
        let Some(depth_dir) = &args.depth_dir else {
            bail!("--o3d-log needs --depth-dir");
        };
        let frames =
            sl_io::trajectory::read_open3d_log_frames_with_limits(log, depth_dir, &limits())?;
        // As sl-io counts them for an Open3D-style folder: the images the log has no entry for.
        let images = sl_io::trajectory::list_depth_files(depth_dir)?.len();
        if images > frames.len() {
            errln!(
                "note: {} depth images of {} have no pose in {} ({} entries) and are skipped",
                images - frames.len(),
                depth_dir.display(),
                log.display(),
                frames.len()
            );
        }
        // The camera of the folder the log lies in, as an Open3D-style folder's.
        let cam = crate::common::folder_camera(
            &args.input,
            log.parent().unwrap_or(Path::new(".")),
            SequenceLayout::Open3d,
        )?;
        Ok((frames, cam, None))
    } else if let Some(dir) = &args.scannet {
        let seq = posed_frames(dir, SequenceLayout::Open3d, args.max_gap_s)?;
        if seq.without_pose > 0 {
            errln!(
                "note: {} depth frames have no pose (no pose/ file, or ScanNet's -inf matrix) and \
                 are skipped",
                seq.without_pose
            );
        }
        let cam = crate::common::folder_camera(&args.input, dir, SequenceLayout::Open3d)?;
        Ok((seq.frames, cam, None))
    } else if let Some(dir) = &args.seven_scenes {
        // The sequence is read by its pose files: say so when depth frames have none.
        let seq = posed_frames(dir, SequenceLayout::SevenScenes, args.max_gap_s)?;
        if seq.without_pose > 0 {
            errln!(
                "note: {} depth frames have no pose file (frame-*.pose.txt) and are skipped",
                seq.without_pose
            );
        }
        let cam = crate::common::folder_camera(&args.input, dir, SequenceLayout::SevenScenes)?;
        Ok((seq.frames, cam, None))
    } else {
        bail!(
            "give the frames with --frames LIST, --tum DIR, --o3d-log FILE --depth-dir DIR, --7scenes DIR or --scannet DIR"
        )
    }
}

/// A sequence folder given without its layout (`sldepth fuse DIR`) becomes the options of the
/// layout it holds: `--tum`, `--7scenes`, or for an Open3D-style folder `--o3d-log` (its one
/// `.log` file) with `--depth-dir DIR/depth`.
fn resolve_layout(args: &mut Args) -> Result<()> {
    let Some(dir) = args.sequence.take() else {
        return Ok(());
    };
    if sl_io::rosbag::is_bag_file(&dir) {
        args.recording = Some(dir);
        return Ok(());
    }
    match crate::common::sequence_layout(&dir)? {
        SequenceLayout::Tum => args.tum = Some(dir),
        SequenceLayout::SevenScenes => args.seven_scenes = Some(dir),
        // A ScanNet export: poses in a pose/ folder, no .log; or an Open3D-style folder fused
        // along --trajectory (its own poses, if any, are not read).
        SequenceLayout::Open3d
            if sl_io::sequence::has_pose_folder(&dir) || args.trajectory.is_some() =>
        {
            args.scannet = Some(dir);
        }
        SequenceLayout::Open3d => {
            let log = sl_io::sequence::open3d_log_of(&dir)
                .context("name the trajectory with --o3d-log FILE --depth-dir DIR")?;
            args.o3d_log = Some(log);
            args.depth_dir = Some(dir.join("depth"));
        }
        other => bail!(
            "{}: a {other:?} folder is not read by `sldepth fuse`",
            dir.display()
        ),
    }
    Ok(())
}

/// Runs `sldepth fuse`.
pub fn run(mut args: Args) -> Result<()> {
    resolve_layout(&mut args)?;
    // Every argument is checked before any work, so that a failing command writes nothing.
    if let Some(out) = &args.output {
        check_output("--output", out, &["ply"])?;
    }
    if let Some(png) = &args.slice_png {
        check_output("--slice-png", png, &["png"])?;
    }
    if let Some(png) = &args.render_png {
        check_output("--render-png", png, &["png"])?;
    }
    check_distinct_outputs(&[
        ("--output", args.output.as_deref()),
        ("--slice-png", args.slice_png.as_deref()),
        ("--render-png", args.render_png.as_deref()),
    ])?;
    // Read as an `f64` (an `f32` parse turned 1e300 into `inf`, which the message then
    // printed) and checked before it becomes the `f32` of the mesh configuration.
    check_range("--min-weight", args.min_weight, 0.0..=1e30)?;
    check_range("--slice-m", args.slice_m, -1e6..=1e6)?;
    // The same bounds as `sldepth track`: beyond them the volume's geometry is meaningless
    // (a 1e300 m voxel overflowed into a "voxel too small" error).
    check_range("--voxel-m", args.voxel_m, 1e-4..=1.0)?;
    check_range("--max-depth-m", args.max_depth_m, 0.2..=100.0)?;
    // Positive (a gap of 0 matches nothing) and at most an hour (`MAX_GAP_S`).
    check_range(
        "--max-gap-s",
        args.max_gap_s,
        1e-6..=sl_io::trajectory::MAX_GAP_S,
    )?;
    if let Some(t) = args.trunc_m {
        check_range("--trunc-m", t, 1e-4..=10.0)?;
    }
    if let Some(s) = args.input.depth_scale {
        check_depth_scale(s)?;
    }
    let axis = Axis::parse(&args.slice_axis)?;
    let tsdf_budget = limits().tsdf_budget_bytes;
    let budget = match args.memory_budget_bytes {
        None => tsdf_budget,
        Some(b) if b <= tsdf_budget => b,
        Some(b) => bail!(
            "--memory-budget-bytes {b}: over the TSDF share of the memory budget ({tsdf_budget} bytes); raise --max-memory"
        ),
    };
    if args.topic.is_some() && args.recording.is_none() {
        bail!("--topic names a topic of a recording; the source is not one (give REC.bag)");
    }
    if args.tf.is_some() && args.recording.is_none() {
        bail!(
            "--tf poses a recording's frames by its transforms; the source is not a recording \
             (give REC.bag, or a folder's poses with --trajectory)"
        );
    }
    let (mut frames, camera, default_scale, bag_lens) = match &args.recording {
        Some(rec) => {
            let (frames, camera, scale, lens) = load_recording(&args, rec)?;
            (frames, camera, Some(scale), lens)
        }
        None => {
            let (frames, camera, scale) = load_source(&args)?;
            (Frames::Files(frames), camera, scale, None)
        }
    };
    // An ICL-NUIM folder's poses are y up: read into sldepth's frame by sl-io, the mesh written
    // back in the data set's.
    let data_y_up = args
        .tum
        .as_deref()
        .is_some_and(sl_io::sequence::icl_nuim_tum_folder);
    if let (true, Some(dir)) = (data_y_up, &args.tum) {
        errln!(
            "note: {} is one of ICL-NUIM's TUM-format folders: its ground truth (y up) is fused \
             in sldepth's frame, and the mesh written back in the data set's",
            dir.display()
        );
    }
    if let Some(n) = args.max_frames {
        frames.truncate(n);
    }
    if frames.len() == 0 {
        // Name the source that had none.
        let source = [
            ("--7scenes", &args.seven_scenes),
            ("--tum", &args.tum),
            ("--o3d-log", &args.o3d_log),
            ("--frames", &args.frames),
        ]
        .into_iter()
        .find_map(|(flag, p)| p.as_ref().map(|p| format!(" in {flag} {}", p.display())))
        .unwrap_or_default();
        bail!(
            "no frames to fuse{source}: `fuse` needs frames with poses (7-Scenes' frame-*.pose.txt, a TUM \
             folder's groundtruth.txt, an Open3D .log); for a recording without poses use \
             `sldepth track ... --mesh`"
        );
    }
    crate::common::check_outputs_spare_inputs(
        &[
            ("--output", args.output.as_deref()),
            ("--slice-png", args.slice_png.as_deref()),
            ("--render-png", args.render_png.as_deref()),
        ],
        source_files(&args)
            .iter()
            .map(PathBuf::as_path)
            .chain(frames.inputs().iter().map(PathBuf::as_path)),
    )?;
    let mut read_opts = ReadConfig::default();
    read_opts.format = parse_format(&args.input)?;
    // A recording's units are its own (a RealSense recording's depth units, float metres).
    let default_scale = match &frames {
        Frames::Files(_) => crate::common::frames_default_scale(
            frames.first_path(),
            read_opts.format,
            default_scale,
        ),
        Frames::Recording(_) => default_scale,
    };
    read_opts.scale_units_per_m = args.input.depth_scale.or(default_scale);
    // Frames a whole fraction of the camera's size are its sensor decimated; any other size
    // is an error at the frame. The first frame, read for its size, is not read again.
    let (camera, mut first_depth) = match &mut frames {
        Frames::Files(_) => {
            crate::common::camera_for_sequence(camera, frames.first_path(), &read_opts)
        }
        Frames::Recording(r) => {
            let scale = read_opts
                .scale_units_per_m
                .unwrap_or(sl_io::depth::DEFAULT_UNITS_PER_M);
            match r.reader.read(0, scale) {
                (Ok(d), stamp) => {
                    let camera = crate::common::camera_for_frames(&camera, d.width(), d.height())
                        .unwrap_or(camera);
                    r.first_stamp = stamp;
                    (camera, Some(d))
                }
                // Reported at the frame, as an unreadable file is.
                (Err(_), _) => (camera, None),
            }
        }
    };
    // Frames at another scale than they are read at are far out of range: say so at the first.
    if let (None, Some(d), Some(first)) =
        (args.input.depth_scale, &first_depth, frames.first_path())
    {
        let units = read_opts.scale_units_per_m.unwrap_or_else(|| {
            sl_io::sequence::depth_scale_of_file(first).unwrap_or(sl_io::depth::DEFAULT_UNITS_PER_M)
        });
        let preset_sensor = crate::common::sensor_from_preset(&args.input, source_folder(&args));
        crate::common::note_doubtful_depth_scale(
            first,
            d,
            &args.input,
            units,
            preset_sensor.then_some(&camera.sensor),
        );
    }
    let k = camera.intrinsics;
    limits()
        .check_pixels(k.width as u64, k.height as u64)
        .map_err(|m| anyhow::anyhow!("camera: {m}"))?;
    // After the size check: the map holds one index per pixel.
    let implied = args
        .tum
        .as_deref()
        .and_then(|d| sl_io::sequence::sensor_preset(d, SequenceLayout::Tum));
    let undistort = match bag_lens {
        Some(lens) if args.lens.lens != "none" => {
            errln!(
                "note: undistorting the depth with the plumb_bob model of the recording's \
                 camera_info (--lens none keeps it as it is)"
            );
            Some(sl_core::Undistorter::new(&camera.intrinsics, &lens))
        }
        _ => crate::common::undistorter(&args.lens, &args.input, implied, &camera),
    };

    let mut params = TsdfConfig::default();
    params.voxel_m = args.voxel_m;
    params.trunc_m = args.trunc_m.unwrap_or(5.0 * args.voxel_m);
    params.truncation = match args.trunc_m {
        Some(_) => Truncation::Fixed,
        None => Truncation::SensorAdaptive {
            sensor: camera.sensor,
            sigmas: args.trunc_sigmas,
            max_m: 0.12f64.max(params.trunc_m),
        },
    };
    params.weight = parse_weight(&args.weight, &camera)?;
    params.max_depth_m = args.max_depth_m;
    params.memory_budget_bytes = budget;
    params.depth_lookup = args.depth_lookup;
    // Built at the first frame, for its measured noise.
    let mut filter: Option<sl_filter::MultiScale> = None;
    let mut noise_scale = 1.0;
    let mut band_sensor = camera.sensor;
    let mut volume = TsdfVolume::new(params)?;

    let bar = indicatif::ProgressBar::new(frames.len() as u64);
    if !std::io::stderr().is_terminal() {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template("fusing {bar:40} {pos}/{len} frames ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut integrate_ms = Vec::with_capacity(frames.len());
    let mut first_pose: Option<CameraToWorld> = None;
    // The frame whose blocks did not fit, and why: the fusion ends there.
    let mut full: Option<(usize, String)> = None;
    for i in 0..frames.len() {
        let Some(frames::Posed {
            mut depth,
            pose,
            label,
        }) = frames.read(i, &read_opts, &mut first_depth)?
        else {
            // A recording's frame the trajectory has no pose for.
            bar.inc(1);
            continue;
        };
        if depth.width() != k.width || depth.height() != k.height {
            bail!(
                "{}: depth map is {}x{} but the camera is {}x{} (every frame of a sequence has the camera's size; --camera names the camera)",
                label,
                depth.width(),
                depth.height(),
                k.width,
                k.height
            );
        }
        if let Some(u) = &undistort {
            depth = u
                .apply(&depth)
                .with_context(|| format!("undistorting {}", label))?;
        }
        if volume.frame_count() == 0 {
            // The first frame: its noise against the camera's model (before the prefilter,
            // which hides it) sets the band and the prefilter.
            if !args.model_noise_only {
                noise_scale = sl_planes::frame_noise_scale(
                    &depth,
                    &camera,
                    &sl_planes::PlaneConfig::default(),
                )
                .with_context(|| format!("measuring the noise of {}", label))?;
            }
            band_sensor = camera.sensor.with_variance_scale(noise_scale);
            volume.set_band_sensor(band_sensor)?;
            filter = args.prefilter.filter_for(&band_sensor);
        }
        if let Some(filt) = &filter {
            depth = filt
                .apply(&depth)
                .with_context(|| format!("filtering {}", label))?;
        }
        let t0 = Instant::now();
        match volume.integrate(&depth, &k, &pose) {
            Ok(_) => {}
            Err(e @ (TsdfError::MemoryBudget { .. } | TsdfError::CandidateBudget { .. }))
                if volume.frame_count() > 0 =>
            {
                errln!(
                    "error: frame {i} ({}): {e}; the mesh of the {} frames before it is written",
                    label,
                    volume.frame_count()
                );
                full = Some((i, format!("{}: {e}", label)));
                break;
            }
            Err(e) => {
                return Err(e).with_context(|| format!("integrating {}", label));
            }
        }
        integrate_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        first_pose.get_or_insert(pose);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Frames::Recording(r) = &frames
        && r.without_pose > 0
    {
        let how = match &r.poses {
            PoseSource::Trajectory {
                by_number: true, ..
            } => "by message number (an Open3D .log)".to_owned(),
            _ => format!("within {} s of its stamp (--max-gap-s)", r.max_dt_s),
        };
        let (question, why) = match &r.poses {
            PoseSource::Trajectory { .. } => (
                "is it this recording's trajectory?".to_owned(),
                String::new(),
            ),
            PoseSource::Transforms { first_miss, .. } => (
                "are they the frames of this recording's camera?".to_owned(),
                first_miss
                    .as_ref()
                    .map(|e| format!("; the first: {e}"))
                    .unwrap_or_default(),
            ),
        };
        if volume.frame_count() == 0 {
            bail!(
                "no frame of {} has a pose in {} ({} frames; a frame takes the pose {how}{why}): \
                 {question}",
                r.path.display(),
                r.poses.describe(),
                r.without_pose
            );
        }
        errln!(
            "note: {} frames of {} have no pose in {} ({how}{why}) and are skipped",
            r.without_pose,
            r.path.display(),
            r.poses.describe()
        );
    }

    let t0 = Instant::now();
    let mut mesh_config = MeshConfig::default();
    mesh_config.min_weight = args.min_weight as f32;
    // The volume's share twice over, unless a budget was given (it bounds both).
    let mesh_budget = match args.memory_budget_bytes {
        Some(_) => params.memory_budget_bytes,
        None => limits().mesh_budget_bytes,
    };
    let mut mesh = volume.extract_mesh_within(&mesh_config, mesh_budget)?;
    let extract_ms = t0.elapsed().as_secs_f64() * 1e3;
    if mesh.vertex_count() == 0 {
        errln!(
            "note: the mesh is empty: no fused surface within --max-depth-m {} m and --min-weight \
             {} (surfaces farther away are left out; is --depth-scale right?)",
            crate::common::num(params.max_depth_m),
            crate::common::num(args.min_weight)
        );
    }

    // The images are made before the first byte is written: a failure writes nothing. The
    // slice is the exception: a plane that misses the fused blocks is a wrong --slice-m, not a
    // failed fusion, so the mesh of the whole run is written before that error is reported.
    let (slice, slice_error) = match &args.slice_png {
        Some(png) => match volume.slice_rgb(&SliceSpec::new(axis, args.slice_m)) {
            Ok(img) => (Some((png, img)), None),
            Err(e) => (None, Some((png, e))),
        },
        None => (None, None),
    };
    let render = match (&args.render_png, first_pose) {
        (Some(png), Some(pose)) => Some((png, sl_eval::render::render_mesh(&mesh, &k, &pose)?)),
        _ => None,
    };
    // An ICL-NUIM folder's mesh in its y-up frame, as its ground truth and `sldepth track`'s.
    if data_y_up {
        mesh.reflect_y();
    }
    if let Some(out) = &args.output {
        let format = if args.ascii {
            sl_io::ply::PlyFormat::Ascii
        } else {
            sl_io::ply::PlyFormat::BinaryLittleEndian
        };
        sl_tsdf::io::write_mesh_ply(out, &mesh, format)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    for (png, img) in slice.iter().chain(render.iter()) {
        sl_tsdf::io::write_png(png, img).with_context(|| format!("writing {}", png.display()))?;
    }
    // (An empty sum would be −0.)
    let total_ms: f64 = integrate_ms.iter().fold(0.0, |a, b| a + b);
    let med = sl_noise::analysis::median(&mut integrate_ms.clone()).unwrap_or(0.0);
    if args.json {
        print_json(&serde_json::json!({
            // Frames with a pose (a recording's without one are not counted, as a folder's).
            "frames": frames.len() - frames.without_pose(),
            // Frames in the volume: all of them unless it reached its memory budget.
            "fused": volume.frame_count(),
            "integrate_ms_median": round_to(med, 3),
            "integrate_ms_total": round_to(total_ms, 3),
            "extract_ms": round_to(extract_ms, 3),
            "vertices": mesh.vertex_count(),
            "triangles": mesh.triangle_count(),
            "blocks": volume.block_count(),
            "memory_bytes": volume.memory_bytes(),
            "voxel_m": params.voxel_m,
            "trunc_m": params.trunc_m,
            "truncation": params.truncation.name(),
            "depth_lookup": params.depth_lookup.name(),
            "weight": params.weight.name(),
            "max_depth_m": params.max_depth_m,
            "prefilter": args.prefilter.name(),
            "noise_scale": round_to(noise_scale, 3),
            "band_sigma_d_px": round_to(band_sensor.sigma_d_px, 4),
            "undistorted": undistort.is_some(),
            "output": args.output.as_ref().map(|p| p.display().to_string()),
        }))?;
    } else {
        if noise_scale > 1.0 {
            errln!(
                "the first frame's noise is {noise_scale:.2}x the camera model's variance: fused with the band of a σ_D of {:.3} px (--model-noise-only: the camera's {:.3} px)",
                band_sensor.sigma_d_px,
                camera.sensor.sigma_d_px
            );
        }
        errln!(
            "fused {} frames ({:.1} ms/frame median): {} vertices, {} triangles, {} blocks ({:.1} MiB); marching cubes {:.0} ms",
            volume.frame_count(),
            med,
            mesh.vertex_count(),
            mesh.triangle_count(),
            volume.block_count(),
            volume.memory_bytes() as f64 / (1 << 20) as f64,
            extract_ms
        );
    }
    if let Some((png, e)) = slice_error {
        let written: Vec<String> = [args.output.as_ref(), args.render_png.as_ref()]
            .into_iter()
            .flatten()
            .map(|p| p.display().to_string())
            .collect();
        let note = if written.is_empty() {
            String::new()
        } else {
            format!(" ({} written)", written.join(" and "))
        };
        return Err(anyhow::Error::new(e).context(format!(
            "--slice-png {} not written{note}: --slice-axis {} --slice-m {} misses the fused \
             volume",
            png.display(),
            args.slice_axis,
            crate::common::num(args.slice_m)
        )));
    }
    if let Some((i, e)) = full {
        bail!(
            "{e}: fused {i} of {} frames (the mesh of those was written); raise --max-memory or --voxel-m",
            frames.len()
        );
    }
    Ok(())
}
