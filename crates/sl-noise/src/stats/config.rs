//! [`NoiseStatsConfig`]: the settings of [`noise_stats`](super::noise_stats), their defaults and
//! their validation.

use serde::Serialize;

use super::DEFAULT_LAGS;
use crate::error::{NoiseError, Result};

/// Settings of [`noise_stats`](super::noise_stats).
///
/// `#[non_exhaustive]`: start from [`NoiseStatsConfig::default`] and assign the fields you need.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct NoiseStatsConfig {
    /// Lags of the autocorrelation, pixels.
    pub lags: Vec<usize>,
    /// Edges of the depth bands for σ_D, metres, ascending.
    pub band_edges_m: Vec<f64>,
    /// Side of the square tiles the affine fits are made in, pixels.
    pub tile_px: usize,
    /// Smallest part of a region in one tile (valid pixels) that is fitted.
    pub min_tile_pixels: usize,
    /// Depth jump that makes an occlusion edge, metres.
    pub jump_m: f64,
    /// Longest invalid run counted as an occlusion band, pixels (longer runs are holes).
    pub max_band_px: usize,
    /// Image pixels per pixel of the sensor (`sl_core::Camera::pixels_per_sensor_pixel`: 0.5
    /// for a 320×240 stream of a 640×480 sensor): the predicted projector shadow, a disparity
    /// in the sensor's pixels, is reported in the image's, like the measured band widths.
    pub pixels_per_sensor_pixel: f64,
}

/// The former name of [`NoiseStatsConfig`].
#[deprecated(
    since = "0.1.0",
    note = "renamed `NoiseStatsConfig` (every configuration is a `…Config`)"
)]
pub type NoiseStatsOptions = NoiseStatsConfig;

impl NoiseStatsConfig {
    /// The defaults for frames of `camera`: its [`sl_core::Camera::pixels_per_sensor_pixel`],
    /// so that the projector shadows predicted for a decimated stream are in its pixels.
    pub fn for_camera(camera: &sl_core::Camera) -> Self {
        Self {
            pixels_per_sensor_pixel: camera.pixels_per_sensor_pixel(),
            ..Self::default()
        }
    }

    /// Checks the settings: `jump_m` must be a positive number, the band edges ascending and
    /// `tile_px` positive ([`NoiseError::InvalidParameter`] otherwise).
    /// [`noise_stats`](super::noise_stats) checks the same first.
    pub fn validate(&self) -> Result<()> {
        if !(self.jump_m.is_finite() && self.jump_m > 0.0) {
            return Err(NoiseError::InvalidParameter(format!(
                "jump_m = {} must be positive",
                sl_core::Compact(self.jump_m)
            )));
        }
        if self
            .band_edges_m
            .windows(2)
            .any(|e| e[0].partial_cmp(&e[1]) != Some(std::cmp::Ordering::Less))
        {
            return Err(NoiseError::InvalidParameter(
                "band edges must be ascending".into(),
            ));
        }
        if !(self.pixels_per_sensor_pixel.is_finite() && self.pixels_per_sensor_pixel > 0.0) {
            return Err(NoiseError::InvalidParameter(format!(
                "pixels_per_sensor_pixel = {} must be positive",
                sl_core::Compact(self.pixels_per_sensor_pixel)
            )));
        }
        if self.tile_px == 0 {
            return Err(NoiseError::InvalidParameter(
                "tile_px must be positive".into(),
            ));
        }
        Ok(())
    }
}

impl Default for NoiseStatsConfig {
    fn default() -> Self {
        Self {
            lags: DEFAULT_LAGS.to_vec(),
            band_edges_m: vec![0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0],
            tile_px: 64,
            min_tile_pixels: 2048,
            jump_m: 0.15,
            max_band_px: 64,
            pixels_per_sensor_pixel: 1.0,
        }
    }
}
