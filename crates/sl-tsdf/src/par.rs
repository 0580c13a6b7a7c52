//! Fork-join on scoped OS threads, for the few long parallel phases of a frame.

use std::sync::Mutex;

/// Runs `f` on every item on `rayon::current_num_threads()` threads — the calling thread and
/// scoped OS threads started for the call — which take the items one at a time from a shared
/// queue; each thread has its own state from `init`. The results come back in item order, so
/// the output does not depend on the number of threads.
///
/// Used for the parallel phases of integration and marching cubes instead of rayon's pool:
/// rayon's idle workers spin with `yield_now` before they sleep, and on a loaded machine a
/// worker that yielded can be away for a whole time slice while a phase of a few milliseconds
/// runs on the other thread alone; a freshly started thread, like a woken one, gets a
/// processor promptly. Starting the threads costs tens of microseconds per phase.
pub(crate) fn run_on_threads<S, I: Send, R: Send>(
    items: Vec<I>,
    init: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, I) -> R + Sync,
) -> Vec<R> {
    let n = items.len();
    let queue = Mutex::new(items.into_iter().enumerate());
    let work = || {
        let mut state = init();
        let mut out = Vec::new();
        loop {
            // A panic in `f` on another thread poisons nothing we rely on: take the queue.
            let next = queue.lock().unwrap_or_else(|e| e.into_inner()).next();
            match next {
                Some((i, item)) => out.push((i, f(&mut state, item))),
                None => return out,
            }
        }
    };
    let threads = rayon::current_num_threads().clamp(1, n.max(1));
    let parts = std::thread::scope(|s| {
        // If the system refuses a thread, the others (at least this one) do its share.
        let helpers: Vec<_> = (1..threads)
            .filter_map(|_| std::thread::Builder::new().spawn_scoped(s, work).ok())
            .collect();
        let mut parts = vec![work()];
        for h in helpers {
            parts.push(h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)));
        }
        parts
    });
    let mut all: Vec<(usize, R)> = parts.into_iter().flatten().collect();
    all.sort_unstable_by_key(|&(i, _)| i);
    all.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_in_item_order_with_any_thread_count() {
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| e.to_string());
            let Ok(pool) = pool else {
                continue;
            };
            let out = pool.install(|| {
                run_on_threads(
                    (0..1000u64).collect(),
                    || 0u64,
                    |calls, i| {
                        *calls += 1;
                        i * i
                    },
                )
            });
            assert_eq!(out, (0..1000u64).map(|i| i * i).collect::<Vec<_>>());
        }
        assert!(run_on_threads(Vec::<u8>::new(), || (), |_, i| i).is_empty());
    }
}
