//! The one parallelism policy, seen from Python: every computation releases the GIL and runs
//! on a rayon pool of the size `set_num_threads(n)` chose (one thread per core by default). The
//! calling thread is itself a worker of that pool ([`own_pool`]), so a call runs in place; only
//! when it cannot be does the call go to a shared pool of the same size ([`Threads`]).

use std::cell::OnceCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError, RwLock};

use pyo3::prelude::*;

use crate::errors::value_error;

/// What `set_num_threads` chose.
#[derive(Clone)]
enum Threads {
    /// One thread per core; the shared pool is [`default_pool`].
    Default,
    /// This many threads; the shared pool of that size, built by the first call that needs it
    /// (most callers compute in their own pool and never do).
    Count(usize, Arc<OnceLock<Option<Arc<rayon::ThreadPool>>>>),
}

impl Threads {
    fn count(&self) -> usize {
        match self {
            Threads::Default => cores(),
            Threads::Count(n, _) => *n,
        }
    }

    /// The shared pool of this size (`None` only when no thread can start).
    fn shared_pool(&self) -> Option<Arc<rayon::ThreadPool>> {
        match self {
            Threads::Default => default_pool(),
            Threads::Count(n, pool) => pool
                .get_or_init(|| build_pool(*n).ok().map(Arc::new))
                .clone(),
        }
    }
}

static THREADS: Mutex<Threads> = Mutex::new(Threads::Default);

/// Stack of the pool threads, bytes: every call runs on one of them (see [`compute`]), so it
/// gets the 8 MiB of a Python thread on Linux rather than a spawned thread's default 2 MiB.
const WORKER_STACK_BYTES: usize = 8 << 20;

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

fn build_pool(n: usize) -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .stack_size(WORKER_STACK_BYTES)
        .thread_name(|i| format!("sldepth-{i}"))
        .build()
}

/// The shared pool of one thread per core (`None` only when no thread can start). It is a pool
/// of sldepth's own rather than rayon's global pool: a Python thread that is a worker of its
/// own pool ([`own_pool`]) would run "the global pool's" work there, at that pool's size.
fn default_pool() -> Option<Arc<rayon::ThreadPool>> {
    static POOL: OnceLock<Option<Arc<rayon::ThreadPool>>> = OnceLock::new();
    POOL.get_or_init(|| {
        build_pool(cores())
            .or_else(|_| build_pool(1))
            .ok()
            .map(Arc::new)
    })
    .clone()
}

/// At most this many threads ever get a pool of their own ([`OWN`]); later ones use the shared
/// pools and pay their hop. Rayon never frees a pool a thread joined (about 8 KB measured, its
/// spawned workers do end with the thread), so a program that starts a new thread for every
/// call would otherwise grow without bound.
const MAX_OWN_POOLS: usize = 256;

static OWN_POOLS: AtomicUsize = AtomicUsize::new(0);

/// Live spawned workers of all own pools (each has `n - 1`, the caller being the n-th).
static OWN_WORKERS: AtomicUsize = AtomicUsize::new(0);

/// At most this many spawned workers of own pools live at once (eight per core): many Python
/// threads that each compute with every core fall back to the shared pools past it, instead of
/// starting threads without bound.
fn max_own_workers() -> usize {
    8 * cores()
}

thread_local! {
    /// The calling thread's own pool, in which it is worker 0 and which has as many threads as
    /// were chosen at the thread's first call: a call installed there runs in place, with no
    /// hop to another thread and back (a wake-up costs 20–90 µs in a VM, 3–8 % of a 640×480
    /// plane extraction; docs/bench/README.md "Session 26" and "Session 27"). `None` when the
    /// thread could not join one (it is a worker of another pool already, or the caps are
    /// reached). A thread can join one pool only, ever: rayon cannot take it out again, so the
    /// pool's registry is never freed ([`MAX_OWN_POOLS`]); its spawned workers end with the
    /// thread, when this `Arc` drops.
    ///
    /// Borrowed only to clone the `Arc` out (tidy rule on `thread_local!`): no borrow is held
    /// while the call computes.
    static OWN: OnceCell<Option<Arc<rayon::ThreadPool>>> = const { OnceCell::new() };
}

/// A pool of `n` threads whose worker 0 is the calling thread, or `None` (see [`OWN`]).
fn build_own_pool(n: usize) -> Option<Arc<rayon::ThreadPool>> {
    if OWN_POOLS.fetch_add(1, Ordering::Relaxed) >= MAX_OWN_POOLS {
        return None;
    }
    let spawned = n - 1;
    if OWN_WORKERS.fetch_add(spawned, Ordering::Relaxed) + spawned > max_own_workers() {
        OWN_WORKERS.fetch_sub(spawned, Ordering::Relaxed);
        return None;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .use_current_thread()
        .stack_size(WORKER_STACK_BYTES)
        .thread_name(|i| format!("sldepth-own-{i}"))
        .exit_handler(|_| {
            OWN_WORKERS.fetch_sub(1, Ordering::Relaxed);
        })
        .build();
    match pool {
        Ok(p) => Some(Arc::new(p)),
        Err(_) => {
            OWN_WORKERS.fetch_sub(spawned, Ordering::Relaxed);
            None
        }
    }
}

/// The calling thread's own pool ([`OWN`]) when it has `n` threads.
fn own_pool(n: usize) -> Option<Arc<rayon::ThreadPool>> {
    OWN.with(|cell| cell.get_or_init(|| build_own_pool(n)).clone())
        .filter(|p| p.current_num_threads() == n)
}

fn chosen() -> Threads {
    THREADS
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone()
}

/// Runs `f` with the GIL released, on a worker thread of a pool of the chosen size. Run on the
/// calling (Python) thread outside a pool, every parallel phase of `f` would queue its work for
/// the pool and put the Python thread to sleep until a worker is done: a sleep and a wake-up per
/// phase, about forty per tracking step (the same measurement as the CLI's,
/// docs/bench/track.md "Session 21"). The calling thread is worker 0 of its own pool
/// ([`own_pool`]) when it can be: `f` then runs in place, and calls from several Python threads
/// run side by side, each with its own workers, as OpenMP gives each thread its own team.
/// Otherwise `f` goes to the shared pool of that size and the caller waits: one hop there and
/// back.
pub(crate) fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> T {
    let threads = chosen();
    py.detach(move || install(&threads, f))
}

/// Runs `f` on a pool of the size `threads` says: the calling thread's own pool when it can,
/// else the shared pool of that size (see [`compute`]).
fn install<T: Send>(threads: &Threads, f: impl FnOnce() -> T + Send) -> T {
    let pool = own_pool(threads.count()).or_else(|| threads.shared_pool());
    // No pool only when the process cannot start a thread: compute in place.
    match pool {
        Some(p) => p.install(f),
        None => f(),
    }
}

/// A lock whose holder panicked: the object it guards may be half-updated.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Poisoned;

/// [`compute`] on the value behind `lock`, taken by the calling thread (with the GIL released)
/// **before** the computation enters a pool, and released after it returns. Taking it inside
/// the pool could deadlock: a worker that waits for its parallel pieces runs other queued jobs
/// of its pool meanwhile, and a job of another Python thread's call on the same object would
/// then wait for a lock its own thread holds, for ever (several Python threads sharing one
/// `TsdfVolume` or `Tracker` through a shared pool). Outside the pools a caller only ever waits
/// for a lock held by another thread, which finishes its call without it.
pub(crate) fn compute_locked<S: Send, T: Send>(
    py: Python<'_>,
    lock: &Mutex<S>,
    f: impl FnOnce(&mut S) -> T + Send,
) -> Result<T, Poisoned> {
    let threads = chosen();
    py.detach(move || {
        let mut guard = lock.lock().map_err(|_| Poisoned)?;
        let state: &mut S = &mut guard;
        Ok(install(&threads, move || f(state)))
    })
}

/// [`compute_locked`] for a read-write lock taken for writing.
pub(crate) fn compute_write<S: Send + Sync, T: Send>(
    py: Python<'_>,
    lock: &RwLock<S>,
    f: impl FnOnce(&mut S) -> T + Send,
) -> Result<T, Poisoned> {
    let threads = chosen();
    py.detach(move || {
        let mut guard = lock.write().map_err(|_| Poisoned)?;
        let state: &mut S = &mut guard;
        Ok(install(&threads, move || f(state)))
    })
}

/// [`compute_locked`] for a read-write lock taken for reading (readers run side by side).
pub(crate) fn compute_read<S: Send + Sync, T: Send>(
    py: Python<'_>,
    lock: &RwLock<S>,
    f: impl FnOnce(&S) -> T + Send,
) -> Result<T, Poisoned> {
    let threads = chosen();
    py.detach(move || {
        let guard = lock.read().map_err(|_| Poisoned)?;
        let state: &S = &guard;
        Ok(install(&threads, move || f(state)))
    })
}

/// Sets how many threads each sldepth computation uses (``n >= 1``); ``None`` or ``0`` returns
/// to one thread per core. A Python thread computes as the first worker of a pool of its own,
/// sized by the count in force at its first call, so calls run in place and calls from several
/// Python threads run side by side; a call with another count than that goes through a shared
/// pool of that count (correct, a few percent slower per call). Affects calls started after it
/// returns. Calls on one ``TsdfVolume`` or ``Tracker`` from several threads take turns (a
/// volume's meshes, raycasts and slices run side by side).
#[pyfunction]
#[pyo3(signature = (n = None))]
pub(crate) fn set_num_threads(
    #[pyo3(from_py_with = crate::ints::opt_int)] n: Option<usize>,
) -> PyResult<()> {
    let threads = match n {
        None | Some(0) => Threads::Default,
        Some(n) if n > 1024 => return Err(value_error(format!("{n} threads is too many"))),
        Some(n) => Threads::Count(n, Arc::default()),
    };
    *THREADS.lock().unwrap_or_else(PoisonError::into_inner) = threads;
    Ok(())
}

/// The number of threads each sldepth computation uses now.
#[pyfunction]
pub(crate) fn get_num_threads() -> usize {
    chosen().count()
}

/// The name of the thread a computation runs on (``None`` for an unnamed thread): in place it is
/// the calling thread; the shared pools' workers are named ``sldepth-<i>``. For the test suite.
#[pyfunction]
#[pyo3(name = "_compute_thread_name")]
pub(crate) fn compute_thread_name(py: Python<'_>) -> Option<String> {
    compute(py, || std::thread::current().name().map(str::to_owned))
}
