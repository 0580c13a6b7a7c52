//! `sldepth filter`: Gaussian, bilateral, adaptive bilateral (σ_d = k·Z², the paper's eq. 6) and
//! disparity-domain bilateral smoothing of a depth map (paper section 3.1–3.2); `adaptive` (the
//! default) and `disparity` are followed by the coarse passes of `sl_filter::MultiScale` unless
//! `--single-scale` is given.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use serde_json::json;
use sl_filter::{
    DepthFilter, FilterConfig, Isa, MAX_RADIUS_PX, Method, MultiScale, RangeKernel, Window,
};

use crate::common::{
    DEPTH_EXTS, InputArgs, check_distinct_outputs, check_output, check_outputs_spare_inputs,
    load_depth, num, output_encoding, print_json, round_to, save_depth,
};

/// Most `--repeat` runs (a timing loop, not a way to keep the machine busy for days).
const MAX_REPEAT: usize = 100_000;

/// Options of `sldepth filter`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input depth map (16-bit PNG/TIFF, float TIFF, NYU raw PGM, SUN PNG).
    #[arg(value_name = "IN")]
    pub input_path: PathBuf,
    /// Output depth map, written in the input's encoding and depth scale: `.png` or `.tif`
    /// (a NYU raw input: millimetres; a float TIFF input: a float `.tif` at its scale, a
    /// millimetre `.png`), or `.pgm` for a NYU raw input only (NYU raw Kinect disparity;
    /// refused for any other input).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,
    /// Filter: `gaussian`, `bilateral` (fixed range σ), `adaptive` (σ_d = k·Z², from the sensor
    /// model: no tuning needed) or `disparity` (bilateral on D = f·B/Z with a constant σ).
    #[arg(long, default_value = "adaptive", value_parser = PossibleValuesParser::new(Method::NAMES).try_map(|s| s.parse::<Method>()))]
    pub method: Method,
    /// Window radius, pixels (window = 2r+1 square; 2 and 3 are the fast paths; at most 32).
    /// Default 3, or ceil(2·σ_s) when only --sigma-s is given.
    #[arg(long, value_name = "PX")]
    pub radius: Option<usize>,
    /// Spatial σ, pixels. Default radius/2. Without --radius the window grows to ceil(2·σ_s),
    /// at most 32 px: a larger σ_s needs --radius.
    #[arg(long, value_name = "PX")]
    pub sigma_s: Option<f64>,
    /// Window shape: `square` (every pixel of the 2r+1 square) or `disc` (dx² + dy² ≤ r²,
    /// OpenCV's bilateralFilter window: 13 taps at 5×5, 29 at 7×7, about half the time).
    #[arg(long, default_value = "square", value_parser = PossibleValuesParser::new(Window::NAMES).try_map(|s| s.parse::<Window>()))]
    pub window_shape: Window,
    /// Range σ of `--method bilateral`, metres. Default: the adaptive σ at 2 m, k·(2 m)².
    #[arg(long, value_name = "M")]
    pub sigma_d_m: Option<f64>,
    /// k of `--method adaptive` (σ_d = k·Z²), per metre. Default m·σ_D/(f·B) from the camera's
    /// sensor model (m = sl_filter::DEFAULT_K_MULTIPLIER).
    #[arg(long = "k", value_name = "PER_M")]
    pub k_per_m: Option<f64>,
    /// Range σ of `--method disparity`, disparity pixels. Default m·σ_D.
    #[arg(long, value_name = "PX")]
    pub sigma_disp_px: Option<f64>,
    /// Run the filter N times on the loaded frame and report the median and minimum time of
    /// the filtering alone (no I/O). Threads: RAYON_NUM_THREADS (default: all cores).
    #[arg(long, value_name = "N")]
    pub repeat: Option<usize>,
    /// Kernel instruction set, for benchmarks: `portable`, `avx2` or `avx512` (default: the best
    /// this CPU supports; one it does not support falls back to `portable`), for every pass.
    #[arg(long, value_parser = ["portable", "avx2", "avx512"])]
    pub isa: Option<String>,
    /// Print a JSON summary (parameters and timing) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write a shaded-normals rendering of the result (PNG).
    #[arg(long, value_name = "FILE.png")]
    pub normals: Option<PathBuf>,
    /// Follow the filter with the coarse passes of `sl_filter::MultiScale` (5×5 disparity-domain
    /// bilateral passes with taps 2, 4 and 8 px apart, range σ m·σ_D), which remove the spatially
    /// correlated error of real frames that a 7×7 window cannot. The default for `adaptive` and
    /// `disparity`; this flag adds them to `gaussian` and `bilateral` too.
    #[arg(long, conflicts_with = "single_scale")]
    pub multiscale: bool,
    /// Only the one pass of `--method` (the paper's filter), without the coarse passes that
    /// follow `adaptive` and `disparity` by default.
    #[arg(long)]
    pub single_scale: bool,
    /// Filter with the camera's noise model as given. By default the frame's own disparity
    /// noise is measured on its 16×16- and 32×32-pixel patches (as `sldepth planes` and `noise-stats` do)
    /// and, when it is significantly larger than the model's, the range kernels follow the
    /// measured σ_D (the camera's σ_D a floor): a sensor noisier than its preset says is
    /// otherwise under-smoothed (simulated frames at twice the model's σ_D: floor 8.3 → 7.6 mm
    /// RMSE, corridor 0.121 → 0.106 px; docs/bench/README.md, session 49). Explicit range
    /// parameters (`--k-per-m`, `--sigma-d-m`, `--sigma-disp-px`) win either way.
    #[arg(long)]
    pub model_noise_only: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

/// The filter the options describe, for a camera's sensor model.
pub fn build_filter(args: &Args, sensor: &sl_core::SensorModel) -> Result<DepthFilter> {
    if let (None, Some(s)) = (args.radius, args.sigma_s) {
        let r = (2.0 * s).ceil();
        if s.is_finite() && r > MAX_RADIUS_PX as f64 {
            bail!(
                "--sigma-s {}: the window radius it implies, ceil(2·σ_s) = {} px, exceeds the \
                 maximum {MAX_RADIUS_PX} px; pass --radius (at most {MAX_RADIUS_PX}) to keep \
                 this σ_s in a smaller window",
                num(s),
                num(r)
            );
        }
    }
    let mut config = FilterConfig::new(args.method);
    config.radius_px = args.radius;
    config.sigma_s_px = args.sigma_s;
    config.window = args.window_shape;
    config.sigma_d_m = args.sigma_d_m;
    config.k_per_m = args.k_per_m;
    config.sigma_disp_px = args.sigma_disp_px;
    Ok(config.build(sensor)?)
}

/// Runs `sldepth filter`.
pub fn run(args: Args) -> Result<()> {
    check_output("OUT", &args.output, &DEPTH_EXTS)?;
    if let Some(p) = &args.normals {
        check_output("--normals", p, &["png"])?;
    }
    let outputs = [
        ("OUT", Some(args.output.as_path())),
        ("--normals", args.normals.as_deref()),
    ];
    check_distinct_outputs(&outputs)?;
    check_outputs_spare_inputs(&outputs, [args.input_path.as_path()])?;
    let reps = args.repeat.unwrap_or(1);
    if !(1..=MAX_REPEAT).contains(&reps) {
        bail!("--repeat {reps}: must be from 1 to {MAX_REPEAT}");
    }
    let loaded = load_depth(&args.input_path, &args.input)?;
    // The frame's own noise against the camera's model.
    let noise_scale = if args.model_noise_only {
        1.0
    } else {
        sl_planes::frame_noise_scale(
            &loaded.depth,
            &loaded.camera,
            &sl_planes::PlaneConfig::default(),
        )
        .context("measuring the frame's noise against the camera's model")?
    };
    let sensor = loaded.camera.sensor.with_variance_scale(noise_scale);
    let filter = build_filter(&args, &sensor)?;
    let out_encoding = output_encoding(&args.output, &loaded.encoding)?;
    let multi = (args.multiscale
        || (!args.single_scale && sl_filter::multiscale_by_default(args.method)))
    .then(|| MultiScale {
        base: filter,
        ..MultiScale::default_for(&sensor)
    });
    let isa = match args.isa.as_deref() {
        None => Isa::detect(),
        Some(name) => Isa::from_name(name).unwrap_or(Isa::Portable),
    };
    let isa = if isa.is_supported() {
        isa
    } else {
        Isa::Portable
    };
    let apply = |d: &sl_core::DepthImage| match &multi {
        Some(m) => m.apply_with_isa(d, isa),
        None => filter.apply_with_isa(d, isa),
    };
    let mut times_ms = Vec::with_capacity(reps);
    if args.repeat.is_some() {
        // Warm-up: page in the buffers and the per-thread scratch.
        apply(&loaded.depth)?;
    }
    let mut out = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let o = apply(std::hint::black_box(&loaded.depth))?;
        times_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        out = Some(o);
    }
    let Some(out) = out else {
        bail!("no filter run");
    };
    // Everything that can fail is computed before the first byte is written.
    let normals = match &args.normals {
        Some(p) => Some((
            p,
            sl_eval::render::shaded_normals(&out, &loaded.camera.intrinsics)?,
        )),
        None => None,
    };
    save_depth(&args.output, &out, &out_encoding)?;
    if let Some((p, img)) = &normals {
        sl_io::write_rgb_png(p, img).with_context(|| format!("writing {}", p.display()))?;
    }
    times_ms.sort_by(f64::total_cmp);
    let median = times_ms[times_ms.len() / 2];
    let min = times_ms[0];
    let (k_per_m, sigma_d_m, sigma_disp_px) = match filter.range {
        RangeKernel::Adaptive { k_per_m } => (Some(k_per_m), None, None),
        RangeKernel::Fixed { sigma_d_m } => (None, Some(sigma_d_m), None),
        RangeKernel::Disparity { sigma_disp_px, .. } => (None, None, Some(sigma_disp_px)),
        RangeKernel::None => (None, None, None),
    };
    if args.json {
        let mut v = json!({
            "input": args.input_path.display().to_string(),
            "output": args.output.display().to_string(),
            "method": filter.method().name(),
            "radius": filter.radius_px,
            "window": filter.window.name(),
            "sigma_s_px": filter.sigma_s_px,
            "k_per_m": k_per_m,
            "sigma_d_m": sigma_d_m,
            "sigma_disp_px": sigma_disp_px,
            "width": out.width(),
            "height": out.height(),
            "valid_pixels": out.valid_count(),
            "repeat": reps,
            "ms_median": round_to(median, 4),
            "ms_min": round_to(min, 4),
            "threads": sl_filter::current_threads(),
            "isa": isa.name(),
            "noise_scale": noise_scale,
            "sigma_d_px": sensor.sigma_d_px,
        });
        if let (Some(m), Some(obj)) = (&multi, v.as_object_mut()) {
            obj.insert("multiscale_dilations".into(), json!(m.dilations));
        }
        print_json(&v)?;
    } else {
        outln!(
            "{} -> {}: {} filter, {}x{} window, sigma_s {} px{}{}",
            args.input_path.display(),
            args.output.display(),
            filter.method(),
            2 * filter.radius_px + 1,
            2 * filter.radius_px + 1,
            filter.sigma_s_px,
            match (k_per_m, sigma_d_m, sigma_disp_px) {
                (Some(k), _, _) => format!(
                    ", k {k:.6} /m (sigma_d {:.1} mm at 1 m, {:.1} mm at 3 m)",
                    k * 1e3,
                    9.0 * k * 1e3
                ),
                (_, Some(s), _) => format!(", sigma_d {:.1} mm", s * 1e3),
                (_, _, Some(s)) => format!(", sigma_D {s:.3} px"),
                _ => String::new(),
            },
            match &multi {
                Some(m) => format!(
                    "; multi-scale: 5x5 disparity passes at dilations {:?} px",
                    m.dilations
                ),
                None => String::new(),
            }
        )?;
        if noise_scale > 1.0 {
            outln!(
                "  the frame's noise is {noise_scale:.2}x the camera model's variance: filtered for a σ_D of {:.3} px (--model-noise-only: the camera's {:.3} px)",
                sensor.sigma_d_px,
                loaded.camera.sensor.sigma_d_px
            )?;
        }
        outln!(
            "  {} valid pixels; filtering {:.3} ms (median of {reps}, min {:.3} ms, {} threads, {})",
            out.valid_count(),
            median,
            min,
            sl_filter::current_threads(),
            isa.name()
        )?;
    }
    Ok(())
}
