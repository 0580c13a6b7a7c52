//! Depth sequences on disk: `read_sequence`, the frames `sldepth track DIR` reads (for
//! `track_sequence`), `read_posed_sequence`, the frames and poses `sldepth fuse DIR` reads, and
//! `sequence_camera`, the camera both use for the folder, and `frame_camera`, that camera for
//! one of the folder's frames.
//! The folders are listed and read with the GIL released, as every computation.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1, PyArray3};
use pyo3::prelude::*;
use sl_io::Limits;
use sl_io::sequence::{SequenceLayout, read_depth_frames, read_posed_frames};

use crate::arrays::poses_array;
use crate::camera::PyCamera;
use crate::errors::{SlDepthIOError, io_error, value_error};
use crate::threads::compute;

/// A sequence's frame paths, and their timestamps (seconds) where the layout has them.
type Frames<'py> = (Vec<String>, Option<Bound<'py, PyArray1<f64>>>);

/// A posed sequence's frame paths, their timestamps where the layout has them, and their
/// camera-to-world poses (N, 4, 4).
type PosedFrames<'py> = (
    Vec<String>,
    Option<Bound<'py, PyArray1<f64>>>,
    Bound<'py, PyArray3<f64>>,
);

/// The frames' paths as strings, and their timestamps where every frame has one (TUM, and an
/// Open3D-style folder whose file names are times; `None` otherwise, an empty sequence of
/// another layout than TUM's included).
fn paths_and_times<'py>(
    py: Python<'py>,
    layout: SequenceLayout,
    frames: impl Iterator<Item = (PathBuf, Option<f64>)>,
) -> Frames<'py> {
    let (paths, times): (Vec<String>, Vec<Option<f64>>) = frames
        .map(|(p, t)| (p.to_string_lossy().into_owned(), t))
        .unzip();
    let times = (layout == SequenceLayout::Tum || !times.is_empty())
        .then(|| times.into_iter().collect::<Option<Vec<f64>>>())
        .flatten();
    (paths, times.map(|t| t.into_pyarray(py)))
}

/// The folder `path` and its layout, named or inferred.
fn folder_layout(
    py: Python<'_>,
    path: &std::path::Path,
    layout: Option<&str>,
) -> PyResult<SequenceLayout> {
    let named = layout
        .map(|l| l.parse::<SequenceLayout>().map_err(value_error))
        .transpose()?;
    if !path.is_dir() {
        return Err(SlDepthIOError::new_err(format!(
            "{}: not a folder (a sequence is a folder of depth images)",
            path.display()
        )));
    }
    match named {
        Some(l) => Ok(l),
        None => compute(py, || SequenceLayout::infer(path)).map_err(io_error),
    }
}

/// The depth frames of a sequence folder, in order, as ``sldepth track`` reads them:
/// ``(paths, timestamps_s)``, a list of ``str`` and a float64 array (N,) of seconds — or
/// ``None`` where the folder has no timestamps. ``layout``: ``"tum"`` (``associations.txt`` when
/// present, else ``depth.txt``, as TUM ships a sequence: timestamps must increase strictly),
/// ``"7scenes"`` (``frame-XXXXXX.depth.png``, no timestamps), ``"open3d"`` (``depth/*.png``, or
/// the folder's own images: by the times their names state when every name is one, such as
/// ``1305031102.160407.png`` or 19-digit nanoseconds, which are then the timestamps, else by
/// name without timestamps); ``None`` infers it from what the folder holds. The paths
/// go straight into ``track_sequence(paths, camera, depth_scale=..., timestamps_s=...)``.
/// A missing folder, one whose layout cannot be inferred, or a malformed list raises
/// ``OSError``; an unknown layout name ``ValueError``.
#[pyfunction]
#[pyo3(signature = (path, layout = None))]
pub(crate) fn read_sequence<'py>(
    py: Python<'py>,
    path: PathBuf,
    layout: Option<&str>,
) -> PyResult<Frames<'py>> {
    let layout = folder_layout(py, &path, layout)?;
    let frames =
        compute(py, || read_depth_frames(&path, layout, &Limits::default())).map_err(io_error)?;
    Ok(paths_and_times(
        py,
        layout,
        frames.into_iter().map(|f| (f.depth_path, f.timestamp)),
    ))
}

/// The frames of a sequence folder with their poses, as ``sldepth fuse DIR`` reads them:
/// ``(paths, timestamps_s, poses)``, ``poses`` a float64 array (N, 4, 4) of camera-to-world
/// matrices. ``layout`` as for ``read_sequence``: a TUM folder's frames get the
/// ``groundtruth.txt`` pose nearest in time (within ``max_dt_s`` seconds; frames without one are
/// left out), a 7-Scenes folder's frames their ``frame-*.pose.txt``, an Open3D-style folder's
/// frames the poses of its one ``.log`` beside ``depth/`` (none or several raise ``OSError``)
/// or, without a ``.log``, each ``depth/<n>.png`` the ``pose/<n>.txt`` of a ScanNet export (its
/// ``-inf`` matrix: no pose).
/// With ``trajectory`` (a file: ``sldepth track``'s output or another system's estimate,
/// camera to world), its poses instead of the folder's own, as ``sldepth fuse DIR --trajectory
/// FILE``: a TUM-format file by time (nearest within ``max_dt_s``; frames without timestamps by
/// their index, as ``track`` stamps them), an Open3D ``.log`` by frame number.
/// Depth frames left out for want of a pose are counted in a ``UserWarning``, as ``sldepth
/// fuse`` notes them. Then
/// ``for p, T in zip(paths, poses): volume.integrate(read_depth(p, depth_scale), camera, T)``.
#[pyfunction]
#[pyo3(signature = (path, layout = None, *, max_dt_s = 0.02, trajectory = None))]
pub(crate) fn read_posed_sequence<'py>(
    py: Python<'py>,
    path: PathBuf,
    layout: Option<&str>,
    max_dt_s: f64,
    trajectory: Option<PathBuf>,
) -> PyResult<PosedFrames<'py>> {
    if !(max_dt_s.is_finite() && max_dt_s > 0.0) {
        return Err(value_error(format!(
            "max_dt_s must be a positive number of seconds, got {max_dt_s}"
        )));
    }
    let layout = folder_layout(py, &path, layout)?;
    let posed = compute(py, || match &trajectory {
        Some(t) => sl_io::sequence::read_frames_along_trajectory(
            &path,
            layout,
            t,
            max_dt_s,
            &Limits::default(),
        ),
        None => read_posed_frames(&path, layout, max_dt_s, &Limits::default()),
    })
    .map_err(io_error)?;
    // Frames left out are said, as `sldepth fuse DIR` notes them (a warning, not an error: a
    // TUM recording's first and last frames often fall outside its motion capture).
    if posed.without_pose > 0 {
        let why = match layout {
            _ if trajectory.is_some() => "no pose in the trajectory".to_owned(),
            SequenceLayout::Tum => format!("no groundtruth.txt pose within {max_dt_s} s"),
            SequenceLayout::SevenScenes => "no pose file (frame-*.pose.txt)".to_owned(),
            _ if sl_io::sequence::has_pose_folder(&path) => {
                "no pose (no pose/ file, or ScanNet's -inf matrix)".to_owned()
            }
            _ => "no entry in the .log".to_owned(),
        };
        let message = format!(
            "{}: {} depth frames have {why} and are left out",
            path.display(),
            posed.without_pose,
        );
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        PyErr::warn(
            py,
            &category,
            &std::ffi::CString::new(message).unwrap_or_default(),
            1,
        )?;
    }
    let frames = posed.frames;
    let matrices: Vec<_> = frames.iter().map(|f| f.pose.to_matrix()).collect();
    let (paths, times) = paths_and_times(
        py,
        layout,
        frames.into_iter().map(|f| (f.depth_path, f.timestamp)),
    );
    Ok((paths, times, poses_array(py, &matrices)))
}

/// The camera a sequence folder implies, as ``sldepth track DIR`` and ``sldepth fuse DIR`` use
/// it when none is given: the folder's camera file when it has one (7-Scenes'
/// ``camera-intrinsics.txt``, the folder's own or its scene's above it as 3DMatch keeps it; an
/// Open3D folder's ``camera.json``; a ScanNet export's ``intrinsic/intrinsic_depth.txt``; text
/// files at the size of the folder's depth images), else the layout's preset — a
/// TUM folder the ``tum-fr1``, ``tum-fr2`` or ``tum-fr3`` preset its name says (fr1 when it names
/// none; with that Kinect's lens model and rolling shutter; an ICL-NUIM TUM-format folder
/// ``icl-nuim-tum``), 7-Scenes ``7-scenes``, Open3D ``ros-default`` (Open3D's PrimeSenseDefault;
/// its camera file may also be ``camera_intrinsic.json``, ``intrinsic.json`` or
/// ``camera_primesense.json``, as Open3D's tools name it; a TUM-layout folder's
/// ``calibration.txt``, the ETH3D SLAM benchmark's ``fx fy cx cy``, names no preset). A 7-Scenes folder's camera file gives the intrinsics and ``7-scenes`` the
/// sensor (``preset_name``, and its 30 ms ``rolling_shutter_ms`` for ``track_sequence``), as on
/// the command line; an Open3D folder's ``camera.json`` names no preset. ``layout`` as for
/// ``read_sequence``.
#[pyfunction]
#[pyo3(signature = (path, layout = None))]
pub(crate) fn sequence_camera(
    py: Python<'_>,
    path: PathBuf,
    layout: Option<&str>,
) -> PyResult<PyCamera> {
    let layout = folder_layout(py, &path, layout)?;
    let (camera, preset) = compute(py, || {
        sl_io::sequence::sequence_camera(&path, layout, &Limits::default())
    })
    .map_err(io_error)?;
    PyCamera::wrap(camera, preset)
}

/// The camera of the sequence folder a depth image lies in, as ``sldepth`` takes it for a frame
/// read without ``--camera`` (and ``sldepth track`` for the whole folder): an image in a TUM
/// folder's ``depth/``, a 7-Scenes-layout frame (``frame-XXXXXX.depth.png``: its folder's or its
/// scene's ``camera-intrinsics.txt``, else ``7-scenes``), an image in the ``depth/`` folder of an
/// Open3D-style folder that has a camera file (``camera_intrinsic.json`` as Open3D's RealSense
/// recorder writes it, and the other names ``sequence_camera`` reads) — that folder's
/// ``sequence_camera``. ``None`` for an image anywhere else: give the camera yourself
/// (``Camera.preset("kinect-v1")`` is the command line's default; a SUN RGB-D sample's frames
/// take ``sun_camera``). A camera file in the folder that cannot be read raises ``OSError``.
#[pyfunction]
pub(crate) fn frame_camera(py: Python<'_>, path: PathBuf) -> PyResult<Option<PyCamera>> {
    let found = compute(py, || {
        sl_io::sequence::sequence_folder_of_file(&path)
            .map(|(dir, layout)| sl_io::sequence::sequence_camera(dir, layout, &Limits::default()))
            .transpose()
    })
    .map_err(io_error)?;
    found
        .map(|(camera, preset)| PyCamera::wrap(camera, preset))
        .transpose()
}

/// The camera of a SUN RGB-D sample folder (``depth/``, ``image/`` and ``intrinsics.txt``) for
/// its ``width`` × ``height`` depth images, as ``sldepth`` takes it for a frame of the sample:
/// the intrinsics of ``intrinsics.txt`` with the Kinect v1 sensor model at that focal length.
/// ``read_depth`` reads the sample's frames in SUN's format by itself.
#[pyfunction]
pub(crate) fn sun_camera(
    py: Python<'_>,
    path: PathBuf,
    width: usize,
    height: usize,
) -> PyResult<PyCamera> {
    let camera =
        compute(py, || sl_io::sequence::sun_camera(&path, width, height)).map_err(io_error)?;
    PyCamera::wrap(camera, None)
}

/// Whether a TUM-layout folder is one of ICL-NUIM's own TUM-format archives: its
/// ``associations.txt`` lists the depth image first, stamped with its frame number
/// (``0 depth/0.png 0 rgb/0.png``), and it holds a ``*.gt.freiburg`` or keeps the archive's name
/// (``..._frei_png``). Such a folder's camera is the ``icl-nuim-tum`` preset
/// (``sequence_camera``), ``track_sequence`` takes its frame numbers as frames 1/30 s apart, and
/// it renders with the image y axis up: ``read_posed_sequence`` gives its ground truth in
/// sldepth's frame (y down), and ``F @ pose @ F`` with ``F = diag(1, -1, 1, 1)`` turns a pose
/// either way (``sldepth track`` writes its trajectory and mesh in the data set's frame).
#[pyfunction]
pub(crate) fn icl_nuim_tum_folder(path: PathBuf) -> bool {
    sl_io::sequence::icl_nuim_tum_folder(path)
}

/// Whether a TUM-layout folder stamps its frames with their numbers instead of times: its
/// ``associations.txt`` lists the depth image first with a whole-number stamp, as ICL-NUIM's
/// archives do. ``track_sequence`` takes such stamps as frames 1/30 s apart.
#[pyfunction]
pub(crate) fn tum_stamps_are_frame_numbers(path: PathBuf) -> bool {
    sl_io::sequence::tum_stamps_are_frame_numbers(path)
}

/// The depth units per metre of a sequence folder's 16-bit depth images, as ``sldepth track
/// DIR`` and ``sldepth fuse DIR`` read them: 5000 for a TUM folder, 1000 (millimetres) for
/// 7-Scenes and Open3D-style folders. Pass it as ``depth_scale`` to ``track_sequence`` or
/// ``read_depth`` (a TUM frame read as millimetres is five times too deep). ``layout`` as for
/// ``read_sequence``.
#[pyfunction]
#[pyo3(signature = (path, layout = None))]
pub(crate) fn sequence_depth_scale(
    py: Python<'_>,
    path: PathBuf,
    layout: Option<&str>,
) -> PyResult<f64> {
    Ok(folder_layout(py, &path, layout)?.depth_scale())
}
