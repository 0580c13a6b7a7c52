//! The depth images of a folder, listed in the order they were recorded: by the times their
//! names state when every name states one, else by the numbers in their names.

use std::path::{Path, PathBuf};

use crate::error::{IoError, Result};

/// Depth image files (`.png`, `.tif`, `.tiff`, `.pgm`) in `dir`, in the order they were
/// recorded: by the time their names state ([`name_timestamp_s`]) when every name states one,
/// else by name in [`natural_order`] (`9.png` before `10.png`).
///
/// Both orders are the same for names of one width (TUM's `1305031102.160407.png`, zero-padded
/// frame numbers). They differ for times written with as few decimals as they need (Python's
/// `str(stamp.to_sec())`: `1305031102.2.png`, `1305031102.175304.png`), which by their digit
/// runs would put 0.2 s before 0.175304 s and shuffle a trajectory without a word. Open3D's
/// reconstruction system (`sorted_alphanum`) takes such names in that shuffled order; a `.log`
/// it made from them pairs differently.
pub fn list_depth_files(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>> {
    let dir = dir.as_ref();
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        if path.is_file() && crate::depth::DepthFormat::from_path(&path).is_some() {
            files.push(path);
        }
    }
    let by_name = |a: &PathBuf, b: &PathBuf| natural_order(a.as_os_str(), b.as_os_str());
    match name_timestamps_s(&files) {
        Some(times) => {
            let mut timed: Vec<(f64, PathBuf)> = times.into_iter().zip(files).collect();
            timed.sort_by(|a, b| a.0.total_cmp(&b.0).then_with(|| by_name(&a.1, &b.1)));
            Ok(timed.into_iter().map(|(_, p)| p).collect())
        }
        None => {
            files.sort_by(by_name);
            Ok(files)
        }
    }
}

/// The times the names of `files` state ([`name_timestamp_s`]), in their order, when every one
/// states a time; `None` when one does not (or there are no files).
pub fn name_timestamps_s(files: &[PathBuf]) -> Option<Vec<f64>> {
    if files.is_empty() {
        return None;
    }
    files.iter().map(|p| name_timestamp_s(p)).collect()
}

/// Nanoseconds in a name of [`NANOSECOND_DIGITS`] digits: from 10¹⁸ (September 2001) on.
const MIN_NANOSECOND_NAME: u64 = 1_000_000_000_000_000_000;

/// Digits of a name that states the time in nanoseconds since 1970 (ROS 2's `Time`, rospy's
/// `str(Time)`), from 2001 to 2286.
pub const NANOSECOND_DIGITS: usize = 19;

/// The time a depth image's file name states, seconds since whatever epoch the recorder used,
/// as the tools that extract frames from recordings name them:
///
/// - **seconds with a fraction**, `<digits>.<digits>` before the extension
///   (`1305031102.160407.png`, as TUM names its frames; `1305031102.2.png`, as Python's
///   `str(stamp.to_sec())` writes it);
/// - **nanoseconds**, [`NANOSECOND_DIGITS`] digits from 10¹⁸ on (`1305031102160407000.png`, as
///   ROS 2's `Time.nanoseconds` or rospy's `str(stamp)` writes it).
///
/// `None` for anything else: frame numbers (`000042.png`, `frame-000042.depth.png`), which have
/// no fraction and fewer digits.
pub fn name_timestamp_s(path: &Path) -> Option<f64> {
    let stem = path.file_stem()?.to_str()?;
    let all_digits = |s: &str| !s.is_empty() && s.bytes().all(|c| c.is_ascii_digit());
    if let Some((whole, fraction)) = stem.split_once('.') {
        if !(all_digits(whole) && all_digits(fraction)) {
            return None;
        }
        return stem.parse::<f64>().ok().filter(|t| t.is_finite());
    }
    if stem.len() != NANOSECOND_DIGITS || !all_digits(stem) {
        return None;
    }
    let ns: u64 = stem.parse().ok()?;
    if ns < MIN_NANOSECOND_NAME {
        return None;
    }
    // Whole seconds and the nanoseconds apart, so the fraction keeps its digits.
    Some((ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9)
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
