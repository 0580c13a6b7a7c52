//! TUM RGB-D text files: trajectories (`groundtruth.txt`: read, write, and how their timestamps
//! are printed) and `associations.txt`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use sl_core::CameraToWorld;

use super::TimedPose;
use super::parse::{check_frames, data_lines, parse_f64, parse_n, read_limited};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// One line of a TUM `associations.txt`; paths are resolved against the file's directory.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    /// Colour frame time, seconds.
    pub rgb_timestamp: f64,
    /// Colour frame file.
    pub rgb_path: PathBuf,
    /// Depth frame time, seconds.
    pub depth_timestamp: f64,
    /// Depth frame file.
    pub depth_path: PathBuf,
}

/// Reads a TUM trajectory (`groundtruth.txt` or any `timestamp tx ty tz qx qy qz qw` file),
/// sorted by timestamp. A timestamp that appears twice is an error naming both lines (as
/// `sldepth eval-traj` has always refused it: which of two poses at one instant holds?).
pub fn read_tum_trajectory(path: impl AsRef<Path>) -> Result<Vec<TimedPose>> {
    read_tum_trajectory_with_limits(path, &Limits::default())
}

/// [`read_tum_trajectory`] within `limits` (text bytes and lines).
pub fn read_tum_trajectory_with_limits(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<TimedPose>> {
    let path = path.as_ref();
    let text = read_limited(path, limits)?;
    let mut poses = Vec::new();
    for (n, line) in data_lines(&text) {
        let toks: Vec<&str> = line.split_whitespace().collect();
        let v = parse_n::<8>(path, n, &toks, "timestamp tx ty tz qx qy qz qw")?;
        let pose = CameraToWorld::from_translation_quaternion(
            [v[1], v[2], v[3]],
            [v[4], v[5], v[6], v[7]],
        )
        .map_err(|e| IoError::core(path, Some(n), e))?;
        poses.push((
            n,
            TimedPose {
                timestamp: v[0],
                pose,
            },
        ));
    }
    // Stable: of two equal stamps the earlier line comes first.
    poses.sort_by(|a, b| a.1.timestamp.total_cmp(&b.1.timestamp));
    if let Some(w) = poses
        .windows(2)
        .find(|w| w[0].1.timestamp == w[1].1.timestamp)
    {
        return Err(IoError::parse(
            path,
            w[1].0,
            format!(
                "timestamp {} s appears twice (also on line {}): a trajectory has one pose per \
                 instant",
                // TUM's ten-digit stamps as they are, an absurd one compactly.
                if w[1].1.timestamp.abs() < 1e15 {
                    w[1].1.timestamp.to_string()
                } else {
                    sl_core::Compact(w[1].1.timestamp).to_string()
                },
                w[0].0
            ),
        ));
    }
    Ok(poses.into_iter().map(|(_, p)| p).collect())
}

/// How the timestamps `ts` of one trajectory file are printed: with 6 decimals (TUM's
/// microseconds) unless two distinct timestamps would print alike — which would make the file
/// one that [`read_tum_trajectory`] refuses (a repeated timestamp) — then with 9, and when even
/// those collide in the shortest form that reads back exactly.
pub fn timestamp_printer(ts: &[f64]) -> impl Fn(f64) -> String + Copy + use<> {
    // Distinct values in order: only neighbours can print alike (rounding is monotonic).
    let mut v: Vec<f64> = ts.iter().copied().filter(|t| t.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    let collide = |print: fn(f64) -> String| v.windows(2).any(|w| print(w[0]) == print(w[1]));
    let micro: fn(f64) -> String = |t| format!("{t:.6}");
    let nano: fn(f64) -> String = |t| format!("{t:.9}");
    let exact: fn(f64) -> String = |t| format!("{t:e}");
    if !collide(micro) {
        micro
    } else if !collide(nano) {
        nano
    } else {
        exact
    }
}

/// Writes a TUM trajectory (`timestamp tx ty tz qx qy qz qw`, 6 decimals for time unless
/// timestamps closer than that need more ([`timestamp_printer`]), 9 for the rest), atomically.
pub fn write_tum_trajectory(path: impl AsRef<Path>, poses: &[TimedPose]) -> Result<()> {
    // What `read_tum_trajectory` would refuse is not written: a timestamp that is not a finite
    // number (a pose is finite by construction).
    if let Some((i, p)) = poses
        .iter()
        .enumerate()
        .find(|(_, p)| !p.timestamp.is_finite())
    {
        return Err(IoError::InvalidConfig {
            message: format!(
                "pose {i} has timestamp {}: a trajectory's timestamps must be finite seconds",
                sl_core::Compact(p.timestamp)
            ),
        });
    }
    let stamps: Vec<f64> = poses.iter().map(|p| p.timestamp).collect();
    let stamp = timestamp_printer(&stamps);
    let mut text = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for p in poses {
        let t = p.pose.translation();
        let q = p.pose.rotation().coords; // (i, j, k, w) = (qx, qy, qz, qw)
        let _ = writeln!(
            text,
            "{} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
            stamp(p.timestamp),
            t.x,
            t.y,
            t.z,
            q.x,
            q.y,
            q.z,
            q.w
        );
    }
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// The columns of the depth frame's time and path in a line of an `associations.txt`: TUM's
/// order (`rgb_ts rgb_path depth_ts depth_path`, what TUM's `associate.py` writes) is columns
/// 2 and 3, unless the first path lies in a `depth` folder and the second does not, as in
/// ICL-NUIM's TUM-format archives (`0 depth/0.png 0 rgb/0.png`) or an `associate.py` run with
/// its two lists the other way round: then columns 0 and 1. `toks` has at least 4 fields.
pub(crate) fn association_depth_columns(toks: &[&str]) -> (usize, usize) {
    let in_depth_folder = |p: &str| {
        Path::new(p)
            .parent()
            .is_some_and(|d| d.iter().any(|c| c.eq_ignore_ascii_case("depth")))
    };
    let depth_first = toks.len() >= 4 && in_depth_folder(toks[1]) && !in_depth_folder(toks[3]);
    if depth_first { (0, 1) } else { (2, 3) }
}

/// Reads a TUM `associations.txt` (`rgb_ts rgb_path depth_ts depth_path`, extra columns
/// ignored; a line whose first path lies in a `depth` folder and whose second does not is read
/// the other way round, see ICL-NUIM's `0 depth/0.png 0 rgb/0.png`); relative paths are
/// resolved against the file's directory.
pub fn read_tum_associations(path: impl AsRef<Path>) -> Result<Vec<Association>> {
    read_tum_associations_with_limits(path, &Limits::default())
}

/// [`read_tum_associations`] within `limits` (text bytes and lines, frames).
pub fn read_tum_associations_with_limits(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<Association>> {
    let path = path.as_ref();
    let base = path.parent().unwrap_or(Path::new(""));
    let text = read_limited(path, limits)?;
    let mut out = Vec::new();
    for (n, line) in data_lines(&text) {
        check_frames(path, out.len() + 1, limits)?;
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < 4 {
            return Err(IoError::parse(
                path,
                n,
                format!(
                    "expected `rgb_ts rgb_path depth_ts depth_path`, found {} fields",
                    toks.len()
                ),
            ));
        }
        let (dt, dp) = association_depth_columns(&toks);
        let (rt, rp) = if dt == 0 { (2, 3) } else { (0, 1) };
        out.push(Association {
            rgb_timestamp: parse_f64(path, n, toks[rt], "rgb timestamp")?,
            rgb_path: base.join(toks[rp]),
            depth_timestamp: parse_f64(path, n, toks[dt], "depth timestamp")?,
            depth_path: base.join(toks[dp]),
        });
    }
    Ok(out)
}
