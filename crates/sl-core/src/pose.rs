//! Rigid camera poses (nalgebra `Isometry3<f64>`), and their construction from the 4×4 matrices
//! and quaternions used by datasets.
//!
//! The typed poses say their direction in their name: [`CameraToWorld`] (`X_w = T·X_c`, what
//! TUM `groundtruth.txt`, 7-Scenes `frame-*.pose.txt` and Open3D `.log` store),
//! [`WorldToCamera`] (`X_c = T·X_w`, its inverse), [`CameraToCamera`] (frame-to-frame motion,
//! `X_a = T·X_b`) and [`WorldToWorld`] (between the world frames of two reconstructions, for
//! instance two fragments of one recording, `X_a = T·X_b`). `inverse()` returns the opposite type
//! and `*` only composes poses whose frames meet, so a direction mistake is a type error.
//!
//! The free functions ([`pose_from_matrix`], [`pose_from_translation_quaternion`], …) build the
//! plain `Isometry3<f64>` the typed constructors wrap. The older untyped `Pose` alias is
//! deprecated: every public pose of the workspace is one of the four types.

use std::ops::Mul;

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point3, Quaternion, Rotation3, Translation3, UnitQuaternion,
    Vector3,
};

use crate::error::{CoreError, Result};

/// A camera-to-world rigid transform, untyped.
#[deprecated(
    since = "0.1.0",
    note = "say the direction in the type: `CameraToWorld` (camera poses), `WorldToCamera` \
            (extrinsics) or `CameraToCamera` (frame-to-frame motion); `Isometry3<f64>` for a \
            plain rigid transform"
)]
pub type Pose = Isometry3<f64>;

/// How far from orthonormal (max |RᵀR − I| entry) a dataset's rotation may be before it is
/// rejected. Datasets print poses with 6–8 significant digits; 1e-3 accepts those and rejects
/// scaled or sheared matrices.
pub const RIGID_TOLERANCE: f64 = 1e-3;

/// Builds a pose from a row-major 4×4 matrix `[R t; 0 0 0 1]`, re-orthonormalising `R`.
pub fn pose_from_matrix(m: &Matrix4<f64>) -> Result<Isometry3<f64>> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(CoreError::NotRigid("matrix has non-finite entries".into()));
    }
    let bottom = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
    if bottom
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(a, b)| (a - b).abs() > RIGID_TOLERANCE)
    {
        return Err(CoreError::NotRigid(format!(
            "last row is {bottom:?}, expected [0, 0, 0, 1]"
        )));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > RIGID_TOLERANCE {
        return Err(CoreError::NotRigid(format!(
            "rotation block is not orthonormal (|RᵀR − I| = {err:.2e})"
        )));
    }
    if r.determinant() < 0.0 {
        return Err(CoreError::NotRigid(
            "rotation block is a reflection (det < 0)".into(),
        ));
    }
    // Nearest rotation (polar decomposition): R = U·Vᵀ from the SVD of the stored block.
    let svd = r.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(CoreError::NotRigid("rotation block has no SVD".into()));
    };
    let rot = Rotation3::from_matrix_unchecked(u * v_t);
    let t = Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok(Isometry3::from_parts(
        t,
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

/// Builds a pose from a row-major array of 16 numbers.
pub fn pose_from_row_major(v: &[f64; 16]) -> Result<Isometry3<f64>> {
    pose_from_matrix(&Matrix4::from_row_slice(v))
}

/// The 4×4 homogeneous matrix of a pose.
pub fn pose_to_matrix(p: &Isometry3<f64>) -> Matrix4<f64> {
    p.to_homogeneous()
}

/// Builds a pose from a translation and a quaternion `(qx, qy, qz, qw)` (TUM order). The
/// quaternion is normalised; a (near-)zero quaternion is an error.
pub fn pose_from_translation_quaternion(t: [f64; 3], q: [f64; 4]) -> Result<Isometry3<f64>> {
    let quat = Quaternion::new(q[3], q[0], q[1], q[2]);
    let n = quat.norm();
    if !(n.is_finite() && n > 1e-9) || t.iter().any(|v| !v.is_finite()) {
        return Err(CoreError::NotRigid(format!(
            "invalid translation {t:?} / quaternion {q:?}"
        )));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_quaternion(quat),
    ))
}

/// Rotation angle of `R_a⁻¹·R_b` in degrees: the geodesic distance between two rotations.
pub fn rotation_angle_deg(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b).to_degrees()
}

/// `F·T·F` with `F = diag(1, −1, 1)`: see `CameraToWorld::y_reflected`.
fn reflect_y(t: &Isometry3<f64>) -> Isometry3<f64> {
    let v = t.translation.vector;
    let q = t.rotation.quaternion();
    Isometry3::from_parts(
        Translation3::new(v.x, -v.y, v.z),
        UnitQuaternion::new_unchecked(Quaternion::new(q.w, -q.i, q.j, -q.k)),
    )
}

/// Defines a pose newtype over `Isometry3<f64>` with the shared constructors and accessors.
macro_rules! typed_pose {
    ($(#[$doc:meta])* $name:ident, $from:literal, $to:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name(Isometry3<f64>);

        impl $name {
            #[doc = concat!("The identity: the ", $from, " and ", $to, " frames coincide.")]
            pub fn identity() -> Self {
                Self(Isometry3::identity())
            }

            #[doc = concat!("Wraps an isometry that maps ", $from, " coordinates to ", $to, " coordinates.")]
            pub fn from_isometry(iso: Isometry3<f64>) -> Self {
                Self(iso)
            }

            /// Validated construction from a 4×4 matrix `[R t; 0 0 0 1]` (see [`pose_from_matrix`]).
            pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self> {
                pose_from_matrix(m).map(Self)
            }

            /// Validated construction from 16 row-major numbers (see [`pose_from_row_major`]).
            pub fn from_row_major(v: &[f64; 16]) -> Result<Self> {
                pose_from_row_major(v).map(Self)
            }

            /// Construction from a translation and a `(qx, qy, qz, qw)` quaternion (TUM order; see
            /// [`pose_from_translation_quaternion`]).
            pub fn from_translation_quaternion(t: [f64; 3], q: [f64; 4]) -> Result<Self> {
                pose_from_translation_quaternion(t, q).map(Self)
            }

            /// The 4×4 homogeneous matrix.
            pub fn to_matrix(&self) -> Matrix4<f64> {
                self.0.to_homogeneous()
            }

            /// The underlying isometry.
            pub fn isometry(&self) -> &Isometry3<f64> {
                &self.0
            }

            /// The underlying isometry, by value.
            pub fn into_isometry(self) -> Isometry3<f64> {
                self.0
            }

            /// The rotation part.
            pub fn rotation(&self) -> UnitQuaternion<f64> {
                self.0.rotation
            }

            /// The translation part, metres.
            pub fn translation(&self) -> Vector3<f64> {
                self.0.translation.vector
            }

            #[doc = concat!("Maps a point from ", $from, " to ", $to, " coordinates.")]
            pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
                self.0.transform_point(p)
            }

            #[doc = concat!("Maps a direction from ", $from, " to ", $to, " coordinates (rotation only).")]
            pub fn transform_vector(&self, v: &Vector3<f64>) -> Vector3<f64> {
                self.0.transform_vector(v)
            }

            /// The same transform seen in mirrored frames, `F·T·F` with `F = diag(1, −1, 1)`
            /// on both sides: translation `(x, −y, z)`, rotation axis `(−x, y, −z)` by the same
            /// angle. It converts between sldepth's right-handed camera frame (x right, y down,
            /// z forward) and a data set that renders with the image y axis up in a
            /// left-handed frame (ICL-NUIM's TUM-format files, published fy = −480), both ways:
            /// applying it twice gives the pose back.
            pub fn y_reflected(&self) -> Self {
                Self(reflect_y(&self.0))
            }
        }

        impl Default for $name {
            fn default() -> Self {
                Self::identity()
            }
        }
    };
}

typed_pose!(
    /// A camera pose that maps camera coordinates to world coordinates, `X_w = T·X_c`: its
    /// translation is the camera centre in the world. This is what trajectory files store.
    CameraToWorld,
    "camera",
    "world"
);

typed_pose!(
    /// The extrinsics of a camera: maps world coordinates to camera coordinates, `X_c = T·X_w`
    /// (the inverse of [`CameraToWorld`]).
    WorldToCamera,
    "world",
    "camera"
);

typed_pose!(
    /// Frame-to-frame camera motion from camera `b` to camera `a`: maps coordinates in camera
    /// `b` to coordinates in camera `a`, `X_a = T·X_b`. With `a` the reference (earlier) frame and
    /// `b` the current one, `pose_b = pose_a * T` ([`CameraToWorld`] composition).
    CameraToCamera,
    "camera-b",
    "camera-a"
);

typed_pose!(
    /// A transform between two world frames: maps coordinates in world `b` to coordinates in
    /// world `a`, `X_a = T·X_b` — for instance from a fragment of a recording to the fragment it
    /// rejoined. `T * pose_in_b` is the same camera's pose in world `a`.
    WorldToWorld,
    "world-b",
    "world-a"
);

impl WorldToWorld {
    /// The transform the other way round, world `a` to world `b`.
    pub fn inverse(&self) -> WorldToWorld {
        WorldToWorld(self.0.inverse())
    }

    /// The transform from world `b` to world `a` given one camera's pose in each:
    /// `T = pose_in_a · pose_in_b⁻¹`, so that `T * pose_in_b == pose_in_a`.
    pub fn between(pose_in_a: &CameraToWorld, pose_in_b: &CameraToWorld) -> Self {
        Self(pose_in_a.0 * pose_in_b.0.inverse())
    }
}

/// `world_ab * pose_in_b` = the camera's pose in world `a`.
impl Mul<CameraToWorld> for WorldToWorld {
    type Output = CameraToWorld;
    fn mul(self, rhs: CameraToWorld) -> CameraToWorld {
        CameraToWorld(self.0 * rhs.0)
    }
}

/// `world_ab * world_bc` = `world_ac`.
impl Mul for WorldToWorld {
    type Output = WorldToWorld;
    fn mul(self, rhs: WorldToWorld) -> WorldToWorld {
        WorldToWorld(self.0 * rhs.0)
    }
}

impl CameraToWorld {
    /// The world-to-camera transform (extrinsics).
    pub fn inverse(&self) -> WorldToCamera {
        WorldToCamera(self.0.inverse())
    }

    /// The camera centre in world coordinates.
    pub fn centre(&self) -> Point3<f64> {
        Point3::from(self.0.translation.vector)
    }
}

impl WorldToCamera {
    /// The camera-to-world pose.
    pub fn inverse(&self) -> CameraToWorld {
        CameraToWorld(self.0.inverse())
    }
}

impl CameraToCamera {
    /// The motion the other way round: maps camera `a` to camera `b`, `X_b = T⁻¹·X_a`.
    pub fn inverse(&self) -> CameraToCamera {
        CameraToCamera(self.0.inverse())
    }

    /// The relative motion between two poses: `T = a⁻¹·b`, mapping camera `b` coordinates to
    /// camera `a` coordinates, so that `a * T == b`.
    pub fn between(a: &CameraToWorld, b: &CameraToWorld) -> Self {
        Self(a.0.inverse() * b.0)
    }

    /// Rotation angle of the motion, degrees.
    pub fn rotation_angle_deg(&self) -> f64 {
        self.0.rotation.angle().to_degrees()
    }

    /// Length of the translation, metres.
    pub fn translation_norm_m(&self) -> f64 {
        self.0.translation.vector.norm()
    }
}

/// `pose_a * motion_ab` = `pose_b`: camera `b`'s pose from camera `a`'s pose and the motion that
/// maps camera `b` to camera `a`.
impl Mul<CameraToCamera> for CameraToWorld {
    type Output = CameraToWorld;
    fn mul(self, rhs: CameraToCamera) -> CameraToWorld {
        CameraToWorld(self.0 * rhs.0)
    }
}

/// `motion_ab * motion_bc` = `motion_ac`.
impl Mul for CameraToCamera {
    type Output = CameraToCamera;
    fn mul(self, rhs: CameraToCamera) -> CameraToCamera {
        CameraToCamera(self.0 * rhs.0)
    }
}

/// `motion_ab * extrinsics_b` = `extrinsics_a`.
impl Mul<WorldToCamera> for CameraToCamera {
    type Output = WorldToCamera;
    fn mul(self, rhs: WorldToCamera) -> WorldToCamera {
        WorldToCamera(self.0 * rhs.0)
    }
}

/// `extrinsics_a * pose_b` = the motion mapping camera `b` to camera `a`.
impl Mul<CameraToWorld> for WorldToCamera {
    type Output = CameraToCamera;
    fn mul(self, rhs: CameraToWorld) -> CameraToCamera {
        CameraToCamera(self.0 * rhs.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A transform between two worlds takes a camera's pose in one to its pose in the other.
    #[test]
    fn world_to_world_moves_poses_between_worlds() {
        let in_a = CameraToWorld::from_isometry(Isometry3::new(
            Vector3::new(1.0, -2.0, 0.5),
            Vector3::new(0.1, 0.2, -0.3),
        ));
        let in_b = CameraToWorld::from_isometry(Isometry3::new(
            Vector3::new(-0.3, 0.7, 2.0),
            Vector3::new(-0.4, 0.0, 0.9),
        ));
        let ab = WorldToWorld::between(&in_a, &in_b);
        let back = ab * in_b;
        assert!((back.to_matrix() - in_a.to_matrix()).abs().max() < 1e-12);
        let again = ab.inverse() * in_a;
        assert!((again.to_matrix() - in_b.to_matrix()).abs().max() < 1e-12);
        let id = ab * ab.inverse();
        assert!((id.to_matrix() - Matrix4::identity()).abs().max() < 1e-12);
    }

    #[test]
    fn matrix_round_trip() {
        let p = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, 0.2, -0.3));
        let q = pose_from_matrix(&pose_to_matrix(&p)).unwrap();
        assert!((p.to_homogeneous() - q.to_homogeneous()).abs().max() < 1e-12);
    }

    #[test]
    fn rejects_non_rigid() {
        let mut m = Matrix4::identity();
        m[(0, 0)] = 2.0;
        assert!(pose_from_matrix(&m).is_err());
        let mut m = Matrix4::identity();
        m[(2, 2)] = -1.0;
        assert!(pose_from_matrix(&m).is_err());
        let mut m = Matrix4::identity();
        m[(3, 0)] = 1.0;
        assert!(pose_from_matrix(&m).is_err());
        assert!(pose_from_translation_quaternion([0.0; 3], [0.0; 4]).is_err());
    }

    #[test]
    fn tum_quaternion() {
        // 90 degrees about z.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let p = pose_from_translation_quaternion([1.0, 2.0, 3.0], [0.0, 0.0, s, s]).unwrap();
        let x = p * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((x - nalgebra::Point3::new(1.0, 3.0, 3.0)).norm() < 1e-12);
        assert!((rotation_angle_deg(&UnitQuaternion::identity(), &p.rotation) - 90.0).abs() < 1e-9);
        let typed =
            CameraToWorld::from_translation_quaternion([1.0, 2.0, 3.0], [0.0, 0.0, s, s]).unwrap();
        assert_eq!(typed.isometry(), &p);
        assert_eq!(typed.centre(), nalgebra::Point3::new(1.0, 2.0, 3.0));
        assert!(CameraToWorld::from_row_major(&[0.0; 16]).is_err());
    }

    fn iso(v: [f64; 6]) -> Isometry3<f64> {
        Isometry3::new(
            Vector3::new(v[0], v[1], v[2]),
            Vector3::new(v[3], v[4], v[5]),
        )
    }

    fn close(a: &Matrix4<f64>, b: &Matrix4<f64>) -> bool {
        (a - b).abs().max() < 1e-9
    }

    proptest::proptest! {
        #[test]
        fn typed_round_trips_and_composition(
            a in proptest::array::uniform6(-2.0..2.0f64),
            b in proptest::array::uniform6(-2.0..2.0f64),
            x in proptest::array::uniform3(-5.0..5.0f64),
        ) {
            let pose_a = CameraToWorld::from_isometry(iso(a));
            let pose_b = CameraToWorld::from_isometry(iso(b));
            let p = nalgebra::Point3::from(x);
            // inverse() flips the type and undoes the mapping.
            let ext = pose_a.inverse();
            proptest::prop_assert!((ext.transform_point(&pose_a.transform_point(&p)) - p).norm() < 1e-9);
            proptest::prop_assert!(close(&ext.inverse().to_matrix(), &pose_a.to_matrix()));
            // Matrix round trip through the validated constructor.
            let back = CameraToWorld::from_matrix(&pose_a.to_matrix()).unwrap();
            proptest::prop_assert!(close(&back.to_matrix(), &pose_a.to_matrix()));
            // Motion b -> a: X_a = T·X_b, and pose_a * T = pose_b.
            let t_ab = CameraToCamera::between(&pose_a, &pose_b);
            proptest::prop_assert!(close(&(pose_a * t_ab).to_matrix(), &pose_b.to_matrix()));
            proptest::prop_assert!(close(&(ext * pose_b).to_matrix(), &t_ab.to_matrix()));
            let x_b = pose_b.inverse().transform_point(&p);
            let x_a = ext.transform_point(&p);
            proptest::prop_assert!((t_ab.transform_point(&x_b) - x_a).norm() < 1e-9);
            proptest::prop_assert!(close(&(t_ab * pose_b.inverse()).to_matrix(), &ext.to_matrix()));
            proptest::prop_assert!(close(&(t_ab * t_ab.inverse()).to_matrix(), &Matrix4::identity()));
        }

        /// The y reflection is `F·T·F` as matrices, an involution, and it maps the mirror
        /// image of a point through the mirrored pose: `F·(T·X) = T'·(F·X)`.
        #[test]
        fn y_reflection_is_the_mirrored_pose(
            a in proptest::array::uniform6(-2.0..2.0f64),
            x in proptest::array::uniform3(-5.0..5.0f64),
        ) {
            let pose = CameraToWorld::from_isometry(iso(a));
            let f = Matrix4::from_diagonal(&nalgebra::Vector4::new(1.0, -1.0, 1.0, 1.0));
            let r = pose.y_reflected();
            proptest::prop_assert!(close(&r.to_matrix(), &(f * pose.to_matrix() * f)));
            proptest::prop_assert!(close(&r.y_reflected().to_matrix(), &pose.to_matrix()));
            let mirror = |p: nalgebra::Point3<f64>| nalgebra::Point3::new(p.x, -p.y, p.z);
            let p = nalgebra::Point3::from(x);
            proptest::prop_assert!((mirror(pose.transform_point(&p)) - r.transform_point(&mirror(p))).norm() < 1e-9);
            // Relative motions keep their size: RPE is the same in either frame.
            let m = CameraToCamera::between(&pose, &CameraToWorld::identity());
            let mr = CameraToCamera::between(&r, &CameraToWorld::identity());
            proptest::prop_assert!((m.rotation_angle_deg() - mr.rotation_angle_deg()).abs() < 1e-9);
        }
    }
}
