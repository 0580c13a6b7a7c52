//! Terrace widths: the runs of identical depth along rows inside a fitted region, and their
//! histogram.

use serde::Serialize;
use sl_core::{DepthImage, Image};

use super::{Residuals, WidthStats};

/// Terrace-width distribution: histogram and summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Terraces {
    /// Summary of the complete runs of equal depth along rows.
    pub widths: WidthStats,
    /// Upper edges of the histogram bins, pixels; `None` for the last bin, which is open (JSON
    /// `null`, Python `None`, as the other open or missing values).
    pub bin_upper_px: Vec<Option<usize>>,
    /// Fraction of runs per bin.
    pub fractions: Vec<f64>,
}

/// Upper edges of the terrace histogram bins, pixels (`None`: the last bin is open).
const TERRACE_BINS: [Option<usize>; 7] =
    [Some(1), Some(2), Some(4), Some(8), Some(16), Some(32), None];

/// The terrace widths: complete runs of equal depth along rows inside one fitted region
/// (bounded on both sides by a different depth of the same region).
pub(super) fn terraces(depth: &DepthImage, res: &Residuals, regions: &Image<u16>) -> Terraces {
    let (w, h) = (depth.width(), depth.height());
    let r = res.residual.data();
    let labels = regions.data();
    let zs = depth.data();
    let mut runs = Vec::new();
    for y in 0..h {
        let row = y * w;
        let mut x = 0;
        while x < w {
            let i = row + x;
            if !r[i].is_finite() {
                x += 1;
                continue;
            }
            let mut e = x + 1;
            while e < w
                && r[row + e].is_finite()
                && labels[row + e] == labels[i]
                && zs[row + e] == zs[i]
            {
                e += 1;
            }
            // Complete when bounded by a different depth of the same tile on both sides.
            let left_ok =
                x > 0 && r[i - 1].is_finite() && labels[i - 1] == labels[i] && zs[i - 1] != zs[i];
            let right_ok = e < w
                && r[row + e].is_finite()
                && labels[row + e] == labels[i]
                && zs[row + e] != zs[i];
            if left_ok && right_ok {
                runs.push((e - x) as f64);
            }
            x = e;
        }
    }
    let mut counts = [0usize; TERRACE_BINS.len()];
    for &wd in &runs {
        let b = TERRACE_BINS
            .iter()
            .position(|u| u.is_none_or(|u| wd as usize <= u))
            .unwrap_or(TERRACE_BINS.len() - 1);
        counts[b] += 1;
    }
    let total = runs.len().max(1) as f64;
    Terraces {
        widths: WidthStats::from_widths(runs),
        bin_upper_px: TERRACE_BINS.to_vec(),
        fractions: counts.iter().map(|c| *c as f64 / total).collect(),
    }
}
