//! Pinhole camera intrinsics: projection, back-projection and pixel rays.

use nalgebra::{Point3, Vector3};

use crate::error::{CoreError, Result};

/// Pinhole intrinsics of a depth camera (no lens distortion: the paper notes the Kinect's is
/// negligible).
///
/// Pixel `(x, y)` has its centre at integer coordinates; `x` grows to the right, `y` downwards,
/// and the camera looks along +Z. Following the paper (section 3.4),
/// `x = fx·X/Z + cx`, `y = fy·Y/Z + cy`, and back-projection is
/// `X = (x − cx)·Z/fx`, `Y = (y − cy)·Z/fy`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels.
    pub cx: f64,
    /// Principal point y, in pixels.
    pub cy: f64,
}

/// Largest image side [`Intrinsics::validate`] accepts, pixels.
pub const MAX_SIDE_PX: usize = 1 << 16;

/// Largest focal length [`Intrinsics::validate`] accepts, pixels (10⁷: a 65536-pixel-wide image
/// with a 0.4° field of view; beyond that the numbers only produce overflowing geometry).
pub const MAX_FOCAL_PX: f64 = 1e7;

/// Smallest focal length [`Intrinsics::validate`] accepts, pixels: below one pixel a pinhole
/// image of even three pixels spans more than 180° (no depth camera; the numbers only produce
/// all-zero frames and overflowing geometry).
pub const MIN_FOCAL_PX: f64 = 1.0;

/// Largest principal-point coordinate magnitude [`Intrinsics::validate`] accepts, pixels.
pub const MAX_PRINCIPAL_PX: f64 = 1e7;

impl Intrinsics {
    /// Validated constructor: sizes must be non-zero (at most 65536 per side), focal lengths in
    /// [[`MIN_FOCAL_PX`], [`MAX_FOCAL_PX`]] and the principal point within [`MAX_PRINCIPAL_PX`].
    pub fn new(width: usize, height: usize, fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self> {
        let k = Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        };
        k.validate()?;
        Ok(k)
    }

    /// Checks the invariants of [`Intrinsics::new`] (useful after deserialising).
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(CoreError::InvalidIntrinsics(format!(
                "image size {}x{} must be non-zero",
                self.width, self.height
            )));
        }
        if self.width > MAX_SIDE_PX || self.height > MAX_SIDE_PX {
            return Err(CoreError::InvalidIntrinsics(format!(
                "image size {}x{} exceeds {MAX_SIDE_PX} pixels per side",
                self.width, self.height
            )));
        }
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && (MIN_FOCAL_PX..=MAX_FOCAL_PX).contains(&v)) {
                return Err(CoreError::InvalidIntrinsics(format!(
                    "{name} = {} must be in [{MIN_FOCAL_PX}, {}] pixels",
                    crate::Compact(v),
                    crate::Compact(MAX_FOCAL_PX)
                )));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !(v.is_finite() && v.abs() <= MAX_PRINCIPAL_PX) {
                return Err(CoreError::InvalidIntrinsics(format!(
                    "{name} = {} must be in [-{max}, {max}] pixels",
                    crate::Compact(v),
                    max = crate::Compact(MAX_PRINCIPAL_PX)
                )));
            }
        }
        Ok(())
    }

    /// The `kinect-v1` preset: 640×480, f = 580 px, principal point (319.5, 239.5).
    pub fn kinect_v1() -> Self {
        crate::preset::KINECT_V1.intrinsics()
    }

    /// The camera of the paper: 640×480, f = 587 px (the paper's calibration), centred
    /// principal point.
    pub fn paper_kinect() -> Self {
        crate::preset::PAPER_KINECT.intrinsics()
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Projects a camera-frame point to continuous pixel coordinates; `None` behind the camera
    /// (Z ≤ 0). The result may lie outside the image.
    pub fn project(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        // Written so that NaN depths are rejected too.
        if p.z.is_nan() || p.z <= 0.0 {
            return None;
        }
        Some((self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    /// Projects to the nearest pixel inside the image, or `None`.
    pub fn project_to_pixel(&self, p: &Point3<f64>) -> Option<(usize, usize)> {
        let (u, v) = self.project(p)?;
        let (x, y) = (u.round(), v.round());
        if x < 0.0 || y < 0.0 || x >= self.width as f64 || y >= self.height as f64 {
            return None;
        }
        Some((x as usize, y as usize))
    }

    /// Back-projects pixel `(x, y)` at depth `z` (metres along the optical axis) to a
    /// camera-frame point.
    pub fn back_project(&self, x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new((x - self.cx) * z / self.fx, (y - self.cy) * z / self.fy, z)
    }

    /// The ray through pixel `(x, y)`, scaled so that its Z component is 1: the point at depth
    /// `z` is `z * ray`.
    pub fn ray(&self, x: f64, y: f64) -> Vector3<f64> {
        Vector3::new((x - self.cx) / self.fx, (y - self.cy) / self.fy, 1.0)
    }

    /// The unit-length ray through pixel `(x, y)`.
    pub fn unit_ray(&self, x: f64, y: f64) -> Vector3<f64> {
        self.ray(x, y).normalize()
    }

    /// Intrinsics for the same camera with the image resampled by `factor` (e.g. 0.5 for half
    /// resolution, pixel-centre convention preserved).
    pub fn scaled(&self, factor: f64) -> Result<Self> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(CoreError::InvalidIntrinsics(format!(
                "scale factor {} must be positive",
                crate::Compact(factor)
            )));
        }
        let (w, h) = (
            ((self.width as f64) * factor).round(),
            ((self.height as f64) * factor).round(),
        );
        // Checked before the conversion, which would saturate a huge side into a wrong size.
        let max_side = MAX_SIDE_PX as f64;
        if w > max_side || h > max_side {
            return Err(CoreError::InvalidIntrinsics(format!(
                "scale factor {} makes a {}x{} image of this {}x{} one: each side must be at \
                 most {MAX_SIDE_PX} pixels",
                crate::Compact(factor),
                crate::Compact(w),
                crate::Compact(h),
                self.width,
                self.height
            )));
        }
        Self::new(
            w as usize,
            h as usize,
            self.fx * factor,
            self.fy * factor,
            (self.cx + 0.5) * factor - 0.5,
            (self.cy + 0.5) * factor - 0.5,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A factor that makes a side beyond 65536 pixels says so with the sizes, compactly (the
    /// conversion saturated 640·1e300 into 18446744073709551615 before).
    #[test]
    fn a_huge_scale_factor_names_the_size_it_would_make() {
        let e = Intrinsics::kinect_v1()
            .scaled(1e300)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scale factor 1e300 makes a 6.4e302x4.8e302 image of this 640x480 one"),
            "{e}"
        );
        let e = Intrinsics::kinect_v1()
            .scaled(103.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("makes a 65920x49440 image"), "{e}");
        assert_eq!(Intrinsics::kinect_v1().scaled(102.0).unwrap().width, 65280);
    }

    #[test]
    fn project_back_project_round_trip() {
        let k = Intrinsics::kinect_v1();
        let p = k.back_project(100.25, 400.5, 2.5);
        let (u, v) = k.project(&p).unwrap();
        assert!((u - 100.25).abs() < 1e-12 && (v - 400.5).abs() < 1e-12);
        assert_eq!(k.project(&Point3::new(0.0, 0.0, -1.0)), None);
    }

    #[test]
    fn rays_scale_to_points() {
        let k = Intrinsics::paper_kinect();
        let r = k.ray(10.0, 20.0);
        let p = k.back_project(10.0, 20.0, 3.0);
        assert!((r * 3.0 - p.coords).norm() < 1e-12);
        assert!((k.unit_ray(10.0, 20.0).norm() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn validation_rejects_nonsense() {
        assert!(Intrinsics::new(0, 480, 500.0, 500.0, 1.0, 1.0).is_err());
        assert!(Intrinsics::new(640, 480, -5.0, 500.0, 1.0, 1.0).is_err());
        assert!(Intrinsics::new(640, 480, 500.0, f64::NAN, 1.0, 1.0).is_err());
        assert!(Intrinsics::new(640, 480, 500.0, 500.0, 319.5, 239.5).is_ok());
    }

    /// The refused value comes back as it was written (`-517.3`, `0`), not as `-5.173e2` and
    /// `0e0`.
    #[test]
    fn refused_values_are_repeated_compactly() {
        let e = |k: Result<Intrinsics>| k.unwrap_err().to_string();
        let neg = e(Intrinsics::new(640, 480, -517.3, 500.0, 1.0, 1.0));
        assert!(
            neg.contains("fx = -517.3 must be in [1, 1e7] pixels"),
            "{neg}"
        );
        let zero = e(Intrinsics::new(640, 480, 500.0, 0.0, 1.0, 1.0));
        assert!(zero.contains("fy = 0 must be"), "{zero}");
        let far = e(Intrinsics::new(640, 480, 500.0, 500.0, 1e300, 1.0));
        assert!(
            far.contains("cx = 1e300 must be in [-1e7, 1e7] pixels"),
            "{far}"
        );
    }

    #[test]
    fn half_resolution() {
        let k = Intrinsics::kinect_v1().scaled(0.5).unwrap();
        assert_eq!((k.width, k.height), (320, 240));
        assert!((k.cx - 159.5).abs() < 1e-12 && (k.fx - 290.0).abs() < 1e-12);
    }
}
