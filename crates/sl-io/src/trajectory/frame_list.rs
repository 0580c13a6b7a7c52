//! Frame lists (the `sldepth fuse --frames` format): a depth image and its camera-to-world pose
//! per line.

use std::path::Path;

use sl_core::CameraToWorld;

use super::Frame;
use super::parse::{check_frames, read_limited};
use crate::error::{IoError, Result};
use crate::limits::Limits;

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
