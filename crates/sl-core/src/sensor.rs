//! The structured-light noise model of the paper (section 2).
//!
//! The camera measures disparity `D` (pixels) and reports depth `Z = f·B / D`. Disparity is
//! estimated to `1/q` pixel (q = 8 for the Kinect) with a constant noise `σ_D`, so the depth
//! noise grows with the square of depth: `σ_Z = Z²·σ_D / (f·B)` and `∂Z/∂D = −Z² / (f·B)`.

use crate::Compact;
use crate::error::{CoreError, Result};

/// Disparity-domain sensor model of a structured-light camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// Focal length of the IR camera, pixels.
    pub focal_px: f64,
    /// Projector–camera baseline, metres.
    pub baseline_m: f64,
    /// Sub-pixel disparity steps per pixel (`q`; 8 for a Kinect).
    pub subpixel_steps: u32,
    /// Standard deviation of the disparity noise, pixels.
    pub sigma_d_px: f64,
}

/// Largest projector–camera (or stereo) baseline [`SensorModel::validate`] accepts, metres.
pub const MAX_BASELINE_M: f64 = 10.0;

/// Most sub-pixel disparity steps per pixel [`SensorModel::validate`] accepts (a Kinect has 8,
/// a RealSense 32; finer than 1/256 px no matcher resolves).
pub const MAX_SUBPIXEL_STEPS: u32 = 256;

/// Largest disparity noise [`SensorModel::validate`] accepts, pixels (a matcher whose error is
/// beyond ten pixels measures nothing).
pub const MAX_SIGMA_D_PX: f64 = 10.0;

/// Default disparity noise, pixels.
///
/// Obtained by converting the axial noise model of Nguyen, Izadi & Lovell (3DIMPVT 2012),
/// `σ_Z = 1.2 mm + 1.9 mm·(Z − 0.4 m)²`, back to disparity with `f·B = 43.5 px·m`: it gives
/// 0.066 px at 2 m and 0.082 px at 1 m. The quantisation alone (1/8 px, uniform) contributes
/// `0.125/√12 = 0.036` px.
pub const DEFAULT_SIGMA_D_PX: f64 = 0.07;

impl SensorModel {
    /// Validated constructor.
    pub fn new(
        focal_px: f64,
        baseline_m: f64,
        subpixel_steps: u32,
        sigma_d_px: f64,
    ) -> Result<Self> {
        let s = Self {
            focal_px,
            baseline_m,
            subpixel_steps,
            sigma_d_px,
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks that the focal length is in the range of [`crate::Intrinsics::validate`], the
    /// baseline in (0, [`MAX_BASELINE_M`]], the steps in 1..=[`MAX_SUBPIXEL_STEPS`] and σ_D in
    /// [0, [`MAX_SIGMA_D_PX`]].
    pub fn validate(&self) -> Result<()> {
        use crate::intrinsics::{MAX_FOCAL_PX, MIN_FOCAL_PX};
        if !(self.focal_px.is_finite() && (MIN_FOCAL_PX..=MAX_FOCAL_PX).contains(&self.focal_px)) {
            return Err(CoreError::InvalidSensor(format!(
                "focal length {} px must be in [{MIN_FOCAL_PX}, {}]",
                Compact(self.focal_px),
                Compact(MAX_FOCAL_PX)
            )));
        }
        if !(self.baseline_m.is_finite()
            && self.baseline_m > 0.0
            && self.baseline_m <= MAX_BASELINE_M)
        {
            return Err(CoreError::InvalidSensor(format!(
                "baseline {} m must be in (0, {MAX_BASELINE_M}]",
                Compact(self.baseline_m)
            )));
        }
        if !(1..=MAX_SUBPIXEL_STEPS).contains(&self.subpixel_steps) {
            return Err(CoreError::InvalidSensor(format!(
                "sub-pixel steps {} must be in 1..={MAX_SUBPIXEL_STEPS}",
                self.subpixel_steps
            )));
        }
        if !(self.sigma_d_px.is_finite() && (0.0..=MAX_SIGMA_D_PX).contains(&self.sigma_d_px)) {
            return Err(CoreError::InvalidSensor(format!(
                "disparity noise {} px must be in [0, {MAX_SIGMA_D_PX}]",
                Compact(self.sigma_d_px)
            )));
        }
        Ok(())
    }

    /// The Kinect of the paper: f = 587 px, B = 75 mm, 1/8 px disparity steps.
    pub fn paper_kinect() -> Self {
        crate::preset::PAPER_KINECT.sensor()
    }

    /// The `kinect-v1` default: f = 580 px, B = 0.075 m, 1/8 px steps.
    pub fn kinect_v1() -> Self {
        crate::preset::KINECT_V1.sensor()
    }

    /// `f·B` in pixel·metres: depth (m) times disparity (px).
    pub fn fb(&self) -> f64 {
        self.focal_px * self.baseline_m
    }

    /// Disparity step `1/q`, pixels.
    pub fn disparity_step_px(&self) -> f64 {
        1.0 / f64::from(self.subpixel_steps)
    }

    /// `D = f·B / Z` (pixels) for a depth in metres; 0 for an invalid (non-positive) depth.
    pub fn depth_to_disparity(&self, z_m: f64) -> f64 {
        if z_m > 0.0 { self.fb() / z_m } else { 0.0 }
    }

    /// `Z = f·B / D` (metres) for a disparity in pixels; 0 for an invalid (non-positive)
    /// disparity.
    pub fn disparity_to_depth(&self, d_px: f64) -> f64 {
        if d_px > 0.0 { self.fb() / d_px } else { 0.0 }
    }

    /// Rounds a disparity to the sensor's `1/q` pixel grid.
    pub fn quantize_disparity(&self, d_px: f64) -> f64 {
        let q = f64::from(self.subpixel_steps);
        (d_px * q).round() / q
    }

    /// Depth sensitivity `∂Z/∂D = −Z² / (f·B)`, metres per pixel of disparity.
    pub fn dz_dd(&self, z_m: f64) -> f64 {
        -z_m * z_m / self.fb()
    }

    /// Depth noise `σ_Z = Z²·σ_D / (f·B)`, metres.
    pub fn sigma_z(&self, z_m: f64) -> f64 {
        z_m * z_m * self.sigma_d_px / self.fb()
    }

    /// Depth noise of a disparity noise `sigma_d_px` (overriding the model's), metres.
    pub fn sigma_z_for(&self, z_m: f64, sigma_d_px: f64) -> f64 {
        z_m * z_m * sigma_d_px / self.fb()
    }

    /// The `σ_D` (pixels) of a sensor whose per-pixel disparity-error variance, the error plus
    /// the `1/q` quantisation (`σ_D² + 1/(12q²)`), is `variance_scale` times this model's
    /// (the quantisation kept; this model's own `σ_D` at 1; 0 when the scale leaves nothing for
    /// the error). A frame's own
    /// noise level against its model (`sl_planes::frame_noise_scale`) is such a scale.
    pub fn sigma_d_for_variance_scale(&self, variance_scale: f64) -> f64 {
        if variance_scale == 1.0 {
            return self.sigma_d_px;
        }
        let quant = 1.0 / (12.0 * f64::from(self.subpixel_steps.max(1)).powi(2));
        let var = variance_scale * (self.sigma_d_px * self.sigma_d_px + quant) - quant;
        if var > 0.0 { var.sqrt() } else { 0.0 }
    }

    /// This model with its `σ_D` raised to [`SensorModel::sigma_d_for_variance_scale`]: the
    /// sensor whose pixel variance is `variance_scale` times this one's (itself at 1), its
    /// `σ_D` at most [`MAX_SIGMA_D_PX`], so that the result is a valid model whatever a frame
    /// measured (a frame read at the wrong depth scale measures hundreds of times the
    /// variance, and every command that tracked, fused or filtered it stopped on an invalid
    /// sensor model).
    pub fn with_variance_scale(&self, variance_scale: f64) -> Self {
        Self {
            sigma_d_px: self
                .sigma_d_for_variance_scale(variance_scale)
                .min(MAX_SIGMA_D_PX),
            ..*self
        }
    }

    /// Depth quantum `ΔZ ≈ c·Z²` between neighbouring representable depths, with
    /// `c = 1 / (q·f·B)` per metre.
    pub fn depth_quantum_per_m(&self) -> f64 {
        1.0 / (f64::from(self.subpixel_steps) * self.fb())
    }

    /// Spacing between neighbouring representable depths at `z_m`, metres (`c·Z²`).
    pub fn depth_step_m(&self, z_m: f64) -> f64 {
        self.depth_quantum_per_m() * z_m * z_m
    }
}

impl Default for SensorModel {
    fn default() -> Self {
        Self::kinect_v1()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's worked example (section 2.1): −8.2 mm/px at 600 mm and −51.1 mm/px at
    /// 1500 mm for f = 587 px, B = 75 mm.
    #[test]
    fn paper_depth_sensitivity() {
        let s = SensorModel::paper_kinect();
        let at_600 = s.dz_dd(0.6) * 1000.0;
        let at_1500 = s.dz_dd(1.5) * 1000.0;
        assert!((at_600 - -8.2).abs() < 0.05, "{at_600}");
        assert!((at_1500 - -51.1).abs() < 0.05, "{at_1500}");
    }

    #[test]
    fn disparity_depth_round_trip() {
        let s = SensorModel::kinect_v1();
        for z in [0.5, 1.0, 2.345, 4.0] {
            let d = s.depth_to_disparity(z);
            assert!((s.disparity_to_depth(d) - z).abs() < 1e-12);
        }
        assert_eq!(s.depth_to_disparity(0.0), 0.0);
        assert_eq!(s.disparity_to_depth(-1.0), 0.0);
    }

    /// A frame measured far noisier than any sensor (read at the wrong depth scale) still
    /// gives a valid model, at the largest σ_D one may have: tracking and fusing it stopped on
    /// "invalid sensor model: disparity noise 1.65e1 px" before.
    #[test]
    fn variance_scaled_models_stay_valid() {
        let s = SensorModel::kinect_v1();
        for scale in [1.0, 4.0, 1e5, 1e300, f64::INFINITY] {
            let scaled = s.with_variance_scale(scale);
            assert!(scaled.validate().is_ok(), "{scale}: {scaled:?}");
        }
        assert_eq!(s.with_variance_scale(1e5).sigma_d_px, MAX_SIGMA_D_PX);
        let four = s.with_variance_scale(4.0).sigma_d_px;
        assert_eq!(four, s.sigma_d_for_variance_scale(4.0));
        assert!(four > 2.0 * s.sigma_d_px && four < MAX_SIGMA_D_PX, "{four}");
    }

    /// Refused values come back as written (`-0.075`, `0`), not as `-7.5e-2` and `0e0`.
    #[test]
    fn refused_values_are_repeated_compactly() {
        let e = |s: Result<SensorModel>| s.unwrap_err().to_string();
        let b = e(SensorModel::new(580.0, -0.075, 8, 0.07));
        assert!(b.contains("baseline -0.075 m must be in (0, 10]"), "{b}");
        let f = e(SensorModel::new(0.0, 0.075, 8, 0.07));
        assert!(f.contains("focal length 0 px must be in [1, 1e7]"), "{f}");
        let d = e(SensorModel::new(580.0, 0.075, 8, 16.5));
        assert!(d.contains("disparity noise 16.5 px"), "{d}");
    }

    #[test]
    fn sigma_z_is_quadratic() {
        let s = SensorModel::kinect_v1();
        let r = s.sigma_z(3.0) / s.sigma_z(1.5);
        assert!((r - 4.0).abs() < 1e-12);
        assert!((s.sigma_z(2.0) - 4.0 * s.sigma_d_px / s.fb()).abs() < 1e-15);
    }

    #[test]
    fn quantum_matches_readme_steps() {
        // The data README: about 3 mm at 1 m, 11-12 mm at 2 m, 26 mm at 3 m.
        let s = SensorModel::kinect_v1();
        assert!((s.depth_step_m(1.0) * 1000.0 - 2.87).abs() < 0.1);
        assert!((s.depth_step_m(2.0) * 1000.0 - 11.5).abs() < 0.3);
        assert!((s.depth_step_m(3.0) * 1000.0 - 25.9).abs() < 0.5);
    }

    #[test]
    fn quantize_to_eighth_pixel() {
        let s = SensorModel::kinect_v1();
        assert_eq!(s.quantize_disparity(10.06), 10.0);
        assert_eq!(s.quantize_disparity(10.07), 10.125);
    }

    #[test]
    fn validation() {
        assert!(SensorModel::new(580.0, 0.0, 8, 0.1).is_err());
        assert!(SensorModel::new(580.0, 0.075, 0, 0.1).is_err());
        assert!(SensorModel::new(580.0, 0.075, 8, -0.1).is_err());
        assert!(SensorModel::new(580.0, 0.075, 8, 0.1).is_ok());
    }
}
