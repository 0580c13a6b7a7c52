//! The smoothing a depth-frame pipeline applies to every frame before tracking or fusing it,
//! by name: `sldepth track --prefilter NAME` and Python's `Tracker(prefilter=NAME)` /
//! `track_in_map(…, prefilter=NAME)` parse the same names into one [`Prefilter`] and build the
//! same filter from it, so the command line and the bindings cannot drift apart.

use std::fmt;
use std::str::FromStr;

use sl_core::{DepthImage, DepthView, SensorModel};

use crate::{FilterError, MultiScale, Result};

/// Which filter smooths each frame before it is tracked and fused.
///
/// ```
/// use sl_core::Camera;
/// use sl_filter::Prefilter;
///
/// let p: Prefilter = "single".parse()?;
/// assert_eq!(p, Prefilter::Single);
/// assert_eq!(p.to_string(), "single");
/// let sensor = Camera::kinect_v1().sensor;
/// assert!(Prefilter::Off.filter_for(&sensor).is_none());
/// assert!(Prefilter::default().filter_for(&sensor).is_some_and(|f| !f.dilations.is_empty()));
/// assert!("smooth".parse::<Prefilter>().is_err());
/// # Ok::<(), sl_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum Prefilter {
    /// `"multiscale"` (the default): [`MultiScale::default_for`] the sensor with the coarse
    /// passes at [`PREFILTER_DILATIONS`] — the adaptive 7×7 pass, then the dilated disparity
    /// passes that remove real sensors' correlated error.
    #[default]
    MultiScale,
    /// `"single"`: the adaptive filter's single 7×7 pass
    /// (`DepthFilter::default_for(Method::Adaptive, …)`, the paper's filter).
    Single,
    /// `"none"`: frames are used as they are.
    Off,
}

/// Dilations of the coarse passes of [`Prefilter::MultiScale`]: 2 and 4, one pass fewer than
/// [`crate::multiscale::DEFAULT_DILATIONS`] (`sldepth filter`'s default).
///
/// Measured in session 58 (`cargo xtask validate --only track`, docs/bench/README.md): with the
/// third pass (dilation 8) the tracked trajectories at the frame rate are as accurate (TUM
/// fr1/rpy-200 2.86 → 2.84 cm, 7-Scenes 0.67 → 0.68 cm), but faster motion lost frames it
/// tracked before (TUM every 3rd frame with the readout model: 0 → 9 lost; every 2nd with a
/// global shutter: 0 → 5), and each frame costs one pass more. The tracker keeps two passes.
pub const PREFILTER_DILATIONS: [usize; 2] = [2, 4];

impl Prefilter {
    /// Every prefilter, in the order of [`Prefilter::NAMES`].
    pub const ALL: [Prefilter; 3] = [Prefilter::MultiScale, Prefilter::Single, Prefilter::Off];
    /// The names [`Prefilter::from_name`] accepts (for a command line's list of values).
    pub const NAMES: [&'static str; 3] = ["multiscale", "single", "none"];

    /// The name of this prefilter (`"multiscale"`, `"single"` or `"none"`).
    pub fn name(self) -> &'static str {
        match self {
            Prefilter::MultiScale => Self::NAMES[0],
            Prefilter::Single => Self::NAMES[1],
            Prefilter::Off => Self::NAMES[2],
        }
    }

    /// The prefilter called `name`; [`FilterError::InvalidParameter`] listing the names
    /// otherwise.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .ok_or_else(|| {
                FilterError::InvalidParameter(format!(
                    "unknown prefilter {name:?}: use \"multiscale\", \"single\" or \"none\""
                ))
            })
    }

    /// The filter for `sensor` (a camera's model, or that model with σ_D raised to a frame's
    /// measured noise, `SensorModel::with_variance_scale`, so a noisier frame is smoothed with
    /// the range kernel of its own noise); `None` for [`Prefilter::Off`]. The single pass is
    /// the multi-scale filter without its coarse passes, which is the adaptive default pass.
    pub fn filter_for(self, sensor: &SensorModel) -> Option<MultiScale> {
        let multi = MultiScale {
            dilations: PREFILTER_DILATIONS.to_vec(),
            ..MultiScale::default_for(sensor)
        };
        match self {
            Prefilter::MultiScale => Some(multi),
            Prefilter::Single => Some(MultiScale {
                dilations: Vec::new(),
                ..multi
            }),
            Prefilter::Off => None,
        }
    }

    /// `depth` smoothed with [`Prefilter::filter_for`]`(sensor)`; `None` for
    /// [`Prefilter::Off`], where the frame is used as it is (no copy is made of it).
    pub fn apply<'a>(
        self,
        depth: impl Into<DepthView<'a>>,
        sensor: &SensorModel,
    ) -> Result<Option<DepthImage>> {
        self.filter_for(sensor).map(|f| f.apply(depth)).transpose()
    }
}

impl fmt::Display for Prefilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Prefilter {
    type Err = FilterError;
    fn from_str(s: &str) -> Result<Self> {
        Self::from_name(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DepthFilter, Method};
    use sl_core::Camera;

    #[test]
    fn every_name_parses_back_to_its_prefilter() {
        for (p, name) in Prefilter::ALL.into_iter().zip(Prefilter::NAMES) {
            assert_eq!(p.name(), name);
            assert_eq!(Prefilter::from_name(name), Ok(p));
            assert_eq!(p.to_string().parse::<Prefilter>(), Ok(p));
        }
        let err = Prefilter::from_name("Multiscale").unwrap_err().to_string();
        assert!(
            err.contains("\"multiscale\", \"single\" or \"none\""),
            "{err}"
        );
        assert!(Prefilter::from_name("").is_err());
    }

    #[test]
    fn the_single_pass_is_the_adaptive_default_and_multiscale_adds_coarse_passes() {
        let sensor = Camera::kinect_v1().sensor;
        let (w, h) = (64, 48);
        let data: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let noise = ((i * 7919) % 13) as f32 / 6.0 - 1.0;
                // A step between two walls, so the filters have an edge to keep.
                (if x < 30 { 1.5 } else { 2.4 }) + 0.004 * noise + 0.0005 * y as f32
            })
            .collect();
        let depth = DepthImage::from_vec(w, h, data).unwrap();
        let single = Prefilter::Single.filter_for(&sensor).unwrap();
        assert!(single.dilations.is_empty());
        let adaptive = DepthFilter::default_for(Method::Adaptive, &sensor);
        assert_eq!(
            single.apply(&depth).unwrap().data(),
            adaptive.apply(&depth).unwrap().data()
        );
        let multi = Prefilter::MultiScale.filter_for(&sensor).unwrap();
        // The default filter with the tracker's coarse passes (one fewer, see
        // PREFILTER_DILATIONS).
        let default = MultiScale::default_for(&sensor);
        assert_eq!(multi.dilations, PREFILTER_DILATIONS);
        assert_eq!(
            (&multi.base, &multi.coarse),
            (&default.base, &default.coarse)
        );
        assert!(default.dilations.starts_with(&multi.dilations));
        assert_ne!(
            multi.apply(&depth).unwrap().data(),
            adaptive.apply(&depth).unwrap().data()
        );
        assert_eq!(Prefilter::Off.filter_for(&sensor), None);
        assert_eq!(Prefilter::Off.apply(&depth, &sensor), Ok(None));
        assert_eq!(
            Prefilter::MultiScale.apply(&depth, &sensor).unwrap(),
            Some(multi.apply(&depth).unwrap())
        );
    }

    #[test]
    fn a_noisier_sensor_gets_a_wider_range_kernel() {
        let sensor = Camera::kinect_v1().sensor;
        let noisier = sensor.with_variance_scale(4.0);
        let (a, b) = (
            Prefilter::MultiScale.filter_for(&sensor).unwrap(),
            Prefilter::MultiScale.filter_for(&noisier).unwrap(),
        );
        assert_ne!(a, b);
        let default = MultiScale::default_for(&noisier);
        assert_eq!((&b.base, &b.coarse), (&default.base, &default.coarse));
    }
}
