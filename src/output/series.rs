//! `--series`: one row per sample of the whole cloud's state (counts, moments, energies,
//! cumulative counters and every energy-ledger term). Columns and units: [`SERIES_COLUMNS`]
//! (docs/outputs.md).

use crate::components::BodyState;
use crate::schedule::Simulation;

use super::table::{Cell, Column, float, int};

/// The columns of the time series, in order.
pub const SERIES_COLUMNS: &[Column] = &[
    float("t", "s", "simulated time of the sample"),
    int("step", "-", "steps completed"),
    int("bodies", "-", "number of bodies (clusters)"),
    float("mass", "kg", "total mass M1 = Σ m"),
    float("momentum_x", "kg m/s", "total momentum Σ m v, x"),
    float("momentum_y", "kg m/s", "total momentum, y"),
    float("momentum_z", "kg m/s", "total momentum, z"),
    float("kinetic_energy", "J", "Σ ½ m |v|²"),
    float("thermal_energy", "J", "Σ m C θ"),
    float(
        "granular_temperature",
        "m²/s²",
        "T_g = Σ m |v − V|² / (3 Σ m), V = Σ m v / Σ m: the mass-weighted velocity variance per component",
    ),
    float("mean_temperature", "K", "number-average θ"),
    float("max_temperature", "K", "largest θ"),
    float("m2", "kg²", "second mass moment M2 = Σ m²"),
    float("m3", "kg³", "third mass moment M3 = Σ m³"),
    float("weight_average_mass", "kg", "weight-average mass M2 / M1"),
    float("mean_radius", "m", "number-average radius b_mean"),
    float("max_radius", "m", "largest radius"),
    float("b_mean_over_b0", "-", "b_mean / b0 (b0: primary radius)"),
    int("impacts", "-", "impacts resolved so far (bounces + bonds)"),
    int("bonds", "-", "impacts that bonded so far"),
    int("bounces", "-", "impacts that bounced so far"),
    int(
        "merges",
        "-",
        "bodies merged away so far: N0 − N + fragments_created − fragmentations",
    ),
    int("fragmentations", "-", "bodies that fragmented so far"),
    int(
        "fragments_created",
        "-",
        "pieces fragmentation created so far",
    ),
    float(
        "reaction_heat",
        "J",
        "energy ledger: reaction heat added, Σ 2 α a_c",
    ),
    float(
        "fracture_energy",
        "J",
        "energy ledger: fracture surface energy, Σ δZ",
    ),
    float(
        "cooling_loss",
        "J",
        "energy ledger: heat lost by cooling up to t (event core: including the bodies not yet brought to t)",
    ),
    float(
        "impact_dissipation",
        "J",
        "energy ledger: kinetic energy dissipated in impacts",
    ),
    float("force_work", "J", "energy ledger: work of external forces"),
    float(
        "force_work_turnover",
        "J",
        "energy ledger: Σ |kinetic energy change| by forces",
    ),
    float(
        "external_heat",
        "J",
        "energy ledger: heat added by extensions",
    ),
    float(
        "force_impulse_x",
        "kg m/s",
        "energy ledger: impulse of external forces, x",
    ),
    float("force_impulse_y", "kg m/s", "impulse of external forces, y"),
    float("force_impulse_z", "kg m/s", "impulse of external forces, z"),
    float("force_impulse_turnover", "kg m/s", "Σ m |Δv| by forces"),
    float(
        "double_counted_heat",
        "J",
        "energy ledger: heat created by the reading impact.work_heat = \"twice\"",
    ),
];

/// What the event core's bodies moved since they were last brought up to date, not yet
/// in the ledger: cooling loss [J], a field's work [J] and impulse [kg m/s] with their
/// turnovers. Zero on the stepped core.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pending {
    /// Cooling loss not yet booked [J].
    pub cooling: f64,
    /// A field's work not yet booked [J].
    pub work: f64,
    /// Σ |work| of the same terms, the scale of its rounding [J].
    pub work_turnover: f64,
    /// A field's impulse not yet booked [kg m/s].
    pub impulse: glam::DVec3,
    /// Σ |impulse| of the same terms, the scale of its rounding [kg m/s].
    pub impulse_turnover: f64,
}

/// One row of the series: the bodies at the sample (sorted by id, brought to t), with
/// what the ledger has not booked yet added to its columns (`pending`).
pub fn series_row(sim: &Simulation, bodies: &[BodyState], pending: Pending) -> Vec<Cell<'static>> {
    let clock = sim.clock();
    let c = sim.counters();
    let e = sim.ledger();
    let material = sim.material();
    let b0 = sim.primary().radius;
    let n = bodies.len();
    let nf = n.max(1) as f64;
    let mut mass = 0.0;
    let mut m2 = 0.0;
    let mut m3 = 0.0;
    let mut p = glam::DVec3::ZERO;
    let mut kinetic = 0.0;
    let mut thermal = 0.0;
    let mut theta_sum = 0.0;
    let mut theta_max = f64::NAN;
    let mut radius_sum = 0.0;
    let mut radius_max = f64::NAN;
    for b in bodies {
        mass += b.mass;
        m2 += b.mass * b.mass;
        m3 += b.mass * b.mass * b.mass;
        p += b.mass * b.velocity;
        kinetic += 0.5 * b.mass * b.velocity.length_squared();
        thermal += b.mass * material.C * b.temperature;
        theta_sum += b.temperature;
        theta_max = theta_max.max(b.temperature);
        radius_sum += b.radius;
        radius_max = radius_max.max(b.radius);
    }
    let v_cm = if mass > 0.0 { p / mass } else { p };
    let peculiar: f64 = bodies
        .iter()
        .map(|b| b.mass * (b.velocity - v_cm).length_squared())
        .sum();
    let granular = if mass > 0.0 {
        peculiar / (3.0 * mass)
    } else {
        0.0
    };
    let initial = sim.info().initial_bodies as i64;
    let merges = initial - n as i64 + c.fragments_created as i64 - c.fragmentations as i64;
    let mean_radius = radius_sum / nf;
    vec![
        Cell::F(clock.time),
        Cell::I(clock.step as i64),
        Cell::I(n as i64),
        Cell::F(mass),
        Cell::F(p.x),
        Cell::F(p.y),
        Cell::F(p.z),
        Cell::F(kinetic),
        Cell::F(thermal),
        Cell::F(granular),
        Cell::F(theta_sum / nf),
        Cell::F(theta_max),
        Cell::F(m2),
        Cell::F(m3),
        Cell::F(if mass > 0.0 { m2 / mass } else { 0.0 }),
        Cell::F(mean_radius),
        Cell::F(radius_max),
        Cell::F(mean_radius / b0),
        Cell::I(c.impacts as i64),
        Cell::I(c.bonds as i64),
        Cell::I(c.bounces as i64),
        Cell::I(merges),
        Cell::I(c.fragmentations as i64),
        Cell::I(c.fragments_created as i64),
        Cell::F(e.reaction_heat),
        Cell::F(e.fracture_energy),
        Cell::F(e.cooling_loss + pending.cooling),
        Cell::F(e.impact_dissipation),
        Cell::F(e.force_work + pending.work),
        Cell::F(e.force_work_turnover + pending.work_turnover),
        Cell::F(e.external_heat),
        Cell::F(e.force_impulse[0] + pending.impulse.x),
        Cell::F(e.force_impulse[1] + pending.impulse.y),
        Cell::F(e.force_impulse[2] + pending.impulse.z),
        Cell::F(e.force_impulse_turnover + pending.impulse_turnover),
        Cell::F(e.double_counted_heat),
    ]
}
