//! Recording a run to MCAP for replay in Foxglove, and reading recordings back.
//!
//! A recording holds four channels:
//!
//! | topic        | schema                       | encoding | what                                        |
//! |--------------|------------------------------|----------|---------------------------------------------|
//! | `/particles` | `foxglove.SceneUpdate`       | protobuf | one sphere per body (id = stable body id), deletions of bodies gone since the last snapshot |
//! | `/box`       | `foxglove.SceneUpdate`       | protobuf | the periodic box [−D, D]³ as a line list, once |
//! | `/stats`     | `agglo.Stats` (JSON Schema)  | json     | observables and counters per snapshot ([`Stats`]) |
//! | `/events`    | `foxglove.Log`               | protobuf | warnings (solver fallbacks, clamped steps, invariant violations) and the run's outcome |
//!
//! plus the scenario actually run (seed applied) as the attachment
//! [`SCENARIO_ATTACHMENT`] and metadata records [`RUN_METADATA`] (engine version,
//! seed, command line, time scale, box half-width D, the pipeline as JSON) and
//! [`RESULT_METADATA`] (outcome, written last).
//!
//! **Time.** A P04 run lasts 10 ms of simulated time; Foxglove replays log time in
//! real time. So the log time of every message is simulated time × a playback
//! scale ([`Sampling::log_seconds_per_sim_second`], default: the whole run in
//! `output.recording.playback_seconds` = 30 s); the true simulated time is the
//! `time` field of every `/stats` message and the scale is in the metadata.
//!
//! **Colour.** Spheres are coloured by temperature on a logarithmic scale
//! ([`ColourScale`]): blue at θ_lo = min(θ0, θ_s), through cyan, green and yellow,
//! to red at 10³ θ_lo and above. In a rigid scene (docs/model.md §6.1) the primaries are
//! coloured by aggregate instead ([`messages::aggregate_rgb`]).
//!
//! The writer lives in [`writer`], the reader behind `agglo inspect` and
//! `agglo run --from` in [`inspect`], and the Foxglove layout fitted to a recording's
//! box (`agglo layout`, and `RUN.layout.json` next to every `agglo run --out`) in
//! [`layout`].

#[doc(hidden)]
pub mod chunk;
pub mod inspect;
pub mod layout;
pub mod messages;
mod stats;
pub mod writer;

pub use inspect::{Inspection, inspect, scenario_from_recording};
pub use stats::Stats;
pub use writer::{Recorder, RecordingReport};

use crate::scenario::Scenario;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Topic of the bodies (`foxglove.SceneUpdate`).
pub const PARTICLES_TOPIC: &str = "/particles";
/// Topic of the periodic box (`foxglove.SceneUpdate`), written once.
pub const BOX_TOPIC: &str = "/box";
/// Topic of the statistics (JSON, schema [`Stats`]).
pub const STATS_TOPIC: &str = "/stats";
/// Topic of warnings and the outcome (`foxglove.Log`).
pub const EVENTS_TOPIC: &str = "/events";
/// Name of the attachment holding the scenario JSON.
pub const SCENARIO_ATTACHMENT: &str = "scenario.json";
/// Name of the metadata record written at the start.
pub const RUN_METADATA: &str = "agglo";
/// Key of the box half-width D [m] in [`RUN_METADATA`] (what a fitted layout needs).
pub const BOX_HALF_WIDTH_KEY: &str = "box_half_width_m";
/// Key of the pipeline (JSON of [`crate::schedule::Pipeline`]) in [`RUN_METADATA`].
pub const PIPELINE_KEY: &str = "pipeline";
/// Name of the metadata record written when the recording is finalised.
pub const RESULT_METADATA: &str = "agglo.result";
/// Frame of every scene entity.
pub const FRAME_ID: &str = "world";

/// Decades of temperature spanned by the colour scale.
pub const COLOUR_DECADES: f64 = 3.0;

/// When to take a snapshot and how to map simulated time to log time.
///
/// From `output.recording`: with `every_steps = k > 0` and no `interval`, every
/// k-th step; with an `interval` Δt_rec (and `every_steps = 0`), whenever simulated time
/// has crossed a multiple of Δt_rec; with both, whichever comes first; with neither,
/// Δt_rec = T / 300. The first (t = 0) and last states are always recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampling {
    /// Record every k-th step (0 = off).
    pub every_steps: u64,
    /// Record every Δt_rec [s] of simulated time (`None` = off).
    pub interval: Option<f64>,
    /// Log seconds per simulated second: playback_seconds / T.
    pub log_seconds_per_sim_second: f64,
}

/// Default number of snapshots per run when nothing is set (Δt_rec = T / this).
pub const DEFAULT_SNAPSHOTS: f64 = 300.0;

impl Sampling {
    /// The recording schedule of `s`: its `output.recording` section (every so many
    /// steps, an interval, or T / [`DEFAULT_SNAPSHOTS`] when neither is set) and its
    /// playback scale.
    pub fn from_scenario(s: &Scenario) -> Self {
        let r = &s.output.recording;
        let interval = match (r.every_steps, r.interval) {
            (0, None) => Some(s.time.end / DEFAULT_SNAPSHOTS),
            (_, i) => i,
        };
        Self {
            every_steps: r.every_steps,
            interval,
            log_seconds_per_sim_second: r.playback_seconds / s.time.end,
        }
    }

    /// Log time [ns] of simulated time `t` [s] (saturating; 0 for non-finite or negative t).
    pub fn log_time(&self, t: f64) -> u64 {
        let ns = (t * self.log_seconds_per_sim_second * 1e9).round();
        if ns.is_finite() && ns > 0.0 {
            // `as` saturates at u64::MAX (≈ 585 years of playback).
            ns as u64
        } else {
            0
        }
    }

    /// Whether step `step` ending at time `t` is due, given the last recorded time `last_t`.
    /// Time-based snapshots fire when t crosses a multiple of Δt_rec, so they do not drift
    /// with the step sizes.
    pub fn due(&self, step: u64, t: f64, last_t: f64) -> bool {
        if self.every_steps > 0 && step.is_multiple_of(self.every_steps) {
            return true;
        }
        match self.interval {
            Some(dt) => (t / dt).floor() > (last_t / dt).floor(),
            None => false,
        }
    }
}

/// The temperature colour scale: log θ from θ_lo (blue) to θ_lo · 10^[`COLOUR_DECADES`] (red).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourScale {
    /// θ_lo [K] = min(θ0, θ_s): the coldest colour.
    pub theta_lo: f64,
    /// θ_hi [K]: the hottest colour (and everything above).
    pub theta_hi: f64,
}

impl ColourScale {
    /// The scale of `s`: from min(θ0, θ_s) over [`COLOUR_DECADES`] decades.
    pub fn from_scenario(s: &Scenario) -> Self {
        let theta_lo = s.material.theta0.min(s.material.theta_s);
        Self {
            theta_lo,
            theta_hi: theta_lo * 10f64.powf(COLOUR_DECADES),
        }
    }

    /// Position of θ on the scale, in [0, 1] (0 for NaN).
    pub fn fraction(&self, theta: f64) -> f64 {
        let f = (theta / self.theta_lo).ln() / (self.theta_hi / self.theta_lo).ln();
        if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) }
    }

    /// RGB in [0, 1] of θ: blue → cyan → green → yellow → red, linear between the stops.
    pub fn rgb(&self, theta: f64) -> [f64; 3] {
        const STOPS: [[f64; 3]; 5] = [
            [0.10, 0.25, 1.00],
            [0.00, 0.85, 1.00],
            [0.20, 0.90, 0.20],
            [1.00, 0.90, 0.00],
            [1.00, 0.10, 0.05],
        ];
        let x = self.fraction(theta) * (STOPS.len() - 1) as f64;
        let i = (x.floor() as usize).min(STOPS.len() - 2);
        let w = x - i as f64;
        let (a, b) = (STOPS[i], STOPS[i + 1]);
        // (1 − w) a + w b: exact at both stops.
        [0, 1, 2].map(|k| (1.0 - w) * a[k] + w * b[k])
    }
}

/// The recording: where it goes, how often and how it samples the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Recording {
    /// Record the run to this MCAP file (same as `--recording`; Python's `recording=`).
    /// Formerly `output.mcap`, which is still read into this field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    /// Record every k-th step (0 = use `interval` only).
    #[serde(default)]
    pub every_steps: u64,
    /// Record whenever this much simulated time [s] has passed; `null` = T / 300.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval: Option<f64>,
    /// Playback duration [s] of the whole run at 1×: log time = simulated time × (this / T).
    #[serde(default = "default_playback")]
    pub playback_seconds: f64,
}

fn default_playback() -> f64 {
    30.0
}

impl Default for Recording {
    fn default() -> Self {
        Self {
            path: None,
            every_steps: 0,
            interval: None,
            playback_seconds: default_playback(),
        }
    }
}
