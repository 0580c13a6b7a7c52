//! σ_D per depth band: the RMS residual of each fitted tile, the median over a band's tiles.

use serde::Serialize;

use super::{MIN_TILE_RESIDUALS, Residuals, median};

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

/// σ_D per depth band: the RMS residual of each tile, the median over the tiles of a band (by
/// the tile's mean fitted depth), so a few non-planar tiles (a person, a cushion) do not decide
/// it. Returns the bands, the median over all tiles and the number of residual pixels.
pub(super) fn band_sigmas(
    res: &Residuals,
    n_keys: usize,
    band_edges_m: &[f64],
) -> (Vec<BandSigma>, f64, usize) {
    let r = res.residual.data();
    let fz = res.fitted_z.data();
    let keys = res.tile.data();
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
    let nb = band_edges_m.len().saturating_sub(1);
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
        if let Some(b) = band_edges_m.windows(2).position(|e| z >= e[0] && z < e[1]) {
            band_rms[b].push(rms);
            band_px[b] += t_n[k];
        }
    }
    let bands = band_edges_m
        .windows(2)
        .zip(band_rms)
        .zip(band_px)
        .map(|((e, rms), pixels)| BandSigma {
            z_lo_m: e[0],
            z_hi_m: e[1],
            pixels,
            tiles: rms.len(),
            sigma_d_px: median(rms),
        })
        .collect();
    (bands, median(all_rms), pixels)
}
