//! Camera trajectories of RGB-D datasets, as depth [`Frame`]s with camera-to-world poses.
//!
//! - TUM RGB-D: `groundtruth.txt` (`timestamp tx ty tz qx qy qz qw`, `#` comments) and
//!   `associations.txt` (`rgb_ts rgb_path depth_ts depth_path`); each depth frame gets the
//!   ground-truth pose nearest in time, within a maximum difference ([`DEFAULT_MAX_DT_S`]),
//!   or the pose interpolated at its time plus a clock offset ([`associate_interpolated`]).
//! - Open3D `.log`: a line `i j n`, then the four rows of a 4×4 camera-to-world matrix.
//! - 7-Scenes: one `frame-XXXXXX.pose.txt` (4×4 camera-to-world, row-major) per frame next to
//!   `frame-XXXXXX.depth.png`.
//!
//! All poses follow the `sl_core::pose` convention `X_w = R·X_c + t`; matrices are
//! re-orthonormalised by [`sl_core::pose_from_matrix`], which rejects non-rigid ones.

use std::borrow::Cow;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use sl_core::CameraToWorld;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::{BUDGET_OPTION, Limits};
use crate::text::read_text;

/// Reads a text input within `limits`.
fn read_limited(path: &Path, limits: &Limits) -> Result<String> {
    read_text(path, limits.max_text_bytes, limits.max_text_lines)
}

/// Fails when a sequence has more than [`Limits::max_frames`] frames.
pub(crate) fn check_frames(path: &Path, n: usize, limits: &Limits) -> Result<()> {
    if n > limits.max_frames {
        return Err(IoError::too_large(
            path,
            format!(
                "more than {} frames, over the frame limit (raise it with {BUDGET_OPTION})",
                limits.max_frames
            ),
        ));
    }
    Ok(())
}

/// Default largest |depth timestamp − pose timestamp| for TUM association, seconds.
pub const DEFAULT_MAX_DT_S: f64 = 0.02;

/// One depth frame with its camera-to-world pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The depth image file.
    pub depth_path: PathBuf,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
    /// Capture time in seconds, when the dataset has one (TUM).
    pub timestamp: Option<f64>,
}

impl Frame {
    /// The camera-to-world pose (the same as the field `pose`).
    #[deprecated(since = "0.1.0", note = "the field `pose` is a `CameraToWorld` now")]
    pub fn camera_to_world(&self) -> CameraToWorld {
        self.pose
    }
}

/// A pose with its timestamp (one line of a TUM trajectory).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedPose {
    /// Seconds.
    pub timestamp: f64,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
}

impl TimedPose {
    /// The camera-to-world pose (the same as the field `pose`).
    #[deprecated(since = "0.1.0", note = "the field `pose` is a `CameraToWorld` now")]
    pub fn camera_to_world(&self) -> CameraToWorld {
        self.pose
    }
}

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

/// Depth frames matched to poses, and those left without one.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TumSequence {
    /// Frames with a pose within the time tolerance, in association-file order.
    pub frames: Vec<Frame>,
    /// Depth frames (timestamp, path) with no pose within the tolerance.
    pub without_pose: Vec<(f64, PathBuf)>,
}

/// Non-empty, non-comment lines with their 1-based numbers.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    crate::text::text_lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

fn parse_f64(path: &Path, line: usize, tok: &str, what: &str) -> Result<f64> {
    let v: f64 = tok
        .parse()
        .map_err(|_| IoError::parse(path, line, format!("{what}: {tok:?} is not a number")))?;
    if !v.is_finite() {
        return Err(IoError::parse(
            path,
            line,
            format!("{what}: {tok:?} is not finite"),
        ));
    }
    Ok(v)
}

fn parse_n<const N: usize>(
    path: &Path,
    line: usize,
    toks: &[&str],
    what: &str,
) -> Result<[f64; N]> {
    if toks.len() != N {
        return Err(IoError::parse(
            path,
            line,
            format!("expected {N} numbers ({what}), found {} fields", toks.len()),
        ));
    }
    let mut out = [0.0; N];
    for (o, t) in out.iter_mut().zip(toks) {
        *o = parse_f64(path, line, t, what)?;
    }
    Ok(out)
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

/// Reads a TUM `associations.txt` (`rgb_ts rgb_path depth_ts depth_path`, extra columns
/// ignored); relative paths are resolved against the file's directory.
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
        out.push(Association {
            rgb_timestamp: parse_f64(path, n, toks[0], "rgb timestamp")?,
            rgb_path: base.join(toks[1]),
            depth_timestamp: parse_f64(path, n, toks[2], "depth timestamp")?,
            depth_path: base.join(toks[3]),
        });
    }
    Ok(out)
}

/// The pose nearest in time to `t` within `max_dt_s` (`poses` sorted by timestamp).
pub fn nearest_pose(poses: &[TimedPose], t: f64, max_dt_s: f64) -> Option<&TimedPose> {
    let i = poses.partition_point(|p| p.timestamp < t);
    let before = i.checked_sub(1).and_then(|j| poses.get(j));
    let after = poses.get(i);
    let best = match (before, after) {
        (Some(a), Some(b)) => {
            if (t - a.timestamp).abs() <= (b.timestamp - t).abs() {
                a
            } else {
                b
            }
        }
        (Some(a), None) => a,
        (None, Some(b)) => b,
        (None, None) => return None,
    };
    ((best.timestamp - t).abs() <= max_dt_s).then_some(best)
}

/// `poses` sorted by timestamp (borrowed when they already are).
fn by_time(poses: &[TimedPose]) -> Cow<'_, [TimedPose]> {
    if poses.is_sorted_by(|a, b| a.timestamp <= b.timestamp) {
        Cow::Borrowed(poses)
    } else {
        let mut sorted = poses.to_vec();
        sorted.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
        Cow::Owned(sorted)
    }
}

/// The pose at time `t`, interpolated between the two poses of `poses` (sorted by timestamp)
/// that bracket it: the translation linearly, the rotation along the shortest arc (slerp). A
/// pose exactly at `t` is returned as it is. `None` when `t` lies outside the trajectory or
/// its two bracketing poses are more than `max_gap_s` apart (a gap in the motion capture is
/// not bridged). This is how a clock offset between a camera and its ground truth is undone
/// for a 100-Hz motion capture: the pose at `t + offset_s`, not the nearest one.
pub fn interpolated_pose(poses: &[TimedPose], t: f64, max_gap_s: f64) -> Option<CameraToWorld> {
    if !t.is_finite() {
        return None;
    }
    let i = poses.partition_point(|p| p.timestamp < t);
    let after = poses.get(i)?;
    if after.timestamp == t {
        return Some(after.pose);
    }
    let before = poses.get(i.checked_sub(1)?)?;
    let span = after.timestamp - before.timestamp;
    if !(span > 0.0 && span <= max_gap_s) {
        return None;
    }
    let s = (t - before.timestamp) / span;
    let iso = before.pose.isometry().lerp_slerp(after.pose.isometry(), s);
    Some(CameraToWorld::from_isometry(iso))
}

/// Gives each depth frame `(timestamp, path)` the ground-truth pose at `timestamp + offset_s`
/// ([`interpolated_pose`], bracketing poses at most `max_gap_s` apart); frames without one go
/// to `without_pose`. With `offset_s = 0` this differs from [`associate`] only by up to half
/// the motion capture's period (5 ms at 100 Hz).
pub fn associate_interpolated(
    depth: &[(f64, PathBuf)],
    poses: &[TimedPose],
    offset_s: f64,
    max_gap_s: f64,
) -> TumSequence {
    let poses = by_time(poses);
    let mut seq = TumSequence::default();
    for (t, p) in depth {
        match interpolated_pose(&poses, *t + offset_s, max_gap_s) {
            Some(pose) => seq.frames.push(Frame {
                depth_path: p.clone(),
                pose,
                timestamp: Some(*t),
            }),
            None => seq.without_pose.push((*t, p.clone())),
        }
    }
    seq
}

/// Gives each depth frame `(timestamp, path)` the nearest pose within `max_dt_s`.
pub fn associate(depth: &[(f64, PathBuf)], poses: &[TimedPose], max_dt_s: f64) -> TumSequence {
    let poses = by_time(poses);
    let mut seq = TumSequence::default();
    for (t, p) in depth {
        match nearest_pose(&poses, *t, max_dt_s) {
            Some(tp) => seq.frames.push(Frame {
                depth_path: p.clone(),
                pose: tp.pose,
                timestamp: Some(*t),
            }),
            None => seq.without_pose.push((*t, p.clone())),
        }
    }
    seq
}

/// Reads a TUM sequence directory: `dir/groundtruth.txt` and the depth frames as TUM ships
/// them (`associations.txt` when present, else `depth.txt`; see
/// [`read_tum_depth_frames`](crate::sequence::read_tum_depth_frames)), matching each depth
/// frame to the nearest ground-truth pose within `max_dt_s` seconds ([`DEFAULT_MAX_DT_S`] =
/// 0.02 s is the usual choice). A non-positive or non-finite tolerance is an error naming
/// `groundtruth.txt`.
pub fn read_tum_sequence(dir: impl AsRef<Path>, max_dt_s: f64) -> Result<TumSequence> {
    read_tum_sequence_with_limits(dir, max_dt_s, &Limits::default())
}

/// [`read_tum_sequence`] within `limits`.
pub fn read_tum_sequence_with_limits(
    dir: impl AsRef<Path>,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<TumSequence> {
    let (depth, poses) = read_tum_parts(dir.as_ref(), max_dt_s, limits)?;
    Ok(associate(&depth, &poses, max_dt_s))
}

/// [`read_tum_sequence_with_limits`] with each depth frame given the ground-truth pose at its
/// stamp plus `offset_s` ([`associate_interpolated`]; bracketing poses at most `max_gap_s`
/// apart) instead of the nearest one. A non-finite offset or a non-positive gap is an error
/// naming `groundtruth.txt`.
pub fn read_tum_sequence_at_offset(
    dir: impl AsRef<Path>,
    offset_s: f64,
    max_gap_s: f64,
    limits: &Limits,
) -> Result<TumSequence> {
    let dir = dir.as_ref();
    if !offset_s.is_finite() {
        return Err(IoError::Format {
            path: dir.join("groundtruth.txt"),
            message: format!(
                "clock offset {} s must be finite",
                sl_core::Compact(offset_s)
            ),
        });
    }
    let (depth, poses) = read_tum_parts(dir, max_gap_s, limits)?;
    Ok(associate_interpolated(&depth, &poses, offset_s, max_gap_s))
}

/// Depth frames `(timestamp, path)`, as [`associate`] takes them.
type TimedDepth = Vec<(f64, PathBuf)>;

/// The timestamped depth frames and the ground-truth poses of a TUM folder, after checking the
/// association's time tolerance.
fn read_tum_parts(
    dir: &Path,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<(TimedDepth, Vec<TimedPose>)> {
    let gt_path = dir.join("groundtruth.txt");
    if !(max_dt_s.is_finite() && max_dt_s > 0.0) {
        return Err(IoError::Format {
            path: gt_path,
            message: format!(
                "maximum time difference {} s must be positive",
                sl_core::Compact(max_dt_s)
            ),
        });
    }
    let poses = read_tum_trajectory_with_limits(&gt_path, limits)?;
    let depth: TimedDepth = crate::sequence::read_tum_depth_frames(dir, limits)?
        .into_iter()
        .filter_map(|f| Some((f.timestamp?, f.depth_path)))
        .collect();
    Ok((depth, poses))
}

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

/// Depth image files (`.png`, `.tif`, `.tiff`, `.pgm`) in `dir`, sorted by name in
/// [`natural_order`] (`9.png` before `10.png`).
pub fn list_depth_files(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>> {
    let dir = dir.as_ref();
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        if path.is_file() && crate::depth::DepthFormat::from_path(&path).is_some() {
            files.push(path);
        }
    }
    files.sort_by(|a, b| natural_order(a.as_os_str(), b.as_os_str()));
    Ok(files)
}

/// The order of numbered file names: runs of ASCII digits compare as the numbers they are
/// (`frame-9` before `frame-10`, `2.png` before `10.png`), everything else byte by byte; names
/// equal by that (`frame-007`, `frame-7`) in plain byte order. Zero-padded names sort as they
/// do by bytes; unpadded ones sort in the order they were recorded in, not `1, 10, 11, 2`,
/// which would silently shuffle a trajectory. The order of Open3D's reconstruction system
/// (`sorted_alphanum`), so an Open3D `.log` pairs with the images it was made from.
pub fn natural_order(a: &std::ffi::OsStr, b: &std::ffi::OsStr) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    fn digits(s: &[u8], from: usize) -> usize {
        s[from..]
            .iter()
            .position(|c| !c.is_ascii_digit())
            .map_or(s.len(), |n| from + n)
    }
    fn trim_zeros(s: &[u8]) -> &[u8] {
        let zeros = s.iter().take_while(|&&c| c == b'0').count();
        &s[zeros..]
    }
    let (x, y) = (a.as_encoded_bytes(), b.as_encoded_bytes());
    let (mut i, mut j) = (0, 0);
    while i < x.len() && j < y.len() {
        let order = if x[i].is_ascii_digit() && y[j].is_ascii_digit() {
            let (ei, ej) = (digits(x, i), digits(y, j));
            let (m, n) = (trim_zeros(&x[i..ei]), trim_zeros(&y[j..ej]));
            (i, j) = (ei, ej);
            m.len().cmp(&n.len()).then_with(|| m.cmp(n))
        } else {
            let o = x[i].cmp(&y[j]);
            (i, j) = (i + 1, j + 1);
            o
        };
        if order != Ordering::Equal {
            return order;
        }
    }
    (x.len() - i).cmp(&(y.len() - j)).then_with(|| x.cmp(y))
}

/// Pairs an Open3D `.log` with the depth images of `depth_dir` (sorted by name in
/// [`natural_order`]): entry `i j n` takes the `i`-th image. An index beyond the images is an error naming the log.
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

/// Reads one 4×4 row-major pose file (7-Scenes `frame-XXXXXX.pose.txt`).
pub fn read_pose_txt(path: impl AsRef<Path>) -> Result<CameraToWorld> {
    let path = path.as_ref();
    let text = read_text(path, 1 << 20, 1 << 10)?;
    let mut m = [0.0; 16];
    let mut k = 0;
    let mut last_line = 1;
    for (n, line) in crate::text::text_lines(&text).enumerate() {
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

/// Reads a frame list (the `sldepth fuse --frames` format): per line a depth image path
/// (relative to the list's directory) and the 16 numbers of a row-major 4×4 camera-to-world
/// pose; `#` starts a comment. Bounded by `limits` (text bytes and lines, frames).
pub fn read_frame_list(path: impl AsRef<Path>, limits: &Limits) -> Result<Vec<Frame>> {
    let path = path.as_ref();
    let text = read_limited(path, limits)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut frames = Vec::new();
    for (i, line) in crate::text::text_lines(&text).enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        check_frames(path, frames.len() + 1, limits)?;
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() != 17 {
            return Err(IoError::parse(
                path,
                i + 1,
                format!(
                    "expected a depth path and 16 pose numbers, found {} fields",
                    toks.len()
                ),
            ));
        }
        let mut m = [0.0; 16];
        for (v, t) in m.iter_mut().zip(&toks[1..]) {
            *v = t
                .parse()
                .map_err(|_| IoError::parse(path, i + 1, format!("{t:?} is not a number")))?;
        }
        let pose =
            CameraToWorld::from_row_major(&m).map_err(|e| IoError::core(path, Some(i + 1), e))?;
        frames.push(Frame {
            depth_path: base.join(toks[0]),
            pose,
            timestamp: None,
        });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::nalgebra::{Isometry3, Vector3};

    fn c2w(t: Vector3<f64>, r: Vector3<f64>) -> CameraToWorld {
        CameraToWorld::from_isometry(Isometry3::new(t, r))
    }

    #[test]
    fn timestamps_print_with_microseconds_unless_that_repeats_one() {
        let tum = [1305031229.528784, 1305031229.564442];
        let p = timestamp_printer(&tum);
        assert_eq!(p(tum[0]), "1305031229.528784");
        let close = [1e9, 1e9 + 2.4e-7, 1e9 + 4.8e-7];
        let p = timestamp_printer(&close);
        let printed: Vec<String> = close.iter().map(|&t| p(t)).collect();
        assert_eq!(printed[0], "1000000000.000000000");
        assert!(
            printed[1] != printed[0] && printed[2] != printed[1],
            "{printed:?}"
        );
        let tiny = [0.0, 5e-324];
        let p = timestamp_printer(&tiny);
        assert!(p(tiny[1]).parse::<f64>().unwrap() == 5e-324 && p(tiny[0]) != p(tiny[1]));
    }

    fn tp(t: f64) -> TimedPose {
        TimedPose {
            timestamp: t,
            pose: c2w(Vector3::new(t, 0.0, 0.0), Vector3::zeros()),
        }
    }

    #[test]
    fn nearest_within_tolerance() {
        let poses = [tp(1.0), tp(1.01), tp(1.02), tp(2.0)];
        assert_eq!(nearest_pose(&poses, 1.012, 0.02).unwrap().timestamp, 1.01);
        assert_eq!(nearest_pose(&poses, 1.016, 0.02).unwrap().timestamp, 1.02);
        assert_eq!(nearest_pose(&poses, 0.99, 0.02).unwrap().timestamp, 1.0);
        assert_eq!(nearest_pose(&poses, 2.015, 0.02).unwrap().timestamp, 2.0);
        assert!(nearest_pose(&poses, 1.5, 0.02).is_none());
        assert!(nearest_pose(&[], 1.5, 0.02).is_none());
        let seq = associate(
            &[(1.011, "a".into()), (1.5, "b".into())],
            &[tp(2.0), tp(1.0), tp(1.01)],
            0.02,
        );
        assert_eq!(seq.frames.len(), 1);
        assert_eq!(seq.frames[0].pose.translation().x, 1.01);
        assert_eq!(seq.without_pose, vec![(1.5, PathBuf::from("b"))]);
    }

    #[test]
    fn interpolated_between_the_bracketing_poses() {
        // Translation t along x, rotation 10·t degrees about z at time t.
        let at = |t: f64| TimedPose {
            timestamp: t,
            pose: c2w(
                Vector3::new(t, 0.0, 0.0),
                Vector3::new(0.0, 0.0, (10.0 * t).to_radians()),
            ),
        };
        let poses = [at(1.0), at(1.01), at(1.02), at(2.0)];
        // Exactly at a sample: that pose, bit for bit.
        assert_eq!(interpolated_pose(&poses, 1.01, 0.02), Some(poses[1].pose));
        // Between two samples: linear translation, rotation along the arc.
        let p = interpolated_pose(&poses, 1.0125, 0.02).unwrap();
        assert!((p.translation().x - 1.0125).abs() < 1e-12);
        let angle = p.isometry().rotation.angle().to_degrees();
        assert!((angle - 10.125).abs() < 1e-9, "{angle}");
        // A gap in the capture is not bridged; outside the trajectory there is no pose.
        assert!(interpolated_pose(&poses, 1.5, 0.02).is_none());
        assert!(interpolated_pose(&poses, 1.5, 1.0).is_some());
        assert!(interpolated_pose(&poses, 0.99, 0.02).is_none());
        assert!(interpolated_pose(&poses, 2.01, 0.02).is_none());
        assert!(interpolated_pose(&poses, f64::NAN, 0.02).is_none());
        assert!(interpolated_pose(&[], 1.0, 0.02).is_none());
        // Association at an offset: the pose 5 ms before each stamp, unsorted poses sorted.
        let seq = associate_interpolated(
            &[(1.0175, "a".into()), (1.5, "b".into()), (1.0, "c".into())],
            &[at(1.02), at(2.0), at(1.0), at(1.01)],
            -0.005,
            0.02,
        );
        assert_eq!(seq.frames.len(), 1);
        assert_eq!(seq.frames[0].depth_path, PathBuf::from("a"));
        assert_eq!(seq.frames[0].timestamp, Some(1.0175));
        assert!((seq.frames[0].pose.translation().x - 1.0125).abs() < 1e-12);
        assert_eq!(
            seq.without_pose,
            vec![(1.5, PathBuf::from("b")), (1.0, PathBuf::from("c"))]
        );
    }

    #[test]
    fn tum_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("gt.txt");
        let poses: Vec<TimedPose> = (0..5)
            .map(|i| TimedPose {
                timestamp: 100.0 + f64::from(i) * 0.01,
                pose: c2w(
                    Vector3::new(1.0, -2.0, 0.5 * f64::from(i)),
                    Vector3::new(0.1, 0.2 * f64::from(i), -0.3),
                ),
            })
            .collect();
        write_tum_trajectory(&p, &poses).unwrap();
        let back = read_tum_trajectory(&p).unwrap();
        assert_eq!(back.len(), 5);
        for (a, b) in back.iter().zip(&poses) {
            assert!((a.timestamp - b.timestamp).abs() < 1e-6);
            assert!((a.pose.to_matrix() - b.pose.to_matrix()).abs().max() < 1e-8);
        }
        std::fs::write(&p, "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0\n").unwrap();
        match read_tum_trajectory(&p).unwrap_err() {
            IoError::Parse { line, .. } => assert_eq!(line, 3),
            e => panic!("{e}"),
        }
        std::fs::write(&p, "1 0 0 0 0 0 0 0\n").unwrap();
        let e = read_tum_trajectory(&p).unwrap_err();
        assert!(matches!(e, IoError::Core { line: Some(1), .. }), "{e}");
        assert!(e.to_string().contains("gt.txt:1"), "{e}");
        // A repeated timestamp (in any order) names both lines.
        std::fs::write(
            &p,
            "# c\n2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n",
        )
        .unwrap();
        let e = read_tum_trajectory(&p).unwrap_err();
        assert!(matches!(e, IoError::Parse { line: 4, .. }), "{e}");
        assert!(
            e.to_string()
                .contains("timestamp 2 s appears twice (also on line 2)"),
            "{e}"
        );
    }

    #[test]
    fn tum_folder_at_a_clock_offset() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // Poses every 10 ms moving 1 m/s along x; depth frames at 1.015 and 1.5 s.
        let poses: Vec<TimedPose> = (0..10)
            .map(|i| {
                let t = 1.0 + f64::from(i) * 0.01;
                TimedPose {
                    timestamp: t,
                    pose: c2w(Vector3::new(t, 0.0, 0.0), Vector3::zeros()),
                }
            })
            .collect();
        write_tum_trajectory(d.join("groundtruth.txt"), &poses).unwrap();
        std::fs::write(
            d.join("depth.txt"),
            "# depth\n1.015 depth/a.png\n1.5 depth/b.png\n",
        )
        .unwrap();
        let limits = Limits::default();
        let seq = read_tum_sequence_at_offset(d, -0.0075, 0.02, &limits).unwrap();
        assert_eq!(seq.frames.len(), 1);
        assert!((seq.frames[0].pose.translation().x - 1.0075).abs() < 1e-6);
        assert_eq!(seq.without_pose.len(), 1);
        assert!(read_tum_sequence_at_offset(d, f64::NAN, 0.02, &limits).is_err());
        assert!(read_tum_sequence_at_offset(d, 0.0, 0.0, &limits).is_err());
    }

    #[test]
    fn open3d_log_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.log");
        let poses = vec![
            c2w(Vector3::new(2.0, 2.0, -0.3), Vector3::zeros()),
            c2w(Vector3::new(1.0, 0.0, 0.5), Vector3::new(0.0, 0.3, 0.1)),
        ];
        write_open3d_log(&p, &poses).unwrap();
        let back = read_open3d_log(&p).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[1].metadata, [1, 1, 2]);
        for (a, b) in back.iter().zip(&poses) {
            assert!((a.pose.to_matrix() - b.to_matrix()).abs().max() < 1e-9);
        }
        std::fs::write(&p, "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n").unwrap();
        assert!(matches!(
            read_open3d_log(&p).unwrap_err(),
            IoError::Parse { line: 1, .. }
        ));
        std::fs::write(&p, "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n0 -1 1\n").unwrap();
        assert!(read_open3d_log(&p).is_err());
        std::fs::write(&p, "0 0 1\n2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n").unwrap();
        assert!(matches!(
            read_open3d_log(&p).unwrap_err(),
            IoError::Core { line: Some(1), .. }
        ));
    }

    #[test]
    fn seven_scenes_directory() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let id = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
        std::fs::write(d.join("frame-000002.pose.txt"), id).unwrap();
        std::fs::write(
            d.join("frame-000001.pose.txt"),
            "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
        )
        .unwrap();
        std::fs::write(d.join("frame-000001.depth.png"), b"").unwrap();
        let err = read_7scenes_sequence(d).unwrap_err();
        assert!(err.to_string().contains("frame-000002.depth.png"), "{err}");
        std::fs::write(d.join("frame-000002.depth.png"), b"").unwrap();
        let frames = read_7scenes_sequence(d).unwrap();
        assert_eq!(frames.len(), 2);
        assert!(frames[0].depth_path.ends_with("frame-000001.depth.png"));
        assert_eq!(frames[0].pose.translation().x, 0.5);
        std::fs::write(
            d.join("frame-000002.pose.txt"),
            "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0\n",
        )
        .unwrap();
        assert!(read_7scenes_sequence(d).is_err());
    }

    /// Numbers in names sort as numbers: unpadded frames in the order they were recorded, not
    /// `10, 11, 8, 9` (a silently shuffled trajectory before); padded ones as by bytes.
    #[test]
    fn numbered_names_sort_as_numbers() {
        let sorted = |names: &[&str]| {
            let mut v: Vec<std::ffi::OsString> = names.iter().map(Into::into).collect();
            v.sort_by(|a, b| natural_order(a, b));
            v.into_iter()
                .map(|s| s.into_string().unwrap())
                .collect::<Vec<_>>()
        };
        assert_eq!(
            sorted(&["10.png", "9.png", "100.png", "8.png", "11.png"]),
            ["8.png", "9.png", "10.png", "11.png", "100.png"]
        );
        assert_eq!(
            sorted(&["frame-000010.depth.png", "frame-000009.depth.png"]),
            ["frame-000009.depth.png", "frame-000010.depth.png"]
        );
        assert_eq!(
            sorted(&["b2", "a10", "a9", "a", "a09", "a9x", "2b"]),
            ["2b", "a", "a09", "a9", "a9x", "a10", "b2"]
        );
        assert_eq!(
            sorted(&["1305031229.564442.png", "1305031229.528784.png"]),
            ["1305031229.528784.png", "1305031229.564442.png"]
        );
        // Digit runs beyond any integer type compare too.
        assert_eq!(
            sorted(&[
                "99999999999999999999999.png",
                "100000000000000000000000.png"
            ]),
            [
                "99999999999999999999999.png",
                "100000000000000000000000.png"
            ]
        );
        let dir = tempfile::tempdir().unwrap();
        for i in [8, 9, 10, 11] {
            std::fs::write(dir.path().join(format!("{i}.png")), b"").unwrap();
        }
        let names: Vec<String> = list_depth_files(dir.path())
            .unwrap()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["8.png", "9.png", "10.png", "11.png"]);
    }
}
