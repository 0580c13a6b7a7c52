//! How well a fitted plane is determined, from the noise model: the standard uncertainty of its
//! normal (degrees) and of its position along the normal at its centroid (metres).
//!
//! A plane is fitted as an affine disparity function `D = a·x + b·y + c` by least squares. With
//! the disparity error of variance `σ²` per pixel, correlated over the camera's block-matching
//! window (triangular autocorrelation over `w_x × w_y` pixels, `docs/NOISE_MODEL.md`), the
//! fit of a region much larger than the window has the covariance of independent samples
//! inflated by `κ = Σ_lags ρ` over the lags of the sampled pixels: `Cov(a, b) = κ·σ²·S⁻¹` with
//! `S` the centred sums of squares of the pixel coordinates, and the disparity at the centroid
//! `D̄` has variance `κ·σ²/n`, uncorrelated with the slopes. `σ²` is the larger of the sensor
//! model's `σ_D² + 1/(12q²)` and the fit's own mean squared residual, so that a plane whose
//! residual exceeds the noise (a surface bent by the sensor's low-frequency distortion, or
//! pieces of two surfaces) is reported as less certain, never as more.
//!
//! The 3D normal is the direction of `m = (a·f_x, b·f_y, D̄ + a·(c_x − x̄) + b·(c_y − ȳ))`
//! (`DisparityAffine::to_plane`); its covariance is carried to the unit normal by the
//! projection `(I − n·nᵀ)/|m|`. The normal's uncertainty is the square root of the trace (the
//! RMS angle between the fitted and the true normal, both tangent directions). The position is
//! the depth `f·B/D̄` along the centroid's ray, projected on the normal. At the centroid the
//! two are uncorrelated.
//!
//! Written by hand: a covariance propagation of a dozen lines, specific to the disparity
//! parameterisation.

use nalgebra::{Matrix3, Vector3};
use sl_core::Intrinsics;

use crate::fit::AffineSums;
use crate::plane::DisparityAffine;

/// The noise of a plane fit's samples: the variance of one pixel's disparity error and the
/// correlation inflation of a fit on every `row_step`-th row and every column of a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FitNoise {
    /// Variance of one pixel's disparity error, px² (`σ_D² + 1/(12q²)`).
    pub(crate) var_px: f64,
    /// `Σ_lags ρ` over the sampled pixels (1 for white noise).
    pub(crate) kappa: f64,
}

impl Default for FitNoise {
    fn default() -> Self {
        Self::new(0.07, 8, 1.0, 1.0, 1)
    }
}

/// `Σ_{m ∈ ℤ} ρ(m·step)` for the triangular autocorrelation `ρ(l) = max(0, 1 − |l|/w)` of a
/// field averaged over a window `w` pixels wide.
fn correlation_sum(w: f64, step: usize) -> f64 {
    let w = w.max(1.0);
    let step = step.max(1) as f64;
    let mut sum = 1.0;
    let mut m = 1.0;
    while m * step < w {
        sum += 2.0 * (1.0 - m * step / w);
        m += 1.0;
    }
    sum
}

/// Variance of one pixel's disparity error, px²: `σ_D²` plus the uniform `1/q` px
/// quantisation's `1/(12q²)`.
pub(crate) fn pixel_variance(sigma_d_px: f64, q: u32) -> f64 {
    let q = f64::from(q.max(1));
    sigma_d_px * sigma_d_px + 1.0 / (12.0 * q * q)
}

impl FitNoise {
    /// The noise of a fit on every `row_step`-th row of the pixels of a region, for a disparity
    /// error of `sigma_d_px` plus the `1/q` px quantisation, correlated over a
    /// `window_x × window_y` pixel window (1 × 1: white noise).
    pub(crate) fn new(
        sigma_d_px: f64,
        q: u32,
        window_x: f64,
        window_y: f64,
        row_step: usize,
    ) -> Self {
        Self::on_grid(sigma_d_px, q, window_x, window_y, 1, row_step)
    }

    /// The noise of a fit on the pixels of a grid `step_x` pixels apart along the rows and
    /// `step_y` rows apart.
    pub(crate) fn on_grid(
        sigma_d_px: f64,
        q: u32,
        window_x: f64,
        window_y: f64,
        step_x: usize,
        step_y: usize,
    ) -> Self {
        Self {
            var_px: pixel_variance(sigma_d_px, q),
            kappa: correlation_sum(window_x, step_x) * correlation_sum(window_y, step_y),
        }
    }
}

/// The standard uncertainties of a fitted plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PlaneSigmas {
    /// RMS angle between the fitted and the true normal, degrees.
    pub(crate) normal_deg: f64,
    /// Standard uncertainty of the plane's position along its normal at its centroid, metres.
    pub(crate) offset_m: f64,
}

impl PlaneSigmas {
    /// Undetermined (the samples do not pin the plane down).
    pub(crate) const UNDETERMINED: Self = Self {
        normal_deg: f64::INFINITY,
        offset_m: f64::INFINITY,
    };
}

/// The RMS angle between a fixed direction and one drawn uniformly from the hemisphere around
/// it, degrees: `√(π − 2)` rad (61.2°; `E[θ²] = ∫₀^{π/2} θ² sin θ dθ = π − 2`). A normal whose
/// linearised uncertainty reaches it is known no better than a guess of the side the camera
/// sees, so [`plane_sigmas`] reports it as undetermined, not as a number of degrees the
/// linearisation no longer means.
pub(crate) const GUESSED_NORMAL_RMS_DEG: f64 = 61.217_870_040_792_25;

/// The uncertainties of the fit `f` of the samples `sums` (pixel coordinates of the frame of
/// intrinsics `k`, disparity in pixels, `f·B` = `fb`); infinite when the samples do not
/// determine a plane.
pub(crate) fn plane_sigmas(
    sums: &AffineSums,
    f: &DisparityAffine,
    k: &Intrinsics,
    fb: f64,
    noise: &FitNoise,
) -> PlaneSigmas {
    let n = sums.n;
    if n < 3.0 {
        return PlaneSigmas::UNDETERMINED;
    }
    let [sxx, sxy, syy] = sums.slope_information();
    let det = sxx * syy - sxy * sxy;
    if !(det > 0.0 && det.is_finite()) {
        return PlaneSigmas::UNDETERMINED;
    }
    let var = noise.var_px.max(sums.rss(f) / n) * noise.kappa;
    let (mx, my) = (sums.sx / n, sums.sy / n);
    let d_mean = f.eval(mx, my);
    // Covariance of (a, b, D̄): the slopes' block and D̄'s variance.
    let c = Matrix3::new(
        var * syy / det,
        -var * sxy / det,
        0.0,
        -var * sxy / det,
        var * sxx / det,
        0.0,
        0.0,
        0.0,
        var / n,
    );
    let m = Vector3::new(
        f.a * k.fx,
        f.b * k.fy,
        d_mean + f.a * (k.cx - mx) + f.b * (k.cy - my),
    );
    let norm = m.norm();
    if !(norm > 0.0 && norm.is_finite() && d_mean > 0.0) {
        return PlaneSigmas::UNDETERMINED;
    }
    let j = Matrix3::new(k.fx, 0.0, 0.0, 0.0, k.fy, 0.0, k.cx - mx, k.cy - my, 1.0);
    let u = m / norm;
    let p = Matrix3::identity() - u * u.transpose();
    let cov_n = p * j * c * j.transpose() * p / (norm * norm);
    let ray = Vector3::new((mx - k.cx) / k.fx, (my - k.cy) / k.fy, 1.0);
    let z = fb / d_mean;
    let sigmas = PlaneSigmas {
        normal_deg: cov_n.trace().max(0.0).sqrt().to_degrees(),
        offset_m: z * z / fb * u.dot(&ray).abs() * (var / n).sqrt(),
    };
    if sigmas.normal_deg < GUESSED_NORMAL_RMS_DEG && sigmas.offset_m.is_finite() {
        sigmas
    } else {
        PlaneSigmas::UNDETERMINED
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};
    use sl_core::{Plane, nalgebra::Vector3 as V3};

    #[test]
    fn correlation_sums_of_a_box_window() {
        // White noise: no inflation; a window w wide sums to w along every pixel.
        assert_eq!(correlation_sum(1.0, 1), 1.0);
        assert!((correlation_sum(9.0, 1) - 9.0).abs() < 1e-12);
        // Every fourth row of an 11-row window: 1 + 2·(7/11 + 3/11).
        assert!((correlation_sum(11.0, 4) - (1.0 + 20.0 / 11.0)).abs() < 1e-12);
        let n = FitNoise::new(0.07, 8, 9.0, 11.0, 4);
        assert!((n.kappa - 9.0 * (1.0 + 20.0 / 11.0)).abs() < 1e-9);
        assert!((n.var_px - (0.0049 + 1.0 / 768.0)).abs() < 1e-12);
    }

    /// With white noise of the model's variance, the predicted uncertainties match the
    /// scatter of many fits (Monte Carlo, 400 draws) within the sampling error.
    #[test]
    fn white_noise_scatter_matches_the_prediction() {
        let k = Intrinsics::new(640, 480, 570.0, 570.0, 319.5, 239.5).unwrap();
        let fb = 570.0 * 0.075;
        let truth = Plane::new(V3::new(0.3, -0.2, -0.93), 2.5)
            .unwrap()
            .facing_origin();
        let f0 = DisparityAffine::from_plane(&truth, &k, fb).unwrap();
        let noise = FitNoise::new(0.07, 8, 1.0, 1.0, 1);
        let normal = Normal::new(0.0, noise.var_px.sqrt()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (mut sq_angle, mut sq_offset, mut predicted) = (0.0, 0.0, None);
        let draws = 400;
        for _ in 0..draws {
            // A 60×50-pixel patch off the image centre.
            let mut s = AffineSums::default();
            for y in 300..350 {
                for x in 400..460 {
                    let d = f0.eval(f64::from(x), f64::from(y)) + normal.sample(&mut rng);
                    s.add(f64::from(x), f64::from(y), d);
                }
            }
            let f = s.solve().unwrap();
            let p = f.to_plane(&k, fb).unwrap();
            let sig = plane_sigmas(&s, &f, &k, fb, &noise);
            predicted.get_or_insert(sig);
            sq_angle += p.angle_to_deg(&truth).powi(2);
            // The fitted plane's position along its normal at the centroid, against the truth's.
            let (mx, my) = (s.sx / s.n, s.sy / s.n);
            let z = fb / f0.eval(mx, my);
            let point = V3::new((mx - k.cx) / k.fx * z, (my - k.cy) / k.fy * z, z);
            sq_offset += p.signed_distance_m(&point.into()).powi(2);
        }
        let pred = predicted.unwrap();
        let rms_angle = (sq_angle / f64::from(draws)).sqrt();
        let rms_offset = (sq_offset / f64::from(draws)).sqrt();
        // 400 draws: the RMS is within ±10 % of its expectation at about 3σ.
        assert!(
            (rms_angle / pred.normal_deg - 1.0).abs() < 0.12,
            "{rms_angle} vs {pred:?}"
        );
        assert!(
            (rms_offset / pred.offset_m - 1.0).abs() < 0.12,
            "{rms_offset} vs {pred:?}"
        );
    }

    #[test]
    fn the_guessed_normal_rms_is_that_of_a_uniform_hemisphere() {
        // Midpoint rule for E[θ²] = ∫₀^{π/2} θ² sin θ dθ.
        let n = 100_000;
        let h = std::f64::consts::FRAC_PI_2 / f64::from(n);
        let m2: f64 = (0..n)
            .map(|i| {
                let t = (f64::from(i) + 0.5) * h;
                t * t * t.sin() * h
            })
            .sum();
        assert!((m2.sqrt().to_degrees() - GUESSED_NORMAL_RMS_DEG).abs() < 1e-6);
    }

    #[test]
    fn a_residual_above_the_noise_widens_and_a_line_of_pixels_is_undetermined() {
        let k = Intrinsics::new(640, 480, 570.0, 570.0, 319.5, 239.5).unwrap();
        let fb = 570.0 * 0.075;
        let noise = FitNoise::new(0.07, 8, 9.0, 11.0, 4);
        let f = DisparityAffine {
            a: 0.01,
            b: 0.02,
            c: 20.0,
        };
        let fill = |amp: f64| {
            let mut s = AffineSums::default();
            for y in (100..200).step_by(4) {
                for x in 100..200 {
                    let r = if (x + y) % 2 == 0 { amp } else { -amp };
                    s.add(
                        f64::from(x),
                        f64::from(y),
                        f.eval(f64::from(x), f64::from(y)) + r,
                    );
                }
            }
            s
        };
        let quiet = plane_sigmas(&fill(0.0), &f, &k, fb, &noise);
        let bumpy = plane_sigmas(&fill(0.3), &f, &k, fb, &noise);
        assert!(quiet.normal_deg > 0.0 && bumpy.normal_deg > 2.0 * quiet.normal_deg);
        // The same patch 10 km away (disparity 0.004 px): its normal is no better than a
        // guess, and is reported as undetermined rather than as a linearised angle.
        let far = DisparityAffine {
            a: 0.0,
            b: 0.0,
            c: fb / 10_000.0,
        };
        let mut distant = AffineSums::default();
        for y in (100..200).step_by(4) {
            for x in 100..200 {
                distant.add(f64::from(x), f64::from(y), far.c);
            }
        }
        assert_eq!(
            plane_sigmas(&distant, &far, &k, fb, &noise),
            PlaneSigmas::UNDETERMINED
        );
        let mut line = AffineSums::default();
        for x in 0..100 {
            line.add(f64::from(x), 50.0, 20.0);
        }
        assert_eq!(
            plane_sigmas(&line, &f, &k, fb, &noise),
            PlaneSigmas::UNDETERMINED
        );
    }
}
