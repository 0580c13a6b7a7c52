//! `sldepth track --odometry FILE | --odometry-tf FRAME`: a motion measured beside the depth (a
//! robot's wheel odometry, another tracker's estimate) that predicts each frame and is the
//! prior of its alignment (`sl_track::Tracker::set_odometry`): from a TUM-format trajectory
//! file of the camera in the odometry's frame, or from a recording's own transforms (the
//! camera's optical frame in `FRAME`, as `fuse --tf` poses frames). Either way a frame takes
//! the pose interpolated at its timestamp by `sl_io::rosbag::TfTree`'s rules: between samples
//! no more than twice their median interval apart, else the nearest within
//! `--odometry-max-gap-s`, else none (the frame is then tracked as without odometry).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use sl_core::nalgebra::Isometry3;
use sl_io::rosbag::{TfLookupError, TfTree};
use sl_track::TrackerConfig;

use crate::common::{check_range, limits};

/// The frame names a trajectory file's poses are kept under.
const ODOMETRY_FRAME: &str = "odometry";
const CAMERA_FRAME: &str = "camera";

/// Options of `sldepth track` for an odometry given with the frames.
#[derive(Debug, clap::Args)]
pub struct OdometryArgs {
    /// A trajectory of the camera in an odometry's frame, TUM format (`timestamp tx ty tz qx
    /// qy qz qw`, camera to odometry: a robot's wheel odometry composed with the camera's
    /// mounting, or another tracker's output), on the frames' clock. Its motion between frames
    /// predicts each frame and is the prior of its alignment, with σ from --odometry-drift and
    /// the floors below: where the depth pins the pose better (most views) the depth decides;
    /// along a direction it leaves free (a corridor's axis, a single wall) the pose is the
    /// odometry's instead of the frame being lost as a degenerate view; across lost frames the
    /// prediction is the odometry's. The frames need timestamps (TUM folders, recordings,
    /// Open3D folders named by time).
    #[arg(long, value_name = "FILE", conflicts_with = "odometry_tf")]
    pub odometry: Option<PathBuf>,
    /// For a recording: the odometry's frame in its transforms (`odom`): each frame takes its
    /// camera's pose in it at its stamp, as `fuse --tf` does (the camera's frame from the depth
    /// images' headers, or --tf-camera-frame).
    #[arg(long, value_name = "FRAME")]
    pub odometry_tf: Option<String>,
    /// The camera's optical frame for --odometry-tf, where the depth images name none or
    /// another one.
    #[arg(long, value_name = "FRAME", requires = "odometry_tf")]
    pub tf_camera_frame: Option<String>,
    /// The namespace of the tree of transforms for --odometry-tf (`/robot1`: `/robot1/tf` and
    /// `/robot1/tf_static`; default: `/tf`, `/tf_static`).
    #[arg(long, value_name = "NS", requires = "odometry_tf", default_value = "")]
    pub tf_namespace: String,
    /// The odometry's drift: the σ of the motion it measures, per axis, as a fraction of the
    /// distance (and of the angle) since the last tracked frame. Wheel odometry drifts by a few
    /// per cent.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.05)]
    pub odometry_drift: f64,
    /// The σ of the odometry's position per frame that the distance does not explain, metres
    /// (the clocks a few milliseconds apart, the camera's lever arm, wheel quantisation).
    #[arg(long, value_name = "M", default_value_t = 0.005)]
    pub odometry_min_sigma_m: f64,
    /// The same for its orientation, degrees.
    #[arg(long, value_name = "DEG", default_value_t = 0.5)]
    pub odometry_min_sigma_deg: f64,
    /// Largest time, seconds, between a frame and the odometry sample it takes beyond the
    /// odometry's samples or in a gap of them.
    #[arg(long, value_name = "SECONDS", default_value_t = sl_io::trajectory::DEFAULT_MAX_DT_S)]
    pub odometry_max_gap_s: f64,
}

impl OdometryArgs {
    /// Whether an odometry is given.
    pub(super) fn given(&self) -> bool {
        self.odometry.is_some() || self.odometry_tf.is_some()
    }

    /// Checks the ranges and sets the tracker's odometry uncertainty.
    pub(super) fn configure(&self, cfg: &mut TrackerConfig) -> Result<()> {
        check_range("--odometry-drift", self.odometry_drift, 0.0..=1.0)?;
        check_range(
            "--odometry-min-sigma-m",
            self.odometry_min_sigma_m,
            1e-6..=1.0,
        )?;
        check_range(
            "--odometry-min-sigma-deg",
            self.odometry_min_sigma_deg,
            1e-4..=90.0,
        )?;
        check_range(
            "--odometry-max-gap-s",
            self.odometry_max_gap_s,
            1e-6..=sl_io::trajectory::MAX_GAP_S,
        )?;
        cfg.odometry_drift = self.odometry_drift;
        cfg.odometry_rotation_drift = self.odometry_drift;
        cfg.odometry_min_sigma_m = self.odometry_min_sigma_m;
        cfg.odometry_min_sigma_deg = self.odometry_min_sigma_deg;
        Ok(())
    }
}

/// The odometry's poses and what was found of them.
pub(super) struct Odometry {
    tree: TfTree,
    target: String,
    camera: String,
    max_gap_s: f64,
    /// Frames given a pose, and frames the odometry had none for.
    pub(super) found: usize,
    pub(super) missing: usize,
    first_miss: Option<TfLookupError>,
    source: String,
}

impl Odometry {
    /// The odometry of a TUM-format trajectory file.
    pub(super) fn from_file(path: &Path, max_gap_s: f64) -> Result<Self> {
        let poses = sl_io::trajectory::read_tum_trajectory_with_limits(path, &limits())
            .with_context(|| format!("--odometry {}", path.display()))?;
        if poses.is_empty() {
            bail!(
                "--odometry {}: no poses (expected lines `timestamp tx ty tz qx qy qz qw`)",
                path.display()
            );
        }
        let mut tree = TfTree::new();
        for p in &poses {
            let iso = p.pose.isometry();
            let t = iso.translation.vector;
            let q = iso.rotation.coords;
            tree.insert(
                ODOMETRY_FRAME,
                CAMERA_FRAME,
                p.timestamp,
                [t.x, t.y, t.z],
                [q.x, q.y, q.z, q.w],
                false,
            )
            .map_err(|e| anyhow::anyhow!("--odometry {}: {e}", path.display()))?;
        }
        if tree.samples() == 0 {
            bail!(
                "--odometry {}: none of its {} poses is a rigid transform",
                path.display(),
                poses.len()
            );
        }
        Ok(Self::over(
            tree,
            ODOMETRY_FRAME,
            CAMERA_FRAME,
            max_gap_s,
            path.display().to_string(),
        ))
    }

    /// The odometry of a recording's transforms: `camera` in `target`.
    pub(super) fn from_tree(
        tree: TfTree,
        target: &str,
        camera: String,
        max_gap_s: f64,
        path: &Path,
    ) -> Self {
        let source = format!(
            "{} in {} from the transforms of {}",
            camera.escape_debug(),
            target.escape_debug(),
            path.display()
        );
        Self::over(tree, target, &camera, max_gap_s, source)
    }

    fn over(tree: TfTree, target: &str, camera: &str, max_gap_s: f64, source: String) -> Self {
        Self {
            tree,
            target: target.to_owned(),
            camera: camera.to_owned(),
            max_gap_s,
            found: 0,
            missing: 0,
            first_miss: None,
            source,
        }
    }

    /// The camera's pose in the odometry's frame at `t` (seconds), when the odometry has one.
    pub(super) fn pose_at(&mut self, t: Option<f64>) -> Option<Isometry3<f64>> {
        let Some(t) = t else {
            self.missing += 1;
            return None;
        };
        match self
            .tree
            .lookup(&self.target, &self.camera, t, self.max_gap_s)
        {
            Ok(p) => {
                self.found += 1;
                Some(p)
            }
            Err(e) => {
                self.missing += 1;
                self.first_miss.get_or_insert(e);
                None
            }
        }
    }

    /// Says on standard error where the odometry came from and which frames it missed.
    pub(super) fn note(&self) {
        errln!(
            "note: odometry ({}): {} frames predicted by it, {} without a pose from it{}",
            self.source,
            self.found,
            self.missing,
            match &self.first_miss {
                Some(e) => format!(" (the first: {e})"),
                None => String::new(),
            }
        );
    }
}

/// The odometry the options give, checked before any frame is tracked: `--odometry FILE`, or
/// `--odometry-tf FRAME` of the recording `bag` (whose transforms are read here). The frames
/// need timestamps on the odometry's clock: frames stamped with their numbers
/// (`frame_numbers`), or without stamps, are refused.
pub(super) fn load(
    args: &super::Args,
    bag: Option<&mut crate::recording::BagFrames>,
    frame_numbers: bool,
    frames: &[sl_io::sequence::SequenceFrame],
) -> Result<Option<Odometry>> {
    let o = &args.odometry;
    if !o.given() {
        return Ok(None);
    }
    let stamped = args.bag.is_some() || frames.first().is_some_and(|f| f.timestamp.is_some());
    if frame_numbers || !stamped {
        bail!(
            "--odometry and --odometry-tf need frames with timestamps on the odometry's clock (a \
             TUM folder, a recording, an Open3D folder named by time); these frames have {}",
            if frame_numbers {
                "frame numbers"
            } else {
                "none"
            }
        );
    }
    if let Some(path) = &o.odometry {
        return Ok(Some(Odometry::from_file(path, o.odometry_max_gap_s)?));
    }
    let (Some(frame), Some(reader), Some(path)) = (&o.odometry_tf, bag, &args.bag) else {
        bail!(
            "--odometry-tf reads a recording's transforms: give a recording (REC.bag, .mcap, .db3)"
        );
    };
    let (tree, image_frame) = reader.transforms(&o.tf_namespace)?;
    let camera = crate::recording::tf_camera_frame(
        path,
        &tree,
        frame,
        o.tf_camera_frame.as_deref(),
        &image_frame,
        ": give the odometry as a file (--odometry FILE)",
    )?;
    Ok(Some(Odometry::from_tree(
        tree,
        frame,
        camera,
        o.odometry_max_gap_s,
        path,
    )))
}
