//! The worker pool through a frame made of many short parallel steps.
//!
//! A reused frame is a chain of parallel steps of 0.1-2 ms each (mapping,
//! tracing, keeping, assembling, gathering, OSTC's bookkeeping), with a
//! little serial work between them. Rayon's idle workers go to sleep
//! within microseconds, and waking one costs a good part of a short step:
//! every step would start on one thread and the others join late. Keeping
//! the other workers looking for work until the frame is done lets each
//! step start on all of them at once.

use std::sync::atomic::{AtomicBool, Ordering};

/// Runs `work` on this thread while every other worker of the current
/// pool keeps looking for jobs (yielding its core to any other thread
/// that wants it), until `work` returns or panics.
pub fn with_workers_awake<R>(work: impl FnOnce() -> R) -> R {
    let done = AtomicBool::new(false);
    let caller = rayon::current_thread_index();
    rayon::in_place_scope(|scope| {
        for _ in 1..rayon::current_num_threads() {
            scope.spawn(|_| {
                // Should the caller take its own spawn while it waits for
                // a step (rayon does not promise the order in which
                // workers take jobs), looking for work there it would
                // never return to finish `work`.
                if rayon::current_thread_index() == caller {
                    return;
                }
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        std::thread::yield_now();
                    }
                }
            });
        }
        // Set on unwinding too: the scope waits for its spawns before it
        // passes a panic on.
        let _finish = Finish(&done);
        work()
    })
}

struct Finish<'a>(&'a AtomicBool);

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a pool")
    }

    /// Many short parallel steps, as a frame makes them.
    fn steps() -> u64 {
        (0..200u64)
            .map(|step| (0..1000u64).into_par_iter().map(|i| i * step).sum::<u64>())
            .sum()
    }

    #[test]
    fn work_runs_to_its_result_from_inside_and_outside_a_pool() {
        let expected = steps();
        for threads in [1, 2, 4] {
            let pool = pool(threads);
            // On one of the pool's workers, as the command line runs.
            let inside = pool.install(|| with_workers_awake(steps));
            assert_eq!(inside, expected, "{threads} threads, inside");
            // Nested, and from a thread outside any pool (a test's own).
            let nested = pool.install(|| with_workers_awake(|| with_workers_awake(steps)));
            assert_eq!(nested, expected, "{threads} threads, nested");
            assert_eq!(with_workers_awake(steps), expected, "outside");
        }
    }

    #[test]
    fn a_panic_in_the_work_reaches_the_caller() {
        let pool = pool(2);
        let caught = pool.install(|| {
            std::panic::catch_unwind(|| {
                with_workers_awake(|| {
                    steps();
                    panic!("in the frame")
                })
            })
        });
        assert!(caught.is_err());
        // The workers were let go: the pool still runs work.
        assert_eq!(pool.install(steps), steps());
    }
}
