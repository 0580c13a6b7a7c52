//! The one parallelism policy, seen from Python: every computation releases the GIL and runs
//! on the rayon pool `set_num_threads(n)` chose — sldepth's default pool (one thread per core),
//! a shared pool of `n` threads, or, for `n = 1`, the calling thread itself.

use std::cell::OnceCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use pyo3::prelude::*;

use crate::errors::value_error;

/// What `set_num_threads` chose.
#[derive(Clone)]
enum Threads {
    /// [`default_pool`]: one thread per core.
    Default,
    /// One thread: the calling thread ([`solo_pool`]).
    One,
    /// A pool of two or more threads shared by every calling thread.
    Shared(Arc<rayon::ThreadPool>),
}

static THREADS: Mutex<Threads> = Mutex::new(Threads::Default);

/// Stack of the pool threads, bytes: every call runs on one of them (see [`compute`]), so it
/// gets the 8 MiB of a Python thread on Linux rather than a spawned thread's default 2 MiB.
const WORKER_STACK_BYTES: usize = 8 << 20;

fn build_pool(n: usize) -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .stack_size(WORKER_STACK_BYTES)
        .thread_name(|i| format!("sldepth-{i}"))
        .build()
}

/// sldepth's default pool, one thread per core, built at import (`None` only when no thread
/// can start). It is a pool of its own rather than rayon's global pool: a Python thread that has computed with `set_num_threads(1)` is a
/// member of its own one-thread pool ([`solo_pool`]), and rayon would run "the global pool's"
/// work there, on that one thread; an explicit pool is reached the same way from every thread.
fn default_pool() -> Option<Arc<rayon::ThreadPool>> {
    static POOL: OnceLock<Option<Arc<rayon::ThreadPool>>> = OnceLock::new();
    POOL.get_or_init(|| {
        let n = std::thread::available_parallelism().map_or(1, |n| n.get());
        build_pool(n).or_else(|_| build_pool(1)).ok().map(Arc::new)
    })
    .clone()
}

/// Builds the default pool (at import), so the first call does not pay for starting threads.
pub(crate) fn init_default_pool() {
    let _ = default_pool();
}

/// At most this many threads get a pool of their own ([`SOLO`]); later ones share one
/// one-thread pool and pay its hop. Each such pool outlives its thread (about 8 KB measured), so
/// a program that starts a new thread for every call would otherwise grow without bound.
const MAX_SOLO_POOLS: usize = 256;

static SOLO_POOLS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// The calling thread's own pool of one thread, in which it is the only worker: a call
    /// installed there runs in place, with no hop to another thread and back (a wake-up costs
    /// 20–90 µs in a VM, 3–8 % of a 640×480 plane extraction; docs/bench/README.md "Session
    /// 26"). `None` when the thread could not join one (it is a worker of another pool already,
    /// or [`MAX_SOLO_POOLS`] threads have one).
    /// Built once per thread and kept: rayon cannot take a thread out of a pool it joined, so the
    /// pool (a few kilobytes, no thread of its own) is never freed, even when its thread ends;
    /// hence [`MAX_SOLO_POOLS`].
    ///
    /// Borrowed only to clone the `Arc` out (tidy rule on `thread_local!`): no borrow is held
    /// while the call computes.
    static SOLO: OnceCell<Option<Arc<rayon::ThreadPool>>> = const { OnceCell::new() };
}

/// The calling thread's pool of one thread ([`SOLO`]), or a shared one-thread pool when the
/// thread cannot have its own (`None` if not even that can start).
fn solo_pool() -> Option<Arc<rayon::ThreadPool>> {
    let own = SOLO.with(|cell| {
        cell.get_or_init(|| {
            (SOLO_POOLS.fetch_add(1, Ordering::Relaxed) < MAX_SOLO_POOLS)
                .then(|| {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(1)
                        .use_current_thread()
                        .build()
                        .ok()
                        .map(Arc::new)
                })
                .flatten()
        })
        .clone()
    });
    own.or_else(|| {
        static FALLBACK: OnceLock<Option<Arc<rayon::ThreadPool>>> = OnceLock::new();
        FALLBACK
            .get_or_init(|| build_pool(1).ok().map(Arc::new))
            .clone()
    })
}

fn chosen() -> Threads {
    THREADS
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone()
}

/// Runs `f` with the GIL released, on a worker thread of the chosen pool. Run on the calling
/// (Python) thread outside a pool, every parallel phase of `f` would queue its work for the pool
/// and put the Python thread to sleep until a worker is done: a sleep and a wake-up per phase,
/// about forty per tracking step (the same measurement as the CLI's, docs/bench/track.md
/// "Session 21"). With one thread, the calling thread is that worker ([`solo_pool`]): `f` runs
/// in place, and calls from several Python threads run side by side, one thread each.
pub(crate) fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> T {
    let threads = chosen();
    py.detach(move || {
        let pool = match threads {
            Threads::Default => default_pool(),
            Threads::One => solo_pool(),
            Threads::Shared(p) => Some(p),
        };
        // No pool only when the process cannot start a thread: compute in place.
        match pool {
            Some(p) => p.install(f),
            None => f(),
        }
    })
}

/// Sets how many threads each sldepth computation uses (``n >= 1``); ``None`` or ``0`` returns
/// to one thread per core. With ``n >= 2`` the calls of every Python thread share one pool of
/// ``n`` threads; with ``n = 1`` every call runs on the thread that makes it, so calls from
/// several Python threads run side by side (as NumPy's and OpenCV's do with one thread).
/// Affects calls started after it returns.
#[pyfunction]
#[pyo3(signature = (n = None))]
pub(crate) fn set_num_threads(n: Option<usize>) -> PyResult<()> {
    let threads = match n {
        None | Some(0) => Threads::Default,
        Some(1) => Threads::One,
        Some(n) if n > 1024 => return Err(value_error(format!("{n} threads is too many"))),
        Some(n) => Threads::Shared(Arc::new(build_pool(n).map_err(value_error)?)),
    };
    *THREADS.lock().unwrap_or_else(PoisonError::into_inner) = threads;
    Ok(())
}

/// The number of threads each sldepth computation uses now.
#[pyfunction]
pub(crate) fn get_num_threads() -> usize {
    match chosen() {
        Threads::Default => default_pool().map_or(1, |p| p.current_num_threads()),
        Threads::One => 1,
        Threads::Shared(p) => p.current_num_threads(),
    }
}

/// The name of the thread a computation runs on (``None`` for an unnamed thread): the pool's
/// workers are named ``sldepth-<i>``; with ``set_num_threads(1)`` it is the calling thread. For
/// the test suite.
#[pyfunction]
#[pyo3(name = "_compute_thread_name")]
pub(crate) fn compute_thread_name(py: Python<'_>) -> Option<String> {
    compute(py, || std::thread::current().name().map(str::to_owned))
}
