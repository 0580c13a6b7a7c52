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

use serde::Serialize;
use sl_core::{DepthImage, Image};

use crate::error::{NoiseError, Result};

/// Fewest residuals (or residual pairs) of a tile that enter the medians.
pub const MIN_TILE_RESIDUALS: usize = 256;

/// Smallest RMS residual of a tile whose autocorrelation is measured, pixels of disparity: far
/// below any sensor's noise (σ_D ≈ 0.07 px), above the rounding of `f32` disparities (about
/// 2·10⁻⁶ px at 20 px). A noise-free surface (a rendered or synthetic frame) has no noise to
/// correlate: its tiles would report the correlation of float rounding (0.97–1.00).
pub const MIN_CORRELATED_RMS_PX: f64 = 1e-4;

/// Lags of the residual autocorrelation, pixels.
pub const DEFAULT_LAGS: [usize; 5] = [1, 2, 4, 8, 16];

/// Settings of [`noise_stats`].
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
    /// `tile_px` positive ([`NoiseError::InvalidParameter`] otherwise). [`noise_stats`] checks
    /// the same first.
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

/// σ_D of one depth band.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BandSigma {
    /// Near edge of the band, metres.
    pub z_lo_m: f64,
    /// Far edge of the band, metres.
    pub z_hi_m: f64,
    /// Residual pixels in the band.
    pub pixels: usize,
    /// Tiles in the band.
    pub tiles: usize,
    /// Median over the band's tiles of their RMS disparity residual, pixels (NaN without
    /// tiles).
    pub sigma_d_px: f64,
}

/// Autocorrelation of the residual at one lag.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LagCorrelation {
    /// Lag, pixels.
    pub lag: usize,
    /// Median over tiles of the correlation along x (NaN without pairs).
    pub x: f64,
    /// Median over tiles of the correlation along y (NaN without pairs).
    pub y: f64,
    /// Pairs along x.
    pub pairs_x: usize,
    /// Pairs along y.
    pub pairs_y: usize,
}

/// Distribution of the widths of a set of runs, pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WidthStats {
    /// Number of runs.
    pub count: usize,
    /// Median width (NaN without runs).
    pub median_px: f64,
    /// Mean width (NaN without runs).
    pub mean_px: f64,
    /// 10th percentile (NaN without runs).
    pub p10_px: f64,
    /// 90th percentile (NaN without runs).
    pub p90_px: f64,
}

impl WidthStats {
    fn from_widths(mut w: Vec<f64>) -> Self {
        w.sort_by(f64::total_cmp);
        let n = w.len();
        if n == 0 {
            return Self {
                count: 0,
                median_px: f64::NAN,
                mean_px: f64::NAN,
                p10_px: f64::NAN,
                p90_px: f64::NAN,
            };
        }
        Self {
            count: n,
            median_px: quantile_sorted(&w, 0.5),
            mean_px: w.iter().sum::<f64>() / n as f64,
            p10_px: quantile_sorted(&w, 0.1),
            p90_px: quantile_sorted(&w, 0.9),
        }
    }
}

/// Invalid bands on one side of foreground objects.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SideBands {
    /// Widths of the invalid runs.
    pub widths: WidthStats,
    /// Median width of the projector shadow predicted from the bounding depths,
    /// `f·B·(1/Z_fg − 1/Z_bg)`, pixels (NaN without runs).
    pub median_shadow_px: f64,
    /// Edges with this jump and no invalid pixel between foreground and background.
    pub direct_edges: usize,
    /// Median depth of the foreground pixel bounding the bands, metres (NaN without runs).
    pub median_fg_m: f64,
    /// Median depth of the background pixel bounding the bands, metres (NaN without runs).
    pub median_bg_m: f64,
    /// Every edge of this side (a band or direct) by the projector shadow its two depths
    /// predict, in the bins of [`SHADOW_BINS_PX`]: how many edges, how many with a band. A
    /// sensor that invalidated the pixels beside every depth edge would put a band at most
    /// edges of every bin; the projector's shadow alone only where the predicted shadow is
    /// wider than what the matcher fills (docs/NOISE_MODEL.md).
    pub by_shadow: Vec<ShadowBin>,
}

/// Upper edges of the predicted-shadow bins of [`SideBands::by_shadow`], pixels (the last bin
/// is open).
pub const SHADOW_BINS_PX: [f64; 4] = [2.0, 5.0, 10.0, f64::INFINITY];

/// The edges of one side whose predicted projector shadow lies in one bin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ShadowBin {
    /// Upper edge of the bin, pixels (the lower is the previous bin's; `inf` for the last).
    pub upper_px: f64,
    /// Edges in the bin.
    pub edges: usize,
    /// Of them, edges with an invalid band.
    pub with_band: usize,
}

impl ShadowBin {
    /// Share of the bin's edges with a band (NaN without edges).
    pub fn share(&self) -> f64 {
        if self.edges == 0 {
            f64::NAN
        } else {
            self.with_band as f64 / self.edges as f64
        }
    }
}

/// Invalid bands at occlusion edges.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OcclusionBands {
    /// Bands on the left of foreground objects (the background is further left).
    pub left: SideBands,
    /// Bands on the right of foreground objects.
    pub right: SideBands,
}

/// Terrace-width distribution: histogram and summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Terraces {
    /// Summary of the complete runs of equal depth along rows.
    pub widths: WidthStats,
    /// Upper edges of the histogram bins, pixels; `None` for the last bin, which is open (JSON
    /// `null`, Python `None`, as the other open or missing values).
    pub bin_upper_px: Vec<Option<usize>>,
    /// Fraction of runs per bin.
    pub fractions: Vec<f64>,
}

/// Upper edges of the terrace histogram bins, pixels (`None`: the last bin is open).
const TERRACE_BINS: [Option<usize>; 7] =
    [Some(1), Some(2), Some(4), Some(8), Some(16), Some(32), None];

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

/// Residuals of the affine disparity fits (NaN where no residual) — the first step of
/// [`noise_stats`], public for plotting and tests.
#[derive(Debug, Clone, PartialEq)]
pub struct Residuals {
    /// Disparity residual, pixels (NaN outside fitted regions or rejected).
    pub residual: Image<f32>,
    /// Fitted depth `f·B/D_fit`, metres (NaN where no residual).
    pub fitted_z: Image<f32>,
    /// Number of fitted tiles (parts of regions).
    pub regions: usize,
    /// The fitted tile of each pixel (`u32::MAX` where no residual).
    pub tile: Image<u32>,
}

/// Fits each region's disparity, tile by tile, by an affine function of the pixel and returns
/// the residuals. A tile is the part of a region inside one `tile_px`×`tile_px` square of the
/// image; tiles with fewer than `min_tile_pixels` valid pixels are left out. Tiles remove what
/// is not sensor noise at the scale of the statistics: real walls are not perfectly flat, and
/// a Kinect's low-frequency disparity distortion (Herrera et al., Smisek et al.) bends them.
pub fn disparity_residuals(
    depth: &DepthImage,
    fb_px_m: f64,
    regions: &Image<u16>,
    tile_px: usize,
    min_tile_pixels: usize,
) -> Result<Residuals> {
    let (w, h) = (depth.width(), depth.height());
    if regions.width() != w || regions.height() != h {
        return Err(NoiseError::InvalidParameter(format!(
            "region labels are {}x{}, the depth map {w}x{h}",
            regions.width(),
            regions.height()
        )));
    }
    if !(fb_px_m.is_finite() && fb_px_m > 0.0) {
        return Err(NoiseError::InvalidParameter(format!(
            "f·B = {} must be positive",
            sl_core::Compact(fb_px_m)
        )));
    }
    if tile_px == 0 {
        return Err(NoiseError::InvalidParameter(
            "tile_px must be positive".into(),
        ));
    }
    let zs = depth.data();
    let labels = regions.data();
    // Compact keys: one per (label, tile) that occurs, so memory follows the pixels, not the
    // number of labels times the number of tiles.
    let tw = w.div_ceil(tile_px);
    let mut ids: std::collections::HashMap<(u16, usize), u32> = std::collections::HashMap::new();
    let mut pixel_key = vec![u32::MAX; labels.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l == 0 {
            continue;
        }
        let (x, y) = (i % w, i / w);
        let tile = (y / tile_px) * tw + x / tile_px;
        let next = u32::try_from(ids.len()).unwrap_or(u32::MAX);
        pixel_key[i] = *ids.entry((l, tile)).or_insert(next);
    }
    let n_keys = ids.len();
    let key_of = |i: usize| -> Option<usize> {
        let k = pixel_key[i];
        (k != u32::MAX).then_some(k as usize)
    };
    let disp = |i: usize| -> Option<f64> {
        let z = f64::from(zs[i]);
        (z > 0.0 && z.is_finite()).then(|| fb_px_m / z)
    };
    // Pass 0 fits all valid pixels, pass 1 refits without the outliers of pass 0. Coordinates
    // are taken relative to the tile corner to keep the normal equations well conditioned.
    let local = |i: usize| -> (f64, f64) {
        let (x, y) = (i % w, i / w);
        ((x % tile_px) as f64, (y % tile_px) as f64)
    };
    let mut coef: Vec<Option<[f64; 3]>> = vec![None; n_keys];
    let mut cut: Vec<f64> = vec![f64::INFINITY; n_keys];
    let mut fitted = 0;
    for pass in 0..2 {
        let mut ata = vec![[0.0f64; 6]; n_keys];
        let mut atb = vec![[0.0f64; 3]; n_keys];
        let mut n = vec![0usize; n_keys];
        for i in 0..labels.len() {
            let (Some(k), Some(d)) = (key_of(i), disp(i)) else {
                continue;
            };
            let (x, y) = local(i);
            if pass == 1 {
                let Some(c) = coef[k] else { continue };
                if (d - (c[0] * x + c[1] * y + c[2])).abs() > cut[k] {
                    continue;
                }
            }
            let a = &mut ata[k];
            a[0] += x * x;
            a[1] += x * y;
            a[2] += x;
            a[3] += y * y;
            a[4] += y;
            a[5] += 1.0;
            let b = &mut atb[k];
            b[0] += x * d;
            b[1] += y * d;
            b[2] += d;
            n[k] += 1;
        }
        fitted = 0;
        for k in 0..n_keys {
            coef[k] = if n[k] >= min_tile_pixels.max(3) {
                solve3(&ata[k], &atb[k])
            } else {
                None
            };
            if coef[k].is_some() {
                fitted += 1;
            }
        }
        if pass == 0 {
            // Robust scale of each tile's residual: 1.4826·MAD.
            let mut res: Vec<Vec<f64>> = vec![Vec::new(); n_keys];
            for i in 0..labels.len() {
                let (Some(k), Some(d)) = (key_of(i), disp(i)) else {
                    continue;
                };
                if let Some(c) = coef[k] {
                    let (x, y) = local(i);
                    res[k].push((d - (c[0] * x + c[1] * y + c[2])).abs());
                }
            }
            for (k, r) in res.iter_mut().enumerate() {
                if r.is_empty() {
                    continue;
                }
                r.sort_by(f64::total_cmp);
                let mad = quantile_sorted(r, 0.5);
                // At least a quarter of a 1/8-px disparity step, so a tile whose residual is
                // mostly exactly zero keeps its terraces' edges.
                cut[k] = 4.0 * (1.4826 * mad).max(1.0 / 32.0);
            }
        }
    }
    let mut residual = vec![f32::NAN; w * h];
    let mut fitted_z = vec![f32::NAN; w * h];
    let mut tile = vec![u32::MAX; w * h];
    for i in 0..labels.len() {
        let (Some(k), Some(d)) = (key_of(i), disp(i)) else {
            continue;
        };
        let Some(c) = coef[k] else { continue };
        let (x, y) = local(i);
        let fit = c[0] * x + c[1] * y + c[2];
        let r = d - fit;
        if r.abs() <= cut[k] && fit > 0.0 {
            residual[i] = r as f32;
            fitted_z[i] = (fb_px_m / fit) as f32;
            tile[i] = u32::try_from(k).unwrap_or(u32::MAX);
        }
    }
    Ok(Residuals {
        residual: Image::from_vec(w, h, residual)?,
        fitted_z: Image::from_vec(w, h, fitted_z)?,
        regions: fitted,
        tile: Image::from_vec(w, h, tile)?,
    })
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
    let (w, h) = (depth.width(), depth.height());
    let r = res.residual.data();
    let fz = res.fitted_z.data();
    let labels = regions.data();

    let keys = res.tile.data();
    let n_keys = keys
        .iter()
        .filter(|k| **k != u32::MAX)
        .max()
        .map_or(0, |k| *k as usize + 1);

    // σ_D: the RMS residual of each tile; the median over the tiles (of a band, by the tile's
    // mean fitted depth), so a few non-planar tiles (a person, a cushion) do not decide it.
    let mut t_sum2 = vec![0.0f64; n_keys];
    let mut t_z = vec![0.0f64; n_keys];
    let mut t_n = vec![0usize; n_keys];
    let mut pixels = 0usize;
    for ((&ri, &zi), &k) in r.iter().zip(fz).zip(keys) {
        if !ri.is_finite() || k == u32::MAX {
            continue;
        }
        let k = k as usize;
        t_sum2[k] += f64::from(ri) * f64::from(ri);
        t_z[k] += f64::from(zi);
        t_n[k] += 1;
        pixels += 1;
    }
    let nb = opts.band_edges_m.len().saturating_sub(1);
    let mut band_rms: Vec<Vec<f64>> = vec![Vec::new(); nb];
    let mut band_px = vec![0usize; nb];
    let mut all_rms = Vec::new();
    for k in 0..n_keys {
        if t_n[k] < MIN_TILE_RESIDUALS {
            continue;
        }
        let rms = (t_sum2[k] / t_n[k] as f64).sqrt();
        all_rms.push(rms);
        let z = t_z[k] / t_n[k] as f64;
        if let Some(b) = opts
            .band_edges_m
            .windows(2)
            .position(|e| z >= e[0] && z < e[1])
        {
            band_rms[b].push(rms);
            band_px[b] += t_n[k];
        }
    }
    let median = |mut v: Vec<f64>| {
        v.retain(|x| x.is_finite());
        v.sort_by(f64::total_cmp);
        quantile_sorted(&v, 0.5)
    };
    let bands = opts
        .band_edges_m
        .windows(2)
        .enumerate()
        .map(|(b, e)| BandSigma {
            z_lo_m: e[0],
            z_hi_m: e[1],
            pixels: band_px[b],
            tiles: band_rms[b].len(),
            sigma_d_px: median(band_rms[b].clone()),
        })
        .collect();

    // Autocorrelation: per tile (pairs inside one tile), then the median over tiles.
    let corr = |dx: usize, dy: usize| -> (f64, usize) {
        let mut acc = vec![[0.0f64; 3]; n_keys];
        let mut cnt = vec![0usize; n_keys];
        for y in 0..h.saturating_sub(dy) {
            for x in 0..w.saturating_sub(dx) {
                let i = y * w + x;
                let j = (y + dy) * w + x + dx;
                let k = keys[i];
                if k == u32::MAX || keys[j] != k {
                    continue;
                }
                let (a, b) = (f64::from(r[i]), f64::from(r[j]));
                let t = &mut acc[k as usize];
                t[0] += a * b;
                t[1] += a * a;
                t[2] += b * b;
                cnt[k as usize] += 1;
            }
        }
        let mut cs = Vec::new();
        let mut pairs = 0;
        for (t, &n) in acc.iter().zip(&cnt) {
            let floor = n as f64 * MIN_CORRELATED_RMS_PX * MIN_CORRELATED_RMS_PX;
            if n >= MIN_TILE_RESIDUALS && t[1] > floor && t[2] > floor {
                cs.push(t[0] / (t[1] * t[2]).sqrt());
                pairs += n;
            }
        }
        (median(cs), pairs)
    };
    let acf = opts
        .lags
        .iter()
        .map(|&lag| {
            let (x, pairs_x) = corr(lag, 0);
            let (y, pairs_y) = corr(0, lag);
            LagCorrelation {
                lag,
                x,
                y,
                pairs_x,
                pairs_y,
            }
        })
        .collect();

    // Terraces: complete runs of equal depth along rows inside one fitted region.
    let zs = depth.data();
    let mut runs = Vec::new();
    for y in 0..h {
        let row = y * w;
        let mut x = 0;
        while x < w {
            let i = row + x;
            if !r[i].is_finite() {
                x += 1;
                continue;
            }
            let mut e = x + 1;
            while e < w
                && r[row + e].is_finite()
                && labels[row + e] == labels[i]
                && zs[row + e] == zs[i]
            {
                e += 1;
            }
            // Complete when bounded by a different depth of the same tile on both sides.
            let left_ok =
                x > 0 && r[i - 1].is_finite() && labels[i - 1] == labels[i] && zs[i - 1] != zs[i];
            let right_ok = e < w
                && r[row + e].is_finite()
                && labels[row + e] == labels[i]
                && zs[row + e] != zs[i];
            if left_ok && right_ok {
                runs.push((e - x) as f64);
            }
            x = e;
        }
    }
    let mut counts = [0usize; TERRACE_BINS.len()];
    for &wd in &runs {
        let b = TERRACE_BINS
            .iter()
            .position(|u| u.is_none_or(|u| wd as usize <= u))
            .unwrap_or(TERRACE_BINS.len() - 1);
        counts[b] += 1;
    }
    let total = runs.len().max(1) as f64;
    let terraces = Terraces {
        widths: WidthStats::from_widths(runs),
        bin_upper_px: TERRACE_BINS.to_vec(),
        fractions: counts.iter().map(|c| *c as f64 / total).collect(),
    };

    let occlusion = occlusion_bands(
        depth,
        fb_px_m * opts.pixels_per_sensor_pixel,
        opts.jump_m,
        opts.max_band_px,
    );
    let invalid = zs.iter().filter(|z| !(**z > 0.0 && z.is_finite())).count();
    Ok(NoiseStats {
        regions: res.regions,
        pixels,
        sigma_d_px: median(all_rms),
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

/// The invalid bands at occlusion edges, per row (see the module documentation).
pub fn occlusion_bands(
    depth: &DepthImage,
    fb_px_m: f64,
    jump_m: f64,
    max_band_px: usize,
) -> OcclusionBands {
    let (w, h) = (depth.width(), depth.height());
    let zs = depth.data();
    let valid = |z: f32| z > 0.0 && z.is_finite();
    let (mut lw, mut ls, mut ld) = (Vec::new(), Vec::new(), 0usize);
    let (mut rw, mut rs, mut rd) = (Vec::new(), Vec::new(), 0usize);
    let bins = || {
        SHADOW_BINS_PX.map(|upper_px| ShadowBin {
            upper_px,
            edges: 0,
            with_band: 0,
        })
    };
    let (mut lbins, mut rbins) = (bins(), bins());
    let count = |bins: &mut [ShadowBin; SHADOW_BINS_PX.len()], shadow: f64, band: bool| {
        let i = SHADOW_BINS_PX
            .iter()
            .position(|u| shadow < *u)
            .unwrap_or(SHADOW_BINS_PX.len() - 1);
        bins[i].edges += 1;
        bins[i].with_band += usize::from(band);
    };
    let (mut lf, mut lb, mut rf, mut rb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for y in 0..h {
        let row = &zs[y * w..(y + 1) * w];
        let mut prev: Option<usize> = None;
        for (x, &z) in row.iter().enumerate() {
            if !valid(z) {
                continue;
            }
            if let Some(p) = prev {
                let (za, zb) = (f64::from(row[p]), f64::from(z));
                let run = x - p - 1;
                if run <= max_band_px {
                    let shadow = fb_px_m * (1.0 / za.min(zb) - 1.0 / za.max(zb));
                    if zb - za > jump_m {
                        // Foreground on the left: the band lies on its right.
                        count(&mut rbins, shadow, run > 0);
                        if run == 0 {
                            rd += 1;
                        } else {
                            rw.push(run as f64);
                            rs.push(shadow);
                            rf.push(za);
                            rb.push(zb);
                        }
                    } else if za - zb > jump_m {
                        count(&mut lbins, shadow, run > 0);
                        if run == 0 {
                            ld += 1;
                        } else {
                            lw.push(run as f64);
                            ls.push(shadow);
                            lf.push(zb);
                            lb.push(za);
                        }
                    }
                }
            }
            prev = Some(x);
        }
    }
    let med = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        quantile_sorted(&v, 0.5)
    };
    let side = |widths: Vec<f64>,
                shadows: Vec<f64>,
                direct: usize,
                fg: Vec<f64>,
                bg: Vec<f64>,
                bins: [ShadowBin; SHADOW_BINS_PX.len()]| SideBands {
        widths: WidthStats::from_widths(widths),
        median_shadow_px: med(shadows),
        direct_edges: direct,
        median_fg_m: med(fg),
        median_bg_m: med(bg),
        by_shadow: bins.to_vec(),
    };
    OcclusionBands {
        left: side(lw, ls, ld, lf, lb, lbins),
        right: side(rw, rs, rd, rf, rb, rbins),
    }
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

/// Solves the symmetric 3×3 system `[a0 a1 a2; a1 a3 a4; a2 a4 a5]·c = b`.
fn solve3(a: &[f64; 6], b: &[f64; 3]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::new(a[0], a[1], a[2], a[1], a[3], a[4], a[2], a[4], a[5]);
    let v = nalgebra::Vector3::new(b[0], b[1], b[2]);
    let c = m.lu().solve(&v)?;
    c.iter().all(|x| x.is_finite()).then(|| [c[0], c[1], c[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fronto-parallel plane at disparity `d0` with a checkerboard residual `±a` px.
    fn checker(w: usize, h: usize, fb: f64, d0: f64, a: f64) -> DepthImage {
        let data = (0..w * h)
            .map(|i| {
                let s = if (i % w + i / w).is_multiple_of(2) {
                    a
                } else {
                    -a
                };
                (fb / (d0 + s)) as f32
            })
            .collect();
        DepthImage::from_vec(w, h, data).unwrap()
    }

    #[test]
    fn checkerboard_residual_sigma_and_correlation() {
        let (w, h, fb) = (128, 128, 43.5);
        let depth = checker(w, h, fb, 20.0, 0.05);
        let labels = Image::filled(w, h, 1u16);
        let s = noise_stats(&depth, fb, &labels, &NoiseStatsConfig::default()).unwrap();
        assert!((s.sigma_d_px - 0.05).abs() < 1e-4, "{}", s.sigma_d_px);
        let (x1, y1) = s.acf_at(1).unwrap();
        let (x2, y2) = s.acf_at(2).unwrap();
        assert!(x1 < -0.99 && y1 < -0.99, "{x1} {y1}");
        assert!(x2 > 0.99 && y2 > 0.99, "{x2} {y2}");
        // Depth ≈ 2.175 m: the band 2.0–2.5 m holds every tile.
        let band = s.bands.iter().find(|b| b.z_lo_m == 2.0).unwrap();
        assert_eq!(band.tiles, 4);
        assert_eq!(band.pixels, w * h);
        // Every pixel differs from its neighbours: all terraces are 1 px wide.
        assert_eq!(s.terraces.widths.median_px, 1.0);
        assert_eq!(s.terraces.fractions[0], 1.0);
        // The open last bin has no upper edge (it printed as 2⁶⁴ − 1 in JSON and Python).
        assert_eq!(s.terraces.bin_upper_px.last(), Some(&None));
        assert_eq!(s.terraces.bin_upper_px[..2], [Some(1), Some(2)]);
    }

    /// A noise-free plane has no noise to correlate: no autocorrelation (NaN), where the float
    /// rounding of its residual used to report 0.97–1.00.
    #[test]
    fn a_noise_free_plane_has_no_autocorrelation() {
        let (w, h, fb) = (128, 128, 43.5);
        // A tilted plane: its residual is the rounding of `f32` depths, not zero.
        let data = (0..w * h)
            .map(|i| (fb / (20.0 + 0.01 * (i % w) as f64 + 0.003 * (i / w) as f64)) as f32)
            .collect();
        let depth = DepthImage::from_vec(w, h, data).unwrap();
        let labels = Image::filled(w, h, 1u16);
        let s = noise_stats(&depth, fb, &labels, &NoiseStatsConfig::default()).unwrap();
        assert!(
            s.sigma_d_px > 0.0 && s.sigma_d_px < 1e-4,
            "{}",
            s.sigma_d_px
        );
        let (x1, y1) = s.acf_at(1).unwrap();
        assert!(x1.is_nan() && y1.is_nan(), "{x1} {y1}");
    }

    #[test]
    fn occlusion_bands_by_side() {
        // A board at 1 m over x in 30..50, a wall at 2 m; 6 invalid pixels left of the board,
        // 2 on its right, in every row.
        let (w, h) = (80, 10);
        let mut data = vec![2.0f32; w * h];
        for y in 0..h {
            for x in 30..50 {
                data[y * w + x] = 1.0;
            }
            for x in 24..30 {
                data[y * w + x] = 0.0;
            }
            for x in 50..52 {
                data[y * w + x] = 0.0;
            }
        }
        let depth = DepthImage::from_vec(w, h, data).unwrap();
        let b = occlusion_bands(&depth, 43.5, 0.15, 64);
        assert_eq!(b.left.widths.count, h);
        assert_eq!(b.left.widths.median_px, 6.0);
        assert_eq!(b.right.widths.median_px, 2.0);
        assert!((b.left.median_shadow_px - 21.75).abs() < 1e-9);
        assert_eq!((b.left.median_fg_m, b.left.median_bg_m), (1.0, 2.0));
        assert_eq!(b.left.direct_edges + b.right.direct_edges, 0);
        // Every edge predicts a 21.75-px shadow: all in the open bin, all with a band.
        for side in [&b.left, &b.right] {
            let bins: Vec<(usize, usize)> = side
                .by_shadow
                .iter()
                .map(|b| (b.edges, b.with_band))
                .collect();
            assert_eq!(bins, vec![(0, 0), (0, 0), (0, 0), (h, h)]);
        }
        assert_eq!(b.left.by_shadow[3].share(), 1.0);
        assert!(b.left.by_shadow[0].share().is_nan());
        // A far, small jump (2.0 / 2.3 m: a 2.8-px shadow) with no band in half the rows: the
        // second bin, half of its edges with a band.
        let mut far = vec![2.3f32; w * h];
        for y in 0..h {
            for x in 30..50 {
                far[y * w + x] = 2.0;
            }
            if y % 2 == 0 {
                far[y * w + 29] = 0.0;
            }
        }
        let f = occlusion_bands(&DepthImage::from_vec(w, h, far).unwrap(), 43.5, 0.15, 64);
        assert_eq!(
            (f.left.by_shadow[1].edges, f.left.by_shadow[1].with_band),
            (h, h / 2)
        );
        assert_eq!(f.left.direct_edges, h / 2);
        assert_eq!(
            (f.right.by_shadow[1].edges, f.right.by_shadow[1].with_band),
            (h, 0)
        );
        // A smaller jump than the threshold is no occlusion edge.
        let none = occlusion_bands(&depth, 43.5, 1.5, 64);
        assert_eq!(none.left.widths.count + none.right.widths.count, 0);
        // The same frame read as the sensor decimated by 2: the predicted shadow (a disparity
        // in sensor pixels) is reported in the image's pixels, as the widths are.
        let labels = Image::filled(w, h, 0u16);
        let mut opts = NoiseStatsConfig {
            pixels_per_sensor_pixel: 0.5,
            ..NoiseStatsConfig::default()
        };
        let s = noise_stats(&depth, 43.5, &labels, &opts).unwrap();
        assert!((s.occlusion.left.median_shadow_px - 21.75 / 2.0).abs() < 1e-9);
        assert_eq!(s.occlusion.left.widths.median_px, 6.0);
        opts.pixels_per_sensor_pixel = 0.0;
        assert!(noise_stats(&depth, 43.5, &labels, &opts).is_err());
    }

    #[test]
    fn bad_inputs_are_errors() {
        let depth = checker(16, 16, 43.5, 20.0, 0.0);
        let wrong = Image::filled(8, 8, 1u16);
        assert!(noise_stats(&depth, 43.5, &wrong, &NoiseStatsConfig::default()).is_err());
        let labels = Image::filled(16, 16, 1u16);
        assert!(noise_stats(&depth, -1.0, &labels, &NoiseStatsConfig::default()).is_err());
        let o = NoiseStatsConfig {
            tile_px: 0,
            ..NoiseStatsConfig::default()
        };
        assert!(noise_stats(&depth, 43.5, &labels, &o).is_err());
        assert!(matches!(o.validate(), Err(NoiseError::InvalidParameter(_))));
        assert!(NoiseStatsConfig::default().validate().is_ok());
        // Too small to fit: no tiles, NaN statistics, no panic.
        let s = noise_stats(&depth, 43.5, &labels, &NoiseStatsConfig::default()).unwrap();
        assert_eq!(s.regions, 0);
        assert!(s.sigma_d_px.is_nan());
    }
}
