//! `sldepth eval-traj`: absolute trajectory error and relative pose error of an estimated
//! trajectory against ground truth (TUM benchmark definitions), each a TUM-format file or an
//! Open3D `.log` (its entries' frame numbers as their timestamps, as `sldepth track` stamps the
//! frames of folders without timestamps).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde_json::json;
use sl_eval::trajectory::{
    AteResult, DeltaUnit, ErrorStats, MAX_OFFSET_S, OffsetSearch, PoseError, RpeResult,
    StampedPose, TimeOffset, TrajectoryConfig, ate, estimate_time_offset, rpe,
};

use crate::common::{check_output, check_outputs_spare_inputs, limits, num, print_json, round_to};

/// Options of `sldepth eval-traj`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimated trajectory, TUM format (`timestamp tx ty tz qx qy qz qw` per line,
    /// camera-to-world, `#` comments), or an Open3D `.log` (`sldepth track --output-log`):
    /// a `.log` file's pose of entry `i j n` is stamped with its frame number `i`, the
    /// timestamp `sldepth track --output` gives the frames of a 7-Scenes folder or of an
    /// Open3D folder whose file names are not times.
    #[arg(value_name = "EST")]
    pub estimated: PathBuf,
    /// Ground-truth trajectory, TUM format (e.g. a sequence's `groundtruth.txt`) or an
    /// Open3D `.log` (e.g. an Open3D-style folder's `odometry.log`), read as EST is; or a
    /// recording whose transforms hold the camera's true poses (with --tf: a motion-capture
    /// system's on `/tf`).
    #[arg(value_name = "GT")]
    pub ground_truth: PathBuf,
    /// GT is a recording: the ground truth is the pose of its depth images' frame (the
    /// camera's optical frame, or --tf-camera-frame) in this frame, from its `/tf` and
    /// `/tf_static`, at each depth frame's stamp, as `fuse REC --tf` poses the frames (each
    /// transform interpolated between samples no more than twice its median interval apart;
    /// beyond its samples or in a gap of them, its nearest sample within --max-gap-s, which
    /// then bounds both this and the ATE's matching). `sldepth info REC` lists the frames.
    #[arg(long, value_name = "WORLD_FRAME")]
    pub tf: Option<String>,
    /// The camera's optical frame for --tf, where the depth images name none or another one.
    #[arg(long, value_name = "FRAME", requires = "tf")]
    pub tf_camera_frame: Option<String>,
    /// The namespace of the tree of transforms for --tf (`/robot1`: `/robot1/tf` and
    /// `/robot1/tf_static`; default: `/tf`, `/tf_static`).
    #[arg(long, value_name = "NS", requires = "tf", default_value = "")]
    pub tf_namespace: String,
    /// The depth topic of the --tf recording (default: the one image topic holding depth).
    #[arg(long, value_name = "TOPIC", requires = "tf")]
    pub topic: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Largest timestamp difference, seconds, of an estimated pose and the ground-truth pose
    /// it is matched to for the ATE (TUM's `evaluate_ate.py --max_difference`). The RPE uses
    /// TUM's own rule: twice the median ground-truth interval.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.02)]
    pub max_gap_s: f64,
    /// RPE pair distance, in `--delta-unit`s (1 frame: the drift per frame; 1 second: per
    /// second).
    #[arg(long, value_name = "N", default_value_t = 1.0)]
    pub delta: f64,
    /// Unit of `--delta`: frames or seconds.
    #[arg(long, value_name = "UNIT", default_value = "frames")]
    pub delta_unit: String,
    /// Milliseconds added to the estimate's timestamps before they are matched to the ground
    /// truth's (TUM's `evaluate_ate.py --offset`, in seconds there; evo's `--t_offset`):
    /// negative when the frames' timestamps lag the ground truth's clock.
    #[arg(
        long,
        value_name = "MS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub offset_ms: f64,
    /// Measure the clock offset (every whole millisecond within ±`--offset-search-ms`: the one
    /// under which the estimate's orientations, turned by the best rotation of the world, agree
    /// best with the ground truth's), report it, and evaluate with it instead of
    /// `--offset-ms`. On TUM fr1/rpy with `sldepth track`'s trajectory it finds about −20 ms
    /// (the depth timestamps lag the motion capture: docs/bench/track.md, session 61).
    #[arg(long)]
    pub estimate_offset: bool,
    /// Range of `--estimate-offset`, milliseconds either way (default 100; only with
    /// `--estimate-offset`).
    #[arg(long, value_name = "MS", allow_negative_numbers = true)]
    pub offset_search_ms: Option<f64>,
    /// Write each matched pose's error after the ATE's alignment to this text file (`.txt`,
    /// written atomically): one line per pose in the estimate's time order, `timestamp
    /// gt_timestamp translation_error_m rotation_error_deg` (the estimate's own timestamp,
    /// before `--offset-ms`; the rotation error is the angle between the aligned orientation
    /// and the ground truth's), to see where a trajectory goes wrong, not only by how much.
    #[arg(long, value_name = "FILE")]
    pub per_pose: Option<PathBuf>,
}

/// Default of `--offset-search-ms`, milliseconds.
const DEFAULT_OFFSET_SEARCH_MS: f64 = 100.0;

/// Reads a trajectory (TUM, or an Open3D `.log` stamped with its frame numbers) within the
/// run's limits.
fn read(path: &Path, what: &str) -> Result<Vec<StampedPose>> {
    let poses = sl_io::trajectory::read_trajectory_with_limits(path, &limits())
        .with_context(|| format!("reading the {what} trajectory"))?;
    Ok(poses.iter().map(|p| (p.timestamp, p.pose)).collect())
}

/// The pose of the recording's camera frame in `world` at each depth frame's stamp (frames
/// without one left out, said on standard error).
fn tf_ground_truth(args: &Args, world: &str) -> Result<Vec<StampedPose>> {
    let path = &args.ground_truth;
    let mut bag = sl_io::rosbag::RosBag::open(path, &limits())?;
    crate::recording::note_split_piece(path);
    let topic = bag.depth_topic(args.topic.as_deref())?;
    let messages = bag.messages(&topic)?;
    let tree = crate::recording::transforms_in(&mut bag, &args.tf_namespace)?;
    let image_frame = match messages.first() {
        Some(m) => bag.image_frame_id(m)?,
        None => bail!("{}: {topic} has no message", path.display()),
    };
    let camera = crate::recording::tf_camera_frame(
        path,
        &tree,
        world,
        args.tf_camera_frame.as_deref(),
        &image_frame,
        "",
    )?;
    let mut out = Vec::with_capacity(messages.len());
    let mut first_miss = None;
    for m in &messages {
        let t = bag.image_stamp_s(m)?;
        match tree.lookup(world, &camera, t, args.max_gap_s) {
            Ok(p) => out.push((t, sl_core::CameraToWorld::from_isometry(p))),
            Err(
                e @ (sl_io::rosbag::TfLookupError::NoSample { .. }
                | sl_io::rosbag::TfLookupError::NotFinite { .. }),
            ) => {
                first_miss.get_or_insert(e);
            }
            Err(e) => bail!("{}: {e}", path.display()),
        }
    }
    if let Some(e) = first_miss {
        errln!(
            "note: {} of {} frames of {} have no ground truth ({} in {} within {} s of their \
             stamps; the first: {e})",
            messages.len() - out.len(),
            messages.len(),
            path.display(),
            camera.escape_debug(),
            world.escape_debug(),
            args.max_gap_s
        );
    }
    Ok(out)
}

/// JSON of error statistics, rounded.
fn stats_json(s: &ErrorStats, digits: i32) -> serde_json::Value {
    json!({
        "rmse": round_to(s.rmse, digits),
        "mean": round_to(s.mean, digits),
        "median": round_to(s.median, digits),
        "std": round_to(s.std, digits),
        "min": round_to(s.min, digits),
        "max": round_to(s.max, digits),
    })
}

/// Writes the per-pose errors of `--per-pose` (atomically).
fn write_per_pose(path: &Path, errors: &[PoseError]) -> Result<()> {
    let mut text = String::from(
        "# sldepth eval-traj: each matched pose's error after the ATE's rigid alignment\n\
         # timestamp gt_timestamp translation_error_m rotation_error_deg\n",
    );
    for e in errors {
        writeln!(
            text,
            "{:.6} {:.6} {:.6} {:.4}",
            e.timestamp_s, e.ground_truth_timestamp_s, e.translation_m, e.rotation_deg
        )?;
    }
    sl_io::atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// Runs `sldepth eval-traj`.
pub fn run(args: Args) -> Result<()> {
    let mut config = TrajectoryConfig::default();
    config.max_gap_s = args.max_gap_s;
    config.delta = args.delta;
    config.delta_unit = DeltaUnit::parse(&args.delta_unit)?;
    // Checked here to name the option and its unit (the library's check says `offset_s`).
    let max_offset_ms = MAX_OFFSET_S * 1e3;
    if !(args.offset_ms.is_finite() && args.offset_ms.abs() <= max_offset_ms) {
        bail!(
            "--offset-ms {}: must be finite and at most {} ms either way",
            num(args.offset_ms),
            num(max_offset_ms)
        );
    }
    if args.offset_search_ms.is_some() && !args.estimate_offset {
        bail!("--offset-search-ms applies to --estimate-offset, which is not given");
    }
    config.offset_s = args.offset_ms * 1e-3;
    config.validate()?;
    if let Some(p) = &args.per_pose {
        check_output("--per-pose", p, &["txt"])?;
        check_outputs_spare_inputs(
            &[("--per-pose", Some(p.as_path()))],
            [args.estimated.as_path(), args.ground_truth.as_path()],
        )?;
    }
    let est = read(&args.estimated, "estimated")?;
    let gt = if sl_io::rosbag::is_bag_file(&args.ground_truth) {
        let Some(world) = &args.tf else {
            bail!(
                "{0}: a recording as the ground truth: name the world frame of its transforms \
                 with --tf WORLD_FRAME (`sldepth info {0}` lists its frames)",
                args.ground_truth.display()
            );
        };
        tf_ground_truth(&args, world).context("the ground truth of the recording's transforms")?
    } else {
        if args.tf.is_some() {
            bail!(
                "--tf takes the ground truth from a recording's transforms; GT is not a recording"
            );
        }
        read(&args.ground_truth, "ground-truth")?
    };
    let found: Option<TimeOffset> = if args.estimate_offset {
        // Every whole millisecond (the default step) within the range.
        let mut search = OffsetSearch::default();
        search.max_s = args.offset_search_ms.unwrap_or(DEFAULT_OFFSET_SEARCH_MS) * 1e-3;
        let f = estimate_time_offset(&est, &gt, &config, &search)
            .context("estimating the clock offset")?;
        config.offset_s = f.offset_s;
        Some(f)
    } else {
        None
    };
    let a: AteResult = ate(&est, &gt, &config).context("absolute trajectory error")?;
    let r: RpeResult = rpe(&est, &gt, &config).with_context(|| {
        format!(
            "relative pose error over --delta {} {}",
            num(config.delta),
            config.delta_unit.name()
        )
    })?;
    if let Some(p) = &args.per_pose {
        write_per_pose(p, &a.per_pose).with_context(|| format!("--per-pose {}", p.display()))?;
    }
    let worst = a
        .per_pose
        .iter()
        .max_by(|x, y| x.translation_m.total_cmp(&y.translation_m));
    if args.json {
        print_json(&json!({
            "estimated": args.estimated.display().to_string(),
            "ground_truth": args.ground_truth.display().to_string(),
            "poses_estimated": a.estimated,
            "poses_ground_truth": a.ground_truth,
            "poses_matched": a.matched,
            "max_gap_s": config.max_gap_s,
            "offset_s": round_to(config.offset_s, 6),
            "offset_estimate": found.as_ref().map(|f| json!({
                "offset_s": round_to(f.offset_s, 6),
                "rotation_rmse_deg": round_to(f.rotation_rmse_deg, 4),
                "rotation_rmse_at_zero_deg": round_to(f.rotation_rmse_at_zero_deg, 4),
                "matched": f.matched,
            })),
            "ate_m": stats_json(&a.stats_m, 6),
            "ate_worst_pose": worst.map(|w| json!({
                "timestamp": w.timestamp_s,
                "translation_m": round_to(w.translation_m, 6),
                "rotation_deg": round_to(w.rotation_deg, 4),
            })),
            "per_pose": args.per_pose.as_ref().map(|p| p.display().to_string()),
            "rpe": {
                "delta": config.delta,
                "delta_unit": config.delta_unit.name(),
                "pairs": r.pairs,
                "max_gap_s": round_to(r.max_gap_s, 6),
                "translation_m": stats_json(&r.translation_m, 6),
                "rotation_deg": stats_json(&r.rotation_deg, 4),
            },
        }))?;
    } else {
        if let Some(f) = &found {
            outln!(
                "clock offset {:+.0} ms (orientation error after the best world rotation: rms {:.3}° against {:.3}° at no offset, {} poses)",
                f.offset_s * 1e3,
                f.rotation_rmse_deg,
                f.rotation_rmse_at_zero_deg,
                f.matched
            )?;
        } else if config.offset_s != 0.0 {
            outln!("clock offset {:+} ms (given)", config.offset_s * 1e3)?;
        }
        let s = &a.stats_m;
        outln!(
            "ATE ({} of {} estimated poses matched to {} ground-truth poses within {} s, after rigid alignment)",
            a.matched,
            a.estimated,
            a.ground_truth,
            config.max_gap_s
        )?;
        outln!(
            "  translation  rmse {:.4} m, mean {:.4} m, median {:.4} m, max {:.4} m",
            s.rmse,
            s.mean,
            s.median,
            s.max
        )?;
        if let Some(w) = worst {
            outln!(
                "  largest at the estimate's timestamp {:.6}: {:.4} m (its orientation {:.3}° off, after the best rotation of the world)",
                w.timestamp_s,
                w.translation_m,
                w.rotation_deg
            )?;
        }
        outln!(
            "RPE over {} {} ({} pairs)",
            config.delta,
            config.delta_unit.name(),
            r.pairs
        )?;
        let (t, d) = (&r.translation_m, &r.rotation_deg);
        outln!(
            "  translation  rmse {:.4} m, mean {:.4} m, median {:.4} m, max {:.4} m",
            t.rmse,
            t.mean,
            t.median,
            t.max
        )?;
        outln!(
            "  rotation     rmse {:.3}°, mean {:.3}°, median {:.3}°, max {:.3}°",
            d.rmse,
            d.mean,
            d.median,
            d.max
        )?;
    }
    Ok(())
}
