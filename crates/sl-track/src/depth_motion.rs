//! Motion between two depth frames end to end: extract planes in both, estimate the rotation
//! from matched planes (verified against the depth data unless asked not to), then optionally
//! refine with point-to-plane ICP that is kept only when the depth data confirm it. The
//! `sldepth motion` command and the Python `sldepth.motion` are thin formatters of this.

use nalgebra::Vector3;
use sl_core::{Camera, CameraToCamera, DepthImage};

use crate::error::{Result, TrackError};
use crate::motion::{
    IcpConfig, IcpOutcome, MotionConfig, MotionFrame, PlaneMotion, VerifyConfig, estimate_motion,
    estimate_motion_verified_or_candidates, refine_motion_icp_verified,
};
use sl_planes::{PlaneConfig, PlaneExtractor, PlaneInfo};

/// How [`motion_between_depths`] works.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct DepthMotionConfig {
    /// Plane extraction.
    pub planes: PlaneConfig,
    /// Plane matching and rotation.
    pub motion: MotionConfig,
    /// Check every hypothesis against both depth maps (default); `false` keeps the plain plane
    /// estimate, which assumes a small motion.
    pub verify: bool,
    /// Refine with point-to-plane ICP (kept only when verified).
    pub icp: bool,
}

impl Default for DepthMotionConfig {
    fn default() -> Self {
        Self {
            planes: PlaneConfig::default(),
            motion: MotionConfig::default(),
            verify: true,
            icp: false,
        }
    }
}

impl DepthMotionConfig {
    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.planes.validate()?;
        self.motion.validate()
    }
}

/// The planes of both frames, the motion estimate and the ICP decision.
#[derive(Debug, Clone)]
pub struct DepthMotion {
    /// Planes of frame A (the reference).
    pub planes_a: Vec<PlaneInfo>,
    /// Planes of frame B.
    pub planes_b: Vec<PlaneInfo>,
    /// The plane-based motion (`X_a = R·X_b + t`), or why it is undetermined
    /// ([`TrackError::MotionNotVerified`] / [`TrackError::MotionUndetermined`]).
    pub motion: std::result::Result<PlaneMotion, TrackError>,
    /// The ICP refinement and whether it was kept (with `icp` and a determined motion).
    pub icp: Option<IcpOutcome>,
    /// When the verification could not decide ([`TrackError::MotionNotVerified`]): the
    /// refined alignments `X_a = R·X_b + t` the depth data do not rule out, best first, each
    /// more than [`MotionConfig::distinct_deg`] from those before it (at most three). Evidence
    /// beyond the two frames can tell them apart: the tracker aligns its fused model from
    /// each. Empty otherwise.
    pub candidates: Vec<CameraToCamera>,
}

impl DepthMotion {
    /// The final pose `X_a = R·X_b + t`: the accepted ICP refinement, else the plane estimate;
    /// `None` when undetermined. Without a determined translation it is 0.
    pub fn pose(&self) -> Option<CameraToCamera> {
        let m = self.motion.as_ref().ok()?;
        Some(self.icp.as_ref().map_or_else(|| m.motion(), |o| o.pose))
    }

    /// The translation, when it is determined (the matched normals span 3D, or ICP was kept).
    pub fn translation_m(&self) -> Option<Vector3<f64>> {
        let m = self.motion.as_ref().ok()?;
        match &self.icp {
            Some(o) if o.accepted => Some(o.pose.translation()),
            _ => m.translation_m,
        }
    }
}

/// Estimates the motion between two depth frames of one camera (see the module docs). An
/// undetermined motion is not an error: it is reported in [`DepthMotion::motion`].
pub fn motion_between_depths(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    cfg: &DepthMotionConfig,
) -> Result<DepthMotion> {
    cfg.validate()?;
    let mut extractor = PlaneExtractor::new(cfg.planes)?;
    let planes_a = extractor.extract_depth(depth_a, camera)?.planes;
    let planes_b = extractor.extract_depth(depth_b, camera)?.planes;
    let vcfg = VerifyConfig::default();
    let (estimate, candidates) = if cfg.verify {
        // An undetermined motion, before any decision, comes as the outer error: reported
        // below like the decision's own.
        estimate_motion_verified_or_candidates(
            MotionFrame {
                depth: depth_a,
                planes: &planes_a,
            },
            MotionFrame {
                depth: depth_b,
                planes: &planes_b,
            },
            camera,
            None,
            &cfg.motion,
            &vcfg,
        )
        .unwrap_or_else(|e| (Err(e), Vec::new()))
    } else {
        (
            estimate_motion(&planes_a, &planes_b, None, &cfg.motion),
            Vec::new(),
        )
    };
    let motion = match estimate {
        Ok(m) => Ok(m),
        Err(e @ (TrackError::MotionNotVerified { .. } | TrackError::MotionUndetermined(_))) => {
            Err(e)
        }
        Err(e) => return Err(e),
    };
    let icp = match (&motion, cfg.icp) {
        (Ok(m), true) => {
            // From a verified alignment a tight correspondence gate; from the plane estimate
            // alone the wide default.
            let icp_cfg = if m.verification.is_some() {
                IcpConfig::refinement()
            } else {
                IcpConfig::default()
            };
            Some(refine_motion_icp_verified(
                depth_a,
                depth_b,
                camera,
                m,
                &icp_cfg,
                &cfg.motion,
                &vcfg,
            )?)
        }
        _ => None,
    };
    Ok(DepthMotion {
        planes_a,
        planes_b,
        motion,
        icp,
        candidates,
    })
}
