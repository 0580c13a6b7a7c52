//! Algorithm 1 of the paper: the synthetic depth-resolution experiment.
//!
//! The paper's Matlab code (section 2.2):
//!
//! ```text
//! b=75; f=587;
//! z=(b*f./(round(b*f./(500:3000)*8)/8));
//! z=unique(round(z));
//! plot(log(z(1:end-1)),log(diff(z)))
//! ```
//!
//! Depths 500…3000 mm in 1 mm steps are turned into disparities `b·f/z` (px), rounded to 1/8 px,
//! turned back into depths and rounded to 1 mm; the unique depths are sorted, and
//! `ln ΔZ_k = ln(Z_{k+1} − Z_k)` is plotted against `ln Z_k`. The slope of the ordinary
//! least-squares line through those points is the number the paper's argument rests on (≈ 2).
//!
//! Matlab's `round` rounds halves away from zero, which is [`f64::round`]; the products and
//! quotients are evaluated in the same order as Matlab (`(b*f)./z`, then `*8`), in IEEE double
//! precision, so the values agree bit for bit.

use serde::Serialize;

use crate::analysis::ols_slope;
use crate::error::{NoiseError, Result};

/// Parameters of [`algorithm1_with`]; [`Algorithm1Params::paper`] is the paper's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Algorithm1Params {
    /// Baseline, millimetres (paper: 75).
    pub baseline_mm: f64,
    /// Focal length, pixels (paper: 587).
    pub focal_px: f64,
    /// Sub-pixel disparity steps per pixel (paper: 8).
    pub subpixel_steps: u32,
    /// First depth of the sweep, millimetres (paper: 500).
    pub z_min_mm: u32,
    /// Last depth of the sweep, millimetres, inclusive (paper: 3000).
    pub z_max_mm: u32,
}

impl Algorithm1Params {
    /// The paper's values: b = 75 mm, f = 587 px, q = 8, Z = 500…3000 mm.
    pub fn paper() -> Self {
        Self {
            baseline_mm: 75.0,
            focal_px: 587.0,
            subpixel_steps: 8,
            z_min_mm: 500,
            z_max_mm: 3000,
        }
    }
}

impl Default for Algorithm1Params {
    fn default() -> Self {
        Self::paper()
    }
}

/// The result of Algorithm 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Algorithm1 {
    /// The parameters used.
    pub params: Algorithm1Params,
    /// `unique(round(z))`: sorted unique depths, millimetres.
    pub unique_depths_mm: Vec<f64>,
    /// `log(z(1:end-1))`.
    pub ln_z: Vec<f64>,
    /// `log(diff(z))`.
    pub ln_dz: Vec<f64>,
    /// Slope of the ordinary least-squares line through `(ln_z, ln_dz)`.
    pub slope_ols: f64,
    /// Intercept of that line.
    pub intercept_ols: f64,
    /// The theoretical quantum `c = 1/(q·f·b)` per mm of `ΔZ ≈ c·Z²` (for comparison).
    pub quantum_per_mm: f64,
}

/// Algorithm 1 with the paper's parameters (slope 1.946).
pub fn algorithm1() -> Algorithm1 {
    // The paper's parameters are valid, so this cannot fail; fall back to an empty result
    // rather than panic should that ever change.
    algorithm1_with(&Algorithm1Params::paper()).unwrap_or_else(|_| Algorithm1 {
        params: Algorithm1Params::paper(),
        unique_depths_mm: Vec::new(),
        ln_z: Vec::new(),
        ln_dz: Vec::new(),
        slope_ols: f64::NAN,
        intercept_ols: f64::NAN,
        quantum_per_mm: f64::NAN,
    })
}

/// Algorithm 1 with other parameters.
pub fn algorithm1_with(p: &Algorithm1Params) -> Result<Algorithm1> {
    if !(p.baseline_mm > 0.0
        && p.baseline_mm.is_finite()
        && p.focal_px > 0.0
        && p.focal_px.is_finite())
    {
        return Err(NoiseError::InvalidParameter(format!(
            "baseline {} mm and focal length {} px must be positive",
            sl_core::Compact(p.baseline_mm),
            sl_core::Compact(p.focal_px)
        )));
    }
    if p.subpixel_steps == 0 || p.z_min_mm == 0 || p.z_max_mm <= p.z_min_mm {
        return Err(NoiseError::InvalidParameter(format!(
            "need q ≥ 1 and 0 < z_min < z_max (got q {}, {}..{} mm)",
            p.subpixel_steps, p.z_min_mm, p.z_max_mm
        )));
    }
    let bf = p.baseline_mm * p.focal_px;
    let q = f64::from(p.subpixel_steps);
    // z = b*f./(round(b*f./(500:3000)*8)/8); z = unique(round(z))
    let mut z: Vec<f64> = (p.z_min_mm..=p.z_max_mm)
        .map(|zi| bf / ((bf / f64::from(zi) * q).round() / q))
        .map(f64::round)
        .collect();
    z.sort_by(f64::total_cmp);
    z.dedup();
    if z.len() < 3 {
        return Err(NoiseError::TooFewDepths {
            within: "",
            found: z.len(),
            needed: 3,
        });
    }
    let ln_z: Vec<f64> = z[..z.len() - 1].iter().map(|v| v.ln()).collect();
    let ln_dz: Vec<f64> = z.windows(2).map(|w| (w[1] - w[0]).ln()).collect();
    let (slope_ols, intercept_ols) = ols_slope(&ln_z, &ln_dz).ok_or(NoiseError::TooFewDepths {
        within: "",
        found: z.len(),
        needed: 3,
    })?;
    Ok(Algorithm1 {
        params: *p,
        unique_depths_mm: z,
        ln_z,
        ln_dz,
        slope_ols,
        intercept_ols,
        quantum_per_mm: 1.0 / (q * bf),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's Matlab recipe gives slope 1.946 (the team's own Matlab run).
    #[test]
    fn reproduces_matlab_slope() {
        let a = algorithm1();
        assert_eq!(
            format!("{:.3}", a.slope_ols),
            "1.946",
            "slope {}",
            a.slope_ols
        );
        assert_eq!(a.ln_z.len(), a.unique_depths_mm.len() - 1);
        assert!(a.unique_depths_mm.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a.unique_depths_mm[0], 500.0);
    }

    #[test]
    fn steps_follow_the_quantum() {
        let a = algorithm1();
        // Far from the 1 mm rounding, ΔZ ≈ c·Z² (to within the 1 mm rounding).
        for w in a.unique_depths_mm.windows(2).filter(|w| w[0] > 2000.0) {
            let predicted = a.quantum_per_mm * w[0] * w[0];
            assert!(
                (w[1] - w[0] - predicted).abs() <= 1.0 + 0.01 * predicted,
                "{w:?}"
            );
        }
    }

    #[test]
    fn rejects_bad_parameters() {
        let mut p = Algorithm1Params::paper();
        p.focal_px = 0.0;
        assert!(algorithm1_with(&p).is_err());
        let p = Algorithm1Params {
            z_max_mm: 400,
            ..Algorithm1Params::paper()
        };
        assert!(algorithm1_with(&p).is_err());
    }
}
