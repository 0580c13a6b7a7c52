//! `sldepth cameras`: the sensor preset table of `sl_core::preset`, as text or JSON.

use anyhow::Result;
use serde_json::{Value, json};
use sl_core::preset::{DepthUnits, PRESETS, SensorPreset};

use crate::common::print_json;

/// Arguments of `sldepth cameras`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print the table as a JSON array.
    #[arg(long)]
    pub json: bool,
}

fn units(u: DepthUnits) -> Value {
    match u {
        DepthUnits::UnitsPerMetre(s) => json!(s),
        _ => json!("raw-disparity"),
    }
}

fn preset_json(p: &SensorPreset) -> Value {
    json!({
        "name": p.name,
        "description": p.description,
        "width": p.width,
        "height": p.height,
        "fx": p.fx,
        "fy": p.fy,
        "cx": p.cx,
        "cy": p.cy,
        "baseline_m": p.baseline_m,
        "subpixel_steps": p.subpixel_steps,
        "sigma_d_px": p.sigma_d_px,
        "min_depth_m": p.min_depth_m,
        "max_depth_m": p.max_depth_m,
        "depth_units_per_m": units(p.depth_units),
        "sigma_z_at_2m_m": p.sensor().sigma_z(2.0),
        "source": p.source,
    })
}

/// Runs `sldepth cameras`.
pub fn run(args: Args) -> Result<()> {
    if args.json {
        print_json(&Value::Array(PRESETS.iter().map(preset_json).collect()))?;
        return Ok(());
    }
    outln!(
        "{:<13} {:>9} {:>7} {:>7} {:>6} {:>4} {:>9} {:>12}  description",
        "name",
        "size",
        "fx px",
        "B mm",
        "1/q px",
        "σ_D",
        "range m",
        "σ_Z(2 m) mm"
    )?;
    for p in PRESETS {
        outln!(
            "{:<13} {:>9} {:>7.1} {:>7.1} {:>6} {:>4} {:>9} {:>12.1}  {}",
            p.name,
            format!("{}x{}", p.width, p.height),
            p.fx,
            p.baseline_m * 1e3,
            format!("1/{}", p.subpixel_steps),
            p.sigma_d_px,
            format!("{}-{}", p.min_depth_m, p.max_depth_m),
            p.sensor().sigma_z(2.0) * 1e3,
            p.description
        )?;
    }
    Ok(())
}
