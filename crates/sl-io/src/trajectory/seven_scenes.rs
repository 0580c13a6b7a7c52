//! 7-Scenes poses: one `frame-XXXXXX.pose.txt`, and a sequence folder of them next to their
//! depth images.

use std::fs;
use std::path::Path;

use sl_core::CameraToWorld;

use super::Frame;
use super::depth_files::natural_order;
use super::parse::{check_frames, parse_f64};
use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::text::read_text;

/// Reads one 4×4 row-major pose file (7-Scenes `frame-XXXXXX.pose.txt`).
pub fn read_pose_txt(path: impl AsRef<Path>) -> Result<CameraToWorld> {
    let path = path.as_ref();
    parse_pose_txt(path, &read_pose_text(path)?)
}

/// The text of a pose file, within the bounds a 4×4 matrix needs.
pub(super) fn read_pose_text(path: &Path) -> Result<String> {
    read_text(path, 1 << 20, 1 << 10)
}

/// The pose of a pose file's `text` (errors name `path`).
pub(super) fn parse_pose_txt(path: &Path, text: &str) -> Result<CameraToWorld> {
    let mut m = [0.0; 16];
    let mut k = 0;
    let mut last_line = 1;
    for (n, line) in crate::text::text_lines(text).enumerate() {
        last_line = n + 1;
        for tok in line.split_whitespace() {
            if k == 16 {
                return Err(IoError::parse(
                    path,
                    n + 1,
                    "more than 16 numbers in a 4x4 pose",
                ));
            }
            m[k] = parse_f64(path, n + 1, tok, "pose matrix entry")?;
            k += 1;
        }
    }
    if k != 16 {
        return Err(IoError::parse(
            path,
            last_line,
            format!("found {k} numbers, a 4x4 pose needs 16"),
        ));
    }
    CameraToWorld::from_row_major(&m).map_err(|e| IoError::core(path, None, e))
}

/// Reads a 7-Scenes sequence directory: every `frame-XXXXXX.pose.txt`, sorted by name in
/// [`natural_order`], with its
/// `frame-XXXXXX.depth.png` (which must exist).
pub fn read_7scenes_sequence(dir: impl AsRef<Path>) -> Result<Vec<Frame>> {
    read_7scenes_sequence_with_limits(dir, &Limits::default())
}

/// [`read_7scenes_sequence`] within `limits` (frames).
pub fn read_7scenes_sequence_with_limits(
    dir: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<Frame>> {
    let dir = dir.as_ref();
    let mut pose_files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if let Some(stem) = name
            .strip_prefix("frame-")
            .and_then(|s| s.strip_suffix(".pose.txt"))
        {
            check_frames(dir, pose_files.len() + 1, limits)?;
            pose_files.push((stem.to_string(), path));
        }
    }
    pose_files.sort_by(|a, b| natural_order(a.1.as_os_str(), b.1.as_os_str()));
    pose_files
        .into_iter()
        .map(|(stem, pose_path)| {
            let depth_path = dir.join(format!("frame-{stem}.depth.png"));
            if !depth_path.is_file() {
                let what = if fs::symlink_metadata(&depth_path).is_ok() {
                    "is not a readable regular file"
                } else {
                    "does not exist"
                };
                return Err(IoError::Format {
                    path: pose_path,
                    message: format!(
                        "the depth image of this pose, {}, {what}",
                        depth_path.display()
                    ),
                });
            }
            Ok(Frame {
                pose: read_pose_txt(&pose_path)?,
                depth_path,
                timestamp: None,
            })
        })
        .collect()
}
