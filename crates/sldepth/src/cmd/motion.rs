//! `sldepth motion`: camera motion between two depth frames from matched planes (paper
//! section 3.5), optionally refined by point-to-plane ICP.

use std::path::PathBuf;

use anyhow::{Result, bail};
use serde_json::json;
use sl_planes::{
    IcpConfig, MotionConfig, PlaneConfig, PlaneExtractor, estimate_motion, icp_point_to_plane,
};

use crate::common::{InputArgs, load_depth, print_json, round_to};

/// Arguments of `sldepth motion`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Depth map of frame A (the reference).
    pub depth_a: PathBuf,
    /// Depth map of frame B.
    pub depth_b: PathBuf,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Refine with point-to-plane ICP (starting from the plane estimate).
    #[arg(long)]
    pub icp: bool,
    /// Disparity residual threshold of the plane extraction, pixels.
    #[arg(long, default_value_t = PlaneConfig::default().threshold_px)]
    pub threshold_px: f64,
    /// Minimum pixels of a plane.
    #[arg(long, default_value_t = PlaneConfig::default().min_pixels)]
    pub min_pixels: usize,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth motion`.
pub fn run(args: Args) -> Result<()> {
    let a = load_depth(&args.depth_a, &args.input)?;
    let b = load_depth(&args.depth_b, &args.input)?;
    if a.camera != b.camera
        || a.depth.width() != b.depth.width()
        || a.depth.height() != b.depth.height()
    {
        bail!("the two frames must come from the same camera and have the same size");
    }
    let cfg = PlaneConfig {
        threshold_px: args.threshold_px,
        min_pixels: args.min_pixels,
        ..PlaneConfig::default()
    };
    let mut ex = PlaneExtractor::new(cfg)?;
    let pa = ex.extract_depth(&a.depth, &a.camera)?;
    let pb = ex.extract_depth(&b.depth, &b.camera)?;
    let m = estimate_motion(&pa.planes, &pb.planes, None, &MotionConfig::default())?;
    let mut pose = m.isometry();
    let mut icp_json = serde_json::Value::Null;
    if args.icp {
        let r = icp_point_to_plane(&a.depth, &b.depth, &a.camera, &pose, &IcpConfig::default())?;
        icp_json = json!({ "inliers": r.inliers, "rms_m": round_to(r.rms_m, 6) });
        pose = r.pose;
    }
    let rot = pose.rotation.to_rotation_matrix();
    let rm = rot.matrix();
    let rotation: Vec<f64> = (0..3)
        .flat_map(|i| (0..3).map(move |j| round_to(rm[(i, j)], 7)))
        .collect();
    let rotation_deg = pose.rotation.angle().to_degrees();
    let translation = if args.icp {
        Some(pose.translation.vector)
    } else {
        m.translation_m
    };
    let matched: Vec<_> = m
        .matches
        .iter()
        .map(|mt| json!({ "a": pa.planes[mt.a].id, "b": pb.planes[mt.b].id, "weight": mt.weight }))
        .collect();
    if args.json {
        print_json(&json!({
            "rotation": rotation,
            "rotation_deg": round_to(rotation_deg, 4),
            "translation_m": translation.map(|t| vec![round_to(t.x, 5), round_to(t.y, 5), round_to(t.z, 5)]),
            "matched_planes": matched,
            "planes_a": pa.planes.len(),
            "planes_b": pb.planes.len(),
            "rms_angle_deg": round_to(m.rms_angle_deg, 4),
            "icp": icp_json,
        }));
    } else {
        println!(
            "planes: {} in A, {} in B, {} matched",
            pa.planes.len(),
            pb.planes.len(),
            m.matches.len()
        );
        println!("rotation (X_a = R X_b + t), {rotation_deg:.3} deg:");
        for i in 0..3 {
            println!(
                "  [{:+.6} {:+.6} {:+.6}]",
                rm[(i, 0)],
                rm[(i, 1)],
                rm[(i, 2)]
            );
        }
        match translation {
            Some(t) => println!("translation: [{:+.4} {:+.4} {:+.4}] m", t.x, t.y, t.z),
            None => println!("translation: not determined (matched normals do not span 3D)"),
        }
    }
    Ok(())
}
