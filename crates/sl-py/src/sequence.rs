//! Depth sequences on disk: `read_sequence`, the frames `sldepth track --tum / --7scenes /
//! --o3d` reads, for `track_sequence`.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use sl_io::Limits;
use sl_io::sequence::{SequenceLayout, read_depth_frames};

use crate::errors::{SlDepthIOError, io_error, value_error};

/// A sequence's frame paths, and their timestamps (seconds) where the layout has them.
type Frames<'py> = (Vec<String>, Option<Bound<'py, PyArray1<f64>>>);

/// The depth frames of a sequence folder, in order, as ``sldepth track`` reads them:
/// ``(paths, timestamps_s)``, a list of ``str`` and a float64 array (N,) of seconds — or
/// ``None`` where the layout has no timestamps. ``layout``: ``"tum"`` (``associations.txt`` when
/// present, else ``depth.txt``, as TUM ships a sequence: timestamps must increase strictly),
/// ``"7scenes"`` (``frame-XXXXXX.depth.png``, no timestamps), ``"open3d"`` (``depth/*.png``, or
/// the folder's own images, by name); ``None`` infers it from what the folder holds. The paths
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
    let named = layout
        .map(|l| l.parse::<SequenceLayout>().map_err(value_error))
        .transpose()?;
    if !path.is_dir() {
        return Err(SlDepthIOError::new_err(format!(
            "{}: not a folder (a sequence is a folder of depth images)",
            path.display()
        )));
    }
    let layout = match named {
        Some(l) => l,
        None => SequenceLayout::infer(&path).map_err(io_error)?,
    };
    let frames = read_depth_frames(&path, layout, &Limits::default()).map_err(io_error)?;
    let times: Option<Vec<f64>> = frames.iter().map(|f| f.timestamp).collect();
    let paths = frames
        .into_iter()
        .map(|f| f.depth_path.to_string_lossy().into_owned())
        .collect();
    Ok((paths, times.map(|t| t.into_pyarray(py))))
}
