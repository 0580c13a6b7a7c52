//! Recordings made by librealsense (the RealSense Viewer, `rs-record`, `rs2::recorder`): a ROS 1
//! bag up to librealsense 2.55, a ROS 2 bag in SQLite (`.db3`) since 2.56. Both keep each
//! stream under `/device_<d>/sensor_<s>/<Stream>_<i>/` — the depth images in
//! `image/data` (`mono16`; since 2.56 `image/data/compressedDepth`, PNG), the intrinsics in
//! `info/camera_info` (2.56: `image/camera_info`) — and the sensor's options under
//! `/device_<d>/sensor_<s>/option/<Name>/value`: `Depth Units` (metres per unit of the 16-bit
//! depth; 0.001 on a D400, 0.00025 on an L515) and, where the device has it, `Stereo
//! Baseline` (millimetres). The device's name is in `/device_<d>/info` (`Name`). Each frame's
//! sensor timestamp (milliseconds) is in `image/metadata` (`timestamp`) since 2.56, and in the
//! image header's stamp before.

use super::messages;
use super::{BagMessage, RosBag};
use crate::error::{IoError, Result};

/// What a RealSense recording says of the sensor behind a depth topic.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RealSenseInfo {
    /// The device's name (`Intel RealSense D435`), when recorded.
    pub device_name: Option<String>,
    /// Metres per unit of the 16-bit depth (the `Depth Units` option), when recorded.
    pub depth_units_m: Option<f64>,
    /// The stereo baseline, metres (the `Stereo Baseline` option), when recorded.
    pub stereo_baseline_m: Option<f64>,
}

/// The namespaces of a RealSense depth topic: device, sensor and stream
/// (`/device_0`, `/device_0/sensor_0`, `/device_0/sensor_0/Depth_0`).
fn namespaces(topic: &str) -> Option<(String, String, String)> {
    let parts: Vec<&str> = topic.split('/').collect();
    // "", "device_0", "sensor_0", "Depth_0", "image", ...
    if parts.len() < 5
        || !parts[0].is_empty()
        || !parts[1].starts_with("device_")
        || !parts[2].starts_with("sensor_")
    {
        return None;
    }
    Some((
        parts[..2].join("/"),
        parts[..3].join("/"),
        parts[..4].join("/"),
    ))
}

/// The value a `key=value;…` text gives `key` (`Name=Intel RealSense D435;…`).
fn keyed_text<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.split(';')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| k.trim() == key)
        .map(|(_, v)| v.trim())
}

/// The number a `key=value;…` text gives `key` (`timestamp=1305031229528.783936;…`).
fn keyed_number(text: &str, key: &str) -> Option<f64> {
    keyed_text(text, key).and_then(|v| v.parse().ok())
}

impl RosBag {
    /// The messages of `topic`, or none when the bag does not have it.
    fn messages_if_any(&mut self, topic: &str) -> Result<Vec<BagMessage>> {
        if self.message_type(topic).is_none() {
            return Ok(Vec::new());
        }
        self.messages(topic)
    }

    /// The first value of the option `name` of `sensor` (its spelling with spaces or
    /// underscores): a `std_msgs/Float32`, or a `std_msgs/String` holding a number.
    fn realsense_option(&mut self, sensor: &str, name: &str) -> Result<Option<f64>> {
        let path = self.path.clone();
        for spelling in [name.to_string(), name.replace(' ', "_")] {
            let topic = format!("{sensor}/option/{spelling}/value");
            let ty = self.message_type(&topic).map(str::to_string);
            let Some(m) = self.messages_if_any(&topic)?.into_iter().next() else {
                continue;
            };
            let encoding = m.encoding;
            let b = self.message(&m)?;
            let v = match ty.as_deref() {
                // The shortest decimal that is this `f32` (a `Depth Units` of 0.001 is 0.001,
                // not 0.0010000000474974513): the value as librealsense states it.
                Some("std_msgs/Float32") => {
                    let v = messages::float32(&path, b, encoding)?;
                    v.to_string().parse().unwrap_or(f64::from(v))
                }
                Some("std_msgs/String") => {
                    let t = messages::string(&path, b, encoding)?;
                    t.trim().parse().map_err(|_| {
                        IoError::malformed(&path, format!("{topic} holds {t:?}, not a number"))
                    })?
                }
                _ => continue,
            };
            return Ok(Some(v));
        }
        Ok(None)
    }

    /// The `Name` of the device at `device` (`diagnostic_msgs/KeyValue` messages, or a
    /// `std_msgs/String` of `key=value;…`).
    fn realsense_name(&mut self, device: &str) -> Result<Option<String>> {
        let path = self.path.clone();
        let topic = format!("{device}/info");
        let ty = self.message_type(&topic).map(str::to_string);
        for m in self.messages_if_any(&topic)? {
            let encoding = m.encoding;
            let b = self.message(&m)?;
            match ty.as_deref() {
                Some("diagnostic_msgs/KeyValue") => {
                    let (k, v) = messages::key_value(&path, b, encoding)?;
                    if k == "Name" {
                        return Ok(Some(v));
                    }
                }
                Some("std_msgs/String") => {
                    let t = messages::string(&path, b, encoding)?;
                    if let Some(name) = keyed_text(&t, "Name") {
                        return Ok(Some(name.to_string()));
                    }
                }
                _ => return Ok(None),
            }
        }
        Ok(None)
    }

    /// What the recording says of the RealSense sensor behind `depth_topic` (`None`: the topic
    /// is not a librealsense stream's, `/device_<d>/sensor_<s>/…`).
    ///
    /// # Errors
    /// A malformed option or info message.
    pub fn realsense(&mut self, depth_topic: &str) -> Result<Option<RealSenseInfo>> {
        let Some((device, sensor, _)) = namespaces(depth_topic) else {
            return Ok(None);
        };
        let units = self.realsense_option(&sensor, "Depth Units")?;
        let baseline_mm = self.realsense_option(&sensor, "Stereo Baseline")?;
        let finite_positive = |v: f64| v.is_finite() && v > 0.0;
        Ok(Some(RealSenseInfo {
            device_name: self.realsense_name(&device)?,
            depth_units_m: units.filter(|&u| finite_positive(u)),
            stereo_baseline_m: baseline_mm
                .filter(|&b| finite_positive(b))
                .map(|b| b * 1e-3),
        }))
    }

    /// The sensor timestamps, seconds, of `frames` (messages of the RealSense depth topic
    /// `depth_topic`), from the `timestamp` (milliseconds) of the stream's metadata recorded
    /// at the same time; `None` for a frame without one (librealsense before 2.56 keeps it
    /// in the image header's stamp instead).
    ///
    /// # Errors
    /// A malformed metadata message.
    pub fn realsense_frame_times(
        &mut self,
        depth_topic: &str,
        frames: &[BagMessage],
    ) -> Result<Vec<Option<f64>>> {
        let path = self.path.clone();
        let mut out = vec![None; frames.len()];
        let Some((_, _, stream)) = namespaces(depth_topic) else {
            return Ok(out);
        };
        let topic = format!("{stream}/image/metadata");
        if self.message_type(&topic) != Some("std_msgs/String") {
            return Ok(out);
        }
        let meta = self.messages_if_any(&topic)?;
        // Both lists are in record-time order.
        let mut j = 0;
        for (i, f) in frames.iter().enumerate() {
            while j < meta.len() && meta[j].record_time_s < f.record_time_s {
                j += 1;
            }
            if let Some(m) = meta.get(j).filter(|m| m.record_time_s == f.record_time_s) {
                let m = *m;
                let encoding = m.encoding;
                let text = messages::string(&path, self.message(&m)?, encoding)?;
                out[i] = keyed_number(&text, "timestamp")
                    .filter(|t| t.is_finite() && *t > 0.0)
                    .map(|ms| ms * 1e-3);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realsense_topics_and_metadata_texts() {
        assert_eq!(
            namespaces("/device_0/sensor_0/Depth_0/image/data"),
            Some((
                "/device_0".into(),
                "/device_0/sensor_0".into(),
                "/device_0/sensor_0/Depth_0".into()
            ))
        );
        assert_eq!(namespaces("/camera/depth/image_raw"), None);
        assert_eq!(namespaces("/device_0/sensor_0/Depth_0"), None);
        let t = "Frame number=1;timestamp_domain=System Time;timestamp=1305031229564.442;";
        assert_eq!(keyed_number(t, "timestamp"), Some(1_305_031_229_564.442));
        assert_eq!(keyed_number(t, "depth_units"), None);
    }
}
