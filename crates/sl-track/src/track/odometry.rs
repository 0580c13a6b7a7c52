//! A motion measured beside the depth ([`Tracker::set_odometry`]): the camera's pose in an
//! odometry's own frame (a robot's wheel odometry, a visual-inertial estimate, through the
//! recording's transforms) at each frame. Its motion since the last good frame, applied to
//! that frame's pose, predicts this frame's pose, and is the prior of every alignment of the
//! frame, on position and orientation alike, with the odometry's own uncertainty
//! ([`TrackerConfig::odometry_drift`] and the floors beside it) instead of the
//! constant-velocity model's. A direction the geometry leaves free (a corridor's axis, a single
//! wall) then takes the odometry's value rather than making the frame lost: every direction
//! is pinned, by the depth or by the odometry.

use nalgebra::{Isometry3, Matrix6, SymmetricEigen, UnitQuaternion, Vector6};

use super::solve::{self, Prior};
use super::structure::Weakest;
use super::{Tracker, TrackerConfig};

/// The longest motion between two frames an odometry is taken for, metres: beyond it (a
/// kilometre: no camera tracked frame by frame moves so far between good frames) its poses are
/// not in one frame, or not numbers a prior can hold.
pub const MAX_ODOMETRY_STEP_M: f64 = 1000.0;

/// The odometry's prediction of the frame being tracked and its uncertainty.
#[derive(Debug, Clone, Copy)]
pub(super) struct OdometryPrior {
    /// The predicted camera-to-world pose.
    pub(super) pose: Isometry3<f64>,
    /// Position variance per axis, m².
    pub(super) var_t_m2: f64,
    /// Orientation variance per axis, rad².
    pub(super) var_r_rad2: f64,
}

impl OdometryPrior {
    /// The prediction from the last good pose `last`, taken where the odometry put the camera
    /// at `then`, to the frame the odometry puts at `now` (camera-to-odometry poses), `n`
    /// frame intervals later: `last` moved by the odometry's motion between the two, with σ
    /// growing with the distance and the angle the odometry measured, and its floor with the
    /// time (a random walk: `√n` floors over `n` intervals, across dropped or lost frames).
    /// `None` for a motion that is not finite or longer than [`MAX_ODOMETRY_STEP_M`] (no
    /// odometry for this frame, rather than a prior that would make the alignment's numbers
    /// overflow).
    pub(super) fn new(
        last: &Isometry3<f64>,
        then: &Isometry3<f64>,
        now: &Isometry3<f64>,
        n: u32,
        cfg: &TrackerConfig,
    ) -> Option<Self> {
        let motion = solve::renormalized(then.inverse() * now);
        let step_m = motion.translation.vector.norm();
        let within = step_m <= MAX_ODOMETRY_STEP_M;
        if !within || !motion.rotation.coords.iter().all(|v| v.is_finite()) {
            return None;
        }
        let walk = f64::from(n.max(1)).sqrt();
        let sigma_t =
            cfg.odometry_min_sigma_m * walk + cfg.odometry_drift * motion.translation.vector.norm();
        let sigma_r = cfg.odometry_min_sigma_deg.to_radians() * walk
            + cfg.odometry_rotation_drift * motion.rotation.angle();
        Some(Self {
            pose: solve::renormalized(last * motion),
            var_t_m2: sigma_t * sigma_t,
            var_r_rad2: sigma_r * sigma_r,
        })
    }

    /// The σ of the predicted position, metres.
    pub(super) fn sigma_t_m(&self) -> f64 {
        self.var_t_m2.sqrt()
    }

    /// The prior of an alignment at a level whose data count `data_share`, the data seen
    /// through `data_projection` ([`weak_projection`]).
    pub(super) fn prior(&self, data_share: f64, data_projection: Option<Matrix6<f64>>) -> Prior {
        Prior {
            data_share,
            info_t: 1.0 / self.var_t_m2,
            centre_t: self.pose.translation.vector,
            info_r: 1.0 / self.var_r_rad2,
            centre_r: UnitQuaternion::from(self.pose.rotation),
            data_projection,
        }
    }
}

/// A direction is left to the odometry where the view's information there is less than
/// `1/ODOMETRY_WEAK_SHARE` of the odometry's: the data's weight in the joint estimate would be under a
/// tenth (σ more than √10 ≈ 3.2 times the odometry's), so dropping them loses little, while
/// the alignment's own information there, from pixels' normals, holds the camera-fixed
/// terraces the view's count leaves out. Where the view says more, the depth and the odometry
/// are estimated together.
pub const ODOMETRY_WEAK_SHARE: f64 = 10.0;

/// The projection that leaves the alignment's data nothing to say along the directions the
/// view pins worse than the odometry: the eigenvectors of the view's information (`weakest`,
/// from its planes' normals and the sensor model, rotations as displacements at its depth)
/// whose σ exceeds the odometry's position σ by more than √[`ODOMETRY_WEAK_SHARE`]. `None` when there is none.
///
/// Why not let the data speak there, weakly: a view that leaves a direction free still gives
/// the point-to-plane alignment false information along it. A wall's correlated noise and
/// its disparity terraces are fixed to the camera, so a camera sliding along the wall sees
/// the same pattern frame after frame, and the alignment reads it as no motion: in the test
/// `a_wall_the_depth_cannot_pin_along_is_tracked_with_odometry` it pulled each frame 0.3–1.5
/// mm back towards the last one. The structure check counts the view's information from its
/// planes, which hold none of that.
pub(super) fn weak_projection(weakest: &Weakest, var_t_m2: f64) -> Option<Matrix6<f64>> {
    let eigen = SymmetricEigen::new(weakest.info);
    let mut p = Matrix6::identity();
    let mut any = false;
    for (i, &lambda) in eigen.eigenvalues.iter().enumerate() {
        // σ along the direction = 1/√λ: left to the odometry when the data hold less than a
        // tenth of its information there, λ·σ² < 1/ODOMETRY_WEAK_SHARE (NaN too).
        let pinned = lambda * var_t_m2 * ODOMETRY_WEAK_SHARE >= 1.0;
        if !pinned {
            let v = eigen.eigenvectors.column(i);
            p -= v * v.transpose();
            any = true;
        }
    }
    if !any {
        return None;
    }
    // From the scaled coordinates (rotations times `scale`) back to the pose's.
    let s = weakest.scale_m.max(1e-6);
    let to_scaled = Matrix6::from_diagonal(&Vector6::new(s, s, s, 1.0, 1.0, 1.0));
    let from_scaled =
        Matrix6::from_diagonal(&Vector6::new(1.0 / s, 1.0 / s, 1.0 / s, 1.0, 1.0, 1.0));
    Some(from_scaled * p * to_scaled)
}

impl Tracker {
    /// Gives the camera's pose in an odometry's frame (camera-to-odometry) at the next frame
    /// tracked: a robot's wheel odometry or another tracker's estimate, for instance through a
    /// recording's transforms. Call before each [`Tracker::track`] (it holds for that frame
    /// only; `None` or no call: the frame has none).
    ///
    /// The odometry's motion since the last good frame predicts the frame's pose and is the
    /// prior of its alignments on position and orientation, with σ =
    /// [`TrackerConfig::odometry_min_sigma_m`] × √(frame intervals since that frame) +
    /// [`TrackerConfig::odometry_drift`] × the distance it measured (and the same for the
    /// angle). The frame's geometry decides where it
    /// pins the pose better; where it does not (a corridor's axis, a single wall) the pose is
    /// the odometry's, and the frame is not lost as a degenerate view. Across lost frames the
    /// prediction is the odometry's too. A frame tracked without odometry leaves the next one
    /// without this prior (constant velocity, as without odometry).
    pub fn set_odometry(&mut self, camera_in_odometry: Option<Isometry3<f64>>) {
        self.next_odometry = camera_in_odometry.filter(|p| {
            p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite())
        });
    }
}
