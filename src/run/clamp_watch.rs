//! Says on stderr, while a run goes on, that the stepped core keeps clamping Δt at
//! Δt_min (docs/model.md §4): such a run resolves contacts late and may crawl towards
//! `time.max_steps`. The summary and the recording count clamped steps too, but only
//! a message during the run reaches a user who is waiting for it.
//!
//! The run is cut into windows of [`WINDOW_STEPS`] steps; a window in which more than
//! [`CLAMPED_FRACTION`] of the steps were clamped is reported, at most once every
//! [`MIN_INTERVAL`] of wall time, so a long run writes a few lines, not thousands.

use std::time::{Duration, Instant};

use crate::observer::{Ending, Observer, Written};
use crate::scenario::{Scenario, Stepping};
use crate::schedule::Simulation;

/// Steps per window.
pub const WINDOW_STEPS: u64 = 1000;
/// Fraction of clamped steps in a window above which it is reported.
pub const CLAMPED_FRACTION: f64 = 0.5;
/// Least wall time between two warnings.
pub const MIN_INTERVAL: Duration = Duration::from_secs(5);

/// A window worth a warning: `clamped` of the last `steps` steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClampedWindow {
    /// Clamped steps in the window.
    pub clamped: u64,
    /// Steps in the window.
    pub steps: u64,
}

/// Counts clamped steps window by window. See the module docs.
#[derive(Debug, Clone)]
pub struct ClampWatch {
    window_start_step: u64,
    window_start_clamped: u64,
    last_warning: Option<Instant>,
}

impl ClampWatch {
    /// A watch starting at `step` with `clamped` steps counted so far.
    pub fn new(step: u64, clamped: u64) -> Self {
        Self {
            window_start_step: step,
            window_start_clamped: clamped,
            last_warning: None,
        }
    }

    /// Call after every step with the step count and the `clamped_steps` counter;
    /// returns the window to report, if one closes now and is worth a warning.
    pub fn observe(&mut self, step: u64, clamped: u64, now: Instant) -> Option<ClampedWindow> {
        let steps = step.saturating_sub(self.window_start_step);
        if steps < WINDOW_STEPS {
            return None;
        }
        let window = ClampedWindow {
            clamped: clamped.saturating_sub(self.window_start_clamped),
            steps,
        };
        self.window_start_step = step;
        self.window_start_clamped = clamped;
        let mostly_clamped = window.clamped as f64 > CLAMPED_FRACTION * steps as f64;
        let quiet_long_enough = self
            .last_warning
            .is_none_or(|last| now.duration_since(last) >= MIN_INTERVAL);
        if mostly_clamped && quiet_long_enough {
            self.last_warning = Some(now);
            Some(window)
        } else {
            None
        }
    }
}

/// The warnings of a run on the stepped core with adaptive steps, printed on stderr
/// (above the progress line, when there is one).
pub struct ClampWarnings {
    watch: ClampWatch,
    /// Δt_min [s].
    dt_min: f64,
    /// T [s] and `time.max_steps`, quoted by the warning.
    end: f64,
    max_steps: u64,
    /// The progress line to print above.
    bar: Option<indicatif::ProgressBar>,
}

impl ClampWarnings {
    /// The warnings of `sim`'s run, if its scene can clamp (see [`clamping_floor`]).
    pub fn new(
        scenario: &Scenario,
        sim: &Simulation,
        bar: Option<indicatif::ProgressBar>,
    ) -> Option<Self> {
        let dt_min = clamping_floor(scenario)?;
        Some(Self {
            watch: ClampWatch::new(sim.clock().step, sim.counters().clamped_steps),
            dt_min,
            end: scenario.time.end,
            max_steps: scenario.time.max_steps,
            bar,
        })
    }

    /// The warning printed (to stderr, even when quiet: it is about a run going wrong)
    /// when most steps of a window were clamped.
    fn warning(&self, t: f64, window: ClampedWindow) -> String {
        format!(
            "warning: at t = {t:.4e} s, {} of the last {} steps were clamped at Δt_min = {:e} s \
             although a contact was due sooner: contacts are resolved late, and the run advances \
             about Δt_min per step (T/Δt_min = {:.1e} steps, time.max_steps = {}); \
             lower time.stepping.adaptive.dt_min",
            window.clamped,
            window.steps,
            self.dt_min,
            self.end / self.dt_min,
            self.max_steps
        )
    }
}

impl Observer for ClampWarnings {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let c = sim.clock();
        let now = Instant::now();
        if let Some(window) = self
            .watch
            .observe(c.step, sim.counters().clamped_steps, now)
        {
            let warning = self.warning(c.time, window);
            match &self.bar {
                Some(bar) => bar.suspend(|| eprintln!("{warning}")),
                None => eprintln!("{warning}"),
            }
        }
        Ok(())
    }

    fn finish(self: Box<Self>, _: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        Ok(())
    }
}

/// Δt_min, if the scene can clamp at it: only the stepped core with adaptive steps does
/// (the event core lands on every contact; fixed steps have no lower bound).
fn clamping_floor(s: &Scenario) -> Option<f64> {
    match s.time.stepping {
        Stepping::Adaptive { dt_min, .. } if !s.uses_event_core() => Some(dt_min),
        _ => None,
    }
}
