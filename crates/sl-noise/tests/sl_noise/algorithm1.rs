//! Algorithm 1 of the paper through the public API.

use sl_noise::algorithm1::{Algorithm1Params, algorithm1, algorithm1_with};
use sl_noise::analysis::{AnalysisConfig, analyze_depths};

#[test]
fn algorithm1_slope_is_1_946() {
    let a = algorithm1();
    eprintln!(
        "Algorithm 1: {} unique depths, OLS slope {:.6}, intercept {:.6}",
        a.unique_depths_mm.len(),
        a.slope_ols,
        a.intercept_ols
    );
    assert_eq!(format!("{:.3}", a.slope_ols), "1.946");
    assert_eq!(a.unique_depths_mm.first(), Some(&500.0));
    // 3000 mm itself is not representable: the last depth is the nearest representable one,
    // within half a quantum (c·Z²/2 ≈ 13 mm at 3 m).
    let last = *a.unique_depths_mm.last().unwrap();
    assert!(
        (last - 3000.0).abs() <= 0.5 * a.quantum_per_mm * 3000.0 * 3000.0,
        "{last}"
    );
}

#[test]
fn analysis_of_algorithm1_depths_agrees() {
    // The resolution analysis of Algorithm 1's unique depths gives the same OLS slope, and its
    // quantum gives back q·f·B = 8 · 587 · 0.075.
    let a = algorithm1();
    let mut config = AnalysisConfig::default();
    config.depth_step_m = 0.001;
    config.subpixel_steps = Some(8);
    config.nominal_fb_px_m = Some(587.0 * 0.075);
    let r = analyze_depths(a.unique_depths_mm.iter().map(|mm| mm / 1000.0), &config).unwrap();
    assert!(
        (r.slope - a.slope_ols).abs() < 1e-9,
        "{} vs {}",
        r.slope,
        a.slope_ols
    );
    let fb = r.fb_px_m.unwrap();
    assert!((fb / (587.0 * 0.075) - 1.0).abs() < 1e-3, "{fb}");
    assert_eq!(r.subpixel_steps, Some(8));
}

#[test]
fn finer_quantisation_lowers_the_ringing() {
    // With 1/64 px disparity steps the depth rounding dominates up to larger Z; the slope of
    // the far range stays 2 but the whole-range OLS slope changes: the parametrised version
    // is a real computation, not a constant.
    let p = Algorithm1Params {
        subpixel_steps: 64,
        ..Algorithm1Params::paper()
    };
    let a = algorithm1_with(&p).unwrap();
    assert_ne!(format!("{:.3}", a.slope_ols), "1.946");
    assert!(a.unique_depths_mm.len() > algorithm1().unique_depths_mm.len());
}
