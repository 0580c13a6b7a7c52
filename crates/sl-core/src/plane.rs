//! Planes in Hesse normal form and the least-squares (PCA) plane fit.
//!
//! One convention for the whole workspace: a [`Plane`] is `normal·X + offset_m = 0` with a unit
//! `normal` and `offset_m` in metres, in whatever frame the caller's points live. Constructors
//! normalise but do not orient; [`Plane::facing_origin`] flips the plane so that `offset_m ≥ 0`,
//! i.e. the normal points towards the frame's origin (the camera centre for camera-frame planes),
//! which is the form plane extraction reports.
//!
//! [`fit_plane`] is the one plane fit: centroid plus the eigenvector of the smallest eigenvalue
//! of the scatter matrix. Its arithmetic is exactly that of the metric-RANSAC refit in
//! `sl-planes`, so `fit_plane(points)?.plane.facing_origin()` reproduces that fit bit for bit.

use nalgebra::{Isometry3, Matrix3, Point3, SymmetricEigen, Vector3};

use crate::error::{CoreError, Result};
use crate::intrinsics::Intrinsics;

/// A plane `normal·X + offset_m = 0` (unit normal, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: Vector3<f64>,
    /// Offset of the Hesse form, metres: `−offset_m` is the signed distance of the plane from
    /// the origin along `normal`.
    pub offset_m: f64,
}

impl Plane {
    /// The plane `normal·X + offset_m = 0` for any non-zero `normal`; both are divided by
    /// `|normal|` (no orientation is imposed). An error for a zero or non-finite normal or a
    /// non-finite offset.
    pub fn new(normal: Vector3<f64>, offset_m: f64) -> Result<Self> {
        let len = normal.norm();
        if !(len.is_finite() && len > 1e-12 && offset_m.is_finite()) {
            return Err(CoreError::DegeneratePlane(format!(
                "normal ({}, {}, {}) / offset {} cannot describe a plane",
                crate::Compact(normal.x),
                crate::Compact(normal.y),
                crate::Compact(normal.z),
                crate::Compact(offset_m)
            )));
        }
        Ok(Self {
            normal: normal / len,
            offset_m: offset_m / len,
        })
    }

    /// The plane through `point` with the given (non-zero) normal.
    pub fn through_point(normal: Vector3<f64>, point: &Point3<f64>) -> Result<Self> {
        if !point.iter().all(|c| c.is_finite()) {
            return Err(CoreError::DegeneratePlane(format!(
                "point {point:?} is not finite"
            )));
        }
        Self::new(normal, -normal.dot(&point.coords))
    }

    /// The same plane with the normal pointing towards the origin (`offset_m ≥ 0`): flipped
    /// when `offset_m < 0`, unchanged otherwise. Flipping is an exact negation.
    #[must_use]
    pub fn facing_origin(self) -> Self {
        if self.offset_m < 0.0 {
            self.flipped()
        } else {
            self
        }
    }

    /// The same plane with the opposite orientation (`−normal`, `−offset_m`).
    #[must_use]
    pub fn flipped(self) -> Self {
        Self {
            normal: -self.normal,
            offset_m: -self.offset_m,
        }
    }

    /// Signed distance of `p` from the plane, metres: positive on the side `normal` points to.
    pub fn signed_distance_m(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&p.coords) + self.offset_m
    }

    /// The foot of the perpendicular from `p` onto the plane.
    pub fn project(&self, p: &Point3<f64>) -> Point3<f64> {
        p - self.normal * self.signed_distance_m(p)
    }

    /// The plane expressed in another frame: if `t_ab` maps frame-b points to frame a
    /// (`X_a = t_ab·X_b`) and `self` is given in frame b, the result is the same plane in frame
    /// a. The orientation follows the normal (no re-orientation).
    #[must_use]
    pub fn transformed(&self, t_ab: &Isometry3<f64>) -> Self {
        let normal = t_ab.rotation * self.normal;
        Self {
            normal,
            offset_m: self.offset_m - normal.dot(&t_ab.translation.vector),
        }
    }

    /// Angle between the two normals in degrees, in `[0, 180]` (orientation-sensitive: a plane
    /// and its flip are 180° apart).
    pub fn angle_to_deg(&self, other: &Self) -> f64 {
        self.normal
            .dot(&other.normal)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// Ray parameter `t` of the intersection with the ray `origin + t·dir` (`dir` any non-zero
    /// vector), or `None` when the ray is parallel to the plane (or the result is not finite).
    /// `t` may be negative (intersection behind the origin); callers filter.
    pub fn intersect_ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        let denom = self.normal.dot(dir);
        if denom == 0.0 {
            return None;
        }
        let t = -self.signed_distance_m(origin) / denom;
        t.is_finite().then_some(t)
    }

    /// The plane of the paper's form `aX + bY + cZ + 1 = 0` from `(a, b, c)`: normal
    /// `(a, b, c)/|(a, b, c)|`, offset `1/|(a, b, c)|`, so it faces the origin. An error for a
    /// zero or non-finite triple (a plane at infinity).
    pub fn from_paper_coefficients(abc: Vector3<f64>) -> Result<Self> {
        let len = abc.norm();
        if !(len.is_finite() && len > 1e-12) {
            return Err(CoreError::DegeneratePlane(format!(
                "paper coefficients {abc:?}"
            )));
        }
        Ok(Self {
            normal: abc / len,
            offset_m: 1.0 / len,
        })
    }

    /// The paper's coefficients `(a, b, c) = normal / offset_m` of `aX + bY + cZ + 1 = 0`
    /// (the same for both orientations); an error for a plane through the origin.
    pub fn paper_coefficients(&self) -> Result<Vector3<f64>> {
        let off_centre = self.offset_m.abs() > 1e-12;
        if !off_centre {
            return Err(CoreError::DegeneratePlane(
                "a plane through the camera centre has no aX+bY+cZ+1=0 form".into(),
            ));
        }
        Ok(self.normal / self.offset_m)
    }

    /// Depth (Z, metres) of a camera-frame plane along the ray of pixel `(x, y)` of a camera with
    /// intrinsics `k`; `None` when the ray does not hit the plane in front of the camera.
    /// Expects the camera-facing orientation ([`Plane::facing_origin`]).
    pub fn depth_at(&self, k: &Intrinsics, x: f64, y: f64) -> Option<f64> {
        let ray = k.ray(x, y);
        let denom = self.normal.dot(&ray);
        if denom >= -1e-12 {
            return None;
        }
        Some(-self.offset_m / denom)
    }
}

/// The result of [`fit_plane`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneFit {
    /// The least-squares plane (orientation: whatever sign the eigenvector solver returned; use
    /// [`Plane::facing_origin`] for camera-facing planes).
    pub plane: Plane,
    /// Mean of the points.
    pub centroid: Point3<f64>,
    /// Root-mean-square point-to-plane distance, metres.
    pub rms_residual_m: f64,
    /// Number of points fitted.
    pub point_count: usize,
}

/// Least-squares plane through `points`: the centroid and the eigenvector of the smallest
/// eigenvalue of the scatter matrix `Σ (p − c)(p − c)ᵀ`. `None` for fewer than three points or
/// a degenerate (non-finite) fit.
///
/// The arithmetic (summation order, the offset `−n·c` before normalisation) is exactly that of
/// `sl-planes`' metric-RANSAC refit, so `fit.plane.facing_origin()` equals it bit for bit.
pub fn fit_plane(points: &[Point3<f64>]) -> Option<PlaneFit> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let c = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut scatter = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        scatter += d * d.transpose();
    }
    let eig = SymmetricEigen::new(scatter);
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let normal = eig.eigenvectors.column(imin).into_owned();
    let plane = Plane::new(normal, -normal.dot(&c)).ok()?;
    let sum_sq = points
        .iter()
        .map(|p| plane.signed_distance_m(p).powi(2))
        .sum::<f64>();
    let rms_residual_m = (sum_sq / n).sqrt();
    rms_residual_m.is_finite().then_some(PlaneFit {
        plane,
        centroid: Point3::from(c),
        rms_residual_m,
        point_count: points.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn approx(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn new_normalises_and_rejects_degenerate() {
        let p = Plane::new(Vector3::new(0.0, 0.0, 2.0), -4.0).unwrap();
        assert_eq!(p.normal, Vector3::new(0.0, 0.0, 1.0));
        assert_eq!(p.offset_m, -2.0);
        assert!(Plane::new(Vector3::zeros(), 1.0).is_err());
        assert!(Plane::new(Vector3::z(), f64::NAN).is_err());
        assert!(Plane::through_point(Vector3::z(), &Point3::new(f64::INFINITY, 0.0, 0.0)).is_err());
    }

    #[test]
    fn facing_origin_points_to_camera() {
        // The wall Z = 2 seen by a camera at the origin.
        let p = Plane::through_point(Vector3::z(), &Point3::new(0.0, 0.0, 2.0))
            .unwrap()
            .facing_origin();
        assert_eq!(p.normal, -Vector3::z());
        assert_eq!(p.offset_m, 2.0);
        assert!(p.signed_distance_m(&Point3::origin()) > 0.0);
        assert_eq!(p.facing_origin(), p);
        assert_eq!(p.flipped().flipped(), p);
    }

    #[test]
    fn ray_intersection() {
        let p = Plane::new(Vector3::z(), -2.0).unwrap();
        let t = p
            .intersect_ray(&Point3::origin(), &Vector3::new(0.1, 0.0, 1.0))
            .unwrap();
        assert!(approx(t, 2.0, 1e-15));
        assert!(p.intersect_ray(&Point3::origin(), &Vector3::x()).is_none());
    }

    #[test]
    fn fit_rejects_too_few_or_degenerate() {
        assert!(fit_plane(&[Point3::origin(), Point3::new(1.0, 0.0, 0.0)]).is_none());
        let nan = Point3::new(f64::NAN, 0.0, 0.0);
        assert!(fit_plane(&[nan, nan, nan]).is_none());
    }

    /// Deterministic pseudo-random numbers in [-1, 1) for the noisy-plane test.
    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    #[test]
    fn fit_noisy_plane() {
        let truth = Plane::new(Vector3::new(0.2, -0.3, -1.0), 2.5).unwrap();
        let (u, v) = {
            let u = truth.normal.cross(&Vector3::x()).normalize();
            (u, truth.normal.cross(&u))
        };
        let origin = Point3::from(-truth.normal * truth.offset_m);
        let mut s = 7u64;
        let sigma = 0.003;
        let points: Vec<_> = (0..5000)
            .map(|_| {
                origin
                    + u * lcg(&mut s)
                    + v * lcg(&mut s)
                    + truth.normal * (sigma * 3f64.sqrt() * lcg(&mut s))
            })
            .collect();
        let fit = fit_plane(&points).unwrap();
        let plane = fit.plane.facing_origin();
        assert!(plane.angle_to_deg(&truth) < 0.2, "{plane:?}");
        assert!(approx(plane.offset_m, truth.offset_m, 1e-3));
        assert!(
            approx(fit.rms_residual_m, sigma, 3e-4),
            "{}",
            fit.rms_residual_m
        );
        assert_eq!(fit.point_count, 5000);
    }

    proptest! {
        #[test]
        fn transform_round_trip(
            nx in -1.0..1.0f64, ny in -1.0..1.0f64, nz in 0.1..1.0f64, d in -5.0..5.0f64,
            tx in -2.0..2.0f64, ty in -2.0..2.0f64, tz in -2.0..2.0f64,
            rx in -3.0..3.0f64, ry in -3.0..3.0f64, rz in -3.0..3.0f64,
            px in -3.0..3.0f64, py in -3.0..3.0f64,
        ) {
            let plane = Plane::new(Vector3::new(nx, ny, nz), d).unwrap();
            let iso = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(rx, ry, rz));
            let moved = plane.transformed(&iso);
            prop_assert!(approx(moved.normal.norm(), 1.0, 1e-12));
            // A point on the plane stays on the moved plane.
            let on = plane.project(&Point3::new(px, py, 1.0));
            prop_assert!(approx(plane.signed_distance_m(&on), 0.0, 1e-9));
            prop_assert!(approx(moved.signed_distance_m(&(iso * on)), 0.0, 1e-9));
            let back = moved.transformed(&iso.inverse());
            prop_assert!((back.normal - plane.normal).norm() < 1e-12);
            prop_assert!(approx(back.offset_m, plane.offset_m, 1e-9));
            // Orientation: facing_origin never leaves a negative offset.
            prop_assert!(moved.facing_origin().offset_m >= 0.0);
        }

        #[test]
        fn fit_exact_plane(
            nx in -1.0..1.0f64, ny in -1.0..1.0f64, nz in 0.2..1.0f64, d in 0.5..5.0f64,
            seed in 0u64..1000,
        ) {
            let truth = Plane::new(Vector3::new(nx, ny, nz), d).unwrap();
            let mut s = seed;
            let points: Vec<_> = (0..50)
                .map(|_| truth.project(&Point3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s))))
                .collect();
            let fit = fit_plane(&points).unwrap();
            let got = fit.plane.facing_origin();
            let want = truth.facing_origin();
            prop_assert!(got.angle_to_deg(&want) < 1e-5, "{got:?} vs {want:?}");
            prop_assert!(approx(got.offset_m, want.offset_m, 1e-8));
            prop_assert!(fit.rms_residual_m < 1e-9);
        }
    }
}
