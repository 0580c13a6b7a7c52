//! What the samples on no plane may count in [`super::structure`]'s information: their own
//! normals are noisy, and near the camera, where `σ_Z` is small, a handful of them outweighed a
//! corridor's planes (`docs/bench/track.md`, session 24).
//!
//! **The bias.** A sample's information along a direction `d` is `(n·d)²/σ²`. With a noisy
//! normal `n̂ = n + e` (`e` ⟂ `n`, variance `σ_a²` per tangent axis),
//! `E[n̂ n̂ᵀ] = n nᵀ (1 − 3σ_a²) + σ_a² I`: every noisy normal adds `σ_a²/σ²` of information in
//! *every* direction, including those the geometry leaves free. On a simulated OAK-D corridor
//! 1–23 samples at 0.6 m claimed 10–100 times the information all the corridor's planes give
//! along its axis, and a tracker drifting 2.6 m along it passed the check.
//!
//! **The rules, from the sensor model's correlation window** (the block matcher's,
//! [`super::TrackerConfig::noise_window_x_px`]):
//! - A sample whose window reaches the image border, an invalid pixel or a depth edge was
//!   matched partly on something else; its normal is left out ([`window_is_one_surface`]).
//! - A sample whose normal does not turn as a smooth surface's does across its window (the
//!   turns toward the two opposite neighbours half a window away differ by more than the
//!   frame's measured noise allows) sits by a crease: its normal is biased, not noisy; it is
//!   left out ([`NormalNoise::holds_across_window`]).
//! - Errors inside one window are shared, so a window's normal is tilted as a whole and no test
//!   of agreement inside it sees the tilt; but errors one window apart are independent. The
//!   sample's `n nᵀ` is estimated by the symmetric product of its own normal and that of a
//!   *partner* one window away on the same surface ([`NormalNoise::partner`]):
//!   `E[½(n̂ m̂ᵀ + m̂ n̂ᵀ)] = n nᵀ` with no noise term, so nothing needs to be known about
//!   `σ_a`. A sample with no partner counts nothing.
//!
//! **The noise for the crease test, measured.** The sensor model predicts `σ_a` of central
//! differences on raw frames (`c·z·f/(√2·r)`, `c = σ_D/(f·B)`); the frames the tracker sees are
//! prefiltered and their noise is correlated, so the model overstates it 4–15 times (OAK-D
//! corridor: 3.5–4.6° measured against 14–51° modelled at 0.5–2 m). [`NormalNoise::measure`]
//! takes the median angle between normals one window apart, per half-octave of depth.
//!
//! **Tried and left out** (session 24): subtracting the bias `σ_a² I` with the measured `σ_a`.
//! Measured on planes (own normal against the plane's) it read 12–40° on TUM fr1 frames in fast
//! motion (pixels by the planes' borders); measured on pairs it still exceeded the noise of the
//! samples it was subtracted from (objects' structure widens the pairs' angles), and 8 to 45 of
//! the 200 TUM frames were reported lost. The partner product needs no such estimate.

use nalgebra::Vector3;
use sl_core::{Intrinsics, SensorModel};

use super::pyramid::{Level, MAX_SLANT_TAN};

/// Depth bins per octave.
const BINS_PER_OCTAVE: f64 = 2.0;
/// Near edge of the first bin, metres.
const FIRST_BIN_M: f64 = 0.25;
/// Bins: 0.25 m to 64 m.
pub(super) const BINS: usize = 16;
/// Plane samples a bin needs before its own median is used: the median of `n` values of a
/// two-degree-of-freedom χ² has a relative standard error of about `1/√n` (12 % here, more
/// with the correlation between neighbouring normals).
pub(super) const MIN_SAMPLES: usize = 64;

/// The squared angle between two normals whose tangent errors (variance `σ_a²` per axis) are
/// independent is `2σ_a²` times a χ² with two degrees of freedom, whose median is `2 ln 2`.
const MEDIAN_CHI2_2: f64 = 2.0 * std::f64::consts::LN_2;

/// The 99 % quantile of a χ² with two degrees of freedom (`−2 ln 0.01`).
const CHI2_2_99: f64 = 9.21;

/// The frame's own-normal noise: per depth bin, the squared angles between normals one
/// correlation window apart on one surface, as ratios to the modelled variance; buffers are
/// reused from frame to frame.
///
/// **Pairs, not planes.** Comparing each normal with its plane's measured the extractor as
/// much as the noise: real planes hold pixels by their border, where the own normal turns
/// toward the next surface (median 17–40° on TUM fr1 frames in fast motion). Two normals one
/// correlation window apart have independent errors; on one smooth surface their angle is the
/// noise. A pair straddling a crease is not noise, and the median ignores the few there are.
#[derive(Debug, Clone, Default)]
pub(crate) struct NormalNoise {
    /// `angle² / (2 · modelled variance)` per bin.
    bins: [Vec<f32>; BINS],
    /// Per bin, once computed: `σ_a²` over the modelled variance, the bin's own or, with too
    /// few pairs, the nearest bin's with enough (the nearer one on a tie); `None` when no bin
    /// has enough.
    ratios: Option<[f64; BINS]>,
}

impl NormalNoise {
    /// Measures the noise of level `level`'s normals (intrinsics `k`, normal radius `r`) on the
    /// sample grid of `step` level pixels, each sample paired with the pixels `window` (level
    /// pixels, x and y) to its right and below it, on the same surface by the depth gate of
    /// [`window_is_one_surface`].
    pub(crate) fn measure(
        &mut self,
        level: &Level,
        k: &Intrinsics,
        sensor: &SensorModel,
        (step, r): (usize, usize),
        (dx, dy): (usize, usize),
    ) {
        self.bins.iter_mut().for_each(Vec::clear);
        let w = k.width;
        for v in (step / 2..k.height).step_by(step.max(1)) {
            for u in (step / 2..w).step_by(step.max(1)) {
                let i = v * w + u;
                let (Some(p), Some(n)) = (level.points.get(i), level.normals.get(i)) else {
                    continue;
                };
                if !(p.z > 0.0 && n.x.is_finite()) {
                    continue;
                }
                let z = f64::from(p.z);
                let modelled = modelled_variance(sensor, z, k.fx, r);
                let gate = depth_gate(k, sensor, p.z);
                let right = (u + dx < w).then_some((i + dx, dx));
                let below = (v + dy < k.height).then_some((i + dy * w, dy));
                for (j, d) in right.into_iter().chain(below) {
                    if let Some(m) = normal_on_surface(level, p.z, gate, j, d) {
                        self.add(z, f64::from((n - m).norm_squared()), modelled);
                    }
                }
            }
        }
        self.finish();
    }

    /// Adds the squared angle `angle2` of a pair at depth `z_m` with modelled variance
    /// `modelled` there.
    fn add(&mut self, z_m: f64, angle2: f64, modelled: f64) {
        let ratio = angle2 / (2.0 * modelled);
        if let (Some(b), true) = (bin(z_m), ratio.is_finite()) {
            self.bins[b].push(ratio as f32);
        }
    }

    /// Computes the per-bin medians of the pairs added since the last measurement, and lends
    /// each bin without enough pairs its nearest measured neighbour's.
    fn finish(&mut self) {
        self.ratios = binned_medians(&mut self.bins, MEDIAN_CHI2_2);
    }

    /// The variance per tangent axis of an own normal at depth `z_m`, rad², given the
    /// modelled variance there: the model scaled by the measured ratio of `z_m`'s bin, or of
    /// the nearest bin with enough pairs (the nearer one on a tie); the model itself when no
    /// bin has enough.
    pub(crate) fn variance(&self, z_m: f64, modelled: f64) -> f64 {
        match (&self.ratios, bin(z_m)) {
            (Some(ratios), Some(b)) => modelled * ratios[b],
            _ => modelled,
        }
    }

    /// The mean of the normals one correlation window (`window`: half sizes, level pixels) to
    /// the right of, below, to the left of and above pixel `(u, v)` that lie on the same surface
    /// by the depth gate of [`window_is_one_surface`] (`None` if none does): an estimate of the
    /// pixel's normal whose error is independent of the pixel's own. On a curved surface
    /// opposite partners' deviations from the pixel's true normal cancel to first order.
    pub(crate) fn partner(
        level: &Level,
        k: &Intrinsics,
        sensor: &SensorModel,
        (u, v): (usize, usize),
        (hx, hy): (usize, usize),
    ) -> Option<Vector3<f32>> {
        let w = k.width;
        let (dx, dy) = (2 * hx + 1, 2 * hy + 1);
        let i = v * w + u;
        let z = *level.depth.get(i)?;
        let gate = depth_gate(k, sensor, z);
        let (sum, count) = [
            (u + dx < w).then_some((i + dx, dx)),
            (v + dy < k.height).then_some((i + dy * w, dy)),
            u.checked_sub(dx).map(|_| (i - dx, dx)),
            v.checked_sub(dy).map(|_| (i - dy * w, dy)),
        ]
        .into_iter()
        .flatten()
        .filter_map(|(j, d)| normal_on_surface(level, z, gate, j, d))
        .fold((Vector3::zeros(), 0u8), |(s, c), m| (s + m, c + 1));
        (count > 0).then(|| sum / f32::from(count))
    }

    /// Whether the own normal at pixel `i` turns as a smooth surface's does across the
    /// window: the turn from the normal `±window` pixels away (x, then y) to this one equals the
    /// turn from this one to the opposite neighbour, within the noise — `n₊ + n₋ − 2n` within
    /// the 99 % quantile for normals of variance `variance` per axis (`6σ²` for that sum). A
    /// plane or a constant curve (a head, a cylinder) passes; a sample by a crease (a wall
    /// meeting the ceiling), whose one side turns and the other does not, fails: near the
    /// camera, where `σ_Z` is small, a few of them outweighed a corridor's planes (session 24).
    /// Comparing each neighbour's normal with this one alone (the first version) also rejected
    /// a head's samples at half resolution, where its normals turn 4° between samples, and a
    /// view pinned by the head was reported degenerate.
    pub(crate) fn holds_across_window(
        level: &Level,
        w: usize,
        i: usize,
        (hx, hy): (usize, usize),
        variance: f64,
    ) -> bool {
        let Some(n) = level.normals.get(i) else {
            return false;
        };
        let gate = 6.0 * variance * CHI2_2_99;
        let at = |j: Option<usize>| {
            j.and_then(|j| level.normals.get(j))
                .filter(|m| m.x.is_finite())
        };
        [
            (i.checked_sub(hx), Some(i + hx)),
            (i.checked_sub(hy * w), Some(i + hy * w)),
        ]
        .into_iter()
        .all(|(a, b)| match (at(a), at(b)) {
            (Some(a), Some(b)) => f64::from((a + b - n * 2.0).norm_squared()) <= gate,
            _ => false,
        })
    }
}

/// Per depth bin, the median of its values (reordered) over `divisor` when it has at least
/// [`MIN_SAMPLES`] of them, or else the nearest such bin's (the nearer one on a tie); `None`
/// when no bin has enough.
pub(super) fn binned_medians(bins: &mut [Vec<f32>; BINS], divisor: f64) -> Option<[f64; BINS]> {
    let own: [f64; BINS] = std::array::from_fn(|b| {
        let values = &mut bins[b];
        if values.len() >= MIN_SAMPLES {
            median(values) / divisor
        } else {
            f64::NAN
        }
    });
    own.iter().any(|r| r.is_finite()).then(|| {
        std::array::from_fn(|b| {
            (0..BINS)
                .flat_map(|d| [b.checked_sub(d), Some(b + d)])
                .flatten()
                .find_map(|i| own.get(i).copied().filter(|r| r.is_finite()))
                .unwrap_or(f64::NAN)
        })
    })
}

/// The median of `values` (reordered), which is not empty.
fn median(values: &mut [f32]) -> f64 {
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f32::total_cmp);
    f64::from(*m)
}

/// The depth difference that still counts as one surface at depth `z`: per pixel of distance,
/// a surface at 80° to the line of sight; plus 3σ of the difference of two depths.
fn depth_gate(k: &Intrinsics, sensor: &SensorModel, z: f32) -> (f32, f32) {
    let slope = z / k.fx as f32 * MAX_SLANT_TAN;
    let noise = 3.0 * std::f32::consts::SQRT_2 * sensor.sigma_z(f64::from(z)) as f32;
    (slope, noise)
}

/// The normal at pixel `j` of a level, `d` pixels from a pixel at depth `z`, if it is valid
/// and on the same surface by `gate` ([`depth_gate`]).
fn normal_on_surface(
    level: &Level,
    z: f32,
    (slope, noise): (f32, f32),
    j: usize,
    d: usize,
) -> Option<Vector3<f32>> {
    let (zj, m) = (*level.depth.get(j)?, *level.normals.get(j)?);
    (zj > 0.0 && m.x.is_finite() && (zj - z).abs() <= d as f32 * slope + noise).then_some(m)
}

/// The half-octave depth bin of `z_m`, if within the bins' range.
pub(super) fn bin(z_m: f64) -> Option<usize> {
    let b = ((z_m / FIRST_BIN_M).log2() * BINS_PER_OCTAVE).floor();
    (b >= 0.0 && b < BINS as f64).then_some(b as usize)
}

/// The sensor model's angular variance per tangent axis of a level's central-difference
/// normal at depth `z_m`, rad²: depths `2r` level pixels apart, each with `σ_Z`, so
/// `σ_a = √2·σ_Z / (2r·z/f) = c·z·f/(√2·r)`. `fl`: the level's focal length, pixels; `r`:
/// its normal radius.
pub(crate) fn modelled_variance(sensor: &SensorModel, z_m: f64, fl: f64, r: usize) -> f64 {
    let c = sensor.sigma_d_px / sensor.fb();
    let s = c * z_m * fl / (std::f64::consts::SQRT_2 * r.max(1) as f64);
    s * s
}

/// Whether the correlation window around pixel `(u, v)` of a level (half sizes `hx`, `hy`,
/// level pixels) lies inside the image on one surface: every pixel valid, none across a depth
/// edge ([`depth_gate`]).
pub(crate) fn window_is_one_surface(
    level: &Level,
    k: &Intrinsics,
    sensor: &SensorModel,
    (u, v): (usize, usize),
    (hx, hy): (usize, usize),
) -> bool {
    let w = k.width;
    if u < hx || v < hy || u + hx >= w || v + hy >= k.height {
        return false;
    }
    let Some(&z) = level.depth.get(v * w + u) else {
        return false;
    };
    let (slope, noise) = depth_gate(k, sensor, z);
    (v - hy..=v + hy).all(|y| {
        level
            .depth
            .get(y * w + u - hx..=y * w + u + hx)
            .is_some_and(|row| {
                row.iter().enumerate().all(|(i, &zj)| {
                    let d = (i.abs_diff(hx).max(y.abs_diff(v))) as f32;
                    zj > 0.0 && (zj - z).abs() <= d * slope + noise
                })
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_ratios(per_bin: &[(f64, f64)]) -> NormalNoise {
        let mut noise = NormalNoise::default();
        for &(z, ratio) in per_bin {
            for _ in 0..MIN_SAMPLES {
                // A pair's squared angle is 2σ_a²·χ²₂; at its median, `ratio` is σ_a²/model.
                noise.add(z, 2.0 * ratio * MEDIAN_CHI2_2, 1.0);
            }
        }
        noise.finish();
        noise
    }

    #[test]
    fn a_bin_with_enough_pairs_reports_its_own_ratio() {
        let noise = with_ratios(&[(1.1, 0.25), (3.0, 0.04)]);
        assert!((noise.variance(1.1, 2e-2) - 0.25 * 2e-2).abs() < 1e-9);
        assert!((noise.variance(3.0, 2e-2) - 0.04 * 2e-2).abs() < 1e-9);
    }

    #[test]
    fn an_empty_bin_takes_the_nearest_measured_ratio() {
        let noise = with_ratios(&[(1.1, 0.25), (4.5, 0.04)]);
        // 0.6 m: nearest measured bin is 1.1 m's.
        assert!((noise.variance(0.6, 1e-2) - 0.25 * 1e-2).abs() < 1e-9);
        // 6 m: 4.5 m's.
        assert!((noise.variance(6.0, 1e-2) - 0.04 * 1e-2).abs() < 1e-9);
    }

    #[test]
    fn the_median_ignores_a_few_pairs_across_creases() {
        let mut noise = NormalNoise::default();
        for i in 0..MIN_SAMPLES {
            let angle2 = if i % 10 == 0 {
                1.0
            } else {
                2.0 * 0.01 * MEDIAN_CHI2_2
            };
            noise.add(2.0, angle2, 1.0);
        }
        noise.finish();
        let v = noise.variance(2.0, 1.0);
        assert!(v < 0.012, "{v}");
    }

    #[test]
    fn without_pairs_the_model_is_used() {
        let noise = with_ratios(&[]);
        assert_eq!(noise.variance(2.0, 3e-3), 3e-3);
        assert_eq!(NormalNoise::default().variance(2.0, 3e-3), 3e-3);
        // Depths outside the bins are not counted.
        let noise = with_ratios(&[(0.1, 5.0), (f64::NAN, 5.0)]);
        assert_eq!(noise.variance(1.0, 5e-3), 5e-3);
    }

    #[test]
    fn the_modelled_variance_grows_with_depth_squared() {
        let sensor = SensorModel::kinect_v1();
        let v1 = modelled_variance(&sensor, 1.0, 580.0, 2);
        let v2 = modelled_variance(&sensor, 2.0, 580.0, 2);
        assert!((v2 / v1 - 4.0).abs() < 1e-9);
    }
}
