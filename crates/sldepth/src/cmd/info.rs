//! `sldepth info`: size and depth statistics of a depth map.

use std::path::PathBuf;

use anyhow::Result;
use serde_json::json;

use crate::common::{InputArgs, load_depth, print_json, round_to};

/// Options of `sldepth info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Depth map (16-bit PNG/TIFF, float TIFF, NYU raw PGM, SUN PNG).
    #[arg(value_name = "DEPTH")]
    pub depth: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth info`.
pub fn run(args: Args) -> Result<()> {
    let loaded = load_depth(&args.depth, &args.input)?;
    let d = &loaded.depth;
    let stats = d.stats();
    let (zmin, zmed, zmax) = stats.map_or((None, None, None), |s| {
        (
            Some(round_to(f64::from(s.min), 6)),
            Some(round_to(f64::from(s.median), 6)),
            Some(round_to(f64::from(s.max), 6)),
        )
    });
    let valid = stats.map_or(0, |s| s.valid_pixels);
    let total = d.width() * d.height();
    if args.json {
        print_json(&json!({
            "path": args.depth.display().to_string(),
            "width": d.width(),
            "height": d.height(),
            "valid_pixels": valid,
            "valid_fraction": round_to(valid as f64 / total.max(1) as f64, 6),
            "z_min_m": zmin,
            "z_median_m": zmed,
            "z_max_m": zmax,
            "encoding": loaded.encoding.to_string(),
        }))?;
    } else {
        outln!("{}", args.depth.display())?;
        outln!(
            "  size          {} x {} px ({})",
            d.width(),
            d.height(),
            loaded.encoding
        )?;
        outln!(
            "  valid pixels  {valid} of {total} ({:.1} %)",
            100.0 * valid as f64 / total.max(1) as f64
        )?;
        match stats {
            Some(s) => outln!(
                "  depth         min {:.3} m, median {:.3} m, max {:.3} m",
                s.min,
                s.median,
                s.max
            )?,
            None => outln!("  depth         no valid pixel")?,
        }
    }
    Ok(())
}
