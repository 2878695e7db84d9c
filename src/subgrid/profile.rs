//! Where a macro step's time goes (issue 37's cost goal: lifting, adjusting,
//! restriction and coupling within 10 % of the boxes' own run time).
//!
//! Every part of a box's step adds its elapsed nanoseconds to a process-wide counter
//! ([`Part`]); `benches/subgrid.rs` resets them, runs a macro step and reads them. The
//! counters are summed over threads (with one thread, wall time); reading a clock twice
//! per part costs about 50 ns against milliseconds per box, and nothing a box computes
//! depends on them.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// A part of a box's macro step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Drawing a fresh box from the cell's classes (lift.rs).
    Lift,
    /// Adjusting a kept box to what transport changed (adjust.rs).
    Adjust,
    /// Reading a kept box back: its snapshot decoded, its scene read from JSON.
    Restore,
    /// Building the box's simulation (world, schedule, checks) and resuming a snapshot.
    Build,
    /// The box's own run over Δt (the event or time-step core).
    Run,
    /// Restriction: the class sums before and after, the replicas' means and SEs.
    Restrict,
    /// Keeping a box for the next step: snapshot captured and encoded, scene to JSON.
    Keep,
}

impl Part {
    /// Every part, in the order of a step.
    pub const ALL: [Part; 7] = [
        Part::Lift,
        Part::Adjust,
        Part::Restore,
        Part::Build,
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
            Part::Run => "run",
            Part::Restrict => "restrict",
            Part::Keep => "keep",
        }
    }
}

static NANOS: [AtomicU64; 7] = [const { AtomicU64::new(0) }; 7];

/// Add the time since `start` to `part`.
pub(crate) fn add(part: Part, start: Instant) {
    let ns = start.elapsed().as_nanos().min(u64::MAX as u128) as u64;
    NANOS[part as usize].fetch_add(ns, Ordering::Relaxed);
}

/// Run `f`, adding its time to `part`.
pub(crate) fn timed<T>(part: Part, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    add(part, start);
    out
}

/// Set every counter to 0.
pub fn reset() {
    for n in &NANOS {
        n.store(0, Ordering::Relaxed);
    }
}

/// Seconds spent in each part since the last [`reset`], summed over threads, in the
/// order of [`Part::ALL`].
pub fn seconds() -> [(Part, f64); 7] {
    Part::ALL.map(|p| (p, NANOS[p as usize].load(Ordering::Relaxed) as f64 * 1e-9))
}
