//! What the run says at the end: the JSON summary (`--json`) or a few lines on standard error.

use anyhow::Result;
use sl_track::{ReconstructionConfig, Step, TrackStatus};

use super::Args;
use super::fragments::{FragmentOut, fragment_path, world_of};
use super::prepare::FramePrep;
use super::trajectory_text::Row;
use crate::common::{print_json, round_to};

/// What the run counted and timed, frame by frame.
#[derive(Default)]
pub(super) struct Tally {
    /// Frames that could not be tracked, and frames that could not be read or prepared.
    pub(super) lost_frames: Vec<usize>,
    pub(super) skipped_frames: Vec<usize>,
    /// Frames per `TrackStatus`.
    pub(super) counts: [usize; 6],
    /// Per step: tracking (every frame's, and the tracked frames'), fusing, raycasting, the
    /// whole step.
    pub(super) track_ms: Vec<f64>,
    pub(super) track_ms_tracked: Vec<f64>,
    pub(super) integrate_ms: Vec<f64>,
    pub(super) raycast_ms: Vec<f64>,
    pub(super) step_ms: Vec<f64>,
    /// Per frame read: its preparation (lens model, noise measurement, prefilter), and that
    /// with the step (every stage of the pipeline but reading the file).
    pub(super) prepare_ms: Vec<f64>,
    pub(super) frame_ms: Vec<f64>,
    /// The whole loop over the frames, seconds.
    pub(super) wall_s: f64,
    /// With an odometry: frames it gave a pose and frames it did not.
    pub(super) odometry_poses: Option<(usize, usize)>,
    /// Frames aligned with the odometry's prior, and those of them whose view left a direction
    /// to it (the weakest σ of the view above √`ODOMETRY_WEAK_SHARE` times the odometry's).
    pub(super) odometry_prior: usize,
    pub(super) odometry_pinned: usize,
}

impl Tally {
    /// Counts frame `i`'s step, whose frame took `prepare_ms` to prepare, and returns its
    /// trajectory row; with `verbose`, one diagnostic line on standard error.
    pub(super) fn record(&mut self, i: usize, step: Step, prepare_ms: f64, verbose: bool) -> Row {
        let r = step.result;
        let tm = step.timings;
        self.track_ms.push(tm.track_ms);
        self.counts[r.status as usize] += 1;
        if r.odometry_sigma_m.is_finite() {
            self.odometry_prior += 1;
            let share = sl_track::ODOMETRY_WEAK_SHARE;
            if r.weakest_sigma_m.powi(2) > share * r.odometry_sigma_m.powi(2) {
                self.odometry_pinned += 1;
            }
        }
        if verbose {
            errln!(
                "frame {i}: {} ovl {:.3} inl {:.3} rms {:.4} m ({:.2}σ) cond {:.2e} weakest σ {:.2} mm it {} {:.1} ms {}",
                r.status.as_str(),
                r.overlap_fraction,
                r.inlier_fraction,
                r.rms_m,
                r.rms_normalised,
                r.condition,
                r.weakest_sigma_m * 1e3,
                r.iterations,
                tm.track_ms,
                r.failure.as_deref().unwrap_or("")
            );
        }
        self.step_ms.push(tm.step_ms);
        self.prepare_ms.push(prepare_ms);
        self.frame_ms.push(prepare_ms + tm.step_ms);
        if r.status.is_tracked() {
            self.track_ms_tracked.push(tm.track_ms);
            self.integrate_ms.extend(tm.integrate_ms);
            self.raycast_ms.extend(tm.raycast_ms);
            Row::Pose(r.pose, step.fragment)
        } else {
            self.lost_frames.push(i);
            Row::Lost(r.failure.unwrap_or_default())
        }
    }
}

/// Reports the run of `args` with `cfg` over `frame_count` frames: the JSON summary on standard
/// output with `--json`, else a summary on standard error.
pub(super) fn print(
    args: &Args,
    cfg: &ReconstructionConfig,
    frame_count: usize,
    tally: &Tally,
    prep: &FramePrep,
    fragments: &[FragmentOut],
    mesh_errors: &[String],
) -> Result<()> {
    let params = cfg.tsdf;
    // Tracked frames in no model: their fragment's model had reached the memory budget.
    let unfused_frames: usize = fragments
        .iter()
        .map(|f| f.tracked.saturating_sub(f.fused))
        .sum();
    // The JSON's vertex and triangle counts are fragment 0's (the whole run's when there is
    // one fragment).
    let mesh_size = fragments
        .first()
        .and_then(|f| f.mesh.as_ref())
        .map(|m| (m.vertices, m.triangles));
    let (tm, im) = (median(&tally.track_ms), median(&tally.integrate_ms));
    let median_or_null = |v: &[f64]| (!v.is_empty()).then(|| round_to(median(v), 3));
    // Continuations of one frame or none fuse nothing together: the budget holds about one
    // frame's blocks, and each frame costs a fragment and a mesh.
    let continuations = fragments.iter().filter(|f| f.continues.is_some()).count();
    let thin = fragments
        .iter()
        .filter(|f| f.continues.is_some() && f.fused <= 1)
        .count();
    if continuations >= 2 && 2 * thin > continuations {
        errln!(
            "warning: {thin} of {continuations} continuations fused one frame or none: the model's budget holds about one frame's blocks (raise --max-memory or --voxel-m)"
        );
    }
    if args.json {
        let fragments_json = fragments
            .iter()
            .enumerate()
            .map(|(index, f)| {
                let world = world_of(index, fragments).0;
                serde_json::json!({
                    "index": index,
                    "first_frame": f.first_frame,
                    "tracked": f.tracked,
                    "fused": f.fused,
                    "blocks": f.blocks,
                    "model_bytes": f.model_bytes,
                    "model_full_at_frame": f.model_full_at,
                    "joined_into": f.rejoined(),
                    "continues": f.continues,
                    "world": world,
                    "output": args.output.as_ref().map(|p| fragment_path(p, world).display().to_string()),
                    "mesh": f.mesh.as_ref().map(|m| m.path.display().to_string()),
                    "vertices": f.mesh.as_ref().map(|m| m.vertices),
                })
            })
            .collect::<Vec<_>>();
        print_json(&serde_json::json!({
            "frames": frame_count,
            "tracked": frame_count - tally.lost_frames.len() - tally.skipped_frames.len(),
            "lost": tally.lost_frames.len(),
            "lost_frames": tally.lost_frames,
            "skipped": tally.skipped_frames.len(),
            "skipped_frames": tally.skipped_frames,
            // Tracked but not fused: their fragment's model had reached the memory budget.
            "unfused": unfused_frames,
            "recovered": tally.counts[TrackStatus::Recovered as usize],
            "relocalised": tally.counts[TrackStatus::Relocalised as usize],
            "tracked_against_frame": tally.counts[TrackStatus::TrackedAgainstFrame as usize],
            "reference": if args.frame_to_frame { "frame" } else { "model" },
            "prefilter": args.prefilter.name(),
            // The median σ_D, disparity pixels, the frames were smoothed for: the camera's, or
            // a noisier frame's measured one (null without a prefilter).
            "prefilter_sigma_d_px_median": (!prep.prefilter_sigmas.is_empty())
                .then(|| round_to(median(&prep.prefilter_sigmas), 4)),
            "undistorted": prep.undistorts(),
            "rolling_shutter_ms": round_to(cfg.tracker.rolling_shutter_readout_s * 1e3, 3),
            // Null when no frame was tracked (nothing was raycast, tracked or fused).
            "raycast_ms_median": median_or_null(&tally.raycast_ms),
            "step_ms_median": round_to(median(&tally.step_ms), 3),
            // Per frame read: the lens model, the noise measurement and the prefilter; and
            // those with the step (the whole pipeline but reading the file).
            "prepare_ms_median": round_to(median(&tally.prepare_ms), 3),
            "frame_ms_median": round_to(median(&tally.frame_ms), 3),
            "weighting": cfg.tracker.weighting.name(),
            "keyframes": cfg.tracker.keyframe_relocalisation,
            // The instruction set the tracker's pass ran with (the fusion's loops use it when
            // it is AVX-512, else their portable code).
            "isa": cfg.tracker.isa.effective().name(),
            "track_ms_median": round_to(tm, 3),
            "track_ms_median_tracked": median_or_null(&tally.track_ms_tracked),
            "integrate_ms_median": median_or_null(&tally.integrate_ms),
            // The raw frames' pixel variance over the camera's model (1: within it).
            "noise_scale_median": (!prep.noise_scales.is_empty()).then(|| round_to(median(&prep.noise_scales), 3)),
            "noise_scaled_frames": prep.noise_scales.iter().filter(|&&s| s > 1.0).count(),
            "wall_s": round_to(tally.wall_s, 3),
            "voxel_m": params.voxel_m,
            "trunc_m": params.trunc_m,
            "truncation": params.truncation.name(),
            "depth_lookup": params.depth_lookup.name(),
            "vertices": mesh_size.map(|m| m.0),
            "triangles": mesh_size.map(|m| m.1),
            "fragments": fragments_json,
            "output": args.output.as_ref().map(|p| p.display().to_string()),
            "mesh": args.mesh.as_ref().map(|p| p.display().to_string()),
            "mesh_errors": mesh_errors,
            // With --odometry or --odometry-tf: frames it gave a pose or none, frames aligned
            // with its prior, and those whose view left a direction to it.
            "odometry": odometry_json(tally),
        }))?;
    } else {
        errln!(
            "tracked {} of {} frames ({} lost, {} skipped); track {:.1} ms, integrate {:.1} ms per frame (median)",
            frame_count - tally.lost_frames.len() - tally.skipped_frames.len(),
            frame_count,
            tally.lost_frames.len(),
            tally.skipped_frames.len(),
            tm,
            im
        );
        if fragments.len() > 1 {
            errln!(
                "{} fragments (tracked frames: {:?}; rejoined: {:?})",
                fragments.len(),
                fragments.iter().map(|f| f.tracked).collect::<Vec<_>>(),
                fragments
                    .iter()
                    .enumerate()
                    .filter_map(|(k, f)| f.rejoined().map(|into| (k, into)))
                    .collect::<Vec<_>>()
            );
            let continued: Vec<_> = fragments
                .iter()
                .enumerate()
                .filter_map(|(k, f)| f.continues.map(|full| (k, full)))
                .collect();
            if !continued.is_empty() {
                errln!(
                    "continuations of a full model, in its world frame (fragment, of): {continued:?}"
                );
            }
        }
        if tally.odometry_poses.is_some() {
            errln!(
                "{} frames aligned with the odometry's prior, {} of them along a direction their view left free",
                tally.odometry_prior,
                tally.odometry_pinned
            );
        }
        if unfused_frames > 0 {
            errln!(
                "{unfused_frames} tracked frames not fused: the model reached the memory budget (--max-memory)"
            );
        }
        let noisier: Vec<f64> = prep
            .noise_scales
            .iter()
            .copied()
            .filter(|&s| s > 1.0)
            .collect();
        if !noisier.is_empty() {
            errln!(
                "{} frames noisier than the camera's model (their median pixel variance ×{:.2}): tracked with their own noise",
                noisier.len(),
                median(&noisier)
            );
        }
    }
    Ok(())
}

/// The median of `v` (0 for none).
fn median(v: &[f64]) -> f64 {
    sl_noise::analysis::median(&mut v.to_vec()).unwrap_or(0.0)
}

/// The `odometry` object of the JSON summary (null without an odometry).
fn odometry_json(tally: &Tally) -> serde_json::Value {
    match tally.odometry_poses {
        Some((found, missing)) => serde_json::json!({
            "frames_with_pose": found,
            "frames_without_pose": missing,
            "prior_frames": tally.odometry_prior,
            "weak_direction_from_odometry": tally.odometry_pinned,
        }),
        None => serde_json::Value::Null,
    }
}
