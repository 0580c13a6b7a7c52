//! The baseline a ROS driver records beside a depth topic, for recordings that carry no
//! device name: the `sensor_msgs/CameraInfo` of the second camera of the pair under the same
//! device namespace, whose projection matrix states it. ROS's convention (`CameraInfo.msg`)
//! puts `Tx = −f·B` in `P[3]` of the right camera of a rectified stereo pair:
//!
//! - `realsense2_camera` (ROS 1 and 2) publishes it in `infra2/camera_info` — the depth of a
//!   D400 is measured between `infra1` and `infra2`, and `depth/camera_info` and
//!   `aligned_depth_to_color/camera_info` have `Tx = 0`;
//! - `openni_camera` (a Kinect or Xtion under `openni_launch`) publishes the projector as the
//!   right camera, `projector/camera_info`, with the device's baseline.
//!
//! `−P[3]` is then `f·B` of the disparity the depth came from, at the focal length of the
//! images it was matched in (`P[0]`), whatever image the depth was later registered to.

use sl_core::camera::KINECT_SUBPIXEL_STEPS;
use sl_core::sensor::DEFAULT_SIGMA_D_PX;
use sl_core::{SensorModel, preset::ACTIVE_STEREO_SIGMA_D_PX};

use super::{CAMERA_INFO_TYPE, RosBag, messages};
use crate::error::Result;

/// Shortest baseline read from a projection matrix, metres (no depth camera has a shorter
/// one; a `Tx` this small is a calibration's rounding, not a stereo pair).
pub const MIN_STEREO_BASELINE_M: f64 = 0.005;
/// Longest baseline read from a projection matrix, metres (a depth camera's head; a longer one
/// is a rig, whose noise model the user gives with `--camera`).
pub const MAX_STEREO_BASELINE_M: f64 = 1.0;
/// Largest `|Ty| / |Tx|` of a horizontal pair (a rectified pair's vertical offset is a
/// calibration's residual, well under this).
const MAX_VERTICAL_SHARE: f64 = 0.1;
/// How far apart two pairs' baselines may be and still be one (a relative difference).
const SAME_BASELINE: f64 = 0.01;

/// Sub-pixel steps of the RealSense D400 family's disparity (1/32 px), the model taken for a
/// stereo pair whose device is not named.
pub(super) const D400_SUBPIXEL_STEPS: u32 = 32;

/// Which camera of the pair the baseline was read from, and so which sensor measured the
/// disparity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairKind {
    /// The right camera of a stereo pair (`realsense2_camera`'s `infra2`): active (or passive)
    /// stereo, modelled as the D400 family (1/32 px).
    StereoCamera,
    /// A structured-light projector published as the right camera (`openni_camera`'s
    /// `projector`): modelled as the Kinect (1/8 px).
    Projector,
}

/// A baseline recorded in a `CameraInfo`'s projection matrix beside a depth topic.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedBaseline {
    /// The `sensor_msgs/CameraInfo` topic it was read from (`/camera/infra2/camera_info`).
    pub topic: String,
    /// `P[0]`, the focal length the disparity was measured at, pixels.
    pub focal_px: f64,
    /// `−P[3] / P[0]`, metres.
    pub baseline_m: f64,
    /// What kind of sensor it is.
    pub kind: PairKind,
}

impl RecordedBaseline {
    /// The noise model of the sensor that measured the disparity: the D400 family's at this
    /// focal length and baseline, or the Kinect's for a projector.
    ///
    /// # Errors
    /// A focal length the sensor model refuses (out of its range).
    pub fn sensor(&self) -> sl_core::Result<SensorModel> {
        let (steps, sigma) = match self.kind {
            PairKind::StereoCamera => (D400_SUBPIXEL_STEPS, ACTIVE_STEREO_SIGMA_D_PX),
            PairKind::Projector => (KINECT_SUBPIXEL_STEPS, DEFAULT_SIGMA_D_PX),
        };
        SensorModel::new(self.focal_px, self.baseline_m, steps, sigma)
    }

    /// The model in words, for the user (`an active-stereo noise model (1/32 px) at the 50 mm
    /// baseline and 382.6 px focal length of /camera/infra2/camera_info`).
    pub fn describe(&self) -> String {
        let model = match self.kind {
            PairKind::StereoCamera => {
                format!("an active-stereo noise model (1/{D400_SUBPIXEL_STEPS} px)")
            }
            PairKind::Projector => "the Kinect's noise model".to_string(),
        };
        format!(
            "{model} at the {} mm baseline and {} px focal length of {} (its P: Tx = -f*B)",
            (self.baseline_m * 1e5).round() / 100.0,
            (self.focal_px * 100.0).round() / 100.0,
            self.topic
        )
    }
}

/// The baseline a projection matrix states: `Some` for the right camera of a horizontal pair
/// within the bounds above.
fn baseline_of(p: &[f64; 12]) -> Option<(f64, f64)> {
    let (f, tx, ty) = (p[0], p[3], p[7]);
    if !(f.is_finite() && f > 0.0 && tx.is_finite() && tx < 0.0 && ty.is_finite()) {
        return None;
    }
    if ty.abs() > MAX_VERTICAL_SHARE * tx.abs() {
        return None;
    }
    let b = -tx / f;
    (MIN_STEREO_BASELINE_M..=MAX_STEREO_BASELINE_M)
        .contains(&b)
        .then_some((f, b))
}

impl RosBag {
    /// The baseline recorded beside `depth_topic` (see the module's documentation): from the
    /// `CameraInfo` topics one level below the depth's device namespace (`/camera/*/camera_info`
    /// for `/camera/depth/image_rect_raw`), the one whose first message's `P` is a right
    /// camera's. `None` when there is none, or when several disagree by more than 1 %.
    ///
    /// # Errors
    /// A malformed `CameraInfo` message among them.
    pub fn recorded_baseline(&mut self, depth_topic: &str) -> Result<Option<RecordedBaseline>> {
        let Some(own) = self.camera_info_topic(depth_topic) else {
            return Ok(None);
        };
        let Some(device) = own
            .rsplit_once('/')
            .and_then(|(ns, _)| ns.rsplit_once('/'))
            .map(|(device, _)| device.to_string())
        else {
            return Ok(None);
        };
        let candidates: Vec<String> = self
            .topics()
            .into_iter()
            .filter(|t| t.message_type == CAMERA_INFO_TYPE && t.topic != own)
            .map(|t| t.topic)
            .filter(|t| {
                t.strip_prefix(device.as_str())
                    .and_then(|rest| rest.strip_prefix('/'))
                    .and_then(|rest| rest.strip_suffix("/camera_info"))
                    .is_some_and(|name| !name.is_empty() && !name.contains('/'))
            })
            .collect();
        let path = self.path.clone();
        let mut found: Vec<RecordedBaseline> = Vec::new();
        for topic in candidates {
            let Some(first) = self.messages(&topic)?.into_iter().next() else {
                continue;
            };
            let b = self.message(&first)?;
            let info = messages::camera_info(&path, b, first.encoding)?;
            let Some((focal_px, baseline_m)) = info.projection.as_ref().and_then(baseline_of)
            else {
                continue;
            };
            let kind = if topic.ends_with("/projector/camera_info") {
                PairKind::Projector
            } else {
                PairKind::StereoCamera
            };
            found.push(RecordedBaseline {
                topic,
                focal_px,
                baseline_m,
                kind,
            });
        }
        let Some(first) = found.first() else {
            return Ok(None);
        };
        let agree = found.iter().all(|r| {
            r.kind == first.kind
                && (r.baseline_m - first.baseline_m).abs() <= SAME_BASELINE * first.baseline_m
        });
        Ok(agree.then(|| first.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::baseline_of;

    fn p(f: f64, tx: f64, ty: f64) -> [f64; 12] {
        [f, 0.0, 320.0, tx, 0.0, f, 240.0, ty, 0.0, 0.0, 1.0, 0.0]
    }

    #[test]
    fn a_right_cameras_projection_gives_its_baseline() {
        let (f, b) = baseline_of(&p(382.5, -382.5 * 0.0501, 0.02)).unwrap();
        assert_eq!(f, 382.5);
        assert!((b - 0.0501).abs() < 1e-12);
    }

    #[test]
    fn left_cameras_and_implausible_pairs_give_none() {
        assert_eq!(baseline_of(&p(382.5, 0.0, 0.0)), None);
        // A left camera of the pair (Tx > 0 is not ROS's convention for the right one).
        assert_eq!(baseline_of(&p(382.5, 19.0, 0.0)), None);
        // A vertical pair, sub-millimetre and rig-sized baselines, non-finite numbers.
        assert_eq!(baseline_of(&p(382.5, -19.0, -19.0)), None);
        assert_eq!(baseline_of(&p(382.5, -0.1, 0.0)), None);
        assert_eq!(baseline_of(&p(382.5, -800.0, 0.0)), None);
        assert_eq!(baseline_of(&p(f64::NAN, -19.0, 0.0)), None);
        assert_eq!(baseline_of(&p(382.5, f64::NEG_INFINITY, 0.0)), None);
        assert_eq!(baseline_of(&p(-382.5, -19.0, 0.0)), None);
    }
}
