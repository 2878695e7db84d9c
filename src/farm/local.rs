//! A list of independent tasks on this process's threads, borrowed rather than handed
//! over ([`map_local`]): the calling thread is one of the workers and each worker
//! claims the next task by one atomic increment, so a task costs no copy, no channel
//! and no thread wake-up. [`super::map`]'s coordinator wakes twice per task (the worker
//! for the task, itself for the result): at issue 37's 2 048 resumed subgrid boxes of
//! about 0.7 ms each that hand-over was most of the coupling's share of the step.
//! Under MPI tasks must travel as bytes: [`super::map`] then.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use super::{FarmError, panic_message, thread_count};

/// Run `work` on every task of `tasks` on `threads` threads of this process (0: one per
/// core; never more than there are tasks), the calling thread among them; results in
/// task order, the same whatever the thread count when `work` depends on its task
/// alone. Tasks are claimed one at a time in list order, so uneven tasks still keep
/// every thread busy to the end. A task that panics stops the claiming of new tasks
/// and is the batch's error ([`FarmError::Panicked`]).
pub fn map_local<T: Sync, O: Send>(
    threads: usize,
    tasks: &[T],
    work: &(dyn Fn(&T) -> O + Sync),
) -> Result<Vec<O>, FarmError> {
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let panicked: Mutex<Option<String>> = Mutex::new(None);
    // One worker's loop: its results with their indices.
    let worker = || {
        let mut done = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(task) = tasks.get(i) else { break };
            match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(task))) {
                Ok(output) => done.push((i, output)),
                Err(payload) => {
                    stop.store(true, Ordering::Relaxed);
                    let mut first = panicked.lock().unwrap_or_else(|p| p.into_inner());
                    first.get_or_insert_with(|| panic_message(payload.as_ref()));
                    break;
                }
            }
        }
        done
    };
    let threads = thread_count(threads).clamp(1, tasks.len().max(1));
    let parts = std::thread::scope(|scope| {
        let spawned: Vec<_> = (1..threads)
            .map(|_| {
                std::thread::Builder::new()
                    .spawn_scoped(scope, worker)
                    .map_err(|e| FarmError::Pool(e.to_string()))
            })
            .collect();
        // The calling thread works too (alone for one thread).
        let mut parts = vec![Ok(worker())];
        for handle in spawned {
            // A worker's own panics are caught per task, so joining cannot fail.
            parts.push(handle.and_then(|h| {
                h.join()
                    .map_err(|p| FarmError::Panicked(panic_message(p.as_ref())))
            }));
        }
        parts
    })
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    if let Some(message) = panicked.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(FarmError::Panicked(message));
    }
    let mut results: Vec<Option<O>> = tasks.iter().map(|_| None).collect();
    for (i, output) in parts.into_iter().flatten() {
        results[i] = Some(output);
    }
    // Every index below the list's length was claimed and, without a panic, done.
    results
        .into_iter()
        .map(|o| o.ok_or(FarmError::Stalled))
        .collect()
}
