//! Depth files: `read_depth` and `write_depth`.

use std::path::PathBuf;

use numpy::PyArray2;
use numpy::prelude::*;
use pyo3::prelude::*;
use sl_io::Limits;
use sl_io::depth::{DepthEncoding, DepthFormat, RawDepth, ReadConfig};

use crate::arrays::{depth_array, depth_input, u16_input};
use crate::errors::{io_error, value_error};
use crate::threads::compute;

fn parse_format(format: Option<&str>) -> PyResult<Option<DepthFormat>> {
    format
        .map(|f| f.parse::<DepthFormat>().map_err(value_error))
        .transpose()
}

/// Reads a depth map (16-bit PNG/TIFF at ``depth_scale`` units per metre — when None, 5000 for
/// a frame in the ``depth`` folder of a TUM RGB-D folder (beside ``depth.txt`` or
/// ``associations.txt``), else 1000 —, a floating-point TIFF (ROS ``32FC1``, ``cv2.imwrite``
/// of a float array: metres when ``depth_scale`` is None; ``format="tiff-f32"``, or ``"tiff"``
/// which reads either kind), NYU raw disparity ``.pgm``, or SUN RGB-D
/// ``format="sun"``, taken without it for a PNG in a SUN RGB-D sample's ``depth`` or
/// ``depth_bfx`` folder beside its ``intrinsics.txt``) into a float32
/// (H, W) array of metres, 0 = invalid. ``format`` is inferred from the extension when None.
/// ``max_memory_bytes`` bounds what reading may allocate (the CLI's ``--max-memory``; default
/// 4 GiB, at least 16 MiB: a smaller one raises ``ValueError``): an image whose header declares more pixels than the budget allows
/// (budget / 256 bytes per pixel, what the algorithms may need per pixel: 16.7 million pixels
/// at the default) is refused with ``OSError`` before it is decoded.
#[pyfunction]
#[pyo3(signature = (path, depth_scale = None, format = None, *, max_memory_bytes = None))]
pub(crate) fn read_depth<'py>(
    py: Python<'py>,
    path: PathBuf,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    format: Option<&str>,
    #[pyo3(from_py_with = crate::ints::opt_int)] max_memory_bytes: Option<u64>,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let mut opts = ReadConfig::default();
    opts.format = parse_format(format)?;
    opts.scale_units_per_m = depth_scale;
    let min = sl_io::limits::MIN_MEMORY_BYTES;
    if let Some(b) = max_memory_bytes.filter(|&b| b < min) {
        return Err(crate::errors::value_error(format!(
            "max_memory_bytes = {b} is below the minimum budget of {min} bytes (16 MiB)"
        )));
    }
    let limits = max_memory_bytes.map_or_else(Limits::default, Limits::for_memory);
    let loaded = compute(py, || {
        sl_io::depth::read_depth_with_limits(&path, &opts, &limits)
    })
    .map_err(|e| {
        // The budget's name here, not the command line's.
        let message = e
            .to_string()
            .replace(sl_io::limits::BUDGET_OPTION, "max_memory_bytes=");
        crate::errors::SlDepthIOError::new_err(message)
    })?;
    depth_array(py, loaded.depth)
}

/// Writes a depth map (metres) as 16-bit PNG or TIFF (by extension or ``format``) at
/// ``depth_scale`` units per metre (None: 1000 = millimetres), atomically, or as a 32-bit
/// float TIFF with ``format="tiff-f32"`` (None: metres). Invalid pixels (0, NaN, negative)
/// are stored as 0; a depth the 16-bit encodings cannot hold (below one unit, or above 65534
/// units: 65535 marks missing depth, as in 7-Scenes) raises ``ValueError``/``OSError``.
/// A ``uint16`` array is taken as depth in units of ``depth_scale`` and written as it is,
/// every value included: 0 and 65535 read back as invalid (a float TIFF stores it in metres
/// times ``depth_scale``).
#[pyfunction]
#[pyo3(signature = (path, depth, depth_scale = None, format = None))]
pub(crate) fn write_depth(
    py: Python<'_>,
    path: PathBuf,
    depth: &Bound<'_, PyAny>,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    format: Option<&str>,
) -> PyResult<()> {
    let format = match parse_format(format)? {
        Some(f) => f,
        None => DepthFormat::from_path(&path).ok_or_else(|| {
            value_error(format!(
                "{}: cannot tell the format from the extension; pass format=\"png\" or \"tiff\"",
                path.display()
            ))
        })?,
    };
    let integer_scale = depth_scale.unwrap_or(sl_io::depth::DEFAULT_UNITS_PER_M);
    let encoding = match format {
        DepthFormat::Png => DepthEncoding::png(integer_scale),
        DepthFormat::Tiff => DepthEncoding::tiff(integer_scale),
        DepthFormat::TiffF32 => {
            DepthEncoding::tiff_f32(depth_scale.unwrap_or(sl_io::depth::FLOAT_UNITS_PER_M))
        }
        other => {
            return Err(value_error(format!(
                "writing {other} depth is not supported; use png, tiff or tiff-f32"
            )));
        }
    };
    let depth_scale = encoding.units_per_m;
    // A uint16 array is depth in units of this same scale: its values are the file's, 65535
    // (which no depth in metres may round to) included. Float files take it as depth below.
    let raw_values = if format == DepthFormat::TiffF32 {
        None
    } else {
        u16_input(depth, Some(depth_scale))?
    };
    if let Some(values) = raw_values {
        let raw = RawDepth { values, encoding };
        return compute(py, || sl_io::depth::write_raw_depth(&path, &raw)).map_err(io_error);
    }
    let integer = depth
        .cast::<numpy::PyUntypedArray>()
        .is_ok_and(|a| a.dtype().kind() == b'u');
    let input = depth_input(depth, integer.then_some(depth_scale))?;
    let image = input.view()?.to_image();
    compute(py, || sl_io::depth::write_depth(&path, &image, &encoding)).map_err(io_error)
}
