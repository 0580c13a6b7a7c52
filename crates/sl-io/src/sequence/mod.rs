//! Depth sequences without poses, for tracking: the frames of a TUM RGB-D folder (`depth.txt`,
//! or `associations.txt` when present), a 7-Scenes folder (`frame-XXXXXX.depth.png`) and an
//! Open3D-style folder (`depth/*.png`, timed when its names are times). Timestamps must increase
//! strictly: a sequence out of order is an error naming the line, never a silently reordered
//! trajectory. With poses: the folder's own ([`read_posed_frames`]), or a trajectory file's
//! (`along.rs`, [`read_frames_along_trajectory`]).

mod along;
mod camera;
mod places;

use std::path::{Path, PathBuf};

pub use along::read_frames_along_trajectory;
pub use camera::{
    OPEN3D_DEFAULT_PRESET, SEVEN_SCENES_CAMERA_FILE, TUM_CALIBRATION_FILE, camera_file_of,
    sensor_preset, sequence_camera,
};
pub use places::{
    depth_scale_of_file, icl_nuim_tum_folder, sequence_folder_of_file, sun_camera,
    sun_folder_of_file, tum_folder_of_file, tum_ground_truth_of, tum_preset_name,
    tum_stamps_are_frame_numbers,
};

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::text::read_text;
use crate::trajectory::{check_frames, natural_order};

/// How a sequence folder lays out its depth frames (the folders `sldepth track --tum`,
/// `--7scenes` and `--o3d` read).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SequenceLayout {
    /// A TUM RGB-D folder: `associations.txt` or `depth.txt` ([`read_tum_depth_frames`]).
    Tum,
    /// A 7-Scenes folder: `frame-XXXXXX.depth.png` ([`read_7scenes_depth_frames`]).
    SevenScenes,
    /// An Open3D-style folder: `depth/*.png` ([`read_open3d_depth_frames`]).
    Open3d,
}

impl SequenceLayout {
    /// The depth units per metre of the layout's 16-bit depth images: 5000 for TUM (as TUM
    /// ships its sequences), millimetres (1000) for 7-Scenes and Open3D-style folders.
    /// `sldepth track` and `sldepth fuse` read a folder's frames at this scale unless
    /// `--depth-scale` is given.
    pub fn depth_scale(self) -> f64 {
        match self {
            Self::Tum => 5000.0,
            Self::SevenScenes | Self::Open3d => 1000.0,
        }
    }

    /// The layout of the folder `dir` by what it holds: TUM when it has `associations.txt` or
    /// `depth.txt`, 7-Scenes when it has a `frame-*.depth.png`, Open3D when it has a `depth`
    /// folder. A folder with none of them is an error that lists what was looked for.
    pub fn infer(dir: impl AsRef<Path>) -> Result<Self> {
        let dir = dir.as_ref();
        if dir.join("associations.txt").is_file() || dir.join("depth.txt").is_file() {
            return Ok(Self::Tum);
        }
        for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
            let entry = entry.map_err(|e| IoError::io(dir, e))?;
            if entry
                .file_name()
                .to_str()
                .is_some_and(|n| n.starts_with("frame-") && n.ends_with(".depth.png"))
            {
                return Ok(Self::SevenScenes);
            }
        }
        if dir.join("depth").is_dir() {
            return Ok(Self::Open3d);
        }
        Err(IoError::malformed(
            dir,
            "cannot tell the sequence's layout: no depth.txt or associations.txt of a TUM \
             folder, no frame-*.depth.png of a 7-Scenes folder, no depth/ folder of an Open3D one",
        ))
    }
}

impl std::str::FromStr for SequenceLayout {
    type Err = String;

    /// `tum`, `7scenes` (or `7-scenes`), `open3d` (or `o3d`).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "tum" => Ok(Self::Tum),
            "7scenes" | "7-scenes" => Ok(Self::SevenScenes),
            "open3d" | "o3d" => Ok(Self::Open3d),
            other => Err(format!(
                "unknown sequence layout {other:?}: \"tum\", \"7scenes\" or \"open3d\""
            )),
        }
    }
}

/// The depth frames of the sequence folder `dir` in `layout`.
pub fn read_depth_frames(
    dir: impl AsRef<Path>,
    layout: SequenceLayout,
    limits: &Limits,
) -> Result<Vec<SequenceFrame>> {
    match layout {
        SequenceLayout::Tum => read_tum_depth_frames(dir, limits),
        SequenceLayout::SevenScenes => read_7scenes_depth_frames(dir, limits),
        SequenceLayout::Open3d => read_open3d_depth_frames(dir, limits),
    }
}

/// The `.log` files of a folder.
fn logs_of(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut logs = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        if path.is_file() && path.extension().is_some_and(|e| e == "log") {
            logs.push(path);
        }
    }
    Ok(logs)
}

/// Whether an Open3D-style folder keeps its poses as ScanNet exports them: a `pose` folder
/// and no `.log` (which [`read_posed_frames`] then reads, and `sldepth fuse DIR` takes as
/// `--scannet`). An unreadable folder is not one.
pub fn has_pose_folder(dir: impl AsRef<Path>) -> bool {
    let dir = dir.as_ref();
    dir.join("pose").is_dir() && logs_of(dir).is_ok_and(|logs| logs.is_empty())
}

/// The trajectory of an Open3D-style folder: its one `.log` file (`odometry.log`,
/// `trajectory.log`, ...) beside the `depth` folder; of several, `trajectory.log` — the name of
/// the camera trajectory Open3D's reconstruction system writes and Open3D's
/// `SampleRedwoodRGBDImages` ships beside its `odometry.log`. None, or several without a
/// `trajectory.log`, is an error that says so. (A ScanNet export has a `pose` folder instead,
/// which [`read_posed_frames`] reads.)
pub fn open3d_log_of(dir: impl AsRef<Path>) -> Result<PathBuf> {
    let dir = dir.as_ref();
    let mut logs = logs_of(dir)?;
    if logs.len() > 1
        && let Some(t) = logs.iter().find(|p| p.ends_with("trajectory.log"))
    {
        return Ok(t.clone());
    }
    logs.sort();
    let names: Vec<String> = logs
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    match <[PathBuf; 1]>::try_from(logs) {
        Ok([log]) => Ok(log),
        Err(logs) => Err(IoError::malformed(
            dir,
            format!(
                "an Open3D-style folder needs one .log trajectory beside its depth/ folder for \
                 its poses (of several, the one named trajectory.log), or a pose/ folder of 4x4 \
                 matrices as ScanNet exports (found {} .log files{}{})",
                logs.len(),
                if names.is_empty() { "" } else { ": " },
                names.join(", ")
            ),
        )),
    }
}

/// The frames of a sequence folder that have a pose ([`read_posed_frames`]), and how many of
/// its depth frames have none and were left out.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PosedFrames {
    /// The frames with their poses, in the sequence's order.
    pub frames: Vec<crate::trajectory::Frame>,
    /// Depth frames of the folder left out for want of a pose: a TUM frame without a
    /// `groundtruth.txt` pose within `max_dt_s`, a 7-Scenes frame without its
    /// `frame-*.pose.txt`, an Open3D-style folder's images beyond its `.log`'s entries (a
    /// ScanNet export's without a `pose/` file or with its `-inf` matrix).
    pub without_pose: usize,
}

/// The frames of a sequence folder with their poses, as `sldepth fuse DIR` reads them: a TUM
/// folder's depth frames with the `groundtruth.txt` pose nearest in time (within `max_dt_s`;
/// frames without one are left out), a 7-Scenes folder's `frame-*.pose.txt`, an Open3D-style
/// folder's `.log` ([`open3d_log_of`]) with the images of its `depth` folder — or, without a
/// `.log`, the `pose/<n>.txt` of each `depth/<n>.png` as ScanNet exports a scan
/// ([`crate::trajectory::read_pose_folder_frames`]); with the count of depth frames left out
/// for want of a pose.
pub fn read_posed_frames(
    dir: impl AsRef<Path>,
    layout: SequenceLayout,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<PosedFrames> {
    let dir = dir.as_ref();
    let (frames, without_pose) = match layout {
        SequenceLayout::Tum => {
            let seq = crate::trajectory::read_tum_sequence_with_limits(dir, max_dt_s, limits)?;
            let without = seq.without_pose.len();
            (seq.frames, without)
        }
        SequenceLayout::SevenScenes => {
            // Read by its pose files: the depth frames without one are counted apart.
            let frames = crate::trajectory::read_7scenes_sequence_with_limits(dir, limits)?;
            let depth = read_7scenes_depth_frames(dir, limits)?.len();
            let without = depth.saturating_sub(frames.len());
            (frames, without)
        }
        // A ScanNet export: no `.log`, a `pose` folder.
        SequenceLayout::Open3d if has_pose_folder(dir) => {
            crate::trajectory::read_pose_folder_frames(dir, limits)?
        }
        SequenceLayout::Open3d => {
            let frames = crate::trajectory::read_open3d_log_frames_with_limits(
                open3d_log_of(dir)?,
                dir.join("depth"),
                limits,
            )?;
            let depth = read_open3d_depth_frames(dir, limits)?.len();
            let without = depth.saturating_sub(frames.len());
            (frames, without)
        }
    };
    Ok(PosedFrames {
        frames,
        without_pose,
    })
}

/// One depth frame of a sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceFrame {
    /// The depth image.
    pub depth_path: PathBuf,
    /// Timestamp, seconds: TUM's, or the time an Open3D-style folder's file names state
    /// ([`read_open3d_depth_frames`]); `None` where the folder has none.
    pub timestamp: Option<f64>,
}

/// The depth frames of a TUM RGB-D sequence folder as TUM ships it: `associations.txt`
/// (`rgb_ts rgb_path depth_ts depth_path`; depth first when its first path lies in a `depth`
/// folder and its second does not, as ICL-NUIM's TUM-format archives write it) when present,
/// else `depth.txt` (`timestamp path`); `#` lines are comments, paths are relative to the
/// folder. The RGB images are not needed. Timestamps must increase strictly.
pub fn read_tum_depth_frames(dir: impl AsRef<Path>, limits: &Limits) -> Result<Vec<SequenceFrame>> {
    let dir = dir.as_ref();
    let assoc = dir.join("associations.txt");
    let (path, associations, min_cols) = if assoc.is_file() {
        (assoc, true, 4)
    } else {
        (dir.join("depth.txt"), false, 2)
    };
    let text = read_text(&path, limits.max_text_bytes, limits.max_text_lines)?;
    let mut out: Vec<SequenceFrame> = Vec::new();
    for (i, line) in crate::text::text_lines(&text).enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        check_frames(&path, out.len() + 1, limits)?;
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < min_cols {
            return Err(IoError::parse(
                &path,
                i + 1,
                format!("expected at least {min_cols} fields, found {}", toks.len()),
            ));
        }
        let (ts_col, path_col) = if associations {
            crate::trajectory::association_depth_columns(&toks)
        } else {
            (0, 1)
        };
        let t: f64 = toks[ts_col]
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| {
                IoError::parse(
                    &path,
                    i + 1,
                    format!("timestamp {:?} is not a number", toks[ts_col]),
                )
            })?;
        if let Some(prev) = out.last().and_then(|f| f.timestamp)
            && t <= prev
        {
            return Err(IoError::parse(
                &path,
                i + 1,
                if t == prev {
                    format!(
                        "timestamp {} repeats the previous frame's: two frames at one time",
                        short_number(t)
                    )
                } else {
                    format!(
                        "timestamp {} does not follow {}: frames out of order",
                        short_number(t),
                        short_number(prev)
                    )
                },
            ));
        }
        out.push(SequenceFrame {
            depth_path: dir.join(toks[path_col]),
            timestamp: Some(t),
        });
    }
    Ok(out)
}

/// The `frame-XXXXXX.depth.png` images of a 7-Scenes sequence folder, sorted by name in
/// [`crate::trajectory::natural_order`] (`frame-9` before `frame-10` where the numbers are
/// not zero-padded; poses, when present, are not read).
pub fn read_7scenes_depth_frames(
    dir: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<SequenceFrame>> {
    let dir = dir.as_ref();
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        let is_depth = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with("frame-") && n.ends_with(".depth.png"));
        if is_depth {
            check_frames(dir, files.len() + 1, limits)?;
            files.push(path);
        }
    }
    files.sort_by(|a, b| natural_order(a.as_os_str(), b.as_os_str()));
    Ok(untimed(files))
}

/// The depth images of an Open3D-style folder (`dir/depth/*.png|tif|pgm`; `dir` itself when it
/// has no `depth` subfolder), in the order of [`crate::trajectory::list_depth_files`]: by the
/// times their names state when every name states one
/// ([`crate::trajectory::name_timestamp_s`]: `1305031102.160407.png`, or nanoseconds), which
/// become the frames' timestamps, else by name in [`crate::trajectory::natural_order`], without
/// timestamps. Two names stating the same time are an error naming both.
pub fn read_open3d_depth_frames(
    dir: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<SequenceFrame>> {
    let dir = dir.as_ref();
    let sub = dir.join("depth");
    let folder = if sub.is_dir() { sub } else { dir.to_path_buf() };
    let files = crate::trajectory::list_depth_files(&folder)?;
    check_frames(dir, files.len(), limits)?;
    let Some(times) = crate::trajectory::name_timestamps_s(&files) else {
        return Ok(untimed(files));
    };
    // Sorted by time: only neighbours can be equal.
    if let Some(i) = (1..times.len()).find(|&i| times[i] <= times[i - 1]) {
        let name = |p: &Path| {
            p.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        };
        return Err(IoError::Malformed {
            path: folder,
            message: format!(
                "{} and {} name the same time, {} s: frames named by their timestamps need one \
                 time each",
                name(&files[i - 1]),
                name(&files[i]),
                short_number(times[i])
            ),
        });
    }
    Ok(files
        .into_iter()
        .zip(times)
        .map(|(depth_path, t)| SequenceFrame {
            depth_path,
            timestamp: Some(t),
        })
        .collect())
}

/// Depth frames without timestamps (7-Scenes folders, and Open3D-style folders whose names are
/// not times).
fn untimed(files: Vec<PathBuf>) -> Vec<SequenceFrame> {
    files
        .into_iter()
        .map(|depth_path| SequenceFrame {
            depth_path,
            timestamp: None,
        })
        .collect()
}

/// A timestamp for a message: fixed-point seconds for ordinary values, scientific notation
/// for absurd ones (a `1e300` printed in full is a 300-digit line).
fn short_number(v: f64) -> String {
    if v.abs() < 1e12 {
        format!("{v:.6}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::Camera;

    /// Unpadded 7-Scenes-style and Open3D-style names come in the order they were recorded:
    /// by bytes, `frame-10` came before `frame-8` and the tracked trajectory was shuffled
    /// without a word.
    /// An Open3D-style folder whose names are times is timed by them, in their order; two
    /// names of one time are an error naming both; frame numbers leave the frames untimed.
    #[test]
    fn an_open3d_folder_named_by_times_is_timed_by_them() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("depth")).unwrap();
        for n in ["100.2", "100.15", "100.0333"] {
            std::fs::write(d.join("depth").join(format!("{n}.png")), b"").unwrap();
        }
        let limits = Limits::default();
        let frames = read_open3d_depth_frames(d, &limits).unwrap();
        let times: Vec<Option<f64>> = frames.iter().map(|f| f.timestamp).collect();
        assert_eq!(times, [Some(100.0333), Some(100.15), Some(100.2)]);
        assert!(frames[0].depth_path.ends_with("depth/100.0333.png"));
        std::fs::write(d.join("depth").join("100.20.png"), b"").unwrap();
        let e = read_open3d_depth_frames(d, &limits)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("100.2.png and 100.20.png name the same time, 100.200000 s"),
            "{e}"
        );
        let numbered = tempfile::tempdir().unwrap();
        for i in 0..3 {
            std::fs::write(numbered.path().join(format!("{i:06}.png")), b"").unwrap();
        }
        let frames = read_open3d_depth_frames(numbered.path(), &limits).unwrap();
        assert_eq!(frames.len(), 3);
        assert!(frames.iter().all(|f| f.timestamp.is_none()));
    }

    #[test]
    fn unpadded_frame_numbers_keep_their_order() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("depth")).unwrap();
        for i in [8, 9, 10, 11] {
            std::fs::write(d.join(format!("frame-{i}.depth.png")), b"").unwrap();
            std::fs::write(d.join("depth").join(format!("{i}.png")), b"").unwrap();
        }
        let names = |frames: Vec<SequenceFrame>| -> Vec<String> {
            frames
                .iter()
                .map(|f| {
                    f.depth_path
                        .file_name()
                        .unwrap()
                        .to_string_lossy()
                        .into_owned()
                })
                .collect()
        };
        let limits = Limits::default();
        assert_eq!(
            names(read_7scenes_depth_frames(d, &limits).unwrap()),
            [
                "frame-8.depth.png",
                "frame-9.depth.png",
                "frame-10.depth.png",
                "frame-11.depth.png"
            ]
        );
        assert_eq!(
            names(read_open3d_depth_frames(d, &limits).unwrap()),
            ["8.png", "9.png", "10.png", "11.png"]
        );
    }

    /// ICL-NUIM's TUM-format archives write `associations.txt` depth first
    /// (`0 depth/0.png 0 rgb/0.png`): its depth paths are read, not its colour images.
    /// TUM's own order (colour first) is kept, also when no path names its folder.
    #[test]
    fn associations_written_depth_first_give_the_depth_frames() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let lim = Limits::default();
        std::fs::write(
            d.join("associations.txt"),
            "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n",
        )
        .unwrap();
        let frames = read_tum_depth_frames(d, &lim).unwrap();
        assert_eq!(frames[1].depth_path, d.join("depth/1.png"));
        assert_eq!(frames[1].timestamp, Some(1.0));
        let assoc =
            crate::trajectory::read_tum_associations_with_limits(d.join("associations.txt"), &lim)
                .unwrap();
        assert_eq!(assoc[0].depth_path, d.join("depth/0.png"));
        assert_eq!(assoc[0].rgb_path, d.join("rgb/0.png"));
        for text in [
            "1.0 rgb/a.png 1.01 depth/a.png\n",
            "1.0 a.png 1.01 b.png\n",
            "1.0 depth/a.png 1.01 depth/b.png\n",
        ] {
            std::fs::write(d.join("associations.txt"), text).unwrap();
            let frames = read_tum_depth_frames(d, &lim).unwrap();
            assert_eq!(frames[0].timestamp, Some(1.01), "{text}");
        }
    }

    /// One of ICL-NUIM's TUM-format folders is told by its associations (depth first, frame
    /// numbers): its preset, and its `*.gt.freiburg` read into sldepth's frame (y reflected).
    /// TUM's own folders are not one.
    #[test]
    fn an_icl_nuim_tum_folder_is_told_by_its_associations() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let lim = Limits::default();
        assert!(!icl_nuim_tum_folder(d));
        let d = &d.join("living_room_traj0_frei_png");
        std::fs::create_dir(d).unwrap();
        for (text, icl) in [
            (
                "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n",
                true,
            ),
            ("# comment\n\n12 depth/12.png 12 rgb/12.png\n", true),
            ("1305031229.52 rgb/a.png 1305031229.53 depth/a.png\n", false),
            ("0.5 depth/0.png 0.5 rgb/0.png\n", false),
            ("0 rgb/0.png 0 depth/0.png\n", false),
            ("0 depth/0.png\n", false),
        ] {
            std::fs::write(d.join("associations.txt"), text).unwrap();
            assert_eq!(icl_nuim_tum_folder(d), icl, "{text}");
            let want = if icl { "icl-nuim-tum" } else { "tum-fr1" };
            assert_eq!(tum_preset_name(d), want, "{text}");
        }
        std::fs::write(
            d.join("associations.txt"),
            "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n",
        )
        .unwrap();
        // Without groundtruth.txt, the one *.gt.freiburg is the ground truth.
        assert_eq!(tum_ground_truth_of(d), d.join("groundtruth.txt"));
        let gt = d.join("livingRoom0.gt.freiburg");
        // Frame 1: at (0.5, 0.25, −2), turned 90° about x (qx = sin 45°).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        std::fs::write(&gt, format!("1 0.5 0.25 -2 {h} 0 0 {h}\n")).unwrap();
        assert_eq!(tum_ground_truth_of(d), gt);
        let seq = crate::trajectory::read_tum_sequence_with_limits(d, 0.02, &lim).unwrap();
        assert_eq!(seq.frames.len(), 1);
        assert_eq!(seq.without_pose.len(), 1);
        let pose = seq.frames[0].pose;
        let t = pose.translation();
        assert_eq!((t.x, t.y, t.z), (0.5, -0.25, -2.0));
        // The mirrored rotation turns the other way about x.
        let axis = pose.rotation().axis().unwrap();
        assert!((axis.x + 1.0).abs() < 1e-12, "{axis:?}");
        // Read as written by the plain trajectory reader.
        let raw = crate::trajectory::read_trajectory(&gt).unwrap();
        assert_eq!(raw[0].pose.translation().y, 0.25);
        // groundtruth.txt wins, as TUM names it.
        std::fs::write(d.join("groundtruth.txt"), "1 0 0 0 0 0 0 1\n").unwrap();
        assert_eq!(tum_ground_truth_of(d), d.join("groundtruth.txt"));
        // Numbered frames under another name are frames, not ICL-NUIM's y-up renders, unless
        // the data set's ground truth lies beside them.
        let other = dir.path().join("my_scan");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(
            other.join("associations.txt"),
            "0 depth/0.png 0 rgb/0.png\n",
        )
        .unwrap();
        assert!(tum_stamps_are_frame_numbers(&other) && !icl_nuim_tum_folder(&other));
        assert_eq!(tum_preset_name(&other), "tum-fr1");
        std::fs::write(other.join("traj0.gt.freiburg"), "").unwrap();
        assert!(icl_nuim_tum_folder(&other));
        assert!(!tum_stamps_are_frame_numbers(dir.path()));
    }

    /// The posed frames come with the count of depth frames left out for want of a pose: a
    /// 7-Scenes frame without its pose file, an Open3D image beyond the `.log`'s entries.
    #[test]
    fn depth_frames_without_a_pose_are_counted() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let lim = Limits::default();
        for i in 0..3 {
            std::fs::write(d.join(format!("frame-{i:06}.depth.png")), b"").unwrap();
        }
        let pose = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
        std::fs::write(d.join("frame-000001.pose.txt"), pose).unwrap();
        let posed = read_posed_frames(d, SequenceLayout::SevenScenes, 0.02, &lim).unwrap();
        assert_eq!((posed.frames.len(), posed.without_pose), (1, 2));
        let o3d = d.join("o3d");
        std::fs::create_dir_all(o3d.join("depth")).unwrap();
        for i in 0..3 {
            std::fs::write(o3d.join("depth").join(format!("{i}.png")), b"").unwrap();
        }
        std::fs::write(o3d.join("traj.log"), format!("0 0 1\n{pose}")).unwrap();
        let posed = read_posed_frames(&o3d, SequenceLayout::Open3d, 0.02, &lim).unwrap();
        assert_eq!((posed.frames.len(), posed.without_pose), (1, 2));
    }

    /// A folder's layout is read from what it holds, in the order TUM, 7-Scenes, Open3D, and a
    /// folder with none of them is an error that says what was looked for.
    #[test]
    fn the_layout_is_inferred_from_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let err = SequenceLayout::infer(d).unwrap_err().to_string();
        assert!(err.contains("cannot tell the sequence's layout"), "{err}");
        std::fs::create_dir(d.join("depth")).unwrap();
        assert_eq!(SequenceLayout::infer(d).unwrap(), SequenceLayout::Open3d);
        std::fs::write(d.join("frame-000000.depth.png"), b"").unwrap();
        assert_eq!(
            SequenceLayout::infer(d).unwrap(),
            SequenceLayout::SevenScenes
        );
        std::fs::write(d.join("depth.txt"), "1.0 depth/a.png\n2.0 depth/b.png\n").unwrap();
        assert_eq!(SequenceLayout::infer(d).unwrap(), SequenceLayout::Tum);
        let frames = read_depth_frames(d, SequenceLayout::Tum, &Limits::default()).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[1].timestamp, Some(2.0));
        assert_eq!(frames[1].depth_path, d.join("depth/b.png"));
        assert!(SequenceLayout::infer(d.join("missing")).is_err());
    }

    /// An Open3D-style folder's poses come from its one `.log`; a second one is an error.
    #[test]
    fn an_open3d_folder_has_one_trajectory_log() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("depth")).unwrap();
        assert!(
            open3d_log_of(d)
                .unwrap_err()
                .to_string()
                .contains("found 0")
        );
        std::fs::write(d.join("odometry.log"), "").unwrap();
        assert_eq!(open3d_log_of(d).unwrap(), d.join("odometry.log"));
        std::fs::write(d.join("other.log"), "").unwrap();
        let e = open3d_log_of(d).unwrap_err().to_string();
        assert!(
            e.contains("found 2 .log files: odometry.log, other.log"),
            "{e}"
        );
        // Of several, trajectory.log (Open3D's Redwood sample: trajectory.log, odometry.log).
        std::fs::remove_file(d.join("other.log")).unwrap();
        std::fs::write(d.join("trajectory.log"), "").unwrap();
        assert_eq!(open3d_log_of(d).unwrap(), d.join("trajectory.log"));
    }

    /// A folder's camera: its camera file when it has one, else the layout's preset (TUM's by
    /// the folder's name).
    #[test]
    fn a_sequence_folder_implies_its_camera() {
        let dir = tempfile::tempdir().unwrap();
        let lim = Limits::default();
        let fr3 = dir.path().join("rgbd_dataset_freiburg3_office");
        std::fs::create_dir(&fr3).unwrap();
        let (cam, preset) = sequence_camera(&fr3, SequenceLayout::Tum, &lim).unwrap();
        assert_eq!(preset, Some("tum-fr3"));
        assert_eq!(cam, Camera::preset("tum-fr3").unwrap());
        assert_eq!(tum_preset_name(dir.path()), "tum-fr1");
        // 3DMatch's layout: the scene's camera file above its `seq-XX` folders.
        let scene = dir.path().join("scene");
        let seven = scene.join("seq-01");
        std::fs::create_dir_all(&seven).unwrap();
        let (cam, preset) = sequence_camera(&seven, SequenceLayout::SevenScenes, &lim).unwrap();
        assert_eq!(
            (preset, cam),
            (Some("7-scenes"), Camera::preset("7-scenes").unwrap())
        );
        let depth = sl_core::DepthImage::from_vec(320, 240, vec![1.0; 320 * 240]).unwrap();
        crate::depth::write_depth(
            seven.join("frame-000000.depth.png"),
            &depth,
            &crate::depth::DepthEncoding::png(1000.0),
        )
        .unwrap();
        let k = |fx: u32| format!("{fx} 0 160\n0 {fx} 120\n0 0 1\n");
        std::fs::write(scene.join(SEVEN_SCENES_CAMERA_FILE), k(290)).unwrap();
        assert_eq!(
            camera_file_of(&seven, SequenceLayout::SevenScenes),
            Some(scene.join(SEVEN_SCENES_CAMERA_FILE))
        );
        // The file's intrinsics at the frames' size, the data set's sensor (its rolling
        // shutter, for the tracker).
        let (cam, preset) = sequence_camera(&seven, SequenceLayout::SevenScenes, &lim).unwrap();
        let i = cam.intrinsics;
        assert_eq!(
            (preset, i.fx, i.width, i.height),
            (Some("7-scenes"), 290.0, 320, 240)
        );
        // The folder's own file wins over the scene's.
        std::fs::write(seven.join(SEVEN_SCENES_CAMERA_FILE), k(300)).unwrap();
        let (cam, _) = sequence_camera(&seven, SequenceLayout::SevenScenes, &lim).unwrap();
        assert_eq!(cam.intrinsics.fx, 300.0);
        // Without a frame to size it by, the file is an error that says so.
        std::fs::remove_file(seven.join("frame-000000.depth.png")).unwrap();
        let e = sequence_camera(&seven, SequenceLayout::SevenScenes, &lim).unwrap_err();
        assert!(e.to_string().contains("no depth frame"), "{e}");
        let o3d = dir.path().join("o3d");
        std::fs::create_dir(&o3d).unwrap();
        let (cam, preset) = sequence_camera(&o3d, SequenceLayout::Open3d, &lim).unwrap();
        assert_eq!(
            (preset, cam),
            (Some("ros-default"), Camera::preset("ros-default").unwrap())
        );
        // Its own camera file: any camera, no preset implied — camera.json, or the name
        // Open3D's Redwood sample gives it.
        for name in ["camera_primesense.json", "camera.json"] {
            std::fs::write(
                o3d.join(name),
                r#"{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 32, 24, 1]}"#,
            )
            .unwrap();
            let (cam, preset) = sequence_camera(&o3d, SequenceLayout::Open3d, &lim).unwrap();
            assert_eq!((preset, cam.intrinsics.width), (None, 64), "{name}");
            std::fs::remove_file(o3d.join(name)).unwrap();
        }
        std::fs::create_dir(o3d.join("camera.json")).unwrap();
        let err = sequence_camera(&o3d, SequenceLayout::Open3d, &lim).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
    }

    /// A frame's place names its sequence folder: a TUM folder's `depth/` image, a 7-Scenes
    /// frame's folder, an Open3D-style folder's `depth/` image only when the folder has a
    /// camera file.
    #[test]
    fn a_frame_is_placed_in_its_sequence_folder() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("depth")).unwrap();
        let frame = d.join("depth/000000.png");
        // A `depth/` folder alone: no sequence.
        assert_eq!(sequence_folder_of_file(&frame), None);
        std::fs::write(d.join("camera_intrinsic.json"), "{}").unwrap();
        assert_eq!(
            sequence_folder_of_file(&frame),
            Some((d, SequenceLayout::Open3d))
        );
        std::fs::write(d.join("depth.txt"), "").unwrap();
        assert_eq!(
            sequence_folder_of_file(&frame),
            Some((d, SequenceLayout::Tum))
        );
        let seven = d.join("seq-01/frame-000150.depth.png");
        assert_eq!(
            sequence_folder_of_file(&seven),
            Some((d.join("seq-01").as_path(), SequenceLayout::SevenScenes))
        );
        // A bare relative name lies in the current folder.
        assert_eq!(
            sequence_folder_of_file(Path::new("frame-000150.depth.png")),
            Some((Path::new("."), SequenceLayout::SevenScenes))
        );
        assert_eq!(
            sequence_folder_of_file(Path::new("frame-000150.color.png")),
            None
        );
    }

    #[test]
    fn layouts_parse_by_their_names() {
        assert_eq!("tum".parse(), Ok(SequenceLayout::Tum));
        assert_eq!("7-scenes".parse(), Ok(SequenceLayout::SevenScenes));
        assert_eq!("o3d".parse(), Ok(SequenceLayout::Open3d));
        // TUM ships 5000 units per metre; the others millimetres.
        assert_eq!(SequenceLayout::Tum.depth_scale(), 5000.0);
        assert_eq!(SequenceLayout::SevenScenes.depth_scale(), 1000.0);
        assert_eq!(SequenceLayout::Open3d.depth_scale(), 1000.0);
        let err = "bag".parse::<SequenceLayout>().unwrap_err();
        assert!(err.contains("\"tum\", \"7scenes\" or \"open3d\""), "{err}");
    }
}
