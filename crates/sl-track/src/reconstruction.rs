//! Tracking and fusing a depth sequence in one loop ([`Reconstruction`]): every frame is
//! tracked against the raycast of the model fused so far and every tracked frame is fused into
//! it — the loop of `sldepth track` and of Python's `sldepth.Tracker` — and a recording whose
//! tracking is lost for good goes on in a new **fragment** (its own volume and world frame)
//! instead of being lost to its end.
//!
//! # Fragments
//! After a lost frame the tracker aligns the next frames from the last good pose (relocalisation,
//! see [`Tracker`]): that succeeds when the camera comes back to within a few centimetres and
//! degrees of where tracking was lost — a hand over the lens, a short view of a bare wall. A
//! camera that has moved on never comes back into that basin, and every later frame would be
//! lost. So when frames that *could* be aligned (enough depth, a view that pins all six degrees
//! of freedom) keep failing to align for [`ReconstructionConfig::new_fragment_after_s`]
//! seconds of the recording, the fragment ends: its volume is handed to the caller
//! ([`Step::finished`]), the tracker forgets the sequence ([`Tracker::restart`]) and the frame
//! starts a new fragment, whose world frame is its first camera. Frames that cannot be aligned
//! at all (no depth, a degenerate view) do not count: a camera that still looks at the same
//! wall may well relocalise once it turns back. Fragments are not registered to each other
//! (that needs place recognition, which sl-track does not have).
//!
//! The time is a policy, not a property of the sensor: shorter loses less of a recording whose
//! camera has moved on, longer leaves more time to relocalise. The default, one second, is two
//! to three times the longest relocalisation measured on TUM fr1/rpy with the lens covered for
//! 1.5 s (docs/bench/track.md, "Session 17").

use std::time::Instant;

use sl_core::{Camera, DepthImage, SensorModel};
use sl_tsdf::{RaycastConfig, Truncation, TsdfConfig, TsdfVolume};

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
}

impl ReconstructionConfig {
    /// The defaults for a camera with `sensor`: 4 mm voxels, the sensor-adaptive truncation band
    /// with a 2 cm (5-voxel) floor and 1/Z⁴ weights ([`TsdfConfig::default`] with the sensor's
    /// model), frame-to-model tracking with the default tracker, a new fragment after 1 s.
    pub fn default_for(sensor: SensorModel) -> Self {
        let mut tsdf = TsdfConfig::default();
        tsdf.truncation = Truncation::sensor_adaptive(sensor);
        Self {
            tracker: TrackerConfig::default(),
            tsdf,
            frame_to_model: true,
            model_scale: None,
            new_fragment_after_s: Some(1.0),
        }
    }

    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.tracker.validate()?;
        self.tsdf.validate()?;
        if let Some(s) = self.model_scale
            && !(s > 0.0 && s <= 1.0)
        {
            return Err(TrackError::InvalidConfig(format!(
                "model_scale must lie in (0, 1], got {s}"
            )));
        }
        if let Some(s) = self.new_fragment_after_s
            && (s.is_nan() || s <= 0.0)
        {
            return Err(TrackError::InvalidConfig(format!(
                "new_fragment_after_s must be positive (None: never), got {s}"
            )));
        }
        Ok(())
    }
}

/// A fragment of the sequence: its volume, in its own world frame (its first camera's).
#[derive(Debug)]
pub struct Fragment {
    /// 0 for the first fragment, then in order.
    pub index: usize,
    /// Everything fused into it.
    pub volume: TsdfVolume,
    /// Frames tracked (and fused) in it.
    pub tracked_frames: usize,
}

/// Wall-clock time of a step's stages, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepTimings {
    /// Tracking (both attempts when the frame started a new fragment).
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
    /// The fragment this frame closed, when it started a new one (its volume is the caller's
    /// now: extract its mesh or drop it).
    pub finished: Option<Fragment>,
    /// Where the time went.
    pub timings: StepTimings,
}

/// Tracks a depth sequence and fuses it, fragment by fragment (see the module docs).
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
    camera: Camera,
    cfg: ReconstructionConfig,
    tracker: Tracker,
    volume: TsdfVolume,
    model: ModelReference,
    fragment: usize,
    fragment_tracked: usize,
    /// Frame intervals of frames lost after an alignment attempt since the last tracked frame
    /// (whole intervals, as the tracker counts time: a driver's timestamp jitter is not time).
    failed_intervals: u64,
    /// The previous frame's timestamp, seconds.
    last_time_s: Option<f64>,
}

impl Reconstruction {
    /// A reconstruction of `camera`'s frames.
    ///
    /// # Errors
    /// An invalid configuration or camera.
    pub fn new(camera: Camera, cfg: ReconstructionConfig) -> Result<Self> {
        cfg.validate()?;
        let tracker = Tracker::new(camera, cfg.tracker)?;
        let volume = TsdfVolume::new(cfg.tsdf)?;
        let mut raycast = RaycastConfig::default();
        raycast.min_depth_m = cfg.tsdf.min_depth_m;
        raycast.max_depth_m = cfg.tsdf.max_depth_m;
        let scale = cfg
            .model_scale
            .unwrap_or_else(|| ModelReference::default_scale(&camera));
        let model = ModelReference::new(&camera.intrinsics, scale, raycast)?;
        Ok(Self {
            camera,
            cfg,
            tracker,
            volume,
            model,
            fragment: 0,
            fragment_tracked: 0,
            failed_intervals: 0,
            last_time_s: None,
        })
    }

    /// Tracks `depth` (the camera's size, metres, 0 = invalid; already undistorted and
    /// smoothed as wanted), fuses it when tracked and renders the model for the next frame.
    /// `timestamp_s`: the frame's time (see [`Tracker::track_at`]); `None` takes it to follow
    /// the previous frame by one frame interval. May start a new fragment (see the module
    /// docs); the frame is then its first.
    ///
    /// # Errors
    /// As [`Tracker::track_at`]; a volume over its memory budget
    /// ([`TsdfConfig::memory_budget_bytes`]).
    pub fn step(&mut self, depth: &DepthImage, timestamp_s: Option<f64>) -> Result<Step> {
        let t0 = Instant::now();
        let frame_interval_s = self.cfg.tracker.frame_interval_s;
        let intervals = match (timestamp_s, self.last_time_s) {
            (Some(t), Some(p)) => ((t - p) / frame_interval_s).round().clamp(1.0, 1e9) as u64,
            _ => 1,
        };
        let mut result = self.track(depth, timestamp_s)?;
        if timestamp_s.is_some() {
            self.last_time_s = timestamp_s;
        }
        let mut finished = None;
        if result.status.is_tracked() {
            self.failed_intervals = 0;
        } else if result.iterations > 0 {
            self.failed_intervals = self.failed_intervals.saturating_add(intervals);
            let limit = self
                .cfg
                .new_fragment_after_s
                .map(|s| (s / frame_interval_s).round().max(1.0));
            if self.fragment_tracked > 0 && limit.is_some_and(|l| self.failed_intervals as f64 >= l)
            {
                finished = Some(self.new_fragment()?);
                result = self.track(depth, timestamp_s)?;
            }
        }
        let track_ms = ms_since(t0);
        let (mut integrate_ms, mut raycast_ms) = (None, None);
        if result.status.is_tracked() {
            let t1 = Instant::now();
            let k = self.camera.intrinsics;
            self.volume.integrate(depth, &k, &result.pose)?;
            integrate_ms = Some(ms_since(t1));
            if self.cfg.frame_to_model {
                let t2 = Instant::now();
                self.model.update_from_frame(
                    &self.volume,
                    &result.pose,
                    &self.camera.sensor,
                    depth,
                    &k,
                )?;
                raycast_ms = Some(ms_since(t2));
            }
            self.fragment_tracked += 1;
        }
        Ok(Step {
            result,
            fragment: self.fragment,
            finished,
            timings: StepTimings {
                track_ms,
                integrate_ms,
                raycast_ms,
                step_ms: ms_since(t0),
            },
        })
    }

    fn track(&mut self, depth: &DepthImage, timestamp_s: Option<f64>) -> Result<FrameResult> {
        let model = if self.cfg.frame_to_model {
            self.model.maps()
        } else {
            None
        };
        match timestamp_s {
            Some(t) => self.tracker.track_at(depth, model, t),
            None => self.tracker.track(depth, model),
        }
    }

    /// Ends the current fragment and starts an empty one.
    fn new_fragment(&mut self) -> Result<Fragment> {
        let fresh = TsdfVolume::new(self.cfg.tsdf)?;
        let volume = std::mem::replace(&mut self.volume, fresh);
        let done = Fragment {
            index: self.fragment,
            volume,
            tracked_frames: self.fragment_tracked,
        };
        self.tracker.restart();
        self.model.clear();
        self.fragment += 1;
        self.fragment_tracked = 0;
        self.failed_intervals = 0;
        Ok(done)
    }

    /// The current fragment's index.
    pub fn fragment(&self) -> usize {
        self.fragment
    }

    /// The current fragment's volume.
    pub fn volume(&self) -> &TsdfVolume {
        &self.volume
    }

    /// The tracker.
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The model reference (the last rendering of the current fragment's model).
    pub fn model(&self) -> &ModelReference {
        &self.model
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The configuration.
    pub fn config(&self) -> &ReconstructionConfig {
        &self.cfg
    }

    /// Ends the reconstruction and hands over the current fragment.
    pub fn finish(self) -> Fragment {
        Fragment {
            index: self.fragment,
            volume: self.volume,
            tracked_frames: self.fragment_tracked,
        }
    }
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
