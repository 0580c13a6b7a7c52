//! Summary statistics of a list of errors, as the TUM tools print them.

/// RMSE, mean, median, standard deviation, minimum and maximum of a list of errors (the
/// median of an even count is the mean of the two middle values, as NumPy's).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    /// Number of errors.
    pub count: usize,
    /// Root mean square.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Population standard deviation (NumPy's `std`).
    pub std: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl ErrorStats {
    /// The statistics of `errors` (all zero when empty).
    pub fn of(errors: &[f64]) -> Self {
        let n = errors.len();
        if n == 0 {
            return Self::default();
        }
        let nf = n as f64;
        let mean = errors.iter().sum::<f64>() / nf;
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / nf).sqrt();
        let std = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / nf).sqrt();
        let mut s = errors.to_vec();
        s.sort_by(f64::total_cmp);
        let median = if n % 2 == 1 {
            s[n / 2]
        } else {
            0.5 * (s[n / 2 - 1] + s[n / 2])
        };
        Self {
            count: n,
            rmse,
            mean,
            median,
            std,
            min: s[0],
            max: s[n - 1],
        }
    }

    /// The statistics scaled by `factor` (e.g. radians to degrees).
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            count: self.count,
            rmse: self.rmse * factor,
            mean: self.mean * factor,
            median: self.median * factor,
            std: self.std * factor,
            min: self.min * factor,
            max: self.max * factor,
        }
    }
}
