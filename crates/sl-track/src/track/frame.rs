//! The steps of tracking one frame around its alignments ([`Tracker::track`]): the checks of
//! the inputs, the frame's noise level and pyramid, the plan of the first alignment (the
//! constant-velocity prediction and its prior), the degenerate-view check run beside that
//! alignment, and the bookkeeping of a frame tracked or lost.

use nalgebra::Isometry3;
use sl_core::{Camera, CameraToWorld, DepthImage};

use super::align::{Iterated, ratio};
use super::fallbacks::Outcome;
use super::{FrameResult, ReferenceMaps, TrackStatus, Tracker, solve, structure};
use crate::error::{Result, TrackError};

/// The first alignment of a frame: from the constant-velocity prediction.
#[derive(Debug, Clone, Copy)]
pub(super) struct AlignPlan {
    /// The last good pose.
    pub(super) last: Isometry3<f64>,
    /// Frame intervals since it (≥ 1).
    pub(super) n: u32,
    pub(super) row_timing: Option<solve::RowTiming>,
    pub(super) predicted: Isometry3<f64>,
    /// The position prior's variance about the prediction, m².
    pub(super) predicted_var: f64,
    /// The prior's variance for a start with no velocity known, m².
    pub(super) unknown_var: f64,
}

impl Tracker {
    /// A depth map of the camera's size, and a model reference of consistent sizes.
    pub(super) fn check_sizes(
        &self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
    ) -> Result<()> {
        let k = self.camera.intrinsics;
        if depth.width() != k.width || depth.height() != k.height {
            return Err(TrackError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: depth.width(),
                height: depth.height(),
            });
        }
        if let Some(m) = model {
            let mk = &m.intrinsics;
            if mk.width * mk.height != m.points.len()
                || m.normals.len() != m.points.len()
                || m.variance_m2.len() != m.points.len()
            {
                return Err(TrackError::InvalidConfig(
                    "reference maps of inconsistent sizes".into(),
                ));
            }
        }
        Ok(())
    }

    /// The frame's own noise level (every σ of this frame follows it: the alignment's weights
    /// and gates, the degenerate-view checks, the planes), the per-frame state reset, and the
    /// frame's pyramid.
    pub(super) fn prepare_frame(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        timestamp_s: Option<f64>,
    ) -> Result<()> {
        let k = self.camera.intrinsics;
        self.noise_scale = if let Some(s) = self.given_noise_scale {
            if s.is_finite() { s.max(1.0) } else { 1.0 }
        } else if self.cfg.estimate_noise {
            let model = Camera {
                intrinsics: k,
                sensor: self.model_sensor,
            };
            self.noise_meter.measure(depth, &model)?.max(1.0)
        } else {
            1.0
        };
        self.camera.sensor = self.model_sensor.with_variance_scale(self.noise_scale);
        self.row_timing = None;
        self.finest_mean_depth_m = None;
        self.rolling_motion = None;
        self.model_given = model.is_some();
        let sensor = self.camera.sensor;
        // Level 0 is sampled every `stride0` pixels by the alignment against a model: its
        // normals are computed there only, the rest if the frame is ever needed as a reference
        // (`refresh_last_ref`). Frame-to-frame tracking needs them all.
        let stride0 = if model.is_some() {
            self.cfg
                .sample_stride(0, self.camera.pixels_per_sensor_pixel())
        } else {
            1
        };
        self.pyramid
            .build(depth.data(), &k, &sensor, self.cfg.levels, stride0)?;
        self.last_timestamp_s = timestamp_s;
        Ok(())
    }

    /// The first alignment's start and prior, for a tracker with a last good pose.
    pub(super) fn plan_alignment(&self) -> Option<AlignPlan> {
        let last = self.last_good?;
        let n = self.intervals_since_good.max(1);
        // A rolling shutter: the rows' poses on the constant-velocity path from the last
        // good pose, once the reference holds frames moved to their poses (the second
        // frame is aligned as a whole to the first, which is skewed alike at constant
        // velocity; a relocalising frame's path from the last good pose is unknown).
        let row_timing =
            (self.cfg.rolling_shutter_readout_s > 0.0 && self.lost_run == 0 && self.velocity_known)
                .then(|| solve::RowTiming {
                    last,
                    intervals: n,
                    readout_fraction: self.cfg.rolling_shutter_readout_fraction(),
                });
        // Constant velocity, also across lost and dropped frames (the camera kept moving
        // meanwhile): the last good pose moved by one step per frame interval since.
        let mut predicted = last;
        for _ in 0..n.min(31) {
            predicted *= self.velocity;
        }
        // The position prior of an alignment from the prediction: how far the camera's
        // path can leave the constant-velocity line in `n` frame intervals (σ ∝ n²); with
        // no velocity known, and for every other start, the largest plausible motion in
        // one. The acceptance bounds (`max_correction_*`) stay those of one frame: the
        // prediction carries the motion over a gap, and what is left to correct is the
        // departure from constant velocity (TUM fr1/rpy's motion capture: 5.6 mm RMS,
        // 17.5 mm at most over 4 intervals, against the 5 cm bound). Bounds scaled with
        // the gap let ICP's wrong minima through (the sequence taken every fourth frame:
        // ATE 2.5 → 10.6 cm).
        let unknown_var = self.cfg.max_correction_m * self.cfg.max_correction_m;
        let predicted_var = if self.velocity_known && self.lost_run == 0 {
            self.cfg.acceleration_variance_m2() * f64::from(n).powi(4)
        } else {
            unknown_var
        };
        Some(AlignPlan {
            last,
            n,
            row_timing,
            predicted: solve::renormalized(predicted),
            predicted_var,
            unknown_var,
        })
    }

    /// The weakest direction of the frame alone (the degenerate-view check on pyramid level
    /// `check_level`; `None` without that level) and, when `plan` is given, the first
    /// alignment's iterations.
    ///
    /// The structure check (plane extraction and the weakest direction of the frame alone,
    /// about 1.8 ms of mostly sequential work on a 640×480 frame) and the first alignment's
    /// iterations (parallel over pixels) read the same pyramid and nothing of each other:
    /// they run side by side, and the iterations are judged once the check's planes are
    /// there. On a frame the check rejects the iterations are wasted.
    pub(super) fn check_structure_beside_first_alignment(
        &mut self,
        check_level: usize,
        plan: Option<&AlignPlan>,
        model: Option<&ReferenceMaps>,
    ) -> Result<(Option<structure::Weakest>, Option<Iterated>)> {
        let mut structure = std::mem::take(&mut self.structure);
        let this = &*self;
        let (gate, iterated) = rayon::join(
            || -> Result<(Option<structure::Weakest>, f64)> {
                // The acceptance checks' scale too: a sequential sum over the finest
                // level, off the critical path here.
                let scale_m = this.finest_mean_depth();
                let Some(level) = this.pyramid.levels.get(check_level) else {
                    return Ok((None, scale_m));
                };
                structure.segment(level, check_level, &this.camera, &this.cfg)?;
                let weakest = structure.weakest_sigma_m(
                    level,
                    check_level,
                    &this.camera,
                    &this.cfg,
                    |_, _| Some(solve::OnReference::NONE),
                    structure::MustAgree::default(),
                );
                Ok((Some(weakest), scale_m))
            },
            || {
                plan.map(|p| {
                    this.iterate(
                        &p.predicted,
                        model.unwrap_or(&this.last_ref),
                        p.predicted_var,
                        false,
                    )
                })
            },
        );
        self.structure = structure;
        let (weakest, scale_m) = gate?;
        self.finest_mean_depth_m = Some(scale_m);
        Ok((weakest, iterated))
    }

    /// The result of a frame whose geometry leaves a direction of the pose to the motion
    /// prior (`weakest_sigma_m` beyond `prior_sigma_m`): lost, or for a first frame, not yet
    /// the start of the sequence.
    pub(super) fn lost_to_degenerate_view(
        &mut self,
        depth: &DepthImage,
        weakest_sigma_m: f64,
        prior_sigma_m: f64,
    ) -> FrameResult {
        self.row_timing = None;
        let (pose, what) = match self.last_good {
            Some(last) => {
                self.mark_lost();
                (CameraToWorld::from_isometry(last), "degenerate view")
            }
            None => (
                self.initial_pose,
                "first frame: degenerate view, waiting for one that pins the pose",
            ),
        };
        let why = if weakest_sigma_m.is_finite() {
            format!(
                "{what}: the geometry leaves the pose uncertain by {:.1} mm (1σ) along one direction, more than the motion prior's {:.1} mm (a single plane, a bare corridor)",
                weakest_sigma_m * 1e3,
                prior_sigma_m * 1e3
            )
        } else if depth.data().iter().any(|&z| z > 0.0 && z.is_finite()) {
            format!(
                "{what}: the geometry leaves one direction of the pose undetermined (a single plane, a bare corridor)"
            )
        } else {
            // Nothing to align at all: say so rather than call it a degenerate view.
            let what = if self.last_good.is_some() {
                "lost"
            } else {
                "first frame: waiting for one with depth"
            };
            format!("{what}: no valid depth in the frame")
        };
        let mut r = FrameResult::lost_unaligned(pose, why);
        r.weakest_sigma_m = weakest_sigma_m;
        r
    }

    /// The bookkeeping of the frame's outcome — a tracked frame becomes the last good one
    /// and measures the velocity, a lost one counts towards relocalisation — and its result.
    pub(super) fn conclude(
        &mut self,
        depth: &DepthImage,
        outcome: Outcome,
        plan: &AlignPlan,
        weakest_sigma_m: f64,
    ) -> FrameResult {
        let Outcome {
            first,
            iterations,
            recovered,
            against_frame,
            fallback_failure,
            keyframe_pose,
            ..
        } = outcome;
        let (last, n) = (plan.last, plan.n);
        let result = match first.failure {
            None => {
                let status = if self.lost_run > 0 {
                    TrackStatus::Relocalised
                } else if recovered {
                    TrackStatus::Recovered
                } else if against_frame {
                    TrackStatus::TrackedAgainstFrame
                } else {
                    TrackStatus::Tracked
                };
                // Found again at a keyframe, the path from the last good pose is unknown: the
                // next frame starts from a guess, as after the first frame of a sequence.
                self.velocity = match keyframe_pose {
                    Some(_) => Isometry3::identity(),
                    None => solve::renormalized(solve::nth_root(&(last.inverse() * first.pose), n)),
                };
                self.velocity_known = keyframe_pose.is_none();
                // The frame's rows as the camera at its pose would have measured them, for
                // when it is the reference (frame to frame, the fallback to the last frame).
                let readout_fraction = self.cfg.rolling_shutter_readout_fraction();
                self.rolling_motion = (readout_fraction > 0.0).then(|| {
                    if let Some(l0) = self.pyramid.levels.first_mut() {
                        l0.undo_rolling_shutter(&self.velocity, readout_fraction);
                    }
                    self.velocity
                });
                self.accept(depth, first.pose);
                self.lost_run = 0;
                status
            }
            Some(_) => {
                self.mark_lost();
                TrackStatus::Lost
            }
        };
        let pose = if result.is_tracked() {
            first.pose
        } else {
            last
        };
        FrameResult {
            status: result,
            pose: CameraToWorld::from_isometry(pose),
            overlap_fraction: ratio(first.stats.associated, first.stats.valid),
            inlier_fraction: ratio(first.stats.inliers, first.stats.associated),
            rms_m: (ratio(first.stats.r2_m2, first.stats.inliers)).sqrt(),
            rms_normalised: (ratio(first.stats.chi2, first.stats.inliers)).sqrt(),
            condition: first.condition,
            iterations,
            // The binding one of the frame's own σ and its overlap's.
            weakest_sigma_m: weakest_sigma_m.max(first.overlap_sigma_m),
            failure: first.failure.map(|why| match fallback_failure {
                Some(fallback) => format!("{why}; {fallback}"),
                None => why,
            }),
            odometry_sigma_m: self.frame_odometry.map_or(f64::NAN, |o| o.sigma_t_m()),
        }
    }
}
