//! Noise statistics of a depth map with planar regions: how a frame's noise looks, so real and
//! simulated frames can be compared (issue 11).
//!
//! [`noise_stats`] takes a depth map, the camera's `f·B` and a label image of planar regions
//! (1.. = region, 0 = none; e.g. the planes `sl-planes` extracts, or a simulator's surface
//! labels) and reports:
//!
//! * **σ_D per depth band**: inside each region, tile by tile ([`NoiseStatsConfig::tile_px`],
//!   64 px, so non-flat walls and low-frequency distortion do not count as noise), the disparity
//!   `D = f·B/Z` is fitted by an affine function of the pixel (exact for a plane, eq. 14 of the
//!   paper) with one robust refit (residuals beyond 4 MAD-σ are dropped); the RMS residual of
//!   each tile, median over the tiles of a band of fitted depth (and over all tiles);
//! * **residual autocorrelation** at lags 1, 2, 4, 8, 16 px along x and along y (Pearson
//!   correlation of residual pairs inside one tile, median over tiles);
//! * **terrace widths**: runs of identical depth along rows inside a region (complete runs only,
//!   bounded on both sides by a different valid depth of the same region and fitted tiles);
//! * **occlusion bands**: per row, the runs of invalid pixels between a valid foreground pixel
//!   and a valid background pixel more than [`NoiseStatsConfig::jump_m`] deeper, split by the
//!   side of the foreground the band lies on; with the width the projector shadow alone would
//!   have (`f·B·(1/Z_fg − 1/Z_bg)`), so the excess (edge invalidation) can be read off.
//!
//! Nothing here reads files or knows about planes beyond the labels: the plane finding is the
//! caller's (the `sldepth noise-stats` command uses `sl-planes`).

mod autocorrelation;
mod config;
mod occlusion;
mod residuals;
mod sigma;
mod terraces;
#[cfg(test)]
mod tests;
mod widths;

pub use autocorrelation::LagCorrelation;
#[allow(deprecated)]
pub use config::{NoiseStatsConfig, NoiseStatsOptions};
pub use occlusion::{OcclusionBands, SHADOW_BINS_PX, ShadowBin, SideBands, occlusion_bands};
pub use residuals::{Residuals, disparity_residuals};
pub use sigma::BandSigma;
pub use terraces::Terraces;
pub use widths::WidthStats;

use autocorrelation::lag_correlations;
use sigma::band_sigmas;
use terraces::terraces;

use serde::Serialize;
use sl_core::{DepthImage, Image};

use crate::error::Result;

/// Fewest residuals (or residual pairs) of a tile that enter the medians.
pub const MIN_TILE_RESIDUALS: usize = 256;

/// Smallest RMS residual of a tile whose autocorrelation is measured, pixels of disparity: far
/// below any sensor's noise (σ_D ≈ 0.07 px), above the rounding of `f32` disparities (about
/// 2·10⁻⁶ px at 20 px). A noise-free surface (a rendered or synthetic frame) has no noise to
/// correlate: its tiles would report the correlation of float rounding (0.97–1.00).
pub const MIN_CORRELATED_RMS_PX: f64 = 1e-4;

/// Lags of the residual autocorrelation, pixels.
pub const DEFAULT_LAGS: [usize; 5] = [1, 2, 4, 8, 16];

/// The result of [`noise_stats`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseStats {
    /// Region tiles fitted.
    pub regions: usize,
    /// Residual pixels (valid, in a fitted region, not rejected).
    pub pixels: usize,
    /// Median over all tiles of their RMS disparity residual, pixels.
    pub sigma_d_px: f64,
    /// σ_D per depth band (bands without pixels are listed with NaN).
    pub bands: Vec<BandSigma>,
    /// Residual autocorrelation per lag.
    pub acf: Vec<LagCorrelation>,
    /// Terrace widths.
    pub terraces: Terraces,
    /// Occlusion bands.
    pub occlusion: OcclusionBands,
    /// Fraction of invalid pixels in the frame.
    pub invalid_fraction: f64,
}

impl NoiseStats {
    /// The autocorrelation at `lag` along x and y, if that lag was measured.
    pub fn acf_at(&self, lag: usize) -> Option<(f64, f64)> {
        self.acf.iter().find(|c| c.lag == lag).map(|c| (c.x, c.y))
    }
}

/// The statistics of the module documentation for one depth map.
pub fn noise_stats(
    depth: &DepthImage,
    fb_px_m: f64,
    regions: &Image<u16>,
    opts: &NoiseStatsConfig,
) -> Result<NoiseStats> {
    opts.validate()?;
    let res = disparity_residuals(depth, fb_px_m, regions, opts.tile_px, opts.min_tile_pixels)?;
    let n_keys = res
        .tile
        .data()
        .iter()
        .filter(|k| **k != u32::MAX)
        .max()
        .map_or(0, |k| *k as usize + 1);
    let (bands, sigma_d_px, pixels) = band_sigmas(&res, n_keys, &opts.band_edges_m);
    let acf = lag_correlations(&res, n_keys, &opts.lags);
    let terraces = terraces(depth, &res, regions);
    let occlusion = occlusion_bands(
        depth,
        fb_px_m * opts.pixels_per_sensor_pixel,
        opts.jump_m,
        opts.max_band_px,
    );
    let zs = depth.data();
    let invalid = zs.iter().filter(|z| !(**z > 0.0 && z.is_finite())).count();
    Ok(NoiseStats {
        regions: res.regions,
        pixels,
        sigma_d_px,
        bands,
        acf,
        terraces,
        occlusion,
        invalid_fraction: if zs.is_empty() {
            0.0
        } else {
            invalid as f64 / zs.len() as f64
        },
    })
}

/// The median of the finite values (NaN for none).
pub(super) fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    crate::analysis::median(&mut v).unwrap_or(f64::NAN)
}

/// Linear-interpolated quantile of sorted values (NaN for none).
pub(crate) fn quantile_sorted(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let t = pos - lo as f64;
    v[lo] * (1.0 - t) + v[hi] * t
}
