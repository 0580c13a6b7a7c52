//! What a file's or a folder's place says about it: a depth image in a TUM folder (its scale,
//! 5000 units per metre) or in a SUN RGB-D sample (its format and intrinsics), a TUM-layout
//! folder's frame numbering, ICL-NUIM's TUM-format archives (their camera, ground truth and
//! y-up frame), and the TUM preset a folder's name implies.

use std::path::{Path, PathBuf};

use sl_core::Camera;

use super::SequenceLayout;
use crate::error::{IoError, Result};

/// The TUM RGB-D sequence folder a depth image lies in: the parent of its `depth` folder when
/// that holds `depth.txt` or `associations.txt` (as TUM and ICL-NUIM's TUM-format archives ship
/// them); `None` for an image anywhere else.
pub fn tum_folder_of_file(path: &Path) -> Option<&Path> {
    let folder = path.parent()?;
    if folder.file_name()? != "depth" {
        return None;
    }
    let sequence = folder.parent()?;
    (sequence.join("depth.txt").is_file() || sequence.join("associations.txt").is_file())
        .then_some(sequence)
}

/// The sequence folder a depth image lies in, and its layout, by the image's place:
///
/// - an image of a TUM folder's `depth/` ([`tum_folder_of_file`]);
/// - a 7-Scenes-layout frame (`frame-XXXXXX.depth.png`): its folder;
/// - an image in the `depth/` folder of an Open3D-style folder that holds a camera file
///   ([`super::camera_file_of`]: `camera.json`, the names Open3D's RealSense recorder, Azure
///   Kinect reader and Redwood samples give it, a ScanNet export's matrix);
///
/// `None` anywhere else: a `depth/` folder alone says nothing of the camera. A frame opened on
/// its own can then take the camera of its folder ([`super::sequence_camera`]), the one
/// `sldepth track` and `sldepth fuse` take for the whole folder.
pub fn sequence_folder_of_file(path: &Path) -> Option<(&Path, SequenceLayout)> {
    if let Some(dir) = tum_folder_of_file(path) {
        return Some((dir, SequenceLayout::Tum));
    }
    let folder = or_current(path.parent()?);
    let name = path.file_name()?.to_str()?;
    if name.starts_with("frame-") && name.ends_with(".depth.png") {
        return Some((folder, SequenceLayout::SevenScenes));
    }
    if folder.file_name()? != "depth" {
        return None;
    }
    let dir = or_current(folder.parent()?);
    super::camera_file_of(dir, SequenceLayout::Open3d)
        .is_some_and(|f| f.is_file())
        .then_some((dir, SequenceLayout::Open3d))
}

/// `dir`, or the current folder for the empty parent of a relative path's first component.
fn or_current(dir: &Path) -> &Path {
    if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    }
}

/// The SUN RGB-D sample folder a depth image lies in: the parent of its `depth` or `depth_bfx`
/// folder when that holds `intrinsics.txt` and an `image` folder, as SUN RGB-D ships every
/// sample; `None` for an image anywhere else. Such a PNG is SUN's bit-rotated millimetres
/// ([`crate::depth::DepthFormat::Sun`]), which [`crate::depth::read_depth`] takes when no
/// format is given, and `intrinsics.txt` its camera's 3×3 matrix ([`sun_camera`]).
pub fn sun_folder_of_file(path: &Path) -> Option<&Path> {
    let folder = path.parent()?;
    let name = folder.file_name()?;
    if name != "depth" && name != "depth_bfx" {
        return None;
    }
    let sample = folder.parent()?;
    (sample.join("intrinsics.txt").is_file() && sample.join("image").is_dir()).then_some(sample)
}

/// The camera of a SUN RGB-D sample folder for its `width`×`height` depth images: the
/// intrinsics of its `intrinsics.txt` (a row-major 3×3 matrix) with the Kinect v1 sensor
/// model (baseline, 1/8-px disparity steps, σ_D) at that focal length — SUN RGB-D's Kinect v1,
/// Xtion and RealSense samples are all triangulating sensors; its Kinect v2 (time of flight)
/// samples follow the model only roughly.
pub fn sun_camera(sample: impl AsRef<Path>, width: usize, height: usize) -> Result<Camera> {
    let file = sample.as_ref().join("intrinsics.txt");
    let k = crate::camera::read_intrinsics_txt(&file, width, height)?;
    Camera::from_intrinsics(k, None, None).map_err(|e| IoError::core(&file, None, e))
}

/// The depth units per metre a depth image's place implies: 5000 for an image of a TUM RGB-D
/// folder ([`tum_folder_of_file`], [`SequenceLayout::depth_scale`]); `None` anywhere else.
/// [`crate::depth::read_depth`] reads a PNG or TIFF at this scale when none is given, so a TUM
/// frame opened on its own is not read five times too deep.
pub fn depth_scale_of_file(path: impl AsRef<Path>) -> Option<f64> {
    tum_folder_of_file(path.as_ref()).map(|_| SequenceLayout::Tum.depth_scale())
}

/// Whether a TUM-layout folder numbers its frames instead of timing them: its
/// `associations.txt` lists the depth image first and stamps it with a whole number
/// (`0 depth/0.png 0 rgb/0.png`, as ICL-NUIM's TUM-format archives and the converters that copy
/// them write it), where TUM's lines start with the colour image's time in seconds. Such stamps
/// are frames, not seconds: `sldepth track` and Python's `track_sequence` take frame `n` at
/// `n / 30` s (one frame interval each), and write the numbers back as they were. Only the first
/// line is looked at; a folder without `associations.txt` does not.
pub fn tum_stamps_are_frame_numbers(dir: impl AsRef<Path>) -> bool {
    crate::text::first_data_fields(&dir.as_ref().join("associations.txt")).is_some_and(|f| {
        let toks: Vec<&str> = f.iter().map(String::as_str).collect();
        toks.len() >= 4
            && crate::trajectory::association_depth_columns(&toks) == (0, 1)
            && crate::text::is_whole_number(toks[0])
    })
}

/// Whether the TUM-layout folder `dir` is one of ICL-NUIM's own TUM-format archives: it numbers
/// its frames ([`tum_stamps_are_frame_numbers`]) and either holds the data set's ground truth
/// (a `*.gt.freiburg` file) or keeps the archive's name (`living_room_traj0_frei_png`,
/// `traj2n_frei_png`, ...: it contains `frei_png`). Such a folder
///
/// - is a rendering at ICL-NUIM's published intrinsics ([`tum_preset_name`]: `icl-nuim-tum`);
/// - and renders with the image y axis up (published fy = −480): its ground truth
///   (`groundtruth.txt`, or the `*.gt.freiburg` beside the frames, see [`tum_ground_truth_of`])
///   is read into sldepth's frame with [`sl_core::CameraToWorld::y_reflected`], and
///   `sldepth track` and `fuse` write trajectories and meshes back in the data set's frame, so
///   they compare with its ground truth directly.
///
/// A folder that numbers its frames under another name, without a `*.gt.freiburg`, is not taken
/// for one: the mirror would turn a right-handed recording's outputs inside out.
pub fn icl_nuim_tum_folder(dir: impl AsRef<Path>) -> bool {
    let dir = dir.as_ref();
    if !tum_stamps_are_frame_numbers(dir) {
        return false;
    }
    let full = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let named = full.file_name().is_some_and(|n| {
        n.to_string_lossy()
            .to_ascii_lowercase()
            .contains("frei_png")
    });
    named || icl_ground_truth_of(dir).is_some()
}

/// The ground-truth file of a TUM-layout folder: its `groundtruth.txt`, else the one
/// `*.gt.freiburg` file in it (ICL-NUIM ships `livingRoom0.gt.freiburg`, `traj0.gt.freiburg`,
/// ... beside its TUM-format archives), else `groundtruth.txt` (for the error that names it).
pub fn tum_ground_truth_of(dir: impl AsRef<Path>) -> PathBuf {
    let dir = dir.as_ref();
    let tum = dir.join("groundtruth.txt");
    if tum.exists() {
        return tum;
    }
    icl_ground_truth_of(dir).unwrap_or(tum)
}

/// The one `*.gt.freiburg` file (ICL-NUIM's ground truth) in `dir`; `None` when there is none,
/// or more than one.
fn icl_ground_truth_of(dir: &Path) -> Option<PathBuf> {
    let found: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(".gt.freiburg"))
        })
        .take(2)
        .collect();
    <[PathBuf; 1]>::try_from(found).ok().map(|[one]| one)
}

/// The TUM camera preset a TUM folder implies: `icl-nuim-tum` for one of ICL-NUIM's
/// TUM-format archives ([`icl_nuim_tum_folder`]), else by its name — `tum-fr2` or `tum-fr3`
/// when its path names `freiburg2` or `freiburg3`, else `tum-fr1` (TUM's sequence folders are
/// named `rgbd_dataset_freiburgN_...`).
pub fn tum_preset_name(dir: impl AsRef<Path>) -> &'static str {
    let dir = dir.as_ref();
    if icl_nuim_tum_folder(dir) {
        return "icl-nuim-tum";
    }
    let full = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let names = full.to_string_lossy().to_ascii_lowercase();
    if names.contains("freiburg2") {
        "tum-fr2"
    } else if names.contains("freiburg3") {
        "tum-fr3"
    } else {
        "tum-fr1"
    }
}
