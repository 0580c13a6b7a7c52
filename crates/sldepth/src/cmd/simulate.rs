//! `sldepth simulate`: render a named synthetic scene through the Kinect noise model.

use std::num::IntErrorKind;
use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use clap::builder::PossibleValuesParser;
use sl_noise::NoiseError;
use sl_noise::sim::{KinectSimulator, NoiseModel, RealisticNoise, SCENE_NAMES, named_scene};

use crate::common::{
    check_depth_scale, check_distinct_outputs, check_output, limits, load_camera, output_encoding,
    print_json, save_depth,
};

/// Options of `sldepth simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene to render: floor, wall, figure-walls, three-planes, corridor, relief, boxes.
    #[arg(long, value_name = "NAME", value_parser = PossibleValuesParser::new(sl_noise::sim::SCENE_NAMES))]
    pub scene: String,
    /// Noisy depth output (16-bit PNG or TIFF, `--depth-scale` units per metre).
    #[arg(long, short, value_name = "DEPTH.png")]
    pub output: PathBuf,
    /// Seed of the noise (the same seed gives the same frame on every machine).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also write the noise-free depth (same encoding; use --depth-scale 5000 or more for
    /// sub-millimetre truth).
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Also write the surface labels as a 16-bit PNG (0 = background, 1.. = surfaces).
    #[arg(long, value_name = "FILE.png")]
    pub labels: Option<PathBuf>,
    /// Depth units per metre of the written files (default 1000 = millimetres).
    #[arg(long, value_name = "UNITS_PER_M", default_value_t = 1000.0)]
    pub depth_scale: f64,
    /// Camera to simulate instead of the scene's kinect-v1 camera: a preset name (`sldepth
    /// cameras`) or a camera JSON file (its intrinsics, baseline and sub-pixel steps are used).
    #[arg(long, value_name = "NAME|FILE")]
    pub camera: Option<PathBuf>,
    /// Disparity noise sigma, pixels (default: the sensor model's 0.07 px).
    #[arg(long, value_name = "PX")]
    pub sigma_d_px: Option<f64>,
    /// Noise model: `realistic` (the default: block-matching-correlated disparity error,
    /// quantisation, occlusion bands and drop-outs, fitted to real Kinect frames) or `white`
    /// (the paper's idealised independent Gaussian disparity noise).
    #[arg(long, value_name = "MODEL", default_value = "realistic", value_parser = PossibleValuesParser::new(["realistic", "white"]))]
    pub noise: String,
    /// Block-matching window of the realistic model, `WxH` pixels (default 9x11, fitted to the
    /// autocorrelation of real Kinect frames: docs/NOISE_MODEL.md).
    #[arg(long, value_name = "WxH")]
    pub window: Option<String>,
    /// Speckle size of the realistic model, pixels (default 1).
    #[arg(long, value_name = "PX")]
    pub speckle: Option<usize>,
    /// Drop out weak returns (realistic model): a pixel is invalid when its surface returns
    /// less of the pattern than this, relative to a white surface facing the camera at 1 m
    /// (`reflectance·cos θ / r²`, r in metres). Default 0 = off; 0.04 puts a white surface's
    /// limit at 5 m and a black one's (reflectance 0.1) at 1.6 m.
    #[arg(long, value_name = "R")]
    pub min_return: Option<f64>,
    /// Infrared reflectance of a surface, `LABEL=R` with R in [0, 1] (labels as --labels
    /// writes them; every other surface reflects 1). Repeatable. Only the realistic model's
    /// drop-out of weak returns reads it: an error without a positive --min-return.
    #[arg(long, value_name = "LABEL=R")]
    pub reflectance: Vec<String>,
    /// Print a JSON summary.
    #[arg(long)]
    pub json: bool,
}

/// Runs `sldepth simulate`.
pub fn run(args: Args) -> Result<()> {
    if !SCENE_NAMES.contains(&args.scene.as_str()) {
        bail!(
            "unknown scene {:?}; choose one of: {}",
            args.scene,
            SCENE_NAMES.join(", ")
        );
    }
    check_depth_scale(args.depth_scale)?;
    check_output("--output", &args.output, &["png", "tif", "tiff"])?;
    if let Some(t) = &args.truth {
        check_output("--truth", t, &["png", "tif", "tiff"])?;
    }
    if let Some(l) = &args.labels {
        check_output("--labels", l, &["png"])?;
    }
    check_distinct_outputs(&[
        ("--output", Some(&args.output)),
        ("--truth", args.truth.as_deref()),
        ("--labels", args.labels.as_deref()),
    ])?;
    let min_return = args.min_return.unwrap_or(0.0);
    if !(min_return.is_finite() && min_return >= 0.0) {
        bail!(
            "--min-return {}: must be a finite number >= 0 (0 = off)",
            crate::common::num(min_return)
        );
    }
    // 0 is the default (off), which the white model has too, as Python's `simulate`.
    if args.noise == "white" && min_return != 0.0 {
        bail!("--min-return is a drop-out of the realistic model; the white model has none");
    }
    let mut named = named_scene(&args.scene)?;
    for spec in &args.reflectance {
        let malformed = || anyhow!("--reflectance {spec}: expected LABEL=R, e.g. 2=0.1");
        let (l, r) = spec.split_once('=').ok_or_else(malformed)?;
        let (l, r) = (l.trim(), r.trim());
        let rho = r.parse::<f64>().map_err(|_| malformed())?;
        // A whole number beyond the 16-bit labels is well formed: it names no surface.
        let label = match l.parse::<i128>() {
            Ok(v) => u16::try_from(v).ok(),
            Err(e)
                if matches!(
                    e.kind(),
                    IntErrorKind::PosOverflow | IntErrorKind::NegOverflow
                ) =>
            {
                None
            }
            Err(_) => return Err(malformed()),
        };
        match label {
            Some(label) => named.scene.set_reflectance(label, rho),
            None => Err(NoiseError::InvalidParameter(format!(
                "no surface {l} (the scene has labels 1..={})",
                named.scene.len()
            ))),
        }
        .with_context(|| format!("--reflectance {spec} (scene {})", args.scene))?;
    }
    // A reflectance read by nothing would be a silent no-op (and the JSON would show it).
    if !args.reflectance.is_empty() {
        if args.noise == "white" {
            bail!(
                "--reflectance has no effect with --noise white: only the realistic model's \
                 drop-out of weak returns (a positive --min-return) reads a reflectance"
            );
        }
        if min_return == 0.0 {
            bail!(
                "--reflectance has no effect without a positive --min-return: only the \
                 realistic model's drop-out of weak returns reads a reflectance, and \
                 --min-return 0 (the default) turns it off"
            );
        }
    }
    let (intrinsics, mut sim) = match &args.camera {
        Some(_) => {
            let cam = load_camera(&crate::common::InputArgs {
                camera: args.camera.clone(),
                ..Default::default()
            })?;
            (cam.intrinsics, KinectSimulator::with_sensor(cam.sensor))
        }
        None => (named.intrinsics, KinectSimulator::kinect_v1()),
    };
    // A camera preset name selects that data set's realistic model (registration to colour).
    let mut realistic = args
        .camera
        .as_ref()
        .map(|c| RealisticNoise::for_camera(&c.to_string_lossy()))
        .unwrap_or_default();
    if let Some(wh) = &args.window {
        let parsed = wh.split_once(['x', 'X']).and_then(|(a, b)| {
            Some((
                a.trim().parse::<usize>().ok()?,
                b.trim().parse::<usize>().ok()?,
            ))
        });
        let Some((wx, wy)) = parsed else {
            bail!("--window {wh}: expected WxH, e.g. 9x11");
        };
        realistic.window_x = wx;
        realistic.window_y = wy;
    }
    if let Some(sp) = args.speckle {
        realistic.speckle_px = sp;
    }
    realistic.min_return = min_return;
    realistic.validate()?;
    sim.noise = match args.noise.as_str() {
        "white" => NoiseModel::White,
        _ => NoiseModel::Realistic(realistic),
    };
    if let Some(s) = args.sigma_d_px {
        if !(s.is_finite() && (0.0..=100.0).contains(&s)) {
            bail!(
                "--sigma-d-px {}: must be a number from 0 to 100 pixels",
                crate::common::num(s)
            );
        }
        sim.sensor.sigma_d_px = s;
    }
    // The frame, the truth and the labels are allocated at the camera's size: check it first.
    limits()
        .check_pixels(intrinsics.width as u64, intrinsics.height as u64)
        .map_err(|m| anyhow::anyhow!("camera: {m}"))?;
    let frame = sim.simulate(&named.scene, &intrinsics, &named.pose, args.seed);
    let encoding = sl_io::depth::DepthEncoding::png(args.depth_scale);
    let enc_for = |p: &PathBuf| output_encoding(p, &encoding);
    let out_enc = enc_for(&args.output)?;
    let truth_enc = args.truth.as_ref().map(enc_for).transpose()?;
    save_depth(&args.output, &frame.depth, &out_enc)?;
    if let (Some(t), Some(enc)) = (&args.truth, truth_enc) {
        save_depth(t, &frame.truth, &enc)?;
    }
    if let Some(l) = &args.labels {
        sl_io::rgb::write_gray16_png(l, &frame.labels)
            .with_context(|| format!("writing {}", l.display()))?;
    }
    let valid = frame.depth.valid_count();
    if args.json {
        print_json(&serde_json::json!({
            "scene": named.name,
            "seed": args.seed,
            "noise": args.noise,
            "width": frame.depth.width(),
            "height": frame.depth.height(),
            "valid_pixels": valid,
            "min_return": min_return,
            "surfaces": named.label_names.iter().map(|(l, n)| serde_json::json!({"label": l, "name": n, "reflectance": named.scene.reflectance(*l)})).collect::<Vec<_>>(),
        }))?;
    } else {
        errln!(
            "{}: {} ({} valid pixels) -> {}",
            named.name,
            named.description,
            valid,
            args.output.display()
        );
    }
    Ok(())
}
