//! A robot recording as a sequence of depth frames, for `sldepth track REC [--topic T]` and
//! `sldepth fuse REC --trajectory FILE` (a ROS 1 bag, a ROS 2 bag in MCAP or SQLite, a
//! RealSense recording): its depth topic (the one image topic
//! holding depth unless named), its frames in the order they were recorded, stamped with their
//! image headers' stamps (a RealSense recording's sensor timestamps where its metadata has
//! them), its depth units (a RealSense recording's own) and its camera — `--camera`, else the
//! `camera_info` topic beside the depth topic with the noise model `RosBag::depth_camera`
//! chooses (its `plumb_bob` lens undone with `--lens auto`).

use std::path::Path;

use anyhow::{Context, Result, bail};
use sl_core::{Camera, DepthImage, LensDistortion};
use sl_io::rosbag::{BagMessage, DepthEncodingKind, RosBag};
use sl_io::sequence::SequenceFrame;

use crate::common::limits;

/// The frames of a bag's depth topic, read one by one as tracking asks for them.
pub(crate) struct BagFrames {
    bag: RosBag,
    messages: Vec<BagMessage>,
    /// A RealSense recording's sensor timestamps of the frames, where recorded (else the image
    /// header's stamp is the frame's time).
    times: Vec<Option<f64>>,
    /// The stamp of the last frame read, which the next must follow.
    last_stamp_s: Option<f64>,
}

/// What a bag gives `track`.
pub(crate) struct BagSource {
    /// One frame per message (the bag's path; the record time until the stamp is read).
    pub(crate) frames: Vec<SequenceFrame>,
    pub(crate) camera: Camera,
    /// The lens model of the bag's `camera_info` (`None` with `--camera`, or none to undo).
    pub(crate) lens: Option<LensDistortion>,
    /// Units per metre of the topic's depth: 1000 for 16-bit millimetres, 1 for float metres.
    pub(crate) default_scale: f64,
    pub(crate) reader: BagFrames,
}

/// The camera frame to pose by a recording's transforms, checked before any frame is read:
/// `camera_override` (`--tf-camera-frame`) or the depth images' own `image_frame`; both it and
/// `world` named by the transforms, and not the same frame. Transforms left out are said.
/// `instead` ends the message of a recording without usable transforms (what to do instead).
pub(crate) fn tf_camera_frame(
    path: &Path,
    tree: &sl_io::rosbag::TfTree,
    world: &str,
    camera_override: Option<&str>,
    image_frame: &str,
    instead: &str,
) -> Result<String> {
    if tree.samples() == 0 {
        if tree.skipped() > 0 {
            bail!(
                "{}: every one of its {} transforms is left out (numbers that make no rigid \
                 transform, or no proper frame name){instead}",
                path.display(),
                tree.skipped()
            );
        }
        bail!(
            "{}: no transforms (no /tf or /tf_static topic of tf2_msgs/TFMessage){instead}",
            path.display()
        );
    }
    let camera_frame = match camera_override {
        Some(f) => f.to_owned(),
        None if image_frame.trim_start_matches('/').is_empty() => bail!(
            "{}: the depth images name no frame in their headers: name the camera's optical \
             frame with --tf-camera-frame",
            path.display()
        ),
        None => image_frame.to_owned(),
    };
    let frames = || crate::common::frame_list(tree);
    for (f, opt) in [
        (world, "--tf"),
        (camera_frame.as_str(), "the camera's frame"),
    ] {
        if !tree.has_frame(f) {
            bail!(
                "{}: no transform names {f:?} ({opt}); its frames: {}",
                path.display(),
                frames()
            );
        }
    }
    if world.trim_start_matches('/') == camera_frame.trim_start_matches('/') {
        bail!(
            "{}: --tf {world:?} is the camera's own frame: name the world frame the camera \
             moves in (its frames: {})",
            path.display(),
            frames()
        );
    }
    if tree.skipped() > 0 {
        errln!(
            "note: {}: {} transforms are left out (numbers that make no rigid transform, or no \
             proper frame name)",
            path.display(),
            tree.skipped()
        );
    }
    Ok(camera_frame)
}

/// Says on standard error when `path` is one piece of a recording split by `rosbag record
/// --split` (read alone, it is only that piece).
pub(crate) fn note_split_piece(path: &Path) {
    if path.is_file()
        && let Some((at, pieces)) = sl_io::rosbag::split_piece_of(path)
    {
        errln!(
            "note: {} is piece {} of {} of a recording split by `rosbag record --split`: only \
             this piece is read (give its folder, {}, to read them all as one recording)",
            path.display(),
            at + 1,
            pieces.len(),
            path.parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."))
                .display()
        );
    }
}

/// Opens the bag at `path` and finds its depth topic (`topic`, or the one that holds depth) and
/// camera (`camera`, else the topic's `camera_info`), said on standard error (`verb`: what is
/// done with the topic, "tracking" or "fusing").
pub(crate) fn load(
    path: &Path,
    topic: Option<&str>,
    camera: Option<Camera>,
    verb: &str,
) -> Result<BagSource> {
    let mut bag = RosBag::open(path, &limits())?;
    note_split_piece(path);
    let topic = bag.depth_topic(topic)?;
    let messages = bag.messages(&topic)?;
    let Some(first) = messages.first().copied() else {
        bail!("{}: {topic} has no message", path.display());
    };
    let Some(kind) = bag.depth_kind(&first)? else {
        bail!(
            "{}: the images of {topic} are not depth (16UC1, mono16 or 32FC1); name the depth \
             topic with --topic",
            path.display()
        );
    };
    let default_scale = match kind {
        DepthEncodingKind::F32 => sl_io::depth::FLOAT_UNITS_PER_M,
        DepthEncodingKind::U16 => bag.depth_units_per_m(&topic)?,
    };
    let (camera, lens, whose) = match camera {
        Some(c) => (c, None, "--camera".to_string()),
        None => {
            let c = bag
                .depth_camera(&topic)
                .context("the camera of the depth topic (or give it with --camera NAME|FILE)")?;
            (
                c.camera,
                c.lens,
                format!("{} with {}", c.camera_info_topic, c.sensor_source),
            )
        }
    };
    let times = bag.realsense_frame_times(&topic, &messages)?;
    let k = camera.intrinsics;
    errln!(
        "note: {}: {verb} {topic} ({} frames, {}), camera from {whose} (fx {}, {}x{})",
        path.display(),
        messages.len(),
        match kind {
            DepthEncodingKind::F32 => "32FC1 metres".to_string(),
            DepthEncodingKind::U16 if default_scale == sl_io::depth::DEFAULT_UNITS_PER_M =>
                "16-bit millimetres unless --depth-scale".to_string(),
            DepthEncodingKind::U16 => format!(
                "16-bit units of {} mm as recorded, unless --depth-scale",
                crate::common::num(1e3 / default_scale)
            ),
        },
        crate::common::num(k.fx),
        k.width,
        k.height
    );
    let frames = messages
        .iter()
        .map(|m| SequenceFrame {
            depth_path: path.to_path_buf(),
            timestamp: Some(m.record_time_s),
        })
        .collect();
    Ok(BagSource {
        frames,
        camera,
        lens,
        default_scale,
        reader: BagFrames {
            bag,
            messages,
            times,
            last_stamp_s: None,
        },
    })
}

/// The tree of transforms of `bag` under `namespace` (`--tf-namespace`; `""`: the root's
/// `/tf` and `/tf_static`). A recording without topics there but with trees under other
/// namespaces is an error that names them.
pub(crate) fn transforms_in(
    bag: &mut sl_io::rosbag::RosBag,
    namespace: &str,
) -> Result<sl_io::rosbag::TfTree> {
    let ns = namespace.trim_matches('/');
    if bag.tf_topics_in(ns).is_empty() {
        // The other trees, the root's shown as `/` (no --tf-namespace).
        let others: Vec<String> = bag
            .tf_namespaces()
            .into_iter()
            .filter(|other| other.trim_matches('/') != ns)
            .map(|other| match other.as_str() {
                "" => "/ (no --tf-namespace)".to_string(),
                _ => other.escape_debug().to_string(),
            })
            .collect();
        // A recording without any transforms is said by `tf_camera_frame`, with what to do.
        if !others.is_empty() || !ns.is_empty() {
            let here = match ns {
                "" => "/tf or /tf_static".to_string(),
                ns => {
                    let ns = ns.escape_debug();
                    format!("/{ns}/tf or /{ns}/tf_static")
                }
            };
            let elsewhere = if others.is_empty() {
                "it has no tree of transforms".to_string()
            } else {
                format!(
                    "its trees of transforms are under {} (choose one with --tf-namespace)",
                    others.join(", ")
                )
            };
            bail!(
                "{}: no transforms on {here}; {elsewhere}",
                bag.path().display()
            );
        }
    }
    Ok(bag.transforms_in(ns)?)
}

impl BagFrames {
    /// The recording's transforms under `namespace` (`""`: `/tf`, `/tf_static`; see
    /// [`transforms_in`]) and the frame the first depth image names in its header (empty when
    /// the driver set none).
    pub(crate) fn transforms(
        &mut self,
        namespace: &str,
    ) -> Result<(sl_io::rosbag::TfTree, String)> {
        let tree = transforms_in(&mut self.bag, namespace)?;
        let frame = match self.messages.first() {
            Some(m) => self.bag.image_frame_id(m)?,
            None => String::new(),
        };
        Ok((tree, frame))
    }

    /// The recording's files.
    pub(crate) fn files(&self) -> Vec<std::path::PathBuf> {
        self.bag.file_paths()
    }

    /// Frame `i`'s depth at `units_per_m` and its stamp. A stamp that does not follow the last
    /// frame read is an error for that frame (tracking skips it, saying why).
    pub(crate) fn read(&mut self, i: usize, units_per_m: f64) -> (Result<DepthImage>, Option<f64>) {
        let Some(m) = self.messages.get(i).copied() else {
            return (Err(anyhow::anyhow!("no message {i}")), None);
        };
        let mut d = match self.bag.read_depth(&m, units_per_m, units_per_m) {
            Ok(d) => d,
            Err(e) => return (Err(e.into()), None),
        };
        if let Some(t) = self.times.get(i).copied().flatten() {
            d.stamp_s = t;
        }
        if let Some(last) = self.last_stamp_s.filter(|&l| d.stamp_s <= l) {
            return (
                Err(anyhow::anyhow!(
                    "its stamp {:.6} s does not follow the frame before's {last:.6} s",
                    d.stamp_s
                )),
                None,
            );
        }
        self.last_stamp_s = Some(d.stamp_s);
        (Ok(d.depth), Some(d.stamp_s))
    }
}
