//! # sl-py — `import sldepth` from Python
//!
//! The Python bindings of the sldepth workspace: a thin, curated facade over the library
//! crates (camera model and presets, depth I/O, noise analysis and simulation, filters, TSDF
//! fusion, planes and motion), with NumPy arrays in and out. The wheel is built with maturin
//! from `crates/sl-py/pyproject.toml`; the Python package `sldepth` (in `python/sldepth`)
//! re-exports this extension module, `sldepth._sldepth`, and ships type stubs.
//!
//! Policies (see `README.md`):
//! - **Arrays.** A C-contiguous `float32` (H, W) depth array is read in place (no copy); other
//!   dtypes and layouts are converted once, at a documented cost. Outputs own the Rust buffers.
//! - **GIL and threads.** Every computation releases the GIL and runs on a rayon pool of the
//!   size `sldepth.set_num_threads(n)` chose, with the calling thread as its first worker.
//! - **Errors.** Every Rust error becomes `sldepth.SlDepthError` (a `ValueError`) or
//!   `sldepth.SlDepthIOError` (an `OSError`) carrying the Rust message; nothing panics across
//!   the boundary.
//!
//! The Rust API is not meant for Rust users (use the library crates); the doctest below only
//! shows that the module is an ordinary crate.
//!
//! ```
//! // The camera presets the bindings expose come from sl-core's table.
//! assert!(sl_core::preset::names().any(|n| n == "kinect-v1"));
//! ```

mod arrays;
mod camera;
mod errors;
mod filter;
mod ints;
mod io;
mod noise;
mod noise_stats;
mod planes;
mod reals;
mod repr;
mod rosbag;
mod sequence;
mod threads;
mod track;
mod trajectory;
mod tsdf;

use pyo3::prelude::*;

/// The extension module `sldepth._sldepth`.
#[pymodule]
fn _sldepth(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<camera::PyCamera>()?;
    m.add_class::<noise::PyAnalysis>()?;
    m.add_class::<tsdf::PyTsdfVolume>()?;
    m.add_class::<tsdf::PyMesh>()?;
    m.add_class::<track::PyTracker>()?;
    m.add_class::<rosbag::PyRosBag>()?;
    m.add_class::<rosbag::PyBagFrames>()?;
    m.add_class::<planes::PyPlane>()?;
    m.add_class::<planes::PyUnlabelledRegion>()?;
    m.add_class::<planes::PyMotion>()?;
    m.add_function(wrap_pyfunction!(io::read_depth, m)?)?;
    m.add_function(wrap_pyfunction!(io::write_depth, m)?)?;
    m.add_function(wrap_pyfunction!(noise::analyze, m)?)?;
    m.add_function(wrap_pyfunction!(noise::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(noise_stats::noise_stats, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::read_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::read_posed_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::sequence_camera, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::frame_camera, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::sequence_depth_scale, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::icl_nuim_tum_folder, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::tum_stamps_are_frame_numbers, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::sun_camera, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory::read_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory::write_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory::evaluate_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory::estimate_time_offset, m)?)?;
    m.add_function(wrap_pyfunction!(filter::filter, m)?)?;
    m.add_function(wrap_pyfunction!(camera::undistort, m)?)?;
    m.add_function(wrap_pyfunction!(planes::extract_planes, m)?)?;
    m.add_function(wrap_pyfunction!(planes::explain_planes, m)?)?;
    m.add_function(wrap_pyfunction!(planes::motion, m)?)?;
    m.add_function(wrap_pyfunction!(track::track_in_map, m)?)?;
    m.add_function(wrap_pyfunction!(threads::set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(threads::get_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(threads::compute_thread_name, m)?)?;
    m.add_function(wrap_pyfunction!(input_is_borrowed, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// Whether a depth array would be read in place (C-contiguous float32) rather than converted;
/// ``depth_scale`` as for the functions that take uint16 depth.
#[pyfunction]
#[pyo3(signature = (depth, depth_scale = None))]
fn input_is_borrowed(depth: &Bound<'_, PyAny>, depth_scale: Option<f64>) -> PyResult<bool> {
    arrays::is_borrowed(depth, depth_scale)
}
