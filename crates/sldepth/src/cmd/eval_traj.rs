//! `sldepth eval-traj`: absolute trajectory error and relative pose error of an estimated
//! trajectory against ground truth, both TUM-format files (TUM benchmark definitions).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;
use sl_eval::trajectory::{
    AteResult, DeltaUnit, ErrorStats, RpeResult, StampedPose, TrajectoryConfig, ate, rpe,
};

use crate::common::{limits, print_json, round_to};

/// Options of `sldepth eval-traj`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimated trajectory, TUM format (`timestamp tx ty tz qx qy qz qw` per line,
    /// camera-to-world, `#` comments).
    #[arg(value_name = "EST")]
    pub estimated: PathBuf,
    /// Ground-truth trajectory, TUM format (e.g. a sequence's `groundtruth.txt`).
    #[arg(value_name = "GT")]
    pub ground_truth: PathBuf,
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
}

/// Reads a TUM trajectory within the run's limits.
fn read(path: &Path, what: &str) -> Result<Vec<StampedPose>> {
    let poses = sl_io::trajectory::read_tum_trajectory_with_limits(path, &limits())
        .with_context(|| format!("reading the {what} trajectory"))?;
    Ok(poses.iter().map(|p| (p.timestamp, p.pose)).collect())
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

/// Runs `sldepth eval-traj`.
pub fn run(args: Args) -> Result<()> {
    let mut config = TrajectoryConfig::default();
    config.max_gap_s = args.max_gap_s;
    config.delta = args.delta;
    config.delta_unit = DeltaUnit::parse(&args.delta_unit)?;
    config.validate()?;
    let est = read(&args.estimated, "estimated")?;
    let gt = read(&args.ground_truth, "ground-truth")?;
    let a: AteResult = ate(&est, &gt, &config).context("absolute trajectory error")?;
    let r: RpeResult = rpe(&est, &gt, &config).context("relative pose error")?;
    if args.json {
        print_json(&json!({
            "estimated": args.estimated.display().to_string(),
            "ground_truth": args.ground_truth.display().to_string(),
            "poses_estimated": a.estimated,
            "poses_ground_truth": a.ground_truth,
            "poses_matched": a.matched,
            "max_gap_s": config.max_gap_s,
            "ate_m": stats_json(&a.stats_m, 6),
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
