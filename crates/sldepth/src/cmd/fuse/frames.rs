//! The frames `fuse` integrates, each with its pose: depth files with theirs (a sequence folder,
//! a frame list, an Open3D `.log`), or a robot recording's depth messages, each posed by the
//! trajectory file's pose nearest its stamp (`fuse REC --trajectory FILE`) or by the
//! recording's own transforms at its stamp (`fuse REC --tf WORLD`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use sl_core::{CameraToWorld, DepthImage};
use sl_io::depth::{ReadConfig, read_depth_with_limits};
use sl_io::rosbag::{TfLookupError, TfTree};
use sl_io::trajectory::{Frame, TimedPose};

use crate::common::limits;
use crate::recording::BagFrames;

/// The frames of `fuse`, read one by one.
pub(super) enum Frames {
    /// Depth files with their poses.
    Files(Vec<Frame>),
    /// A recording's depth messages, posed by a trajectory.
    Recording(Box<Recording>),
}

/// What poses a recording's frames.
pub(super) enum PoseSource {
    /// A trajectory file's poses.
    Trajectory {
        poses: Vec<TimedPose>,
        /// The file, for messages.
        file: PathBuf,
        /// An Open3D `.log`: message `i` takes entry `i`, not a pose by time.
        by_number: bool,
    },
    /// The recording's own transforms: the pose of `camera_frame` in `world` at each stamp.
    Transforms {
        tree: TfTree,
        world: String,
        camera_frame: String,
        /// Why the first frame without a pose had none, for the messages.
        first_miss: Option<TfLookupError>,
    },
}

impl PoseSource {
    /// Where the poses come from, for messages.
    pub(super) fn describe(&self) -> String {
        match self {
            Self::Trajectory { file, .. } => file.display().to_string(),
            Self::Transforms {
                world,
                camera_frame,
                ..
            } => format!(
                "the recording's transforms ({} in {})",
                camera_frame.escape_debug(),
                world.escape_debug()
            ),
        }
    }
}

/// A recording's depth messages and what poses them.
pub(super) struct Recording {
    pub(super) path: PathBuf,
    pub(super) reader: BagFrames,
    /// Messages of the depth topic (after `--max-frames`).
    pub(super) count: usize,
    pub(super) poses: PoseSource,
    /// The largest time between a frame's stamp and its pose.
    pub(super) max_dt_s: f64,
    /// Frames read so far without a pose within `max_dt_s`.
    pub(super) without_pose: usize,
    /// The stamp of the first frame, read for the camera's size (the caller keeps its depth).
    pub(super) first_stamp: Option<f64>,
}

/// One frame to integrate.
pub(super) struct Posed {
    pub(super) depth: DepthImage,
    pub(super) pose: CameraToWorld,
    /// How messages name the frame: its file, or the recording's message and stamp.
    pub(super) label: String,
}

impl Frames {
    /// Frames in the source (a recording's: its depth messages, posed or not).
    pub(super) fn len(&self) -> usize {
        match self {
            Self::Files(f) => f.len(),
            Self::Recording(r) => r.count,
        }
    }

    /// Keeps the first `n` frames.
    pub(super) fn truncate(&mut self, n: usize) {
        match self {
            Self::Files(f) => f.truncate(n),
            Self::Recording(r) => r.count = r.count.min(n),
        }
    }

    /// The first frame's file, or the recording.
    pub(super) fn first_path(&self) -> Option<&Path> {
        match self {
            Self::Files(f) => f.first().map(|f| f.depth_path.as_path()),
            Self::Recording(r) => (r.count > 0).then_some(r.path.as_path()),
        }
    }

    /// The files the frames are read from.
    pub(super) fn inputs(&self) -> Vec<PathBuf> {
        match self {
            Self::Files(f) => f.iter().map(|f| f.depth_path.clone()).collect(),
            Self::Recording(r) => r.reader.files(),
        }
    }

    /// Frames that had no pose: a recording's frames read so far without one in the
    /// trajectory (a folder's were left out when it was read).
    pub(super) fn without_pose(&self) -> usize {
        match self {
            Self::Files(_) => 0,
            Self::Recording(r) => r.without_pose,
        }
    }

    /// Frame `i` read (`first`: the first frame, already read for the camera's size) and
    /// posed; `None` for a recording's frame the trajectory has no pose for.
    ///
    /// # Errors
    /// An unreadable file or message, or a message stamped before the one before it.
    pub(super) fn read(
        &mut self,
        i: usize,
        read_opts: &ReadConfig,
        first: &mut Option<DepthImage>,
    ) -> Result<Option<Posed>> {
        match self {
            Self::Files(frames) => {
                let f = &frames[i];
                let depth = match first.take() {
                    Some(d) => d,
                    None => {
                        read_depth_with_limits(&f.depth_path, read_opts, &limits())
                            .with_context(|| format!("reading {}", f.depth_path.display()))?
                            .depth
                    }
                };
                Ok(Some(Posed {
                    depth,
                    pose: f.pose,
                    label: f.depth_path.display().to_string(),
                }))
            }
            Self::Recording(r) => r.read(i, read_opts, first),
        }
    }
}

impl Recording {
    fn read(
        &mut self,
        i: usize,
        read_opts: &ReadConfig,
        first: &mut Option<DepthImage>,
    ) -> Result<Option<Posed>> {
        let label = |stamp: Option<f64>| match stamp {
            Some(t) => format!("{} message {i} (stamp {t:.6} s)", self.path.display()),
            None => format!("{} message {i}", self.path.display()),
        };
        let (depth, stamp) = match first.take() {
            Some(d) => (Ok(d), self.first_stamp),
            None => {
                let scale = read_opts
                    .scale_units_per_m
                    .unwrap_or(sl_io::depth::DEFAULT_UNITS_PER_M);
                self.reader.read(i, scale)
            }
        };
        let depth = depth.with_context(|| format!("reading {}", label(stamp)))?;
        let by_number = matches!(
            self.poses,
            PoseSource::Trajectory {
                by_number: true,
                ..
            }
        );
        let (t, max_dt) = match stamp {
            _ if by_number => (i as f64, 0.0),
            Some(t) => (t, self.max_dt_s),
            None => bail!(
                "{}: no stamp to match in {}",
                label(None),
                self.poses.describe()
            ),
        };
        let pose = match &mut self.poses {
            PoseSource::Trajectory { poses, .. } => {
                sl_io::trajectory::nearest_pose(poses, t, max_dt).map(|p| p.pose)
            }
            PoseSource::Transforms {
                tree,
                world,
                camera_frame,
                first_miss,
            } => match tree.lookup(world, camera_frame, t, max_dt) {
                Ok(p) => Some(CameraToWorld::from_isometry(p)),
                Err(e) => {
                    first_miss.get_or_insert(e);
                    None
                }
            },
        };
        match pose {
            Some(pose) => Ok(Some(Posed {
                depth,
                pose,
                label: label(stamp),
            })),
            None => {
                self.without_pose += 1;
                Ok(None)
            }
        }
    }
}
