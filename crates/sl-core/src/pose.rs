//! Rigid camera poses (nalgebra `Isometry3<f64>`), and their construction from the 4×4 matrices
//! and quaternions used by datasets.
//!
//! Convention: a pose maps camera coordinates to world coordinates, `X_w = R·X_c + t`
//! (TUM `groundtruth.txt`, 7-Scenes `frame-*.pose.txt` and Open3D `.log` all store this).

use nalgebra::{Isometry3, Matrix3, Matrix4, Quaternion, Rotation3, Translation3, UnitQuaternion};

use crate::error::{CoreError, Result};

/// A camera-to-world rigid transform.
pub type Pose = Isometry3<f64>;

/// How far from orthonormal (max |RᵀR − I| entry) a dataset's rotation may be before it is
/// rejected. Datasets print poses with 6–8 significant digits; 1e-3 accepts those and rejects
/// scaled or sheared matrices.
pub const RIGID_TOLERANCE: f64 = 1e-3;

/// Builds a pose from a row-major 4×4 matrix `[R t; 0 0 0 1]`, re-orthonormalising `R`.
pub fn pose_from_matrix(m: &Matrix4<f64>) -> Result<Pose> {
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
pub fn pose_from_row_major(v: &[f64; 16]) -> Result<Pose> {
    pose_from_matrix(&Matrix4::from_row_slice(v))
}

/// The 4×4 homogeneous matrix of a pose.
pub fn pose_to_matrix(p: &Pose) -> Matrix4<f64> {
    p.to_homogeneous()
}

/// Builds a pose from a translation and a quaternion `(qx, qy, qz, qw)` (TUM order). The
/// quaternion is normalised; a (near-)zero quaternion is an error.
pub fn pose_from_translation_quaternion(t: [f64; 3], q: [f64; 4]) -> Result<Pose> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

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
    }
}
