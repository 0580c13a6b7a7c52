//! Open3D `.log` trajectories: read, write, and paired with the depth images of a folder.

use std::fmt::Write as _;
use std::path::Path;

use sl_core::CameraToWorld;

use super::Frame;
use super::depth_files::list_depth_files;
#[cfg(doc)] // for the doc links
use super::depth_files::natural_order;
use super::parse::{check_frames, parse_n, read_limited};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// One entry of an Open3D `.log` trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogEntry {
    /// The metadata line `i j n` (for a trajectory: frame index, frame index, frame count).
    pub metadata: [u64; 3],
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
}

impl LogEntry {
    /// The camera-to-world pose (the same as the field `pose`).
    #[deprecated(since = "0.1.0", note = "the field `pose` is a `CameraToWorld` now")]
    pub fn camera_to_world(&self) -> CameraToWorld {
        self.pose
    }
}

/// Reads an Open3D `.log` trajectory: per entry a line of three integers, then four lines of
/// four numbers (a camera-to-world matrix).
pub fn read_open3d_log(path: impl AsRef<Path>) -> Result<Vec<LogEntry>> {
    read_open3d_log_with_limits(path, &Limits::default())
}

/// [`read_open3d_log`] within `limits` (text bytes and lines, frames).
pub fn read_open3d_log_with_limits(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<LogEntry>> {
    let path = path.as_ref();
    let text = read_limited(path, limits)?;
    let lines: Vec<(usize, &str)> = crate::text::text_lines(&text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    check_frames(path, lines.len().div_ceil(5), limits)?;
    let mut out = Vec::with_capacity(lines.len() / 5);
    for chunk in lines.chunks(5) {
        let (n0, head) = chunk[0];
        if chunk.len() < 5 {
            return Err(IoError::parse(
                path,
                n0,
                format!(
                    "entry has {} matrix rows, expected 4 (truncated file?)",
                    chunk.len() - 1
                ),
            ));
        }
        let toks: Vec<&str> = head.split_whitespace().collect();
        if toks.len() != 3 {
            return Err(IoError::parse(
                path,
                n0,
                format!(
                    "expected a metadata line `i j n`, found {} fields",
                    toks.len()
                ),
            ));
        }
        let mut metadata = [0u64; 3];
        for (m, t) in metadata.iter_mut().zip(&toks) {
            *m = t.parse().map_err(|_| {
                IoError::parse(
                    path,
                    n0,
                    format!("metadata {t:?} is not a non-negative integer"),
                )
            })?;
        }
        let mut m = [0.0; 16];
        for (r, &(n, row)) in chunk[1..].iter().enumerate() {
            let toks: Vec<&str> = row.split_whitespace().collect();
            let v = parse_n::<4>(path, n, &toks, "a matrix row")?;
            m[r * 4..r * 4 + 4].copy_from_slice(&v);
        }
        let pose =
            CameraToWorld::from_row_major(&m).map_err(|e| IoError::core(path, Some(n0), e))?;
        out.push(LogEntry { metadata, pose });
    }
    Ok(out)
}

/// Writes an Open3D `.log` trajectory (`i i n` metadata, as Open3D writes odometry), atomically.
pub fn write_open3d_log(path: impl AsRef<Path>, poses: &[CameraToWorld]) -> Result<()> {
    let mut text = String::new();
    let n = poses.len();
    for (i, p) in poses.iter().enumerate() {
        let _ = writeln!(text, "{i} {i} {n}");
        let m = p.to_matrix();
        for r in 0..4 {
            let _ = writeln!(
                text,
                "{:.10} {:.10} {:.10} {:.10}",
                m[(r, 0)],
                m[(r, 1)],
                m[(r, 2)],
                m[(r, 3)]
            );
        }
    }
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// Pairs an Open3D `.log` with the depth images of `depth_dir` (in the order of
/// [`list_depth_files`]: by name in [`natural_order`], or by time when every name is one):
/// entry `i j n` takes the `i`-th image. An index beyond the images is an error naming the log.
pub fn read_open3d_log_frames(
    log_path: impl AsRef<Path>,
    depth_dir: impl AsRef<Path>,
) -> Result<Vec<Frame>> {
    read_open3d_log_frames_with_limits(log_path, depth_dir, &Limits::default())
}

/// [`read_open3d_log_frames`] within `limits`.
pub fn read_open3d_log_frames_with_limits(
    log_path: impl AsRef<Path>,
    depth_dir: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<Frame>> {
    let log_path = log_path.as_ref();
    let entries = read_open3d_log_with_limits(log_path, limits)?;
    let files = list_depth_files(depth_dir.as_ref())?;
    entries
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let i = e.metadata[0];
            let depth_path = usize::try_from(i)
                .ok()
                .and_then(|i| files.get(i))
                .ok_or_else(|| IoError::Format {
                    path: log_path.to_path_buf(),
                    message: format!(
                        "entry {k} refers to frame {i}, but {} has only {} depth images",
                        depth_dir.as_ref().display(),
                        files.len()
                    ),
                })?;
            Ok(Frame {
                depth_path: depth_path.clone(),
                pose: e.pose,
                timestamp: None,
            })
        })
        .collect()
}
