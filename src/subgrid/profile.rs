//! Where a macro step's time goes (issue 37's cost goal: lifting, adjusting,
//! restriction and coupling within 10 % of the boxes' own run time).
//!
//! Every part of a box's step adds the CPU time its thread spent in it to a
//! process-wide counter ([`Part`]); `benches/subgrid.rs` resets them, runs a macro step
//! and reads them against the process's CPU time ([`process_cpu_seconds`]). CPU time,
//! not wall time: on a machine shared with other jobs a preempted part would otherwise
//! be charged for the others' work. Reading the clock twice per part costs well under a
//! microsecond against milliseconds per box, and nothing a box computes depends on it.

use std::sync::atomic::{AtomicU64, Ordering};

/// A part of a box's macro step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Drawing a fresh box from the cell's classes (lift.rs).
    Lift,
    /// Adjusting a kept box to what transport changed (adjust.rs).
    Adjust,
    /// Reading a kept box back: its snapshot decoded, its scene's settings made.
    Restore,
    /// Assembling the box's simulation: the scene checked, its bodies spawned, the
    /// plugins' resources and systems added (`plugins::builder`).
    Build,
    /// Finishing it (`SimBuilder::build`: the pipeline's access checks and the
    /// schedule's initialisation, and the event core's first prediction of every body
    /// — about 90 % of this part for a lifted P04 box under callgrind, and what a
    /// direct run of the box does first) and, for a kept box, resuming its snapshot
    /// (its bodies spawned, the core rebuilt from them).
    Calendar,
    /// The box's own run over Δt (the event or time-step core).
    Run,
    /// Restriction: the class sums before and after, the replicas' means and SEs.
    Restrict,
    /// Keeping a box for the next step: its snapshot captured and encoded.
    Keep,
}

impl Part {
    /// Every part, in the order of a step.
    pub const ALL: [Part; 8] = [
        Part::Lift,
        Part::Adjust,
        Part::Restore,
        Part::Build,
        Part::Calendar,
        Part::Run,
        Part::Restrict,
        Part::Keep,
    ];

    /// The part's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Part::Lift => "lift",
            Part::Adjust => "adjust",
            Part::Restore => "restore",
            Part::Build => "build",
            Part::Calendar => "calendar",
            Part::Run => "run",
            Part::Restrict => "restrict",
            Part::Keep => "keep",
        }
    }
}

static NANOS: [AtomicU64; 8] = [const { AtomicU64::new(0) }; 8];

/// A CPU clock [ns]: `CLOCK_THREAD_CPUTIME_ID` or `CLOCK_PROCESS_CPUTIME_ID`.
fn cpu_nanos(clock: libc::clockid_t) -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec to write; the clock ids are POSIX's.
    let ok = unsafe { libc::clock_gettime(clock, &mut t) } == 0;
    if !ok {
        return 0;
    }
    (t.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(t.tv_nsec as u64)
}

/// This thread's CPU time [ns], where a part starts.
pub(crate) fn start() -> u64 {
    cpu_nanos(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// Add this thread's CPU time since `start` ([`start`]) to `part`.
pub(crate) fn add(part: Part, start: u64) {
    let ns = cpu_nanos(libc::CLOCK_THREAD_CPUTIME_ID).saturating_sub(start);
    NANOS[part as usize].fetch_add(ns, Ordering::Relaxed);
}

/// Run `f`, adding its CPU time to `part`.
pub(crate) fn timed<T>(part: Part, f: impl FnOnce() -> T) -> T {
    let begun = start();
    let out = f();
    add(part, begun);
    out
}

/// The CPU time the process has used [s], all threads.
pub fn process_cpu_seconds() -> f64 {
    cpu_nanos(libc::CLOCK_PROCESS_CPUTIME_ID) as f64 * 1e-9
}

/// Set every counter to 0.
pub fn reset() {
    for n in &NANOS {
        n.store(0, Ordering::Relaxed);
    }
}

/// CPU seconds spent in each part since the last [`reset`], summed over threads, in
/// the order of [`Part::ALL`].
pub fn seconds() -> [(Part, f64); 8] {
    Part::ALL.map(|p| (p, NANOS[p as usize].load(Ordering::Relaxed) as f64 * 1e-9))
}
