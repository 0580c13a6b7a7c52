//! The first step of the statistics: each region's disparity fitted tile by tile by an affine
//! function of the pixel, and the residuals ([`disparity_residuals`]).

use sl_core::{DepthImage, Image};

use super::quantile_sorted;
use crate::error::{NoiseError, Result};

/// Residuals of the affine disparity fits (NaN where no residual) — the first step of
/// [`noise_stats`](super::noise_stats), public for plotting and tests.
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

/// Solves the symmetric 3×3 system `[a0 a1 a2; a1 a3 a4; a2 a4 a5]·c = b`.
fn solve3(a: &[f64; 6], b: &[f64; 3]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::new(a[0], a[1], a[2], a[1], a[3], a[4], a[2], a[4], a[5]);
    let v = nalgebra::Vector3::new(b[0], b[1], b[2]);
    let c = m.lu().solve(&v)?;
    c.iter().all(|x| x.is_finite()).then(|| [c[0], c[1], c[2]])
}
