//! Row-major single-channel images: the generic [`Image`], and the typed [`DepthImage`]
//! (metres) and [`DisparityImage`] (pixels), where 0 marks an invalid pixel.

use nalgebra::Point3;

use crate::error::{CoreError, Result};
use crate::intrinsics::Intrinsics;
use crate::sensor::SensorModel;

/// A row-major image of `width * height` values.
#[derive(Debug, Clone, PartialEq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Clone> Image<T> {
    /// An image filled with `value`.
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }
}

impl<T> Image<T> {
    /// Wraps a row-major buffer; its length must be `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Result<Self> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(CoreError::BufferLength {
                len: data.len(),
                width,
                height,
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Builds an image from a function of `(x, y)`.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    pub fn dimensions(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The row-major buffer.
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// The row-major buffer, mutable.
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// Consumes the image, returning its buffer.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// The value at `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<&T> {
        if x < self.width && y < self.height {
            self.data.get(y * self.width + x)
        } else {
            None
        }
    }

    /// Row `y` (panics if `y >= height`; use [`Image::rows`] to iterate).
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Iterator over rows.
    pub fn rows(&self) -> std::slice::Chunks<'_, T> {
        self.data.chunks(self.width.max(1))
    }

    /// Mutable iterator over rows.
    pub fn rows_mut(&mut self) -> std::slice::ChunksMut<'_, T> {
        self.data.chunks_mut(self.width.max(1))
    }

    /// Checks that the image has the size of the camera.
    pub fn check_size(&self, k: &Intrinsics) -> Result<()> {
        if self.width != k.width || self.height != k.height {
            return Err(CoreError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: self.width,
                height: self.height,
            });
        }
        Ok(())
    }

    /// Applies `f` to every value.
    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

/// A pixel `(x, y)` with the camera-frame point it back-projects to.
pub type PixelPoint = ((usize, usize), Point3<f32>);

/// Summary statistics of the valid (> 0, finite) values of a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidStats {
    /// Number of valid pixels.
    pub valid_pixels: usize,
    /// Smallest valid value.
    pub min: f32,
    /// Median valid value (the lower middle for an even count).
    pub median: f32,
    /// Largest valid value.
    pub max: f32,
}

fn is_valid(v: f32) -> bool {
    v > 0.0 && v.is_finite()
}

macro_rules! typed_map {
    ($name:ident, $unit:literal) => {
        impl $name {
            /// Wraps a row-major buffer of values in
            #[doc = $unit]
            /// (0 = invalid); its length must be `width * height`.
            pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Result<Self> {
                Ok(Self(Image::from_vec(width, height, data)?))
            }

            /// An image with every pixel invalid (0).
            pub fn invalid(width: usize, height: usize) -> Self {
                Self(Image::filled(width, height, 0.0))
            }

            /// Wraps an [`Image`].
            pub fn from_image(image: Image<f32>) -> Self {
                Self(image)
            }

            /// The underlying image.
            pub fn as_image(&self) -> &Image<f32> {
                &self.0
            }

            /// The underlying image, mutable.
            pub fn as_image_mut(&mut self) -> &mut Image<f32> {
                &mut self.0
            }

            /// Consumes into the underlying image.
            pub fn into_image(self) -> Image<f32> {
                self.0
            }

            /// Width in pixels.
            pub fn width(&self) -> usize {
                self.0.width()
            }

            /// Height in pixels.
            pub fn height(&self) -> usize {
                self.0.height()
            }

            /// The row-major values.
            pub fn data(&self) -> &[f32] {
                self.0.data()
            }

            /// The row-major values, mutable.
            pub fn data_mut(&mut self) -> &mut [f32] {
                self.0.data_mut()
            }

            /// The value at `(x, y)` (0 when invalid), or `None` outside the image.
            pub fn get(&self, x: usize, y: usize) -> Option<f32> {
                self.0.get(x, y).copied()
            }

            /// Whether `(x, y)` is inside the image and holds a valid value.
            pub fn is_valid_at(&self, x: usize, y: usize) -> bool {
                self.get(x, y).is_some_and(is_valid)
            }

            /// Number of valid pixels.
            pub fn valid_count(&self) -> usize {
                self.0.data().iter().filter(|v| is_valid(**v)).count()
            }

            /// Sets every non-finite or negative value to 0 (invalid).
            pub fn sanitize(&mut self) {
                for v in self.0.data_mut() {
                    if !is_valid(*v) {
                        *v = 0.0;
                    }
                }
            }

            /// Min / median / max of the valid values, or `None` when nothing is valid.
            pub fn stats(&self) -> Option<ValidStats> {
                let mut v: Vec<f32> = self
                    .0
                    .data()
                    .iter()
                    .copied()
                    .filter(|v| is_valid(*v))
                    .collect();
                if v.is_empty() {
                    return None;
                }
                let n = v.len();
                let mid = (n - 1) / 2;
                let (_, median, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
                let median = *median;
                let min = v.iter().copied().fold(f32::INFINITY, f32::min);
                let max = v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                Some(ValidStats {
                    valid_pixels: n,
                    min,
                    median,
                    max,
                })
            }
        }
    };
}

/// A depth map: `f32` metres along the optical axis, 0 = invalid.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage(Image<f32>);

/// A disparity map: `f32` pixels, 0 = invalid. `D = f·B / Z`.
#[derive(Debug, Clone, PartialEq)]
pub struct DisparityImage(Image<f32>);

typed_map!(DepthImage, "metres");
typed_map!(DisparityImage, "pixels");

impl DepthImage {
    /// Converts to disparity with `D = f·B / Z`; invalid stays invalid.
    pub fn to_disparity(&self, sensor: &SensorModel) -> DisparityImage {
        let fb = sensor.fb() as f32;
        DisparityImage(self.0.map(|&z| if is_valid(z) { fb / z } else { 0.0 }))
    }

    /// Back-projects every valid pixel to a camera-frame point (metres), in row-major order.
    pub fn to_points(&self, k: &Intrinsics) -> Result<Vec<Point3<f32>>> {
        Ok(self
            .to_points_with_pixels(k)?
            .into_iter()
            .map(|(_, p)| p)
            .collect())
    }

    /// Like [`DepthImage::to_points`], each point paired with its pixel `(x, y)`.
    pub fn to_points_with_pixels(&self, k: &Intrinsics) -> Result<Vec<PixelPoint>> {
        self.0.check_size(k)?;
        let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
        let mut out = Vec::with_capacity(self.valid_count());
        for (y, row) in self.0.rows().enumerate() {
            let ry = (y as f32 - cy) / fy;
            for (x, &z) in row.iter().enumerate() {
                if is_valid(z) {
                    out.push(((x, y), Point3::new((x as f32 - cx) / fx * z, ry * z, z)));
                }
            }
        }
        Ok(out)
    }
}

impl DisparityImage {
    /// Converts to depth with `Z = f·B / D`; invalid stays invalid.
    pub fn to_depth(&self, sensor: &SensorModel) -> DepthImage {
        let fb = sensor.fb() as f32;
        DepthImage(self.0.map(|&d| if is_valid(d) { fb / d } else { 0.0 }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffer_length_is_checked() {
        assert!(DepthImage::from_vec(4, 3, vec![0.0; 11]).is_err());
        assert!(DepthImage::from_vec(4, 3, vec![0.0; 12]).is_ok());
        assert!(Image::<u8>::from_vec(usize::MAX, 2, vec![]).is_err());
    }

    #[test]
    fn stats_ignore_invalid() {
        let d = DepthImage::from_vec(3, 2, vec![0.0, 1.0, 3.0, f32::NAN, 2.0, 0.0]).unwrap();
        let s = d.stats().unwrap();
        assert_eq!((s.valid_pixels, s.min, s.median, s.max), (3, 1.0, 2.0, 3.0));
        assert_eq!(DepthImage::invalid(2, 2).stats(), None);
    }

    #[test]
    fn disparity_round_trip_keeps_invalid() {
        let s = SensorModel::kinect_v1();
        let d = DepthImage::from_vec(2, 2, vec![0.0, 1.0, 2.0, 4.0]).unwrap();
        let disp = d.to_disparity(&s);
        assert_eq!(disp.get(0, 0), Some(0.0));
        assert!((disp.get(1, 0).unwrap() - 43.5).abs() < 1e-4);
        let back = disp.to_depth(&s);
        for (a, b) in back.data().iter().zip(d.data()) {
            assert!((a - b).abs() < 1e-6);
        }
    }

    #[test]
    fn points_back_project() {
        let k = Intrinsics::new(4, 3, 2.0, 2.0, 1.5, 1.0).unwrap();
        let mut d = DepthImage::invalid(4, 3);
        d.data_mut()[4 + 3] = 2.0; // (3, 1)
        let pts = d.to_points_with_pixels(&k).unwrap();
        assert_eq!(pts.len(), 1);
        let ((x, y), p) = pts[0];
        assert_eq!((x, y), (3, 1));
        assert!((p.x - 1.5).abs() < 1e-6 && p.y.abs() < 1e-6 && (p.z - 2.0).abs() < 1e-6);
        assert!(DepthImage::invalid(5, 3).to_points(&k).is_err());
    }
}
