//! Point-to-plane ICP with projective data association, and the verified refinement that keeps
//! an ICP result only when the depth data confirm it.

use super::*;

/// Parameters of point-to-plane ICP.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct IcpConfig {
    /// Iterations.
    pub iterations: usize,
    /// Pixel stride of the source (B) samples.
    pub stride: usize,
    /// Correspondence distance at the first iteration, metres.
    pub max_dist_m: f64,
    /// Correspondence distance at the last iteration, metres.
    pub min_dist_m: f64,
}

impl Default for IcpConfig {
    /// From a rough start (e.g. the identity): correspondences up to 15 cm apart at first.
    fn default() -> Self {
        Self {
            iterations: 30,
            stride: 4,
            max_dist_m: 0.15,
            min_dist_m: 0.02,
        }
    }
}

impl IcpConfig {
    /// For refining a verified alignment ([`refine_motion_icp_verified`]): as the default
    /// but with correspondences at most 5 cm apart from the first iteration. The verified
    /// alignment already puts ≥ 90 % of the overlapping points within the inlier tolerance
    /// of [`VerifyConfig`] (1 cm + 3σ_Z, under 3 cm up to 3 m), so a pair further apart is
    /// almost always a point matched to the wrong surface. With the default 15 cm such pairs
    /// dominate when the views overlap little and pull the rotation about a dominant plane's
    /// normal, which the rest of the view constrains only weakly (TUM fr1/rpy 0 → 15: 34.8° of
    /// motion, 27 % overlap; 15 cm from the verified alignment ends 3.6° from the motion
    /// capture, 5 cm ends 1.5° away and explains 99 % instead of 96 % of the overlap).
    pub fn refinement() -> Self {
        Self {
            max_dist_m: 0.05,
            ..Self::default()
        }
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 || self.stride == 0 {
            return Err(TrackError::InvalidConfig(
                "ICP iterations and stride must be ≥ 1".into(),
            ));
        }
        if !(self.min_dist_m.is_finite()
            && self.min_dist_m > 0.0
            && self.max_dist_m.is_finite()
            && self.max_dist_m >= self.min_dist_m)
        {
            return Err(TrackError::InvalidConfig(format!(
                "ICP needs 0 < min_dist_m ≤ max_dist_m, got {} and {}",
                self.min_dist_m, self.max_dist_m
            )));
        }
        Ok(())
    }
}

/// The result of ICP.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpResult {
    /// The motion `X_a = R·X_b + t`.
    pub pose: CameraToCamera,
    /// Correspondences used in the last iteration.
    pub inliers: usize,
    /// RMS point-to-plane residual of the last iteration, metres.
    pub rms_m: f64,
}

/// Point-to-plane ICP aligning depth frame B to frame A (same camera), with projective data
/// association into A and normals of A from the depth image; starts from `init`.
///
/// ICP only minimises residuals: nothing checks that the result explains the data better
/// than its start. To refine a verified motion use [`refine_motion_icp_verified`], which
/// accepts the refinement only when the depth data confirm it.
pub fn icp_point_to_plane(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    init: &CameraToCamera,
    cfg: &IcpConfig,
) -> Result<IcpResult> {
    let mut target = Target::new(depth_a, camera)?;
    let k = &camera.intrinsics;
    if depth_b.width() != k.width || depth_b.height() != k.height {
        return Err(TrackError::SizeMismatch {
            expected_width: k.width,
            expected_height: k.height,
            width: depth_b.width(),
            height: depth_b.height(),
        });
    }
    let src = verify::grid_points(depth_b, k, cfg.stride);
    let (pose, inliers, rms_m) = verify::icp(
        &mut target,
        &src,
        init.isometry(),
        cfg.iterations,
        cfg.max_dist_m,
        cfg.min_dist_m,
    )?;
    Ok(IcpResult {
        pose: CameraToCamera::from_isometry(pose),
        inliers,
        rms_m,
    })
}

/// Largest loss of inlier fraction (of the overlapping points, see [`Verification`]) with
/// which an ICP refinement is still accepted by [`refine_motion_icp_verified`]: 0.001, i.e.
/// 8 of the 8000 points of the default two-way check. The fraction is a ratio of counts, and
/// a refinement that moves the pose by a hundredth of a degree flips a few points at the
/// tolerance boundary either way; a loss beyond that is a real loss.
pub const ICP_INLIER_TOLERANCE: f64 = 1e-3;

/// One-sided 99.9 % quantile of the standard normal: [`refine_motion_icp_verified`] refuses an
/// ICP refinement for lost inliers only when the net loss of the discordant samples exceeds
/// this many standard deviations (McNemar's test).
pub const ICP_LOSS_Z: f64 = 3.09;

/// McNemar's test on the samples two poses disagree about: `only_before` are inliers of the
/// estimate only, `only_after` of the refinement only. Under "both poses explain the data
/// equally well" each discordant sample is as likely to favour either, so the net loss
/// `only_before − only_after` is ~N(0, only_before + only_after); the loss is significant
/// beyond the one-sided 99.9 % quantile ([`ICP_LOSS_Z`] standard deviations).
pub fn significant_loss(only_before: usize, only_after: usize) -> bool {
    let lost = only_before as f64 - only_after as f64;
    lost > ICP_LOSS_Z * ((only_before + only_after) as f64).sqrt()
}

/// Why [`refine_motion_icp_verified`] kept the plane estimate.
#[derive(Debug, Clone, PartialEq)]
pub enum IcpRejection {
    /// ICP itself failed (too few correspondences, singular normal equations).
    Failed(String),
    /// The refined pose is not consistent with the data: it explains fewer than
    /// `min_inlier_fraction` of the overlapping points or overlaps the other frame with fewer
    /// than `min_overlap_fraction` of the points ([`VerifyConfig`]).
    NotVerified,
    /// The refined pose explains a smaller fraction of the overlapping points than the
    /// verified estimate (by more than [`ICP_INLIER_TOLERANCE`], and significantly by
    /// McNemar's test, [`ICP_LOSS_Z`]).
    LostInliers,
    /// The refined rotation is more than [`MotionConfig::distinct_deg`] from the start: a
    /// distinct alternative that the verification did not rule in.
    MovedTooFar,
}

impl IcpRejection {
    /// Short lower-case name (`icp-failed`, `not-verified`, `lost-inliers`, `moved-too-far`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Failed(_) => "icp-failed",
            Self::NotVerified => "not-verified",
            Self::LostInliers => "lost-inliers",
            Self::MovedTooFar => "moved-too-far",
        }
    }
}

/// The result of [`refine_motion_icp_verified`].
#[derive(Debug, Clone, PartialEq)]
pub struct IcpOutcome {
    /// Whether the ICP refinement was accepted (`rejection` is `None` exactly then).
    pub accepted: bool,
    /// Why it was not.
    pub rejection: Option<IcpRejection>,
    /// The motion to use: ICP's pose when accepted, else the plane estimate
    /// ([`PlaneMotion::motion`]).
    pub pose: CameraToCamera,
    /// Where ICP started: the verified alignment ([`Verification::aligned`]) when the motion
    /// has one, else the plane estimate.
    pub start: CameraToCamera,
    /// ICP's own result (also when rejected); `None` when ICP failed.
    pub icp: Option<IcpResult>,
    /// Inlier fraction of the estimate before the refinement: the verification's
    /// ([`Verification::inlier_fraction`]), or for an unverified motion that of the plane
    /// estimate, scored the same way.
    pub inlier_fraction_before: f64,
    /// Inlier fraction of ICP's pose (two-way, as in the verification); `None` when ICP
    /// failed.
    pub inlier_fraction_after: Option<f64>,
    /// Overlap fraction of ICP's pose; `None` when ICP failed.
    pub overlap_fraction_after: Option<f64>,
}

/// Refines a plane-based motion by point-to-plane ICP and accepts the refinement only when
/// the depth data confirm it; otherwise keeps the plane estimate.
///
/// ICP starts from the verified alignment ([`Verification::aligned`], the pose the
/// verification scored) when the motion has one, else from [`PlaneMotion::isometry`]; use
/// [`IcpConfig::refinement`] (a tight correspondence gate) for a verified start. The ICP pose
/// is then checked exactly like a hypothesis in [`estimate_motion_verified`] (the same
/// two-way grid samples of both depth maps and the same tolerances of `vcfg`) and accepted
/// only when
/// * it overlaps the other frame with `min_overlap_fraction` of the points and explains
///   `min_inlier_fraction` of the overlapping ones (it is itself verified);
/// * it explains no smaller a fraction than the estimate did, up to
///   [`ICP_INLIER_TOLERANCE`] or, beyond it, by a loss that McNemar's test on the two poses'
///   discordant samples does not find significant ([`ICP_LOSS_Z`]);
/// * its rotation lies within `mcfg.distinct_deg` of the start (a rotation further away is an
///   alternative that the verification's ambiguity checks never saw).
///
/// The decision uses the depth maps only, never a reference trajectory. When rejected, the
/// outcome's `pose` is the plane estimate and `rejection` says why; ICP's own result is kept
/// for inspection.
///
/// # Errors
/// Size and configuration errors only; a failing ICP is a rejection.
///
/// ```
/// use sl_core::{Camera, DepthImage, nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3}};
/// use sl_track::{IcpConfig, MotionConfig, MotionFrame, Plane, PlaneConfig, PlaneExtractor,
///     VerifyConfig, estimate_motion_verified, refine_motion_icp_verified};
///
/// // Floor, ceiling and two walls seen by a 160x120 camera, which then turns 10° and moves.
/// let k = sl_core::Intrinsics::new(160, 120, 80.0, 80.0, 79.5, 59.5)?;
/// let cam = Camera { intrinsics: k, sensor: sl_core::SensorModel::kinect_v1() };
/// let room = [
///     Plane::new(Vector3::new(0.0, -1.0, 0.0), 0.8)?.facing_origin(),
///     Plane::new(Vector3::new(-0.048, 0.999, -0.012), 1.6)?.facing_origin(),
///     Plane::new(Vector3::new(-0.982, -0.1, 0.158), 1.5)?.facing_origin(),
///     Plane::new(Vector3::new(-0.213, 0.164, -0.963), 3.0)?.facing_origin(),
/// ];
/// let render = |planes: &[Plane]| {
///     let z = (0..k.width * k.height).map(|i| {
///         let (x, y) = ((i % k.width) as f64, (i / k.width) as f64);
///         let z = planes.iter().filter_map(|p| p.depth_at(&k, x, y)).fold(f64::INFINITY, f64::min);
///         if z.is_finite() { z as f32 } else { 0.0 }
///     });
///     DepthImage::from_vec(k.width, k.height, z.collect())
/// };
/// let truth = Isometry3::from_parts(
///     Translation3::new(0.03, 0.0, 0.02),
///     UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 10f64.to_radians()),
/// );
/// let room_b: Vec<Plane> = room.iter().map(|p| p.transformed(&truth.inverse()).facing_origin()).collect();
/// let (da, db) = (render(&room)?, render(&room_b)?);
/// let mut cfg = PlaneConfig::default();
/// cfg.min_pixels = 200;
/// let mut ex = PlaneExtractor::new(cfg)?;
/// let (sa, sb) = (ex.extract_depth(&da, &cam)?, ex.extract_depth(&db, &cam)?);
/// let (mcfg, vcfg) = (MotionConfig::default(), VerifyConfig::default());
/// let m = estimate_motion_verified(
///     MotionFrame { depth: &da, planes: &sa.planes },
///     MotionFrame { depth: &db, planes: &sb.planes },
///     &cam, None, &mcfg, &vcfg,
/// )?;
/// let out = refine_motion_icp_verified(&da, &db, &cam, &m, &IcpConfig::refinement(), &mcfg, &vcfg)?;
/// assert!(out.accepted, "{:?}", out.rejection);
/// assert!(out.inlier_fraction_after.is_some_and(|f| f + 1e-3 >= out.inlier_fraction_before));
/// assert!(out.pose.rotation().angle_to(&truth.rotation).to_degrees() < 0.5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn refine_motion_icp_verified(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    motion: &PlaneMotion,
    cfg: &IcpConfig,
    mcfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<IcpOutcome> {
    cfg.validate()?;
    mcfg.validate()?;
    vcfg.validate()?;
    let estimate = motion.motion();
    let start = motion.verification.as_ref().map_or(estimate, |v| v.aligned);
    let mut check = TwoWay::new(
        depth_a,
        depth_b,
        camera,
        vcfg.max_samples,
        (SPARSE_SAMPLES, COARSE_SAMPLES),
    )?;
    let tol = (vcfg.inlier_base_m, vcfg.inlier_sigmas);
    // The verification scored `aligned` on these same samples and tolerances.
    let inlier_fraction_before = match &motion.verification {
        Some(v) => v.inlier_fraction,
        None => check
            .score(estimate.isometry(), tol, Density::Full)
            .inlier_fraction(),
    };
    let mut outcome = IcpOutcome {
        accepted: false,
        rejection: None,
        pose: estimate,
        start,
        icp: None,
        inlier_fraction_before,
        inlier_fraction_after: None,
        overlap_fraction_after: None,
    };
    let icp = match icp_point_to_plane(depth_a, depth_b, camera, &start, cfg) {
        Ok(r) => r,
        Err(TrackError::MotionUndetermined(why)) => {
            outcome.rejection = Some(IcpRejection::Failed(why));
            return Ok(outcome);
        }
        Err(e) => return Err(e),
    };
    let score = check.score(icp.pose.isometry(), tol, Density::Full);
    let (inl, ovl) = (score.inlier_fraction(), score.overlap_fraction());
    outcome.inlier_fraction_after = Some(inl);
    outcome.overlap_fraction_after = Some(ovl);
    outcome.rejection = if ovl < vcfg.min_overlap_fraction || inl < vcfg.min_inlier_fraction {
        Some(IcpRejection::NotVerified)
    } else if inl + ICP_INLIER_TOLERANCE < inlier_fraction_before && {
        let (only_before, only_after) =
            check.discordant(start.isometry(), icp.pose.isometry(), tol, Density::Full);
        significant_loss(only_before, only_after)
    } {
        Some(IcpRejection::LostInliers)
    } else if icp.pose.rotation().angle_to(&start.rotation()) > mcfg.distinct_deg.to_radians() {
        Some(IcpRejection::MovedTooFar)
    } else {
        None
    };
    outcome.accepted = outcome.rejection.is_none();
    if outcome.accepted {
        outcome.pose = icp.pose;
    }
    outcome.icp = Some(icp);
    Ok(outcome)
}
