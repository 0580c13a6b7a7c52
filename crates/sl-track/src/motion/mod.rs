//! Motion between two frames from matched planes (paper section 3.5), verified against the
//! depth data, and point-to-plane ICP.
//!
//! Convention: the motion `(R, t)` maps frame B's camera coordinates into frame A's,
//! `X_a = R·X_b + t`; a plane `n_b·X + d_b = 0` of B becomes `n_a = R·n_b`,
//! `d_a = d_b − n_a·t` in A.
//!
//! * **Hypotheses.** Candidate pairs are all (A plane, B plane) pairs, or with a prior only
//!   those whose normals (after the prior) differ by less than `max_angle_deg` and offsets by
//!   less than `max_offset_m`. Every two candidate pairs with non-parallel normals whose mutual
//!   angles agree (∠(n_a1, n_a2) ≈ ∠(n_b1, n_b2)) propose a rotation (Kabsch on the two
//!   normals). Each proposal collects its one-to-one plane matches within `inlier_angle_deg`
//!   whose offsets agree with one translation (within `inlier_offset_m`), is refined by
//!   weighted Kabsch over them, and is scored by their support (sum of the smaller pixel count
//!   of each match). Proposals closer than `inlier_angle_deg` are merged.
//! * **Planes only** ([`estimate_motion`], the identity as prior when no guess is given): the
//!   proposal with the largest support wins. Plane normals alone are often ambiguous — two
//!   monitors at the same angle to a desk, a desk split into near-parallel bands that inflate
//!   the support of a wrong proposal (TUM fr1/rpy: 37° wrong at 20° of motion) — so the result
//!   is marked [`MotionConfidence::Ambiguous`] when a proposal more than `distinct_deg` away
//!   has `ambiguity_ratio` of the winner's support, and [`MotionConfidence::Unverified`]
//!   otherwise: nothing in the planes alone proves it right.
//! * **Verified** ([`estimate_motion_verified`], recommended when the depth maps are at hand,
//!   no prior needed): every proposal is checked against the data. A grid of points of each
//!   frame is moved into the other and projected into its depth map (projective association);
//!   a point on the other surface agrees, a point in front of or behind it contradicts, a
//!   point out of view counts neither way (see [`VerifyConfig`]). The proposals are ranked by
//!   agreement minus weighted contradictions; the best are refined by a short point-to-plane
//!   ICP and scored again, and must keep two non-parallel consistent plane matches. The winner
//!   must explain `min_inlier_fraction` of the overlapping points while no alternative more
//!   than `distinct_deg` away may — neither another proposal nor the winner itself turned by
//!   `distinct_deg` about the camera axes or a plane normal (which catches views that share
//!   mostly one plane, where a rotation about its normal is invisible). An alternative is ruled
//!   out only when its share lies significantly below `min_inlier_fraction` given the few
//!   hundred samples it was measured on (the upper end of the 99.9 % Wilson interval below
//!   it), not merely below it. Otherwise the motion
//!   is reported as not determined ([`TrackError::MotionNotVerified`]) rather than guessed.
//!   The returned rotation is the weighted Kabsch over the plane matches consistent with the
//!   verified alignment; [`Verification`] gives the numbers.
//! * **Rotation** from matches by weighted Kabsch (SVD of `Σ w·n_b·n_aᵀ`, weights = the smaller
//!   pixel count of the pair): needs ≥ 2 non-parallel normals.
//! * **Translation** from `n_a·t = d_b − d_a` by weighted least squares; it is reported as
//!   determined only when the matched normals span 3D (≥ 3 independent planes).
//! * **ICP**: point-to-plane with projective data association, the reference the paper used
//!   ([`icp_point_to_plane`]). ICP only minimises residuals and can make a verified estimate
//!   worse: at large motion and small overlap a wide correspondence gate matches points to the
//!   wrong surfaces, which pull the rotation about a dominant plane's normal (TUM fr1/rpy
//!   0 → 15: 34.8° of motion, 27 % overlap, the plane estimate 3.8° off, ICP from it 10° off).
//!   [`refine_motion_icp_verified`] starts from the verified alignment with a tight gate
//!   ([`IcpConfig::refinement`]) and accepts the result only when the same depth-data check
//!   verifies it and it explains no smaller a share of the overlap ([`IcpOutcome`]);
//!   otherwise the plane estimate stands.

use nalgebra::{
    Isometry3, Matrix3, Rotation3, SymmetricEigen, Translation3, UnitQuaternion, Vector3,
};
use sl_core::{Camera, CameraToCamera, DepthImage};

use crate::error::{Result, TrackError};
pub use crate::verify::VerifyConfig;
use crate::verify::{self, Density, Score, Target, TwoWay};
use sl_core::Plane;
use sl_planes::PlaneInfo;

/// Parameters of plane matching and motion estimation.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct MotionConfig {
    /// Largest normal angle of a candidate match after the initial guess, degrees. Applies to
    /// [`estimate_motion`] always (the identity without a guess) and to
    /// [`estimate_motion_verified`] only when a guess is given (without one every pair of
    /// planes is a candidate).
    pub max_angle_deg: f64,
    /// Largest offset difference of a candidate match after the initial guess, metres (applies
    /// like `max_angle_deg`).
    pub max_offset_m: f64,
    /// Normal angle under a rotation hypothesis for a match to count as inlier, degrees.
    pub inlier_angle_deg: f64,
    /// Two normals closer than this are treated as parallel, degrees.
    pub min_spread_deg: f64,
    /// Largest disagreement of a match's offset with the common translation, metres.
    pub inlier_offset_m: f64,
    /// Smallest eigenvalue of the normalised normal scatter `Σw·n·nᵀ / Σw` for the translation
    /// to count as determined.
    pub min_translation_eigen: f64,
    /// Two rotation hypotheses further apart than this are distinct alternatives, degrees.
    /// Real Kinect planes are bent by the sensor's low-frequency distortion (the bands of one
    /// desk disagree by up to ~6°), so proposals from different bands of the same planes
    /// scatter by several degrees; 15° is over twice that.
    pub distinct_deg: f64,
    /// Planes only: a distinct alternative with at least this fraction of the winner's support
    /// makes the result [`MotionConfidence::Ambiguous`]. Support counts pixels and real planes
    /// are often split into several bands that each count, so only a clear margin means
    /// anything.
    pub ambiguity_ratio: f64,
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            max_angle_deg: 45.0,
            max_offset_m: 0.5,
            inlier_angle_deg: 4.0,
            min_spread_deg: 15.0,
            inlier_offset_m: 0.08,
            min_translation_eigen: 0.02,
            distinct_deg: 15.0,
            ambiguity_ratio: 0.7,
        }
    }
}

impl MotionConfig {
    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let angles = [
            ("max_angle_deg", self.max_angle_deg),
            ("inlier_angle_deg", self.inlier_angle_deg),
            ("min_spread_deg", self.min_spread_deg),
            ("distinct_deg", self.distinct_deg),
        ];
        for (name, v) in angles {
            if !(v > 0.0 && v <= 180.0) {
                return Err(TrackError::InvalidConfig(format!(
                    "{name} must lie in (0, 180], got {}",
                    sl_core::Compact(v)
                )));
            }
        }
        for (name, v) in [
            ("max_offset_m", self.max_offset_m),
            ("inlier_offset_m", self.inlier_offset_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(TrackError::InvalidConfig(format!(
                    "{name} must be positive, got {}",
                    sl_core::Compact(v)
                )));
            }
        }
        if !(0.0..=1.0).contains(&self.ambiguity_ratio)
            || !(0.0..1.0).contains(&self.min_translation_eigen)
        {
            return Err(TrackError::InvalidConfig(
                "ambiguity_ratio must lie in [0, 1] and min_translation_eigen in [0, 1)".into(),
            ));
        }
        Ok(())
    }
}

/// A matched pair of planes: index into frame A's and frame B's plane lists.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneMatch {
    /// Index in frame A's planes.
    pub a: usize,
    /// Index in frame B's planes.
    pub b: usize,
    /// Weight (smaller pixel count of the two).
    pub weight: f64,
}

/// How far a [`PlaneMotion`] can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionConfidence {
    /// Checked against both depth maps ([`estimate_motion_verified`]): the alignment explains
    /// most overlapping points and no distinct alternative comes close (see
    /// [`PlaneMotion::verification`]).
    Verified,
    /// From planes only; no distinct rotation hypothesis has comparable plane support.
    Unverified,
    /// From planes only, and a distinct rotation hypothesis (more than
    /// [`MotionConfig::distinct_deg`] away) has nearly the same plane support
    /// ([`PlaneMotion::runner_up_support`]): the rotation may be wrong by a large angle.
    Ambiguous,
}

impl MotionConfidence {
    /// Lower-case name (`verified`, `unverified`, `ambiguous`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Verified => "verified",
            Self::Unverified => "unverified",
            Self::Ambiguous => "ambiguous",
        }
    }
}

/// The result of checking a motion against the depth maps.
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// Fraction of the overlapping points that lie on the other frame's surface after the
    /// winning hypothesis' local refinement (B's points in A and A's points in B together).
    pub inlier_fraction: f64,
    /// Fraction of the points that land on a valid pixel of the other frame.
    pub overlap_fraction: f64,
    /// The largest inlier fraction of a distinct alternative (another plane hypothesis more
    /// than `distinct_deg` away, refined on the data); 0 when there is none. Below
    /// `min_inlier_fraction` for a verified motion.
    pub alternative_inlier_fraction: f64,
    /// The largest inlier fraction of the winning alignment turned by `distinct_deg` about one
    /// of several axes (camera axes and plane normals, through the inliers' centroid): close
    /// to the winner's when the shared view cannot pin the rotation down. Below
    /// `min_inlier_fraction` for a verified motion.
    pub turned_inlier_fraction: f64,
    /// Distinct plane hypotheses scored on the data.
    pub hypotheses: usize,
    /// Points used per frame (the fewer of the two).
    pub samples: usize,
    /// The winning hypothesis after the short data refinement (a coarse ICP result, not the
    /// plane estimate), `X_a = T·X_b`.
    pub aligned: CameraToCamera,
}

/// The motion of frame B relative to frame A estimated from planes.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneMotion {
    /// Rotation `R` of `X_a = R·X_b + t`.
    pub rotation: UnitQuaternion<f64>,
    /// The translation, when the matched normals span 3D.
    pub translation_m: Option<Vector3<f64>>,
    /// The least-squares translation restricted to the directions the normals determine
    /// (minimum norm; equal to `translation_m` when that is determined).
    pub translation_partial_m: Vector3<f64>,
    /// The matched planes.
    pub matches: Vec<PlaneMatch>,
    /// Weighted RMS angle between matched normals after the rotation, degrees.
    pub rms_angle_deg: f64,
    /// How far the result can be trusted.
    pub confidence: MotionConfidence,
    /// Plane support of the best distinct alternative hypothesis relative to the winner's
    /// (0 when there is none).
    pub runner_up_support: f64,
    /// The check against the depth maps ([`estimate_motion_verified`] only).
    pub verification: Option<Verification>,
}

impl PlaneMotion {
    /// The motion mapping camera B to camera A, `X_a = T·X_b` (`translation_partial_m` when
    /// the translation is not fully determined).
    pub fn motion(&self) -> CameraToCamera {
        CameraToCamera::from_isometry(Isometry3::from_parts(
            Translation3::from(self.translation_m.unwrap_or(self.translation_partial_m)),
            self.rotation,
        ))
    }

    /// The motion as an untyped isometry.
    #[deprecated(
        since = "0.1.0",
        note = "use `motion()`, which says its direction (camera B to camera A) in its type"
    )]
    pub fn isometry(&self) -> Isometry3<f64> {
        self.motion().into_isometry()
    }
}

mod hypotheses;
mod icp;
mod kabsch;
#[cfg(test)]
mod tests;
mod verified;

pub use hypotheses::estimate_motion;
use hypotheses::*;
pub use icp::{
    ICP_INLIER_TOLERANCE, ICP_LOSS_Z, IcpConfig, IcpOutcome, IcpRejection, IcpResult,
    icp_point_to_plane, refine_motion_icp_verified, significant_loss,
};
pub use kabsch::weighted_kabsch;
use kabsch::*;
pub(crate) use verified::estimate_motion_verified_or_candidates;
use verified::*;
pub use verified::{MotionFrame, estimate_motion_verified};
