//! Range checks of a scenario's sections, each naming its field by its full path and
//! saying the allowed range and the value given
//! (`material.rho: allowed a finite number > 0 (got -1)`). Every built-in section checks
//! itself with these (an `issues()` next
//! to its type: the box and the material in `scene.rs`, the cloud in `cloud.rs`, the
//! field in `field.rs`, the impact model and the diagnostics in their plugins, the
//! `output` section with the drivers), as an extension's section does
//! (`agglo::plugins::PluginSection`); the scenario's `validate` is the loop over them
//! plus the checks that join two sections.

use crate::error::ValidationIssue;

/// The largest speed a scenario may give [m/s]: any |v_mean|, any v_rel component, any
/// explicit body's |velocity|; a restart snapshot's bodies are held to it too.
///
/// 1e5 m/s (100 km/s) is above the fastest natural impacts (meteoroids meet the Earth at
/// up to ~72 km/s) and hundreds of times the speeds of granular flows and of the papers'
/// scenes (P04: ~200 m/s; P02: ~4 m/s), so no physical scene is refused. Below it every
/// energy stays far from overflow (½ v² ~ 1e10 J/kg) and runs of the
/// shipped size finish: with v̄ = (1e5, 0, 0) m/s and v_rel = 1e5 m/s per component
/// (release build) P04's best case takes 0.01 s, quick_demo 0.25 s (38 635 impacts).
/// Above it lie only mistakes: with v_rel = 1e300 m/s the kinetic energies overflow to ∞
/// and P04's scene was still running after 200 s.
pub const MAX_SPEED: f64 = 1e5;

/// Collects range violations with their field paths.
#[derive(Debug, Default)]
pub struct Issues {
    /// The problems found, in the order they were found.
    pub issues: Vec<ValidationIssue>,
}

impl Issues {
    /// `path`: allowed `allowed` (got `got`), the value printed exactly.
    pub fn push(&mut self, path: &str, allowed: &str, got: f64) {
        self.issues.push(ValidationIssue {
            path: path.into(),
            message: format!("allowed {allowed} (got {})", crate::readable::exact(got)),
        });
    }
    /// A problem said in words of its own.
    pub fn say(&mut self, path: &str, message: impl Into<String>) {
        self.issues.push(ValidationIssue {
            path: path.into(),
            message: message.into(),
        });
    }
    /// `path` must be finite.
    pub fn finite(&mut self, path: &str, x: f64) {
        if !x.is_finite() {
            self.push(path, "a finite number", x);
        }
    }
    /// `path` must be finite and > 0.
    pub fn positive(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x > 0.0) {
            self.push(path, "a finite number > 0", x);
        }
    }
    /// `path` must be finite and ≥ 0.
    pub fn non_negative(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x >= 0.0) {
            self.push(path, "a finite number ≥ 0", x);
        }
    }
    /// `path` must lie in (lo, hi); `allowed` says so in the message.
    pub fn range_open(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x > lo && x < hi) {
            self.push(path, allowed, x);
        }
    }
    /// `path` must lie in (lo, hi]; `allowed` says so in the message.
    pub fn range_open_closed(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x > lo && x <= hi) {
            self.push(path, allowed, x);
        }
    }
    /// `path` must lie in [lo, hi]; `allowed` says so in the message.
    pub fn range_closed(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x >= lo && x <= hi) {
            self.push(path, allowed, x);
        }
    }
    /// A speed [m/s] above [`MAX_SPEED`]. ∞ counts (finite components whose norm
    /// overflows, e.g. v̄ = (1e200, 0, 0), validated and then hung the run); NaN is
    /// reported by the finiteness checks.
    pub fn below_speed_limit(&mut self, path: &str, speed: f64) {
        if speed > MAX_SPEED {
            self.say(
                path,
                format!(
                    "speed {speed:.4e} m/s is not physical; allowed ≤ {MAX_SPEED:e} m/s \
                     (100 km/s, above the fastest natural impacts)"
                ),
            );
        }
    }
    /// A run of `end` [s] in steps of at most `dt` [s] that needs more than `max_steps`
    /// steps can never finish. Non-positive or non-finite values are reported elsewhere.
    pub fn step_count_fits(&mut self, path: &str, count: &str, end: f64, dt: f64, max_steps: u64) {
        if !(end.is_finite() && end > 0.0 && dt.is_finite() && dt > 0.0) {
            return;
        }
        let planned = planned_steps(end, dt);
        if planned > max_steps as f64 {
            self.say(
                path,
                format!(
                    "{count} = {end:e} s / {dt:e} s = {planned:.3e} planned steps exceed \
                     time.max_steps = {max_steps}; allowed Δt ≥ time.end / time.max_steps \
                     = {:e} s (or raise time.max_steps)",
                    end / max_steps as f64
                ),
            );
        }
    }
}

/// Length of a 3-vector [same unit as its components].
/// |x|, without overflowing for components up to f64::MAX / √3 (the sum of squares of
/// components ≳ 1.34e154 is ∞; hypot scales first).
pub fn norm(x: [f64; 3]) -> f64 {
    x[0].hypot(x[1]).hypot(x[2])
}

/// Steps a run of length `end` [s] needs at steps of at most `dt` [s]: ⌈T/Δt⌉, less a
/// relative 1e-12 (the clock lands on T when a step ends that close to it).
pub fn planned_steps(end: f64, dt: f64) -> f64 {
    (end / dt * (1.0 - 1e-12)).ceil()
}
