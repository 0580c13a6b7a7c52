//! `sldepth info`: size and depth statistics of a depth map; the topics of a ROS bag.

use std::path::PathBuf;

use anyhow::Result;
use serde_json::json;

use crate::common::{InputArgs, load_depth, print_json, round_to};

/// Options of `sldepth info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Depth map (16-bit PNG/TIFF, float TIFF, NYU raw PGM, SUN PNG), or a robot recording — a
    /// ROS 1 bag (`.bag`), a ROS 2 bag in MCAP or SQLite (`.mcap`, `.db3`, or its folder), a
    /// RealSense recording —: its topics, their message types and counts, and the depth topic
    /// `sldepth track` takes.
    #[arg(value_name = "DEPTH|BAG")]
    pub depth: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth info`.
pub fn run(args: Args) -> Result<()> {
    if sl_io::rosbag::is_bag_file(&args.depth) {
        return bag_info(&args);
    }
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

/// The topics of a ROS bag and the depth topic `track` would take (or why none), with the
/// camera and depth units it would read it with.
fn bag_info(args: &Args) -> Result<()> {
    let mut bag = sl_io::rosbag::RosBag::open(&args.depth, &crate::common::limits())?;
    crate::recording::note_split_piece(&args.depth);
    let topics = bag.topics();
    let depth = bag.depth_topic(None);
    let realsense = match &depth {
        Ok(t) => bag.realsense(t)?,
        Err(_) => None,
    };
    // The units of 16-bit depth (none for float depth, which is metres).
    let units = match &depth {
        Ok(t) => {
            let first = bag.messages(t)?.first().copied();
            let kind = match first {
                Some(m) => bag.depth_kind(&m)?,
                None => None,
            };
            match kind {
                Some(sl_io::rosbag::DepthEncodingKind::F32) => None,
                _ => Some(bag.depth_units_per_m(t)?),
            }
        }
        Err(_) => None,
    };
    let camera = match &depth {
        Ok(t) => bag.depth_camera(t).map_err(|e| e.to_string()),
        Err(_) => Err("no depth topic".to_string()),
    };
    // The frame the depth images name, and the transforms `fuse --tf` would pose it by.
    let image_frame = match &depth {
        Ok(t) => match bag.messages(t)?.first().copied() {
            Some(m) => Some(bag.image_frame_id(&m)?),
            None => None,
        },
        Err(_) => None,
    };
    let other_trees: Vec<String> = bag
        .tf_namespaces()
        .into_iter()
        .filter(|ns| !ns.is_empty())
        .collect();
    let transforms = if bag.tf_topics().is_empty() {
        Ok((Vec::new(), 0))
    } else {
        bag.transforms()
            .map(|t| (t.frames(), t.skipped()))
            .map_err(|e| e.to_string())
    };
    if args.json {
        let list: Vec<_> = topics
            .iter()
            .map(|t| json!({"topic": t.topic, "type": t.message_type, "messages": t.messages}))
            .collect();
        print_json(&json!({
            "path": args.depth.display().to_string(),
            "container": bag.container(),
            "files": bag.files(),
            "topics": list,
            "depth_topic": depth.as_ref().ok(),
            "depth_units_per_m": units,
            "camera": camera.as_ref().ok().map(|c| json!({
                "camera_info_topic": c.camera_info_topic,
                "fx": c.camera.intrinsics.fx,
                "width": c.camera.intrinsics.width,
                "height": c.camera.intrinsics.height,
                "baseline_m": c.camera.sensor.baseline_m,
                "subpixel_steps": c.camera.sensor.subpixel_steps,
                "noise_model": c.sensor_source,
            })),
            "image_frame": image_frame,
            "transforms": match &transforms {
                Ok((frames, _)) => json!(frames.iter().map(|f| json!({
                    "frame": f.frame,
                    "parent": f.parent,
                    "static": f.is_static,
                    "republished_constant": f.republished_constant,
                    "samples": f.samples,
                    "first_s": f.first_s,
                    "last_s": f.last_s,
                })).collect::<Vec<_>>()),
                Err(e) => json!({"error": e}),
            },
            "transforms_left_out": transforms.as_ref().ok().map(|t| t.1),
            // Namespaces of other trees (`/robot1/tf`), which `--tf-namespace` chooses.
            "tf_namespaces": &other_trees,
            "realsense": realsense.as_ref().map(|r| json!({
                "device": r.device_name,
                "depth_units_m": r.depth_units_m,
                "stereo_baseline_m": r.stereo_baseline_m,
            })),
        }))?;
    } else {
        let files = match bag.files() {
            1 => String::new(),
            n => format!(", in {n} files"),
        };
        outln!("{} ({}{files})", args.depth.display(), bag.container())?;
        for t in &topics {
            outln!("  {}  {}  {} messages", t.topic, t.message_type, t.messages)?;
        }
        match &depth {
            Ok(t) => outln!("  depth topic   {t} (what `sldepth track` reads)")?,
            Err(e) => outln!("  depth topic   none chosen: {e}")?,
        }
        if let Some(r) = &realsense {
            outln!(
                "  RealSense     {}",
                r.device_name.as_deref().unwrap_or("device not named")
            )?;
        }
        if let Some(u) = units.filter(|&u| u != sl_io::depth::DEFAULT_UNITS_PER_M) {
            outln!(
                "  depth units   {} mm (16-bit values, as recorded)",
                crate::common::num(1e3 / u)
            )?;
        }
        match &camera {
            Ok(c) => outln!(
                "  camera        {} (fx {}, {}x{}) with {}",
                c.camera_info_topic,
                crate::common::num(c.camera.intrinsics.fx),
                c.camera.intrinsics.width,
                c.camera.intrinsics.height,
                c.sensor_source
            )?,
            Err(e) if depth.is_ok() => outln!("  camera        none: {e}")?,
            Err(_) => {}
        }
        if let Some(f) = image_frame.as_deref().filter(|f| !f.is_empty()) {
            outln!("  image frame   {}", f.escape_debug())?;
        }
        match &transforms {
            Ok((frames, 0)) if frames.is_empty() => {}
            Ok((frames, skipped)) => {
                outln!(
                    "  transforms    (`sldepth fuse REC --tf WORLD_FRAME` poses the image frame by them)"
                )?;
                for f in frames {
                    let when = if f.is_static {
                        "static".to_string()
                    } else {
                        format!(
                            "{} samples, {:.3}–{:.3} s{}",
                            f.samples,
                            f.first_s,
                            f.last_s,
                            if f.republished_constant {
                                ", never changed"
                            } else {
                                ""
                            }
                        )
                    };
                    outln!(
                        "    {} → {}  {when}",
                        f.parent.escape_debug(),
                        f.frame.escape_debug()
                    )?;
                }
                if *skipped > 0 {
                    outln!(
                        "    ({skipped} left out: numbers that make no rigid transform, or no \
                         proper frame name)"
                    )?;
                }
            }
            Err(e) => outln!("  transforms    unreadable: {e}")?,
        }
        if !other_trees.is_empty() {
            outln!(
                "  other trees   {} (`--tf-namespace NS` chooses one)",
                other_trees
                    .iter()
                    .map(|n| n.escape_debug().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
    }
    Ok(())
}
