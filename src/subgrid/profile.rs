//! Where a macro step's time goes (issue 37's cost goal: lifting, adjusting,
//! restriction and coupling within 10 % of the boxes' own run time).
//!
//! Once [`enable`]d, every part of a box's step adds the CPU time its thread spent in it
//! to a process-wide counter ([`Part`]); `benches/subgrid.rs` resets them, runs a macro
//! step and reads them against the process's CPU time ([`process_cpu_seconds`]). CPU time,
//! not wall time: on a machine shared with other jobs a preempted part would otherwise
//! be charged for the others' work. A part timed inside another is counted once, in the
//! inner part. What no part covers is the task farm's own cost (handing tasks to the
//! worker threads and results back). Nothing a box computes depends on the clock; a
//! box's parts are timed as laps of one stopwatch ([`Lap`]), one clock reading per part.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The number of parts ([`Part::ALL`]).
pub const COUNT: usize = 10;

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
    /// plugins' resources and systems added (`plugins::builder`, inside `Run`'s start).
    Build,
    /// Finishing it (`SimBuilder::build`: the pipeline's access checks and the
    /// schedule's initialisation, and the event core's first prediction of every body
    /// — about 90 % of this part for a lifted P04 box under callgrind, and what a
    /// direct run of the box does first) and, for a kept box, resuming its snapshot
    /// (its bodies spawned, the core rebuilt from them).
    Calendar,
    /// The box's own run over Δt (the event or time-step core), and `Run::finish`.
    Run,
    /// Restriction: the class sums before and after, the replicas' means and SEs.
    Restrict,
    /// Keeping a box for the next step: its snapshot captured and encoded.
    Keep,
    /// Dropping the box's simulation (its world, schedule and event core) once it is
    /// measured and kept: what a direct run of the box also does at its end.
    Teardown,
    /// The coupling's own bookkeeping on the calling thread: each cell's input and
    /// state checked and its tasks made, and its replicas' results put together
    /// (restriction's means and SEs apart, timed as [`Part::Restrict`]) into its output
    /// and next state. What the task farm itself costs (handing tasks to the worker
    /// threads and results back) is in no part: the process's CPU time less the parts.
    Coupling,
}

impl Part {
    /// Every part, in the order of a step.
    pub const ALL: [Part; COUNT] = [
        Part::Lift,
        Part::Adjust,
        Part::Restore,
        Part::Build,
        Part::Calendar,
        Part::Run,
        Part::Restrict,
        Part::Keep,
        Part::Teardown,
        Part::Coupling,
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
            Part::Teardown => "teardown",
            Part::Coupling => "coupling",
        }
    }
}

static NANOS: [AtomicU64; COUNT] = [const { AtomicU64::new(0) }; COUNT];

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

/// True while parts are timed ([`enable`]).
static ENABLED: AtomicBool = AtomicBool::new(false);

/// Time the parts from now on (`true`) or stop (`false`, the default). Reading a
/// thread's CPU clock is a system call — 0.4 µs on this project's 2-core VM when it is
/// quiet, 1.8 µs under a load of 12–17 — against a resumed P04 box's 0.36 ms run and
/// about ten readings per box, so a macro step pays for it only when asked.
pub fn enable(on: bool) {
    ENABLED.store(on, Ordering::Relaxed);
}

/// This thread's CPU time [ns] if parts are timed.
fn now() -> Option<u64> {
    ENABLED
        .load(Ordering::Relaxed)
        .then(|| cpu_nanos(libc::CLOCK_THREAD_CPUTIME_ID))
}

/// Where a part started: this thread's CPU time [ns] (None: not timed) and its time in
/// parts so far.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Started {
    cpu: Option<u64>,
    in_parts: u64,
}

thread_local! {
    /// This thread's CPU time counted into parts so far [ns]: a part timed inside
    /// another (restriction inside the coupling's putting together) is counted once, in
    /// the inner part, so that the parts add up to no more than the process's time.
    static IN_PARTS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Where a part starts.
pub(crate) fn start() -> Started {
    Started {
        cpu: now(),
        in_parts: IN_PARTS.get(),
    }
}

/// Add this thread's CPU time since `start` ([`start`]) to `part`, less what parts
/// timed inside it counted; returns the clock's reading (None when not timed).
pub(crate) fn add(part: Part, start: Started) -> Option<u64> {
    let (Some(begun), Some(end)) = (start.cpu, now()) else {
        return None;
    };
    let elapsed = end.saturating_sub(begun);
    let inner = IN_PARTS.get().saturating_sub(start.in_parts);
    NANOS[part as usize].fetch_add(elapsed.saturating_sub(inner), Ordering::Relaxed);
    IN_PARTS.set(start.in_parts.saturating_add(elapsed.max(inner)));
    Some(end)
}

/// Run `f`, adding its CPU time to `part`.
pub(crate) fn timed<T>(part: Part, f: impl FnOnce() -> T) -> T {
    let begun = start();
    let out = f();
    add(part, begun);
    out
}

/// A stopwatch over consecutive parts: each [`Lap::to`] charges the time since the
/// last to a part with one clock reading, where [`timed`] takes two per part (a box's
/// step has about ten parts).
pub(crate) struct Lap(Started);

impl Lap {
    /// Start timing.
    pub(crate) fn start() -> Self {
        Self(start())
    }

    /// Charge the time since the last lap (or the start) to `part`.
    pub(crate) fn to(&mut self, part: Part) {
        let end = add(part, self.0);
        self.0 = Started {
            cpu: end,
            in_parts: IN_PARTS.get(),
        };
    }
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
pub fn seconds() -> [(Part, f64); COUNT] {
    Part::ALL.map(|p| (p, NANOS[p as usize].load(Ordering::Relaxed) as f64 * 1e-9))
}
