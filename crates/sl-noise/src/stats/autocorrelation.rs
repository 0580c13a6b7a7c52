//! The residual autocorrelation at given lags along x and y, per tile, median over tiles.

use serde::Serialize;

use super::{MIN_CORRELATED_RMS_PX, MIN_TILE_RESIDUALS, Residuals, median};

/// Autocorrelation of the residual at one lag.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LagCorrelation {
    /// Lag, pixels.
    pub lag: usize,
    /// Median over tiles of the correlation along x (NaN without pairs).
    pub x: f64,
    /// Median over tiles of the correlation along y (NaN without pairs).
    pub y: f64,
    /// Pairs along x.
    pub pairs_x: usize,
    /// Pairs along y.
    pub pairs_y: usize,
}

/// The residual autocorrelation at each of `lags`, along x and along y: per tile (pairs inside
/// one tile), then the median over tiles.
pub(super) fn lag_correlations(
    res: &Residuals,
    n_keys: usize,
    lags: &[usize],
) -> Vec<LagCorrelation> {
    let (w, h) = (res.residual.width(), res.residual.height());
    let r = res.residual.data();
    let keys = res.tile.data();
    let corr = |dx: usize, dy: usize| -> (f64, usize) {
        let mut acc = vec![[0.0f64; 3]; n_keys];
        let mut cnt = vec![0usize; n_keys];
        for y in 0..h.saturating_sub(dy) {
            for x in 0..w.saturating_sub(dx) {
                let i = y * w + x;
                let j = (y + dy) * w + x + dx;
                let k = keys[i];
                if k == u32::MAX || keys[j] != k {
                    continue;
                }
                let (a, b) = (f64::from(r[i]), f64::from(r[j]));
                let t = &mut acc[k as usize];
                t[0] += a * b;
                t[1] += a * a;
                t[2] += b * b;
                cnt[k as usize] += 1;
            }
        }
        let mut cs = Vec::new();
        let mut pairs = 0;
        for (t, &n) in acc.iter().zip(&cnt) {
            let floor = n as f64 * MIN_CORRELATED_RMS_PX * MIN_CORRELATED_RMS_PX;
            if n >= MIN_TILE_RESIDUALS && t[1] > floor && t[2] > floor {
                cs.push(t[0] / (t[1] * t[2]).sqrt());
                pairs += n;
            }
        }
        (median(cs), pairs)
    };
    lags.iter()
        .map(|&lag| {
            let (x, pairs_x) = corr(lag, 0);
            let (y, pairs_y) = corr(0, lag);
            LagCorrelation {
                lag,
                x,
                y,
                pairs_x,
                pairs_y,
            }
        })
        .collect()
}
