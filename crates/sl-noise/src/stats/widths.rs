//! [`WidthStats`]: the distribution of the widths of a set of runs (terraces, occlusion bands).

use serde::Serialize;

use super::quantile_sorted;

/// Distribution of the widths of a set of runs, pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WidthStats {
    /// Number of runs.
    pub count: usize,
    /// Median width (NaN without runs).
    pub median_px: f64,
    /// Mean width (NaN without runs).
    pub mean_px: f64,
    /// 10th percentile (NaN without runs).
    pub p10_px: f64,
    /// 90th percentile (NaN without runs).
    pub p90_px: f64,
}

impl WidthStats {
    pub(super) fn from_widths(mut w: Vec<f64>) -> Self {
        w.sort_by(f64::total_cmp);
        let n = w.len();
        if n == 0 {
            return Self {
                count: 0,
                median_px: f64::NAN,
                mean_px: f64::NAN,
                p10_px: f64::NAN,
                p90_px: f64::NAN,
            };
        }
        Self {
            count: n,
            median_px: quantile_sorted(&w, 0.5),
            mean_px: w.iter().sum::<f64>() / n as f64,
            p10_px: quantile_sorted(&w, 0.1),
            p90_px: quantile_sorted(&w, 0.9),
        }
    }
}
