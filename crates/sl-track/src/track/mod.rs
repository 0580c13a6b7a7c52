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
//! ([`TrackStatus::TrackedAgainstFrame`]), where a pose that passes is challenged by the
//! alignment from the verified plane-based estimate against the same frame: replaced when that
//! one passes and fits the frame clearly better, no pose when it fits clearly better and
//! fails. Once the first attempt has failed, every start of
//! a stage runs, and where several pass the earliest is kept unless a later one fits the frame
//! clearly better than the noise explains (`better_fit`: a paired test on the robust
//! objective's per-sample terms, the sensor's correlated error counted): a fallback runs
//! because the frame left the prediction's basin, and the first start that passes can have
//! settled in a wrong minimum. Then from the verified plane-based estimate between
//! the last good frame and this one ([`crate::motion_between_depths`]), or, where the two
//! frames cannot tell several plane-based alignments apart, from each of them
//! ([`crate::DepthMotion::candidates`]) against the model, which has more to say: kept only
//! when the planes' best passes and every other converges within 15° of it or fits clearly
//! worse; then against each
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
mod fallbacks;
mod frame;
mod frame_planes;
mod keyframes;
mod model;
mod normal_noise;
mod odometry;
mod pyramid;
mod reference;
mod reference_normal_noise;
mod solve;
mod structure;

pub use config::{DEFAULT_LATERAL_SIGMA_PX, TrackerConfig, WeightMode};
pub use model::ModelReference;
pub use odometry::{MAX_ODOMETRY_STEP_M, ODOMETRY_WEAK_SHARE};
pub use reference::ReferenceMaps;

use nalgebra::Isometry3;
use sl_core::{Camera, CameraToWorld, DepthImage, SensorModel};
use sl_planes::NoiseMeter;

use crate::error::{Result, TrackError};
use frame_planes::FramePlanes;
use keyframes::Keyframes;
use odometry::OdometryPrior;
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
    /// to the last good frame instead (and no alignment from the plane-based estimate against
    /// that frame fitted it clearly better).
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
    /// The σ of the position the odometry predicted for the frame, metres
    /// ([`Tracker::set_odometry`]): where `weakest_sigma_m` is more than
    /// √[`ODOMETRY_WEAK_SHARE`] times larger, the pose along that direction is the odometry's.
    /// NaN when the frame had no odometry prior.
    pub odometry_sigma_m: f64,
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
            odometry_sigma_m: f64::NAN,
        }
    }
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
    /// The odometry's camera pose for the next frame ([`Tracker::set_odometry`]).
    next_odometry: Option<Isometry3<f64>>,
    /// The odometry's camera pose at the frame being tracked.
    frame_odometry_pose: Option<Isometry3<f64>>,
    /// The odometry's camera pose at the last good frame.
    odometry_at_good: Option<Isometry3<f64>>,
    /// The odometry's prediction and prior of the frame being tracked (`odometry`).
    frame_odometry: Option<OdometryPrior>,
    /// What the frame's alignments see of their data (`odometry::weak_projection`).
    frame_projection: Option<nalgebra::Matrix6<f64>>,
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
            next_odometry: None,
            frame_odometry_pose: None,
            odometry_at_good: None,
            frame_odometry: None,
            frame_projection: None,
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

    /// Models a rolling-shutter readout of `readout_s` again (after
    /// [`Tracker::use_global_shutter`]; a continuation of a full model tracks against a model
    /// again); the motion across the readout is measured anew from the next tracked frames.
    pub(crate) fn restore_rolling_shutter(&mut self, readout_s: f64) {
        self.cfg.rolling_shutter_readout_s = readout_s;
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

    /// One frame, in the order of the module documentation: the frame's noise and pyramid,
    /// the degenerate-view check beside the first alignment, the fallbacks while it fails, and
    /// the bookkeeping of a tracked or lost frame.
    fn track_frame(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        timestamp_s: Option<f64>,
    ) -> Result<FrameResult> {
        // The odometry given for this call is this call's, whatever becomes of it.
        let odometry_pose = self.next_odometry.take();
        self.check_sizes(depth, model)?;
        let intervals = self.intervals_from_timestamp(timestamp_s)?;
        self.frame_odometry_pose = odometry_pose;
        self.frame_odometry = None;
        self.frame_projection = None;
        self.prepare_frame(depth, model, timestamp_s)?;
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
        let mut plan = self.plan_alignment();
        // A measured motion replaces the constant-velocity prediction (`odometry`).
        if let (Some(p), Some(now), Some(then)) = (
            plan.as_mut(),
            self.frame_odometry_pose,
            self.odometry_at_good,
        ) && let Some(o) = OdometryPrior::new(&p.last, &then, &now, p.n, &self.cfg)
        {
            p.predicted = o.pose;
            p.predicted_var = o.var_t_m2;
            self.frame_odometry = Some(o);
        }
        if let Some(p) = &plan {
            self.row_timing = p.row_timing;
            if model.is_none() {
                self.refresh_last_ref();
            }
        }
        let (weakest, mut first_iterated) = if checked {
            self.check_structure_beside_first_alignment(check_level, plan.as_ref(), model)?
        } else {
            (None, None)
        };
        let weakest_sigma_m = weakest.as_ref().map_or(f64::NAN, |w| w.sigma_m);
        // Where the view pins some direction worse than the odometry, the alignment's data
        // say nothing along it (`odometry::weak_projection`): aligned again, on such frames
        // only.
        self.frame_projection = match (&self.frame_odometry, &weakest) {
            (Some(o), Some(w)) => odometry::weak_projection(w, o.var_t_m2),
            _ => None,
        };
        if self.frame_projection.is_some() {
            first_iterated = None;
        }
        // With odometry every direction is pinned, by the depth or by the odometry: the first
        // frame anchors the sequence, and the odometry carries a later one's weak direction.
        let odometry_pins =
            self.frame_odometry.is_some() || (plan.is_none() && self.frame_odometry_pose.is_some());
        if weakest_sigma_m > prior_sigma_m && !odometry_pins {
            return Ok(self.lost_to_degenerate_view(depth, weakest_sigma_m, prior_sigma_m));
        }
        let Some(plan) = plan else {
            let mut r = self.initialise(depth);
            r.weakest_sigma_m = weakest_sigma_m;
            return Ok(r);
        };
        let outcome = self.align_with_fallbacks(depth, model, &plan, first_iterated)?;
        Ok(self.conclude(depth, outcome, &plan, weakest_sigma_m))
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
            odometry_sigma_m: f64::NAN,
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
        self.odometry_at_good = self.frame_odometry_pose;
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
