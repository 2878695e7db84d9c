//! When `--series`, `--sizes` and `--snapshots` take a sample (`output.sampling`): every
//! Δt of simulated time, log-spaced in time (aggregation spans decades), or every k
//! steps. A sample is also taken at t = 0 and at the end of the run.
//!
//! A sample is taken at the end of the first step that reaches a scheduled time, and
//! its `t` column is that step's end time: the engine does not stop at sample times
//! (that would change the stepping, and so the run). On the event core a step ends at
//! each event, so the lag is one inter-event time.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Samples per run when `output.sampling` is not given (every T/100).
pub const DEFAULT_SAMPLES: f64 = 100.0;

/// Decades covered by a log schedule whose `first` time is not given: first = T/10⁴.
pub const DEFAULT_LOG_DECADES: i32 = 4;

/// The first time `next + k·dt` (k ≥ 1) after `now` [s], found at once (Python's
/// `on_step(every=dt)` hooks): a step may pass
/// many of them, and counting them one by one never ended for `every=1e-20` (1e17 per
/// step), nor for any dt below the clock's rounding, where `next + dt == next`. When dt is
/// that fine the hook is due at every step: the next representable time after `now`.
pub fn next_time(next: f64, dt: f64, now: f64) -> f64 {
    if next > now {
        return next;
    }
    let passed = ((now - next) / dt).floor() + 1.0;
    let candidate = next + passed * dt;
    // When (now − next)/dt overflows (dt = 5e-324), `passed` and the candidate are ∞:
    // due at every step, as for any dt below the clock's rounding.
    if candidate > now && candidate.is_finite() {
        candidate
    } else {
        now.next_up()
    }
}

/// The sampling schedule of the time series, size distribution and snapshots.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum SampleSchedule {
    /// Every `dt` [s] of simulated time (t = 0, dt, 2 dt, …).
    Interval {
        /// Δt between samples [s], > 0.
        dt: f64,
    },
    /// Log-spaced: t = 0, then t_k = first · 10^(k / per_decade), k = 0, 1, …, up to T.
    Log {
        /// First sample time after t = 0 [s], > 0 (default T/10⁴).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        first: Option<f64>,
        /// Samples per decade of time, ≥ 1.
        per_decade: u32,
    },
    /// Every `every` steps (on the event core a step ends at each event time: every k events).
    Steps {
        /// Steps between samples, ≥ 1.
        every: u64,
    },
}

impl SampleSchedule {
    /// The schedule used when none is given: every T/100 of a run of length `end` [s].
    pub fn default_for(end: f64) -> Self {
        SampleSchedule::Interval {
            dt: end / DEFAULT_SAMPLES,
        }
    }

    /// Problems with the schedule's numbers as (field under `output.sampling`, allowed).
    pub fn problems(&self) -> Vec<(&'static str, &'static str, f64)> {
        let mut out = Vec::new();
        match *self {
            SampleSchedule::Interval { dt } => {
                if !(dt.is_finite() && dt > 0.0) {
                    out.push(("interval.dt", "a finite number > 0", dt));
                }
            }
            SampleSchedule::Log { first, per_decade } => {
                if let Some(f) = first
                    && !(f.is_finite() && f > 0.0)
                {
                    out.push(("log.first", "a finite number > 0", f));
                }
                if per_decade == 0 {
                    out.push(("log.per_decade", "≥ 1", 0.0));
                }
            }
            SampleSchedule::Steps { every } => {
                if every == 0 {
                    out.push(("steps.every", "≥ 1", 0.0));
                }
            }
        }
        out
    }
}

/// The schedule running: which sample is next.
#[derive(Debug, Clone)]
pub struct Sampler {
    schedule: SampleSchedule,
    end: f64,
    /// Index of the next scheduled time (interval and log schedules).
    k: u64,
    /// Time of the last sample taken [s].
    last: Option<f64>,
}

impl Sampler {
    /// The schedule of a run that ends at `end` [s].
    pub fn new(schedule: SampleSchedule, end: f64) -> Self {
        Self {
            schedule,
            end,
            k: 0,
            last: None,
        }
    }

    /// The k-th scheduled time after t = 0 [s] (interval and log schedules).
    fn time_of(&self, k: u64) -> f64 {
        match self.schedule {
            SampleSchedule::Interval { dt } => (k + 1) as f64 * dt,
            SampleSchedule::Log { first, per_decade } => {
                let first = first.unwrap_or(self.end * 10f64.powi(-DEFAULT_LOG_DECADES));
                first * 10f64.powf(k as f64 / f64::from(per_decade))
            }
            SampleSchedule::Steps { .. } => f64::INFINITY,
        }
    }

    /// A scheduled index a little below the last one reached by `t` (interval and log
    /// schedules), or None when it is beyond 1e18.
    fn index_near(&self, t: f64) -> Option<u64> {
        let index = match self.schedule {
            SampleSchedule::Interval { dt } => t / dt - 1.0,
            SampleSchedule::Log { first, per_decade } => {
                let first = first.unwrap_or(self.end * 10f64.powi(-DEFAULT_LOG_DECADES));
                f64::from(per_decade) * (t / first).log10()
            }
            SampleSchedule::Steps { .. } => 0.0,
        };
        if index >= 1e18 {
            return None;
        }
        // Two below, for the rounding of the division and of 10^x; a NaN or negative
        // index is 0 (`as` saturates).
        Some((index as u64).saturating_sub(2))
    }

    /// Whether a sample is due at the end of step `step` (steps completed), at time `t`
    /// [s]; when it is, the schedule moves past `t`. O(1) per call, apart from the
    /// scheduled times a long step skips over.
    pub fn due(&mut self, step: u64, t: f64) -> bool {
        if self.last.is_none() {
            return true; // t = 0
        }
        let due = match self.schedule {
            SampleSchedule::Steps { every } => step.is_multiple_of(every),
            _ => {
                // A relative 1e-12 of slack, so a step that lands on k·Δt up to rounding counts.
                let reached = |when: f64| t >= when * (1.0 - 1e-12);
                if reached(self.time_of(self.k)) {
                    // Jump to about the index of t at once, then step past it: a step
                    // may pass many scheduled times (an interval of 1e-300 s passed
                    // 1e297 per step, counted one by one while no signal was heard).
                    let Some(near) = self.index_near(t) else {
                        // Finer than u64 can count: a sample at every step.
                        return true;
                    };
                    self.k = self.k.max(near);
                    while reached(self.time_of(self.k)) {
                        self.k += 1;
                    }
                    true
                } else {
                    false
                }
            }
        };
        due || (t >= self.end && self.last.is_some_and(|last| last < t))
    }

    /// Note that a sample was taken at `t` [s].
    pub fn taken(&mut self, t: f64) {
        self.last = Some(t);
    }

    /// Time of the last sample taken [s].
    pub fn last(&self) -> Option<f64> {
        self.last
    }
}
