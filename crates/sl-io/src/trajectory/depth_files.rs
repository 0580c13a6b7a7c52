//! The depth images of a folder, listed in the order of the numbers in their names.

use std::path::{Path, PathBuf};

use crate::error::{IoError, Result};

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
