//! Lens distortion (the Brown–Conrady model of OpenCV and the TUM RGB-D calibration) and the
//! undistortion of depth images.
//!
//! Depth images registered to a colour camera (TUM RGB-D fr1/fr2, OpenNI's hardware
//! registration) sit in the *distorted* colour image: a pixel `(u, v)` sees the ray through the
//! distorted normalised point, not the pinhole ray. Unprojecting them with pinhole intrinsics
//! bends every plane (the TUM fr1 lens scales the image radially by up to 6 % at the corners),
//! which costs plane fits, tracking and fusion alike. [`Undistorter`] resamples a depth image
//! into the ideal pinhole image of the same intrinsics: each output pixel takes the depth of the
//! input pixel nearest to where the lens maps its ray (nearest neighbour: depth is never
//! blended across an edge). The depth value is unchanged — `Z` along the optical axis does not
//! depend on where the lens images the point.
//!
//! ```
//! use sl_core::{DepthImage, Intrinsics, lens::{LensDistortion, Undistorter}};
//!
//! let k = Intrinsics::new(64, 48, 52.0, 52.0, 31.5, 23.5)?;
//! let lens = LensDistortion::new(0.2624, -0.9531, -0.0054, 0.0026, 1.1633)?;
//! let und = Undistorter::new(&k, &lens);
//! let depth = DepthImage::from_vec(64, 48, vec![1.5; 64 * 48])?;
//! let out = und.apply(&depth)?;
//! assert_eq!(out.get(32, 24), Some(1.5));
//! # Ok::<(), sl_core::CoreError>(())
//! ```

use crate::error::{CoreError, Result};
use crate::image::DepthImage;
use crate::intrinsics::Intrinsics;
use crate::view::DepthView;

/// Radial (`k1`, `k2`, `k3`) and tangential (`p1`, `p2`) distortion coefficients, in OpenCV's
/// order `(k1, k2, p1, p2, k3)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensDistortion {
    /// Radial coefficient of `r²`.
    pub k1: f64,
    /// Radial coefficient of `r⁴`.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial coefficient of `r⁶`.
    pub k3: f64,
}

impl LensDistortion {
    /// Coefficients in OpenCV's order `(k1, k2, p1, p2, k3)`; all must be finite.
    pub fn new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self> {
        if [k1, k2, p1, p2, k3].iter().any(|v| !v.is_finite()) {
            return Err(CoreError::InvalidIntrinsics(format!(
                "lens distortion coefficients must be finite, got ({}, {}, {}, {}, {})",
                crate::Compact(k1),
                crate::Compact(k2),
                crate::Compact(p1),
                crate::Compact(p2),
                crate::Compact(k3)
            )));
        }
        Ok(Self { k1, k2, p1, p2, k3 })
    }

    /// Whether every coefficient is zero (a pinhole lens).
    pub fn is_zero(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
            .iter()
            .all(|&v| v == 0.0)
    }

    /// The distorted normalised point of the ideal (pinhole) normalised point `(x, y)`.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }
}

/// A precomputed nearest-neighbour map from the ideal pinhole image to a distorted one of the
/// same intrinsics: [`Undistorter::apply`] costs one gather per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Undistorter {
    width: usize,
    height: usize,
    /// Per output pixel: the input pixel index, or `u32::MAX` where the ray leaves the image.
    source: Vec<u32>,
}

impl Undistorter {
    /// The map for images of intrinsics `k` taken through `lens`.
    pub fn new(k: &Intrinsics, lens: &LensDistortion) -> Self {
        let (w, h) = (k.width, k.height);
        let mut source = Vec::with_capacity(w * h);
        for v in 0..h {
            let y = (v as f64 - k.cy) / k.fy;
            for u in 0..w {
                let x = (u as f64 - k.cx) / k.fx;
                let (xd, yd) = lens.distort(x, y);
                let (ud, vd) = ((k.fx * xd + k.cx).round(), (k.fy * yd + k.cy).round());
                let inside = ud >= 0.0 && vd >= 0.0 && ud < w as f64 && vd < h as f64;
                source.push(if inside {
                    (vd as usize * w + ud as usize) as u32
                } else {
                    u32::MAX
                });
            }
        }
        Self {
            width: w,
            height: h,
            source,
        }
    }

    /// The undistorted depth image (0 where the ray leaves the input image).
    pub fn apply<'a>(&self, depth: impl Into<DepthView<'a>>) -> Result<DepthImage> {
        let mut out = Vec::new();
        self.apply_into(depth, &mut out)?;
        DepthImage::from_vec(self.width, self.height, out)
    }

    /// [`Undistorter::apply`] into `out` (resized; no other allocation).
    pub fn apply_into<'a>(
        &self,
        depth: impl Into<DepthView<'a>>,
        out: &mut Vec<f32>,
    ) -> Result<()> {
        let depth: DepthView<'a> = depth.into();
        if (depth.width(), depth.height()) != (self.width, self.height) {
            return Err(CoreError::SizeMismatch {
                expected_width: self.width,
                expected_height: self.height,
                width: depth.width(),
                height: depth.height(),
            });
        }
        let z = depth.data();
        out.clear();
        out.extend(
            self.source
                .iter()
                .map(|&s| z.get(s as usize).copied().unwrap_or(0.0)),
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_distortion_is_the_identity() {
        let k = Intrinsics::new(20, 10, 15.0, 15.0, 9.5, 4.5).unwrap();
        let lens = LensDistortion::new(0.0, 0.0, 0.0, 0.0, 0.0).unwrap();
        assert!(lens.is_zero());
        let z: Vec<f32> = (0..200).map(|i| 0.5 + i as f32 * 0.01).collect();
        let depth = DepthImage::from_vec(20, 10, z.clone()).unwrap();
        assert_eq!(
            Undistorter::new(&k, &lens).apply(&depth).unwrap().data(),
            &z[..]
        );
    }

    #[test]
    fn a_point_lands_where_the_lens_images_it() {
        // The TUM fr1 lens: a pixel near the corner of the distorted image comes from farther
        // out (barrel-like at mid radius for these coefficients); invert numerically and check
        // that the map sends the ideal pixel to the distorted one.
        let k = Intrinsics::new(640, 480, 517.3, 516.5, 318.6, 255.3).unwrap();
        let lens = LensDistortion::new(0.2624, -0.9531, -0.0054, 0.0026, 1.1633).unwrap();
        let und = Undistorter::new(&k, &lens);
        let (u, v) = (600usize, 440usize);
        let (x, y) = ((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy);
        let (xd, yd) = lens.distort(x, y);
        let (ud, vd) = (k.fx * xd + k.cx, k.fy * yd + k.cy);
        assert!(
            (ud - u as f64).abs() > 2.0,
            "the lens moves the corner: {ud}"
        );
        let s = und.source[v * 640 + u] as usize;
        assert_eq!(
            (s % 640, s / 640),
            (ud.round() as usize, vd.round() as usize)
        );
        // A marked input pixel appears at the ideal position.
        let mut z = vec![1.0f32; 640 * 480];
        z[s] = 2.0;
        let out = und
            .apply(&DepthImage::from_vec(640, 480, z).unwrap())
            .unwrap();
        assert_eq!(out.get(u, v), Some(2.0));
        // Size mismatch and bad coefficients are errors.
        assert!(und.apply(&DepthImage::invalid(10, 10)).is_err());
        assert!(LensDistortion::new(f64::NAN, 0.0, 0.0, 0.0, 0.0).is_err());
    }
}
