//! The progress line of `agglo run` on a terminal: how far the run is in simulated
//! time, how fast it goes (events — or steps, on the stepped core — per wall second,
//! over the last update interval), how many bodies are left, and an ETA from simulated
//! time: wall time so far × (T − t) / t.
//!
//! It is redrawn at most every [`UPDATE_INTERVAL`] of wall time; the clock is looked at
//! every [`CHECK_EVERY`] steps, so a step costs O(1), and the O(N) body count is taken
//! only at a redraw.

use std::time::{Duration, Instant};

use crate::observer::{Ending, Observer, Written};
use crate::schedule::Simulation;
use indicatif::{ProgressBar, ProgressStyle};

/// Least wall time between two redraws.
pub const UPDATE_INTERVAL: Duration = Duration::from_millis(200);
/// Steps between two looks at the wall clock.
pub const CHECK_EVERY: u64 = 64;

/// The progress line of one run.
pub struct Progress {
    bar: ProgressBar,
    end: f64,
    /// "events" on the event core (a step ends at each event time), else "steps".
    unit: &'static str,
    start: Instant,
    last: Instant,
    last_step: u64,
}

impl Progress {
    /// A progress line for a run to `end` [s].
    pub fn new(end: f64, event_core: bool) -> Self {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let now = Instant::now();
        Self {
            bar,
            end,
            unit: if event_core { "events" } else { "steps" },
            start: now,
            last: now,
            last_step: 0,
        }
    }

    /// After a step: redraw if it is time.
    pub fn update(&mut self, sim: &Simulation) {
        let c = sim.clock();
        if !c.step.is_multiple_of(CHECK_EVERY) {
            return;
        }
        let now = Instant::now();
        let since = now.duration_since(self.last);
        if since < UPDATE_INTERVAL {
            return;
        }
        let rate = (c.step - self.last_step) as f64 / since.as_secs_f64();
        let elapsed = now.duration_since(self.start).as_secs_f64();
        self.bar.set_position((1000.0 * c.time / self.end) as u64);
        self.bar.set_message(line(
            c.time,
            self.end,
            rate,
            self.unit,
            sim.body_count(),
            elapsed,
        ));
        self.last = now;
        self.last_step = c.step;
    }

    /// Print `text` above the line.
    pub fn suspend(&self, f: impl FnOnce()) {
        self.bar.suspend(f);
    }

    /// Clear the progress line (the run is over).
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    /// The line itself, for another output to print above it ([`ProgressBar::suspend`]).
    pub fn bar(&self) -> ProgressBar {
        self.bar.clone()
    }
}

impl Observer for Progress {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        self.update(sim);
        Ok(())
    }

    fn finish(self: Box<Self>, _: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        Progress::finish(&self);
        Ok(())
    }
}

/// The message: simulated time of T, rate, bodies and the ETA from simulated time.
pub fn line(t: f64, end: f64, rate: f64, unit: &str, bodies: usize, elapsed: f64) -> String {
    let eta = if t > 0.0 {
        format_duration(elapsed * (end - t).max(0.0) / t)
    } else {
        "?".into()
    };
    let end = crate::readable::sci(end);
    format!("t = {t:.3e} of {end} s · {rate:.3e} {unit}/s · {bodies} bodies · ETA {eta}")
}

/// Seconds as `1h02m03s`, `2m03s` or `3.4s`.
pub fn format_duration(seconds: f64) -> String {
    if !seconds.is_finite() {
        return "?".into();
    }
    let s = seconds.round() as u64;
    match s {
        _ if seconds < 60.0 => format!("{seconds:.1}s"),
        _ if s < 3600 => format!("{}m{:02}s", s / 60, s % 60),
        _ => format!("{}h{:02}m{:02}s", s / 3600, s % 3600 / 60, s % 60),
    }
}
