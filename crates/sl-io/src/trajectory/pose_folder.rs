//! A folder of per-frame pose files beside a `depth` folder, as ScanNet's SensReader exports a
//! scan (`depth/<n>.png`, `pose/<n>.txt`: 4×4 camera-to-world, row-major), with the frames its
//! reconstruction lost marked by a matrix of `-inf`.

use std::path::Path;

use super::Frame;
use super::depth_files::list_depth_files;
use super::parse::check_frames;
use super::seven_scenes::{parse_pose_txt, read_pose_text};
use crate::error::Result;
use crate::limits::Limits;

/// The depth images of `dir/depth` (in the order of [`list_depth_files`]) with the pose of
/// `dir/pose/<stem>.txt` (a 4×4 camera-to-world matrix, row-major, as 7-Scenes' pose files),
/// and how many images have none: no pose file, or ScanNet's mark of a frame without a pose —
/// a matrix whose every entry is not finite (`-inf`). Any other malformed pose file is an
/// error naming it.
pub fn read_pose_folder_frames(
    dir: impl AsRef<Path>,
    limits: &Limits,
) -> Result<(Vec<Frame>, usize)> {
    let dir = dir.as_ref();
    let depth = list_depth_files(dir.join("depth"))?;
    check_frames(dir, depth.len(), limits)?;
    let mut frames = Vec::with_capacity(depth.len());
    let mut without = 0;
    for depth_path in depth {
        let Some(stem) = depth_path.file_stem() else {
            without += 1;
            continue;
        };
        let mut name = stem.to_os_string();
        name.push(".txt");
        let pose_path = dir.join("pose").join(name);
        if !pose_path.is_file() {
            without += 1;
            continue;
        }
        let text = read_pose_text(&pose_path)?;
        if marks_no_pose(&text) {
            without += 1;
            continue;
        }
        frames.push(Frame {
            pose: parse_pose_txt(&pose_path, &text)?,
            depth_path,
            timestamp: None,
        });
    }
    Ok((frames, without))
}

/// Whether a pose file's text is ScanNet's mark of a frame without a pose: 16 entries, none
/// finite.
fn marks_no_pose(text: &str) -> bool {
    let mut n = 0;
    for tok in text.split_whitespace() {
        match tok.parse::<f64>() {
            Ok(v) if !v.is_finite() => n += 1,
            _ => return false,
        }
    }
    n == 16
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames with a pose come back in the images' order; a missing pose file and a `-inf`
    /// matrix are counted as frames without a pose; a partly broken matrix is an error.
    #[test]
    fn a_scannet_export_reads_as_posed_frames() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("depth")).unwrap();
        std::fs::create_dir_all(d.join("pose")).unwrap();
        for i in [0, 1, 2, 10] {
            std::fs::write(d.join("depth").join(format!("{i}.png")), b"").unwrap();
        }
        let pose = |x: f64| format!("1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
        std::fs::write(d.join("pose/0.txt"), pose(0.0)).unwrap();
        std::fs::write(d.join("pose/1.txt"), "-inf -inf -inf -inf\n".repeat(4)).unwrap();
        std::fs::write(d.join("pose/10.txt"), pose(1.0)).unwrap();
        let (frames, without) = read_pose_folder_frames(d, &Limits::default()).unwrap();
        assert_eq!(without, 2);
        let names: Vec<_> = frames
            .iter()
            .map(|f| {
                f.depth_path
                    .file_name()
                    .unwrap()
                    .to_str()
                    .unwrap()
                    .to_owned()
            })
            .collect();
        assert_eq!(names, ["0.png", "10.png"]);
        assert_eq!(frames[1].pose.isometry().translation.vector.x, 1.0);
        std::fs::write(
            d.join("pose/2.txt"),
            "1 0 0 inf\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
        )
        .unwrap();
        let e = read_pose_folder_frames(d, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("2.txt") && e.contains("not finite"), "{e}");
    }
}
