//! Python exceptions: every Rust error crosses the boundary as a subclass of `ValueError`
//! (bad input or parameters) or `OSError` (files), carrying the Rust message.

use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;

create_exception!(
    sldepth,
    SlDepthError,
    PyValueError,
    "Invalid input or parameters for an sldepth function (a ValueError)."
);
create_exception!(
    sldepth,
    SlDepthIOError,
    PyOSError,
    "A depth map, camera or mesh file that cannot be read or written (an OSError)."
);

/// A `ValueError` subclass with the message of any displayable error.
pub(crate) fn value_error(e: impl std::fmt::Display) -> PyErr {
    SlDepthError::new_err(e.to_string())
}

/// An `OSError` subclass with the message of an I/O error.
pub(crate) fn io_error(e: sl_io::IoError) -> PyErr {
    // sl-io names the command line's option for a limit; from Python the limit is the default
    // budget's (only `read_depth` takes `max_memory_bytes`, and maps the hint itself).
    let hint = format!("raise it with {}", sl_io::limits::BUDGET_OPTION);
    SlDepthIOError::new_err(e.to_string().replace(
        &hint,
        "a limit of the default 4 GiB memory budget, which `sldepth --max-memory` raises",
    ))
}

/// Registers the exception types on the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SlDepthError", m.py().get_type::<SlDepthError>())?;
    m.add("SlDepthIOError", m.py().get_type::<SlDepthIOError>())?;
    Ok(())
}
