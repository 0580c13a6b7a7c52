//! [`FilterConfig`]: a filter described the way users choose one — a method plus optional
//! overrides — turned into a [`DepthFilter`] for a camera's sensor model. The CLI's `filter`
//! options and the Python `sldepth.filter` keywords both map onto it.

use sl_core::SensorModel;

use crate::error::{FilterError, Result};
use crate::filter::{DepthFilter, Method, RangeKernel, Window, default_sigma_s_px};

/// A filter choice: the method and any parameter the user set; everything left `None` takes
/// the sensor-derived default of [`DepthFilter::default_for`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct FilterConfig {
    /// The method (default: the paper's adaptive bilateral filter).
    pub method: Method,
    /// Window radius, pixels (window `2r + 1`); default 3, or `⌈2σ_s⌉` when only σ_s is set.
    pub radius_px: Option<usize>,
    /// Spatial σ, pixels; default from the radius ([`default_sigma_s_px`]).
    pub sigma_s_px: Option<f64>,
    /// The window's shape (default [`Window::Square`]).
    pub window: Window,
    /// Range σ of the fixed bilateral filter, metres (bilateral only).
    pub sigma_d_m: Option<f64>,
    /// `k` of the adaptive range σ `σ_d = k·Z²`, per metre (adaptive only).
    pub k_per_m: Option<f64>,
    /// Range σ in disparity, pixels (disparity only).
    pub sigma_disp_px: Option<f64>,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self::new(Method::Adaptive)
    }
}

impl FilterConfig {
    /// The defaults of `method`.
    pub fn new(method: Method) -> Self {
        Self {
            method,
            radius_px: None,
            sigma_s_px: None,
            window: Window::Square,
            sigma_d_m: None,
            k_per_m: None,
            sigma_disp_px: None,
        }
    }

    /// Checks that every parameter set belongs to the method.
    pub fn validate(&self) -> Result<()> {
        let m = self.method;
        let misplaced = |name: &str, owner: Method| {
            FilterError::InvalidParameter(format!(
                "{name} applies to method {owner} (got method {m})"
            ))
        };
        if self.k_per_m.is_some() && m != Method::Adaptive {
            return Err(misplaced("k", Method::Adaptive));
        }
        if self.sigma_d_m.is_some() && m != Method::Bilateral {
            return Err(misplaced("sigma_d_m", Method::Bilateral));
        }
        if self.sigma_disp_px.is_some() && m != Method::Disparity {
            return Err(misplaced("sigma_disp_px", Method::Disparity));
        }
        Ok(())
    }

    /// The filter for a sensor: the method's defaults with every set parameter applied, checked
    /// by [`DepthFilter::validate`].
    pub fn build(&self, sensor: &SensorModel) -> Result<DepthFilter> {
        self.validate()?;
        let mut f = DepthFilter::default_for(self.method, sensor);
        let radius = match (self.radius_px, self.sigma_s_px) {
            (Some(r), _) => r,
            (None, Some(s)) if s.is_finite() && s > 0.0 => ((2.0 * s).ceil() as usize).max(1),
            _ => f.radius_px,
        };
        f = f.with_radius(radius).with_window(self.window).with_sigma_s(
            self.sigma_s_px
                .unwrap_or_else(|| default_sigma_s_px(radius)),
        );
        f.range = match f.range {
            RangeKernel::Fixed { sigma_d_m } => RangeKernel::Fixed {
                sigma_d_m: self.sigma_d_m.unwrap_or(sigma_d_m),
            },
            RangeKernel::Adaptive { k_per_m } => RangeKernel::Adaptive {
                k_per_m: self.k_per_m.unwrap_or(k_per_m),
            },
            RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m,
            } => RangeKernel::Disparity {
                sigma_disp_px: self.sigma_disp_px.unwrap_or(sigma_disp_px),
                fb_px_m,
            },
            RangeKernel::None => RangeKernel::None,
        };
        f.validate()?;
        Ok(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_sensor_defaults() {
        let s = SensorModel::kinect_v1();
        for m in Method::ALL {
            assert_eq!(
                FilterConfig::new(m).build(&s).unwrap(),
                DepthFilter::default_for(m, &s)
            );
        }
    }

    #[test]
    fn overrides_apply_and_misplaced_ones_are_errors() {
        let s = SensorModel::kinect_v1();
        let f = FilterConfig {
            radius_px: Some(2),
            k_per_m: Some(0.5),
            ..FilterConfig::new(Method::Adaptive)
        }
        .build(&s)
        .unwrap();
        assert_eq!(f.radius_px, 2);
        assert_eq!(f.range, RangeKernel::Adaptive { k_per_m: 0.5 });
        let only_sigma = FilterConfig {
            sigma_s_px: Some(2.2),
            ..FilterConfig::new(Method::Gaussian)
        };
        assert_eq!(only_sigma.build(&s).unwrap().radius_px, 5);
        let bad = FilterConfig {
            k_per_m: Some(0.5),
            ..FilterConfig::new(Method::Bilateral)
        };
        assert!(bad.build(&s).unwrap_err().to_string().contains("adaptive"));
        let nan = FilterConfig {
            sigma_s_px: Some(f64::NAN),
            ..FilterConfig::default()
        };
        assert!(nan.build(&s).is_err());
    }
}
