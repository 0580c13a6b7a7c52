//! Planar regions of a real frame (walls, floors, desks), for measuring how much a filter
//! flattens them: RANSAC with the sensor model's noise band, one connected surface per plane.

use sl_core::nalgebra::Point3;
use sl_core::{DepthImage, Intrinsics, Plane, SensorModel};

use super::{dilate, erode, valid};
use crate::error::Result;

/// Fewest pixels a measured region keeps after erosion, absolute.
pub const MIN_REGION_PIXELS: usize = 1000;

/// Fewest pixels a region of [`plane_regions`] keeps after erosion, as a share of the image:
/// walls, floors and desks, not the strips of shelves and box faces that a plane's noise band
/// (8 cm wide at 3 m) also catches and whose residual is their shape, not noise.
pub const MIN_REGION_SHARE: f64 = 0.05;

/// A planar surface of a frame and the pixels that belong to it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneRegion {
    /// Least-squares plane through the region's pixels of the input frame.
    pub plane: Plane,
    /// Row-major pixel mask of the region.
    pub mask: Vec<bool>,
}

/// How [`plane_regions`] searches a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionSearch {
    /// Erosion of each region, pixels (use the filter radius + 1).
    pub erode_px: usize,
    /// RANSAC samples per plane.
    pub iterations: usize,
    /// RANSAC seed.
    pub seed: u64,
    /// Most planes returned.
    pub max_planes: usize,
    /// Fewest region pixels after erosion, as a share of the image.
    pub min_share: f64,
}

impl Default for RegionSearch {
    /// 4 px erosion (a 7×7 filter), 500 samples, seed 7, six planes of at least
    /// [`MIN_REGION_SHARE`] of the image.
    fn default() -> Self {
        Self {
            erode_px: 4,
            iterations: 500,
            seed: 7,
            max_planes: 6,
            min_share: MIN_REGION_SHARE,
        }
    }
}

/// Deterministic SplitMix64, for RANSAC sampling.
pub(super) fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The dominant plane of a (raw) depth frame and a robust region on it: the first of
/// [`plane_regions`]. Returns `None` when no plane with at least [`MIN_REGION_PIXELS`] region
/// pixels exists.
pub fn dominant_plane_region(
    depth: &DepthImage,
    k: &Intrinsics,
    sensor: &SensorModel,
    erode_px: usize,
    iterations: usize,
    seed: u64,
) -> Result<Option<PlaneRegion>> {
    let search = RegionSearch {
        erode_px,
        iterations,
        seed,
        max_planes: 1,
        min_share: 0.0,
    };
    Ok(plane_regions(depth, k, sensor, &search)?.into_iter().next())
}

/// Up to `search.max_planes` planar surfaces of a (raw) depth frame, largest consensus first, for
/// measuring how much a filter flattens walls and floors. For each plane:
///
/// 1. RANSAC (`search.iterations` samples of 3 points, seeded) over every 4th pixel in each direction
///    not yet taken by an earlier plane; a point is an inlier when its distance to the plane is
///    below `τ(Z) = 3·σ_Z(Z) + ΔZ(Z) + 2 mm` — three noise σ plus one depth quantum of the
///    sensor model, so the band widens with `Z²` exactly like the noise and inliers are not
///    selected by their (depth-dependent) noise.
/// 2. The largest-consensus plane is refitted by least squares on all its inlier pixels.
/// 3. The inlier mask is *closed* (dilated then eroded by 2 px) so that isolated noisy pixels
///    inside the surface are put back (otherwise the raw frame's residual would be truncated at
///    `τ` and look better than it is).
/// 4. Only the largest 4-connected component is kept: one surface. At 3 m the band `τ` is
///    ~8 cm wide, and every other surface crossing the plane's extension leaves a strip of
///    "inliers" along the crossing line (on TUM fr1/rpy frame 0, the strip where the far wall
///    cuts the desk's plane was the whole "≥ 2 m" part of the desk region, and its residual
///    measured the wall's tilt, not noise). The plane is refitted on the component.
/// 5. The component is taken (later planes sample outside it) and *eroded* by `search.erode_px` (use
///    the filter radius + 1) so the region keeps away from its boundaries, where filters
///    legitimately mix in other surfaces.
///
/// Stops at the first plane whose region has fewer than `search.min_share` of the image's pixels (and
/// fewer than [`MIN_REGION_PIXELS`]); [`MIN_REGION_SHARE`] keeps walls and floors.
pub fn plane_regions(
    depth: &DepthImage,
    k: &Intrinsics,
    sensor: &SensorModel,
    search: &RegionSearch,
) -> Result<Vec<PlaneRegion>> {
    let RegionSearch {
        erode_px,
        iterations,
        seed,
        max_planes,
        min_share,
    } = *search;
    depth.as_image().check_size(k)?;
    let (w, h) = (depth.width(), depth.height());
    let z = depth.data();
    let point = |i: usize| -> Point3<f64> {
        let (x, y, d) = ((i % w) as f64, (i / w) as f64, f64::from(z[i]));
        Point3::new((x - k.cx) / k.fx * d, (y - k.cy) / k.fy * d, d)
    };
    let tau = |d: f64| 3.0 * sensor.sigma_z(d) + sensor.depth_step_m(d) + 0.002;
    let mut taken = vec![false; w * h];
    let mut state = seed;
    let mut out = Vec::new();
    while out.len() < max_planes {
        let samples: Vec<Point3<f64>> = (0..h)
            .step_by(4)
            .flat_map(|y| (0..w).step_by(4).map(move |x| y * w + x))
            .filter(|&i| valid(z[i]) && !taken[i])
            .map(point)
            .collect();
        let Some(plane) = ransac(&samples, iterations, &mut state, &tau) else {
            break;
        };
        let inlier = |plane: &Plane| -> Vec<bool> {
            (0..w * h)
                .map(|i| {
                    valid(z[i]) && !taken[i] && {
                        let p = point(i);
                        plane.signed_distance_m(&p).abs() < tau(p.z)
                    }
                })
                .collect()
        };
        let first = inlier(&plane);
        let pts: Vec<Point3<f64>> = (0..w * h).filter(|&i| first[i]).map(point).collect();
        let Some(fit) = sl_core::fit_plane(&pts) else {
            break;
        };
        let mask = inlier(&fit.plane);
        let closed: Vec<bool> = erode(&dilate(&mask, w, h, 2), w, h, 2)
            .iter()
            .zip(&taken)
            .map(|(&c, &t)| c && !t)
            .collect();
        let surface = largest_component(&closed, w, h);
        let pts: Vec<Point3<f64>> = (0..w * h)
            .filter(|&i| surface[i] && valid(z[i]))
            .map(point)
            .collect();
        let Some(fit) = sl_core::fit_plane(&pts) else {
            break;
        };
        let region = erode(&surface, w, h, erode_px);
        let mask: Vec<bool> = region.iter().zip(z).map(|(&m, &d)| m && valid(d)).collect();
        let min = MIN_REGION_PIXELS.max((min_share * (w * h) as f64).ceil() as usize);
        if mask.iter().filter(|&&m| m).count() < min {
            break;
        }
        for (t, &s) in taken.iter_mut().zip(&surface) {
            *t |= s;
        }
        out.push(PlaneRegion {
            plane: fit.plane,
            mask,
        });
    }
    Ok(out)
}

/// The plane through three of `samples` with the most samples within `tau` of it.
fn ransac(
    samples: &[Point3<f64>],
    iterations: usize,
    state: &mut u64,
    tau: &dyn Fn(f64) -> f64,
) -> Option<Plane> {
    if samples.len() < 3 {
        return None;
    }
    let mut best: Option<(usize, Plane)> = None;
    for _ in 0..iterations {
        let mut pick = || samples[(splitmix(state) % samples.len() as u64) as usize];
        let (a, b, c) = (pick(), pick(), pick());
        let n = (b - a).cross(&(c - a));
        let len = n.norm();
        if len.is_nan() || len <= 1e-9 {
            continue;
        }
        let n = n / len;
        let plane = Plane {
            normal: n,
            offset_m: -n.dot(&a.coords),
        };
        let count = samples
            .iter()
            .filter(|p| plane.signed_distance_m(p).abs() < tau(p.z))
            .count();
        if best.as_ref().is_none_or(|(bc, _)| count > *bc) {
            best = Some((count, plane));
        }
    }
    best.map(|(_, p)| p)
}

/// The largest 4-connected component of `mask` (the first found on a tie).
fn largest_component(mask: &[bool], w: usize, h: usize) -> Vec<bool> {
    let mut label = vec![0u32; w * h];
    let mut stack = Vec::new();
    let (mut best, mut best_size, mut next) = (0u32, 0usize, 0u32);
    for start in 0..w * h {
        if !mask[start] || label[start] != 0 {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if mask[j] && label[j] == 0 {
                    label[j] = next;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if size > best_size {
            (best, best_size) = (next, size);
        }
    }
    label.iter().map(|&l| l != 0 && l == best).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_component_keeps_one_surface() {
        // Two blobs: 3 pixels and 2 pixels, separated by a column of false.
        let (w, h) = (5, 2);
        let m = [
            true, true, false, true, false, //
            true, false, false, true, false,
        ];
        let c = largest_component(&m, w, h);
        assert_eq!(
            c,
            vec![
                true, true, false, false, false, true, false, false, false, false
            ]
        );
    }
}
