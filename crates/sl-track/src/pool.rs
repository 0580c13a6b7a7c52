//! Where a frame's work runs: on a worker thread of the caller's rayon pool.

/// Runs `f` on a worker thread of the caller's rayon pool: in place when called from one
/// (inside `ThreadPool::install`, or from the `sldepth` CLI and the Python bindings, which run
/// every command there), otherwise on a worker of rayon's global pool while the calling thread
/// waits, once.
///
/// Why: a parallel phase (`par_iter`, `join`) started from a thread outside the pool queues its
/// work for the pool and puts the calling thread to sleep until a worker has done it; started
/// on a worker it splits on the spot. A tracking step has about forty such phases (the pyramid,
/// each pass of the alignment, the fusion, the raycast). On a 2-core Intel Xeon VM (TUM fr1/rpy
/// 200) a step took 33 ms from the main thread and 28 ms from a worker, with 160,000 against
/// 13,000 context switches over the sequence and the same trajectory bit for bit
/// (docs/bench/track.md, "Session 21").
pub(crate) fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn runs_on_a_worker_of_the_callers_pool() {
        // From a thread outside every pool: on a worker of the global pool.
        let outside = std::thread::spawn(|| {
            assert!(rayon::current_thread_index().is_none());
            on_pool(rayon::current_thread_index)
        })
        .join()
        .unwrap();
        assert!(outside.is_some());
        // Inside a pool the caller chose: on that pool, on the caller's own worker.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let (caller, ran_on, threads) = pool.install(|| {
            let caller = rayon::current_thread_index();
            (
                caller,
                on_pool(rayon::current_thread_index),
                on_pool(rayon::current_num_threads),
            )
        });
        assert_eq!(ran_on, caller);
        assert_eq!(threads, 3);
    }
}
