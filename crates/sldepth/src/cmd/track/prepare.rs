//! One frame from its file to the depth the tracker is given: read (the first frame was read
//! already, for the camera's size), checked against the camera's size, then the lens model, the
//! noise measurement and the prefilter.

use anyhow::{Context, Result, bail};
use sl_core::{Camera, DepthImage, Undistorter};
use sl_filter::Prefilter;
use sl_io::depth::{ReadConfig, read_depth_with_limits};
use sl_io::sequence::SequenceFrame;
use sl_planes::NoiseMeter;
use sl_track::Reconstruction;

use crate::common::limits;
use crate::recording::BagFrames;

/// A camera the prefilter cannot serve (a baseline or focal length so extreme that its range
/// kernel leaves the supported range) is the camera's fault, not every frame's: says so once,
/// before any frame is read.
pub(super) fn check_prefilter(prefilter: Prefilter, camera: &Camera) -> Result<()> {
    if let Some(f) = prefilter.filter_for(&camera.sensor) {
        f.validate().with_context(|| {
            format!(
                "--prefilter {} for this camera (f = {} px, B = {} m, sigma_d = {} px); --prefilter none skips it",
                prefilter.name(),
                crate::common::num(camera.sensor.focal_px),
                crate::common::num(camera.sensor.baseline_m),
                crate::common::num(camera.sensor.sigma_d_px)
            )
        })?;
    }
    Ok(())
}

/// Reads and prepares the frames of the sequence, one by one, and keeps what it measured.
pub(super) struct FramePrep {
    read_opts: ReadConfig,
    /// The first frame, read for its size (and a bag frame's stamp): not read again.
    first_depth: Option<(DepthImage, Option<f64>)>,
    /// The frames of a ROS bag, read by index; `None`: files.
    bag: Option<BagFrames>,
    camera: Camera,
    undistort: Option<Undistorter>,
    prefilter: Prefilter,
    /// Measures the raw frames' noise against the camera's model (the prefilter hides it);
    /// `None` with `--model-noise-only`.
    noise_meter: Option<NoiseMeter>,
    /// The raw frames' noise against the camera's model (the prefilter hides it).
    pub(super) noise_scales: Vec<f64>,
    /// The σ_D each frame was smoothed for (the prefilter follows the measured noise).
    pub(super) prefilter_sigmas: Vec<f64>,
}

impl FramePrep {
    /// Frames read with `read_opts` (`first_depth`: the first frame, already read, and its stamp;
    /// `bag`: the frames of a ROS bag, read by index, rather than files) for
    /// `camera`, undistorted by `undistort`, measured by `noise_meter` and smoothed by
    /// `prefilter`.
    pub(super) fn new(
        read_opts: ReadConfig,
        first_depth: Option<(DepthImage, Option<f64>)>,
        bag: Option<BagFrames>,
        camera: Camera,
        undistort: Option<Undistorter>,
        prefilter: Prefilter,
        noise_meter: Option<NoiseMeter>,
    ) -> Self {
        Self {
            read_opts,
            first_depth,
            bag,
            camera,
            undistort,
            prefilter,
            noise_meter,
            noise_scales: Vec::new(),
            prefilter_sigmas: Vec::new(),
        }
    }

    /// Whether the frames are undistorted (a lens model).
    pub(super) fn undistorts(&self) -> bool {
        self.undistort.is_some()
    }

    /// Frame `i` (`f`)'s depth as its file or bag message holds it, or why it could not be
    /// read; and a bag frame's stamp.
    pub(super) fn read(
        &mut self,
        i: usize,
        f: &SequenceFrame,
    ) -> (Result<DepthImage>, Option<f64>) {
        if let Some((d, stamp)) = self.first_depth.take() {
            return (Ok(d), stamp);
        }
        if let Some(bag) = &mut self.bag {
            let scale = self
                .read_opts
                .scale_units_per_m
                .unwrap_or(sl_io::depth::DEFAULT_UNITS_PER_M);
            return bag.read(i, scale);
        }
        let d = read_depth_with_limits(&f.depth_path, &self.read_opts, &limits())
            .map(|l| l.depth)
            .map_err(anyhow::Error::from);
        (d, None)
    }

    /// Refuses a frame of another size than the camera's.
    pub(super) fn check_size(&self, f: &SequenceFrame, d: &DepthImage) -> Result<()> {
        let k = self.camera.intrinsics;
        if d.width() != k.width || d.height() != k.height {
            bail!(
                "{}: depth map is {}x{} but the camera is {}x{} (every frame of a sequence has the camera's size; --camera names the camera)",
                f.depth_path.display(),
                d.width(),
                d.height(),
                k.width,
                k.height
            );
        }
        Ok(())
    }

    /// The frame `raw` ready to track: undistorted, its noise measured (and given to `rec`),
    /// smoothed; or why it cannot be.
    pub(super) fn prepare(
        &mut self,
        raw: Result<DepthImage>,
        rec: &mut Reconstruction,
    ) -> Result<DepthImage> {
        let camera = &self.camera;
        let prefilter = self.prefilter;
        raw.and_then(|d| match &self.undistort {
            Some(u) => Ok(u.apply(&d)?),
            None => Ok(d),
        })
        .map(|d| {
            let scale = self
                .noise_meter
                .as_mut()
                .and_then(|m| m.measure(&d, camera).ok());
            self.noise_scales.extend(scale);
            rec.set_noise_scale(scale);
            (d, scale.unwrap_or(1.0))
        })
        .and_then(|(d, scale)| {
            let sensor = camera.sensor.with_variance_scale(scale);
            if prefilter != Prefilter::Off {
                self.prefilter_sigmas.push(sensor.sigma_d_px);
            }
            // The range kernel follows the frame's measured noise, as `sldepth filter`.
            Ok(prefilter.apply(&d, &sensor)?.unwrap_or(d))
        })
    }
}
