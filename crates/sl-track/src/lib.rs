//! # sl-track — where is the camera
//!
//! Camera motion for structured-light depth cameras, weighted by the sensor's noise model
//! (σ_Z = Z²·σ_D/(f·B)). Pipeline position: depth frames → `sl-io` → `sl-core` types →
//! **`sl-track`** (poses) → `sl-tsdf` (fusion); `sl-track` uses `sl-planes` for plane
//! extraction and `sl-tsdf` for the model it tracks against.
//!
//! * [`motion`] (paper section 3.5): plane matching, rotation (weighted Kabsch) and translation
//!   from planes, [`estimate_motion_verified`] checking every plane hypothesis against both
//!   depth maps (no prior needed; "not determined" rather than a wrong rotation), and
//!   point-to-plane ICP ([`refine_motion_icp_verified`]: a refinement is kept only when the
//!   depth data verify it). [`motion_between_depths`] does it all for two depth frames
//!   (`sldepth motion`, Python's `sldepth.motion`).
//! * [`Tracker`]: frame-to-model tracking of a depth sequence. Projective data association
//!   against [`ReferenceMaps`] (a raycast of the fused model, or the previous frame),
//!   point-to-plane Gauss–Newton on SE(3) over a depth pyramid, a robust kernel on the
//!   residual normalised by its standard deviation from the sensor model ([`WeightMode`]),
//!   a constant-velocity prior (or an odometry's, [`Tracker::set_odometry`], which also pins
//!   what the depth cannot: a corridor's axis, a single wall), failure detection and the
//!   verified plane-based estimate as the fallback; a frame that cannot be tracked is reported
//!   lost, never given a wrong pose.
//! * [`Reconstruction`]: the tracker and the fused model in one loop (`sldepth track`,
//!   Python's `Tracker`), with a new fragment (own volume and world frame) when tracking stays
//!   lost.
//!
//! ```
//! use sl_core::{Camera, CameraToWorld, DepthImage, Intrinsics, SensorModel};
//! use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
//! use sl_track::{Tracker, TrackerConfig, TrackStatus};
//!
//! // A corner of three walls seen by an 80x60 camera, which then moves 1 cm sideways.
//! let k = Intrinsics::new(80, 60, 60.0, 60.0, 39.5, 29.5)?;
//! let cam = Camera { intrinsics: k, sensor: SensorModel::kinect_v1() };
//! let walls = [
//!     (Vector3::new(0.3f64, 0.2, -1.0).normalize(), 2.0f64),
//!     (Vector3::new(-0.8, 0.1, -0.6).normalize(), 1.5),
//!     (Vector3::new(0.1, -0.9, -0.4).normalize(), 1.2),
//! ];
//! let render = |pose: &CameraToWorld| -> Result<DepthImage, sl_core::CoreError> {
//!     let mut z = vec![0f32; k.width * k.height];
//!     for (i, zi) in z.iter_mut().enumerate() {
//!         let ray = pose.rotation() * k.ray((i % k.width) as f64, (i / k.width) as f64);
//!         let o = pose.translation();
//!         let mut best = f64::INFINITY;
//!         for (n, d) in &walls {
//!             let s = -(n.dot(&o) + d) / n.dot(&ray);
//!             if s > 0.0 && s < best { best = s; }
//!         }
//!         if best.is_finite() { *zi = best as f32; }
//!     }
//!     DepthImage::from_vec(k.width, k.height, z)
//! };
//! let moved = CameraToWorld::from_isometry(Isometry3::from_parts(
//!     Translation3::new(0.01, 0.0, 0.0),
//!     UnitQuaternion::identity(),
//! ));
//! let mut tracker = Tracker::new(cam, TrackerConfig::default())?;
//! let first = tracker.track(&render(&CameraToWorld::identity())?, None)?;
//! assert_eq!(first.status, TrackStatus::Initialised);
//! let second = tracker.track(&render(&moved)?, None)?;
//! assert_eq!(second.status, TrackStatus::Tracked);
//! let err = (second.pose.translation() - moved.translation()).norm();
//! assert!(err < 1e-3, "translation error {err} m");
//! # let _: CameraToWorld = second.pose;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod depth_motion;
pub mod error;
pub mod in_map;
pub mod motion;
mod pool;
pub mod reconstruction;
pub mod rolling_shutter;
pub mod track;
mod verify;

pub use depth_motion::{DepthMotion, DepthMotionConfig, motion_between_depths};
pub use error::{Result, TrackError};
pub use in_map::{track_in_map, track_in_map_with_noise};
pub use motion::{
    ICP_INLIER_TOLERANCE, ICP_LOSS_Z, IcpConfig, IcpOutcome, IcpRejection, IcpResult,
    MotionConfidence, MotionConfig, MotionFrame, PlaneMatch, PlaneMotion, Verification,
    VerifyConfig, estimate_motion, estimate_motion_verified, icp_point_to_plane,
    refine_motion_icp_verified, significant_loss,
};
pub use reconstruction::{
    Fragment, FragmentJoin, Reconstruction, ReconstructionConfig, Step, StepTimings,
    continued_chain,
};
/// Plane extraction, re-exported for the motion API's inputs (`PlaneInfo`, `PlaneConfig`).
pub use sl_planes::{Plane, PlaneConfig, PlaneExtractor, PlaneInfo};
pub use track::{
    DEFAULT_LATERAL_SIGMA_PX, FrameResult, MAX_ODOMETRY_STEP_M, ModelReference,
    ODOMETRY_WEAK_SHARE, ReferenceMaps, TrackStatus, Tracker, TrackerConfig, WeightMode,
};
