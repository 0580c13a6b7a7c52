//! Tracking and fusing a depth sequence in one loop ([`Reconstruction`]): every frame is
//! tracked against the raycast of the model fused so far and every tracked frame is fused into
//! it — the loop of `sldepth track` and of Python's `sldepth.Tracker` — and a recording whose
//! tracking is lost for good goes on in a new **fragment** (its own volume and world frame)
//! instead of being lost to its end.
//!
//! # Fragments
//! After a lost frame the tracker aligns the next frames from the last good pose and against
//! its keyframes (relocalisation, see [`Tracker`]): that succeeds when the camera comes back to
//! within a few centimetres and degrees of where tracking was lost or of a view it kept — a
//! hand over the lens, a short view of a bare wall, a fast turn that swings back. A
//! camera that has moved on may not come back for a long time, and every frame until then would
//! be lost. So when frames that *could* be aligned (enough depth, a view that pins all six
//! degrees of freedom) keep failing to align for [`ReconstructionConfig::new_fragment_after_s`]
//! seconds of the recording, a new fragment starts with this frame: a fresh tracker and volume,
//! its world frame its first camera. Frames that cannot be aligned at all (no depth, a
//! degenerate view) do not count: a camera that still looks at the same wall may well
//! relocalise once it turns back.
//!
//! The fragment that stayed lost is **suspended**, not closed: a frame every sixth frame
//! interval is also aligned to its model from its last good pose, exactly as its tracker would
//! have relocalised (one try costs several tracked frames). When one succeeds, the camera is
//! back: the reconstruction goes on in the suspended fragment (the frame is
//! [`crate::TrackStatus::Relocalised`] there), and the fragment that ends is handed over with the
//! transform between the two world frames ([`FragmentJoin`], from the frame's pose in each), so
//! its poses and mesh can be put into the older one's frame. A fragment is handed to the caller
//! ([`Step::finished`], [`Reconstruction::finish`]) when it rejoins the one before, or when a
//! newer fragment's start pushes it out of suspension (one suspended fragment at a time: at most
//! two volumes in memory). Fragments that never meet again are not registered to each other
//! (that needs place recognition, which sl-track does not have).
//!
//! The time is a policy, not a property of the sensor: shorter starts tracking again sooner,
//! longer makes fewer fragments. Rejoining makes a short time cheap — a fragment started too
//! early is joined back when the camera returns. The default is one second (docs/bench/track.md,
//! "Session 17").
//!
//! # A model that reaches the memory budget
//! The fragments share one budget, [`TsdfConfig::memory_budget_bytes`] of
//! [`ReconstructionConfig::tsdf`]: the current fragment's volume may use what the suspended one
//! does not hold, nor the caller for what it keeps of the fragments handed over
//! ([`Reconstruction::reserve_bytes`]). A frame whose blocks the budget cannot hold is not
//! fused into it (the volume is left as it was) and the fragment's model is **full**
//! ([`Step::model_full`] on that frame, [`Fragment::model_full`]).
//!
//! By default ([`ReconstructionConfig::new_volume_when_full`]) the reconstruction then goes on in a
//! **continuation**: a new fragment with a fresh volume in the *same* world frame, tracked by the
//! same tracker (its motion, keyframes and pose carry on). The frame the full model could not hold
//! ([`Step::continued`] on that frame) is the continuation's first: it is fused with the next frame
//! (as a rolling-shutter fragment's first frame is), so that the full fragment, handed over at once
//! ([`Step::finished`]), can be meshed by the caller beside an empty volume; its volume's memory
//! goes to the continuation. A continuation is joined to the fragment it continues by the identity
//! ([`Fragment::continues`], and [`Fragment::joined`] unless it later rejoins a suspended
//! fragment), so its poses and mesh are already in that world. A continuation that rejoins a
//! suspended fragment is in one world frame with the fragments it continues (back to the first,
//! which has no `continues`): its join moves them too, and callers that keep their poses or meshes
//! apply it to them ([`continued_chain`]; `sldepth track` and Python's `Tracker` join the first
//! of them to the same fragment). So a recording longer than the budget is tracked against a model to its end and fused
//! whole, as a sequence of meshes that overlap where the camera saw the same surfaces again (they
//! are not merged). The frame after a continuation's first is tracked against the full model it
//! continues, rendered from the first frame's pose before the full volume is handed over (as it
//! would have been without the budget; TUM fr1/rpy-200 at `--max-memory` 300M / 400M / 800M: ATE
//! 3.17 / 3.80 / 2.59 → 2.87 / 3.27 / 2.48 cm against the frame before; docs/bench/track.md,
//! session 83), then against its own model.
//!
//! Without continuations, the fragment's next frames are tracked against the last tracked frame
//! ([`Reconstruction::model_full`]), as with `frame_to_model = false` and a global shutter (a
//! rolling-shutter readout made frame-to-frame tracking worse on TUM fr1/rpy), and not fused, so
//! the trajectory goes on to the end and the mesh holds what was fused before. A volume that holds
//! no frame yet (a fragment's or a continuation's first frame alone needs more blocks than the
//! budget leaves it) is tried again with every frame: frames too large are skipped and tracked as
//! above, and the first that fits starts the model. Nothing is dropped from a model to make room
//! (the mesh would lose it). Tracking on against the full model, not fused, was tried: frames it
//! barely covers went 10–14 cm astray on TUM fr1/rpy (docs/bench/track.md, session 79).

use std::time::Instant;

use sl_core::{Camera, DepthImage, Intrinsics, SensorModel, WorldToWorld};
use sl_tsdf::{RaycastConfig, TsdfConfig, TsdfError, TsdfVolume};

use crate::error::{Result, TrackError};
use crate::track::{FrameResult, ModelReference, Tracker, TrackerConfig};

/// How a [`Reconstruction`] tracks, fuses and splits a sequence.
#[derive(Debug, Clone, Copy)]
pub struct ReconstructionConfig {
    /// The tracker.
    pub tracker: TrackerConfig,
    /// The volume every fragment is fused into; the raycast of the model uses its depth range.
    pub tsdf: TsdfConfig,
    /// Track against the raycast of the fused model (default) or, when `false`, against the
    /// last tracked frame.
    pub frame_to_model: bool,
    /// The fraction of the camera's resolution the model is rendered at for tracking, in
    /// `(0, 1]`; `None`: [`ModelReference::default_scale`].
    pub model_scale: Option<f64>,
    /// Seconds of frames that could be aligned but were lost after which a new fragment starts
    /// (see the module docs), counted in whole frame intervals
    /// ([`TrackerConfig::frame_interval_s`], at least one); `None` never starts one. Default 1 s.
    pub new_fragment_after_s: Option<f64>,
    /// When a fragment's model reaches the memory budget, go on in a continuation: a fresh
    /// volume in the same world frame (see the module docs). Default `true`; `false` tracks
    /// the rest against the last frame and fuses nothing more.
    pub new_volume_when_full: bool,
}

impl ReconstructionConfig {
    /// The defaults for a camera with `sensor`: 4 mm voxels, the sensor-adaptive truncation band
    /// with a 2 cm (5-voxel) floor and 1/Z⁴ weights ([`TsdfConfig::for_sensor`]), frame-to-model tracking with the default tracker, a new fragment after 1 s.
    pub fn default_for(sensor: SensorModel) -> Self {
        Self {
            tracker: TrackerConfig::default(),
            tsdf: TsdfConfig::for_sensor(sensor),
            frame_to_model: true,
            model_scale: None,
            new_fragment_after_s: Some(1.0),
            new_volume_when_full: true,
        }
    }

    /// The raycast of the fused model over the fusion's depth range (the defaults of
    /// [`RaycastConfig`] otherwise).
    pub fn raycast_config(&self) -> RaycastConfig {
        let mut raycast = RaycastConfig::default();
        raycast.min_depth_m = self.tsdf.min_depth_m;
        raycast.max_depth_m = self.tsdf.max_depth_m;
        raycast
    }

    /// The model reference a frame of `camera` is tracked against: [`Self::raycast_config`] at
    /// `model_scale` (by default [`ModelReference::default_scale`]).
    ///
    /// # Errors
    /// A `model_scale` outside `(0, 1]`.
    pub fn model_reference(&self, camera: &Camera) -> Result<ModelReference> {
        let scale = self
            .model_scale
            .unwrap_or_else(|| ModelReference::default_scale(camera));
        ModelReference::new(&camera.intrinsics, scale, self.raycast_config())
    }

    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.tracker.validate()?;
        self.tsdf.validate()?;
        if let Some(s) = self.model_scale
            && !(s > 0.0 && s <= 1.0)
        {
            return Err(TrackError::InvalidConfig(format!(
                "model_scale must lie in (0, 1], got {}",
                sl_core::Compact(s)
            )));
        }
        if let Some(s) = self.new_fragment_after_s
            && (s.is_nan() || s <= 0.0)
        {
            return Err(TrackError::InvalidConfig(format!(
                "new_fragment_after_s must be positive (None: never), got {}",
                sl_core::Compact(s)
            )));
        }
        Ok(())
    }
}

/// A fragment of the sequence: its volume, in its own world frame (its first camera's).
#[derive(Debug)]
pub struct Fragment {
    /// 0 for the first fragment, then in order of their start.
    pub index: usize,
    /// Everything fused into it, in its own world frame.
    pub volume: TsdfVolume,
    /// Frames tracked (and fused) in it.
    pub tracked_frames: usize,
    /// Set when the fragment ended because the camera came back to the fragment before it
    /// (see the module docs), and a frame had a pose in both.
    pub joined: Option<FragmentJoin>,
    /// Set when the fragment's model reached the memory budget (see the module docs): why, as
    /// the fusion's message. Its frames from then on are in a continuation, or tracked but not
    /// in `volume` when there is none.
    pub model_full: Option<String>,
    /// The fragment this one continues in a fresh volume, that fragment's model being full
    /// (see the module docs): its world frame is that fragment's.
    pub continues: Option<usize>,
}

impl Fragment {
    /// The join of a fragment that ended by rejoining a suspended fragment: [`Fragment::joined`]
    /// unless it is a continuation's identity link to the fragment it continues.
    pub fn rejoin(&self) -> Option<FragmentJoin> {
        self.joined.filter(|j| Some(j.into) != self.continues)
    }
}

/// The fragments a chain of continuations holds, from fragment `from` back to the first of them
/// (the one that continues none), with `continues` giving each fragment's
/// [`Fragment::continues`]: one world frame, which a rejoin of the chain's last continuation
/// moves as a whole (see the module docs). A link that does not go to an older fragment ends the
/// chain.
pub fn continued_chain(
    from: usize,
    continues: impl Fn(usize) -> Option<usize>,
) -> impl Iterator<Item = usize> {
    std::iter::successors(Some(from), move |&k| continues(k).filter(|&q| q < k))
}

/// How a fragment that ended by rejoining the fragment before it relates to that one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FragmentJoin {
    /// The fragment it rejoined (whose world frame the poses go on in).
    pub into: usize,
    /// From this fragment's world frame to `into`'s: `transform * pose` is a pose of this
    /// fragment in `into`'s world.
    pub transform: WorldToWorld,
}

/// Wall-clock time of a step's stages, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepTimings {
    /// Tracking, with the try of the suspended fragment and the second attempt of a frame that
    /// started a new fragment.
    pub track_ms: f64,
    /// Fusing the frame (`None`: not tracked, not fused).
    pub integrate_ms: Option<f64>,
    /// Raycasting the model for the next frame (`None`: not tracked, or frame to frame).
    pub raycast_ms: Option<f64>,
    /// The whole step.
    pub step_ms: f64,
}

/// What [`Reconstruction::step`] did with a frame.
#[derive(Debug)]
pub struct Step {
    /// The tracker's result; its pose is in the world frame of fragment `fragment`.
    pub result: FrameResult,
    /// The fragment the frame belongs to.
    pub fragment: usize,
    /// The fragment this frame handed over: the current one when the frame went back to the
    /// suspended one (joined to it), or the suspended one when the frame started a new fragment.
    /// Its volume is the caller's now: extract its mesh or drop it.
    pub finished: Option<Fragment>,
    /// Where the time went.
    pub timings: StepTimings,
    /// Whether the frame went into the model (a tracked frame is not fused once its fragment's
    /// model is full; a rolling-shutter fragment's first frame waits for the second's).
    pub fused: bool,
    /// Set on the frame whose fusion found its fragment's model full (the memory budget reached,
    /// see the module docs): the fusion's message. When [`Step::continued`] is set too, the
    /// frame is the continuation's first (fused with the next step); otherwise later frames of
    /// the fragment are tracked against the last frame and not fused, unless the volume holds
    /// no frame yet: then every later frame is tried, and a step whose frame fits after a
    /// waiting first frame was refused reports both (`fused` and this set, while
    /// [`Reconstruction::model_full`] is `None` again).
    pub model_full: Option<String>,
    /// Set on the frame that started a continuation (see the module docs): the fragment whose
    /// full model it continues (handed over in [`Step::finished`]). `fragment` is the
    /// continuation's index.
    pub continued: Option<usize>,
}

/// Tracks a depth sequence and fuses it, fragment by fragment (see the module docs).
///
/// Frames are used as given. `sldepth track` and Python's `Tracker` first smooth every frame
/// with `sl_filter::MultiScale::default_for(&camera.sensor)`; do the same with raw sensor
/// frames: unsmoothed full-resolution frames bias the pose along weakly constrained directions
/// (13 mm on the first step of a simulated 640×480 Kinect sequence, 28 mm with a D435;
/// docs/bench/track.md, session 23).
///
/// ```
/// use sl_core::{Camera, DepthImage};
/// use sl_core::nalgebra::Vector3;
/// use sl_track::{Reconstruction, ReconstructionConfig, TrackStatus};
///
/// // A corner of three walls seen by a Kinect's 320x240 stream, from a camera that does not
/// // move.
/// let cam = Camera::kinect_v1().resampled(0.5)?;
/// let k = cam.intrinsics;
/// let walls = [
///     (Vector3::new(0.3f64, 0.2, -1.0).normalize(), 2.0f64),
///     (Vector3::new(-0.8, 0.1, -0.6).normalize(), 1.5),
///     (Vector3::new(0.1, -0.9, -0.4).normalize(), 1.2),
/// ];
/// let mut z = vec![0f32; k.width * k.height];
/// for (i, zi) in z.iter_mut().enumerate() {
///     // The ray has z = 1, so the distance along it is the depth.
///     let ray = k.ray((i % k.width) as f64, (i / k.width) as f64);
///     let near = walls.iter().map(|(n, d)| -d / n.dot(&ray)).filter(|s| *s > 0.0);
///     *zi = near.fold(f64::INFINITY, f64::min) as f32;
/// }
/// let depth = DepthImage::from_vec(k.width, k.height, z)?;
/// let mut rec = Reconstruction::new(cam, ReconstructionConfig::default_for(cam.sensor))?;
/// let first = rec.step(&depth, None)?;
/// assert_eq!(first.result.status, TrackStatus::Initialised);
/// let second = rec.step(&depth, None)?;
/// assert_eq!(second.result.status, TrackStatus::Tracked);
/// assert_eq!(second.fragment, 0);
/// assert!(rec.volume().block_count() > 0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Reconstruction {
    /// The buffer of a rolling-shutter frame moved to its pose for fusion.
    rectified: Option<DepthImage>,
    /// The rectification's displacement buffer.
    rectifier: crate::rolling_shutter::Rectifier,
    camera: Camera,
    cfg: ReconstructionConfig,
    /// The fragment frames are tracked and fused in.
    current: Live,
    /// The fragment before it, while the camera may still come back to it: every
    /// [`REJOIN_EVERY_INTERVALS`] a frame is also aligned to its model from its last good pose
    /// (its tracker's relocalisation).
    suspended: Option<Live>,
    /// The index of the next fragment to start.
    next_index: usize,
    /// Frame intervals of frames lost after an alignment attempt since the last tracked frame
    /// (whole intervals, as the tracker counts time: a driver's timestamp jitter is not time).
    failed_intervals: u64,
    /// The previous frame's timestamp, seconds.
    last_time_s: Option<f64>,
    /// Frame intervals until the suspended fragment is tried again.
    rejoin_wait: u64,
    /// The noise scale of the next frames, measured by the caller ([`Reconstruction::set_noise_scale`]).
    noise_scale: Option<f64>,
    /// The odometry's camera pose for the next step ([`Reconstruction::set_odometry`]).
    odometry: Option<nalgebra::Isometry3<f64>>,
    /// Bytes of the budget the caller holds outside the fragments' volumes
    /// ([`Reconstruction::reserve_bytes`]).
    reserved_bytes: usize,
}

/// Frame intervals between two tries of the suspended fragment (0.2 s at 30 Hz). A try is the
/// tracker's whole relocalisation (every start, the plane-based fallback): several times a
/// tracked frame's cost when it fails. Trying every frame made a new fragment's frames three
/// to four times slower on TUM fr1/rpy; a rejoin found a few frames late loses nothing, since
/// those frames are tracked in the new fragment and joined with it (docs/bench/track.md,
/// "Session 17").
const REJOIN_EVERY_INTERVALS: u64 = 6;

/// A fragment being tracked (or suspended): its tracker, volume and model.
#[derive(Debug)]
struct Live {
    index: usize,
    tracker: Tracker,
    volume: TsdfVolume,
    model: ModelReference,
    tracked: usize,
    /// A rolling-shutter fragment's first frame and pose, fused once the second frame gives
    /// the camera's motion.
    first_frame: Option<(DepthImage, sl_core::CameraToWorld)>,
    /// Set once a frame's blocks did not fit in the memory budget (the fusion's message): the
    /// model is full, frames are tracked against the last frame and no longer fused.
    model_full: Option<String>,
    /// A continuation's first frames are tracked against the full model it continues (its
    /// rendering from the continuation's first frame), until its own model is rendered.
    on_full_model: bool,
    /// The message of the last frame the budget refused in the current step (taken by the
    /// step): set even when a later frame of the step fits an empty volume.
    refused: Option<String>,
    /// The fragment this one continues in a fresh volume (see the module docs).
    continues: Option<usize>,
}

impl Live {
    fn new(index: usize, camera: &Camera, cfg: &ReconstructionConfig) -> Result<Self> {
        Ok(Self {
            index,
            tracker: Tracker::new(*camera, cfg.tracker)?,
            volume: TsdfVolume::new(cfg.tsdf)?,
            model: cfg.model_reference(camera)?,
            tracked: 0,
            first_frame: None,
            model_full: None,
            on_full_model: false,
            refused: None,
            continues: None,
        })
    }

    /// Fuses `depth` from `pose` unless the model is full. A frame the memory budget cannot
    /// hold leaves the volume as it was and makes the model full. Returns whether it was fused.
    ///
    /// # Errors
    /// The fusion's other errors (a size mismatch, a pose out of range).
    fn fuse(
        &mut self,
        depth: &DepthImage,
        intrinsics: &Intrinsics,
        pose: &sl_core::CameraToWorld,
    ) -> Result<bool> {
        // An empty volume is tried again with every frame: a frame whose blocks alone are more
        // than the budget is skipped, and a later one that fits starts the model.
        if self.model_full.is_some() && self.volume.frame_count() > 0 {
            return Ok(false);
        }
        match self.volume.integrate(depth, intrinsics, pose) {
            Ok(_) => {
                self.model_full = None;
                Ok(true)
            }
            Err(e @ (TsdfError::MemoryBudget { .. } | TsdfError::CandidateBudget { .. })) => {
                self.model_full = Some(e.to_string());
                self.refused.clone_from(&self.model_full);
                Ok(false)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// Tracks `depth` against the model, or against the last frame while the model holds no
    /// more than the fragment's first frame (never rendered when tracking frame to frame).
    ///
    /// A model of one frame holds that frame's data fused into voxels and rendered at a
    /// fraction of its resolution; the frame itself holds the same at full fidelity. Against
    /// the one-frame model the simulated OAK-D room 3012's second frame slid 23.8 mm along its
    /// weakest direction at a reported σ of 6.6 mm; against the first frame it is 7.7 mm off
    /// at σ 3.5 mm (docs/bench/track.md, session 45). A rolling-shutter fragment's first frame
    /// waits for the second anyway (see [`Reconstruction::step`]). A continuation's first
    /// frames are tracked against the full model it continues (`on_full_model`).
    /// `noise_scale`: the frame's noise measured elsewhere ([`Tracker::set_noise_scale`]).
    fn track(
        &mut self,
        depth: &DepthImage,
        timestamp_s: Option<f64>,
        noise_scale: Option<f64>,
        odometry: Option<nalgebra::Isometry3<f64>>,
    ) -> Result<FrameResult> {
        self.tracker.set_noise_scale(noise_scale);
        self.tracker.set_odometry(odometry);
        let model = if (self.tracked > 1 || self.on_full_model) && self.model_full.is_none() {
            self.model.maps()
        } else {
            None
        };
        match timestamp_s {
            Some(t) => self.tracker.track_at(depth, model, t),
            None => self.tracker.track(depth, model),
        }
    }

    /// The fragment as it ends. A rolling-shutter fragment's first frame still waiting for the
    /// camera's motion (the fragment ended before a second frame was tracked) is fused as it
    /// was measured: its motion is unknown, and a frame left out would leave the fragment
    /// empty.
    ///
    /// # Errors
    /// The fusion's errors but the memory budget's (a frame it cannot hold makes the model
    /// full).
    fn into_fragment(
        mut self,
        joined: Option<FragmentJoin>,
        intrinsics: &Intrinsics,
    ) -> Result<Fragment> {
        if let Some((first, pose)) = self.first_frame.take() {
            self.fuse(&first, intrinsics, &pose)?;
        }
        Ok(Fragment {
            index: self.index,
            volume: self.volume,
            tracked_frames: self.tracked,
            joined: joined.or(self.continues.map(identity_join)),
            model_full: self.model_full,
            continues: self.continues,
        })
    }

    /// Hands over this fragment's full volume and goes on as a continuation of it (see the
    /// module docs): index `index`, a fresh volume, the same tracker and model reference, no
    /// frame tracked yet.
    ///
    /// # Errors
    /// A volume of `cfg` that cannot be made.
    fn continue_in(&mut self, index: usize, cfg: &ReconstructionConfig) -> Result<Fragment> {
        let volume = std::mem::replace(&mut self.volume, TsdfVolume::new(cfg.tsdf)?);
        let done = Fragment {
            index: self.index,
            volume,
            tracked_frames: self.tracked,
            joined: self.continues.map(identity_join),
            model_full: self.model_full.take(),
            continues: self.continues,
        };
        self.index = index;
        self.continues = Some(done.index);
        self.tracked = 0;
        Ok(done)
    }
}

/// The join of a continuation to the fragment it continues: the same world frame.
fn identity_join(into: usize) -> FragmentJoin {
    FragmentJoin {
        into,
        transform: WorldToWorld::identity(),
    }
}

impl Reconstruction {
    /// A reconstruction of `camera`'s frames.
    ///
    /// # Errors
    /// An invalid configuration or camera.
    pub fn new(camera: Camera, cfg: ReconstructionConfig) -> Result<Self> {
        cfg.validate()?;
        let rectifier = crate::rolling_shutter::Rectifier::with_isa(cfg.tracker.isa);
        Ok(Self {
            current: Live::new(0, &camera, &cfg)?,
            camera,
            cfg,
            suspended: None,
            next_index: 1,
            failed_intervals: 0,
            last_time_s: None,
            rejoin_wait: 0,
            noise_scale: None,
            odometry: None,
            reserved_bytes: 0,
            rectified: None,
            rectifier,
        })
    }

    /// Tracks `depth` (the camera's size, metres, 0 = invalid; already undistorted and
    /// smoothed as wanted), fuses it when tracked and renders the model for the next frame.
    /// `timestamp_s`: the frame's time (see [`Tracker::track_at`]); `None` takes it to follow
    /// the previous frame by one frame interval. May start a new fragment, or go back to the
    /// one before (see the module docs). Runs on a worker thread of the caller's rayon pool (in
    /// place when called from one, otherwise on the global pool while the caller waits), so
    /// that its parallel phases split on the spot.
    ///
    /// # Errors
    /// As [`Tracker::track_at`]. A frame the memory budget cannot hold is not an error: it is
    /// not fused and the fragment's model is full (see the module docs).
    pub fn step(&mut self, depth: &DepthImage, timestamp_s: Option<f64>) -> Result<Step> {
        crate::pool::on_pool(|| self.step_on_pool(depth, timestamp_s))
    }

    /// Tracks the next frames with a noise scale measured by the caller on the raw frames
    /// ([`Tracker::set_noise_scale`]: frames smoothed before [`Reconstruction::step`] no
    /// longer show their sensor's noise); `None` (the default) measures the frames given.
    pub fn set_noise_scale(&mut self, scale: Option<f64>) {
        self.noise_scale = scale;
    }

    /// Gives the camera's pose in an odometry's frame (camera-to-odometry) at the next frame
    /// [`Reconstruction::step`] takes, for that step only: the odometry's motion predicts the
    /// frame and is the prior of its alignment ([`Tracker::set_odometry`]). Each fragment's
    /// tracker relates it to its own last good frame, so the odometry's frame may be any.
    pub fn set_odometry(&mut self, camera_in_odometry: Option<nalgebra::Isometry3<f64>>) {
        self.odometry = camera_in_odometry;
    }

    /// [`Reconstruction::step`], on a worker thread of the caller's pool.
    fn step_on_pool(&mut self, depth: &DepthImage, timestamp_s: Option<f64>) -> Result<Step> {
        let t0 = Instant::now();
        let intervals = match (timestamp_s, self.last_time_s) {
            (Some(t), Some(p)) => u64::from(self.cfg.tracker.whole_intervals(t - p)),
            _ => 1,
        };
        let odometry = self.odometry.take();
        let mut result = self
            .current
            .track(depth, timestamp_s, self.noise_scale, odometry)?;
        if timestamp_s.is_some() {
            self.last_time_s = timestamp_s;
        }
        let mut finished = None;
        self.rejoin_wait = self.rejoin_wait.saturating_sub(intervals);
        if let Some(old) = self.suspended.as_mut().filter(|_| self.rejoin_wait == 0) {
            self.rejoin_wait = REJOIN_EVERY_INTERVALS;
            let back = old.track(depth, timestamp_s, self.noise_scale, odometry)?;
            if back.status.is_tracked() {
                // The camera is back where the fragment before was lost: go on there. The
                // fragment that ends is related to it through this frame's two poses.
                let joined = result.status.is_tracked().then(|| FragmentJoin {
                    into: old.index,
                    transform: WorldToWorld::between(&back.pose, &result.pose),
                });
                if let Some(old) = self.suspended.take() {
                    let ended = std::mem::replace(&mut self.current, old);
                    self.share_budget();
                    finished = Some(ended.into_fragment(joined, &self.camera.intrinsics)?);
                }
                result = back;
            }
        }
        if result.status.is_tracked() {
            self.failed_intervals = 0;
        } else if result.iterations > 0 {
            // (A rejoined frame is tracked: this is the current fragment's failure.)
            self.failed_intervals = self.failed_intervals.saturating_add(intervals);
            let limit = self
                .cfg
                .new_fragment_after_s
                .map(|s| u64::from(self.cfg.tracker.whole_intervals(s)));
            if self.current.tracked > 0 && limit.is_some_and(|l| self.failed_intervals >= l) {
                let fresh = Live::new(self.next_index, &self.camera, &self.cfg)?;
                self.next_index += 1;
                self.failed_intervals = 0;
                self.rejoin_wait = REJOIN_EVERY_INTERVALS;
                let ended = std::mem::replace(&mut self.current, fresh);
                // The fragment that stayed lost may still be rejoined; the one suspended before
                // it no longer (one suspended fragment at a time bounds memory and time).
                finished = self
                    .suspended
                    .replace(ended)
                    .map(|f| f.into_fragment(None, &self.camera.intrinsics))
                    .transpose()?;
                self.share_budget();
                result = self
                    .current
                    .track(depth, timestamp_s, self.noise_scale, odometry)?;
            }
        }
        let track_ms = ms_since(t0);
        let (mut integrate_ms, mut raycast_ms) = (None, None);
        let (mut fused, mut model_full, mut continued) = (false, None, None);
        if result.status.is_tracked() {
            let t1 = Instant::now();
            let k = self.camera.intrinsics;
            let live = &mut self.current;
            // A rolling-shutter frame is fused as the camera at its pose would have seen it.
            // A fragment's first frame has no motion yet: it waits for the second's (the
            // second is aligned to it as a whole, both skewed alike at constant velocity).
            let readout = self.cfg.tracker.rolling_shutter_readout_fraction();
            // A fragment's band follows the noise its first tracked frame measured (a sensor
            // noisier than its camera says needs its own σ_Z's band; `Tracker::noise_scale`).
            if live.volume.frame_count() == 0 {
                live.volume.set_band_sensor(live.tracker.frame_sensor())?;
            }
            let was_full = live.model_full.is_some();
            let raw = depth;
            let depth = match live.tracker.rolling_shutter_motion() {
                Some(motion) => {
                    let moved = self
                        .rectified
                        .get_or_insert_with(|| DepthImage::invalid(k.width, k.height));
                    if let Some((first, pose)) = live.first_frame.take() {
                        self.rectifier.rectify(&first, &k, &motion, readout, moved);
                        live.fuse(&*moved, &k, &pose)?;
                    }
                    self.rectifier.rectify(depth, &k, &motion, readout, moved);
                    Some(&*moved)
                }
                None if readout > 0.0 && live.tracked == 0 => {
                    live.first_frame = Some((depth.clone(), result.pose));
                    None
                }
                None => {
                    // A continuation's first frame, without a readout to move it by.
                    if let Some((first, pose)) = live.first_frame.take() {
                        live.fuse(&first, &k, &pose)?;
                    }
                    Some(depth)
                }
            };
            if let Some(depth) = depth {
                fused = live.fuse(depth, &k, &result.pose)?;
            }
            let refused = live.refused.take();
            if !was_full {
                model_full = refused;
            } else if live.model_full.is_none() {
                // An empty volume took a frame at last (see `Live::fuse`): its fragment is
                // tracked as any other again.
                live.tracker
                    .restore_rolling_shutter(self.cfg.tracker.rolling_shutter_readout_s);
            }
            if live.model_full.is_some() {
                // The model is full (now, or since a step that already handed a fragment
                // over). Go on in a continuation, unless this step hands a fragment over (the
                // next one tries again) or the full volume holds no frame (its first frame did
                // not fit: it tries the next ones, see `Live::fuse`). This frame is the
                // continuation's first: it waits, as a rolling-shutter fragment's first frame
                // does, and is fused with the next step, after the caller has meshed and
                // dropped the full volume. The next frame is tracked against the full model
                // rendered from this frame's pose, as it would have been without the budget,
                // not against this frame alone.
                if self.cfg.new_volume_when_full
                    && finished.is_none()
                    && live.volume.frame_count() > 0
                {
                    if self.cfg.frame_to_model {
                        let t2 = Instant::now();
                        live.model.update_from_frame(
                            &live.volume,
                            &result.pose,
                            &live.tracker.frame_sensor(),
                            depth.unwrap_or(raw),
                            &k,
                        )?;
                        raycast_ms = Some(ms_since(t2));
                    }
                    let done = live.continue_in(self.next_index, &self.cfg)?;
                    live.on_full_model = self.cfg.frame_to_model;
                    self.next_index += 1;
                    continued = Some(done.index);
                    finished = Some(done);
                    // The full volume is the caller's now (`share_budget`, which `live`'s borrow
                    // keeps from being called here).
                    live.volume.set_memory_budget_bytes(current_share(
                        &self.cfg,
                        self.suspended.as_ref(),
                        self.reserved_bytes,
                    ));
                    live.volume.set_band_sensor(live.tracker.frame_sensor())?;
                    live.first_frame = Some((raw.clone(), result.pose));
                    live.tracker
                        .restore_rolling_shutter(self.cfg.tracker.rolling_shutter_readout_s);
                }
                if live.model_full.is_some() && model_full.is_some() {
                    live.tracker.use_global_shutter();
                }
            }
            let depth = depth.unwrap_or(raw);
            integrate_ms = Some(ms_since(t1));
            if self.cfg.frame_to_model && live.first_frame.is_none() && live.model_full.is_none() {
                let t2 = Instant::now();
                live.model.update_from_frame(
                    &live.volume,
                    &result.pose,
                    &live.tracker.frame_sensor(),
                    depth,
                    &k,
                )?;
                raycast_ms = Some(ms_since(t2));
                live.on_full_model = false;
            }
            live.tracked += 1;
        }
        Ok(Step {
            result,
            fragment: self.current.index,
            finished,
            timings: StepTimings {
                track_ms,
                integrate_ms,
                raycast_ms,
                step_ms: ms_since(t0),
            },
            fused,
            model_full,
            continued,
        })
    }

    /// Gives the current fragment the part of the budget that neither the suspended one nor the
    /// caller ([`Reconstruction::reserve_bytes`]) holds (see the module docs).
    fn share_budget(&mut self) {
        let share = current_share(&self.cfg, self.suspended.as_ref(), self.reserved_bytes);
        self.current.volume.set_memory_budget_bytes(share);
    }

    /// Bytes the fragments' volumes hold now: the current one's and the suspended one's
    /// ([`TsdfVolume::memory_bytes`]). A [`Step::finished`] fragment's volume is no longer
    /// counted: it is the caller's.
    pub fn memory_bytes(&self) -> usize {
        self.current.volume.memory_bytes()
            + self
                .suspended
                .as_ref()
                .map_or(0, |s| s.volume.memory_bytes())
    }

    /// Takes `bytes` more out of the budget the fragments share, for what the caller keeps of
    /// the fragments it was handed (Python's `Tracker` keeps each finished fragment's mesh),
    /// so that the volumes and those stay within [`TsdfConfig::memory_budget_bytes`] together.
    /// The current fragment's volume gets what is left; a volume already beyond it keeps its
    /// blocks, and its next frame that needs a block makes its model full.
    pub fn reserve_bytes(&mut self, bytes: usize) {
        self.reserved_bytes = self.reserved_bytes.saturating_add(bytes);
        self.share_budget();
    }

    /// The bytes reserved with [`Reconstruction::reserve_bytes`] so far.
    pub fn reserved_bytes(&self) -> usize {
        self.reserved_bytes
    }

    /// Why the current fragment's model is full, when it is (see the module docs): its frames
    /// are tracked against the last frame and not fused (a volume that holds no frame yet is
    /// tried again with each frame).
    pub fn model_full(&self) -> Option<&str> {
        self.current.model_full.as_deref()
    }

    /// The current fragment's index.
    pub fn fragment(&self) -> usize {
        self.current.index
    }

    /// The index of the fragment that may still be rejoined, if any.
    pub fn suspended_fragment(&self) -> Option<usize> {
        self.suspended.as_ref().map(|s| s.index)
    }

    /// The current fragment's volume.
    pub fn volume(&self) -> &TsdfVolume {
        &self.current.volume
    }

    /// The current fragment's volume with every tracked frame in it: [`Reconstruction::volume`]
    /// while no frame waits, else a copy with the fragment's first frame fused as it was
    /// measured (a rolling-shutter fragment's first frame waits for the second frame's motion,
    /// so a fragment of one tracked frame would mesh empty). For meshing the current fragment
    /// mid-sequence. A waiting frame the memory budget cannot hold is left out.
    ///
    /// # Errors
    /// The fusion's errors but the memory budget's.
    pub fn volume_with_waiting_frame(&self) -> Result<std::borrow::Cow<'_, TsdfVolume>> {
        let live = &self.current;
        match &live.first_frame {
            None => Ok(std::borrow::Cow::Borrowed(&live.volume)),
            Some(_) if live.model_full.is_some() => Ok(std::borrow::Cow::Borrowed(&live.volume)),
            Some((first, pose)) => {
                let mut volume = live.volume.clone();
                match volume.integrate(first, &self.camera.intrinsics, pose) {
                    Ok(_) => Ok(std::borrow::Cow::Owned(volume)),
                    // The frame would make the model full: the volume without it.
                    Err(TsdfError::MemoryBudget { .. } | TsdfError::CandidateBudget { .. }) => {
                        Ok(std::borrow::Cow::Borrowed(&live.volume))
                    }
                    Err(e) => Err(e.into()),
                }
            }
        }
    }

    /// The current fragment's tracker.
    pub fn tracker(&self) -> &Tracker {
        &self.current.tracker
    }

    /// The current fragment's model reference (its last rendering).
    pub fn model(&self) -> &ModelReference {
        &self.current.model
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The configuration.
    pub fn config(&self) -> &ReconstructionConfig {
        &self.cfg
    }

    /// Ends the reconstruction and hands over the fragments not yet handed over (the current
    /// one and a suspended one), in order of their index. A fragment that ended with a single
    /// tracked frame holds that frame (unless the memory budget cannot hold it: the fragment's
    /// model is then full, [`Fragment::model_full`]).
    ///
    /// # Errors
    /// The fusion's errors but the memory budget's, while a last waiting frame is fused.
    pub fn finish(self) -> Result<Vec<Fragment>> {
        let k = self.camera.intrinsics;
        let mut out = self
            .suspended
            .into_iter()
            .map(|f| f.into_fragment(None, &k))
            .collect::<Result<Vec<Fragment>>>()?;
        out.push(self.current.into_fragment(None, &k)?);
        out.sort_by_key(|f| f.index);
        Ok(out)
    }
}

/// The part of `cfg`'s budget the current fragment's volume gets: what neither the suspended
/// fragment nor the caller's reserve (`reserved_bytes`) holds.
fn current_share(
    cfg: &ReconstructionConfig,
    suspended: Option<&Live>,
    reserved_bytes: usize,
) -> usize {
    let held = suspended
        .map_or(0, |s| s.volume.memory_bytes())
        .saturating_add(reserved_bytes);
    cfg.tsdf.memory_budget_bytes.saturating_sub(held)
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::nalgebra::Vector3;

    /// A corner of three walls seen by a still Kinect at 320×240 (the type's example).
    fn corner() -> (Camera, DepthImage) {
        let cam = Camera::kinect_v1().resampled(0.5).unwrap();
        let k = cam.intrinsics;
        let walls = [
            (Vector3::new(0.3f64, 0.2, -1.0).normalize(), 2.0f64),
            (Vector3::new(-0.8, 0.1, -0.6).normalize(), 1.5),
            (Vector3::new(0.1, -0.9, -0.4).normalize(), 1.2),
        ];
        let mut z = vec![0f32; k.width * k.height];
        for (i, zi) in z.iter_mut().enumerate() {
            let ray = k.ray((i % k.width) as f64, (i / k.width) as f64);
            let near = walls
                .iter()
                .map(|(n, d)| -d / n.dot(&ray))
                .filter(|s| *s > 0.0);
            *zi = near.fold(f64::INFINITY, f64::min) as f32;
        }
        (cam, DepthImage::from_vec(k.width, k.height, z).unwrap())
    }

    /// A model found full in a step that could not go on in a continuation (one that handed
    /// another fragment over) goes on in one at the next step: that step's frame is the
    /// continuation's first, fused with the step after, and the full fragment is handed over
    /// with every frame it fused. Without continuations the model stays full.
    #[test]
    fn a_full_model_left_by_a_busy_step_continues_at_the_next() {
        let (cam, depth) = corner();
        for continue_when_full in [true, false] {
            let mut cfg = ReconstructionConfig::default_for(cam.sensor);
            cfg.new_volume_when_full = continue_when_full;
            let mut rec = Reconstruction::new(cam, cfg).unwrap();
            for _ in 0..3 {
                assert!(rec.step(&depth, None).unwrap().result.status.is_tracked());
            }
            let fused = rec.volume().frame_count();
            assert!(fused > 0);
            // What a step that handed a fragment over leaves: a full model, not continued.
            rec.current.model_full = Some("full".into());
            let step = rec.step(&depth, None).unwrap();
            assert!(step.result.status.is_tracked() && step.model_full.is_none());
            if !continue_when_full {
                assert!(step.continued.is_none() && step.finished.is_none());
                assert_eq!((rec.fragment(), rec.model_full()), (0, Some("full")));
                continue;
            }
            assert_eq!(
                (step.continued, step.fragment, step.fused),
                (Some(0), 1, false)
            );
            let done = step.finished.expect("the full fragment is handed over");
            assert_eq!((done.index, done.volume.frame_count()), (0, fused));
            assert_eq!(done.model_full.as_deref(), Some("full"));
            assert!(rec.model_full().is_none() && rec.volume().frame_count() == 0);
            // The continuation's next frame is tracked against the full model, rendered from
            // this frame's pose; once its own model is rendered, against that one.
            assert!(step.timings.raycast_ms.is_some());
            assert!(rec.current.on_full_model && rec.current.model.maps().is_some());
            let next = rec.step(&depth, None).unwrap();
            assert!(next.fused && next.finished.is_none() && next.fragment == 1);
            assert!(next.result.status.is_tracked() && !rec.current.on_full_model);
            assert_eq!(rec.volume().frame_count(), 2);
            let left = rec.finish().unwrap();
            assert_eq!(left[0].continues, Some(0));
            assert_eq!(left[0].joined.map(|j| j.into), Some(0));
        }
    }
}
