//! The one parallelism policy, seen from Python: every computation releases the GIL and runs
//! on one rayon pool — the global pool, or the pool `set_num_threads(n)` made.

use std::sync::{Arc, Mutex, PoisonError};

use pyo3::prelude::*;

use crate::errors::value_error;

/// The pool chosen by `set_num_threads`, or `None` for rayon's global pool (one thread per
/// core).
static POOL: Mutex<Option<Arc<rayon::ThreadPool>>> = Mutex::new(None);

/// Stack of the pool threads, bytes: every call runs on one of them (see [`compute`]), so it
/// gets the 8 MiB of a Python thread on Linux rather than a spawned thread's default 2 MiB.
const WORKER_STACK_BYTES: usize = 8 << 20;

/// Builds rayon's global pool with [`WORKER_STACK_BYTES`] stacks (at import; a no-op when it
/// exists).
pub(crate) fn init_global_pool() {
    let _ = rayon::ThreadPoolBuilder::new()
        .stack_size(WORKER_STACK_BYTES)
        .thread_name(|i| format!("sldepth-{i}"))
        .build_global();
}

fn current_pool() -> Option<Arc<rayon::ThreadPool>> {
    POOL.lock().unwrap_or_else(PoisonError::into_inner).clone()
}

/// Runs `f` with the GIL released, on a worker thread of the chosen rayon pool. Run on the
/// calling (Python) thread instead, every parallel phase of `f` would queue its work for the pool
/// and put the Python thread to sleep until a worker is done: a sleep and a wake-up per phase,
/// about forty per tracking step (the same measurement as the CLI's, docs/bench/track.md
/// "Session 21").
pub(crate) fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> T {
    let pool = current_pool();
    py.detach(move || match pool {
        Some(p) => p.install(f),
        None => rayon::scope(|_| f()),
    })
}

/// Sets how many threads sldepth's computations use (``n >= 1``); ``None`` or ``0`` returns to
/// one thread per core. Affects calls started after it returns.
#[pyfunction]
#[pyo3(signature = (n = None))]
pub(crate) fn set_num_threads(n: Option<usize>) -> PyResult<()> {
    let pool = match n {
        None | Some(0) => None,
        Some(n) if n > 1024 => return Err(value_error(format!("{n} threads is too many"))),
        Some(n) => Some(Arc::new(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .stack_size(WORKER_STACK_BYTES)
                .thread_name(|i| format!("sldepth-{i}"))
                .build()
                .map_err(value_error)?,
        )),
    };
    *POOL.lock().unwrap_or_else(PoisonError::into_inner) = pool;
    Ok(())
}

/// The number of threads sldepth's computations use now.
#[pyfunction]
pub(crate) fn get_num_threads() -> usize {
    current_pool().map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
}
