//! [`PlaneConfig`]: the extractor's parameters, their defaults and their validation.

use super::*;

/// Parameters of the disparity-domain extractor.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct PlaneConfig {
    /// Fixed residual threshold `τ` in disparity pixels: a pixel belongs to a plane when
    /// `|D − D_plane| < τ`.
    pub threshold_px: f64,
    /// Threshold on the magnitude of the box-LoG response, disparity pixels, for the camera's
    /// noise: a frame measured noisier ([`PlaneConfig::estimate_noise`]) gets it times the
    /// square root of its variance scale, since the LoG is linear in the disparity and its
    /// noise grows as the frame's does.
    pub log_threshold_px: f64,
    /// Scale of the LoG, pixels.
    pub log_sigma_px: f64,
    /// Minimum pixels of a seed component and of an output plane, pixels of the sensor (a
    /// frame decimated by `n` from its sensor, `sl_core::Camera::resampled`, is extracted on
    /// the sensor's grid, where each of its pixels counts `n²`).
    pub min_pixels: usize,
    /// Maximum refinement iterations (coarse passes) before the final pass.
    pub max_iterations: usize,
    /// Two planes merge when the least-squares plane of their union fits each of them with an
    /// RMS residual below this, pixels (of the cell-averaged disparity); they also merge, with
    /// no parameter, when the noise model says one affine function explains both (the extra
    /// residual sum of squares of one fit within χ²₃ at 99.9 %, the patch seeding's test).
    pub merge_px: f64,
    /// Disconnected pieces of a plane smaller than this are dropped (0 keeps all).
    pub min_piece_pixels: usize,
    /// Width of the window over which the disparity error is correlated, pixels of the sensor
    /// (the block-matching window of a Kinect-class camera; 1 = white noise; a camera resampled
    /// from its sensor, `sl_core::Camera::resampled`, sees it scaled by
    /// `Camera::pixels_per_sensor_pixel`). With the sensor's `σ_D` and `q` it sets the noise of
    /// the patch fits that seed the planes (see `docs/NOISE_MODEL.md`: 9 × 11 px fitted on real
    /// frames).
    pub noise_window_x_px: f64,
    /// Height of that window, pixels.
    pub noise_window_y_px: f64,
    /// Largest curvature of one surface's disparity that the sensor's low-frequency distortion
    /// makes, px/px² at a focal length of 585 px (scaled as `585/f` for other cameras).
    /// Adjacent planes whose affine functions meet along their border, whose slopes at the
    /// border agree within the noise once this bend is allowed for, and whose whole fits'
    /// slopes differ by no more than this curvature times the distance between their centroids
    /// are pieces of one bent surface and take one label (the `bend` stage; 0 = never). The
    /// default, 7.7·10⁻⁵, is the largest curvature measured on the real planes of ≥ 40,000
    /// pixels of TUM fr1 and 7-Scenes frames (docs/bench/README.md, session 12).
    pub bend_px_per_px2: f64,
    /// Planes whose normal the noise model determines less well than this, degrees
    /// ([`PlaneInfo::normal_sigma_deg`]), are not reported (their pixels are left unlabelled);
    /// infinite (the default) reports every plane. On the simulated rooms the spurious planes
    /// are the uncertain ones (examined rooms: all 5 above 1.5°, against 97 % of the correct
    /// planes below it; docs/bench/README.md, session 36): a user who needs only planes whose
    /// parameters can be trusted (landmarks, motion) sets this, at the price of small, far or
    /// narrow true planes.
    pub max_normal_sigma_deg: f64,
    /// Whether planes whose residual has the shape of a fold — curved beyond what the
    /// distortion (`bend_px_per_px2`) and the noise allow, and fitted better by two affine
    /// pieces meeting along a line than by any smooth quadratic — are split along it (the
    /// `crease` stage; the default). Far creases between two surfaces, or a box face with a
    /// strip of the wall beside it, otherwise come out as one plane spanning both.
    pub split_creases: bool,
    /// Whether the pixels along a crease between two planes are re-decided with the planes'
    /// local fits where a plane's whole fit is off there (the `seam` stage; off by default).
    /// A surface bent by the sensor's low-frequency distortion is otherwise cut a few pixels
    /// inside it, and a small neighbour takes a strip of it. On the simulated rooms with a
    /// 0.5 / 1 px radial distortion it takes the spurious planes from 17 / 26 to 8 / 14 and
    /// changes nothing without distortion; on real frames (bent surfaces) it costs 0.1–0.3 ms
    /// per 640×480 frame and leaves their repeatability where it was (docs/bench/README.md,
    /// session 43).
    pub refine_seams: bool,
    /// Whether the pieces of a neighbouring surface that a plane took in are given back (the
    /// `taken_in` stage; off by default): 8 × 8-pixel blocks of a plane's pixels whose mean
    /// residual, beyond a quadratic fit of the whole plane's, is outside the noise model's
    /// 99.9 % bound and off the median of the plane's blocks around them by as much (grown over
    /// the adjacent blocks beyond the 99 % bound), in 4-connected pieces of at least
    /// `min_piece_pixels` pixels, are left unlabelled and the plane refitted without them: a
    /// socket or a cable on a wall, the front strip of a tray. On the real sequences the share
    /// of planes found again 5 frames later rises (7-Scenes 77.3 → 79.6 %, TUM fr1/rpy
    /// 61.9 → 62.3 %) but the count found again does not (359 and 784 instead of 361 and 797:
    /// planes that give pieces back shrink, and some fall below the benchmark's 5,000 pixels);
    /// the simulated rooms score the same or slightly better, with one spurious plane more in
    /// four of the room sets; it costs 0.4–0.7 ms per 640×480 frame on one thread
    /// (docs/bench/README.md, session 75).
    pub give_back_taken_in: bool,
    /// Whether a frame noisier than its camera's model is detected on the frame's own patches
    /// and extracted with its measured noise (the default; see `PlaneExtractor::noise_scale`):
    /// the lower quartile of the patches' residuals against the model's law, the camera's
    /// `σ_D` a floor. A sensor twice as noisy as its camera says otherwise comes out in
    /// pieces and spurious planes.
    pub estimate_noise: bool,
}

impl Default for PlaneConfig {
    fn default() -> Self {
        Self {
            threshold_px: 0.5,
            log_threshold_px: 0.1,
            log_sigma_px: 2.0,
            min_pixels: 1000,
            max_iterations: 3,
            merge_px: 0.3,
            min_piece_pixels: 256,
            noise_window_x_px: 9.0,
            noise_window_y_px: 11.0,
            bend_px_per_px2: 7.7e-5,
            max_normal_sigma_deg: f64::INFINITY,
            split_creases: true,
            refine_seams: false,
            give_back_taken_in: false,
            estimate_noise: true,
        }
    }
}

impl PlaneConfig {
    /// Checks the ranges of all parameters.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(PlanesError::InvalidConfig(format!(
                    "{name} = {} must be positive and finite",
                    sl_core::Compact(v)
                )))
            }
        };
        pos("threshold_px", self.threshold_px)?;
        pos("log_threshold_px", self.log_threshold_px)?;
        pos("merge_px", self.merge_px)?;
        pos("log_sigma_px", self.log_sigma_px)?;
        for (name, v) in [
            ("noise_window_x_px", self.noise_window_x_px),
            ("noise_window_y_px", self.noise_window_y_px),
        ] {
            if !(v.is_finite() && (1.0..=64.0).contains(&v)) {
                return Err(PlanesError::InvalidConfig(format!(
                    "{name} = {} must be in [1, 64]",
                    sl_core::Compact(v)
                )));
            }
        }
        if !(self.bend_px_per_px2.is_finite() && self.bend_px_per_px2 >= 0.0) {
            return Err(PlanesError::InvalidConfig(format!(
                "bend_px_per_px2 = {} must be finite and at least 0",
                sl_core::Compact(self.bend_px_per_px2)
            )));
        }
        if self.max_normal_sigma_deg.is_nan() || self.max_normal_sigma_deg <= 0.0 {
            return Err(PlanesError::InvalidConfig(format!(
                "max_normal_sigma_deg = {} must be positive (infinite: report every plane)",
                sl_core::Compact(self.max_normal_sigma_deg)
            )));
        }
        if self.log_sigma_px > 16.0 {
            return Err(PlanesError::InvalidConfig(format!(
                "log_sigma_px = {} must be at most 16",
                sl_core::Compact(self.log_sigma_px)
            )));
        }
        if self.min_pixels < 3 {
            return Err(PlanesError::InvalidConfig(
                "min_pixels must be at least 3".into(),
            ));
        }
        Ok(())
    }
}
