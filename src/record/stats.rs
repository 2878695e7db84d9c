//! The `/stats` message: observables and counters of one snapshot, JSON-encoded with a
//! JSON Schema so every field is plottable in Foxglove's Plot panel.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::observables::Summary;

/// One `/stats` message. Energies in J, temperatures in K, times in s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Stats {
    /// Simulated time t [s] (the log time is t × the playback scale).
    pub time: f64,
    /// Step size of the last step Δt [s].
    pub dt: f64,
    /// Steps taken.
    pub step: u64,
    /// Number of bodies N.
    pub bodies: u64,
    /// Mean radius over the primary radius, b_f / b0.
    pub mean_radius_over_b0: f64,
    /// b_f / b*: mean radius over the radius of one sphere holding all the mass (1 − Π04).
    pub b_f_over_b_star: f64,
    /// Mean number of primaries per body.
    pub mean_primaries: f64,
    /// Σ ½ m v² [J].
    pub kinetic_energy: f64,
    /// Kinetic energy over its value in the first snapshot (0 if that was 0): the
    /// fraction left, plottable on one scale whatever the grain size (P02's grains carry
    /// ~1e-11 J, P04's ~100 J).
    pub kinetic_energy_over_initial: f64,
    /// Σ m C θ [J].
    pub thermal_energy: f64,
    /// Mean temperature [K].
    pub mean_temperature: f64,
    /// Maximum temperature [K].
    pub max_temperature: f64,
    /// Impacts resolved so far.
    pub impacts: u64,
    /// Impacts that bonded so far.
    pub bonds: u64,
    /// Impacts that bounced so far.
    pub bounces: u64,
    /// Bodies that fragmented so far.
    pub fragmentations: u64,
    /// Fixed-point iterations of the pair solve so far.
    pub fixed_point_iterations: u64,
    /// Impacts that needed the bracketed fallback solver.
    pub fallbacks: u64,
    /// Steps whose Δt was clamped at Δt_min.
    pub clamped_steps: u64,
    /// Invariant checks that failed.
    pub invariant_violations: u64,
    /// Quantities extensions carry (engine/carried.rs), each for the whole cloud combined
    /// by its rule, under its name; none (and no field) when none is registered. Not in
    /// the schema, which stays that of the built-in fields.
    #[serde(flatten)]
    #[schemars(skip)]
    pub carried: std::collections::BTreeMap<String, f64>,
}

impl Stats {
    /// From a run's summary, the last step size and the kinetic energy of the first
    /// snapshot [J].
    pub fn new(summary: &Summary, dt: f64, initial_kinetic_energy: f64) -> Self {
        let c = &summary.counters;
        let g = &summary.growth;
        Self {
            time: summary.time,
            dt,
            step: summary.steps,
            bodies: summary.final_bodies as u64,
            mean_radius_over_b0: g.growth_ratio,
            b_f_over_b_star: g.b_f / g.b_star,
            mean_primaries: summary.mean_primaries,
            kinetic_energy: summary.kinetic_energy,
            kinetic_energy_over_initial: if initial_kinetic_energy > 0.0 {
                summary.kinetic_energy / initial_kinetic_energy
            } else {
                0.0
            },
            thermal_energy: summary.thermal_energy,
            mean_temperature: summary.mean_temperature,
            max_temperature: summary.max_temperature,
            impacts: c.impacts,
            bonds: c.bonds,
            bounces: c.bounces,
            fragmentations: c.fragmentations,
            fixed_point_iterations: c.fixed_point_iterations,
            fallbacks: c.fallbacks,
            clamped_steps: c.clamped_steps,
            invariant_violations: c.invariant_violations,
            carried: Default::default(),
        }
    }

    /// The JSON Schema bytes written as the channel's schema.
    pub fn schema_bytes() -> Vec<u8> {
        serde_json::to_vec(&schemars::schema_for!(Stats)).expect("schema serialises") // ok: plain data
    }
}
