//! How noisy the reference's normals are, measured where a plane of the frame lands on them, so
//! that [`super::structure`] can credit a plane's sample by the squared cosine between its
//! plane's normal and the reference's without that noise biasing it.
//!
//! **The bias.** A reference normal `n̂ = n + e` (tangent error `e`, variance `σ_r²` per axis)
//! against a plane normal `m` that is exact in comparison (thousands of pixels): the squared
//! cosine `(m·n̂)²` is `cos²θ − |e|²` on average for a true angle `θ` near 0, so every aligned
//! sample is credited `2σ_r²` short. Only normals that are not a pixel's own are compared
//! ([`super::ReferenceMaps::own_normals`]): the last frame's planes' (as exact as the frame's)
//! and the fused model's, whose noise depends on how many views were fused and how far away —
//! on TUM fr1/rpy-200, 4–11° per axis from 0.7 to 4 m (`2σ_r²` 0.010–0.069, session 53), so
//! without the correction a real frame's planes would be credited 1–7 % short. So the noise is
//! measured, not assumed: per half-octave of depth, `|e|² = 1 − (m·n̂)²` is `σ_r²` times a χ²
//! with two degrees of freedom, whose median is `2 ln 2·σ_r²`; the mean `2σ_r²` is the median
//! over `ln 2`. The samples that land on another surface (a plane's pixels by a crease, the rim
//! of a fused range) are not noise; the median ignores the few there are.

use super::normal_noise::{BINS, bin, binned_medians};

/// The reference normals' mean squared tangent error `2σ_r²` per depth bin, measured from plane
/// samples: what a plane sample's squared cosine to the reference is short of on average.
#[derive(Debug, Clone)]
pub(crate) struct ReferenceNormalNoise {
    /// `2σ_r²` per bin, lent from the nearest measured bin; `None`: nothing measured.
    per_bin: Option<[f64; BINS]>,
}

impl ReferenceNormalNoise {
    /// Nothing measured: no correction.
    pub(crate) const NONE: Self = Self { per_bin: None };

    /// From `(depth m, 1 − cos²)` pairs of plane samples (plane normal against the reference
    /// normal they land on), in any order. A bin needs `MIN_SAMPLES` of them for its own
    /// median; a bin with fewer borrows the nearest measured bin's.
    pub(crate) fn measure(samples: impl IntoIterator<Item = (f64, f32)>) -> Self {
        let mut bins: [Vec<f32>; BINS] = std::array::from_fn(|_| Vec::new());
        for (z, s) in samples {
            if let (Some(b), true) = (bin(z), s.is_finite()) {
                bins[b].push(s.max(0.0));
            }
        }
        Self {
            per_bin: binned_medians(&mut bins, std::f64::consts::LN_2),
        }
    }

    /// `2σ_r²` at depth `z_m` (0 where nothing was measured).
    pub(crate) fn mean_square_error(&self, z_m: f64) -> f64 {
        match (&self.per_bin, bin(z_m)) {
            (Some(per_bin), Some(b)) => per_bin[b],
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::normal_noise::MIN_SAMPLES;
    use super::*;

    /// Tangent errors of σ per axis (a deterministic spread of the two-dimensional Gaussian's
    /// squared radius: `σ²·χ²₂` at evenly spaced quantiles) give back `2σ²`, and a tenth of the
    /// samples on another surface move it little.
    #[test]
    fn the_median_gives_back_the_mean_squared_error() {
        let sigma2 = (3f64.to_radians()).powi(2);
        let n = 1000;
        let chi2 = |i: usize| -2.0 * (1.0 - (i as f64 + 0.5) / n as f64).ln();
        let noise = ReferenceNormalNoise::measure((0..n).map(|i| (2.0, (sigma2 * chi2(i)) as f32)));
        let got = noise.mean_square_error(2.0);
        assert!(
            (got / (2.0 * sigma2) - 1.0).abs() < 0.01,
            "{got} vs {}",
            2.0 * sigma2
        );
        // Lent to the other bins.
        assert_eq!(noise.mean_square_error(4.0), got);
        let with_creases = ReferenceNormalNoise::measure(
            (0..n)
                .map(|i| (2.0, (sigma2 * chi2(i)) as f32))
                .chain((0..n / 10).map(|_| (2.0, 1.0))),
        );
        let got = with_creases.mean_square_error(2.0);
        assert!((got / (2.0 * sigma2) - 1.0).abs() < 0.2, "{got}");
    }

    #[test]
    fn too_few_samples_measure_nothing() {
        let noise = ReferenceNormalNoise::measure((0..MIN_SAMPLES - 1).map(|_| (2.0, 0.1)));
        assert_eq!(noise.mean_square_error(2.0), 0.0);
        assert_eq!(ReferenceNormalNoise::NONE.mean_square_error(2.0), 0.0);
    }
}
