//! The public filter API: [`DepthFilter`], [`Method`] and the sensor-derived defaults.

use std::fmt;
use std::str::FromStr;

use sl_core::{DepthImage, DepthView, SensorModel};

use crate::error::{FilterError, Result};
use crate::kernel::{self, Adaptive, Fixed, INVALID_FILL, Isa, NoRange, Source, Taps};
use crate::weight::{E_SCALE, LOG2_E, TapExp};

/// Multiplier `m` of the default adaptive coefficient `k = m·σ_D/(f·B)`: the range σ of the
/// adaptive filter is `m` times the sensor's depth noise `σ_Z(Z) = Z²·σ_D/(f·B)`.
///
/// Chosen by measurement: `cargo xtask validate` sweeps `m` ∈ {1, 2, 3, 4, 6, 8, 10, 12, 16, 24,
/// 32} on simulated Kinect frames (the tilted floor 0.8–3.9 m, the figure before two walls, a
/// book 1 cm above a table, boxes on a floor; 3 noise seeds each; 7×7 window, σ_s = 1.5 px) and
/// `m = 10` has the lowest RMSE against ground truth over all pixels (2.34 mm; 8 and 12 are
/// within 1 %, 4 gives 2.81 mm, 24 gives 3.36 mm). A range σ of ten noise σ sounds large, but
/// the Kinect's depth is quantised in steps of `Z²/(q·f·B)` ≈ 1.8 σ_Z, so a few steps must be
/// averaged; the range kernel still rejects real depth jumps of more than ~3 σ_d (5 cm at 1 m).
pub const DEFAULT_K_MULTIPLIER: f64 = 10.0;

/// Default window radius: 3, a 7×7 window.
pub const DEFAULT_RADIUS_PX: usize = 3;

/// Largest supported window radius (a 65×65 window).
pub const MAX_RADIUS_PX: usize = 32;

/// Largest supported depth, metres (valid depths above it are an error, not silently dropped).
pub const MAX_DEPTH_M: f32 = 1.0e4;
/// Smallest supported depth, metres.
pub const MIN_DEPTH_M: f32 = 1.0e-6;

/// Memory budget: images with more pixels than this are refused (the filter allocates one padded
/// copy and one output of about this size, 256 MiB each at the limit).
pub const MAX_PIXELS: usize = 1 << 26;

/// Depth at which the default fixed-σ bilateral matches the default adaptive filter, metres:
/// the default `σ_d` of [`DepthFilter::default_for`]`(Method::Bilateral, …)` is
/// `k·(2 m)²`, i.e. the adaptive σ in the middle of the Kinect's range.
pub const BILATERAL_DEFAULT_DEPTH_M: f64 = 2.0;

/// The default adaptive coefficient for a sensor: `k = m·σ_D/(f·B)` per metre, with
/// `m =` [`DEFAULT_K_MULTIPLIER`], so that `σ_d(Z) = k·Z² = m·σ_Z(Z)`.
pub fn default_k_per_m(sensor: &SensorModel) -> f64 {
    DEFAULT_K_MULTIPLIER * sensor.sigma_d_px / sensor.fb()
}

/// The default spatial σ for a radius: `r/2` pixels (at least 0.5), so the window spans ±2σ_s.
pub fn default_sigma_s_px(radius_px: usize) -> f64 {
    (radius_px as f64 / 2.0).max(0.5)
}

/// The four filters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Gaussian smoothing (spatial weights only), normalised over the valid pixels.
    Gaussian,
    /// Bilateral filter with a fixed range σ in metres (paper eq. 3–5).
    Bilateral,
    /// Adaptive bilateral filter, `σ_d(p) = k·Z(p)²` (paper eq. 6).
    Adaptive,
    /// Bilateral filter on disparity `D = f·B/Z` with a constant σ in pixels, converted back.
    Disparity,
}

impl Method {
    /// The names of [`Method::ALL`], in the same order (`--method` values).
    pub const NAMES: [&'static str; 4] = ["gaussian", "bilateral", "adaptive", "disparity"];
    /// All methods, in the order of the docs.
    pub const ALL: [Method; 4] = [
        Method::Gaussian,
        Method::Bilateral,
        Method::Adaptive,
        Method::Disparity,
    ];

    /// The lowercase name used by the CLI.
    pub fn name(self) -> &'static str {
        match self {
            Method::Gaussian => "gaussian",
            Method::Bilateral => "bilateral",
            Method::Adaptive => "adaptive",
            Method::Disparity => "disparity",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = FilterError;
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                FilterError::InvalidParameter(format!(
                    "unknown method {s:?} (gaussian, bilateral, adaptive, disparity)"
                ))
            })
    }
}

/// The shape of the window.
///
/// [`Window::Square`] (the default) uses every pixel of the `(2r+1)×(2r+1)` square;
/// [`Window::Disc`] only those with `dx² + dy² ≤ r²` — OpenCV's `bilateralFilter` rule, 13 taps
/// at 5×5 instead of 25 and 29 instead of 49 at 7×7 — so the kernel is isotropic (the square
/// reaches `√2·r` along the diagonals) and about half as costly. With the default `σ_s = r/2`
/// the dropped corner taps carry about 9 % (5×5) and 6 % (7×7) of the spatial weight, so fewer
/// samples are averaged: on simulated Kinect frames the adaptive filter's RMSE against the truth
/// is 8–12 % higher with white noise at 5×5 (0–9 % at 7×7) and 1–2 % higher with the realistic
/// correlated noise (measurements in `docs/bench/README.md`). A speed option, not the default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Window {
    /// The full square `(2r+1)×(2r+1)`.
    #[default]
    Square,
    /// The disc `dx² + dy² ≤ r²`.
    Disc,
}

impl Window {
    /// The names of [`Window::ALL`], in the same order.
    pub const NAMES: [&'static str; 2] = ["square", "disc"];
    /// Both shapes.
    pub const ALL: [Window; 2] = [Window::Square, Window::Disc];

    /// The lowercase name used by the CLI and Python.
    pub fn name(self) -> &'static str {
        match self {
            Window::Square => "square",
            Window::Disc => "disc",
        }
    }

    /// Whether the tap at offset `(dx, dy)` belongs to a window of radius `r`.
    pub fn contains(self, dx: i64, dy: i64, r: i64) -> bool {
        match self {
            Window::Square => dx.abs() <= r && dy.abs() <= r,
            Window::Disc => dx * dx + dy * dy <= r * r,
        }
    }
}

impl fmt::Display for Window {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Window {
    type Err = FilterError;
    fn from_str(s: &str) -> Result<Self> {
        Window::ALL
            .into_iter()
            .find(|w| w.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                FilterError::InvalidParameter(format!("unknown window {s:?} (square, disc)"))
            })
    }
}

/// The range kernel of a filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RangeKernel {
    /// No range weight: the Gaussian filter.
    None,
    /// A fixed range σ in metres.
    Fixed {
        /// Range σ, metres.
        sigma_d_m: f64,
    },
    /// `σ_d(p) = k·Z(p)²`.
    Adaptive {
        /// `k`, per metre.
        k_per_m: f64,
    },
    /// A fixed σ in disparity pixels, applied to `D = fb/Z`.
    Disparity {
        /// Range σ in disparity, pixels.
        sigma_disp_px: f64,
        /// `f·B`, pixel·metres.
        fb_px_m: f64,
    },
}

/// A configured depth filter. Build it with [`DepthFilter::default_for`] (sensor-derived
/// defaults, no tuning) or one of the explicit constructors, then [`DepthFilter::apply`] it.
///
/// **Invalid pixels** (0, negative or non-finite) never contribute and are never filled: the
/// output is invalid (0) exactly where the input is. **Borders:** the window is clipped at the
/// image border and the weights are renormalised over the valid pixels inside the image (the
/// same rule as for holes), so border pixels are smoothed with fewer neighbours, never with
/// replicated or mirrored values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthFilter {
    /// Window radius `r`: the window is `(2r+1)×(2r+1)`, or the disc of radius `r` inside it.
    pub radius_px: usize,
    /// The window's shape (default [`Window::Square`]).
    pub window: Window,
    /// Spatial σ, pixels.
    pub sigma_s_px: f64,
    /// The range kernel (which also selects the method).
    pub range: RangeKernel,
}

impl DepthFilter {
    /// Gaussian smoothing.
    pub fn gaussian(radius_px: usize, sigma_s_px: f64) -> Self {
        Self {
            radius_px,
            window: Window::Square,
            sigma_s_px,
            range: RangeKernel::None,
        }
    }

    /// Bilateral filter with a fixed range σ (metres).
    pub fn bilateral(radius_px: usize, sigma_s_px: f64, sigma_d_m: f64) -> Self {
        Self {
            radius_px,
            window: Window::Square,
            sigma_s_px,
            range: RangeKernel::Fixed { sigma_d_m },
        }
    }

    /// Adaptive bilateral filter, `σ_d(p) = k·Z(p)²`.
    pub fn adaptive(radius_px: usize, sigma_s_px: f64, k_per_m: f64) -> Self {
        Self {
            radius_px,
            window: Window::Square,
            sigma_s_px,
            range: RangeKernel::Adaptive { k_per_m },
        }
    }

    /// Disparity-domain bilateral filter with range σ `sigma_disp_px` (disparity pixels).
    pub fn disparity(
        radius_px: usize,
        sigma_s_px: f64,
        sigma_disp_px: f64,
        sensor: &SensorModel,
    ) -> Self {
        Self {
            radius_px,
            window: Window::Square,
            sigma_s_px,
            range: RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m: sensor.fb(),
            },
        }
    }

    /// The defaults for `method` and a sensor: radius [`DEFAULT_RADIUS_PX`], σ_s from
    /// [`default_sigma_s_px`], adaptive `k` from [`default_k_per_m`], bilateral σ_d =
    /// `k·(2 m)²`, disparity σ = `m·σ_D` (the same noise multiple, in disparity).
    pub fn default_for(method: Method, sensor: &SensorModel) -> Self {
        let r = DEFAULT_RADIUS_PX;
        let s = default_sigma_s_px(r);
        let k = default_k_per_m(sensor);
        match method {
            Method::Gaussian => Self::gaussian(r, s),
            Method::Bilateral => Self::bilateral(
                r,
                s,
                k * BILATERAL_DEFAULT_DEPTH_M * BILATERAL_DEFAULT_DEPTH_M,
            ),
            Method::Adaptive => Self::adaptive(r, s, k),
            Method::Disparity => {
                Self::disparity(r, s, DEFAULT_K_MULTIPLIER * sensor.sigma_d_px, sensor)
            }
        }
    }

    /// The same filter with another radius.
    pub fn with_radius(mut self, radius_px: usize) -> Self {
        self.radius_px = radius_px;
        self
    }

    /// The same filter with another window shape.
    pub fn with_window(mut self, window: Window) -> Self {
        self.window = window;
        self
    }

    /// The same filter with another spatial σ.
    pub fn with_sigma_s(mut self, sigma_s_px: f64) -> Self {
        self.sigma_s_px = sigma_s_px;
        self
    }

    /// Which of the four methods this is.
    pub fn method(&self) -> Method {
        match self.range {
            RangeKernel::None => Method::Gaussian,
            RangeKernel::Fixed { .. } => Method::Bilateral,
            RangeKernel::Adaptive { .. } => Method::Adaptive,
            RangeKernel::Disparity { .. } => Method::Disparity,
        }
    }

    /// Checks the parameters: `1 ≤ r ≤` [`MAX_RADIUS_PX`], `0 < σ_s ≤ 1000` px,
    /// `10⁻⁶ ≤ σ_d ≤ 1000` m, `10⁻⁶ ≤ k ≤ 1000` /m, `10⁻⁶ ≤ σ_D ≤ 1000` px, `f·B > 0`.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: String| Err(FilterError::InvalidParameter(what));
        if self.radius_px == 0 || self.radius_px > MAX_RADIUS_PX {
            return bad(format!(
                "radius {} px must be in 1..={MAX_RADIUS_PX}",
                self.radius_px
            ));
        }
        let in_range = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        if !(in_range(self.sigma_s_px, f64::MIN_POSITIVE, 1.0e3)) {
            return bad(format!(
                "sigma_s {:e} px must be in (0, 1000]",
                self.sigma_s_px
            ));
        }
        match self.range {
            RangeKernel::None => {}
            RangeKernel::Fixed { sigma_d_m } if !in_range(sigma_d_m, 1e-6, 1e3) => {
                return bad(format!("sigma_d {sigma_d_m:e} m must be in [1e-6, 1000]"));
            }
            RangeKernel::Adaptive { k_per_m } if !in_range(k_per_m, 1e-6, 1e3) => {
                return bad(format!(
                    "k {k_per_m:e} per m must be in [1e-6, 1000] (the adaptive range σ_d = k·Z²; by \
                     default k is derived from the camera's disparity noise, σ_D/(f·B): a \
                     noise-free camera, σ_D = 0, needs k given explicitly)"
                ));
            }
            RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m,
            } => {
                if !in_range(sigma_disp_px, 1e-6, 1e3) {
                    return bad(format!(
                        "disparity sigma {sigma_disp_px:e} px must be in [1e-6, 1000]"
                    ));
                }
                if !in_range(fb_px_m, 1e-6, 1e9) {
                    return bad(format!(
                        "f*B {} px*m must be positive",
                        sl_core::Compact(fb_px_m)
                    ));
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The normalised spatial weights `ŵ(δ)` of the window, row-major `(2r+1)²` (0 outside a
    /// disc window).
    pub fn spatial_weights(&self) -> Vec<f64> {
        let r = self.radius_px as i64;
        let mut w = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
        for dy in -r..=r {
            for dx in -r..=r {
                w.push(if self.window.contains(dx, dy, r) {
                    (-((dx * dx + dy * dy) as f64) / (2.0 * self.sigma_s_px * self.sigma_s_px))
                        .exp()
                } else {
                    0.0
                });
            }
        }
        let s: f64 = w.iter().sum();
        w.iter().map(|v| v / s).collect()
    }

    /// `Σ ŵ(δ)·|δ|²` over the full window, px²: the second moment of the spatial kernel, which
    /// sets the curvature bias on tilted planes (see the crate docs).
    pub fn spatial_second_moment_px2(&self) -> f64 {
        let r = self.radius_px as i64;
        let w = self.spatial_weights();
        let mut m = 0.0;
        let mut i = 0;
        for dy in -r..=r {
            for dx in -r..=r {
                m += w[i] * (dx * dx + dy * dy) as f64;
                i += 1;
            }
        }
        m
    }

    /// Filters `depth` (using the best instruction set of this CPU and all rayon threads; run it
    /// inside `ThreadPool::install` to choose the threads).
    ///
    /// `depth` is a `&DepthImage` or a [`DepthView`] over a buffer the caller owns (no copy).
    pub fn apply<'a>(&self, depth: impl Into<DepthView<'a>>) -> Result<DepthImage> {
        self.apply_with_isa(depth, Isa::detect())
    }

    /// Like [`DepthFilter::apply`] with an explicit instruction set (for tests and benchmarks;
    /// an unsupported one falls back to the portable code).
    pub fn apply_with_isa<'a>(
        &self,
        depth: impl Into<DepthView<'a>>,
        isa: Isa,
    ) -> Result<DepthImage> {
        let depth: DepthView<'a> = depth.into();
        let (w, h) = (depth.width(), depth.height());
        Self::check_size(w, h)?;
        let mut out = vec![0.0f32; w * h];
        self.apply_into(depth, isa, &mut out)?;
        Ok(DepthImage::from_vec(w, h, out)?)
    }

    /// The pixel budget of one image.
    fn check_size(w: usize, h: usize) -> Result<()> {
        if w.checked_mul(h).is_none_or(|n| n > MAX_PIXELS) {
            return Err(FilterError::ImageSize(format!(
                "{w}x{h} exceeds the budget of {MAX_PIXELS} pixels"
            )));
        }
        Ok(())
    }

    /// [`DepthFilter::apply_with_isa`] into `out` (`width × height`, every pixel written), for
    /// callers that reuse their buffers.
    pub(crate) fn apply_into(&self, depth: DepthView<'_>, isa: Isa, out: &mut [f32]) -> Result<()> {
        self.apply_dilated_into(depth, 1, None, isa, out)
    }

    /// [`DepthFilter::apply_into`] with the window's taps `step` pixels apart (a dilated, "à
    /// trous" pass: the window reaches `radius · step` pixels; `step = 1` is the filter
    /// itself). The same as filtering each of the image's `step × step` polyphase sub-images
    /// (every `step`-th pixel of every `step`-th row) with the filter and interleaving them
    /// back, without copying them out: a window clipped by a sub-image's border is the dilated
    /// window clipped by the image's. With `keep` (`width × height`), the output is the input
    /// wherever `keep` is false.
    pub(crate) fn apply_dilated_into(
        &self,
        depth: DepthView<'_>,
        step: usize,
        keep: Option<&[bool]>,
        isa: Isa,
        out: &mut [f32],
    ) -> Result<()> {
        self.validate()?;
        if step == 0 {
            return Err(FilterError::InvalidParameter(
                "the taps of a dilated window must be at least 1 px apart".into(),
            ));
        }
        let (w, h) = (depth.width(), depth.height());
        Self::check_size(w, h)?;
        if out.len() != w * h || keep.is_some_and(|k| k.len() != w * h) {
            let mask = keep.map_or(String::new(), |k| format!(" and a mask of {}", k.len()));
            return Err(FilterError::ImageSize(format!(
                "output of {} pixels{mask} for a {w}x{h} image",
                out.len()
            )));
        }
        let isa = if isa.is_supported() {
            isa
        } else {
            Isa::Portable
        };
        let r = self.radius_px;
        let k = 2 * r + 1;
        let inv2s2 = 1.0 / (2.0 * self.sigma_s_px * self.sigma_s_px);
        // Gaussian: linear spatial weights. Range filters: the spatial exponent
        // t = −d²/(2σ_s²)·log2 e of each tap, folded into the range weight's constants.
        let mut taps = Vec::with_capacity(k * k);
        let mut exps = Vec::with_capacity(k * k);
        for dy in 0..k {
            for dx in 0..k {
                let d2 = (dx.abs_diff(r).pow(2) + dy.abs_diff(r).pow(2)) as f64;
                match self.range {
                    // Spatial weights below 1e-30 are 0 (no subnormal products; see `weight`).
                    RangeKernel::None => {
                        let w = (-d2 * inv2s2).exp();
                        taps.push(if w > 1e-30 { w as f32 } else { 0.0 });
                    }
                    _ => {
                        let t = -d2 * inv2s2 * std::f64::consts::LOG2_E;
                        exps.push(TapExp::new(t));
                    }
                }
            }
        }
        let taps = Taps {
            radius: r,
            step,
            disc: self.window == Window::Disc,
            taps: &taps,
            exps: &exps,
        };
        let log2e = f64::from(LOG2_E);
        // Range scale √(log2 e / (2σ²)); for the adaptive filter √(log2 e / 2) / k. Times
        // 2^11.5, the range weight's unit (`weight`).
        let coef = |sigma: f64| ((log2e / 2.0).sqrt() / sigma * E_SCALE).min(1e15) as f32;
        let mut src = Source {
            data: depth.data(),
            width: w,
            height: h,
            fill: INVALID_FILL,
            disparity_fb: None,
            min_m: MIN_DEPTH_M,
            max_m: MAX_DEPTH_M,
            keep,
        };
        let ok = match self.range {
            RangeKernel::None => {
                src.fill = 0.0;
                kernel::run(isa, taps, &src, out, NoRange)
            }
            RangeKernel::Fixed { sigma_d_m } => {
                kernel::run(isa, taps, &src, out, Fixed(coef(sigma_d_m)))
            }
            RangeKernel::Adaptive { k_per_m } => {
                kernel::run(isa, taps, &src, out, Adaptive(coef(k_per_m)))
            }
            RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m,
            } => {
                src.disparity_fb = Some(fb_px_m as f32);
                kernel::run(isa, taps, &src, out, Fixed(coef(sigma_disp_px)))
            }
        };
        if !ok {
            return Err(out_of_range(depth));
        }
        Ok(())
    }
}

/// The error for the first valid depth outside `[MIN_DEPTH_M, MAX_DEPTH_M]`.
fn out_of_range(depth: DepthView<'_>) -> FilterError {
    let w = depth.width().max(1);
    let found = depth
        .data()
        .iter()
        .enumerate()
        .find(|&(_, &z)| z > 0.0 && z.is_finite() && !(MIN_DEPTH_M..=MAX_DEPTH_M).contains(&z));
    match found {
        Some((i, &z)) => FilterError::DepthOutOfRange {
            value_m: z,
            x: i % w,
            y: i / w,
            min_m: MIN_DEPTH_M,
            max_m: MAX_DEPTH_M,
        },
        None => FilterError::ImageSize("inconsistent range check".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().unwrap(), m);
            assert_eq!(
                DepthFilter::default_for(m, &SensorModel::kinect_v1()).method(),
                m
            );
        }
        assert!("median".parse::<Method>().is_err());
    }

    #[test]
    fn window_names_round_trip_and_the_disc_is_opencvs() {
        for (w, n) in Window::ALL.into_iter().zip(Window::NAMES) {
            assert_eq!(w.to_string(), n);
            assert_eq!(n.parse::<Window>().unwrap(), w);
        }
        assert!("round".parse::<Window>().is_err());
        // OpenCV's bilateralFilter keeps dx² + dy² ≤ r²: 13 taps at 5×5, 29 at 7×7.
        let taps = |r: i64| {
            (-r..=r)
                .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
                .filter(|&(dx, dy)| Window::Disc.contains(dx, dy, r))
                .count()
        };
        assert_eq!((taps(1), taps(2), taps(3)), (5, 13, 29));
        let f = DepthFilter::gaussian(2, 1.0).with_window(Window::Disc);
        let w = f.spatial_weights();
        assert_eq!(w.iter().filter(|&&v| v > 0.0).count(), 13);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn validation_rejects_nonsense() {
        let s = SensorModel::kinect_v1();
        assert!(DepthFilter::gaussian(0, 1.0).validate().is_err());
        assert!(
            DepthFilter::gaussian(MAX_RADIUS_PX + 1, 1.0)
                .validate()
                .is_err()
        );
        assert!(DepthFilter::gaussian(2, 0.0).validate().is_err());
        assert!(DepthFilter::gaussian(2, f64::NAN).validate().is_err());
        assert!(DepthFilter::bilateral(2, 1.0, -0.01).validate().is_err());
        assert!(
            DepthFilter::adaptive(2, 1.0, f64::INFINITY)
                .validate()
                .is_err()
        );
        assert!(DepthFilter::disparity(2, 1.0, 0.0, &s).validate().is_err());
        for m in Method::ALL {
            assert!(DepthFilter::default_for(m, &s).validate().is_ok());
        }
    }

    #[test]
    fn default_k_is_a_multiple_of_the_depth_noise() {
        let s = SensorModel::kinect_v1();
        let k = default_k_per_m(&s);
        for z in [0.8, 2.0, 4.0] {
            assert!((k * z * z - DEFAULT_K_MULTIPLIER * s.sigma_z(z)).abs() < 1e-12);
        }
    }

    #[test]
    fn names_parse_and_print_the_same_way() {
        for (m, n) in Method::ALL.into_iter().zip(Method::NAMES) {
            assert_eq!(m.name(), n);
            assert_eq!(m.to_string(), n);
            assert_eq!(n.parse::<Method>().unwrap(), m);
        }
    }

    #[test]
    fn out_of_range_depth_is_an_error_not_a_hole() {
        let mut d = DepthImage::from_vec(8, 8, vec![1.0; 64]).unwrap();
        d.data_mut()[9] = 1.0e6;
        let e = DepthFilter::default_for(Method::Adaptive, &SensorModel::kinect_v1()).apply(&d);
        assert!(
            matches!(e, Err(FilterError::DepthOutOfRange { x: 1, y: 1, .. })),
            "{e:?}"
        );
    }

    /// The range check of the padded copy at every column of rows of several widths (the
    /// vectorised part of a row and its remainder), with every instruction set and both
    /// domains; invalid values (0, negative, NaN, ±inf) are holes, not range errors.
    #[test]
    fn the_range_check_sees_every_column() {
        let s = SensorModel::kinect_v1();
        let filters = [
            DepthFilter::default_for(Method::Adaptive, &s),
            DepthFilter::default_for(Method::Disparity, &s),
        ];
        for w in [7usize, 8, 9, 15, 16, 19] {
            let mut base = vec![1.5f32; w * 5];
            base[3] = f32::NAN;
            base[w] = f32::INFINITY;
            base[w + 1] = f32::NEG_INFINITY;
            base[2 * w] = -2.0;
            base[2 * w + 1] = 0.0;
            for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
                for f in &filters {
                    let clean = DepthImage::from_vec(w, 5, base.clone()).unwrap();
                    assert!(f.apply_with_isa(&clean, isa).is_ok(), "w {w} {isa:?}");
                    for x in 0..w {
                        for bad in [MIN_DEPTH_M / 2.0, MAX_DEPTH_M * 2.0] {
                            let mut d = base.clone();
                            d[3 * w + x] = bad;
                            let d = DepthImage::from_vec(w, 5, d).unwrap();
                            let e = f.apply_with_isa(&d, isa);
                            assert!(
                                matches!(e, Err(FilterError::DepthOutOfRange { y: 3, .. })),
                                "w {w} x {x} {bad} {isa:?}: {e:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn second_moment_of_a_wide_kernel_approaches_two_sigma_squared() {
        let f = DepthFilter::gaussian(12, 2.0);
        assert!((f.spatial_second_moment_px2() - 8.0).abs() < 1e-3);
        // Truncation lowers it.
        assert!(DepthFilter::gaussian(2, 2.0).spatial_second_moment_px2() < 8.0);
    }

    #[test]
    fn empty_image_is_fine() {
        let d = DepthImage::invalid(0, 0);
        let out = DepthFilter::gaussian(2, 1.0).apply(&d).unwrap();
        assert_eq!(out.width(), 0);
    }
}
