//! Baseline: sequential RANSAC with a fixed metric point-to-plane threshold, as Open3D's
//! `segment_plane` applied repeatedly (the usual way to get several planes with it).
//!
//! Each round samples three points among the remaining ones, scores the hypothesis on a random
//! subset, takes the best, collects all remaining points within `threshold_m`, refits by PCA
//! (least squares), re-collects the inliers, labels them and removes them. The fixed threshold
//! is the weakness the paper shows (Figure 8): too small for far planes, too large to separate
//! close ones.

use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sl_core::{Camera, DepthImage, Image};

use crate::error::{PlanesError, Result};
use crate::extract::{PlaneConfig, PlaneInfo, PlaneSegmentation};
use crate::fit::AffineSums;
use crate::plane::DisparityAffine;
use crate::uncertainty::{FitNoise, plane_sigmas};
use sl_core::Plane;

/// Parameters of the metric RANSAC baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct RansacConfig {
    /// Point-to-plane inlier threshold, metres.
    pub threshold_m: f64,
    /// Hypotheses per plane.
    pub iterations: usize,
    /// Minimum inliers of a plane.
    pub min_pixels: usize,
    /// Most planes extracted.
    pub max_planes: usize,
    /// Size of the random subset used to score hypotheses.
    pub score_samples: usize,
    /// Random seed (the result is deterministic for a seed).
    pub seed: u64,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            threshold_m: 0.01,
            iterations: 500,
            min_pixels: 1000,
            max_planes: 20,
            score_samples: 4000,
            seed: 1,
        }
    }
}

/// Least-squares (PCA) plane of points, facing the camera; `None` for fewer than 3 or
/// degenerate points. The fit is `sl_core::fit_plane`.
pub fn fit_plane_pca(points: &[Point3<f64>]) -> Option<Plane> {
    Some(sl_core::fit_plane(points)?.plane.facing_origin())
}

/// Sequential metric RANSAC on a depth image. Returns the same structure as the disparity
/// extractor (the disparity-affine coefficients are derived from the 3D planes).
pub fn metric_ransac(
    depth: &DepthImage,
    camera: &Camera,
    cfg: &RansacConfig,
) -> Result<PlaneSegmentation> {
    let k = &camera.intrinsics;
    if depth.width() != k.width || depth.height() != k.height {
        return Err(PlanesError::SizeMismatch {
            expected_width: k.width,
            expected_height: k.height,
            width: depth.width(),
            height: depth.height(),
        });
    }
    if !(cfg.threshold_m.is_finite() && cfg.threshold_m > 0.0) || cfg.min_pixels < 3 {
        return Err(PlanesError::InvalidConfig(format!(
            "threshold_m = {} must be positive, min_pixels = {} at least 3",
            sl_core::Compact(cfg.threshold_m),
            cfg.min_pixels
        )));
    }
    let (w, h) = (depth.width(), depth.height());
    let fb = camera.sensor.fb();
    // The planes' uncertainties: the noise model's for a plane through their pixels (every
    // row; the extractor's default correlation window).
    let window = camera.pixels_per_sensor_pixel();
    let defaults = PlaneConfig::default();
    let noise = FitNoise::new(
        camera.sensor.sigma_d_px,
        camera.sensor.subpixel_steps,
        defaults.noise_window_x_px * window,
        defaults.noise_window_y_px * window,
        1,
    );
    let mut idx: Vec<u32> = Vec::new();
    let mut pts: Vec<Point3<f64>> = Vec::new();
    for (i, &z) in depth.data().iter().enumerate() {
        if z > 0.0 && z.is_finite() {
            idx.push(i as u32);
            pts.push(k.back_project((i % w) as f64, (i / w) as f64, f64::from(z)));
        }
    }
    let mut labels = vec![0u16; w * h];
    let mut remaining: Vec<usize> = (0..pts.len()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut planes = Vec::new();
    let thr = cfg.threshold_m;
    while planes.len() < cfg.max_planes && remaining.len() >= cfg.min_pixels.max(3) {
        let nr = remaining.len();
        let subset: Vec<usize> = (0..cfg.score_samples.min(nr))
            .map(|_| remaining[rng.random_range(0..nr)])
            .collect();
        let mut best: Option<(usize, Plane)> = None;
        for _ in 0..cfg.iterations {
            let (a, b, c) = (
                remaining[rng.random_range(0..nr)],
                remaining[rng.random_range(0..nr)],
                remaining[rng.random_range(0..nr)],
            );
            let (pa, pb, pc) = (pts[a], pts[b], pts[c]);
            let nrm = (pb - pa).cross(&(pc - pa));
            let Ok(pl) = Plane::new(nrm, -nrm.dot(&pa.coords)).map(Plane::facing_origin) else {
                continue;
            };
            let score = subset
                .iter()
                .filter(|&&i| pl.signed_distance_m(&pts[i]).abs() < thr)
                .count();
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, pl));
            }
        }
        let Some((_, mut pl)) = best else { break };
        // Inliers, PCA refit, inliers again.
        for _ in 0..2 {
            let inl: Vec<Point3<f64>> = remaining
                .iter()
                .filter(|&&i| pl.signed_distance_m(&pts[i]).abs() < thr)
                .map(|&i| pts[i])
                .collect();
            match fit_plane_pca(&inl) {
                Some(p) => pl = p,
                None => break,
            }
        }
        let (inl, rest): (Vec<usize>, Vec<usize>) = remaining
            .iter()
            .partition(|&&i| pl.signed_distance_m(&pts[i]).abs() < thr);
        if inl.len() < cfg.min_pixels {
            break;
        }
        let id = planes.len() as u16 + 1;
        let mut ss = 0.0;
        let mut sr = 0.0;
        let mut c = Vector3::zeros();
        let mut sums = AffineSums::default();
        let affine = DisparityAffine::from_plane(&pl, k, fb)?;
        for &i in &inl {
            let p = idx[i] as usize;
            labels[p] = id;
            let dist = pl.signed_distance_m(&pts[i]);
            ss += dist * dist;
            let d = fb / pts[i].z;
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let r = d - affine.eval(x, y);
            sr += r * r;
            sums.add(x, y, d);
            c += pts[i].coords;
        }
        let n = inl.len() as f64;
        let sigmas = plane_sigmas(&sums, &affine, k, fb, &noise);
        planes.push(PlaneInfo {
            id,
            plane: pl,
            affine,
            pixels: inl.len(),
            rms_px: (sr / n).sqrt(),
            rms_m: (ss / n).sqrt(),
            centroid_m: Point3::from(c / n),
            normal_sigma_deg: sigmas.normal_deg,
            offset_sigma_m: sigmas.offset_m,
        });
        remaining = rest;
    }
    Ok(PlaneSegmentation {
        labels: Image::from_vec(w, h, labels)?,
        planes,
    })
}
