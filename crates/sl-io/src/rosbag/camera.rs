//! The camera and the depth units of a bag's depth topic, from what the recording holds: the
//! intrinsics and lens of the `sensor_msgs/CameraInfo` beside the topic, and the noise model
//! of the sensor behind it — a librealsense recording's device (its preset) and recorded
//! stereo baseline; else the baseline a ROS driver's stereo or projector `CameraInfo` states
//! (`stereo.rs`); else the Kinect's model at the recorded focal length.

use sl_core::preset::{ACTIVE_STEREO_SIGMA_D_PX, for_device_name};
use sl_core::{Camera, LensDistortion, SensorModel};

use super::RosBag;
use super::stereo::D400_SUBPIXEL_STEPS;
use crate::depth::DEFAULT_UNITS_PER_M;
use crate::error::{IoError, Result};

/// The camera of a bag's depth topic.
#[derive(Debug, Clone, PartialEq)]
pub struct BagCamera {
    /// Intrinsics from the `camera_info`, with the noise model of [`BagCamera::sensor_source`].
    pub camera: Camera,
    /// The `camera_info`'s lens, when it has one to undo.
    pub lens: Option<LensDistortion>,
    /// The `sensor_msgs/CameraInfo` topic read.
    pub camera_info_topic: String,
    /// The noise model, in words (`the d435 preset's noise model (Intel RealSense D435I) at the
    /// recorded 49.9 mm baseline`).
    pub sensor_source: String,
}

/// `metres` in millimetres to 0.01 mm, as briefly as that can be written (`49.9`, `50`).
fn mm(metres: f64) -> f64 {
    (metres * 1e5).round() / 100.0
}

impl RosBag {
    /// Units per metre of the 16-bit depth of `depth_topic`: a RealSense recording's `Depth
    /// Units` (1 / 0.001 m on a D400), else ROS's millimetres (1000).
    ///
    /// # Errors
    /// A malformed option message.
    pub fn depth_units_per_m(&mut self, depth_topic: &str) -> Result<f64> {
        Ok(self
            .realsense(depth_topic)?
            .and_then(|r| r.depth_units_m)
            .map_or(DEFAULT_UNITS_PER_M, |u| 1.0 / u))
    }

    /// The camera of `depth_topic`: the intrinsics and lens of the `camera_info` beside it
    /// ([`RosBag::camera_info_topic`]) and the noise model of its sensor — in a RealSense
    /// recording the preset of its device ([`sl_core::preset::for_device_name`]) at the recorded
    /// focal length and stereo baseline, or the D400 family's model at a recorded baseline;
    /// else the model of a baseline a ROS driver recorded beside the topic
    /// ([`RosBag::recorded_baseline`]: `realsense2_camera`'s `infra2`, `openni_camera`'s
    /// projector); otherwise the Kinect's model at the recorded focal length.
    ///
    /// # Errors
    /// No `camera_info` beside the topic, or one [`RosBag::camera`] refuses.
    pub fn depth_camera(&mut self, depth_topic: &str) -> Result<BagCamera> {
        let path = self.path.clone();
        let Some(info) = self.camera_info_topic(depth_topic) else {
            let ns = depth_topic.rsplit_once('/').map_or("", |(ns, _)| ns);
            return Err(IoError::malformed(
                &path,
                format!(
                    "no sensor_msgs/CameraInfo topic beside {depth_topic} (expected \
                     {ns}/camera_info): give the camera"
                ),
            ));
        };
        let ros = self.camera(&info)?;
        let k = ros.intrinsics;
        let rs = self.realsense(depth_topic)?.unwrap_or_default();
        let preset = rs.device_name.as_deref().and_then(for_device_name);
        let core = |e| IoError::core(&path, None, e);
        let (sensor, sensor_source) = match (preset, rs.stereo_baseline_m) {
            (Some(p), baseline) => {
                let s = p.sensor();
                let b = baseline.unwrap_or(s.baseline_m);
                (
                    SensorModel::new(k.fx, b, s.subpixel_steps, s.sigma_d_px).map_err(core)?,
                    format!(
                        "the {} preset's noise model ({}) at {} {} mm baseline",
                        p.name,
                        rs.device_name.as_deref().unwrap_or_default(),
                        if baseline.is_some() {
                            "the recorded"
                        } else {
                            "its"
                        },
                        mm(b)
                    ),
                )
            }
            (None, Some(b)) => (
                SensorModel::new(k.fx, b, D400_SUBPIXEL_STEPS, ACTIVE_STEREO_SIGMA_D_PX)
                    .map_err(core)?,
                format!(
                    "an active-stereo noise model (1/{D400_SUBPIXEL_STEPS} px) at the recorded {} \
                     mm baseline",
                    mm(b)
                ),
            ),
            (None, None) => match self.recorded_baseline(depth_topic)? {
                Some(r) => (r.sensor().map_err(core)?, r.describe()),
                None => (
                    Camera::from_intrinsics(k, None, None).map_err(core)?.sensor,
                    match rs.device_name.as_deref() {
                        None => "the Kinect's noise model".to_string(),
                        Some(d) if is_lidar(d) => format!(
                            "the Kinect's noise model, though the {d} is a LiDAR camera (time of \
                         flight): its depth error does not grow as the disparity model's; \
                         --camera FILE sets another"
                        ),
                        Some(d) => format!(
                            "the Kinect's noise model (no preset models the {d}; --camera FILE \
                         sets its baseline and sub-pixel steps)"
                        ),
                    },
                ),
            },
        };
        Ok(BagCamera {
            camera: Camera {
                intrinsics: k,
                sensor,
            },
            lens: ros.lens,
            camera_info_topic: info,
            sensor_source,
        })
    }
}

/// Whether a RealSense device's name is one of its LiDAR (time-of-flight) cameras, the L5xx
/// series, which measure no disparity.
fn is_lidar(name: &str) -> bool {
    name.to_ascii_uppercase()
        .split(|c: char| !c.is_ascii_alphanumeric())
        .any(|w| w.len() >= 4 && w.starts_with("L5") && w[2..].bytes().all(|b| b.is_ascii_digit()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn lidar_cameras_are_told_by_name() {
        assert!(super::is_lidar("Intel RealSense L515"));
        assert!(!super::is_lidar("Intel RealSense D435I"));
        assert!(!super::is_lidar("L5"));
    }
}
