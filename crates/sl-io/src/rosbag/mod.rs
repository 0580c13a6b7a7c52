//! Robot recordings: ROS 1 bags (`.bag`, format 2.0) and ROS 2 bags in MCAP (`.mcap`) or in
//! SQLite (`.db3`, the default storage up to Humble), or a ROS 2 bag's folder holding
//! `metadata.yaml` and one or several such files (a recording split by size or duration, read
//! as one: `part.rs` is one file), or a folder of one ROS 1 recording's pieces
//! (`rosbag record --split`: `NAME_0.bag`, `NAME_1.bag`, …, [`ros1_split_files`]) — the depth images and camera calibration a robot
//! recorded, read straight from the recording. TUM RGB-D ships every sequence as a ROS 1 bag;
//! a Kinect, Xtion, RealSense or OAK-D driver under ROS records its depth as
//! `sensor_msgs/Image`; librealsense's own recorder (the RealSense Viewer) writes a ROS 1 bag,
//! or a `.db3` since 2.56, whose sensor options (`realsense.rs`: depth units, stereo
//! baseline, the device) choose the depth scale and noise model (`camera.rs`).
//!
//! Written by hand (no crate reads bags within a memory budget): the index (ROS 1: connections
//! and chunk places at the end of the file; MCAP: the summary section the footer points at) is
//! read first; a topic's messages are then found from the index records of each chunk, without
//! decompressing anything; a message is read by decompressing its chunk (`none`; ROS 1 `bz2`
//! through the `bzip2` crate; `lz4` frames through `lz4_flex`; MCAP `zstd` through `ruzstd`),
//! which is kept for the next message. Every length is checked against the file and
//! [`Limits::max_decoded_bytes`] before a buffer is sized from it. A `.db3` is read through
//! a read-only reader of the SQLite file format (`sqlite.rs`, `db3.rs`): its `messages` table
//! walked once for each row's topic, time and place, a message's data read when asked for.
//!
//! Messages: ROS 1's serialisation, or ROS 2's CDR (`messages.rs`). Depth: `16UC1` and
//! `mono16` are units (millimetres by ROS's REP 118, 0 = none), `32FC1` metres (NaN = none;
//! TUM's bags store `/camera/depth/image` so); `image_transport`'s `compressedDepth`
//! (`sensor_msgs/CompressedImage`, what a robot records over a network) is read in both its
//! codecs, PNG and RVL (`rvl.rs`), `16UC1` millimetres or `32FC1` as quantised inverse depth. The frame's time is its message header's stamp (the sensor's), not the time the
//! recorder received it.
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use sl_io::Limits;
//! use sl_io::rosbag::RosBag;
//!
//! // A file that is not a bag is an error that says what was expected.
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("not.bag");
//! std::fs::write(&path, b"hello")?;
//! let err = RosBag::open(&path, &Limits::default()).unwrap_err();
//! assert!(err.to_string().contains("not a ROS 1 bag"));
//! # Ok(())
//! # }
//! ```

mod camera;
mod db3;
mod mcap;
mod messages;
mod part;
mod realsense;
mod records;
mod rvl;
mod sqlite;
mod stereo;
mod tf;

use std::path::{Path, PathBuf};

use sl_core::DepthImage;

pub use camera::BagCamera;
pub use messages::DepthEncodingKind;
use messages::Encoding;
pub use realsense::RealSenseInfo;
pub use stereo::{MAX_STEREO_BASELINE_M, MIN_STEREO_BASELINE_M, PairKind, RecordedBaseline};
pub use tf::{
    MAX_CHAIN_FRAMES, MAX_FRAME_NAME_BYTES, MAX_TRANSLATION_M, TfFrame, TfLookupError, TfTree,
};

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::ros_camera::{RosCamera, camera_info_to_camera};

/// The message type of a depth or colour image.
pub const IMAGE_TYPE: &str = "sensor_msgs/Image";
/// The message type of a compressed image (`image_transport`'s `compressedDepth` for depth).
pub const COMPRESSED_IMAGE_TYPE: &str = "sensor_msgs/CompressedImage";
/// The message type of a camera calibration.
pub const CAMERA_INFO_TYPE: &str = "sensor_msgs/CameraInfo";
/// The message types of transforms: `tf2`'s, and ROS 1 `tf`'s of the same layout.
pub const TF_TYPES: [&str; 2] = ["tf2_msgs/TFMessage", "tf/tfMessage"];

/// The namespace of a transforms topic, without its slashes (`/tf` → `""`, `/robot1/tf_static`
/// → `"robot1"`), or `None` for a topic that is not `tf` or `tf_static` under one.
fn tf_namespace_of(topic: &str) -> Option<&str> {
    let t = topic.trim_start_matches('/');
    let (ns, last) = t.rsplit_once('/').unwrap_or(("", t));
    matches!(last, "tf" | "tf_static").then_some(ns.trim_matches('/'))
}
/// Memory a transform sample is allowed, bytes: a recording's transforms are held to
/// [`Limits::max_memory_bytes`] divided by this (4 million samples at the default budget).
pub const BYTES_PER_TRANSFORM: u64 = 1 << 10;

/// One topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagTopic {
    /// Its name (`/camera/depth/image`).
    pub topic: String,
    /// Its message type (`sensor_msgs/Image`).
    pub message_type: String,
    /// How many messages the bag holds on it (from the index).
    pub messages: u64,
}

/// Where one message lies (found by [`RosBag::messages`], read by [`RosBag::read_depth`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagMessage {
    /// The file of the recording it is in.
    part: u32,
    chunk_pos: u64,
    /// Where its record lies in the chunk's decompressed records.
    offset: u64,
    /// A `sensor_msgs/CompressedImage` rather than an `Image`.
    compressed: bool,
    /// How it is serialised (ROS 1, or ROS 2's CDR).
    encoding: Encoding,
    /// When the recorder received it, seconds (the message's own stamp is read with it).
    pub record_time_s: f64,
}

/// A depth frame read from a bag.
#[derive(Debug, Clone)]
pub struct BagDepth {
    /// The image header's stamp, seconds (the record time when the stamp is 0).
    pub stamp_s: f64,
    /// Depth in metres, 0 = none.
    pub depth: DepthImage,
    /// How the message stored it.
    pub kind: DepthEncodingKind,
}

/// A topic's connection (ROS 1) or channel (MCAP).
#[derive(Debug, Clone)]
struct Connection {
    id: u32,
    topic: String,
    /// As ROS 1 names it (`sensor_msgs/Image`; MCAP's `sensor_msgs/msg/Image` so renamed).
    message_type: String,
    encoding: Encoding,
}

/// A chunk: where it lies and what it holds.
#[derive(Debug, Clone)]
struct ChunkInfo {
    pos: u64,
    /// `(connection, messages)` in the chunk.
    counts: Vec<(u32, u32)>,
    /// MCAP: where each channel's message index record lies (ROS 1's follow the chunk).
    index_at: Vec<(u32, u64)>,
}

/// The container of the recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    /// ROS 1 bag, format 2.0.
    Ros1,
    /// MCAP (ROS 2).
    Mcap,
    /// SQLite (ROS 2, `.db3`).
    Sqlite,
}

/// An open recording (see the module docs): one file, or the files of a ROS 2 bag split into
/// several.
#[derive(Debug)]
pub struct RosBag {
    /// The file, or the folder of a recording in several files.
    path: PathBuf,
    limits: Limits,
    parts: Vec<part::Part>,
}

/// Whether `path` names a recording [`RosBag::open`] takes: a `.bag` (ROS 1) or `.mcap` file,
/// a ROS 2 bag's folder (`metadata.yaml` beside its `.mcap` or `.db3` files), or a folder of
/// one ROS 1 recording split by `rosbag record --split` ([`ros1_split_files`]) that is not
/// also a folder of depth frames ([`crate::sequence::SequenceLayout::infer`]).
pub fn is_bag_file(path: &Path) -> bool {
    let ext = |p: &Path, e: &str| p.extension().is_some_and(|x| x.eq_ignore_ascii_case(e));
    if path.is_dir() {
        let ros2 = path.join("metadata.yaml").is_file()
            && std::fs::read_dir(path).is_ok_and(|d| {
                d.flatten()
                    .any(|e| ext(&e.path(), "mcap") || ext(&e.path(), "db3"))
            });
        // A folder of frames that also holds a split bag is the folder of frames.
        let frames = crate::sequence::SequenceLayout::infer(path).is_ok();
        return ros2 || (!frames && ros1_split_files(path).is_some());
    }
    ext(path, "bag") || ext(path, "mcap") || ext(path, "db3")
}

/// The files of a ROS 1 recording split by `rosbag record --split` in the folder `dir`, in
/// order: every `.bag` file in it is named `<name>_<n>.bag` with one `<name>` (as the recorder
/// names the pieces: `rec_0.bag`, `rec_1.bag`, …, or `rec_2024-05-01-10-00-00_0.bag`, …) and
/// `n` counting from 0 without a gap. `None` for a folder with no `.bag` file, or with bags
/// of different names or numbers (separate recordings: give one of them).
pub fn ros1_split_files(dir: &Path) -> Option<Vec<PathBuf>> {
    let mut pieces: Vec<(u64, PathBuf)> = Vec::new();
    let mut name: Option<String> = None;
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        let p = e.path();
        if !p.extension().is_some_and(|x| x.eq_ignore_ascii_case("bag")) || !p.is_file() {
            continue;
        }
        let stem = p.file_stem()?.to_str()?;
        let (base, n) = stem.rsplit_once('_')?;
        if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        match &name {
            Some(b) if b != base => return None,
            Some(_) => {}
            None => name = Some(base.to_owned()),
        }
        pieces.push((n.parse().ok()?, p));
    }
    pieces.sort();
    let numbered_from_zero = pieces.iter().enumerate().all(|(i, (n, _))| *n == i as u64);
    (!pieces.is_empty() && numbered_from_zero).then(|| pieces.into_iter().map(|(_, p)| p).collect())
}

/// Where the ROS 1 bag file `path` is one piece of a recording split by `rosbag record --split`
/// (its folder holds that recording's pieces, [`ros1_split_files`], and more than this one):
/// its index among them and all the pieces, in order. Opened alone it reads as that piece, a
/// part of the recording; the folder reads as the whole.
pub fn split_piece_of(path: &Path) -> Option<(usize, Vec<PathBuf>)> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let pieces = ros1_split_files(dir).filter(|p| p.len() > 1)?;
    let name = path.file_name()?;
    let at = pieces.iter().position(|p| p.file_name() == Some(name))?;
    Some((at, pieces))
}

/// The files of a recording: `path` itself, a ROS 2 bag folder's `.mcap` or `.db3` files (a
/// recording split by size or duration), in the natural order of their names, or the pieces of
/// a split ROS 1 recording ([`ros1_split_files`]).
fn bag_files_of(path: &Path) -> Result<Vec<PathBuf>> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    if !path.join("metadata.yaml").is_file()
        && let Some(files) = ros1_split_files(path)
    {
        return Ok(files);
    }
    let mut files = Vec::new();
    for e in std::fs::read_dir(path).map_err(|e| IoError::io(path, e))? {
        let p = e.map_err(|e| IoError::io(path, e))?.path();
        if p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("db3"))
        {
            files.push(p);
        }
    }
    files.sort_by(|a, b| crate::trajectory::natural_order(a.as_os_str(), b.as_os_str()));
    if files.is_empty() {
        return Err(IoError::malformed(
            path,
            "a folder without an .mcap or .db3 file (a ROS 2 bag), or the .bag files of one ROS \
             1 recording split by `rosbag record --split` (NAME_0.bag, NAME_1.bag, ...)",
        ));
    }
    let ext = |p: &PathBuf| p.extension().map(|e| e.to_ascii_lowercase());
    if files.iter().any(|f| ext(f) != ext(&files[0])) {
        return Err(IoError::malformed(
            path,
            "a folder of both .mcap and .db3 files (a ROS 2 bag keeps one storage): give one \
             of them",
        ));
    }
    Ok(files)
}

impl RosBag {
    /// Opens a recording and reads its index (connections and chunk places; of a `.db3`, its
    /// topics and every message's topic, time and place): a file, or a ROS 2 bag's folder and
    /// every `.mcap` (or `.db3`) file in it, read as one recording.
    ///
    /// # Errors
    /// A file that is not a bag (ROS 1 of format 2.0, MCAP or SQLite), a bag without an index
    /// (a recording that was not closed: `rosbag reindex` or `mcap recover` writes one; a
    /// `.db3` whose newest writes are still in its `-wal` file), a folder of both storages, or
    /// a malformed or truncated record or page.
    pub fn open(path: impl AsRef<Path>, limits: &Limits) -> Result<Self> {
        let path = path.as_ref();
        let files = bag_files_of(path)?;
        let parts = files
            .iter()
            .map(|f| part::Part::open(f, limits))
            .collect::<Result<Vec<_>>>()?;
        let path = match parts.as_slice() {
            [one] => one.path().to_path_buf(),
            _ => path.to_path_buf(),
        };
        Ok(Self {
            path,
            limits: *limits,
            parts,
        })
    }

    /// The bag's file (a ROS 2 bag folder's `.mcap` or `.db3`), or the folder of a recording
    /// in several files.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// How many files hold the recording (a ROS 2 bag split by size or duration: several).
    pub fn files(&self) -> usize {
        self.parts.len()
    }

    /// The recording's files, in the order they are read (one, or a split ROS 2 bag's).
    pub fn file_paths(&self) -> Vec<PathBuf> {
        self.parts.iter().map(|p| p.path().to_path_buf()).collect()
    }

    /// What holds the recording: `"ROS 1 bag"`, `"MCAP (ROS 2 bag)"` or `"SQLite (ROS 2 bag)"`.
    pub fn container(&self) -> &'static str {
        self.parts
            .first()
            .map_or("ROS 1 bag", part::Part::container)
    }

    /// The bag's topics, by name, with their message types and counts (over all its files).
    pub fn topics(&self) -> Vec<BagTopic> {
        let mut out: Vec<BagTopic> = Vec::new();
        for t in self.parts.iter().flat_map(part::Part::topics) {
            match out.iter_mut().find(|o| o.topic == t.topic) {
                Some(o) => o.messages += t.messages,
                None => out.push(t),
            }
        }
        out.sort_by(|a, b| a.topic.cmp(&b.topic));
        out
    }

    /// The messages of `topic`, in the order they were recorded (at most
    /// [`Limits::max_frames`]; over all the recording's files).
    ///
    /// # Errors
    /// A topic the bag does not have (the error lists those it has), more messages than the
    /// limit, or a malformed index.
    pub fn messages(&mut self, topic: &str) -> Result<Vec<BagMessage>> {
        if self.message_type(topic).is_none() {
            let have: Vec<String> = self.topics().into_iter().map(|t| t.topic).collect();
            return Err(IoError::malformed(
                &self.path,
                format!("no topic {topic:?} (the bag has {})", have.join(", ")),
            ));
        }
        let mut out = Vec::new();
        for (i, p) in self.parts.iter_mut().enumerate() {
            if p.message_type(topic).is_some() {
                out.extend(p.messages(topic, i as u32)?);
            }
            if out.len() > self.limits.max_frames {
                return Err(IoError::too_large(
                    &self.path,
                    format!(
                        "{topic} has more than {} messages, the limit of frames a sequence may \
                         have (raise --max-memory)",
                        self.limits.max_frames
                    ),
                ));
            }
        }
        // Each file's in time order; a stable sort keeps the files' order among equal times.
        out.sort_by(|a, b| a.record_time_s.total_cmp(&b.record_time_s));
        Ok(out)
    }

    /// The serialised message `m`.
    fn message(&mut self, m: &BagMessage) -> Result<&[u8]> {
        let path = self.path.clone();
        match self.parts.get_mut(m.part as usize) {
            Some(p) => p.message(m),
            None => Err(IoError::malformed(&path, "a message of another recording")),
        }
    }

    /// The type of the messages of `topic`, if the bag has it.
    pub fn message_type(&self, topic: &str) -> Option<&str> {
        self.parts.iter().find_map(|p| p.message_type(topic))
    }

    /// How the image message `m` stores depth (`None`: an image that is not depth).
    ///
    /// # Errors
    /// As [`RosBag::read_depth`], but for the pixels.
    pub fn depth_kind(&mut self, m: &BagMessage) -> Result<Option<DepthEncodingKind>> {
        Ok(self
            .image_encoding(m)?
            .as_deref()
            .and_then(DepthEncodingKind::of))
    }

    /// The depth image of message `m` (of a `sensor_msgs/Image` topic): 16-bit values divided by
    /// `units_per_m` (ROS's millimetres: 1000), floats by `float_units_per_m` (metres: 1).
    ///
    /// # Errors
    /// A message that is not a depth image, pixels beyond the limits, or a malformed chunk.
    pub fn read_depth(
        &mut self,
        m: &BagMessage,
        units_per_m: f64,
        float_units_per_m: f64,
    ) -> Result<BagDepth> {
        let path = self.path.clone();
        let limits = self.limits;
        let (compressed, cdr) = (m.compressed, m.encoding);
        let b = self.message(m)?;
        let (stamp_s, depth, encoding) = if compressed {
            let c = messages::compressed_image(&path, b, cdr)?;
            let depth =
                messages::compressed_depth_of(&path, &c, units_per_m, float_units_per_m, &limits)?;
            let encoding = messages::compressed_depth_encoding(&c.format)
                .unwrap_or_default()
                .to_string();
            (c.stamp_s, depth, encoding)
        } else {
            let img = messages::image(&path, b, cdr)?;
            let depth = messages::depth_of(&path, &img, units_per_m, float_units_per_m, &limits)?;
            (img.stamp_s, depth, img.encoding)
        };
        let kind = DepthEncodingKind::of(&encoding).unwrap_or(DepthEncodingKind::U16);
        let stamp_s = if stamp_s > 0.0 {
            stamp_s
        } else {
            m.record_time_s
        };
        Ok(BagDepth {
            stamp_s,
            depth,
            kind,
        })
    }

    /// The camera of the first message on the `sensor_msgs/CameraInfo` topic `topic`.
    ///
    /// # Errors
    /// No such topic or message, or a calibration [`crate::ros_camera::read_ros_camera`] would
    /// refuse (binning, a region of interest, a distortion other than `plumb_bob`).
    pub fn camera(&mut self, topic: &str) -> Result<RosCamera> {
        let path = self.path.clone();
        let first = self
            .messages(topic)?
            .into_iter()
            .next()
            .ok_or_else(|| IoError::malformed(&path, format!("{topic} has no message")))?;
        let b = self.message(&first)?;
        let info = messages::camera_info(&path, b, first.encoding)?;
        self.limits
            .check_pixels(info.width as u64, info.height as u64)
            .map_err(|e| IoError::too_large(&path, e))?;
        camera_info_to_camera(&path, &info)
    }

    /// The depth topic to read: `requested` when given (it must be an image topic), else the one
    /// image topic whose first message holds depth (`16UC1`, `32FC1`, or `mono16` on a topic
    /// named for depth; an infrared `mono16` stream is not depth), a `compressedDepth` topic
    /// counting as one.
    ///
    /// # Errors
    /// No depth topic, or several (the error lists them: name one).
    pub fn depth_topic(&mut self, requested: Option<&str>) -> Result<String> {
        let path = self.path.clone();
        if let Some(t) = requested {
            return match self.message_type(t) {
                Some(IMAGE_TYPE | COMPRESSED_IMAGE_TYPE) => Ok(t.to_string()),
                Some(other) => Err(IoError::malformed(
                    &path,
                    format!("{t} carries {other}, not {IMAGE_TYPE}"),
                )),
                None => self.messages(t).map(|_| t.to_string()),
            };
        }
        let images: Vec<String> = self
            .topics()
            .into_iter()
            .filter(|t| {
                (t.message_type == IMAGE_TYPE || t.message_type == COMPRESSED_IMAGE_TYPE)
                    && t.messages > 0
            })
            .map(|t| t.topic)
            .collect();
        let mut depth = Vec::new();
        for t in &images {
            let Some(first) = self.messages(t)?.into_iter().next() else {
                continue;
            };
            let named = t.to_ascii_lowercase().contains("depth");
            // `mono16` is depth only on a topic named for it (an infrared stream is not).
            let is_depth = match self.image_encoding(&first)?.as_deref() {
                Some("mono16") => named,
                Some(e) => DepthEncodingKind::of(e).is_some(),
                None => false,
            };
            if is_depth {
                depth.push(t.clone());
            }
        }
        match depth.len() {
            1 => Ok(depth.swap_remove(0)),
            0 => Err(IoError::malformed(
                &path,
                format!(
                    "no depth image topic (16UC1, 32FC1, or mono16 named for depth) among its \
                     image topics: {}",
                    if images.is_empty() {
                        "none".to_string()
                    } else {
                        images.join(", ")
                    }
                ),
            )),
            _ => Err(IoError::malformed(
                &path,
                format!(
                    "several depth image topics: {}; name one (--topic)",
                    depth.join(", ")
                ),
            )),
        }
    }

    /// The encoding of image message `m` (of a `compressedDepth` image, the encoding its format
    /// names; `None` for another compressed image).
    fn image_encoding(&mut self, m: &BagMessage) -> Result<Option<String>> {
        let path = self.path.clone();
        let (compressed, cdr) = (m.compressed, m.encoding);
        let b = self.message(m)?;
        if compressed {
            let c = messages::compressed_image(&path, b, cdr)?;
            return Ok(messages::compressed_depth_encoding(&c.format).map(str::to_string));
        }
        Ok(Some(messages::image(&path, b, cdr)?.encoding))
    }

    /// The frame an image message names in its header (`header.frame_id`: a camera driver's
    /// optical frame, `camera_depth_optical_frame`; empty when the driver set none).
    ///
    /// # Errors
    /// A malformed message.
    pub fn image_frame_id(&mut self, m: &BagMessage) -> Result<String> {
        let path = self.path.clone();
        let cdr = m.encoding;
        let b = self.message(m)?;
        Ok(messages::image_header(&path, b, cdr)?.1)
    }

    /// The stamp of image message `m` (its header's, seconds; the record time when the stamp
    /// is 0, as [`RosBag::read_depth`] stamps the frame), read without decoding its pixels.
    ///
    /// # Errors
    /// A malformed message.
    pub fn image_stamp_s(&mut self, m: &BagMessage) -> Result<f64> {
        let path = self.path.clone();
        let cdr = m.encoding;
        let b = self.message(m)?;
        let t = messages::image_header(&path, b, cdr)?.0;
        Ok(if t > 0.0 { t } else { m.record_time_s })
    }

    /// The topics of transforms [`RosBag::transforms`] reads: `/tf` and `/tf_static` of
    /// `tf2_msgs/TFMessage` (or ROS 1's `tf/tfMessage`), sorted. A robot's own namespaced
    /// tree (`/robot1/tf`) is another tree and is not among them ([`RosBag::tf_topics_in`]).
    pub fn tf_topics(&self) -> Vec<String> {
        self.tf_topics_in("")
    }

    /// The topics of the tree of transforms under `namespace` (`/robot1`: `/robot1/tf` and
    /// `/robot1/tf_static`, as a multi-robot recording remaps them; `""` or `/`: the root's),
    /// sorted.
    pub fn tf_topics_in(&self, namespace: &str) -> Vec<String> {
        let ns = namespace.trim_matches('/');
        self.topics()
            .into_iter()
            .filter(|t| {
                TF_TYPES.contains(&t.message_type.as_str()) && tf_namespace_of(&t.topic) == Some(ns)
            })
            .map(|t| t.topic)
            .collect()
    }

    /// The namespaces that hold a tree of transforms (`/tf` or `/tf_static` of a transform type
    /// under them), sorted: `""` for the root's, `/robot1` for `/robot1/tf`.
    pub fn tf_namespaces(&self) -> Vec<String> {
        let mut out: Vec<String> = self
            .topics()
            .iter()
            .filter(|t| TF_TYPES.contains(&t.message_type.as_str()))
            .filter_map(|t| tf_namespace_of(&t.topic))
            .map(|ns| {
                if ns.is_empty() {
                    String::new()
                } else {
                    format!("/{ns}")
                }
            })
            .collect();
        out.sort();
        out.dedup();
        out
    }

    /// Every transform the recording holds on its [`RosBag::tf_topics`], as a tree of frames
    /// ([`TfTree`]): `/tf_static` holds static transforms, `/tf` transforms over time. Empty
    /// when the recording has no transforms.
    ///
    /// # Errors
    /// A malformed message, more samples than the budget allows ([`BYTES_PER_TRANSFORM`]), or
    /// transforms that make no tree (a frame with two parents, a frame its own parent).
    pub fn transforms(&mut self) -> Result<TfTree> {
        self.transforms_in("")
    }

    /// [`RosBag::transforms`] of the tree under `namespace` ([`RosBag::tf_topics_in`]).
    ///
    /// # Errors
    /// As [`RosBag::transforms`].
    pub fn transforms_in(&mut self, namespace: &str) -> Result<TfTree> {
        let path = self.path.clone();
        let max = self.limits.max_memory_bytes / BYTES_PER_TRANSFORM;
        let mut tree = TfTree::new();
        for topic in self.tf_topics_in(namespace) {
            let is_static = topic.ends_with("tf_static");
            for m in self.messages(&topic)? {
                let b = self.message(&m)?;
                let entries = messages::transforms(&path, b, m.encoding)?;
                tree.insert_entries(&entries, is_static)
                    .map_err(|e| IoError::malformed(&path, format!("{topic}: {e}")))?;
                if (tree.samples() + tree.skipped()) as u64 > max {
                    return Err(IoError::too_large(
                        &path,
                        format!(
                            "more than {max} transforms, the most the memory budget holds \
                             (raise --max-memory)"
                        ),
                    ));
                }
            }
        }
        Ok(tree)
    }

    /// The `sensor_msgs/CameraInfo` topic beside the image topic `image_topic`
    /// (`/camera/depth/image` → `/camera/depth/camera_info`; a transport's topic
    /// `/camera/depth/image_raw/compressedDepth` → the same; a RealSense recording's
    /// `/device_0/sensor_0/Depth_0/image/data` → `/device_0/sensor_0/Depth_0/info/camera_info`),
    /// if the bag has it.
    pub fn camera_info_topic(&self, image_topic: &str) -> Option<String> {
        let ns = image_topic.rsplit_once('/').map_or("", |(ns, _)| ns);
        let parent = ns.rsplit_once('/').map_or("", |(p, _)| p);
        [
            format!("{ns}/camera_info"),
            format!("{parent}/camera_info"),
            format!("{parent}/info/camera_info"),
        ]
        .into_iter()
        .find(|t| self.message_type(t) == Some(CAMERA_INFO_TYPE))
    }
}
