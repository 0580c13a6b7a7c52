//! [`TrackerConfig`] and [`WeightMode`].

use sl_core::Isa;

use crate::depth_motion::DepthMotionConfig;
use crate::error::{Result, TrackError};

/// How the point-to-plane residuals are weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WeightMode {
    /// Inverse variance from the sensor model (default): a residual's variance is the frame
    /// point's `σ_Z(z)²` projected on the reference normal, `σ_Z² (n·r)²` with `r` the unit ray,
    /// plus the reference's variance along its normal (the previous frame's own `σ_Z² (n·r)²`,
    /// or `σ_Z(z_ref)²/W` for a model point of fused weight `W`; see
    /// [`crate::ReferenceMaps::model_variance_m2`]). Against the previous frame both points
    /// also carry the sensor's lateral error ([`TrackerConfig::lateral_sigma_px`]),
    /// `(σ_L·z/f)²·(1 − (n·r)²)`, which keeps surfaces seen at grazing incidence from counting
    /// as exact. The robust kernel acts on `r/σ`.
    #[default]
    InvVar,
    /// Every residual weighs the same (KinectFusion, Open3D): the kernel acts on `r/σ_Z(z_ref)`.
    Uniform,
}

impl WeightMode {
    /// Parses the CLI name (`inv-var`, `uniform`).
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "inv-var" => Ok(Self::InvVar),
            "uniform" => Ok(Self::Uniform),
            other => Err(TrackError::InvalidConfig(format!(
                "unknown weighting {other:?} (expected inv-var or uniform)"
            ))),
        }
    }

    /// The CLI name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::InvVar => "inv-var",
            Self::Uniform => "uniform",
        }
    }
}

/// The default [`TrackerConfig::lateral_sigma_px`]: a Kinect's lateral error, sensor pixels
/// (Nguyen, Izadi & Lovell, 3DIMPVT 2012).
pub const DEFAULT_LATERAL_SIGMA_PX: f64 = 0.8;

/// Parameters of [`crate::Tracker`].
///
/// The gates follow the sensor model: a correspondence is kept when its point-to-plane
/// residual is within `gate_sigmas·σ + allowance` (σ from the sensor model, see
/// [`WeightMode::InvVar`]), where the allowance covers what the pose still has to correct at
/// that level and what the noise model does not describe (the Kinect's low-frequency depth
/// distortion of a few millimetres): `allowance_fine_m` at full resolution, doubled at every
/// coarser level. The point distance must stay within twice the same bound.
///
/// `#[non_exhaustive]`: start from [`TrackerConfig::default`] and assign the fields you need.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TrackerConfig {
    /// Pyramid levels (≥ 3 recommended; level 0 is full resolution).
    pub levels: usize,
    /// The finest pyramid level aligned (0 = full resolution, the default). Level 1 makes a
    /// step about 1.5× cheaper with the same accuracy on the real TUM fr1/rpy and 7-Scenes
    /// sequences, but on simulated sequences with known poses it is 2–3× less accurate (the
    /// benchmark in `docs/bench/track.md`), so full resolution stays the default.
    pub finest_level: usize,
    /// Gauss–Newton iterations per level at most (fewer when the step becomes negligible).
    pub max_iterations: usize,
    /// The residual weighting.
    pub weighting: WeightMode,
    /// Residuals within this many σ (plus the allowance) are inliers; 3σ keeps 99.7 % of a
    /// Gaussian.
    pub gate_sigmas: f64,
    /// Metric allowance of the gate at full resolution, metres (doubled per coarser level).
    pub allowance_fine_m: f64,
    /// Largest angle between a frame normal and its reference normal where the normals are
    /// precise, degrees. Normals from central differences are noisy at distance, so the gate
    /// widens to 3× the normals' noise from the sensor model (σ_Z(z)·f/(4·z) per normal over
    /// ±2 pixels, √2 for two: 42° at 1 m, 60° at 2 m for a Kinect); it separates the two
    /// sides of thin objects nearby.
    pub max_normal_angle_deg: f64,
    /// Threshold of the Huber kernel on the normalised residual.
    pub huber_k: f64,
    /// Reference depth of the uniform weighting's σ and of the model's fused weights, metres.
    pub z_ref_m: f64,
    /// Tracking has failed when fewer than this fraction of the frame's points that land on a
    /// reference surface are inliers at the final pose. At the right pose the gates keep
    /// 99.7 % of a Gaussian residual; what remains are occlusions, depth edges, moving objects
    /// and the model's unobserved fringe: well over half. Below half, most of the overlap
    /// disagrees and the alignment is wrong. (Points landing where the reference has no surface
    /// — new parts of the scene — do not count either way; too few inliers in absolute terms,
    /// 1 % of the pixels, is a failure of its own.)
    pub min_inlier_fraction: f64,
    /// Tracking has failed when the smallest over the largest eigenvalue of the normal
    /// equations (rotation in metres at the scene's depth) is below this: the geometry does
    /// not constrain all six degrees of freedom (a single plane, a corridor). Not applied to an
    /// alignment against the last frame with its planes' normals while
    /// [`TrackerConfig::degenerate_check`] is on: that check decides from the sensor model.
    pub min_condition: f64,
    /// Tracking has failed when the final pose is further than this from where it started
    /// (the constant-velocity prediction), metres: a hand-held camera moving at up to
    /// 1.5 m/s covers 5 cm between two frames at 30 Hz, so even from a prediction of no
    /// motion at all a larger correction came from a wrong association (real Kinect data:
    /// ICP sliding 12 cm along a counter top between two 7-Scenes frames 3 mm apart)...
    pub max_correction_m: f64,
    /// ... or rotation, degrees (fast hand-held rotation, 300 °/s, is 10° per frame at 30 Hz;
    /// twice that).
    pub max_correction_deg: f64,
    /// Try the verified plane-based estimate between the last good frame and this one when
    /// ICP fails, then ICP again from it.
    pub plane_fallback: bool,
    /// When every other attempt fails, align the frame against the keyframes (depth frames
    /// accepted earlier, kept at poses about half the acceptance bounds apart), each from its
    /// own pose, and keep the best that passes every check: a camera lost in a fast turn is
    /// found again where it looks at something it saw before, not only near the last good
    /// pose.
    pub keyframe_relocalisation: bool,
    /// Report a frame lost, before any alignment, when its geometry leaves some direction of
    /// the pose less well determined than the motion prior does: the pose's standard
    /// deviation along its least-constrained direction, from the sensor model with the normals
    /// of the frame's planes (`sl-planes`; `FrameResult::weakest_sigma_m`), above
    /// `max_acceleration_m_s2 · frame_interval_s²` (10.9 mm at 1 g and 30 Hz). A single wall
    /// or floor, or a corridor with nothing but its four planes, is such a view; nor does
    /// such a view start the sequence (the first frame waits for one that pins the pose). The
    /// same bound holds for the part of the frame that overlaps the reference at an aligned
    /// pose (inliers only, the reference's variance added): an alignment that fails it is
    /// rejected like one that fails the other checks. Costs one plane extraction per frame at
    /// half resolution (under 1 ms at 640×480 on one core).
    pub degenerate_check: bool,
    /// Measure each frame's disparity noise on its own 16×16- and 32×32-pixel patches against the
    /// camera's model (`sl_planes::NoiseMeter`, as the plane extractor does) and, when it is
    /// significantly larger, track the frame with that noise: every σ of the frame — the
    /// alignment's weights and gates, the degenerate-view checks, its planes — follows it, the
    /// camera's `σ_D` a floor ([`crate::Tracker::noise_scale`]). A sensor noisier than its
    /// camera says otherwise has a third of its residuals gated out and its poses'
    /// uncertainty understated: simulated rooms at σ_D 0.2 px behind the Kinect's 0.07 kept
    /// steps 27 mm off with a reported σ of 5 mm (docs/bench/track.md, session 49). Costs one
    /// pass over the frame's 4×4-pixel cells. Off: the frame is tracked with the camera's model
    /// alone, its planes (degenerate-view checks, plane fallback) extracted with
    /// `sl_planes::PlaneConfig::estimate_noise` off too (on, their extractor is given the
    /// frame's raised `σ_D` and measures the level against it, as every extractor does).
    pub estimate_noise: bool,
    /// Width of the window over which a structured-light camera's depth error is correlated,
    /// pixels of the sensor (the block-matching window: 9 × 11 px fitted on real Kinect frames,
    /// `docs/NOISE_MODEL.md`; the same window as `sl_planes::PlaneConfig::noise_window_x_px`;
    /// 1 × 1 = white noise). Frames of a camera resampled from its sensor
    /// (`sl_core::Camera::resampled`: a 320×240 stream of a 640×480 Kinect) see it scaled by
    /// `Camera::pixels_per_sensor_pixel`, so they carry the same information per solid angle.
    /// The normal equations count one independent measurement per window, not per pixel:
    /// otherwise a weakly constrained direction (far walls, few planes) looks hundreds of times
    /// better known than it is and outweighs the motion prior.
    pub noise_window_x_px: f64,
    /// Height of that window, pixels.
    pub noise_window_y_px: f64,
    /// The sensor's lateral error, pixels of the sensor: how far from its pixel's ray the
    /// surface a depth value measures may lie (the block matcher's estimate belongs to its
    /// window, not to the pixel's centre; Nguyen, Izadi & Lovell, 3DIMPVT 2012 — the paper
    /// `sl_core::DEFAULT_SIGMA_D_PX` comes from — measured about 0.8 px on a Kinect, nearly
    /// independent of depth). On a surface seen at incidence θ it moves the point along the
    /// surface's normal by `σ_L·z/f·sin θ`, where the depth error moves it by `σ_Z·cos θ`:
    /// without it, a floor or a wall seen at a grazing angle counts as nearly exact (its
    /// variance along the normal goes to 0 with `cos θ`) and its samples outweigh the rest of
    /// the view. Only against the previous frame (frame-to-frame tracking, and the fallback of
    /// frame-to-model tracking to the last frame), whose points are raw measurements as the
    /// tracked frame's are ([`crate::ReferenceMaps`]' field `lateral_sigma_per_m`): on a
    /// simulated corridor with white noise tracked frame to frame it removes a drift along the
    /// corridor's axis of 0.1 mm per frame at 640×480 and 0.75 mm per frame at 320×240, and on
    /// 7-Scenes it lowers the frame-to-frame ATE 6.0 → 5.5 mm; against the fused model the
    /// frame's own term cost TUM fr1/rpy-200's ATE 2.85 → 2.95 cm, so it is not applied there
    /// (docs/bench/track.md, session 57). 0 leaves it out.
    pub lateral_sigma_px: f64,
    /// Samples the alignment keeps across the narrower side of that window on each pyramid
    /// level ([`TrackerConfig::sample_stride`]): 4 samples every second pixel of a 640×480
    /// Kinect's full-resolution level (a step 1.5× cheaper; TUM fr1/rpy and 7-Scenes ATE equal
    /// or slightly better, docs/bench/track.md); a value above the window's width in pixels
    /// (64) uses every pixel.
    pub samples_per_noise_window: f64,
    /// The largest acceleration of the camera, m/s², and ...
    pub max_acceleration_m_s2: f64,
    /// ... the time between frames, seconds: they set the prior on the camera's position
    /// when aligning from the constant-velocity prediction, a Gaussian about the predicted
    /// position with σ = `max_acceleration_m_s2 · frame_interval_s²` per axis (1 g at 30 Hz:
    /// 10.9 mm, how far a hand-held camera's path can leave the constant-velocity line in one
    /// frame). Without a measured velocity (the first step, after a lost frame) and from any
    /// other start, the prior's σ is `max_correction_m`. It is also the unit in which
    /// [`crate::Tracker::track_at`] counts the time between timestamped frames (a gap of `n`
    /// intervals: the prediction spans `n` steps, the prior's σ grows `n²`-fold).
    pub frame_interval_s: f64,
    /// The sensor's rolling-shutter readout time, seconds: from the exposure of the first image
    /// row to the last (0, the default: a global shutter, every row at once). A moving camera
    /// sees each row of such a sensor from another pose; with a readout time the alignment
    /// gives each row its own pose on the constant-velocity path from the last good pose to the
    /// frame's, and the frame's pose is the camera's at the middle of the readout. The Kinect
    /// v1 family reads its IR sensor row by row over most of the frame interval
    /// ([`sl_core::preset::KINECT_READOUT_S`], the presets'
    /// [`sl_core::SensorPreset::rolling_shutter_readout_s`], which `sldepth track` and Python's
    /// `Tracker` use by default against the fused model; the default here stays a global
    /// shutter, as the simulator renders; docs/bench/track.md, sessions 19 and 44).
    pub rolling_shutter_readout_s: f64,
    /// The uncertainty of an odometry given with the frames ([`crate::Tracker::set_odometry`]):
    /// the σ of the position it predicts, per axis, is `odometry_min_sigma_m` plus
    /// `odometry_drift` times the distance it measured since the last good frame (wheel
    /// odometry drifts by a few per cent of the distance; 5 % by default) ...
    pub odometry_drift: f64,
    /// ... with a floor per frame interval, metres, for what the distance does not explain:
    /// the odometry's and the camera's clocks a few milliseconds apart, a lever arm, wheel
    /// quantisation (5 mm by default: 5 ms at 1 m/s); over `n` intervals (dropped or lost
    /// frames) it grows as a random walk, `√n` times ...
    pub odometry_min_sigma_m: f64,
    /// ... and the σ of the orientation, per axis: `odometry_min_sigma_deg` plus
    /// `odometry_rotation_drift` times the angle it measured (5 % by default) ...
    pub odometry_rotation_drift: f64,
    /// ... with a floor, degrees (0.5° by default: 5 ms of a 100°/s turn, a base's flex).
    pub odometry_min_sigma_deg: f64,
    /// The plane-based estimate's configuration.
    pub fallback: DepthMotionConfig,
    /// The instruction set the alignment's inner loop is run with: by default the widest this
    /// CPU supports ([`Isa::detect`]). Every instruction set gives bit-identical poses (the
    /// loop's arithmetic is elementwise and its sums are added in the same order); a narrower
    /// one is for benchmarks.
    pub isa: Isa,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            levels: 3,
            finest_level: 0,
            max_iterations: 10,
            weighting: WeightMode::InvVar,
            gate_sigmas: 3.0,
            allowance_fine_m: 0.01,
            max_normal_angle_deg: 30.0,
            huber_k: 2.0,
            z_ref_m: 1.0,
            min_inlier_fraction: 0.5,
            min_condition: 1e-3,
            max_correction_m: 0.05,
            max_correction_deg: 20.0,
            plane_fallback: true,
            keyframe_relocalisation: true,
            degenerate_check: true,
            estimate_noise: true,
            noise_window_x_px: 9.0,
            noise_window_y_px: 11.0,
            lateral_sigma_px: DEFAULT_LATERAL_SIGMA_PX,
            samples_per_noise_window: 4.0,
            max_acceleration_m_s2: 9.81,
            frame_interval_s: 1.0 / 30.0,
            rolling_shutter_readout_s: 0.0,
            odometry_drift: 0.05,
            odometry_min_sigma_m: 0.005,
            odometry_rotation_drift: 0.05,
            odometry_min_sigma_deg: 0.5,
            fallback: DepthMotionConfig::default(),
            isa: Isa::detect(),
        }
    }
}

impl TrackerConfig {
    /// The rolling-shutter readout time in frame intervals (0: a global shutter).
    pub fn rolling_shutter_readout_fraction(&self) -> f64 {
        self.rolling_shutter_readout_s / self.frame_interval_s
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(TrackError::InvalidConfig(m));
        if !(1..=6).contains(&self.levels) {
            return bad(format!("levels must lie in 1..=6, got {}", self.levels));
        }
        if self.finest_level >= self.levels {
            return bad(format!(
                "finest_level must be below levels ({}), got {}",
                self.levels, self.finest_level
            ));
        }
        if !(1..=100).contains(&self.max_iterations) {
            return bad(format!(
                "max_iterations must lie in 1..=100, got {}",
                self.max_iterations
            ));
        }
        for (name, v) in [
            ("gate_sigmas", self.gate_sigmas),
            ("huber_k", self.huber_k),
            ("z_ref_m", self.z_ref_m),
            ("max_correction_m", self.max_correction_m),
            ("max_acceleration_m_s2", self.max_acceleration_m_s2),
            ("frame_interval_s", self.frame_interval_s),
            ("samples_per_noise_window", self.samples_per_noise_window),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!(
                    "{name} must be positive, got {}",
                    sl_core::Compact(v)
                ));
            }
        }
        for (name, v, range) in [
            ("odometry_drift", self.odometry_drift, 0.0..=1.0),
            (
                "odometry_rotation_drift",
                self.odometry_rotation_drift,
                0.0..=1.0,
            ),
            (
                "odometry_min_sigma_m",
                self.odometry_min_sigma_m,
                1e-6..=1.0,
            ),
            (
                "odometry_min_sigma_deg",
                self.odometry_min_sigma_deg,
                1e-4..=90.0,
            ),
        ] {
            if !(v.is_finite() && range.contains(&v)) {
                return bad(format!(
                    "{name} must lie in [{}, {}], got {}",
                    sl_core::Compact(*range.start()),
                    sl_core::Compact(*range.end()),
                    sl_core::Compact(v)
                ));
            }
        }
        for (name, v) in [
            ("noise_window_x_px", self.noise_window_x_px),
            ("noise_window_y_px", self.noise_window_y_px),
        ] {
            if !(v.is_finite() && (1.0..=1000.0).contains(&v)) {
                return bad(format!(
                    "{name} must lie in [1, 1000], got {}",
                    sl_core::Compact(v)
                ));
            }
        }
        if !(self.lateral_sigma_px.is_finite() && (0.0..=100.0).contains(&self.lateral_sigma_px)) {
            return bad(format!(
                "lateral_sigma_px must lie in [0, 100], got {}",
                sl_core::Compact(self.lateral_sigma_px)
            ));
        }
        if !(self.rolling_shutter_readout_s.is_finite()
            && (0.0..=self.frame_interval_s).contains(&self.rolling_shutter_readout_s))
        {
            return bad(format!(
                "rolling_shutter_readout_s must lie in [0, frame_interval_s = {}], got {}",
                sl_core::Compact(self.frame_interval_s),
                sl_core::Compact(self.rolling_shutter_readout_s)
            ));
        }
        if !(self.allowance_fine_m.is_finite() && self.allowance_fine_m >= 0.0) {
            return bad(format!(
                "allowance_fine_m must be >= 0, got {}",
                sl_core::Compact(self.allowance_fine_m)
            ));
        }
        for (name, v) in [
            ("max_normal_angle_deg", self.max_normal_angle_deg),
            ("max_correction_deg", self.max_correction_deg),
        ] {
            if !(v > 0.0 && v <= 180.0) {
                return bad(format!(
                    "{name} must lie in (0, 180], got {}",
                    sl_core::Compact(v)
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.min_inlier_fraction)
            || !(0.0..1.0).contains(&self.min_condition)
        {
            return bad("min_inlier_fraction must lie in [0, 1], min_condition in [0, 1)".into());
        }
        self.fallback.validate()
    }
}

impl TrackerConfig {
    /// Pixels of pyramid level `level` over which the depth error is correlated (at least 1):
    /// the noise window's area (in the sensor's pixels) in image pixels, `pixel_scale²` of
    /// them per sensor pixel ([`sl_core::Camera::pixels_per_sensor_pixel`]: 1 at the sensor's
    /// resolution, 0.5 for frames decimated to half of it), divided by the 4^level
    /// full-resolution pixels of a pixel of the level.
    pub fn correlated_pixels(&self, level: usize, pixel_scale: f64) -> f64 {
        let area = self.noise_window_x_px * self.noise_window_y_px * pixel_scale * pixel_scale;
        (area / 4f64.powi(level.min(30) as i32)).max(1.0)
    }

    /// A meter of a frame's noise against its camera's model for this sensor's correlation
    /// window ([`TrackerConfig::noise_window_x_px`]): what the tracker measures each frame with
    /// ([`TrackerConfig::estimate_noise`]), and what a caller that smooths its frames before
    /// tracking measures the raw frames with ([`crate::Tracker::set_noise_scale`]).
    pub fn noise_meter(&self) -> sl_planes::NoiseMeter {
        let mut pc = sl_planes::PlaneConfig::default();
        pc.noise_window_x_px = self.noise_window_x_px;
        pc.noise_window_y_px = self.noise_window_y_px;
        sl_planes::NoiseMeter::new(&pc)
    }

    /// Every how many pixels (along rows and columns) of pyramid level `level` the alignment
    /// samples the frame: the narrower side of the noise window in the level's pixels divided
    /// by [`TrackerConfig::samples_per_noise_window`], at least 1 — 2 at full resolution for a 640×480
    /// Kinect (9 px / 4), 1 on coarser levels, on decimated frames and for white noise.
    /// Neighbours within a window share most of their error (correlation 0.7 / 0.57 at 1 / 2
    /// px on real Kinect walls), so the skipped ones add little information; the normal
    /// equations count each sample as `stride²` pixels, so the information they report is
    /// unchanged.
    pub fn sample_stride(&self, level: usize, pixel_scale: f64) -> usize {
        let side = self.noise_window_x_px.min(self.noise_window_y_px) * pixel_scale
            / 2f64.powi(level.min(30) as i32);
        let stride = (side / self.samples_per_noise_window).floor();
        if stride.is_finite() && stride >= 1.0 {
            stride.min(64.0) as usize
        } else {
            1
        }
    }

    /// A time span in whole frame intervals ([`TrackerConfig::frame_interval_s`], rounded: the
    /// jitter of a driver's timestamps is not time), at least 1 and at most an hour of frames.
    pub fn whole_intervals(&self, span_s: f64) -> u32 {
        (span_s / self.frame_interval_s)
            .round()
            .clamp(1.0, 108_000.0) as u32
    }

    /// Variance per axis of the camera's departure from the constant-velocity prediction
    /// over one frame, `(max_acceleration_m_s2 · frame_interval_s²)²`, m².
    pub fn acceleration_variance_m2(&self) -> f64 {
        let sigma = self.motion_prior_sigma_m();
        sigma * sigma
    }

    /// The motion prior's σ over one frame, `max_acceleration_m_s2 · frame_interval_s²`,
    /// metres (10.9 mm at 1 g and 30 Hz): also the bound of the degenerate-view check
    /// ([`TrackerConfig::degenerate_check`]).
    pub fn motion_prior_sigma_m(&self) -> f64 {
        self.max_acceleration_m_s2 * self.frame_interval_s * self.frame_interval_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every second pixel at a Kinect's full resolution; every pixel on coarser levels, on a
    /// decimated stream, for white noise, and when asked for more samples than the window has.
    #[test]
    fn the_sample_stride_follows_the_noise_window() {
        let cfg = TrackerConfig::default();
        assert_eq!(cfg.sample_stride(0, 1.0), 2);
        assert_eq!(cfg.sample_stride(1, 1.0), 1);
        assert_eq!(cfg.sample_stride(0, 0.5), 1);
        // A camera resampled finer than its sensor (pixel scale 2): every fourth pixel.
        assert_eq!(cfg.sample_stride(0, 2.0), 4);
        let mut white = cfg;
        white.noise_window_x_px = 1.0;
        white.noise_window_y_px = 1.0;
        assert_eq!(white.sample_stride(0, 1.0), 1);
        let mut all = cfg;
        all.samples_per_noise_window = 64.0;
        assert_eq!(all.sample_stride(0, 1.0), 1);
        all.samples_per_noise_window = 0.0;
        assert!(all.validate().is_err());
    }
}
