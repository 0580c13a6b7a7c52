//! `sldepth motion`: camera motion between two depth frames from matched planes (paper
//! section 3.5), checked against the depth data, optionally refined by point-to-plane ICP.
//!
//! `--icp` refines through `sl_track::refine_motion_icp_verified`: the ICP pose is kept only
//! when it is itself verified on the depth maps and explains no smaller a share of the
//! overlapping points than the estimate (`icp_accepted`, `icp_inlier_fraction` in the JSON);
//! otherwise the plane estimate is reported and the reason given.
//!
//! The plane hypotheses are verified on both depth maps (`sl_track::estimate_motion_verified`):
//! when no rotation explains the data, or two distinct ones do, or the shared view is nearly one
//! plane, the motion is reported as undetermined (with `--json`: `"determined": false`,
//! `"rotation": null` and the reason) and the command fails, instead of printing a wrong
//! rotation. `--no-verify` gives the plain plane estimate (prior: small motion), marked
//! `unverified` or `ambiguous`.

use std::path::PathBuf;

use anyhow::{Result, bail};
use serde_json::{Value, json};
use sl_core::CameraToCamera;
use sl_core::nalgebra::Vector3;
use sl_track::{DepthMotionConfig, IcpOutcome, PlaneConfig, TrackError, motion_between_depths};

use crate::common::{InputArgs, LensArgs, check_range, load_depth, print_json, round_to};

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
    /// Refine with point-to-plane ICP (from the verified alignment, or the plane estimate with
    /// `--no-verify`); the refinement is kept only when the depth data confirm it.
    #[arg(long)]
    pub icp: bool,
    /// Skip the check against the depth data: plane matching alone, assuming a small motion
    /// (the result may be ambiguous; see `confidence`).
    #[arg(long)]
    pub no_verify: bool,
    /// Disparity residual threshold of the plane extraction, pixels.
    #[arg(long, default_value_t = PlaneConfig::default().threshold_px)]
    pub threshold_px: f64,
    /// Minimum pixels of a plane, pixels of the sensor (frames of the sensor decimated by n,
    /// extracted on its grid, count n² per pixel).
    #[arg(long, default_value_t = PlaneConfig::default().min_pixels)]
    pub min_pixels: usize,
    #[command(flatten)]
    pub lens: LensArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

fn vec3(v: &Vector3<f64>, digits: i32) -> Value {
    json!([
        round_to(v.x, digits),
        round_to(v.y, digits),
        round_to(v.z, digits)
    ])
}

fn rotation_rows(pose: &CameraToCamera) -> Vec<f64> {
    let rot = pose.rotation().to_rotation_matrix();
    let rm = rot.matrix();
    (0..3)
        .flat_map(|i| (0..3).map(move |j| round_to(rm[(i, j)], 7)))
        .collect()
}

/// The JSON of an undecided estimate's candidates (`DepthMotion::candidates`).
fn candidates_json(candidates: &[CameraToCamera]) -> Value {
    candidates
        .iter()
        .map(|c| {
            json!({
                "rotation": rotation_rows(c),
                "rotation_deg": round_to(c.rotation_angle_deg(), 4),
                "translation_m": vec3(&c.translation(), 6),
            })
        })
        .collect()
}

/// The JSON of an undetermined motion.
fn undetermined_json(err: &TrackError, planes_a: usize, planes_b: usize) -> Value {
    let (inlier, alternative) = match err {
        TrackError::MotionNotVerified {
            inlier_fraction,
            alternative_inlier_fraction,
            ..
        } => (
            json!(round_to(*inlier_fraction, 4)),
            json!(round_to(*alternative_inlier_fraction, 4)),
        ),
        _ => (Value::Null, Value::Null),
    };
    json!({
        "determined": false,
        "confidence": "undetermined",
        "reason": err.to_string(),
        "rotation": Value::Null,
        "rotation_deg": Value::Null,
        "translation_m": Value::Null,
        "matched_planes": [],
        "planes_a": planes_a,
        "planes_b": planes_b,
        "inlier_fraction": inlier,
        "alternative_inlier_fraction": alternative,
    })
}

/// The JSON of a verified ICP refinement.
fn icp_outcome_json(o: &IcpOutcome) -> Value {
    json!({
        "accepted": o.accepted,
        "rejection": o.rejection.as_ref().map(|r| r.as_str()),
        "inliers": o.icp.as_ref().map(|r| r.inliers),
        "rms_m": o.icp.as_ref().map(|r| round_to(r.rms_m, 6)),
        "inlier_fraction_before": round_to(o.inlier_fraction_before, 4),
        "inlier_fraction_after": o.inlier_fraction_after.map(|f| round_to(f, 4)),
        "overlap_fraction_after": o.overlap_fraction_after.map(|f| round_to(f, 4)),
    })
}

/// Runs `sldepth motion`.
pub fn run(args: Args) -> Result<()> {
    check_range("--threshold-px", args.threshold_px, 1e-6..=1e3)?;
    let mut a = load_depth(&args.depth_a, &args.input)?;
    let mut b = load_depth(&args.depth_b, &args.input)?;
    if a.camera != b.camera
        || a.depth.width() != b.depth.width()
        || a.depth.height() != b.depth.height()
    {
        bail!(
            "the two frames must come from the same camera and have the same size: {} is {}x{}, {} is {}x{}{}",
            args.depth_a.display(),
            a.depth.width(),
            a.depth.height(),
            args.depth_b.display(),
            b.depth.width(),
            b.depth.height(),
            if a.camera == b.camera {
                ""
            } else {
                " (and their cameras differ)"
            }
        );
    }
    let undistorter =
        crate::common::undistorter(&args.lens, &args.input, a.implied_preset, &a.camera);
    if let Some(u) = &undistorter {
        a.depth = u.apply(&a.depth)?;
        b.depth = u.apply(&b.depth)?;
    }
    let mut cfg = DepthMotionConfig::default();
    cfg.planes.threshold_px = args.threshold_px;
    cfg.planes.min_pixels = args.min_pixels;
    cfg.verify = !args.no_verify;
    cfg.icp = args.icp;
    let mcfg = cfg.motion;
    let result = motion_between_depths(&a.depth, &b.depth, &a.camera, &cfg)?;
    let (pa, pb) = (&result.planes_a, &result.planes_b);
    let m = match &result.motion {
        Ok(m) => m,
        Err(e) => {
            if args.json {
                let mut v = undetermined_json(e, pa.len(), pb.len());
                v["undistorted"] = json!(undistorter.is_some());
                v["candidates"] = candidates_json(&result.candidates);
                print_json(&v)?;
            } else {
                outln!(
                    "planes: {} in A, {} in B; motion undetermined",
                    pa.len(),
                    pb.len()
                )?;
                if !result.candidates.is_empty() {
                    let angles: Vec<String> = result
                        .candidates
                        .iter()
                        .map(|c| format!("{:.1}°", c.rotation_angle_deg()))
                        .collect();
                    outln!(
                        "the two frames cannot tell apart {} alignments (rotations {}; --json lists them)",
                        angles.len(),
                        angles.join(", ")
                    )?;
                }
            }
            bail!("{e}");
        }
    };
    let outcome = result.icp.as_ref();
    let icp_json = outcome.map_or(Value::Null, icp_outcome_json);
    let pose = result.pose().unwrap_or_else(|| m.motion());
    let rotation_deg = pose.rotation_angle_deg();
    let translation = result.translation_m();
    let matched: Vec<_> = m
        .matches
        .iter()
        .map(|mt| json!({ "a": pa[mt.a].id, "b": pb[mt.b].id, "weight": mt.weight }))
        .collect();
    let verification = m.verification.as_ref().map_or(Value::Null, |v| {
        json!({
            "inlier_fraction": round_to(v.inlier_fraction, 4),
            "overlap_fraction": round_to(v.overlap_fraction, 4),
            "alternative_inlier_fraction": round_to(v.alternative_inlier_fraction, 4),
            "turned_inlier_fraction": round_to(v.turned_inlier_fraction, 4),
            "hypotheses": v.hypotheses,
            "samples": v.samples,
        })
    });
    if args.json {
        print_json(&json!({
            "determined": true,
            "undistorted": undistorter.is_some(),
            "confidence": m.confidence.as_str(),
            "rotation": rotation_rows(&pose),
            "rotation_deg": round_to(rotation_deg, 4),
            "translation_m": translation.map(|t| vec3(&t, 5)),
            "matched_planes": matched,
            "planes_a": pa.len(),
            "planes_b": pb.len(),
            "rms_angle_deg": round_to(m.rms_angle_deg, 4),
            "runner_up_support": round_to(m.runner_up_support, 4),
            "inlier_fraction": m.verification.as_ref().map(|v| round_to(v.inlier_fraction, 4)),
            "verification": verification,
            "icp_accepted": outcome.map(|o| o.accepted),
            "icp_inlier_fraction": outcome
                .and_then(|o| o.inlier_fraction_after)
                .map(|f| round_to(f, 4)),
            "icp": icp_json,
        }))?;
    } else {
        outln!(
            "planes: {} in A, {} in B, {} matched; confidence: {}",
            pa.len(),
            pb.len(),
            m.matches.len(),
            m.confidence.as_str()
        )?;
        if let Some(v) = &m.verification {
            outln!(
                "verified: {:.1} % of the overlapping points explained (best alternative {:.1} %, \
                 turned by {}° {:.1} %)",
                100.0 * v.inlier_fraction,
                100.0 * v.alternative_inlier_fraction,
                mcfg.distinct_deg,
                100.0 * v.turned_inlier_fraction
            )?;
        }
        if let Some(o) = outcome {
            let after = o
                .inlier_fraction_after
                .map_or("–".to_string(), |f| format!("{:.1} %", 100.0 * f));
            match &o.rejection {
                None => outln!(
                    "ICP refinement accepted: {after} of the overlapping points explained \
                     (before {:.1} %)",
                    100.0 * o.inlier_fraction_before
                )?,
                Some(r) => outln!(
                    "ICP refinement rejected ({}): {after} of the overlapping points explained \
                     (before {:.1} %); keeping the plane estimate",
                    r.as_str(),
                    100.0 * o.inlier_fraction_before
                )?,
            }
        }
        outln!("rotation (X_a = R X_b + t), {rotation_deg:.3} deg:")?;
        let r = rotation_rows(&pose);
        for row in r.chunks_exact(3) {
            outln!("  [{:+.6} {:+.6} {:+.6}]", row[0], row[1], row[2])?;
        }
        match translation {
            Some(t) => outln!("translation: [{:+.4} {:+.4} {:+.4}] m", t.x, t.y, t.z)?,
            None => outln!("translation: not determined (matched normals do not span 3D)")?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icp_outcome_json_reports_the_decision() {
        let o = IcpOutcome {
            accepted: false,
            rejection: Some(sl_track::IcpRejection::LostInliers),
            pose: CameraToCamera::identity(),
            start: CameraToCamera::identity(),
            icp: None,
            inlier_fraction_before: 0.99,
            inlier_fraction_after: Some(0.95),
            overlap_fraction_after: Some(0.5),
        };
        let v = icp_outcome_json(&o);
        assert_eq!(v["accepted"], json!(false));
        assert_eq!(v["rejection"], json!("lost-inliers"));
        assert_eq!(v["inlier_fraction_before"], json!(0.99));
        assert_eq!(v["inlier_fraction_after"], json!(0.95));
        assert!(v["inliers"].is_null());
    }

    #[test]
    fn undetermined_json_has_no_rotation() {
        let e = TrackError::MotionNotVerified {
            reason: "ambiguous".into(),
            inlier_fraction: 0.95,
            alternative_inlier_fraction: 0.93,
        };
        let v = undetermined_json(&e, 3, 4);
        assert_eq!(v["determined"], json!(false));
        assert!(v["rotation"].is_null());
        assert_eq!(v["inlier_fraction"], json!(0.95));
        assert!(
            v["reason"]
                .as_str()
                .is_some_and(|r| r.contains("ambiguous"))
        );
    }
}
