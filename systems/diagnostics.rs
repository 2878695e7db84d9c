//! Stage 9 — invariant checks (MODEL.md §10), switchable per scenario.
//!
//! Total mass and momentum must stay constant to rounding; the energy
//! E = Σ ½ m v² + Σ m C θ may change only by the tallied reaction heat, fracture
//! energy and cooling loss; no state may be NaN/∞ and every θ > 0. Violations are
//! counted and the first few described (step, body, size of the error); the worst
//! relative errors are kept in [`InvariantReport`]. Overlap violations (missed
//! contacts) are counted by contact detection, which sees the pairs.
//!
//! Reads: every body, [`EnergyLedger`]. Writes: [`InvariantReport`], [`Counters`].

use bevy_ecs::prelude::*;
use glam::DVec3;

use crate::components::{Mass, Particle, ParticleId, Position, Radius, Temperature, Velocity};
use crate::resources::{Counters, EnergyLedger, InvariantReport, MaterialConstants, SimClock};

/// How often and how strictly to check.
#[derive(Resource, Debug, Clone, Copy, PartialEq)]
pub struct DiagnosticsSettings {
    pub every: u64,
    /// Relative tolerance of the mass, momentum and energy checks.
    pub tolerance: f64,
}

/// Totals of the conserved (or tallied) quantities.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Totals {
    pub mass: f64,
    pub momentum: DVec3,
    /// Σ m |v| [kg m/s].
    pub momentum_scale: f64,
    pub kinetic: f64,
    pub thermal: f64,
}

impl Totals {
    pub fn energy(&self) -> f64 {
        self.kinetic + self.thermal
    }
}

/// Sum the totals over (mass, velocity, temperature) rows.
pub fn totals(rows: impl Iterator<Item = (f64, DVec3, f64)>, heat_capacity: f64) -> Totals {
    let mut t = Totals::default();
    for (m, v, theta) in rows {
        t.mass += m;
        t.momentum += m * v;
        t.momentum_scale += m * v.length();
        t.kinetic += 0.5 * m * v.length_squared();
        t.thermal += m * heat_capacity * theta;
    }
    t
}

const MAX_REPORTED: usize = 20;

/// The system.
#[allow(clippy::type_complexity)]
pub fn check_invariants(
    settings: Res<DiagnosticsSettings>,
    material: Res<MaterialConstants>,
    clock: Res<SimClock>,
    ledger: Res<EnergyLedger>,
    bodies: Query<
        (
            &ParticleId,
            &Position,
            &Velocity,
            &Mass,
            &Radius,
            &Temperature,
        ),
        With<Particle>,
    >,
    mut report: ResMut<InvariantReport>,
    mut counters: ResMut<Counters>,
) {
    // clock.step is the index of the step being finished; check after every `every`-th.
    if !(clock.step + 1).is_multiple_of(settings.every) && clock.time + clock.dt < clock.end {
        return;
    }
    check_now(
        &settings,
        &material,
        clock.step,
        &ledger,
        &bodies,
        &mut report,
        &mut counters,
    );
}

/// Run every check once and record violations.
#[allow(clippy::type_complexity)]
pub fn check_now(
    settings: &DiagnosticsSettings,
    material: &MaterialConstants,
    step: u64,
    ledger: &EnergyLedger,
    bodies: &Query<
        (
            &ParticleId,
            &Position,
            &Velocity,
            &Mass,
            &Radius,
            &Temperature,
        ),
        With<Particle>,
    >,
    report: &mut InvariantReport,
    counters: &mut Counters,
) {
    let mut violations: Vec<String> = Vec::new();
    for (id, p, v, m, b, t) in bodies.iter() {
        let finite = p.0.is_finite() && v.0.is_finite() && m.0.is_finite() && b.0.is_finite();
        if !finite || !t.0.is_finite() || t.0 <= 0.0 || m.0 <= 0.0 {
            violations.push(format!(
                "step {step}: body {} has invalid state (r = {}, v = {}, m = {:e}, b = {:e}, θ = {:e})",
                id.0, p.0, v.0, m.0, b.0, t.0
            ));
        }
    }
    let now = totals(
        bodies.iter().map(|(_, _, v, m, _, t)| (m.0, v.0, t.0)),
        material.heat_capacity,
    );
    let mass_error = (now.mass - report.initial_mass).abs() / report.initial_mass;
    let p0 = DVec3::from_array(report.initial_momentum);
    let momentum_error =
        (now.momentum - p0).length() / report.momentum_scale.max(f64::MIN_POSITIVE);
    let expected_energy =
        report.initial_energy + ledger.reaction_heat - ledger.fracture_energy - ledger.cooling_loss;
    // Relative to everything that entered the books: E0 alone would make a run whose
    // reaction heat dwarfs E0 (P04: θ → 10⁹ K) fail on rounding of the large terms.
    let energy_scale = report.initial_energy.abs()
        + ledger.reaction_heat
        + ledger.fracture_energy
        + ledger.cooling_loss.abs();
    let energy_error = (now.energy() - expected_energy).abs() / energy_scale.max(f64::MIN_POSITIVE);
    let tol = settings.tolerance;
    if mass_error.is_nan() || mass_error > tol {
        violations.push(format!(
            "step {step}: total mass off by {mass_error:.3e} (relative)"
        ));
    }
    if momentum_error.is_nan() || momentum_error > tol {
        violations.push(format!(
            "step {step}: total momentum off by {momentum_error:.3e} (relative to Σ m|v|)"
        ));
    }
    if energy_error.is_nan() || energy_error > tol {
        violations.push(format!(
            "step {step}: energy ledger off by {energy_error:.3e} (relative to E0 + Σ|ledger|)"
        ));
    }
    report.max_mass_error = report.max_mass_error.max(mass_error);
    report.max_momentum_error = report.max_momentum_error.max(momentum_error);
    report.max_energy_error = report.max_energy_error.max(energy_error);
    counters.invariant_violations += violations.len() as u64;
    for v in violations {
        if report.violations.len() < MAX_REPORTED {
            report.violations.push(v);
        }
    }
}
