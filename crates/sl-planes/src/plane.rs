//! 3D planes and their image in the disparity domain (paper eq. 14).
//!
//! A plane in camera coordinates is sl-core's [`Plane`] in Hesse normal form `n·X + d = 0`; plane
//! extraction reports it facing the camera (unit normal `n` pointing towards the camera, `d > 0`
//! its distance from the camera centre, metres; [`Plane::facing_origin`]). The paper writes the
//! same plane as `aX + bY + cZ + 1 = 0`, i.e. `(a, b, c) = n / d`
//! ([`Plane::paper_coefficients`]).
//!
//! With `x = fx·X/Z + cx`, `y = fy·Y/Z + cy` and the disparity `D = f·B / Z` (`fb` = `f·B` of
//! the sensor, pixel·metres), dividing the plane equation by `Z` gives
//! `a·(x − cx)/fx + b·(y − cy)/fy + c + D/fb = 0`, so the disparity is affine in the pixel
//! coordinates: `D(x, y) = α·x + β·y + γ` with
//!
//! ```text
//! α = −fb·a/fx,   β = −fb·b/fy,   γ = −fb·(c − a·cx/fx − b·cy/fy)
//! ```
//!
//! and back `a = −α·fx/fb`, `b = −β·fy/fb`, `c = −(γ + α·cx + β·cy)/fb`. For `fx = fy = f` and
//! `fb = f·B` this is the paper's `a·x + b·y + D/B + (c·f − a·u − b·v) = 0`.

use nalgebra::Vector3;
use sl_core::{Intrinsics, Plane};

use crate::error::{PlanesError, Result};

/// The disparity of a plane as an affine function of the pixel: `D(x, y) = a·x + b·y + c`
/// (pixels of disparity, pixel coordinates as in [`Intrinsics`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DisparityAffine {
    /// ∂D/∂x.
    pub a: f64,
    /// ∂D/∂y.
    pub b: f64,
    /// D at pixel (0, 0).
    pub c: f64,
}

/// The difference of two disparity functions, coefficient by coefficient (itself affine: where
/// it is zero, the two planes' disparities cross).
impl std::ops::Sub for DisparityAffine {
    type Output = Self;

    fn sub(self, o: Self) -> Self {
        Self {
            a: self.a - o.a,
            b: self.b - o.b,
            c: self.c - o.c,
        }
    }
}

impl DisparityAffine {
    /// Disparity predicted at pixel `(x, y)`.
    #[inline]
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        self.a * x + self.b * y + self.c
    }

    /// The disparity function of a 3D plane seen by a camera with intrinsics `k` and
    /// `fb = f·B` (pixel·metres): see the module docs.
    pub fn from_plane(plane: &Plane, k: &Intrinsics, fb: f64) -> Result<Self> {
        let m = plane.paper_coefficients()?;
        if !(fb.is_finite() && fb > 0.0) {
            return Err(PlanesError::InvalidConfig(format!(
                "f·B = {} must be positive",
                sl_core::Compact(fb)
            )));
        }
        let a = -fb * m.x / k.fx;
        let b = -fb * m.y / k.fy;
        let c = -fb * (m.z - m.x * k.cx / k.fx - m.y * k.cy / k.fy);
        Ok(Self { a, b, c })
    }

    /// The 3D plane of a disparity function (inverse of [`DisparityAffine::from_plane`]).
    /// An error when the function is (numerically) zero everywhere: a plane at infinity.
    pub fn to_plane(&self, k: &Intrinsics, fb: f64) -> Result<Plane> {
        if !(fb.is_finite() && fb > 0.0) {
            return Err(PlanesError::InvalidConfig(format!(
                "f·B = {} must be positive",
                sl_core::Compact(fb)
            )));
        }
        let m = Vector3::new(
            -self.a * k.fx / fb,
            -self.b * k.fy / fb,
            -(self.c + self.a * k.cx + self.b * k.cy) / fb,
        );
        if !m.iter().all(|v| v.is_finite()) {
            return Err(PlanesError::DegeneratePlane(format!(
                "{self:?} is not finite"
            )));
        }
        Ok(Plane::from_paper_coefficients(m)?)
    }

    /// The paper's eq. 14 coefficients `(a, b, 1/B, c·f − a·u − b·v)` of
    /// `a·x + b·y + D/B + (c·f − a·u − b·v) = 0` for a camera with `fx = fy = f`, baseline `B`.
    pub fn paper_eq14(&self, baseline_m: f64) -> [f64; 4] {
        [
            -self.a / baseline_m,
            -self.b / baseline_m,
            1.0 / baseline_m,
            -self.c / baseline_m,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3};

    #[test]
    fn affine_round_trip_and_consistency() {
        let k = Intrinsics::new(640, 480, 517.3, 516.5, 318.6, 255.3).unwrap();
        let fb = 580.0 * 0.075;
        let plane = Plane::new(Vector3::new(0.2, -0.7, -0.6), 1.3)
            .unwrap()
            .facing_origin();
        let aff = DisparityAffine::from_plane(&plane, &k, fb).unwrap();
        // Every pixel's disparity equals fb / Z of the plane's depth there.
        for (x, y) in [(0.0, 0.0), (100.0, 400.0), (639.0, 12.0), (320.5, 240.25)] {
            let z = plane.depth_at(&k, x, y).unwrap();
            assert!((aff.eval(x, y) - fb / z).abs() < 1e-9, "{x},{y}");
        }
        let back = aff.to_plane(&k, fb).unwrap();
        assert!((back.normal - plane.normal).norm() < 1e-12);
        assert!((back.offset_m - plane.offset_m).abs() < 1e-12);
    }

    #[test]
    fn paper_eq14_matches_definition() {
        // fx = fy = f, fb = f·B: a x + b y + D/B + (c f − a u − b v) = 0.
        let k = Intrinsics::paper_kinect();
        let (f, bl) = (587.0, 0.075);
        let plane = Plane::from_paper_coefficients(Vector3::new(0.1, 0.3, -0.5)).unwrap();
        let m = plane.paper_coefficients().unwrap();
        let aff = DisparityAffine::from_plane(&plane, &k, f * bl).unwrap();
        let e = aff.paper_eq14(bl);
        assert!((e[0] - m.x).abs() < 1e-12 && (e[1] - m.y).abs() < 1e-12);
        assert!((e[3] - (m.z * f - m.x * k.cx - m.y * k.cy)).abs() < 1e-9);
        let (x, y) = (200.0, 100.0);
        let d = aff.eval(x, y);
        assert!((e[0] * x + e[1] * y + e[2] * d + e[3]).abs() < 1e-9);
    }

    #[test]
    fn transform_moves_plane_with_points() {
        let plane = Plane::new(Vector3::new(0.0, 0.3, -1.0), 2.0)
            .unwrap()
            .facing_origin();
        let t = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.05, -0.1, 0.2));
        // A point on the plane in B, moved into A, lies on the transformed plane.
        let p_b = Point3::new(0.4, 0.0, 0.0)
            + plane.normal * -plane.signed_distance_m(&Point3::new(0.4, 0.0, 0.0));
        assert!(plane.signed_distance_m(&p_b).abs() < 1e-12);
        let pa = t * p_b;
        assert!(
            plane
                .transformed(&t)
                .facing_origin()
                .signed_distance_m(&pa)
                .abs()
                < 1e-12
        );
        assert!(
            Plane::new(Vector3::zeros(), 1.0)
                .map(Plane::facing_origin)
                .is_err()
        );
        assert!(
            DisparityAffine::default()
                .to_plane(&Intrinsics::kinect_v1(), 43.5)
                .is_err()
        );
    }
}
