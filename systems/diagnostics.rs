//! Stage 9 — invariant checks (docs/model.md §10), switchable per scenario.
//!
//! Total mass and momentum must stay constant to rounding; the energy
//! E = Σ ½ m v² + Σ m C θ may change only by the tallied reaction heat, fracture
//! energy, cooling loss, force work and external heat; and each of its two ledgers is
//! checked against its own scale (docs/model.md §10): the kinetic energy Σ ½ m v²
//! changes only by the impact dissipation and the force work, the thermal energy
//! Σ m C θ only by its inflows and outflows. No state may be NaN/∞ and every θ > 0.
//! Violations are counted and the first few described (step, body or ledger, size of
//! the error); the worst relative errors are kept in [`InvariantReport`]. Overlap
//! violations (missed contacts) are counted by contact detection, which sees the pairs.
//!
//! Reads: every body, [`EnergyLedger`]. Writes: [`InvariantReport`], [`Counters`].

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use agglo_engine::error::ValidationIssue;
use agglo_engine::issues::Issues;
use agglo_engine::params::SceneConstants;
use agglo_engine::scene::Material;
use bevy_ecs::system::SystemParam;
use glam::DVec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use agglo_engine::components::{
    Mass, Particle, ParticleId, Position, Radius, Temperature, Velocity,
};
use agglo_engine::resources::{
    Counters, EnergyLedger, InvariantReport, NonFiniteState, SimClock, StepEvents,
};
pub use agglo_engine::totals::{Totals, totals};

// The `diagnostics` section of a scenario: how often and how strictly to check, read by
// the check systems as it is (the doc line below is the schema's description).
/// Invariant checks (docs/model.md §10).
#[derive(Resource, Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Diagnostics {
    /// Check the invariants every `every` steps (and at the end); false = never.
    #[serde(default = "agglo_engine::scene::yes")]
    pub invariants: bool,
    /// Check period in steps.
    #[serde(default = "default_check_every")]
    pub every: u64,
    /// Relative tolerance for mass, momentum and energy checks.
    // Each check is relative to its own scale. Every tally and total is a sum of terms
    // each rounded to ~1e-16 of the energy it moves, and the scales bound those
    // energies; even 10⁶ rounding errors all of one sign stay below 1e-9 of the scale.
    // Measured worst errors on P04's best case (docs/model.md §13): kinetic 5.6e-16,
    // thermal 3.1e-15, total 3.2e-15; on quick_demo 1.1e-15, 2.5e-15, 2.5e-15. A wrong
    // impulse of 1e-6 on each bounce shows as 4.3e-8 in the kinetic ledger
    // (`tests/suite/energy_ledgers.rs`).
    #[serde(default = "default_check_tol")]
    pub tolerance: f64,
}

impl Diagnostics {
    /// Range problems of the `diagnostics` section, by full path.
    pub fn issues(&self) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        if self.every == 0 {
            v.push("diagnostics.every", "≥ 1", 0.0);
        }
        v.positive("diagnostics.tolerance", self.tolerance);
        v.issues
    }
}

fn default_check_every() -> u64 {
    1
}
fn default_check_tol() -> f64 {
    1e-9
}

impl Default for Diagnostics {
    fn default() -> Self {
        Self {
            invariants: true,
            every: default_check_every(),
            tolerance: default_check_tol(),
        }
    }
}

const MAX_REPORTED: usize = 20;

/// The kinetic and thermal energy at t = 0 [J], the references of the two ledgers.
///
/// Held in each check system's `Local`, which bevy fills from the world when the system
/// is initialised — when the pipeline is built, before the first step — so it sees the
/// initial cloud (on the event core every body is then at t_ref = 0). A simulation
/// built without its initial cloud, to be resumed (`SimBuilder::resuming`), gives them
/// as a resource instead, inserted before it is built.
#[derive(Resource, Debug, Clone, Copy, PartialEq)]
pub struct InitialEnergies {
    /// Σ ½ m v² at t = 0 [J].
    pub kinetic: f64,
    /// Σ m C θ at t = 0 [J].
    pub thermal: f64,
}

impl FromWorld for InitialEnergies {
    fn from_world(world: &mut World) -> Self {
        if let Some(given) = world.get_resource::<Self>() {
            return *given;
        }
        let c = world.resource::<Material>().C;
        let mut query = world.query_filtered::<(&Mass, &Velocity, &Temperature), With<Particle>>();
        let t = totals(query.iter(world).map(|(m, v, t)| (m.0, v.0, t.0)), c);
        Self {
            kinetic: t.kinetic,
            thermal: t.thermal,
        }
    }
}

/// What a check reads (its settings, the scene's constants, the clock, the ledger and the
/// energies at t = 0) and where it records what it finds (the report and the violation
/// counter): one system parameter for both check systems.
#[derive(SystemParam)]
pub struct Checks<'w, 's> {
    settings: Res<'w, Diagnostics>,
    scene: SceneConstants<'w>,
    clock: Res<'w, SimClock>,
    ledger: Res<'w, EnergyLedger>,
    initial: Local<'s, InitialEnergies>,
    report: ResMut<'w, InvariantReport>,
    counters: ResMut<'w, Counters>,
    non_finite: ResMut<'w, NonFiniteState>,
}

/// Stage 9 as a system: check mass, momentum and the energy ledgers every so many steps
/// and record the worst relative errors.
pub fn check_invariants(mut checks: Checks, bodies: TotalsQuery) {
    let clock = *checks.clock;
    // clock.step is the index of the step being finished; check after every `every`-th.
    if !(clock.step + 1).is_multiple_of(checks.settings.every)
        && clock.time + clock.dt < checks.scene.time.end
    {
        return;
    }
    checks.check_now(&bodies);
}

/// Note the first NaN or infinite quantity of a body (the run then stops with
/// `SimError::NonFinite`, naming it). Called only for a body already found invalid.
#[allow(clippy::too_many_arguments)]
fn note_non_finite(
    state: &mut NonFiniteState,
    step: u64,
    id: u64,
    p: DVec3,
    v: DVec3,
    m: f64,
    b: f64,
    t: f64,
) {
    state.check_body(
        step,
        id,
        [
            ("position x", p.x),
            ("position y", p.y),
            ("position z", p.z),
            ("velocity x", v.x),
            ("velocity y", v.y),
            ("velocity z", v.z),
            ("mass", m),
            ("radius", b),
            ("temperature", t),
        ],
    );
}

/// Relative error of the energy ledger: |E − (E0 + reaction heat − fracture energy −
/// cooling loss + force work + external heat)| over the energy turned over, E0 + reaction
/// heat + fracture energy + cooling loss + Σ|force work| + |external heat|. Rounding in
/// the tallies scales with the heat flowing through them, not with E0: in P04's best case
/// α heats the cloud by ~1e7 × E0 and radiation takes it out again, so an error relative
/// to E0 alone flags rounding as violations. The same scale hides any error in the
/// kinetic energy (~1e2 J against ~1e11 J turned over), which [`kinetic_error`] checks.
pub fn energy_error(now: f64, initial: f64, ledger: &EnergyLedger) -> f64 {
    let expected = initial + ledger.reaction_heat - ledger.fracture_energy - ledger.cooling_loss
        + ledger.force_work
        + ledger.external_heat
        + ledger.double_counted_heat;
    let turnover = initial.abs()
        + ledger.double_counted_heat.abs()
        + ledger.reaction_heat.abs()
        + ledger.fracture_energy.abs()
        + ledger.cooling_loss.abs()
        + ledger.force_work_turnover.abs()
        + ledger.external_heat.abs();
    relative(now - expected, turnover)
}

/// Relative error of the kinetic ledger (docs/model.md §10): |K − (K0 − D + F)| over
/// K0 + D + Σ|F|, with K = Σ ½ m v² [J], D the impact dissipation and F the force work.
/// Nothing else changes K: a bond's common velocity, merging and fragmentation conserve
/// it to rounding, and fracture energy comes out of heat. Its scale is the kinetic
/// energy that ever existed or moved — ~1e2 J in P04's best case, where the total
/// energy's scale is ~1e11 J — so an error of 1e-9 of the cloud's motion shows.
pub fn kinetic_error(now: f64, initial: f64, ledger: &EnergyLedger) -> f64 {
    let expected = initial - ledger.impact_dissipation + ledger.force_work;
    let scale = initial.abs() + ledger.impact_dissipation.abs() + ledger.force_work_turnover.abs();
    relative(now - expected, scale)
}

/// Relative error of the thermal ledger (docs/model.md §10): |Θ − (Θ0 + D + R − Z − L +
/// X)| over Θ0 + D + R + Z + L + |X|, with Θ = Σ m C θ [J], inflows D (impact
/// dissipation turned to heat) and R (reaction heat), outflows Z (fracture energy) and
/// L (cooling loss), and X the heat added by extensions.
pub fn thermal_error(now: f64, initial: f64, ledger: &EnergyLedger) -> f64 {
    let expected = initial + ledger.impact_dissipation + ledger.reaction_heat
        - ledger.fracture_energy
        - ledger.cooling_loss
        + ledger.external_heat
        + ledger.double_counted_heat;
    let scale = initial.abs()
        + ledger.double_counted_heat.abs()
        + ledger.impact_dissipation.abs()
        + ledger.reaction_heat.abs()
        + ledger.fracture_energy.abs()
        + ledger.cooling_loss.abs()
        + ledger.external_heat.abs();
    relative(now - expected, scale)
}

/// |error| / scale, guarded against a zero scale.
fn relative(error: f64, scale: f64) -> f64 {
    error.abs() / scale.max(f64::MIN_POSITIVE)
}

/// Compensated (Neumaier) running sums of the totals, updated from the bodies each step
/// touches (event core): O(k) per step instead of O(N).
#[derive(Resource, Debug, Clone, Default)]
pub struct RunningTotals {
    /// Mass, momentum x, y, z, kinetic energy, thermal energy: (sum, compensation).
    sums: [(f64, f64); 6],
    /// Steps between full recomputations (at least the initial body count).
    pub full_every: u64,
}

/// The summed quantities of [`RunningTotals`], in its order.
fn running_values(t: &Totals) -> [f64; 6] {
    [
        t.mass,
        t.momentum.x,
        t.momentum.y,
        t.momentum.z,
        t.kinetic,
        t.thermal,
    ]
}

impl RunningTotals {
    /// Totals running from `start`, recomputed in full (rounding reset) every
    /// `full_every` steps (at least 1).
    pub fn new(start: &Totals, full_every: u64) -> Self {
        let mut r = Self {
            sums: [(0.0, 0.0); 6],
            full_every: full_every.max(1),
        };
        r.reset(start);
        r
    }

    fn reset(&mut self, t: &Totals) {
        for (s, v) in self.sums.iter_mut().zip(running_values(t)) {
            *s = (v, 0.0);
        }
    }

    fn add(&mut self, t: &Totals, sign: f64) {
        for ((sum, c), v) in self.sums.iter_mut().zip(running_values(t)) {
            let x = sign * v;
            let next = *sum + x;
            *c += if sum.abs() >= x.abs() {
                (*sum - next) + x
            } else {
                (x - next) + *sum
            };
            *sum = next;
        }
    }

    fn value(&self, k: usize) -> f64 {
        self.sums[k].0 + self.sums[k].1
    }

    /// Start again from the totals over every body now in the world (the restart part
    /// of the event core's checks: at a checkpoint the bodies are brought to the current
    /// time, which the running totals do not follow, so they are recomputed — in the
    /// run that takes the checkpoint and in a resumed one alike).
    pub fn recompute(world: &mut World) -> Result<(), String> {
        let start = initial_totals(world);
        let mut running = world
            .get_resource_mut::<RunningTotals>()
            .ok_or("the scene keeps no running totals")?;
        running.reset(&start);
        Ok(())
    }

    /// The running totals (without Σ m|v|, which is not kept).
    pub fn totals(&self) -> Totals {
        Totals {
            mass: self.value(0),
            momentum: DVec3::new(self.value(1), self.value(2), self.value(3)),
            momentum_scale: 0.0,
            kinetic: self.value(4),
            thermal: self.value(5),
        }
    }
}

/// What the invariant checks read of a body: its state and totals.
#[derive(QueryData)]
pub struct CheckedBody {
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
    /// Position [m].
    pub position: &'static Position,
    /// Velocity [m/s].
    pub velocity: &'static Velocity,
    /// Mass [kg].
    pub mass: &'static Mass,
    /// Radius [m].
    pub radius: &'static Radius,
    /// Temperature θ [K].
    pub temperature: &'static Temperature,
}

type TotalsQuery<'w, 's> = Query<'w, 's, CheckedBody, With<Particle>>;

/// The event core's checks: the totals follow the bodies each step touched; every
/// `full_every` steps and at the end they are recomputed over all bodies.
pub fn check_step_totals(
    mut checks: Checks,
    events: Res<StepEvents>,
    bodies: TotalsQuery,
    mut running: ResMut<RunningTotals>,
    mut seen: Local<Vec<(Entity, Totals)>>,
) {
    let clock = *checks.clock;
    let c = checks.scene.material.C;
    seen.clear();
    seen.extend_from_slice(&events.touched);
    // The first record of each body is its state before the step changed it.
    seen.sort_by_key(|x| x.0);
    seen.dedup_by_key(|x| x.0);
    let mut violations = Vec::new();
    let step = clock.step;
    let changed = seen
        .iter()
        .map(|x| x.0)
        .chain(events.spawned.iter().copied());
    for entity in changed {
        let Ok(CheckedBodyItem {
            id,
            position: p,
            velocity: v,
            mass: m,
            radius: b,
            temperature: t,
        }) = bodies.get(entity)
        else {
            continue; // removed this step
        };
        let finite = p.0.is_finite() && v.0.is_finite() && m.0.is_finite() && b.0.is_finite();
        if !finite || !t.0.is_finite() || t.0 <= 0.0 || m.0 <= 0.0 {
            violations.push(format!(
                "step {step}: body {} has invalid state (r = {}, v = {}, m = {:e}, b = {:e}, θ = {:e})",
                id.0, p.0, v.0, m.0, b.0, t.0
            ));
            note_non_finite(&mut checks.non_finite, step, id.0, p.0, v.0, m.0, b.0, t.0);
        }
        running.add(&Totals::of_body(m.0, v.0, t.0, c), 1.0);
    }
    for (_, before) in seen.iter() {
        running.add(before, -1.0);
    }
    checks.record(violations);
    let last = clock.time + clock.dt >= checks.scene.time.end;
    if (clock.step + 1).is_multiple_of(running.full_every) || last {
        // Full recomputation: also catches a change no system reported.
        checks.check_now(&bodies);
        let all = totals(
            bodies
                .iter()
                .map(|b| (b.mass.0, b.velocity.0, b.temperature.0)),
            c,
        );
        running.reset(&all);
    } else if (clock.step + 1).is_multiple_of(checks.settings.every) {
        let now = running.totals();
        checks.compare(&now);
    }
}

impl Checks<'_, '_> {
    /// Count `violations` and keep the first few in the report.
    fn record(&mut self, violations: Vec<String>) {
        self.counters.invariant_violations += violations.len() as u64;
        for v in violations {
            if self.report.violations.len() < MAX_REPORTED {
                self.report.violations.push(v);
            }
        }
    }

    /// Compare totals with the reference and the ledgers; record violations.
    fn compare(&mut self, now: &Totals) {
        let step = self.clock.step;
        let (settings, ledger, initial) = (&*self.settings, &*self.ledger, &*self.initial);
        let report = &mut *self.report;
        let mut violations: Vec<String> = Vec::new();
        let mass_error = (now.mass - report.initial_mass).abs() / report.initial_mass;
        // P may change only by the impulse of external forces, booked by `Bodies`; the
        // scale is Σ m|v| at t = 0 plus the momentum those forces moved.
        let p0 = DVec3::from_array(report.initial_momentum);
        let impulse = DVec3::from_array(ledger.force_impulse);
        let momentum_scale = report.momentum_scale + ledger.force_impulse_turnover;
        let momentum_error =
            (now.momentum - p0 - impulse).length() / momentum_scale.max(f64::MIN_POSITIVE);
        let energy_error = energy_error(now.energy(), report.initial_energy, ledger);
        let kinetic_error = kinetic_error(now.kinetic, initial.kinetic, ledger);
        let thermal_error = thermal_error(now.thermal, initial.thermal, ledger);
        let tol = settings.tolerance;
        if mass_error.is_nan() || mass_error > tol {
            violations.push(format!(
                "step {step}: total mass off by {mass_error:.3e} (relative)"
            ));
        }
        if momentum_error.is_nan() || momentum_error > tol {
            violations.push(format!(
                "step {step}: total momentum off by {momentum_error:.3e} (relative to Σ m|v| + the momentum forces moved)"
            ));
        }
        if energy_error.is_nan() || energy_error > tol {
            violations.push(format!(
            "step {step}: energy ledger off by {energy_error:.3e} (relative to E0 + energy turned over)"
        ));
        }
        if kinetic_error.is_nan() || kinetic_error > tol {
            violations.push(format!(
                "step {step}: kinetic energy ledger off by {kinetic_error:.3e} (relative to \
             E_kin0 + impact dissipation + Σ|force work|)"
            ));
        }
        if thermal_error.is_nan() || thermal_error > tol {
            violations.push(format!(
                "step {step}: thermal energy ledger off by {thermal_error:.3e} (relative to \
             Σ m C θ at t = 0 + heat in + heat out)"
            ));
        }
        report.max_mass_error = report.max_mass_error.max(mass_error);
        report.max_momentum_error = report.max_momentum_error.max(momentum_error);
        report.max_energy_error = report.max_energy_error.max(energy_error);
        report.max_kinetic_error = report.max_kinetic_error.max(kinetic_error);
        report.max_thermal_error = report.max_thermal_error.max(thermal_error);
        self.record(violations);
    }

    /// Run every check once and record violations.
    pub fn check_now(&mut self, bodies: &TotalsQuery) {
        let step = self.clock.step;
        let mut violations: Vec<String> = Vec::new();
        for CheckedBodyItem {
            id,
            position: p,
            velocity: v,
            mass: m,
            radius: b,
            temperature: t,
        } in bodies.iter()
        {
            let finite = p.0.is_finite() && v.0.is_finite() && m.0.is_finite() && b.0.is_finite();
            if !finite || !t.0.is_finite() || t.0 <= 0.0 || m.0 <= 0.0 {
                violations.push(format!(
                "step {step}: body {} has invalid state (r = {}, v = {}, m = {:e}, b = {:e}, θ = {:e})",
                id.0, p.0, v.0, m.0, b.0, t.0
            ));
                note_non_finite(&mut self.non_finite, step, id.0, p.0, v.0, m.0, b.0, t.0);
            }
        }
        self.record(violations);
        let now = totals(
            bodies
                .iter()
                .map(|b| (b.mass.0, b.velocity.0, b.temperature.0)),
            self.scene.material.C,
        );
        self.compare(&now);
    }
}

/// Invariant checks (stage 9), when `diagnostics.invariants` is on.
pub struct DiagnosticsPlugin;
impl SimPlugin for DiagnosticsPlugin {
    fn name(&self) -> &'static str {
        "diagnostics"
    }
    fn build(&self, sim: &mut SimBuilder) {
        // The scene's `diagnostics` section, or the defaults when it gives none.
        let d = sim
            .world_mut()
            .get_resource_or_init::<Diagnostics>()
            .clone();
        if d.invariants && sim.uses_event_core() {
            let start = initial_totals(sim.world_mut());
            let full_every = d.every.max(sim.info().initial_bodies as u64);
            sim.insert_resource(RunningTotals::new(&start, full_every))
                .add_core_systems(StepSystems::Diagnostics, check_step_totals)
                .add_restart_part(agglo_engine::restart::RestartPart {
                    name: "running_totals",
                    save: |_| Vec::new(),
                    load: |world, _| RunningTotals::recompute(world),
                });
        } else if d.invariants {
            sim.add_core_systems(StepSystems::Diagnostics, check_invariants);
        } else {
            sim.leave_out("diagnostics off: diagnostics.invariants = false");
        }
    }
}

/// Totals over the bodies now in the world.
pub(crate) fn initial_totals(world: &mut World) -> Totals {
    let c = world.resource::<Material>().C;
    let rows: Vec<_> = world
        .query_filtered::<(&Mass, &Velocity, &Temperature), With<Particle>>()
        .iter(world)
        .map(|(m, v, t)| (m.0, v.0, t.0))
        .collect();
    totals(rows.into_iter(), c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_error_is_relative_to_the_energy_turned_over() {
        // E0 = 1e4 J; 1.5e11 J of reaction heat in, nearly all radiated out again.
        let ledger = EnergyLedger {
            reaction_heat: 1.5e11,
            cooling_loss: 1.5e11 - 1.0,
            ..Default::default()
        };
        let expected = 1e4 + 1.0;
        // A rounding-size mismatch (1e-16 of the flows ≈ 1.5e-5 J) is not a violation …
        assert!(energy_error(expected + 1.5e-5, 1e4, &ledger) < 1e-15);
        // … but energy really missing (1 % of the heat that flowed) is.
        assert!(energy_error(expected - 3e9, 1e4, &ledger) > 1e-3);
        // Without flows this is the error relative to E0, as before.
        let none = EnergyLedger::default();
        assert!((energy_error(1e4 * (1.0 + 1e-6), 1e4, &none) - 1e-6).abs() < 1e-15);
    }

    /// P04-like flows: K0 = 150 J, 80 J dissipated, 1.5e11 J of reaction heat in and
    /// nearly all of it radiated out; a drag took 10 J out and put 2 J in elsewhere.
    fn p04_like() -> (EnergyLedger, f64, f64) {
        let ledger = EnergyLedger {
            reaction_heat: 1.5e11,
            cooling_loss: 1.5e11 - 1e3,
            impact_dissipation: 80.0,
            force_work: -8.0,
            force_work_turnover: 12.0,
            ..Default::default()
        };
        (ledger, 150.0, 1e4)
    }

    #[test]
    fn kinetic_error_is_relative_to_the_kinetic_scale() {
        let (ledger, k0, _) = p04_like();
        let expected = 150.0 - 80.0 - 8.0;
        let scale = 150.0 + 80.0 + 12.0;
        assert_eq!(kinetic_error(expected, k0, &ledger), 0.0);
        // 1 µJ missing from the motion: 1e-6 / 242 of the kinetic scale …
        let e = kinetic_error(expected - 1e-6, k0, &ledger);
        // (to the rounding of 62 J, 1e-14 J).
        assert!((e - 1e-6 / scale).abs() < 1e-7 * e, "{e}");
        // … which the total check, relative to ~3e11 J turned over, cannot see: the 1 µJ
        // is below the rounding of the 1.5e11 J flows themselves (~3e-5 J).
        let e0 = k0 + 1e4;
        let total = e0 + ledger.reaction_heat - ledger.cooling_loss + ledger.force_work;
        assert!(energy_error(total - 1e-6, e0, &ledger) < 1e-15);
    }

    #[test]
    fn thermal_error_counts_dissipation_as_heat_in() {
        let (ledger, _, theta0) = p04_like();
        let expected = theta0 + 80.0 + 1.5e11 - (1.5e11 - 1e3);
        let scale = theta0 + 80.0 + 1.5e11 + (1.5e11 - 1e3);
        // Rounding only: a few ulp of the 1.5e11 J flows.
        assert!(thermal_error(expected, theta0, &ledger) < 1e-15);
        // Heat the ledger does not know of (dissipation counted twice): 80 J of 3e11 J.
        let e = thermal_error(expected + 80.0, theta0, &ledger);
        assert!((e - 80.0 / scale).abs() < 1e-6 * e, "{e}");
        // Heat added by an extension is an inflow.
        let heated = EnergyLedger {
            external_heat: 5.0,
            ..ledger
        };
        assert!(thermal_error(expected + 5.0, theta0, &heated) < 1e-15);
    }
}
