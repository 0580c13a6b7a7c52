//! `sldepth analyze`: the depth-resolution analysis of the paper's section 2 on any depth map.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use serde_json::json;
use sl_noise::analysis::analyze;

use crate::common::{InputArgs, check_output, load_depth, print_json, round_to};

/// Options of `sldepth analyze`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Depth map to analyse (a scan with a continuous range of depths, e.g. a floor).
    #[arg(value_name = "DEPTH")]
    pub depth: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write the paper's Figure 2 (sorted unique Z; ln ΔZ vs ln Z with the fit) as SVG or PNG
    /// (by extension).
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth analyze`.
pub fn run(args: Args) -> Result<()> {
    if let Some(plot) = &args.plot {
        check_output("--plot", plot, &["svg", "png"])?;
        crate::common::check_outputs_spare_inputs(
            &[("--plot", Some(plot))],
            [args.depth.as_path()],
        )?;
    }
    let loaded = load_depth(&args.depth, &args.input)?;
    let sensor = loaded.camera.sensor;
    let a = analyze(&loaded.depth, &sensor)
        .with_context(|| format!("analysing {}", args.depth.display()))?;
    if let Some(plot) = &args.plot {
        let ext = plot
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "svg" => {
                let svg = sl_eval::plot::resolution_svg(&a);
                sl_io::atomic::write_atomic(plot, |w| w.write_all(svg.as_bytes()))?;
            }
            "png" => sl_io::rgb::write_rgb_png(plot, &sl_eval::plot::resolution_rgb(&a, 900, 420))?,
            _ => bail!("--plot {}: use a .svg or .png file name", plot.display()),
        }
    }
    // The steps of disparity-quantised depth grow as Z² (the paper's slope 2; real Kinect-class
    // frames measure 1.9–2.1): a slope far from it says the frame is not such depth (rendered,
    // resampled, filtered, or stored at another scale), and what follows from the quantum
    // (f·B, the sub-pixel step) means nothing.
    let quantised_like_the_model = a.quantised_like_the_model();
    if !quantised_like_the_model {
        errln!(
            "note: {}: depth steps grow as Z^{:.2}, not Z² (robust slope): this frame's depth does \
             not look like a structured-light sensor's disparity-quantised depth (rendered, \
             resampled, filtered?); the implied f·B and sub-pixel step below are not meaningful",
            args.depth.display(),
            a.slope_robust
        );
    }
    if args.json {
        print_json(&json!({
            "path": args.depth.display().to_string(),
            "quantised_like_the_model": quantised_like_the_model,
            "unique_depths": a.unique_depths,
            "slope": round_to(a.slope, 6),
            "slope_continuous": round_to(a.slope_continuous, 6),
            "gap_pairs": a.gap_pairs,
            "slope_robust": round_to(a.slope_robust, 6),
            "quantum_per_m": a.quantum_per_m,
            "fb_px_m": a.fb_px_m.map(|v| round_to(v, 6)),
            "fb_used_px_m": a.fb_used_px_m.map(|v| round_to(v, 6)),
            "fb_source": format!("{:?}", a.fb_source),
            "subpixel_steps": a.subpixel_steps,
            "camera_fb_px_m": round_to(sensor.fb(), 6),
            "camera_subpixel_steps": sensor.subpixel_steps,
        }))?;
    } else {
        outln!("{}", args.depth.display())?;
        outln!("  unique depths          {}", a.unique_depths)?;
        outln!(
            "  slope ln ΔZ vs ln Z    {:.3} (OLS), {:.3} (robust), {:.3} (OLS without {} coverage-gap pairs); the model predicts 2",
            a.slope,
            a.slope_robust,
            a.slope_continuous,
            a.gap_pairs
        )?;
        outln!("  quantum c (ΔZ ≈ c·Z²)  {:.6} 1/m", a.quantum_per_m)?;
        match a.fb_px_m {
            Some(fb) => outln!(
                "  implied f·B            {fb:.3} px·m with q = {} (camera: {:.3})",
                sensor.subpixel_steps,
                sensor.fb()
            )?,
            None => outln!("  implied f·B            undetermined (too few far depths)")?,
        }
        match (a.subpixel_steps, a.fb_used_px_m) {
            (Some(q), Some(fb)) => outln!(
                "  disparity sub-pixel    1/{q} px (counted with f·B = {fb:.3} px·m, {:?})",
                a.fb_source
            )?,
            _ => outln!("  disparity sub-pixel    undetermined (too few far depths)")?,
        }
    }
    Ok(())
}
