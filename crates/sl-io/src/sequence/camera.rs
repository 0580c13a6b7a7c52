//! The camera a sequence folder implies: its camera file (7-Scenes' `camera-intrinsics.txt`, an
//! Open3D-style folder's JSON by the names Open3D's tools write or a ScanNet export's 4×4
//! matrix, a TUM-layout folder's `calibration.txt` as the ETH3D SLAM benchmark ships it), else
//! the preset of the sensor its layout names.

use std::path::{Path, PathBuf};

use sl_core::Camera;

use super::{
    SequenceLayout, read_7scenes_depth_frames, read_open3d_depth_frames, read_tum_depth_frames,
    tum_preset_name,
};
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// The camera files an Open3D-style folder may hold, in the order they are looked for, each an
/// Open3D `PinholeCameraIntrinsic` JSON but the last two: `camera.json` (Open3D's ICL-NUIM
/// sample), `camera_intrinsic.json` (what Open3D's RealSense recorder writes beside `depth/`),
/// `intrinsic.json` (Open3D's Azure Kinect MKV reader), `camera_primesense.json` (Open3D's
/// Redwood samples), else ScanNet's `intrinsic/intrinsic_depth.txt` or `intrinsic_depth.txt` (a
/// 4×4 matrix whose top-left 3×3 is the depth camera's).
const OPEN3D_CAMERA_FILES: [&str; 6] = [
    "camera.json",
    "camera_intrinsic.json",
    "intrinsic.json",
    "camera_primesense.json",
    "intrinsic/intrinsic_depth.txt",
    "intrinsic_depth.txt",
];

/// The camera file a sequence folder of `layout` may hold: 7-Scenes' `camera-intrinsics.txt`
/// ([`SEVEN_SCENES_CAMERA_FILE`]; the folder's own, else its parent's, where 3DMatch's RGB-D
/// scenes keep it above their `seq-XX` folders), an Open3D-style folder's `camera.json` (or `camera_intrinsic.json`, `intrinsic.json`,
/// `camera_primesense.json`, as Open3D's tools and samples name it) or, for a ScanNet export,
/// its `intrinsic/intrinsic_depth.txt` (the first that exists; `camera.json` when none does);
/// for a TUM-layout folder its [`TUM_CALIBRATION_FILE`] when it has one (the ETH3D SLAM
/// benchmark's `fx fy cx cy`), else `None` (TUM's own camera is a preset).
pub fn camera_file_of(dir: impl AsRef<Path>, layout: SequenceLayout) -> Option<PathBuf> {
    let dir = dir.as_ref();
    match layout {
        SequenceLayout::Tum => Some(dir.join(TUM_CALIBRATION_FILE)).filter(|p| present(p)),
        SequenceLayout::SevenScenes => {
            // 3DMatch's RGB-D scenes (7-Scenes, SUN3D, BundleFusion, ... in 7-Scenes' layout)
            // keep one file per scene, above its `seq-XX` folders.
            let own = dir.join(SEVEN_SCENES_CAMERA_FILE);
            let scene = dir.parent().map(|p| p.join(SEVEN_SCENES_CAMERA_FILE));
            Some(match scene {
                Some(s) if !present(&own) && present(&s) => s,
                _ => own,
            })
        }
        SequenceLayout::Open3d => Some(
            OPEN3D_CAMERA_FILES
                .iter()
                .map(|f| dir.join(f))
                .find(|p| present(p))
                .unwrap_or_else(|| dir.join(OPEN3D_CAMERA_FILES[0])),
        ),
    }
}

/// Whether something is at `path` (any kind of file: one that is not a regular file is then
/// reported by [`sequence_camera`] rather than passed over).
fn present(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok()
}

/// The camera file of a 7-Scenes-layout folder: a 3×3 intrinsic matrix, row by row. 7-Scenes
/// itself publishes its camera on its web page only; 3DMatch's conversions of 7-Scenes, SUN3D,
/// BundleFusion, RGB-D Scenes v2 and Analysis-by-Synthesis ship this file with each scene.
pub const SEVEN_SCENES_CAMERA_FILE: &str = "camera-intrinsics.txt";

/// The camera file of a TUM-layout folder that is not one of TUM's: the ETH3D SLAM benchmark
/// ships `calibration.txt` (`fx fy cx cy` of its undistorted images, 739×458 at about 27 Hz,
/// global shutters, active-stereo depth) beside `depth.txt`, `associated.txt` and
/// `groundtruth.txt`, its depth at TUM's 5000 units per metre.
pub const TUM_CALIBRATION_FILE: &str = "calibration.txt";

/// The camera of an Open3D-style folder without a camera file: `ros-default` (fx = fy = 525,
/// c = (319.5, 239.5)), Open3D's `PrimeSenseDefault`, which Open3D's own reconstruction system
/// takes for such a folder — depth registered to the colour camera, as Open3D's pipelines and
/// data sets (Redwood, its TUM and ICL-NUIM copies) keep it.
pub const OPEN3D_DEFAULT_PRESET: &str = "ros-default";

/// The camera preset of the sensor a sequence folder of `layout` was recorded with, as far as
/// the layout says: a TUM folder's by its name ([`tum_preset_name`]: TUM's Kinects, with their
/// lens models and rolling shutters; `None` for one with its own [`TUM_CALIBRATION_FILE`], any
/// camera), 7-Scenes `7-scenes` (a Kinect v1), an Open3D-style
/// folder without a camera file [`OPEN3D_DEFAULT_PRESET`]; `None` for an Open3D-style folder
/// with its own camera file (`camera.json` and the others Open3D's tools write, or a ScanNet
/// export's `intrinsic_depth.txt`: any camera). `sldepth track` models that preset's rolling
/// shutter and lens when no `--camera` is given, whether the intrinsics come from the preset or
/// from the folder's camera file.
pub fn sensor_preset(dir: impl AsRef<Path>, layout: SequenceLayout) -> Option<&'static str> {
    let dir = dir.as_ref();
    let own_file = camera_file_of(dir, layout).is_some_and(|f| f.is_file());
    match layout {
        SequenceLayout::Tum => (!own_file).then(|| tum_preset_name(dir)),
        SequenceLayout::SevenScenes => Some("7-scenes"),
        SequenceLayout::Open3d => (!own_file).then_some(OPEN3D_DEFAULT_PRESET),
    }
}

/// The camera a sequence folder implies, as `sldepth track DIR` and `sldepth fuse DIR` use it
/// when none is given, and the preset of its sensor ([`sensor_preset`]): the folder's camera
/// file ([`camera_file_of`]) when it has one (a path there that is not a regular file is an
/// error), else that preset's camera — TUM the one its name implies (an ICL-NUIM TUM-format
/// folder `icl-nuim-tum`), 7-Scenes `7-scenes`, Open3D [`OPEN3D_DEFAULT_PRESET`]. A 7-Scenes
/// folder's `camera-intrinsics.txt` (its own or its scene's, see [`camera_file_of`]) gives the
/// intrinsics and `7-scenes` the sensor's rolling shutter, as the command line takes them. A
/// 7-Scenes folder's `camera-intrinsics.txt`, a TUM-layout folder's `calibration.txt` and a
/// ScanNet export's matrix are sized by the folder's first depth image (a folder without one is
/// an error); their sensor is the Kinect v1 model at their focal length.
pub fn sequence_camera(
    dir: impl AsRef<Path>,
    layout: SequenceLayout,
    limits: &Limits,
) -> Result<(Camera, Option<&'static str>)> {
    let dir = dir.as_ref();
    if let Some(file) = camera_file_of(dir, layout)
        && let Ok(m) = std::fs::metadata(&file)
    {
        if !m.is_file() {
            return Err(IoError::malformed(
                &file,
                "exists but is not a regular file (a camera file was expected)",
            ));
        }
        let is_json = file.extension().is_some_and(|e| e == "json");
        // Files that give no image size: read at the size of the folder's first depth frame,
        // with the Kinect v1 sensor model at their focal length.
        let sized = |frames: Vec<super::SequenceFrame>, read: SizedReader| -> Result<Camera> {
            let (w, h) = first_frame_size(dir, frames, limits)?;
            Camera::from_intrinsics(read(&file, w, h)?, None, None)
                .map_err(|e| IoError::core(&file, None, e))
        };
        let camera = match layout {
            SequenceLayout::Open3d if is_json => {
                crate::camera::read_camera_json_with_limits(&file, limits)?
            }
            // A ScanNet export's matrix.
            SequenceLayout::Open3d => sized(read_open3d_depth_frames(dir, limits)?, |p, w, h| {
                crate::camera::read_intrinsics_txt(p, w, h)
            })?,
            // ETH3D's `fx fy cx cy`.
            SequenceLayout::Tum => sized(read_tum_depth_frames(dir, limits)?, |p, w, h| {
                crate::camera::read_fx_fy_cx_cy_txt(p, w, h)
            })?,
            // 7-Scenes' (and 3DMatch's) matrix, for frames of the first one's size: 640×480
            // for 7-Scenes and every scene 3DMatch converted.
            SequenceLayout::SevenScenes => {
                sized(read_7scenes_depth_frames(dir, limits)?, |p, w, h| {
                    crate::camera::read_intrinsics_txt(p, w, h)
                })?
            }
        };
        return Ok((camera, sensor_preset(dir, layout)));
    }
    // Without a camera file every layout names its sensor (an Open3D folder: Open3D's default).
    let preset = sensor_preset(dir, layout).unwrap_or(OPEN3D_DEFAULT_PRESET);
    let camera = Camera::preset(preset).map_err(|e| IoError::core(dir, None, e))?;
    Ok((camera, Some(preset)))
}

/// A reader of a camera text file that gives no image size, for frames of the given size.
type SizedReader = fn(&Path, usize, usize) -> Result<sl_core::Intrinsics>;

/// The size of the first of a folder's depth frames (from its header), which sizes a camera file
/// that gives no image size; a folder without a frame is an error.
fn first_frame_size(
    dir: &Path,
    frames: Vec<super::SequenceFrame>,
    limits: &Limits,
) -> Result<(usize, usize)> {
    let first = frames.into_iter().next().ok_or_else(|| {
        IoError::malformed(
            dir,
            "no depth frame to size the camera of its camera file by",
        )
    })?;
    crate::raster::image_size(&first.depth_path, limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A TUM-layout folder with the ETH3D SLAM benchmark's `calibration.txt` takes it, sized
    /// by its first depth frame, and names no preset (no TUM lens model or rolling shutter);
    /// without one it is TUM's.
    #[test]
    fn an_eth3d_folder_takes_its_calibration() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let lim = Limits::default();
        std::fs::create_dir(d.join("depth")).unwrap();
        let depth = sl_core::DepthImage::from_vec(739, 458, vec![1.0; 739 * 458]).unwrap();
        crate::depth::write_depth(
            d.join("depth/1.png"),
            &depth,
            &crate::depth::DepthEncoding::png(5000.0),
        )
        .unwrap();
        std::fs::write(d.join("depth.txt"), "1.0 depth/1.png\n").unwrap();
        assert_eq!(camera_file_of(d, SequenceLayout::Tum), None);
        assert_eq!(sensor_preset(d, SequenceLayout::Tum), Some("tum-fr1"));
        std::fs::write(d.join("calibration.txt"), "726.28 726.28 354.65 186.46\n").unwrap();
        assert_eq!(sensor_preset(d, SequenceLayout::Tum), None);
        let (cam, preset) = sequence_camera(d, SequenceLayout::Tum, &lim).unwrap();
        assert_eq!(preset, None);
        let k = cam.intrinsics;
        assert_eq!((k.width, k.height, k.fx, k.cy), (739, 458, 726.28, 186.46));
        // Not four numbers, or a principal point off the image: an error naming the file.
        for bad in [
            "726 726 354\n",
            "726 726 354 186 1\n",
            "726 726 354 x\n",
            "726 726 900 186\n",
        ] {
            std::fs::write(d.join("calibration.txt"), bad).unwrap();
            let e = sequence_camera(d, SequenceLayout::Tum, &lim)
                .unwrap_err()
                .to_string();
            assert!(e.contains("calibration.txt"), "{bad}: {e}");
        }
    }
}
