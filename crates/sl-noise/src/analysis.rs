//! Depth-resolution analysis of a depth map (the paper's section 2.2, Figure 2).
//!
//! A structured-light camera can only report the depths `Z = f·B/D` of its quantised
//! disparities `D = k/q`, rounded to its output unit (1 mm). The sorted unique depths of any
//! frame that covers a continuous range of depths therefore climb in steps
//! `ΔZ = Z_{k+1} − Z_k ≈ c·Z²` with the **quantum** `c = 1/(q·f·B)`, so `ln ΔZ` against `ln Z`
//! is a line of slope 2. [`analyze`] measures:
//!
//! * the sorted unique depths (depths are first rounded to the sensor's depth step, e.g. integer
//!   millimetres, so float noise in the file's scaling cannot create spurious values);
//! * `slope`: the ordinary least-squares slope of `ln ΔZ` vs `ln Z` over **all** neighbouring
//!   pairs (exactly the paper's procedure and Algorithm 1's);
//! * `slope_robust`: the Theil–Sen slope of the same points (median of pairwise slopes; exact
//!   up to 1 000 000 pairs, otherwise the median over that many pairs drawn with a fixed seed,
//!   so the result is deterministic). Gaps in a real frame's depth coverage (a neighbour
//!   missing because no pixel saw that depth) make upward outliers that it shrugs off;
//! * `slope_continuous`: the OLS slope over the continuous range only — pairs spanning a
//!   coverage gap of more than [`GAP_FACTOR`] quanta are left out (counted in `gap_pairs`);
//! * `quantum_per_m` (c): see [`fit_quantum`] — a data-only, robust estimate valid in the far
//!   range where the depth rounding cannot merge neighbouring disparities;
//! * `fb_px_m`: the implied `f·B = 1/(q·c)` with the camera's `q` (the data alone determine
//!   only the product `q·f·B`);
//! * `subpixel_steps`: the paper's sub-pixel experiment — unique depths converted to
//!   disparities `D = f·B/Z` with a stated `f·B` (`fb_used_px_m`), distinct disparities counted
//!   between consecutive integer disparities in the far range, the largest count (seen in at
//!   least two intervals) reported (8 for a Kinect). See [`ResolutionAnalysis::fb_source`] for which `f·B` is used and why.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use sl_core::{DepthImage, SensorModel};

use crate::error::{NoiseError, Result};

/// Fewest unique depths [`analyze`] accepts.
pub const MIN_UNIQUE_DEPTHS: usize = 16;
/// Fewest neighbouring pairs in the far range needed to fit the quantum.
pub const MIN_FAR_PAIRS: usize = 8;
/// Largest number of point pairs the Theil–Sen slope examines exactly.
pub const THEIL_SEN_MAX_PAIRS: usize = 1_000_000;
/// The far range starts where the predicted step `c·Z²` is this many depth steps: above one
/// step, two neighbouring disparities can no longer round to the same depth.
pub const FAR_RANGE_STEPS: f64 = 1.5;
/// The quantum is refined over pairs where `c·Z²` is at least this many depth steps.
pub const REFINE_STEPS: f64 = 4.0;

/// Settings of [`analyze_with`].
///
/// `#[non_exhaustive]`: start from [`AnalysisConfig::default`] (the `kinect-v1` sensor) or
/// [`AnalysisConfig::for_sensor`] and assign the fields you need.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub struct AnalysisConfig {
    /// The sensor's depth output step, metres (1 mm for a Kinect); depths are rounded to it.
    pub depth_step_m: f64,
    /// The camera's sub-pixel disparity steps `q`, if known (gives the implied `f·B`).
    pub subpixel_steps: Option<u32>,
    /// The nominal `f·B` of the camera (from its intrinsics and baseline), px·m, if known.
    pub nominal_fb_px_m: Option<f64>,
}

/// The former name of [`AnalysisConfig`].
#[deprecated(
    since = "0.1.0",
    note = "renamed `AnalysisConfig` (every configuration is a `…Config`)"
)]
pub type AnalysisOptions = AnalysisConfig;

impl AnalysisConfig {
    /// The configuration for a camera with the given sensor model: 1 mm steps, its `q` and its
    /// `f·B`.
    pub fn for_sensor(sensor: &SensorModel) -> Self {
        Self {
            depth_step_m: 0.001,
            subpixel_steps: Some(sensor.subpixel_steps),
            nominal_fb_px_m: Some(sensor.fb()),
        }
    }

    /// Checks the settings: the depth step must be a positive number and `q`, when given, at
    /// least 1 ([`NoiseError::InvalidParameter`] otherwise). [`analyze_with`] checks the same.
    pub fn validate(&self) -> Result<()> {
        let step = self.depth_step_m;
        if !(step.is_finite() && step > 0.0) {
            return Err(NoiseError::InvalidParameter(format!(
                "depth step {} m must be positive",
                sl_core::Compact(step)
            )));
        }
        if self.subpixel_steps == Some(0) {
            return Err(NoiseError::InvalidParameter(
                "sub-pixel steps must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

impl Default for AnalysisConfig {
    fn default() -> Self {
        Self::for_sensor(&SensorModel::kinect_v1())
    }
}

/// Where the `f·B` used for the sub-pixel count came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FbSource {
    /// Implied by the data: `1/(q·c)` with the camera's `q`.
    Implied,
    /// The camera's nominal `f·B` (no `q` was given).
    Nominal,
    /// Neither was available: no sub-pixel count.
    None,
}

/// A neighbouring pair whose `ΔZ` exceeds this many depth quanta `c·Z²` (plus one depth step)
/// spans a gap in the frame's depth coverage: at least this many representable depths between
/// them were seen by no pixel. Sensor noise cannot produce it (a missing level or two gives 2–3
/// quanta), so such pairs are left out of [`ResolutionAnalysis::slope_continuous`].
pub const GAP_FACTOR: f64 = 8.0;

/// The result of [`analyze`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResolutionAnalysis {
    /// Valid pixels examined.
    pub valid_pixels: usize,
    /// The depth step the depths were rounded to, metres.
    pub depth_step_m: f64,
    /// Number of distinct depths.
    pub unique_depths: usize,
    /// The distinct depths, ascending, metres (Figure 2a).
    pub sorted_depths_m: Vec<f64>,
    /// `ln Z_k` with Z in millimetres, for `k < unique_depths − 1` (Figure 2b, x).
    pub ln_z_mm: Vec<f64>,
    /// `ln (Z_{k+1} − Z_k)` with ΔZ in millimetres (Figure 2b, y).
    pub ln_dz_mm: Vec<f64>,
    /// OLS slope of `ln ΔZ` vs `ln Z` (2 for a structured-light camera).
    pub slope: f64,
    /// OLS intercept (millimetre units).
    pub intercept: f64,
    /// OLS slope over the *continuous range* only: the same points without the pairs that
    /// span a gap in the frame's depth coverage (see [`GAP_FACTOR`]). The paper's experiment
    /// presupposes "a continuous range of depth values"; a `ΔZ` across depths no pixel saw
    /// measures the scene, not the sensor, and one such point (a 0.37 m gap behind a desk, say)
    /// can move the whole-frame OLS slope by 0.08. Equals `slope` when there is no gap.
    pub slope_continuous: f64,
    /// Pairs left out of `slope_continuous` as coverage gaps.
    pub gap_pairs: usize,
    /// Theil–Sen slope of the same points.
    pub slope_robust: f64,
    /// Theil–Sen intercept (median residual, millimetre units).
    pub intercept_robust: f64,
    /// The quantum `c` of `ΔZ ≈ c·Z²`, per metre (see [`fit_quantum`]).
    pub quantum_per_m: f64,
    /// The plain median of `ΔZ/(Z_k·Z_{k+1})` over the far range, per metre (a cross-check of
    /// `quantum_per_m`).
    pub quantum_median_per_m: f64,
    /// Start of the far range (`c·Z² ≥ 1.5` depth steps), metres.
    pub far_range_min_m: f64,
    /// Neighbouring pairs in the far range.
    pub far_pairs: usize,
    /// The camera's `q` the implied `f·B` assumes, if given.
    pub subpixel_steps_assumed: Option<u32>,
    /// Implied `f·B = 1/(q·c)`, px·m (needs `q`).
    pub fb_px_m: Option<f64>,
    /// The camera's nominal `f·B`, px·m, if given.
    pub fb_nominal_px_m: Option<f64>,
    /// The `f·B` used to convert depths to disparities for the sub-pixel count, px·m.
    pub fb_used_px_m: Option<f64>,
    /// Which `f·B` that is. The implied one is preferred: nominal intrinsics are often off by
    /// several percent (TUM's 525 px vs a Kinect's ≈ 580 px), and a 1 % error in `f·B` already
    /// shifts the disparity grid by a whole step across a 10–60 px disparity range, which spoils
    /// the count. With the implied `f·B` the count checks that the data's steps form a regular
    /// `1/q` grid in disparity without merges or gaps (it cannot tell `q` apart from `f·B`: only
    /// their product is observable); `subpixel_steps_nominal` gives the paper's independent count
    /// with the nominal `f·B`.
    pub fb_source: FbSource,
    /// The disparity sub-pixel resolution (8 for a Kinect): the paper's "at most 8 disparities
    /// between two integer disparities" — the largest number of distinct disparities per unit
    /// disparity interval in the far range that occurs in at least two complete intervals (so a
    /// single stray value cannot raise it; with one interval, its count). Gaps in a frame's depth
    /// coverage only lower individual counts, which is why the largest and not the most
    /// frequent count is used: a sparse 160×120 frame may fill only a few intervals completely.
    pub subpixel_steps: Option<u32>,
    /// Most frequent count (ties to the larger); equals `subpixel_steps` on densely covered
    /// frames.
    pub subpixel_steps_mode: Option<u32>,
    /// Largest count.
    pub subpixel_steps_max: Option<u32>,
    /// `subpixel_steps` with the nominal `f·B` (the paper's procedure with calibrated
    /// intrinsics).
    pub subpixel_steps_nominal: Option<u32>,
    /// Per complete unit interval `[i + offset, i + 1 + offset)`: `(i, distinct disparities)`.
    pub subpixel_counts: Vec<(i64, u32)>,
    /// The interval offset: placed in the widest empty gap of the disparities' fractional parts,
    /// so that no interval edge cuts through a cluster of (rounded) disparities.
    pub disparity_bin_offset_px: f64,
}

/// Largest distance of the robust slope of `ln ΔZ` against `ln Z` from the model's 2 for a frame
/// to count as disparity-quantised depth ([`ResolutionAnalysis::quantised_like_the_model`]):
/// real Kinect-class frames measure 1.9–2.1; rendered, resampled or filtered depth, or depth
/// rounded to a fixed step, lands far from it.
pub const SLOPE_PLAUSIBLE_DEVIATION: f64 = 0.5;

impl ResolutionAnalysis {
    /// Whether the frame's depth steps grow as `Z²` (robust slope within
    /// [`SLOPE_PLAUSIBLE_DEVIATION`] of 2), as a structured-light sensor's disparity-quantised
    /// depth does: only then does the implied `f·B` mean anything.
    pub fn quantised_like_the_model(&self) -> bool {
        (self.slope_robust - 2.0).abs() <= SLOPE_PLAUSIBLE_DEVIATION
    }

    /// The implied `f·B` over the camera's (`sensor`), when the frame is quantised like the model
    /// and the analysis determined one. The depth steps follow `ΔZ = Z²/(q·f·B)`, so a frame read
    /// at `k` times its true scale (depths `k` times too deep) implies `k·f·B`: real frames at
    /// their right scale give 0.89–1.12 (TUM, 7-Scenes, the PrimeSense frames, ICL-NUIM), the
    /// same frames read five times too deep 5.4–5.6 — however near or far the scene is.
    pub fn fb_ratio(&self, sensor: &SensorModel) -> Option<f64> {
        let fb = self.fb_px_m.filter(|v| v.is_finite() && *v > 0.0)?;
        (self.quantised_like_the_model() && sensor.fb() > 0.0).then(|| fb / sensor.fb())
    }
}

/// Analyses a depth map with the options of a camera's sensor model ([`AnalysisConfig::for_sensor`]).
pub fn analyze(depth: &DepthImage, sensor: &SensorModel) -> Result<ResolutionAnalysis> {
    analyze_with(depth, &AnalysisConfig::for_sensor(sensor))
}

/// Analyses a depth map (0 / non-finite = invalid).
pub fn analyze_with(depth: &DepthImage, opts: &AnalysisConfig) -> Result<ResolutionAnalysis> {
    analyze_depths(depth.data().iter().map(|z| f64::from(*z)), opts)
}

/// Analyses any collection of depths in metres (non-positive or non-finite values are ignored).
pub fn analyze_depths(
    depths_m: impl IntoIterator<Item = f64>,
    opts: &AnalysisConfig,
) -> Result<ResolutionAnalysis> {
    opts.validate()?;
    let step = opts.depth_step_m;
    let mut valid_pixels = 0usize;
    let mut keys: Vec<i64> = Vec::new();
    for z in depths_m {
        if z > 0.0 && z.is_finite() {
            valid_pixels += 1;
            let k = (z / step).round();
            if (1.0..9.0e15).contains(&k) {
                keys.push(k as i64);
            }
        }
    }
    keys.sort_unstable();
    keys.dedup();
    if keys.len() < MIN_UNIQUE_DEPTHS {
        return Err(NoiseError::TooFewDepths {
            within: "",
            found: keys.len(),
            needed: MIN_UNIQUE_DEPTHS,
        });
    }
    let z: Vec<f64> = keys.iter().map(|k| *k as f64 * step).collect();
    let ln_z_mm: Vec<f64> = z[..z.len() - 1].iter().map(|v| (v * 1000.0).ln()).collect();
    let ln_dz_mm: Vec<f64> = z
        .windows(2)
        .map(|w| ((w[1] - w[0]) * 1000.0).ln())
        .collect();
    let too_few = NoiseError::TooFewDepths {
        within: "",
        found: z.len(),
        needed: MIN_UNIQUE_DEPTHS,
    };
    let (slope, intercept) = ols_slope(&ln_z_mm, &ln_dz_mm).ok_or(too_few.clone())?;
    let (slope_robust, intercept_robust) =
        theil_sen(&ln_z_mm, &ln_dz_mm, THEIL_SEN_MAX_PAIRS).ok_or(too_few)?;
    let fit = fit_quantum(&z, step)?;
    let c = fit.quantum_per_m;
    // Coverage gaps: ΔZ larger than GAP_FACTOR quanta (plus one depth step of rounding).
    let (mut xs, mut ys) = (
        Vec::with_capacity(ln_z_mm.len()),
        Vec::with_capacity(ln_z_mm.len()),
    );
    for (w, (x, y)) in z.windows(2).zip(ln_z_mm.iter().zip(&ln_dz_mm)) {
        if w[1] - w[0] <= GAP_FACTOR * c * w[0] * w[1] + step {
            xs.push(*x);
            ys.push(*y);
        }
    }
    let gap_pairs = ln_z_mm.len() - xs.len();
    let slope_continuous = if gap_pairs == 0 {
        slope
    } else {
        ols_slope(&xs, &ys).map_or(f64::NAN, |(s, _)| s)
    };
    let q = opts.subpixel_steps;
    let fb_implied = q.map(|q| 1.0 / (f64::from(q) * c));
    let fb_nominal = opts.nominal_fb_px_m.filter(|f| f.is_finite() && *f > 0.0);
    let (fb_used, fb_source) = match (fb_implied, fb_nominal) {
        (Some(f), _) => (Some(f), FbSource::Implied),
        (None, Some(f)) => (Some(f), FbSource::Nominal),
        (None, None) => (None, FbSource::None),
    };
    let far = &z[fit.first_far_index..];
    let count = fb_used.and_then(|fb| count_subpixel(far, fb));
    let count_nominal = fb_nominal.and_then(|fb| count_subpixel(far, fb));
    Ok(ResolutionAnalysis {
        valid_pixels,
        depth_step_m: step,
        unique_depths: z.len(),
        ln_z_mm,
        ln_dz_mm,
        slope,
        intercept,
        slope_continuous,
        gap_pairs,
        slope_robust,
        intercept_robust,
        quantum_per_m: c,
        quantum_median_per_m: fit.quantum_median_per_m,
        far_range_min_m: fit.far_range_min_m,
        far_pairs: fit.far_pairs,
        subpixel_steps_assumed: q,
        fb_px_m: fb_implied,
        fb_nominal_px_m: fb_nominal,
        fb_used_px_m: fb_used,
        fb_source,
        subpixel_steps: count.as_ref().map(|c| c.steps),
        subpixel_steps_mode: count.as_ref().map(|c| c.mode),
        subpixel_steps_max: count.as_ref().map(|c| c.max),
        subpixel_steps_nominal: count_nominal.map(|c| c.steps),
        disparity_bin_offset_px: count.as_ref().map_or(0.0, |c| c.offset),
        subpixel_counts: count.map(|c| c.counts).unwrap_or_default(),
        sorted_depths_m: z,
    })
}

/// Ordinary least squares `y = slope·x + intercept`; `None` with fewer than 2 points or no
/// spread in `x`.
pub fn ols_slope(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = x.len();
    if n < 2 || y.len() != n {
        return None;
    }
    let mx = x.iter().sum::<f64>() / n as f64;
    let my = y.iter().sum::<f64>() / n as f64;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    if sxx <= 0.0 || !sxx.is_finite() {
        return None;
    }
    let s = sxy / sxx;
    Some((s, my - s * mx))
}

/// Median of a slice (mean of the middle two for an even count), `None` when empty. NaNs sort
/// last.
pub fn median(v: &mut [f64]) -> Option<f64> {
    let n = v.len();
    if n == 0 {
        return None;
    }
    let (left, m, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let m = *m;
    if n % 2 == 1 {
        return Some(m);
    }
    // The lower middle is the largest element left of position n/2.
    let lower = left.iter().copied().max_by(f64::total_cmp)?;
    Some(0.5 * (lower + m))
}

/// Theil–Sen line: the median of the slopes over point pairs with distinct `x`, and the median
/// of `y − slope·x`. All pairs when there are at most `max_pairs`, else `max_pairs` pairs drawn
/// with a fixed-seed ChaCha8 generator (deterministic). `None` without a usable pair.
pub fn theil_sen(x: &[f64], y: &[f64], max_pairs: usize) -> Option<(f64, f64)> {
    let n = x.len();
    if n < 2 || y.len() != n || max_pairs == 0 {
        return None;
    }
    let total = n * (n - 1) / 2;
    let mut slopes = Vec::with_capacity(total.min(max_pairs));
    let mut push = |i: usize, j: usize| {
        let dx = x[j] - x[i];
        if dx != 0.0 && dx.is_finite() {
            slopes.push((y[j] - y[i]) / dx);
        }
    };
    if total <= max_pairs {
        for i in 0..n {
            for j in i + 1..n {
                push(i, j);
            }
        }
    } else {
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_7e11);
        for _ in 0..max_pairs {
            let i = rng.random_range(0..n);
            let j = rng.random_range(0..n - 1);
            let j = if j >= i { j + 1 } else { j };
            push(i.min(j), i.max(j));
        }
    }
    let slope = median(&mut slopes)?;
    let mut residuals: Vec<f64> = x.iter().zip(y).map(|(a, b)| b - slope * a).collect();
    Some((slope, median(&mut residuals)?))
}

/// The fitted quantum `c` of `ΔZ ≈ c·Z²`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct QuantumFit {
    /// The quantum, per metre.
    pub quantum_per_m: f64,
    /// The plain median of `ΔZ/(Z_k·Z_{k+1})` in the far range, per metre.
    pub quantum_median_per_m: f64,
    /// Start of the far range, metres.
    pub far_range_min_m: f64,
    /// Index of the first unique depth in the far range.
    pub first_far_index: usize,
    /// Neighbouring pairs in the far range.
    pub far_pairs: usize,
}

/// Fits the quantum `c` from sorted unique depths (metres) rounded to `step_m`.
///
/// Neighbouring representable depths `Z = f·B·q/k` satisfy exactly
/// `1/Z_k − 1/Z_{k+1} = c` (c = 1/(q·f·B)), i.e. `ΔZ = c·Z_k·Z_{k+1} ≈ c·Z²`. The fit:
///
/// 1. a first guess `c₀` = median of `ΔZ/(Z_k·Z_{k+1})` over the pairs with `ΔZ ≥ 2` steps;
/// 2. the **far range**: depths where `c₀·Z² ≥ 1.5` steps. Below it, two neighbouring
///    disparities can round to the same output depth (at 0.6 m a Kinect's disparity step is only
///    1.04 mm), so unique depths skip disparities and `ΔZ` there is not one quantum — that is
///    the "ringing" of the paper's Figure 2;
/// 3. `c` = the median of `ΔZ/(Z_k·Z_{k+1})` over the far range (robust to missing depths);
/// 4. refinement over the pairs where `c·Z² ≥ 4` steps: each pair's inverse-depth step
///    `1/Z_k − 1/Z_{k+1}` is an integer number `n_k = round(·/c)` of quanta (1 for neighbours,
///    more across a gap in the frame's coverage; pairs with `n_k > 4` are left out). There the
///    ±½-step rounding of each depth moves the step by at most ¼ quantum, so `n_k` is exact, and
///    `c = Σ(1/Z_k − 1/Z_{k+1}) / Σ n_k`. The sum telescopes over runs of consecutive depths, so
///    the rounding enters only at the ends of runs: on a clean frame `c` comes out to ~10⁻³
///    relative or better, where the median of step 3 scatters by ~1 % (each ratio carries up to
///    ±1 step of rounding error). Repeated three times, recomputing the ranges. When fewer than
///    8 pairs reach 4 steps, `c` stays the median of step 3.
pub fn fit_quantum(z: &[f64], step_m: f64) -> Result<QuantumFit> {
    let n = z.len();
    let too_few = |found| NoiseError::TooFewDepths {
        within: "",
        found,
        needed: MIN_FAR_PAIRS + 1,
    };
    if n < 2 {
        return Err(too_few(n));
    }
    let ratio = |k: usize| (z[k + 1] - z[k]) / (z[k] * z[k + 1]);
    let mut first: Vec<f64> = (0..n - 1)
        .filter(|&k| z[k + 1] - z[k] >= 2.0 * step_m)
        .map(ratio)
        .collect();
    if first.len() < MIN_FAR_PAIRS {
        first = (0..n - 1).map(ratio).collect();
    }
    let mut c = median(&mut first).ok_or(too_few(n))?;
    let far_start = |c: f64| {
        let z_min = (FAR_RANGE_STEPS * step_m / c).sqrt();
        (z_min, z.partition_point(|v| *v < z_min))
    };
    let (mut z_far, mut k0) = far_start(c);
    let mut ratios: Vec<f64> = (k0..n.saturating_sub(1)).map(ratio).collect();
    if ratios.len() < MIN_FAR_PAIRS {
        return Err(NoiseError::TooFewDepths {
            within: " in the far range (where one depth step is the disparity quantum's)",
            found: ratios.len() + 1,
            needed: MIN_FAR_PAIRS + 1,
        });
    }
    let mut c_median = median(&mut ratios).ok_or(too_few(n))?;
    c = c_median;
    for _ in 0..3 {
        // Refinement pairs: where c·Z² ≥ 4 steps, the rounding error of a pair's inverse-depth
        // step is at most a quarter quantum, so its number of quanta rounds correctly.
        let z_refine = (REFINE_STEPS * step_m / c).sqrt();
        let kr = z.partition_point(|v| *v < z_refine);
        let (mut sum_ds, mut sum_n, mut pairs) = (0.0, 0.0, 0usize);
        for k in kr..n - 1 {
            let ds = 1.0 / z[k] - 1.0 / z[k + 1];
            let quanta = (ds / c).round();
            if (1.0..=4.0).contains(&quanta) {
                sum_ds += ds;
                sum_n += quanta;
                pairs += 1;
            }
        }
        if pairs >= MIN_FAR_PAIRS {
            c = sum_ds / sum_n;
        }
        let (zf, kf) = far_start(c);
        if n.saturating_sub(1).saturating_sub(kf) >= MIN_FAR_PAIRS {
            (z_far, k0) = (zf, kf);
        }
    }
    let mut ratios: Vec<f64> = (k0..n - 1).map(ratio).collect();
    c_median = median(&mut ratios).unwrap_or(c_median);
    if !(c.is_finite() && c > 0.0) {
        return Err(NoiseError::InvalidParameter(format!(
            "fitted quantum {c} per m is not positive"
        )));
    }
    Ok(QuantumFit {
        quantum_per_m: c,
        quantum_median_per_m: c_median,
        far_range_min_m: z_far,
        first_far_index: k0,
        far_pairs: n - 1 - k0,
    })
}

/// Result of the sub-pixel count.
#[derive(Debug, Clone, PartialEq)]
struct SubpixelCount {
    steps: u32,
    mode: u32,
    max: u32,
    counts: Vec<(i64, u32)>,
    offset: f64,
}

/// Counts the distinct disparities `f·B/Z` per unit disparity interval over complete intervals.
fn count_subpixel(depths_m: &[f64], fb: f64) -> Option<SubpixelCount> {
    let d: Vec<f64> = depths_m
        .iter()
        .filter(|z| **z > 0.0)
        .map(|z| fb / z)
        .collect();
    if d.len() < 2 {
        return None;
    }
    // Interval offset: middle of the widest circular gap between fractional parts.
    let mut frac: Vec<f64> = d.iter().map(|v| v - v.floor()).collect();
    frac.sort_by(f64::total_cmp);
    let mut best = (frac[0] + 1.0 - frac[frac.len() - 1], frac[frac.len() - 1]);
    for w in frac.windows(2) {
        if w[1] - w[0] > best.0 {
            best = (w[1] - w[0], w[0]);
        }
    }
    let offset = (best.1 + best.0 / 2.0).rem_euclid(1.0);
    let (d_min, d_max) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let mut counts: std::collections::BTreeMap<i64, u32> = std::collections::BTreeMap::new();
    for v in &d {
        *counts.entry((v - offset).floor() as i64).or_insert(0) += 1;
    }
    // Complete intervals: [i + offset, i + 1 + offset) inside [d_min, d_max].
    let complete: Vec<(i64, u32)> = counts
        .into_iter()
        .filter(|(i, _)| {
            let lo = *i as f64 + offset;
            lo > d_min && lo + 1.0 < d_max
        })
        .collect();
    if complete.is_empty() {
        return None;
    }
    let mut histogram: std::collections::BTreeMap<u32, usize> = std::collections::BTreeMap::new();
    for (_, c) in &complete {
        *histogram.entry(*c).or_insert(0) += 1;
    }
    let mode = histogram
        .iter()
        .max_by_key(|(c, n)| (**n, **c))
        .map(|(c, _)| *c)?;
    let max = complete.iter().map(|(_, c)| *c).max()?;
    let steps = if complete.len() == 1 {
        max
    } else {
        histogram
            .iter()
            .rev()
            .find(|(_, n)| **n >= 2)
            .map_or(mode, |(c, _)| *c)
    };
    Some(SubpixelCount {
        steps,
        mode,
        max,
        counts: complete,
        offset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::KinectSimulator;

    /// Every representable depth of a sensor between two depths (a perfect "floor").
    fn ladder(sensor: SensorModel, z0: f64, z1: f64) -> Vec<f64> {
        let sim = KinectSimulator {
            min_depth_m: z0,
            max_depth_m: z1,
            ..KinectSimulator::with_sensor(sensor).white()
        };
        sim.representable_depths()
    }

    #[test]
    fn ols_and_theil_sen_on_a_line() {
        let x: Vec<f64> = (0..50).map(f64::from).collect();
        let mut y: Vec<f64> = x.iter().map(|v| 2.0 * v + 1.0).collect();
        assert_eq!(ols_slope(&x, &y), Some((2.0, 1.0)));
        y[7] = 1000.0;
        y[20] = -50.0;
        let (s, b) = theil_sen(&x, &y, THEIL_SEN_MAX_PAIRS).unwrap();
        assert!((s - 2.0).abs() < 1e-12 && (b - 1.0).abs() < 1e-12);
        // Sampled pairs give the same answer on clean data and are deterministic.
        let y: Vec<f64> = x.iter().map(|v| -0.5 * v + 3.0).collect();
        let a = theil_sen(&x, &y, 100).unwrap();
        assert!((a.0 + 0.5).abs() < 1e-12);
        assert_eq!(a, theil_sen(&x, &y, 100).unwrap());
        assert!(ols_slope(&[1.0], &[1.0]).is_none());
        assert_eq!(median(&mut [3.0, 1.0, 2.0, 10.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
    }

    #[test]
    fn perfect_ladder_recovers_quantum_and_steps() {
        for sensor in [SensorModel::kinect_v1(), SensorModel::paper_kinect()] {
            let z = ladder(sensor, 0.5, 4.0);
            let opts = AnalysisConfig::for_sensor(&sensor);
            let a = analyze_depths(z.iter().copied(), &opts).unwrap();
            let fb = a.fb_px_m.unwrap();
            assert!(
                (fb / sensor.fb() - 1.0).abs() < 1e-3,
                "fB {fb} vs {}",
                sensor.fb()
            );
            assert_eq!(a.fb_source, FbSource::Implied);
            assert_eq!(a.subpixel_steps, Some(8));
            assert_eq!(a.subpixel_steps_max, Some(8));
            assert_eq!(a.subpixel_steps_nominal, Some(8));
            assert!((a.slope - 2.0).abs() < 0.1, "{}", a.slope);
            assert!((a.slope_robust - 2.0).abs() < 0.1, "{}", a.slope_robust);
            // Far range starts where c·Z² = 1.5 mm.
            let expect = (1.5e-3 / sensor.depth_quantum_per_m()).sqrt();
            assert!((a.far_range_min_m - expect).abs() < 0.01);
        }
    }

    /// A frame that sees 0.8–1.8 m and 2.2–3.0 m but nothing in between: the one pair across
    /// the gap is an outlier of ~100 quanta; the continuous-range slope leaves it out.
    #[test]
    fn coverage_gap_is_left_out_of_the_continuous_slope() {
        let sensor = SensorModel::kinect_v1();
        let sim = crate::sim::KinectSimulator::kinect_v1().white();
        let z: Vec<f64> = sim
            .representable_depths()
            .into_iter()
            .filter(|z| (0.8..1.8).contains(z) || (2.2..3.0).contains(z))
            .collect();
        let a = analyze_depths(z.iter().copied(), &AnalysisConfig::for_sensor(&sensor)).unwrap();
        assert_eq!(a.gap_pairs, 1);
        assert!(
            (a.slope_continuous - 2.0).abs() < 0.1,
            "{}",
            a.slope_continuous
        );
        assert!(
            a.slope > a.slope_continuous,
            "{} vs {}",
            a.slope,
            a.slope_continuous
        );
        // Without a gap the two slopes are the same number.
        let full: Vec<f64> = sim
            .representable_depths()
            .into_iter()
            .filter(|z| (0.8..3.0).contains(z))
            .collect();
        let b = analyze_depths(full.iter().copied(), &AnalysisConfig::for_sensor(&sensor)).unwrap();
        assert_eq!(b.gap_pairs, 0);
        assert_eq!(b.slope, b.slope_continuous);
    }

    #[test]
    fn sixteenth_pixel_sensor_is_told_apart_with_nominal_fb() {
        // A hypothetical 1/16 px sensor: with the right f·B the paper's count says 16.
        let sensor = SensorModel {
            subpixel_steps: 16,
            ..SensorModel::kinect_v1()
        };
        let z = ladder(sensor, 0.8, 4.5);
        let opts = AnalysisConfig {
            subpixel_steps: None,
            ..AnalysisConfig::for_sensor(&sensor)
        };
        let a = analyze_depths(z.iter().copied(), &opts).unwrap();
        assert_eq!(a.fb_source, FbSource::Nominal);
        assert_eq!(a.subpixel_steps, Some(16));
        assert!(a.fb_px_m.is_none());
        assert!((a.quantum_per_m * 16.0 * sensor.fb() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn gaps_do_not_bias_the_quantum() {
        let sensor = SensorModel::kinect_v1();
        // Drop every 17th depth and a whole band: ΔZ outliers.
        let z: Vec<f64> = ladder(sensor, 0.6, 3.5)
            .into_iter()
            .enumerate()
            .filter(|(i, z)| i % 17 != 3 && !(1.9..2.1).contains(z))
            .map(|(_, z)| z)
            .collect();
        let a = analyze_depths(z, &AnalysisConfig::for_sensor(&sensor)).unwrap();
        assert!((a.fb_px_m.unwrap() / sensor.fb() - 1.0).abs() < 2e-3);
        assert!((a.slope_robust - 2.0).abs() < 0.15, "{}", a.slope_robust);
        assert_eq!(a.subpixel_steps_max, Some(8));
    }

    #[test]
    fn simulated_frames_recover_fb_and_steps() {
        // Several seeds and scenes at quarter resolution: f·B within 1 %, q exactly.
        for (name, seed) in [("floor", 3), ("corridor", 8), ("floor", 21)] {
            let ns = crate::sim::named_scene(name).unwrap();
            let k = ns.intrinsics.scaled(0.25).unwrap();
            let sim = KinectSimulator::kinect_v1().white();
            let f = sim.simulate(&ns.scene, &k, &ns.pose, seed);
            let a = analyze(&f.depth, &sim.sensor).unwrap();
            assert!(
                (a.fb_px_m.unwrap() / sim.sensor.fb() - 1.0).abs() < 0.01,
                "{name} {seed}"
            );
            assert_eq!(
                a.subpixel_steps,
                Some(8),
                "{name} {seed}: {:?}",
                a.subpixel_counts
            );
            assert!((a.slope - 2.0).abs() < 0.1, "{name} {seed}: {}", a.slope);
        }
    }

    #[test]
    fn errors() {
        let opts = AnalysisConfig::default();
        let few = DepthImage::from_vec(4, 1, vec![1.0, 1.0, 2.0, 0.0]).unwrap();
        assert!(matches!(
            analyze_with(&few, &opts),
            Err(NoiseError::TooFewDepths { found: 2, .. })
        ));
        assert!(opts.validate().is_ok());
        let bad = AnalysisConfig {
            depth_step_m: 0.0,
            ..opts
        };
        assert!(matches!(
            bad.validate(),
            Err(NoiseError::InvalidParameter(_))
        ));
        assert!(matches!(
            analyze_with(&few, &bad),
            Err(NoiseError::InvalidParameter(_))
        ));
        // Many unique depths but all below the far range: no quantum.
        let near: Vec<f64> = (500..540).map(|mm| f64::from(mm) / 1000.0).collect();
        assert!(matches!(
            analyze_depths(near, &opts),
            Err(NoiseError::TooFewDepths { .. })
        ));
    }
}
