//! Data-parallel map on the caller's rayon pool, for the few long parallel phases of a frame
//! (block discovery and voxel updates of integration, the passes of marching cubes).

use rayon::prelude::*;

/// Runs `f` on every item on the current rayon pool — the global pool, or the one the caller
/// chose with `ThreadPool::install`, so a program embedding the library (or Python through
/// `sldepth.set_num_threads`) bounds the threads and several callers share one set of them.
/// Each rayon task has its own state from `init` (scratch buffers reused across the items it
/// takes). The results come back in item order, so the output does not depend on the number of
/// threads.
pub(crate) fn run_on_threads<S, I: Send, R: Send>(
    items: Vec<I>,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, I) -> R + Sync + Send,
) -> Vec<R> {
    items
        .into_par_iter()
        .with_max_len(1)
        .map_init(init, |state, item| f(state, item))
        .collect()
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

    #[test]
    fn runs_on_the_callers_pool() {
        let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(3).build() else {
            return;
        };
        let ids = pool.install(|| {
            run_on_threads(
                (0..64).collect(),
                || (),
                |_, _: i32| rayon::current_thread_index(),
            )
        });
        // Every item ran on one of the pool's three workers.
        assert!(ids.iter().all(|i| matches!(i, Some(0..=2))), "{ids:?}");
    }
}
