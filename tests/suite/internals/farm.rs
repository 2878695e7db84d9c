//! Unit tests of `farm` (src/farm/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::farm::*;

#[test]
fn a_panicking_task_is_an_error_not_a_hang() {
    for threads in [1, 2] {
        let tasks: Vec<u64> = (0..6).collect();
        let work = |t: &u64| -> u64 {
            assert!(*t != 3, "task three fails");
            *t
        };
        let e = map(&Workers::local(threads), tasks, &work).unwrap_err();
        assert!(
            matches!(&e, FarmError::Panicked(m) if m.contains("task three fails")),
            "{e}"
        );
    }
}

#[test]
fn map_returns_results_in_task_order_for_any_thread_count() {
    let tasks: Vec<u64> = (0..50).collect();
    // Uneven task costs so that results arrive out of order.
    let work = |x: &u64| {
        std::thread::sleep(std::time::Duration::from_micros((50 - x) * 20));
        x * x
    };
    for threads in [1, 2, 4] {
        let out = map(&Workers::local(threads), tasks.clone(), &work).unwrap();
        assert_eq!(out, tasks.iter().map(|x| x * x).collect::<Vec<_>>());
    }
}

/// A dispatcher that never starts anything and never finishes is reported, not hung.
struct Stuck;
impl Dispatcher for Stuck {
    type Task = u8;
    type Output = u8;
    fn next_task(&mut self) -> Option<u8> {
        None
    }
    fn complete(&mut self, _: u8, _: u8) {}
    fn finished(&self) -> bool {
        false
    }
}

#[test]
fn a_stalled_dispatcher_is_an_error() {
    let r = Workers::local(2).run(&mut Stuck, &|x: &u8| *x);
    assert!(matches!(r, Err(FarmError::Stalled)), "{r:?}");
}

#[test]
fn map_local_returns_results_in_task_order_for_any_thread_count() {
    let tasks: Vec<u64> = (0..50).collect();
    // Uneven task costs so that the threads finish their tasks out of order.
    let work = |x: &u64| {
        std::thread::sleep(std::time::Duration::from_micros((50 - x) * 20));
        x * x
    };
    let squares: Vec<u64> = tasks.iter().map(|x| x * x).collect();
    for threads in [1, 2, 4, 64] {
        assert_eq!(map_local(threads, &tasks, &work).unwrap(), squares);
    }
    assert!(map_local(2, &[] as &[u64], &work).unwrap().is_empty());
}

#[test]
fn map_local_runs_on_the_calling_thread_alone_for_one_thread() {
    // One thread: no worker is spawned, so a task sees the caller's thread.
    let caller = std::thread::current().id();
    let tasks = [0u8; 4];
    let ids = map_local(1, &tasks, &|_| std::thread::current().id()).unwrap();
    assert!(
        ids.iter().all(|id| *id == caller),
        "{ids:?} against {caller:?}"
    );
}

#[test]
fn map_local_a_panicking_task_is_an_error_not_a_hang() {
    for threads in [1, 2] {
        let tasks: Vec<u64> = (0..6).collect();
        let work = |t: &u64| -> u64 {
            assert!(*t != 3, "task three fails");
            *t
        };
        let e = map_local(threads, &tasks, &work).unwrap_err();
        assert!(
            matches!(&e, FarmError::Panicked(m) if m.contains("task three fails")),
            "{e}"
        );
    }
}
