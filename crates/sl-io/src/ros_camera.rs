//! ROS camera calibrations: the YAML file `camera_calibration` writes and
//! `camera_calibration_parsers` reads (`image_width`, `image_height`, `camera_matrix.data`,
//! `distortion_model`, `distortion_coefficients.data`), and a `sensor_msgs/CameraInfo` message
//! as `rostopic echo` (ROS 1: `width`, `height`, `K`, `D`) or `ros2 topic echo` (ROS 2: `k`,
//! `d`, block lists) prints it, saved to a file. This is how a robot's depth camera — a Kinect or
//! Xtion through `openni_launch`, a RealSense through `realsense2_camera` — publishes its
//! intrinsics.
//!
//! Parsed with `yaml-rust2`'s event parser, not its document loader: the events are walked
//! here, only the first document is read, anchors and aliases are refused (a file of a few
//! hundred bytes could otherwise expand into gigabytes), nesting deeper than a camera file
//! needs is refused, and the file is read within a small size bound. Nothing else of YAML is
//! needed for these files.

use std::collections::HashMap;
use std::path::Path;

use sl_core::{Intrinsics, LensDistortion};
use yaml_rust2::parser::{Event, Parser};

use crate::camera::intrinsics_from_k;
use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::text::read_text;

/// The largest camera YAML file read (a real one is 0.5–2 KiB).
pub const MAX_ROS_CAMERA_BYTES: u64 = 64 << 10;
/// The deepest nesting of mappings and sequences accepted (a `CameraInfo` echo nests 3 deep).
const MAX_DEPTH: usize = 8;

/// What a ROS camera file says about the camera: its intrinsics (at the image size it states)
/// and its lens.
#[derive(Debug, Clone, PartialEq)]
pub struct RosCamera {
    /// The pinhole intrinsics of `K` (`camera_matrix`), for the file's image size.
    pub intrinsics: Intrinsics,
    /// The `distortion_model` as written (`plumb_bob`, `rational_polynomial`, ...; empty when
    /// absent).
    pub distortion_model: String,
    /// The `plumb_bob` coefficients `(k1, k2, p1, p2, k3)` when any is non-zero; `None` when the
    /// image has no distortion to undo (every coefficient zero, or none given).
    pub lens: Option<LensDistortion>,
}

/// Whether `path` names a ROS camera YAML file by its extension (`.yaml`, `.yml`).
pub fn is_ros_camera_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml"))
}

/// The scalars and scalar lists of a document, by their key path (`width`,
/// `camera_matrix.data`, `roi.x_offset`).
#[derive(Default)]
struct Fields {
    scalars: HashMap<String, String>,
    lists: HashMap<String, Vec<String>>,
}

enum Node {
    /// A mapping: its key path, and the key read whose value comes next.
    Map(String, Option<String>),
    /// A sequence at a key path, with its scalar items.
    Seq(String, Vec<String>),
}

fn join(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

/// Walks the first document's events into [`Fields`].
fn fields_of(path: &Path, text: &str) -> Result<Fields> {
    let bad = |m: String| IoError::malformed(path, m);
    let mut parser = Parser::new_from_str(text);
    let mut stack: Vec<Node> = Vec::new();
    let mut fields = Fields::default();
    let mut documents = 0;
    loop {
        let (event, mark) = parser
            .next_token()
            .map_err(|e| bad(format!("not YAML: {e}")))?;
        let at = |m: &str| format!("{m} (line {})", mark.line());
        let anchored = match &event {
            Event::Scalar(_, _, a, _) | Event::SequenceStart(a, _) | Event::MappingStart(a, _) => {
                *a > 0
            }
            _ => false,
        };
        if anchored {
            return Err(bad(at("YAML anchors are not read in a camera file")));
        }
        match event {
            Event::StreamEnd => break,
            Event::DocumentStart => {
                documents += 1;
                if documents > 1 {
                    break;
                }
            }
            Event::DocumentEnd if documents >= 1 => break,
            Event::Alias(_) => {
                return Err(bad(at("YAML aliases are not read in a camera file")));
            }
            Event::Scalar(value, ..) => match stack.last_mut() {
                Some(Node::Map(_, key @ None)) => *key = Some(value),
                Some(Node::Map(p, key @ Some(_))) => {
                    if let Some(k) = key.take() {
                        fields.scalars.insert(join(p, &k), value);
                    }
                }
                Some(Node::Seq(_, items)) => items.push(value),
                None => {}
            },
            Event::SequenceStart(..) | Event::MappingStart(..) => {
                if stack.len() >= MAX_DEPTH {
                    return Err(bad(at(&format!(
                        "nested more than {MAX_DEPTH} deep: not a camera file"
                    ))));
                }
                let key_path = match stack.last_mut() {
                    Some(Node::Map(p, key)) => join(p, &key.take().unwrap_or_default()),
                    Some(Node::Seq(p, _)) => format!("{p}[]"),
                    None => String::new(),
                };
                stack.push(match event {
                    Event::SequenceStart(..) => Node::Seq(key_path, Vec::new()),
                    _ => Node::Map(key_path, None),
                });
            }
            Event::SequenceEnd | Event::MappingEnd => {
                if let Some(Node::Seq(p, items)) = stack.pop() {
                    fields.lists.insert(p, items);
                }
            }
            _ => {}
        }
    }
    Ok(fields)
}

/// A number of the file (YAML's `.nan`/`.inf` spellings are not accepted: no camera has them).
fn number(path: &Path, name: &str, text: &str) -> Result<f64> {
    let t = text.trim();
    t.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| IoError::malformed(path, format!("{name}: {t:?} is not a finite number")))
}

fn first_scalar<'a>(f: &'a Fields, names: &[&str]) -> Option<(&'a str, String)> {
    names
        .iter()
        .find_map(|n| f.scalars.get(*n).map(|v| (v.as_str(), (*n).to_string())))
}

fn first_list<'a>(f: &'a Fields, names: &[&str]) -> Option<(&'a [String], String)> {
    names
        .iter()
        .find_map(|n| f.lists.get(*n).map(|v| (v.as_slice(), (*n).to_string())))
}

fn size(path: &Path, f: &Fields, names: &[&str]) -> Result<usize> {
    let Some((v, name)) = first_scalar(f, names) else {
        return Err(IoError::malformed(
            path,
            format!(
                "no image size: expected `{}` (a ROS camera calibration or CameraInfo)",
                names.join("` or `")
            ),
        ));
    };
    let n = number(path, &name, v)?;
    if !(n >= 1.0 && n.fract() == 0.0 && n <= sl_core::intrinsics::MAX_SIDE_PX as f64) {
        return Err(IoError::malformed(
            path,
            format!(
                "{name} is {v}: a whole number of pixels from 1 to {} is needed (0 is an \
                 uncalibrated camera)",
                sl_core::intrinsics::MAX_SIDE_PX
            ),
        ));
    }
    Ok(n as usize)
}

/// Reads a ROS camera calibration YAML or a saved `CameraInfo` echo (see the module docs).
///
/// # Errors
/// A file over [`MAX_ROS_CAMERA_BYTES`], YAML that does not parse, anchors or aliases, no image
/// size or `K`, a `K` that is not a pinhole matrix (skew, `K[2] ≠ [0, 0, 1]`), a principal point
/// outside the image, binning or a region of interest other than the whole image, a non-zero
/// distortion of a model other than `plumb_bob`, or an image larger than `limits` allows.
pub fn read_ros_camera(path: impl AsRef<Path>, limits: &Limits) -> Result<RosCamera> {
    let path = path.as_ref();
    let text = read_text(path, MAX_ROS_CAMERA_BYTES, MAX_ROS_CAMERA_BYTES)?;
    let f = fields_of(path, &text)?;
    let width = size(path, &f, &["image_width", "width"])?;
    let height = size(path, &f, &["image_height", "height"])?;
    limits
        .check_pixels(width as u64, height as u64)
        .map_err(|m| IoError::too_large(path, m))?;
    let Some((k, k_name)) = first_list(&f, &["camera_matrix.data", "K", "k"]) else {
        return Err(IoError::malformed(
            path,
            "no intrinsic matrix: expected `camera_matrix: {data: [...]}` or `K: [...]`",
        ));
    };
    if k.len() != 9 {
        return Err(IoError::malformed(
            path,
            format!("{k_name} has {} numbers, a 3x3 matrix needs 9", k.len()),
        ));
    }
    let mut m = [0.0; 9];
    for (i, v) in k.iter().enumerate() {
        m[i] = number(path, &k_name, v)?;
    }
    let scalar = |name: &str| -> Result<f64> {
        f.scalars
            .get(name)
            .map_or(Ok(0.0), |v| number(path, name, v))
    };
    let binning = (scalar("binning_x")?, scalar("binning_y")?);
    let roi = [
        scalar("roi.x_offset")?,
        scalar("roi.y_offset")?,
        scalar("roi.width")?,
        scalar("roi.height")?,
    ];
    let distortion_model = first_scalar(&f, &["distortion_model"])
        .map(|(v, _)| v.trim().to_string())
        .unwrap_or_default();
    let d: Vec<f64> = match first_list(&f, &["distortion_coefficients.data", "D", "d"]) {
        Some((d, name)) => d
            .iter()
            .map(|v| number(path, &name, v))
            .collect::<Result<_>>()?,
        None => Vec::new(),
    };
    camera_info_to_camera(
        path,
        &CameraInfo {
            width,
            height,
            k: m,
            binning,
            roi,
            distortion_model,
            d,
            projection: None,
        },
    )
}

/// The fields of a ROS `sensor_msgs/CameraInfo` that make a camera, as a YAML file or a bag
/// message states them.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CameraInfo {
    /// Image size, pixels.
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// `K`, row by row.
    pub(crate) k: [f64; 9],
    /// `binning_x`, `binning_y` (0 and 1 mean none).
    pub(crate) binning: (f64, f64),
    /// The region of interest: `x_offset`, `y_offset`, `width`, `height` (0 width and height:
    /// the whole image).
    pub(crate) roi: [f64; 4],
    /// `distortion_model` as written.
    pub(crate) distortion_model: String,
    /// `D`.
    pub(crate) d: Vec<f64>,
    /// `P`, row by row, when read (a bag's message; a YAML file's is not needed).
    pub(crate) projection: Option<[f64; 12]>,
}

/// The camera of a `CameraInfo` (see [`read_ros_camera`] for what is refused); errors name
/// `path`.
pub(crate) fn camera_info_to_camera(path: &Path, info: &CameraInfo) -> Result<RosCamera> {
    let (width, height) = (info.width, info.height);
    // Binning and a region of interest change the published image against `K`.
    for (name, b) in [("binning_x", info.binning.0), ("binning_y", info.binning.1)] {
        if b > 1.0 {
            return Err(IoError::malformed(
                path,
                format!(
                    "{name} is {b}: binned images are not read (their intrinsics are `K` \
                     divided by the binning)"
                ),
            ));
        }
    }
    let [rx, ry, rw, rh] = info.roi;
    let whole = rx == 0.0
        && ry == 0.0
        && (rw == 0.0 || rw == width as f64)
        && (rh == 0.0 || rh == height as f64);
    if !whole {
        return Err(IoError::malformed(
            path,
            format!(
                "a region of interest ({rw}x{rh} at {rx}, {ry}) is not read: its image is a \
                 crop of the one `K` describes"
            ),
        ));
    }
    let k = info.k;
    let m = [[k[0], k[1], k[2]], [k[3], k[4], k[5]], [k[6], k[7], k[8]]];
    let intrinsics = intrinsics_from_k(path, width, height, m)?;
    let distortion_model = info.distortion_model.clone();
    let d = &info.d;
    let lens = if d.iter().all(|&v| v == 0.0) {
        None
    } else if (distortion_model == "plumb_bob" || distortion_model == "Brown Conrady")
        && d.len() == 5
    {
        // librealsense's "Brown Conrady" is the same model, coefficients in the same order.
        Some(
            LensDistortion::new(d[0], d[1], d[2], d[3], d[4])
                .map_err(|e| IoError::core(path, None, e))?,
        )
    } else {
        return Err(IoError::malformed(
            path,
            format!(
                "distortion model {distortion_model:?} with {} non-zero coefficients: only \
                 `plumb_bob` (k1, k2, p1, p2, k3; librealsense's \"Brown Conrady\") is undone; \
                 undistort the depth first",
                d.len()
            ),
        ));
    };
    Ok(RosCamera {
        intrinsics,
        distortion_model,
        lens,
    })
}
