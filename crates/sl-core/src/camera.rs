//! A depth camera: pinhole [`Intrinsics`] plus the disparity [`SensorModel`].

use crate::error::Result;
use crate::intrinsics::Intrinsics;
use crate::sensor::{DEFAULT_SIGMA_D_PX, SensorModel};

/// Intrinsics and sensor model of one structured-light camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Disparity sensor model.
    pub sensor: SensorModel,
}

/// Default projector–camera baseline of a Kinect v1, metres.
pub const KINECT_BASELINE_M: f64 = 0.075;
/// Default sub-pixel disparity steps of a Kinect v1.
pub const KINECT_SUBPIXEL_STEPS: u32 = 8;
/// Largest whole decimation of a camera's frames that [`Camera::for_frames`] recognises.
pub const MAX_DECIMATION: usize = 8;

impl Camera {
    /// The `kinect-v1` preset: 640×480, f = 580 px, c = (319.5, 239.5), B = 0.075 m, 1/8 px.
    pub fn kinect_v1() -> Self {
        Self {
            intrinsics: Intrinsics::kinect_v1(),
            sensor: SensorModel::kinect_v1(),
        }
    }

    /// The paper's Kinect: f = 587 px, B = 75 mm, 1/8 px.
    pub fn paper_kinect() -> Self {
        Self {
            intrinsics: Intrinsics::paper_kinect(),
            sensor: SensorModel::paper_kinect(),
        }
    }

    /// A camera with the given intrinsics and a Kinect-like sensor: focal length `fx`,
    /// baseline and sub-pixel steps from the Kinect defaults unless given.
    pub fn from_intrinsics(
        intrinsics: Intrinsics,
        baseline_m: Option<f64>,
        subpixel_steps: Option<u32>,
    ) -> Result<Self> {
        intrinsics.validate()?;
        let sensor = SensorModel::new(
            intrinsics.fx,
            baseline_m.unwrap_or(KINECT_BASELINE_M),
            subpixel_steps.unwrap_or(KINECT_SUBPIXEL_STEPS),
            DEFAULT_SIGMA_D_PX,
        )?;
        Ok(Self { intrinsics, sensor })
    }
}

impl Camera {
    /// The same sensor seen through an image resampled by `factor` (0.5: a 320×240 stream of a
    /// 640×480 sensor, as a QVGA mode or a decimating driver delivers it). The intrinsics are
    /// scaled ([`Intrinsics::scaled`]); the sensor model is kept, so the depth noise `σ_Z(Z)`
    /// stays the sensor's and its pixel-sized quantities (the disparity step, the
    /// block-matching window) stay in the sensor's own pixels
    /// ([`Camera::pixels_per_sensor_pixel`] converts them).
    ///
    /// # Errors
    /// A `factor` that is not positive and finite, or intrinsics that scale to no pixel.
    pub fn resampled(&self, factor: f64) -> Result<Self> {
        Ok(Self {
            intrinsics: self.intrinsics.scaled(factor)?,
            sensor: self.sensor,
        })
    }

    /// The camera of frames `width`×`height` taken by this camera's sensor, and the decimation
    /// factor: itself (factor 1) at its own size; the same sensor decimated
    /// ([`Camera::resampled`]`(1/n)`: intrinsics scaled, noise model kept) when the frames are
    /// its size divided by a whole `n` from 2 to [`MAX_DECIMATION`] (a QVGA stream of a VGA
    /// sensor, a driver's decimation); `None` for any other size.
    pub fn for_frames(&self, width: usize, height: usize) -> Option<(Self, usize)> {
        let k = &self.intrinsics;
        if (width, height) == (k.width, k.height) {
            return Some((*self, 1));
        }
        let n = (2..=MAX_DECIMATION).find(|&n| width * n == k.width && height * n == k.height)?;
        Some((self.resampled(1.0 / n as f64).ok()?, n))
    }

    /// Image pixels per pixel of the sensor, `fx / sensor.focal_px`: 1 for a camera at its
    /// sensor's resolution, 0.5 for [`Camera::resampled`]`(0.5)`. Quantities the sensor defines
    /// in its own pixels (the block-matching window over which its error is correlated) span
    /// this many times as many image pixels along each axis. 1 when the ratio is not positive
    /// and finite (a camera assembled from unvalidated fields).
    pub fn pixels_per_sensor_pixel(&self) -> f64 {
        let s = self.intrinsics.fx / self.sensor.focal_px;
        if s.is_finite() && s > 0.0 { s } else { 1.0 }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self::kinect_v1()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn frames_a_whole_fraction_of_the_camera_are_its_sensor_decimated() {
        let c = Camera::kinect_v1();
        assert_eq!(c.for_frames(640, 480), Some((c, 1)));
        let (half, n) = c.for_frames(320, 240).unwrap();
        assert_eq!(n, 2);
        assert_eq!((half.intrinsics.width, half.intrinsics.height), (320, 240));
        assert_eq!(half.sensor, c.sensor);
        assert_eq!(c.for_frames(80, 60).map(|(_, n)| n), Some(8));
        assert!(c.for_frames(64, 48).is_none()); // 1/10
        assert!(c.for_frames(320, 480).is_none());
        assert!(c.for_frames(1280, 960).is_none());
    }
}
