//! `sldepth planes`: plane extraction with a fixed threshold in disparity (paper section 3.4),
//! or the fixed-metric-threshold RANSAC baseline.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde_json::json;
use sl_core::Image;
use sl_eval::planes::overlay;
use sl_io::DepthFormat;
use sl_planes::{
    PlaneConfig, PlaneExtractor, PlaneSegmentation, RansacConfig, RegionExplanation, metric_ransac,
};

use crate::common::{
    InputArgs, check_distinct_outputs, check_output, check_range, load_depth, print_json, round_to,
};

/// Arguments of `sldepth planes`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Depth map (PNG/TIFF, float TIFF, NYU raw PGM).
    pub depth: PathBuf,
    /// Output label image: 16-bit PNG, 0 = not on a plane, i = plane id.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Also write a colour overlay of the planes (PNG).
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Colour image to draw the overlay on (default: the depth map in grey).
    #[arg(long)]
    pub color: Option<PathBuf>,
    /// Print the planes as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also say why each unlabelled region of at least `--min-pixels` valid pixels is on no
    /// plane (LoG test, residual above the noise, several surfaces, too small a seed, left out as
    /// uncertain, given back by `--give-back-taken-in`); with `--json`, an `unlabelled` list
    /// (disparity method).
    #[arg(long)]
    pub explain: bool,
    /// `disparity` (the paper's method) or `metric-ransac` (the fixed metric threshold baseline).
    #[arg(long, default_value = "disparity", value_parser = ["disparity", "metric-ransac"])]
    pub method: String,
    /// Disparity residual threshold, pixels (disparity method).
    #[arg(long, default_value_t = PlaneConfig::default().threshold_px)]
    pub threshold_px: f64,
    /// LoG response threshold, pixels of disparity (disparity method).
    #[arg(long, default_value_t = PlaneConfig::default().log_threshold_px)]
    pub log_threshold_px: f64,
    /// Point-to-plane threshold, metres (metric-ransac).
    #[arg(long, default_value_t = 0.01)]
    pub threshold_m: f64,
    /// LoG scale, pixels (disparity method).
    #[arg(long, default_value_t = PlaneConfig::default().log_sigma_px)]
    pub log_sigma_px: f64,
    /// Largest curvature of one surface's disparity that the sensor's low-frequency distortion
    /// makes, px/px² at f = 585 px (disparity method): adjacent planes whose slopes agree at
    /// their border and whose fits differ by no more than this bend allows are joined into one
    /// (0 = never).
    #[arg(long, default_value_t = PlaneConfig::default().bend_px_per_px2)]
    pub bend_px_per_px2: f64,
    /// Report only the planes whose normal the sensor's noise model determines within this,
    /// degrees (each plane's `±` in the output, `normal_sigma_deg` in `--json`); the others'
    /// pixels are left unlabelled (disparity method). Default: every plane. On simulated rooms
    /// the spurious planes are the uncertain ones (all above 1.5°, against 97 % of the
    /// correct ones below it), at the price of small, far or narrow true planes.
    #[arg(long)]
    pub max_normal_sigma_deg: Option<f64>,
    /// Do not split the planes that span a crease (disparity method). By default a plane whose
    /// residual is curved beyond the sensor's distortion and the noise, and fitted better by
    /// two affine pieces meeting along a line than by any smooth surface, is split along it.
    #[arg(long)]
    pub no_split_creases: bool,
    /// Re-decide the pixels along a crease with the two planes' local fits where a plane's
    /// whole fit is off there (disparity method; off by default). For sensors whose
    /// low-frequency distortion bends surfaces, where a small plane otherwise takes a strip of
    /// its bent neighbour; costs 0.1-0.3 ms per 640x480 frame on real frames.
    #[arg(long)]
    pub refine_seams: bool,
    /// Give back the pieces of a neighbouring surface a plane took in (disparity method; off
    /// by default): 8×8-pixel blocks whose mean residual, beyond a quadratic fit of the whole
    /// plane's and off the blocks around them, is outside the noise model's 99.9 % bound (grown
    /// over neighbouring blocks beyond its 99 % bound), in connected pieces of at least 256
    /// pixels, are left unlabelled and the plane refitted without them (a socket or a cable on
    /// a wall). Costs 0.4-0.7 ms per 640x480 frame.
    #[arg(long)]
    pub give_back_taken_in: bool,
    /// Take the noise of every test from the camera's model alone (disparity method). By
    /// default a frame noisier than its camera says, measured on its own 16×16- and 32×32-pixel patches,
    /// is extracted with the measured noise (the camera's σ_D is a floor, never lowered) and the
    /// factor is reported (`noise_scale` in `--json`).
    #[arg(long)]
    pub model_noise_only: bool,
    /// Minimum pixels of a plane, pixels of the sensor (frames of the sensor decimated by n,
    /// extracted on its grid, count n² per pixel).
    #[arg(long, default_value_t = PlaneConfig::default().min_pixels)]
    pub min_pixels: usize,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth planes`.
pub fn run(args: Args) -> Result<()> {
    check_output("--output", &args.output, &["png"])?;
    if let Some(p) = &args.overlay {
        check_output("--overlay", p, &["png"])?;
    }
    let outputs = [
        ("--output", Some(args.output.as_path())),
        ("--overlay", args.overlay.as_deref()),
    ];
    check_distinct_outputs(&outputs)?;
    crate::common::check_outputs_spare_inputs(&outputs, [args.depth.as_path()])?;
    if args.method == "metric-ransac" {
        // Switches of the disparity method would be ignored without a word.
        let disparity_only = [
            ("--explain", args.explain),
            ("--give-back-taken-in", args.give_back_taken_in),
            ("--refine-seams", args.refine_seams),
            ("--no-split-creases", args.no_split_creases),
            ("--model-noise-only", args.model_noise_only),
            (
                "--max-normal-sigma-deg",
                args.max_normal_sigma_deg.is_some(),
            ),
        ];
        if let Some((flag, _)) = disparity_only.iter().find(|(_, given)| *given) {
            bail!("{flag} applies to --method disparity, not metric-ransac");
        }
    }
    check_range("--threshold-px", args.threshold_px, 1e-6..=1e3)?;
    check_range("--log-threshold-px", args.log_threshold_px, 0.0..=1e3)?;
    check_range("--log-sigma-px", args.log_sigma_px, 0.0..=1e3)?;
    check_range("--threshold-m", args.threshold_m, 1e-9..=1e3)?;
    check_range("--bend-px-per-px2", args.bend_px_per_px2, 0.0..=1.0)?;
    if let Some(v) = args.max_normal_sigma_deg {
        check_range("--max-normal-sigma-deg", v, 1e-6..=180.0)?;
    }
    let loaded = load_depth(&args.depth, &args.input)?;
    let camera = loaded.camera;
    let mut explained = Vec::new();
    let mut noise_scale = None;
    let mut noise_beyond_threshold = false;
    let (seg, ms) = match args.method.as_str() {
        "disparity" => {
            let mut cfg = PlaneConfig::default();
            cfg.threshold_px = args.threshold_px;
            cfg.log_threshold_px = args.log_threshold_px;
            cfg.log_sigma_px = args.log_sigma_px;
            cfg.min_pixels = args.min_pixels;
            cfg.bend_px_per_px2 = args.bend_px_per_px2;
            cfg.max_normal_sigma_deg = args.max_normal_sigma_deg.unwrap_or(f64::INFINITY);
            cfg.split_creases = !args.no_split_creases;
            cfg.refine_seams = args.refine_seams;
            cfg.give_back_taken_in = args.give_back_taken_in;
            cfg.estimate_noise = !args.model_noise_only;
            let mut ex = PlaneExtractor::new(cfg)?;
            let out = if loaded.encoding.format == DepthFormat::NyuRaw {
                // Work on the raw disparity directly: D = (doff − raw) / 8 px.
                let raw = sl_io::depth::read_raw_depth_with_limits(
                    &args.depth,
                    &sl_io::ReadConfig::default().with_format(DepthFormat::NyuRaw),
                    &crate::common::limits(),
                )?;
                let disp = sl_io::depth::nyu_raw_to_disparity(&raw.values, sl_io::depth::NYU_DOFF);
                let t = Instant::now();
                let seg = ex.extract_disparity(&disp, &camera)?;
                (seg, t.elapsed().as_secs_f64() * 1e3)
            } else {
                let t = Instant::now();
                let seg = ex.extract_depth(&loaded.depth, &camera)?;
                (seg, t.elapsed().as_secs_f64() * 1e3)
            };
            if args.explain {
                explained = ex.explain_unlabelled(&out.0, args.min_pixels);
            }
            noise_scale = Some(ex.noise_scale());
            noise_beyond_threshold = ex.noise_beyond_threshold();
            out
        }
        "metric-ransac" => {
            let mut cfg = RansacConfig::default();
            cfg.threshold_m = args.threshold_m;
            cfg.min_pixels = args.min_pixels;
            let t = Instant::now();
            let seg = metric_ransac(&loaded.depth, &camera, &cfg)?;
            (seg, t.elapsed().as_secs_f64() * 1e3)
        }
        other => bail!("unknown --method {other:?}: use disparity or metric-ransac"),
    };
    // The overlay (which reads --color) is built before the first byte is written.
    let overlay = match &args.overlay {
        Some(path) => Some((
            path,
            build_overlay(args.color.as_deref(), &loaded.depth, &seg)?,
        )),
        None => None,
    };
    sl_io::write_gray16_png(&args.output, &seg.labels)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if let Some((path, img)) = &overlay {
        sl_io::write_rgb_png(path, img).with_context(|| format!("writing {}", path.display()))?;
    }
    if args.json {
        let mut v = segmentation_json(&seg, ms);
        if let Some(f) = noise_scale {
            v["noise_scale"] = json!(f);
            v["noise_beyond_threshold"] = json!(noise_beyond_threshold);
        }
        if args.explain {
            v["unlabelled"] = explain_json(&explained);
        }
        print_json(&v)?;
    } else {
        outln!(
            "{} planes in {:.2} ms ({})",
            seg.planes.len(),
            ms,
            args.method
        )?;
        if let Some(f) = noise_scale.filter(|&f| f > 1.0) {
            outln!(
                "  the frame is noisier than the camera model: its disparity-error variance is {f:.2}x the model's, used for every test (--model-noise-only to keep the model)"
            )?;
        }
        if noise_beyond_threshold {
            outln!(
                "  no plane extracted: the frame's measured disparity noise exceeds --threshold-px {} (a true plane would keep fewer than 68 % of its pixels within it); a sensor this noisy needs a larger --threshold-px",
                args.threshold_px
            )?;
        }
        for p in &seg.planes {
            let n = p.plane.normal;
            outln!(
                "  #{:<3} {:>7} px  normal [{:+.3} {:+.3} {:+.3}] ±{:.2}°  offset {:.3} m ±{:.1} mm  rms {:.3} px / {:.1} mm",
                p.id,
                p.pixels,
                n.x,
                n.y,
                n.z,
                p.normal_sigma_deg,
                p.plane.offset_m,
                p.offset_sigma_m * 1e3,
                p.rms_px,
                p.rms_m * 1e3
            )?;
        }
        if args.explain {
            // `--min-pixels` counts the sensor's pixels; a decimated frame's regions are given
            // in its own.
            let s = camera.pixels_per_sensor_pixel();
            if (s - 1.0).abs() > 1e-9 {
                outln!(
                    "{} unlabelled regions of at least {} px of the sensor ({:.0} px of this frame):",
                    explained.len(),
                    args.min_pixels,
                    args.min_pixels as f64 * s * s
                )?;
            } else {
                outln!(
                    "{} unlabelled regions of at least {} px:",
                    explained.len(),
                    args.min_pixels
                )?;
            }
            for r in &explained {
                outln!(
                    "  {:>7} px  box [{} {} {} {}]  LoG-rejected {:.0} %  residual-rejected {:.0} %  rms {:.2} px: {}",
                    r.pixels,
                    r.bbox_px[0],
                    r.bbox_px[1],
                    r.bbox_px[2],
                    r.bbox_px[3],
                    100.0 * r.log_rejected_fraction,
                    100.0 * r.residual_rejected_fraction,
                    r.rms_px,
                    r.reason.describe()
                )?;
            }
        }
    }
    Ok(())
}

/// The JSON list of the unlabelled regions and why.
fn explain_json(regions: &[RegionExplanation]) -> serde_json::Value {
    regions
        .iter()
        .map(|r| {
            json!({
                "pixels": r.pixels,
                "bbox_px": r.bbox_px,
                "reason": format!("{:?}", r.reason),
                "why": r.reason.describe(),
                "log_rejected_fraction": round_to(r.log_rejected_fraction, 4),
                "residual_rejected_fraction": round_to(r.residual_rejected_fraction, 4),
                "rms_px": finite_or_null(r.rms_px, 4),
            })
        })
        .collect()
}

/// `v` rounded to `digits` decimals, or `null` when not finite (an undetermined plane).
fn finite_or_null(v: f64, digits: i32) -> serde_json::Value {
    if v.is_finite() {
        json!(round_to(v, digits))
    } else {
        serde_json::Value::Null
    }
}

/// The JSON description of a segmentation.
pub fn segmentation_json(seg: &PlaneSegmentation, ms: f64) -> serde_json::Value {
    let planes: Vec<_> = seg
        .planes
        .iter()
        .map(|p| {
            json!({
                "id": p.id,
                "pixels": p.pixels,
                "normal": [round_to(p.plane.normal.x, 6), round_to(p.plane.normal.y, 6), round_to(p.plane.normal.z, 6)],
                "offset_m": round_to(p.plane.offset_m, 6),
                "disparity_affine": [p.affine.a, p.affine.b, p.affine.c],
                "rms_px": round_to(p.rms_px, 5),
                "rms_m": round_to(p.rms_m, 6),
                "centroid_m": [round_to(p.centroid_m.x, 4), round_to(p.centroid_m.y, 4), round_to(p.centroid_m.z, 4)],
                "normal_sigma_deg": finite_or_null(p.normal_sigma_deg, 4),
                "offset_sigma_m": finite_or_null(p.offset_sigma_m, 6),
            })
        })
        .collect();
    json!({ "planes": planes, "ms": round_to(ms, 3) })
}

fn build_overlay(
    color: Option<&std::path::Path>,
    depth: &sl_core::DepthImage,
    seg: &PlaneSegmentation,
) -> Result<Image<[u8; 3]>> {
    let (w, h) = seg.labels.dimensions();
    let base: Vec<u8> = match color {
        Some(c) => {
            let img = sl_io::rgb::read_rgb_with_limits(c, &crate::common::limits())
                .with_context(|| format!("reading {}", c.display()))?;
            if img.dimensions() != (w, h) {
                bail!(
                    "{}: colour image is {}x{}, depth is {w}x{h}",
                    c.display(),
                    img.width(),
                    img.height()
                );
            }
            img.data().iter().flatten().copied().collect()
        }
        None => overlay::depth_to_rgb(depth),
    };
    let rgb = overlay::overlay_rgb(&seg.labels, &base, 0.6).context("overlay size mismatch")?;
    let pixels: Vec<[u8; 3]> = rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(Image::from_vec(w, h, pixels)?)
}
