//! Frame-to-model tracking of a depth sequence ([`Tracker`]).
//!
//! Each frame is aligned to [`ReferenceMaps`] — a raycast of the fused model when the caller
//! passes one ([`ModelReference`], or [`ReferenceMaps::from_model`] for a raycast of one's
//! own), else the last well-tracked frame (on its planes with the planes' normals, see
//! `frame_planes`) — by
//! point-to-plane Gauss–Newton on SE(3) over a depth pyramid (coarse to fine, a depth-aware 2×2
//! downsample), with projective data association, a Huber kernel on the normalised residual and
//! weights from the sensor model ([`WeightMode`]). The normal equations count one independent
//! measurement per correlation window of the sensor's depth error
//! ([`TrackerConfig::noise_window_x_px`]) and carry a Gaussian prior on the camera's position:
//! about the constant-velocity prediction, σ from the camera's largest acceleration over one
//! frame ([`TrackerConfig::max_acceleration_m_s2`]); without a measured velocity, and from
//! any other start, σ = [`TrackerConfig::max_correction_m`]. Frames with timestamps
//! ([`Tracker::track_at`]) are predicted across the frames a recording dropped. Every σ of a
//! frame follows its own noise where that exceeds the camera's model
//! ([`TrackerConfig::estimate_noise`], measured on the frame's patches as `sl_planes` does, or
//! given by the caller for smoothed frames: [`Tracker::set_noise_scale`]).
//!
//! A result is accepted only when enough of the frame's points are inliers, the normal
//! equations constrain all six degrees of freedom and the correction from the start is
//! plausible. The attempts, until one passes: Gauss–Newton from the prediction; the same with
//! Levenberg–Marquardt step control from the prediction and from the last good pose; when the
//! reference is the model, both again against the last good frame
//! ([`TrackStatus::TrackedAgainstFrame`]). Once the first attempt has failed, every start of
//! a stage runs, and where several pass the earliest is kept unless a later one fits the frame
//! clearly better than the noise explains (`better_fit`: a paired test on the robust
//! objective's per-sample terms, the sensor's correlated error counted): a fallback runs
//! because the frame left the prediction's basin, and the first start that passes can have
//! settled in a wrong minimum. Then from the verified plane-based estimate between
//! the last good frame and this one ([`crate::motion_between_depths`]); then against each
//! keyframe (accepted frames kept at spread poses, [`TrackerConfig::keyframe_relocalisation`])
//! from its own pose, the best that passes kept. When all fail the frame
//! is [`TrackStatus::Lost`] with the last good pose — never a pose it could not check — and the
//! next frames are aligned against the last good reference again (relocalisation). A frame that
//! relocalises is aligned again from the last good pose turned ±3° about the camera's horizontal
//! and vertical axes, and the fit with the lowest robust objective over all its points is kept:
//! from one start, point-to-plane ICP can settle in a wrong minimum that trades a rotation for a
//! translation and still passes every check. [`crate::Reconstruction`] builds fragments on top
//! of this when the relocalisation does not come.

mod agreement;
mod align;
mod associate;
mod better_fit;
mod config;
mod frame_planes;
mod keyframes;
mod model;
mod normal_noise;
mod pyramid;
mod reference;
mod reference_normal_noise;
mod solve;
mod structure;

pub use config::{DEFAULT_LATERAL_SIGMA_PX, TrackerConfig, WeightMode};
pub use model::ModelReference;
pub use reference::ReferenceMaps;

use nalgebra::Isometry3;
use sl_core::{Camera, CameraToWorld, DepthImage, SensorModel};
use sl_planes::NoiseMeter;

use crate::depth_motion::motion_between_depths;
use crate::error::{Result, TrackError};
use align::ratio;
use frame_planes::FramePlanes;
use keyframes::Keyframes;
use pyramid::{Level, Pyramid, normal_radius};
use structure::StructureCheck;

/// How far the extra starts of a relocalisation are turned from the last good pose about the
/// camera's horizontal and vertical axes, degrees.
const RELOCALISATION_TURN_DEG: f64 = 3.0;

/// What happened to a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// The first frame (or the first with enough valid depth): it defines the world frame.
    Initialised,
    /// Aligned from the constant-velocity prediction (or the last good pose).
    Tracked,
    /// ICP failed from the prediction; the plane-based estimate, or a keyframe's pose against
    /// that keyframe, started a successful ICP.
    Recovered,
    /// The model reference disagreed (every start failed its checks); the frame was aligned
    /// to the last good frame instead.
    TrackedAgainstFrame,
    /// Aligned again after one or more lost frames.
    Relocalised,
    /// Not tracked: the pose is the last good one and must not be used as this frame's pose.
    Lost,
}

impl TrackStatus {
    /// Lower-case name.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Initialised => "initialised",
            Self::Tracked => "tracked",
            Self::Recovered => "recovered",
            Self::TrackedAgainstFrame => "tracked-against-frame",
            Self::Relocalised => "relocalised",
            Self::Lost => "lost",
        }
    }

    /// Whether the frame has a pose of its own (not [`TrackStatus::Lost`]).
    pub fn is_tracked(&self) -> bool {
        !matches!(self, Self::Lost)
    }
}

/// The result of tracking one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameResult {
    /// What happened.
    pub status: TrackStatus,
    /// The camera-to-world pose; for a lost frame the last good pose.
    pub pose: CameraToWorld,
    /// Fraction of the frame's points (with a normal, full resolution) that land on a surface
    /// of the reference at the final pose.
    pub overlap_fraction: f64,
    /// Fraction of those overlapping points that are inliers (within the gates).
    pub inlier_fraction: f64,
    /// RMS point-to-plane residual of the inliers, metres.
    pub rms_m: f64,
    /// RMS of the inliers' residuals normalised by their σ from the sensor model.
    pub rms_normalised: f64,
    /// Smallest over largest eigenvalue of the final normal equations (see
    /// [`TrackerConfig::min_condition`]).
    pub condition: f64,
    /// Gauss–Newton iterations, all levels and attempts together.
    pub iterations: usize,
    /// Standard deviation of the pose along its least-constrained direction that the frame's
    /// geometry allows (the sensor model, the normals of the frame's planes; rotations as
    /// displacements at the scene's depth), metres: infinite for a single plane. Above the
    /// motion prior's σ the frame is lost ([`TrackerConfig::degenerate_check`]); NaN when not
    /// checked (the first frame, or the check disabled).
    pub weakest_sigma_m: f64,
    /// Why the frame was lost: the alignment's failure from the prediction (a degenerate
    /// view, a disputed or degenerate overlap, too few inliers, …), followed, when the
    /// plane-based fallback was tried, by why that failed too (`…; plane fallback: motion not
    /// verified: …`); `None` for a frame with a pose, whichever attempt gave it.
    pub failure: Option<String>,
}

impl FrameResult {
    /// A frame lost before any alignment ran, with `pose` (the last good or initial one).
    fn lost_unaligned(pose: CameraToWorld, failure: String) -> Self {
        Self {
            status: TrackStatus::Lost,
            pose,
            overlap_fraction: 0.0,
            inlier_fraction: 0.0,
            rms_m: 0.0,
            rms_normalised: 0.0,
            condition: 0.0,
            iterations: 0,
            weakest_sigma_m: f64::NAN,
            failure: Some(failure),
        }
    }
}

/// The first alignment of a frame: from the constant-velocity prediction.
struct AlignPlan {
    /// The last good pose.
    last: Isometry3<f64>,
    /// Frame intervals since it (≥ 1).
    n: u32,
    row_timing: Option<solve::RowTiming>,
    predicted: Isometry3<f64>,
    /// The position prior's variance about the prediction, m².
    predicted_var: f64,
    /// The prior's variance for a start with no velocity known, m².
    unknown_var: f64,
}

/// Tracks the camera through a depth sequence (see the module docs). Reuse one tracker for a
/// sequence: its buffers (pyramid, reference maps, last frame) are kept between frames.
#[derive(Debug)]
pub struct Tracker {
    /// The camera of the frame being tracked: the camera given, its `σ_D` raised to the
    /// frame's own noise level when that exceeds the model ([`TrackerConfig::estimate_noise`]).
    camera: Camera,
    /// The camera's sensor model as given.
    model_sensor: SensorModel,
    /// Measures each frame's noise against `model_sensor`.
    noise_meter: NoiseMeter,
    /// The last frame's pixel variance over the model's (1: within the model).
    noise_scale: f64,
    /// A noise scale measured elsewhere for the frames given ([`Tracker::set_noise_scale`]).
    given_noise_scale: Option<f64>,
    cfg: TrackerConfig,
    pyramid: Pyramid,
    /// The last good frame as a reference, built from `last_level` when first needed
    /// (`last_ref_stale`): most frames are tracked against the model and never need it.
    last_ref: ReferenceMaps,
    /// Level 0 of the last good frame's pyramid (swapped out of the pyramid on acceptance).
    last_level: Level,
    /// The last good frame's planes (from the structure check): their normals replace the
    /// pixels' own in `last_ref` (see `frame_planes`).
    last_planes: FramePlanes,
    last_ref_stale: bool,
    /// The last good frame's depth (for the plane-based fallback).
    last_depth: DepthImage,
    last_good: Option<Isometry3<f64>>,
    /// Motion of the last step, `T_k = T_{k−1}·velocity`.
    velocity: Isometry3<f64>,
    /// Whether `velocity` was measured (false until a frame after the first is tracked; after
    /// lost frames `lost_run` disables it until the next tracked one).
    velocity_known: bool,
    lost_run: usize,
    /// Accepted frames kept for relocalisation ([`TrackerConfig::keyframe_relocalisation`]).
    keyframes: Keyframes,
    /// Nominal frame intervals ([`TrackerConfig::frame_interval_s`]) from the last good frame
    /// to the frame being tracked: 1 for consecutive frames, more after dropped or lost ones.
    intervals_since_good: u32,
    /// The timestamp of the last frame given to [`Tracker::track_at`], seconds.
    last_timestamp_s: Option<f64>,
    initial_pose: CameraToWorld,
    /// The degenerate-view check's plane extractor.
    structure: StructureCheck,
    /// The rows' exposure times of the frame being aligned (a rolling shutter, tracked on
    /// from the last good frame), `None` for one pose per frame.
    row_timing: Option<solve::RowTiming>,
    /// The mean valid depth of the finest alignment level of the frame being tracked (the
    /// scene's scale for the conditioning), computed beside its first alignment; `None`
    /// until then.
    finest_mean_depth_m: Option<f64>,
    /// The per-interval motion the last frame was aligned with row by row (when it was).
    rolling_motion: Option<Isometry3<f64>>,
    /// Whether the frame being tracked was given a model to track against: an alignment to
    /// the last frame is then the fallback after the model's was rejected.
    model_given: bool,
}

impl Tracker {
    /// A tracker for `camera`'s frames.
    pub fn new(camera: Camera, cfg: TrackerConfig) -> Result<Self> {
        cfg.validate()?;
        camera.intrinsics.validate()?;
        camera.sensor.validate()?;
        pyramid::check_levels(&camera.intrinsics, cfg.levels)?;
        let k = camera.intrinsics;
        Ok(Self {
            camera,
            model_sensor: camera.sensor,
            noise_meter: cfg.noise_meter(),
            noise_scale: 1.0,
            given_noise_scale: None,
            cfg,
            pyramid: Pyramid::default(),
            last_ref: ReferenceMaps::empty(&k),
            last_level: Level::default(),
            last_planes: FramePlanes::default(),
            last_ref_stale: false,
            last_depth: DepthImage::invalid(k.width, k.height),
            last_good: None,
            velocity: Isometry3::identity(),
            velocity_known: false,
            lost_run: 0,
            keyframes: Keyframes::default(),
            intervals_since_good: 0,
            last_timestamp_s: None,
            initial_pose: CameraToWorld::identity(),
            structure: StructureCheck::default(),
            row_timing: None,
            finest_mean_depth_m: None,
            rolling_motion: None,
            model_given: false,
        })
    }

    /// The pose given to the first frame (identity by default). Call before the first frame.
    pub fn set_initial_pose(&mut self, pose: CameraToWorld) {
        self.initial_pose = pose;
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.cfg
    }

    /// The factor by which the last frame's disparity-error variance exceeded the camera's
    /// model, measured on the frame's own 16×16- and 32×32-pixel patches as `sl_planes` does
    /// (`sl_planes::NoiseMeter`; [`TrackerConfig::estimate_noise`]); 1 when it did not, or
    /// before any frame.
    pub fn noise_scale(&self) -> f64 {
        self.noise_scale
    }

    /// Tracks the next frames with a noise scale measured elsewhere (the factor by which the
    /// raw frame's pixel variance exceeds the camera's model, `sl_planes::NoiseMeter`) instead
    /// of measuring the frames given: a frame smoothed before tracking (`sldepth track`'s and
    /// Python's prefilter) no longer shows its sensor's noise, so the caller measures the raw
    /// frame. Values below 1 (and non-finite ones) count as 1; `None` goes back to
    /// [`TrackerConfig::estimate_noise`].
    pub fn set_noise_scale(&mut self, scale: Option<f64>) {
        self.given_noise_scale = scale;
    }

    /// The sensor model the last frame was tracked with: the camera's, its `σ_D` raised by
    /// [`Tracker::noise_scale`] (what a fused model's reference variance should use, as
    /// [`crate::Reconstruction`] does).
    pub fn frame_sensor(&self) -> SensorModel {
        self.camera.sensor
    }

    /// When the last frame was tracked row by row (a rolling shutter,
    /// [`TrackerConfig::rolling_shutter_readout_s`]): the camera's motion over one frame
    /// interval it was aligned with (camera frame, `T_k = T_{k−1}·motion`), with which
    /// [`crate::rolling_shutter::Rectifier`] moves the frame to its pose for fusion.
    pub fn rolling_shutter_motion(&self) -> Option<Isometry3<f64>> {
        self.rolling_motion
    }

    /// Aligns the next frames as a global shutter's ([`TrackerConfig::rolling_shutter_readout_s`]
    /// = 0): what [`crate::Reconstruction`] does when a full model leaves it tracking frame to
    /// frame (there a readout made TUM fr1/rpy-200's trajectory worse, ATE 3.08 → 3.98 cm;
    /// docs/bench/track.md, session 79).
    pub(crate) fn use_global_shutter(&mut self) {
        self.cfg.rolling_shutter_readout_s = 0.0;
        self.rolling_motion = None;
    }

    /// The last well-tracked pose (`None` before the first frame with valid depth).
    pub fn last_good_pose(&self) -> Option<CameraToWorld> {
        self.last_good.map(CameraToWorld::from_isometry)
    }

    /// The last well-tracked frame as reference maps (what a frame is aligned to when no model
    /// reference is given).
    pub fn last_frame_reference(&mut self) -> &ReferenceMaps {
        self.refresh_last_ref();
        &self.last_ref
    }

    /// Builds the last good frame's reference maps if they are not yet.
    fn refresh_last_ref(&mut self) {
        if !self.last_ref_stale {
            return;
        }
        let Some(pose) = self.last_good else {
            return;
        };
        let k = self.camera.intrinsics;
        self.last_level
            .complete_normals(&self.camera.sensor, k.fx as f32, normal_radius(0));
        self.last_ref.set_from_level(
            &self.last_level,
            &k,
            &self.camera.sensor,
            &CameraToWorld::from_isometry(pose),
            self.cfg.lateral_sigma_px,
        );
        self.last_planes.apply(&mut self.last_ref, &self.last_level);
        self.last_ref_stale = false;
    }

    /// Tracks one frame against `model` (a raycast of the fused model from about the last
    /// good pose) or, when `None`, against the last good frame. The frame is taken to follow
    /// the previous one by one frame interval ([`TrackerConfig::frame_interval_s`]); use
    /// [`Tracker::track_at`] when the frames have timestamps (a recording that dropped frames).
    /// Runs on a worker thread of the caller's rayon pool, as [`crate::Reconstruction::step`].
    ///
    /// # Errors
    /// A depth map of another size than the camera, or a model reference of another size;
    /// a frame that cannot be tracked is not an error but [`TrackStatus::Lost`].
    pub fn track(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
    ) -> Result<FrameResult> {
        crate::pool::on_pool(|| self.track_frame(depth, model, None))
    }

    /// [`Tracker::track`] for a frame taken at `timestamp_s` (seconds, any origin). The time
    /// since the previous frame, in whole frame intervals ([`TrackerConfig::frame_interval_s`],
    /// rounded: the jitter of a driver's timestamps is not motion), scales what the tracker
    /// expects of the motion: the constant-velocity prediction spans the gap, the velocity
    /// measured over it is taken per interval, and the motion prior's σ grows as its model
    /// says (∝ intervals²); the acceptance bounds (the largest correction, the degenerate-view
    /// bound) stay those of one interval. A recording that dropped frames is then predicted
    /// across the gap (TUM fr1/rpy every fourth frame: one frame lost with [`Tracker::track`],
    /// none with timestamps; docs/bench/track.md). A frame given to [`Tracker::track`] after
    /// timestamped ones counts as one interval.
    ///
    /// # Errors
    /// As [`Tracker::track`], and [`TrackError::TimestampOrder`] for a timestamp that is not
    /// finite or not after the previous frame's (the tracker's state is then unchanged).
    pub fn track_at(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        timestamp_s: f64,
    ) -> Result<FrameResult> {
        crate::pool::on_pool(|| self.track_frame(depth, model, Some(timestamp_s)))
    }

    fn track_frame(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        timestamp_s: Option<f64>,
    ) -> Result<FrameResult> {
        let k = self.camera.intrinsics;
        let size_err = |w: usize, h: usize| TrackError::SizeMismatch {
            expected_width: k.width,
            expected_height: k.height,
            width: w,
            height: h,
        };
        if depth.width() != k.width || depth.height() != k.height {
            return Err(size_err(depth.width(), depth.height()));
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
        let intervals = self.intervals_from_timestamp(timestamp_s)?;
        // The frame's own noise level: every σ of this frame (the alignment's weights and
        // gates, the degenerate-view checks, the planes) follows it.
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
        // A view whose geometry leaves some direction of the pose to the motion prior (a
        // single wall or floor, a bare corridor) is lost before any alignment: whatever pose
        // an alignment returned would be the prior's guess along that direction. Nor does such
        // a view start the sequence: a model of one wall cannot anchor the frames after it.
        let check_level = self.check_level();
        let checked = self.cfg.degenerate_check && self.pyramid.levels.get(check_level).is_some();
        let prior_sigma_m = self.cfg.motion_prior_sigma_m();
        if self.last_good.is_some() {
            self.intervals_since_good = self.intervals_since_good.saturating_add(intervals);
        }
        // The first alignment's start and prior (a tracker with a last good pose).
        let plan = self.last_good.map(|last| {
            let n = self.intervals_since_good.max(1);
            // A rolling shutter: the rows' poses on the constant-velocity path from the last
            // good pose, once the reference holds frames moved to their poses (the second
            // frame is aligned as a whole to the first, which is skewed alike at constant
            // velocity; a relocalising frame's path from the last good pose is unknown).
            let row_timing = (self.cfg.rolling_shutter_readout_s > 0.0
                && self.lost_run == 0
                && self.velocity_known)
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
            AlignPlan {
                last,
                n,
                row_timing,
                predicted: solve::renormalized(predicted),
                predicted_var,
                unknown_var,
            }
        });
        if let Some(p) = &plan {
            self.row_timing = p.row_timing;
            if model.is_none() {
                self.refresh_last_ref();
            }
        }
        // The structure check (plane extraction and the weakest direction of the frame alone,
        // about 1.8 ms of mostly sequential work on a 640×480 frame) and the first alignment's
        // iterations (parallel over pixels) read the same pyramid and nothing of each other:
        // they run side by side, and the iterations are judged once the check's planes are
        // there. On a frame the check rejects the iterations are wasted.
        let (weakest_sigma_m, first_iterated) = if checked {
            let mut structure = std::mem::take(&mut self.structure);
            let this = &*self;
            let (gate, iterated) = rayon::join(
                || -> Result<(f64, f64)> {
                    // The acceptance checks' scale too: a sequential sum over the finest
                    // level, off the critical path here.
                    let scale_m = this.finest_mean_depth();
                    let Some(level) = this.pyramid.levels.get(check_level) else {
                        return Ok((f64::NAN, scale_m));
                    };
                    structure.segment(level, check_level, &this.camera, &this.cfg)?;
                    let sigma = structure
                        .weakest_sigma_m(
                            level,
                            check_level,
                            &this.camera,
                            &this.cfg,
                            |_, _| Some(solve::OnReference::NONE),
                            structure::MustAgree::default(),
                        )
                        .sigma_m;
                    Ok((sigma, scale_m))
                },
                || {
                    plan.as_ref().map(|p| {
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
            let (sigma, scale_m) = gate?;
            self.finest_mean_depth_m = Some(scale_m);
            (sigma, iterated)
        } else {
            (f64::NAN, None)
        };
        if weakest_sigma_m > prior_sigma_m {
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
            return Ok(r);
        }
        let Some(AlignPlan {
            last,
            n,
            predicted,
            predicted_var,
            unknown_var,
            ..
        }) = plan
        else {
            let mut r = self.initialise(depth);
            r.weakest_sigma_m = weakest_sigma_m;
            return Ok(r);
        };
        let mut iterations = 0;
        let reference = model.unwrap_or(&self.last_ref);
        let mut first = match first_iterated {
            Some(it) => self.judge(&predicted, reference, it),
            None => self.align(&predicted, reference, predicted_var, false),
        };
        iterations += first.iterations;
        let mut recovered = false;
        let mut against_frame = false;
        // Why the plane fallback, when tried, gave no pose either (for the lost frame's report).
        let mut fallback_failure: Option<String> = None;
        // The damped starts: the prediction and the last good pose. After a few lost frames
        // the prediction is the last good pose with the same prior (the velocity is
        // forgotten), and the same start would give the same result: it runs once.
        let starts = [(predicted, predicted_var), (last, unknown_var)];
        let distinct = if starts[0] == starts[1] { 1 } else { 2 };
        // Not after a disputed pose: the damped starts are for an iteration that did not
        // converge, and from another start against the same reference the alignment can slide
        // further along the disputed direction, where the objecting samples leave the window
        // they are counted in (room 3021 with a shaking camera: 34 mm, session 41). The last
        // frame, a reference of its own, is asked next.
        let model_disputed = first.disputed && model.is_some();
        let restarts = if model_disputed { 0 } else { distinct };
        // Every restart runs, and one that passes the checks is kept only over another that
        // fits clearly worse (`Tracker::keep_better`): a fallback runs because the frame left
        // the prediction's basin, and the first start that passes can have settled in a
        // wrong minimum of its own.
        if first.failure.is_some() {
            let mut found = None;
            for &(start, var) in &starts[..restarts] {
                let again = self.align(&start, model.unwrap_or(&self.last_ref), var, true);
                iterations += again.iterations;
                if again.failure.is_none() {
                    found = Some(self.keep_better(found, again, model.unwrap_or(&self.last_ref)));
                }
            }
            if let Some(attempt) = found {
                first = attempt;
            }
        }
        // The model can disagree with a frame where the last frame does not. On TUM fr1/rpy
        // (hand-held, turning at up to 120°/s), one step against a model fused with the
        // motion-capture poses errs by 2–6 cm where the same step against the previous frame
        // errs by 0.2–1 cm: likely a view-dependent depth distortion or the rolling shutter,
        // which differ between the views the model averages and agree between consecutive
        // frames. Try the last good frame before the plane fallback, in the order the model
        // was tried: plain Gauss–Newton from the prediction first, then the damped starts.
        // Damped steps are taken only when they lower the robust objective, which the 1/8-pixel
        // quantisation makes rough: along a weakly constrained direction they stop early, short
        // of the data's optimum and near the prediction, so the next velocity lags the camera
        // and the next prediction with it. On the simulated Kinect corridor, where every frame
        // falls back to the last one (the end wall lies beyond the fused range), that shrinkage
        // lost 0.5 mm per 4 mm step along the axis (six noise seeds: −13 mm by frame 28, every
        // seed short; plain Gauss–Newton first: −3 mm, within the noise; docs/bench/track.md,
        // session 55). The damped starts run too, and one of them is kept only where it fits
        // the frame clearly better (`Tracker::keep_better`): from the prediction, centimetres
        // from a shaking camera, plain Gauss–Newton can pass every check in a wrong minimum
        // (simulated room 6006 with the camera shaken: 33 mm off, reported σ 6.6 mm, while
        // the damped start from the last pose reaches the camera within 2 mm and a robust
        // objective 21 % lower; docs/bench/track.md, session 63).
        if first.failure.is_some() && model.is_some() {
            self.refresh_last_ref();
            let plain = std::iter::once((predicted, predicted_var, false));
            let damped = starts[..distinct].iter().map(|&(s, v)| (s, v, true));
            let mut found = None;
            for (start, var, damped) in plain.chain(damped) {
                let again = self.align(&start, &self.last_ref, var, damped);
                iterations += again.iterations;
                if again.failure.is_none() {
                    found = Some(self.keep_better(found, again, &self.last_ref));
                }
            }
            if let Some(attempt) = found {
                first = attempt;
                against_frame = true;
            }
        }
        if first.failure.is_some() && self.cfg.plane_fallback {
            let planes =
                motion_between_depths(&self.last_depth, depth, &self.camera, &self.cfg.fallback)?;
            if let Some(m) = planes.pose() {
                let start = solve::renormalized(last * m.into_isometry());
                let again = self.align(&start, model.unwrap_or(&self.last_ref), unknown_var, true);
                iterations += again.iterations;
                match again.failure {
                    None => {
                        first = again;
                        recovered = true;
                    }
                    Some(why) => {
                        fallback_failure = Some(format!(
                            "plane fallback: the alignment from its verified estimate failed: {why}"
                        ));
                    }
                }
            } else if let Err(e) = &planes.motion {
                fallback_failure = Some(format!("plane fallback: {e}"));
            }
        }
        // Where the camera looks at something seen before: each keyframe from its own pose.
        let mut keyframe_pose = None;
        if first.failure.is_some() && self.cfg.keyframe_relocalisation {
            let search = self.relocalise_on_keyframes(&last, unknown_var)?;
            iterations += search.iterations;
            if let Some((pose, attempt)) = search.found {
                first = attempt;
                keyframe_pose = Some(pose);
                recovered = true;
            }
        }
        // A frame found at a keyframe is judged as a relocalisation too.
        if first.failure.is_none() && (self.start_is_a_guess() || keyframe_pose.is_some()) {
            // Relocalising, or the first step of the sequence: the start (the last good pose,
            // or the prediction) may be several frames' motion from the camera, where point-to-plane ICP can settle in a wrong
            // minimum that trades a rotation for a translation and still passes every check
            // (docs/bench/track.md, "Session 17"). Align again from starts turned about the
            // camera's horizontal and vertical axes and keep the best fit by the robust
            // objective over all the frame's points.
            let reference = match (keyframe_pose, self.keyframes.reference()) {
                (Some(_), Some(keyframe)) => keyframe,
                _ if against_frame => &self.last_ref,
                _ => model.unwrap_or(&self.last_ref),
            };
            let centre = keyframe_pose.unwrap_or(last);
            let cfg = &self.cfg;
            let mut best = first.stats.total_loss(cfg.gate_sigmas, cfg.huber_k);
            for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)] {
                let mut turn = nalgebra::Vector3::zeros();
                turn[axis] = sign * RELOCALISATION_TURN_DEG.to_radians();
                let start = centre * Isometry3::rotation(turn);
                let alt = self.align(&start, reference, unknown_var, true);
                iterations += alt.iterations;
                let cost = alt.stats.total_loss(cfg.gate_sigmas, cfg.huber_k);
                if alt.failure.is_none() && cost < best {
                    best = cost;
                    first = alt;
                }
            }
        }
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
        Ok(FrameResult {
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
        })
    }

    /// Whether the frame being tracked starts from a guess rather than a constant-velocity
    /// prediction: relocalising after lost frames, or the first frame after the one that
    /// anchored the sequence (or a fragment), whose motion nothing has measured yet. Its
    /// alignment then has the wide prior (`max_correction_m`), its start may lie centimetres
    /// from the camera, and it is judged as a relocalisation is: from several starts, and
    /// with planes that vouch only for what they agree with ([`StructureCheck::weakest_sigma_m`];
    /// against the fused model they always do). On the simulated rooms a second frame aligned to a one-frame model slid 44–51 mm along
    /// its weakest direction with a reported σ of 6–9 mm (docs/bench/track.md, session 38).
    pub(super) fn start_is_a_guess(&self) -> bool {
        self.lost_run > 0 || !self.velocity_known
    }

    /// The bookkeeping of a lost frame: after a few the old velocity says little, and the
    /// next frames relocalise from the last good pose.
    fn mark_lost(&mut self) {
        self.lost_run += 1;
        if self.lost_run > 3 {
            self.velocity = Isometry3::identity();
        }
    }

    /// The first frame with enough valid depth defines the world frame.
    fn initialise(&mut self, depth: &DepthImage) -> FrameResult {
        let (sensor, fl) = (self.camera.sensor, self.camera.intrinsics.fx as f32);
        let valid = self.pyramid.levels.first_mut().map_or(0, |l| {
            l.complete_normals(&sensor, fl, normal_radius(0));
            l.normals.iter().filter(|n| n.x.is_finite()).count()
        });
        let min_points = self.min_points(0);
        let pose = *self.initial_pose.isometry();
        if valid < min_points {
            return FrameResult::lost_unaligned(
                self.initial_pose,
                format!("first frame: {valid} points with a normal, fewer than {min_points}"),
            );
        }
        self.accept(depth, pose);
        FrameResult {
            status: TrackStatus::Initialised,
            pose: self.initial_pose,
            overlap_fraction: 1.0,
            inlier_fraction: 1.0,
            rms_m: 0.0,
            rms_normalised: 0.0,
            condition: 1.0,
            iterations: 0,
            weakest_sigma_m: f64::NAN,
            failure: None,
        }
    }

    /// Makes the current frame (level 0 of the pyramid) the last good one: its level 0 is kept
    /// (swapped with the pyramid's spare buffers) and its reference maps built when needed.
    fn accept(&mut self, depth: &DepthImage, pose: Isometry3<f64>) {
        if let Some(l0) = self.pyramid.levels.first_mut() {
            std::mem::swap(l0, &mut self.last_level);
            self.last_ref_stale = true;
        }
        self.structure.hand_over(&mut self.last_planes);
        self.last_depth.data_mut().copy_from_slice(depth.data());
        self.last_good = Some(pose);
        self.intervals_since_good = 0;
        if self.cfg.keyframe_relocalisation {
            let (m, deg) = (self.cfg.max_correction_m, self.cfg.max_correction_deg);
            self.keyframes.offer(depth, &pose, m, deg);
        }
    }

    /// Whole frame intervals since the previous frame's timestamp (1 without timestamps),
    /// after checking the order.
    fn intervals_from_timestamp(&self, timestamp_s: Option<f64>) -> Result<u32> {
        let Some(t) = timestamp_s else {
            return Ok(1);
        };
        let previous = self.last_timestamp_s;
        if !t.is_finite() || previous.is_some_and(|p| t <= p) {
            return Err(TrackError::TimestampOrder {
                previous_s: previous.unwrap_or(f64::NAN),
                timestamp_s: t,
            });
        }
        // At most an hour of frames; the prediction itself stops at 31 intervals.
        Ok(previous.map_or(1, |p| self.cfg.whole_intervals(t - p)))
    }

    /// The pyramid level the degenerate-view check runs on: 1 (half resolution; a plane's
    /// normal needs no more), or 0 for a one-level pyramid.
    fn check_level(&self) -> usize {
        1.min(self.pyramid.levels.len().saturating_sub(1))
    }

    /// Fewest associated points for the normal equations of `level` to mean anything: 1 % of
    /// the level's pixels.
    fn min_points(&self, level: usize) -> usize {
        let k = self.camera.intrinsics;
        ((k.width * k.height) >> (2 * level)) / 100
    }
}
