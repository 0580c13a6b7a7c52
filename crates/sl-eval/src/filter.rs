//! Evaluation metrics for depth filters (used by `cargo xtask validate` and the `sl-filter`
//! tests): RMSE against ground truth per depth band, depth-edge masks, and plane-fit residuals
//! on a robustly chosen planar region of a real frame.

use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{DepthImage, Intrinsics};

use crate::error::{EvalError, Result};

mod regions;
pub use regions::{
    MIN_REGION_PIXELS, MIN_REGION_SHARE, PlaneRegion, RegionSearch, dominant_plane_region,
    plane_regions,
};

/// The depth bands of the evaluation, metres: `< 1.5`, `1.5–2.5`, `> 2.5`.
pub const KINECT_BANDS_M: [(f32, f32); 3] = [(0.0, 1.5), (1.5, 2.5), (2.5, f32::INFINITY)];

/// An error statistic over the pixels of one depth band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandError {
    /// Lower band limit (inclusive), metres.
    pub lo_m: f32,
    /// Upper band limit (exclusive), metres.
    pub hi_m: f32,
    /// Number of pixels in the band.
    pub pixels: usize,
    /// Root-mean-square error, metres (NaN when the band is empty).
    pub rmse_m: f64,
}

/// Turns per-band `(pixel count, sum of squared errors)` into [`BandError`]s.
fn band_errors(bands: &[(f32, f32)], acc: &[(usize, f64)]) -> Vec<BandError> {
    bands
        .iter()
        .zip(acc)
        .map(|(&(lo_m, hi_m), &(n, s))| BandError {
            lo_m,
            hi_m,
            pixels: n,
            rmse_m: if n > 0 {
                (s / n as f64).sqrt()
            } else {
                f64::NAN
            },
        })
        .collect()
}

fn valid(z: f32) -> bool {
    z > 0.0 && z.is_finite()
}

fn same_size(a: &DepthImage, b: &DepthImage) -> Result<()> {
    if a.width() != b.width() || a.height() != b.height() {
        return Err(EvalError::ImageSize(format!(
            "{}x{} vs {}x{}",
            a.width(),
            a.height(),
            b.width(),
            b.height()
        )));
    }
    Ok(())
}

/// RMSE of `estimate` against `truth` per depth band of the *true* depth, over the pixels valid
/// in both (and inside `mask` when given). The filters keep the input's valid mask, so every
/// method is scored on the same pixels.
pub fn rmse_by_band(
    estimate: &DepthImage,
    truth: &DepthImage,
    mask: Option<&[bool]>,
    bands: &[(f32, f32)],
) -> Result<Vec<BandError>> {
    same_size(estimate, truth)?;
    let mut acc = vec![(0usize, 0.0f64); bands.len()];
    for (i, (&e, &t)) in estimate.data().iter().zip(truth.data()).enumerate() {
        if !(valid(e) && valid(t)) || mask.is_some_and(|m| !m.get(i).copied().unwrap_or(false)) {
            continue;
        }
        if let Some(b) = bands.iter().position(|&(lo, hi)| t >= lo && t < hi) {
            let d = f64::from(e) - f64::from(t);
            acc[b].0 += 1;
            acc[b].1 += d * d;
        }
    }
    Ok(band_errors(bands, &acc))
}

/// RMSE over all bands together (pooled pixels), metres, and the pixel count.
pub fn pooled(bands: &[BandError]) -> (f64, usize) {
    let n: usize = bands.iter().map(|b| b.pixels).sum();
    let s: f64 = bands
        .iter()
        .filter(|b| b.pixels > 0)
        .map(|b| b.rmse_m * b.rmse_m * b.pixels as f64)
        .sum();
    (
        if n > 0 {
            (s / n as f64).sqrt()
        } else {
            f64::NAN
        },
        n,
    )
}

/// Pixels within `radius_px` (Chebyshev distance) of a true depth edge: a pair of 4-neighbours,
/// both valid in `truth`, whose depths differ by more than `rel_jump` times the nearer one
/// (5 % is a good choice: far above the depth change between neighbours on any surface the
/// Kinect sees at less than ~80° incidence, far below the jumps at occluding contours).
pub fn depth_edge_mask(truth: &DepthImage, rel_jump: f32, radius_px: usize) -> Vec<bool> {
    let (w, h) = (truth.width(), truth.height());
    let z = truth.data();
    let mut edge = vec![false; w * h];
    let jump = |a: f32, b: f32| valid(a) && valid(b) && (a - b).abs() > rel_jump * a.min(b);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w && jump(z[i], z[i + 1]) {
                edge[i] = true;
                edge[i + 1] = true;
            }
            if y + 1 < h && jump(z[i], z[i + w]) {
                edge[i] = true;
                edge[i + w] = true;
            }
        }
    }
    dilate(&edge, w, h, radius_px)
}

/// Binary dilation with a `(2r+1)²` square.
pub fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    morph(mask, w, h, r, true)
}

/// Binary erosion with a `(2r+1)²` square (outside the image counts as `false`).
pub fn erode(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    morph(mask, w, h, r, false)
}

fn morph(mask: &[bool], w: usize, h: usize, r: usize, dilate: bool) -> Vec<bool> {
    if r == 0 {
        return mask.to_vec();
    }
    // Separable: rows, then columns.
    let pass = |src: &[bool], horizontal: bool| -> Vec<bool> {
        let mut out = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let (c, n) = if horizontal { (x, w) } else { (y, h) };
                let lo = c.saturating_sub(r);
                let hi = (c + r).min(n - 1);
                let at = |t: usize| {
                    if horizontal {
                        src[y * w + t]
                    } else {
                        src[t * w + x]
                    }
                };
                let inside = c >= r && c + r < n;
                out[y * w + x] = if dilate {
                    (lo..=hi).any(at)
                } else {
                    inside && (lo..=hi).all(at)
                };
            }
        }
        out
    };
    let a = pass(mask, true);
    pass(&a, false)
}

/// Plane-fit residual of `depth` on `mask`, per depth band: a least-squares plane is fitted to
/// the masked points of this (filtered) frame, and the RMS orthogonal distance of the points to
/// it is reported per band of their depth. Each frame gets its own fit, so a filter is judged on
/// how flat it leaves the surface, not on how it moves it.
pub fn plane_residual_by_band(
    depth: &DepthImage,
    k: &Intrinsics,
    mask: &[bool],
    bands: &[(f32, f32)],
) -> Result<Vec<BandError>> {
    depth.as_image().check_size(k)?;
    let (w, h) = (depth.width(), depth.height());
    let z = depth.data();
    let idx: Vec<usize> = (0..w * h)
        .filter(|&i| mask.get(i).copied().unwrap_or(false) && valid(z[i]))
        .collect();
    let pts: Vec<Point3<f64>> = idx
        .iter()
        .map(|&i| {
            let (x, y, d) = ((i % w) as f64, (i / w) as f64, f64::from(z[i]));
            Point3::new((x - k.cx) / k.fx * d, (y - k.cy) / k.fy * d, d)
        })
        .collect();
    let mut acc = vec![(0usize, 0.0f64); bands.len()];
    if let Some(fit) = sl_core::fit_plane(&pts) {
        let plane = fit.plane;
        for p in &pts {
            let d = p.z as f32;
            if let Some(b) = bands.iter().position(|&(lo, hi)| d >= lo && d < hi) {
                let r = plane.signed_distance_m(p);
                acc[b].0 += 1;
                acc[b].1 += r * r;
            }
        }
    }
    Ok(band_errors(bands, &acc))
}

/// [`plane_residual_by_band`] over several planar regions, pooled: each region gets its own
/// least-squares plane, and the squared distances of all regions are pooled per depth band.
pub fn plane_residual_by_band_pooled(
    depth: &DepthImage,
    k: &Intrinsics,
    regions: &[PlaneRegion],
    bands: &[(f32, f32)],
) -> Result<Vec<BandError>> {
    let mut acc = vec![(0usize, 0.0f64); bands.len()];
    for r in regions {
        for (a, b) in acc
            .iter_mut()
            .zip(plane_residual_by_band(depth, k, &r.mask, bands)?)
        {
            if b.pixels > 0 {
                a.0 += b.pixels;
                a.1 += b.rmse_m * b.rmse_m * b.pixels as f64;
            }
        }
    }
    Ok(band_errors(bands, &acc))
}

/// The spread of surface normals over the pixels of one depth band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandSpread {
    /// Lower band limit (inclusive), metres.
    pub lo_m: f32,
    /// Upper band limit (exclusive), metres.
    pub hi_m: f32,
    /// Number of pixels with a normal in the band.
    pub pixels: usize,
    /// RMS angle between the pixel normals and `reference`, degrees (NaN when empty).
    pub rms_deg: f64,
}

/// Spread of the surface normals of `depth` on `mask` around the plane normal `reference`, per
/// depth band: the normal at a pixel is the cross product of the central differences of the
/// back-projected points `step_px` pixels left/right and up/down (all four valid and within 5 %
/// of the centre's depth, else the pixel is skipped), and the RMS of its angle to `reference`
/// (sign-agnostic) is reported. This is what a shaded-normal rendering shows: it differentiates
/// the depth, so it sees the fine-scale noise a plane residual mixes with the surface's shape.
pub fn normal_spread_by_band(
    depth: &DepthImage,
    k: &Intrinsics,
    mask: &[bool],
    reference: &Vector3<f64>,
    step_px: usize,
    bands: &[(f32, f32)],
) -> Result<Vec<BandSpread>> {
    depth.as_image().check_size(k)?;
    let (w, h) = (depth.width(), depth.height());
    let z = depth.data();
    let s = step_px.max(1);
    let rn = reference.norm();
    let mut acc = vec![(0usize, 0.0f64); bands.len()];
    let point = |x: usize, y: usize| -> Vector3<f64> {
        let d = f64::from(z[y * w + x]);
        Vector3::new(
            (x as f64 - k.cx) / k.fx * d,
            (y as f64 - k.cy) / k.fy * d,
            d,
        )
    };
    if rn > 0.0 && rn.is_finite() {
        for y in s..h.saturating_sub(s) {
            for x in s..w.saturating_sub(s) {
                let i = y * w + x;
                let c = z[i];
                if !mask.get(i).copied().unwrap_or(false) || !valid(c) {
                    continue;
                }
                let nb = [i - s, i + s, i - s * w, i + s * w];
                if nb
                    .iter()
                    .any(|&j| !valid(z[j]) || (z[j] - c).abs() > 0.05 * c)
                {
                    continue;
                }
                let u = point(x + s, y) - point(x - s, y);
                let v = point(x, y + s) - point(x, y - s);
                let n = u.cross(&v);
                let len = n.norm();
                if !(len > 0.0 && len.is_finite()) {
                    continue;
                }
                let cos = (n.dot(reference).abs() / (len * rn)).min(1.0);
                if let Some(b) = bands.iter().position(|&(lo, hi)| c >= lo && c < hi) {
                    let a = cos.acos().to_degrees();
                    acc[b].0 += 1;
                    acc[b].1 += a * a;
                }
            }
        }
    }
    Ok(bands
        .iter()
        .zip(&acc)
        .map(|(&(lo_m, hi_m), &(pixels, ss))| BandSpread {
            lo_m,
            hi_m,
            pixels,
            rms_deg: if pixels > 0 {
                (ss / pixels as f64).sqrt()
            } else {
                f64::NAN
            },
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::regions::splitmix;
    use super::*;
    use sl_core::SensorModel;

    #[test]
    fn normal_spread_of_a_tilted_plane_is_zero() {
        let k = Intrinsics::new(40, 30, 50.0, 50.0, 20.0, 15.0).unwrap();
        // 1/Z affine in the pixel coordinates: a 3D plane.
        let d: Vec<f32> = (0..40 * 30)
            .map(|i| 1.0 / (0.4 + 0.004 * (i % 40) as f32 + 0.002 * (i / 40) as f32))
            .collect();
        let depth = DepthImage::from_vec(40, 30, d).unwrap();
        let mask = vec![true; 40 * 30];
        let p = |x: f64, y: f64| {
            let z = 1.0 / (0.4 + 0.004 * x + 0.002 * y);
            Vector3::new((x - 20.0) / 50.0 * z, (y - 15.0) / 50.0 * z, z)
        };
        let n = (p(30.0, 10.0) - p(10.0, 10.0)).cross(&(p(10.0, 20.0) - p(10.0, 10.0)));
        let b = normal_spread_by_band(&depth, &k, &mask, &n, 1, &[(0.0, 100.0)]).unwrap();
        assert!(b[0].pixels > 500 && b[0].rms_deg < 0.05, "{b:?}");
    }

    #[test]
    fn rmse_bands_use_the_true_depth() {
        let truth = DepthImage::from_vec(4, 1, vec![1.0, 2.0, 3.0, 0.0]).unwrap();
        let est = DepthImage::from_vec(4, 1, vec![1.1, 2.0, 2.8, 5.0]).unwrap();
        let b = rmse_by_band(&est, &truth, None, &KINECT_BANDS_M).unwrap();
        assert_eq!(
            b.iter().map(|b| b.pixels).collect::<Vec<_>>(),
            vec![1, 1, 1]
        );
        assert!(
            (b[0].rmse_m - 0.1).abs() < 1e-6
                && b[1].rmse_m == 0.0
                && (b[2].rmse_m - 0.2).abs() < 1e-6
        );
        let (all, n) = pooled(&b);
        assert_eq!(n, 3);
        assert!((all - ((0.01 + 0.04) / 3.0f64).sqrt()).abs() < 1e-6);
        let masked = rmse_by_band(
            &est,
            &truth,
            Some(&[false, true, true, true]),
            &KINECT_BANDS_M,
        )
        .unwrap();
        assert_eq!(masked[0].pixels, 0);
        assert!(masked[0].rmse_m.is_nan());
    }

    #[test]
    fn edge_mask_marks_jumps_not_slopes() {
        // A steep ramp (2 % per pixel) with a 50 % step in the middle.
        let w = 20;
        let data: Vec<f32> = (0..w * 5)
            .map(|i| 1.0 + 0.02 * (i % w) as f32 + if i % w >= 10 { 1.0 } else { 0.0 })
            .collect();
        let d = DepthImage::from_vec(w, 5, data).unwrap();
        let m = depth_edge_mask(&d, 0.05, 2);
        for x in 0..w {
            assert_eq!(m[2 * w + x], (7..=12).contains(&x), "x = {x}");
        }
    }

    #[test]
    fn morphology() {
        let mut m = vec![false; 49];
        m[24] = true;
        let d = dilate(&m, 7, 7, 1);
        assert_eq!(d.iter().filter(|&&v| v).count(), 9);
        assert_eq!(erode(&d, 7, 7, 1), m);
        assert!(erode(&[true; 49], 7, 7, 1)[0..7].iter().all(|&v| !v));
    }

    #[test]
    fn plane_fit_and_region_on_a_noisy_floor() {
        let k = Intrinsics::new(160, 120, 145.0, 145.0, 79.5, 59.5).unwrap();
        let sensor = SensorModel::kinect_v1();
        // Plane n·X = 1 with n tilted 60° from the optical axis, plus ±2 mm noise, and a box
        // (a 0.5 m closer rectangle) that must be excluded from the region.
        let n = [0.0, -(60f64.to_radians().sin()), 60f64.to_radians().cos()];
        let mut state = 7u64;
        let data: Vec<f32> = (0..160 * 120)
            .map(|i| {
                let (x, y) = ((i % 160) as f64, (i / 160) as f64);
                let r = k.ray(x, y);
                let z = 1.0 / (n[0] * r.x + n[1] * r.y + n[2] * r.z);
                let noise = (splitmix(&mut state) % 1000) as f64 / 1000.0 * 0.004 - 0.002;
                let boxed = (60..90).contains(&(i % 160)) && (70..100).contains(&(i / 160));
                if boxed {
                    (z - 0.5) as f32
                } else {
                    (z + noise) as f32
                }
            })
            .collect();
        let d = DepthImage::from_vec(160, 120, data).unwrap();
        let region = dominant_plane_region(&d, &k, &sensor, 3, 200, 1)
            .unwrap()
            .unwrap();
        let dot: f64 = region.plane.normal.iter().zip(&n).map(|(a, b)| a * b).sum();
        assert!(dot.abs() > 0.999, "{:?}", region.plane);
        assert!(!region.mask[85 * 160 + 75], "the box is not in the region");
        assert!(region.mask[20 * 160 + 20]);
        let res = plane_residual_by_band(&d, &k, &region.mask, &[(0.0, f32::INFINITY)]).unwrap();
        // Uniform ±2 mm noise along Z has an RMS of 1.15 mm, seen at 60° from the normal.
        assert!(
            res[0].rmse_m > 0.0003 && res[0].rmse_m < 0.0012,
            "{:?}",
            res[0]
        );
    }
}
