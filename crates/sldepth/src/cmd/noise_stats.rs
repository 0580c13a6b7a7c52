//! `sldepth noise-stats`: the noise statistics of a real (or simulated) depth map — σ_D per
//! depth band, residual autocorrelation, terrace widths and occlusion-band widths — with the
//! planar regions found by `sl-planes`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use sl_noise::stats::{NoiseStats, NoiseStatsConfig, noise_stats};
use sl_planes::{PlaneConfig, extract_planes, frame_noise_scale};

use crate::common::{InputArgs, load_depth, print_json};

/// Options of `sldepth noise-stats`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Depth map with planar regions (walls, floors, table tops).
    #[arg(value_name = "DEPTH")]
    pub depth: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Smallest plane used, pixels of the sensor (a frame decimated by n from its sensor counts
    /// n² per pixel, as `sldepth planes --min-pixels` does).
    #[arg(long, default_value_t = 2000)]
    pub min_plane_pixels: usize,
    #[command(flatten)]
    pub input: InputArgs,
}

/// The planes of `depth` (sl-planes defaults, larger minimum size) and the statistics on them.
pub fn stats_of(
    depth: &sl_core::DepthImage,
    camera: &sl_core::Camera,
    min_plane_pixels: usize,
) -> Result<NoiseStats> {
    let mut cfg = PlaneConfig::default();
    cfg.min_pixels = min_plane_pixels.max(3);
    let seg = extract_planes(depth, camera, &cfg).context("extracting planes")?;
    let opts = NoiseStatsConfig::for_camera(camera);
    Ok(noise_stats(depth, camera.sensor.fb(), &seg.labels, &opts)?)
}

/// Runs `sldepth noise-stats`.
pub fn run(args: Args) -> Result<()> {
    let loaded = load_depth(&args.depth, &args.input)?;
    let s = stats_of(&loaded.depth, &loaded.camera, args.min_plane_pixels)
        .with_context(|| format!("analysing {}", args.depth.display()))?;
    let sensor = loaded.camera.sensor;
    let scale = frame_noise_scale(&loaded.depth, &loaded.camera, &PlaneConfig::default())
        .context("measuring the frame's noise against the camera's model")?;
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("path".into(), json!(args.depth.display().to_string()));
            o.insert("fb_px_m".into(), json!(sensor.fb()));
            o.insert("model_sigma_d_px".into(), json!(sensor.sigma_d_px));
            o.insert("model_variance_scale".into(), json!(scale));
            o.insert(
                "model_effective_sigma_d_px".into(),
                json!(sensor.sigma_d_for_variance_scale(scale)),
            );
        }
        return print_json(&v);
    }
    outln!("{}", args.depth.display())?;
    outln!(
        "  planar regions {}, residual pixels {}, invalid {:.1} %",
        s.regions,
        s.pixels,
        100.0 * s.invalid_fraction
    )?;
    outln!(
        "  σ_D {:.4} px overall (f·B {:.2} px·m)",
        s.sigma_d_px,
        loaded.camera.sensor.fb()
    )?;
    for b in s.bands.iter().filter(|b| b.pixels > 0) {
        outln!(
            "    {:.1}-{:.1} m  σ_D {:.4} px  ({} px)",
            b.z_lo_m,
            b.z_hi_m,
            b.sigma_d_px,
            b.pixels
        )?;
    }
    if scale > 1.0 {
        outln!(
            "  against the camera's model (σ_D {:.3} px): pixel variance ×{scale:.2}, as a σ_D of {:.3} px",
            sensor.sigma_d_px,
            sensor.sigma_d_for_variance_scale(scale)
        )?;
    } else {
        outln!(
            "  against the camera's model (σ_D {:.3} px): within it",
            sensor.sigma_d_px
        )?;
    }
    outln!("  residual autocorrelation (lag: x / y)")?;
    // A lag longer than every planar region is unmeasured (NaN, `null` in JSON).
    let acf = |v: f64| {
        if v.is_nan() {
            "–".to_owned()
        } else {
            format!("{v:.3}")
        }
    };
    for c in &s.acf {
        outln!("    {:>3} px  {} / {}", c.lag, acf(c.x), acf(c.y))?;
    }
    let t = &s.terraces.widths;
    if t.count == 0 {
        outln!("  terraces along rows: none")?;
    } else {
        outln!(
            "  terraces along rows: {} runs, median {:.1} px, mean {:.1}, p10 {:.1}, p90 {:.1}",
            t.count,
            t.median_px,
            t.mean_px,
            t.p10_px,
            t.p90_px
        )?;
    }
    for (name, side) in [("left", &s.occlusion.left), ("right", &s.occlusion.right)] {
        // Without a band there is no width to give (the statistics are NaN, `null` in JSON).
        let bands = if side.widths.count == 0 {
            "no band".to_owned()
        } else {
            format!(
                "{} runs, median {:.1} px (p10 {:.1}, p90 {:.1}); projector shadow alone {:.1} px",
                side.widths.count,
                side.widths.median_px,
                side.widths.p10_px,
                side.widths.p90_px,
                side.median_shadow_px
            )
        };
        outln!(
            "  occlusion bands {name:>5} of foreground: {bands}; {} edges without a band",
            side.direct_edges
        )?;
        // The same edges by the shadow their depths predict: where they have bands at all.
        let mut lo = 0.0;
        let bins: Vec<String> = side
            .by_shadow
            .iter()
            .map(|b| {
                let range = if b.upper_px.is_finite() {
                    format!("{lo:.0}-{:.0} px", b.upper_px)
                } else {
                    format!("{lo:.0}+ px")
                };
                lo = b.upper_px;
                format!("{range} {}/{}", b.with_band, b.edges)
            })
            .collect();
        outln!(
            "    edges with a band, by the shadow their depths predict: {}",
            bins.join(", ")
        )?;
    }
    Ok(())
}
