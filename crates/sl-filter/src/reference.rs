//! A straightforward, slow implementation of every filter (per pixel, `f64`, the window clipped
//! at the border), kept as the executable specification the fast kernel is tested against. The
//! Gaussian's weights are `f64::exp`; the range filters' joint weight `w_s·w_d = 2^x` is the
//! log-linear `2^x` of the fast kernels (the crate docs' *Speed*: within 3 % of `2^x` down to
//! `2^−126`, 0 below `2^−127`), evaluated in `f64`. Invalid neighbours, which the fast paths
//! weigh 0, are left out.

use sl_core::DepthImage;

use crate::error::Result;
use crate::filter::{DepthFilter, RangeKernel};
use crate::weight::weight_f64;

/// Filters `depth` with `filter` the slow way. Same semantics as [`DepthFilter::apply`]:
/// `Ẑ(p) = Σ_q w_s(q−p)·w_d(q, p)·v(q) / Σ_q w_s·w_d` over the valid `q` of the window clipped
/// to the image, with `v = Z` (or `D = fb/Z` for the disparity variant, converted back), and 0
/// where the input is invalid.
pub fn filter_reference(filter: &DepthFilter, depth: &DepthImage) -> Result<DepthImage> {
    filter.validate()?;
    let (w, h) = (depth.width(), depth.height());
    let r = filter.radius_px as i64;
    let ss = filter.sigma_s_px;
    let value = |z: f32| -> f64 {
        match filter.range {
            RangeKernel::Disparity { fb_px_m, .. } => fb_px_m / f64::from(z),
            _ => f64::from(z),
        }
    };
    let valid = |z: f32| z > 0.0 && z.is_finite();
    let src = depth.data();
    let mut out = vec![0.0f32; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let zp = src[(y as usize) * w + x as usize];
            if !valid(zp) {
                continue;
            }
            let vp = value(zp);
            let sigma_range = match filter.range {
                RangeKernel::None => f64::INFINITY,
                RangeKernel::Fixed { sigma_d_m } => sigma_d_m,
                RangeKernel::Adaptive { k_per_m } => k_per_m * vp * vp,
                RangeKernel::Disparity { sigma_disp_px, .. } => sigma_disp_px,
            };
            let (mut sw, mut swv) = (0.0f64, 0.0f64);
            for qy in (y - r).max(0)..=(y + r).min(h as i64 - 1) {
                for qx in (x - r).max(0)..=(x + r).min(w as i64 - 1) {
                    let zq = src[(qy as usize) * w + qx as usize];
                    if !valid(zq) {
                        continue;
                    }
                    if !filter.window.contains(qx - x, qy - y, r) {
                        continue;
                    }
                    let vq = value(zq);
                    let d2s = ((qx - x) * (qx - x) + (qy - y) * (qy - y)) as f64;
                    let w = if sigma_range.is_finite() {
                        // log2 of the Gaussian spatial weight and of the Gaussian range weight.
                        let log2e = std::f64::consts::LOG2_E;
                        let t = -d2s / (2.0 * ss * ss) * log2e;
                        let e2 = (vq - vp) * (vq - vp) / (2.0 * sigma_range * sigma_range) * log2e;
                        weight_f64(t, e2)
                    } else {
                        (-d2s / (2.0 * ss * ss)).exp()
                    };
                    sw += w;
                    swv += w * vq;
                }
            }
            let v = swv / sw;
            out[(y as usize) * w + x as usize] = match filter.range {
                RangeKernel::Disparity { fb_px_m, .. } => (fb_px_m / v) as f32,
                _ => v as f32,
            };
        }
    }
    Ok(DepthImage::from_vec(w, h, out)?)
}
