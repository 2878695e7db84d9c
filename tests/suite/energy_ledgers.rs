//! Each energy ledger is checked against its own scale (docs/model.md §10).
//!
//! A deliberately wrong impulse — a test-only plugin written outside the crate — is
//! caught on P04's best case (scenarios/paper2004_best.json) by the kinetic ledger,
//! although the total-energy check, relative to the ~1e11 J that P04's reaction heat
//! turns over, cannot see it (issue 9, part 3). Without the plugin the same scene has no
//! violation; and a force added through `Bodies` is tallied as force work, so it is not
//! mistaken for an error.

use std::path::Path;

use agglo::bevy_ecs::prelude::*;
use agglo::bodies::Bodies;
use agglo::components::Velocity;
use agglo::core_only::SimBuilderCore;
use agglo::glam::DVec3;
use agglo::prelude::*;
use agglo::resources::{ImpactRecords, InvariantReport};
use agglo::systems::impact::resolve_impacts;

/// Relative excess of the wrong impulse: each bounced pair leaves with its relative
/// velocity 1 + 1e-6 times what the impact solve gave it.
const EXCESS: f64 = 1e-6;

/// The wrong impulse's parameter, and how many pairs it changed.
#[derive(Resource, Clone, Copy, Default)]
struct WrongImpulse {
    excess: f64,
    pairs: u64,
}

/// Right after the impact stage, scale the relative velocity of every pair that just
/// bounced by (1 + excess) about the pair's centre-of-mass velocity: equal and opposite
/// extra impulses, so mass and momentum stay exact and only the kinetic energy is wrong
/// (by 2·excess of the pair's relative kinetic energy after the impact).
///
/// It writes `Velocity` directly, as a faulty impact solve would — not through `Bodies`,
/// which would tally the change as force work and so make it legitimate. That is safe on
/// both cores: the bodies it changes have just had an impact, so they are at the current
/// time, and they are already listed in `StepEvents::touched`, from which the event core
/// re-predicts them (stage `TimeStep`) and the diagnostics update their running totals.
fn wrong_impulse(
    mut wrong: ResMut<WrongImpulse>,
    records: Res<ImpactRecords>,
    mut bodies: Query<(&Mass, &mut Velocity), With<Particle>>,
) {
    let factor = 1.0 + wrong.excess;
    for r in records.records.iter().filter(|r| !r.bonded) {
        let Ok([(ma, mut va), (mb, mut vb)]) = bodies.get_many_mut([r.a, r.b]) else {
            continue;
        };
        let v_cm = (ma.0 * va.0 + mb.0 * vb.0) / (ma.0 + mb.0);
        va.0 = v_cm + (va.0 - v_cm) * factor;
        vb.0 = v_cm + (vb.0 - v_cm) * factor;
        wrong.pairs += 1;
    }
}

struct WrongImpulsePlugin(f64);
impl SimPlugin for WrongImpulsePlugin {
    fn name(&self) -> &'static str {
        "wrong_impulse"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.insert_resource(WrongImpulse {
            excess: self.0,
            pairs: 0,
        })
        // As part of the core (SimBuilderCore): an extension's direct write of
        // `Velocity` in the impact stage would be refused on the event core.
        .add_core_systems(StepSystems::Impact, wrong_impulse.after(resolve_impacts));
    }
}

fn p04() -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper2004_best.json");
    Scenario::load(&path).unwrap()
}

/// Run `scenario` with the built-in physics and the given extra plugins.
fn run(scenario: &Scenario, plugins: &[&dyn SimPlugin]) -> Simulation {
    let mut builder = Simulation::builder(scenario).unwrap();
    builder.add_default_plugins();
    for plugin in plugins {
        builder.add_plugin(*plugin);
    }
    let mut sim = builder.build().unwrap();
    sim.run().unwrap();
    sim
}

fn has_violation(report: &InvariantReport, ledger: &str) -> bool {
    report.violations.iter().any(|v| v.contains(ledger))
}

#[test]
fn a_wrong_impulse_is_caught_by_the_kinetic_ledger_on_p04_but_not_by_the_total() {
    // P04 runs on the event core (running totals, O(k) per step); the stepped core
    // re-sums every body at every check.
    let events = p04();
    assert!(events.uses_event_core());
    let mut stepped = p04();
    stepped.time.core = serde_json::from_value(serde_json::json!("stepped")).unwrap();
    assert!(!stepped.uses_event_core());
    for scenario in [events, stepped] {
        caught_by_the_kinetic_ledger_only(&scenario);
    }
}

fn caught_by_the_kinetic_ledger_only(scenario: &Scenario) {
    let tol = scenario.diagnostics.tolerance;

    // Control: the same scene with the right impulses passes every check.
    let right = run(scenario, &[]);
    let report = right.invariants();
    assert_eq!(
        right.counters().invariant_violations,
        0,
        "{:?}",
        report.violations
    );
    assert!(report.max_kinetic_error <= tol && report.max_thermal_error <= tol);

    let sim = run(scenario, &[&WrongImpulsePlugin(EXCESS)]);
    let pairs = sim.world().resource::<WrongImpulse>().pairs;
    assert!(pairs > 100, "the wrong impulse acted on {pairs} bounces");
    let report = sim.invariants();
    eprintln!(
        "{}: wrong impulse on {pairs} bounces: kinetic error {:.3e}, total energy error {:.3e}, \
         thermal {:.3e}, momentum {:.3e} (right impulses: kinetic {:.3e}, total {:.3e})",
        if scenario.uses_event_core() {
            "event core"
        } else {
            "stepped core"
        },
        report.max_kinetic_error,
        report.max_energy_error,
        report.max_thermal_error,
        report.max_momentum_error,
        right.invariants().max_kinetic_error,
        right.invariants().max_energy_error,
    );
    // The kinetic ledger sees it …
    assert!(
        report.max_kinetic_error > tol,
        "kinetic error {:.3e}",
        report.max_kinetic_error
    );
    assert!(
        has_violation(&report, "kinetic energy ledger off by"),
        "{:?}",
        report.violations
    );
    assert!(sim.counters().invariant_violations > 0);
    // … which the total energy alone would have let through: its error stays below the
    // tolerance (and is reported as no violation), as do mass, momentum and heat.
    assert!(
        report.max_energy_error <= tol,
        "total energy error {:.3e}",
        report.max_energy_error
    );
    assert!(only_kinetic(&report), "{:?}", report.violations);
    assert!(report.max_mass_error <= tol && report.max_momentum_error <= tol);
    assert!(report.max_thermal_error <= tol);
}

/// True when every reported violation is the kinetic ledger's.
fn only_kinetic(report: &InvariantReport) -> bool {
    report
        .violations
        .iter()
        .all(|v| v.contains("kinetic energy ledger off by"))
}

/// Linear drag towards a gas moving at 20 m/s along z, relaxation time 2 ms, exact over
/// each interval: a force added through `Bodies`.
#[derive(Resource, Clone, Copy)]
struct Drag;

fn drag(_: Res<Drag>, mut bodies: Bodies) {
    let decay = (-bodies.dt() / 2e-3).exp();
    let gas = DVec3::new(0.0, 0.0, 20.0);
    bodies.update_all(|b| b.velocity = gas + (b.velocity - gas) * decay);
}

/// A force added through `Bodies` is force work: the kinetic ledger closes with it on
/// both cores, and the ledger holds the kinetic energy the force took out.
#[test]
fn force_work_through_bodies_closes_the_kinetic_ledger_on_both_cores() {
    struct DragPlugin;
    impl SimPlugin for DragPlugin {
        fn name(&self) -> &'static str {
            "drag"
        }
        fn build(&self, sim: &mut SimBuilder) {
            sim.insert_resource(Drag).add_force_systems(drag);
        }
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let base = Scenario::load(&path).unwrap();
    for core in ["events", "stepped"] {
        let mut scenario = base.clone();
        scenario.time.core = serde_json::from_value(serde_json::json!(core)).unwrap();
        let sim = run(&scenario, &[&DragPlugin]);
        let report = sim.invariants();
        let ledger = sim.ledger();
        // The force's impulse is booked as well: the momentum check passes along with
        // the energy checks, and nothing is reported.
        let tol = scenario.diagnostics.tolerance;
        assert!(
            report.max_kinetic_error <= tol
                && report.max_thermal_error <= tol
                && report.max_energy_error <= tol
                && report.max_momentum_error <= tol,
            "{core}: kinetic {:.3e}, thermal {:.3e}, total {:.3e}, momentum {:.3e}",
            report.max_kinetic_error,
            report.max_thermal_error,
            report.max_energy_error,
            report.max_momentum_error
        );
        assert!(
            report.violations.is_empty(),
            "{core}: {:?}",
            report.violations
        );
        assert!(
            DVec3::from_array(ledger.force_impulse).z > 0.0,
            "{core}: the gas moves along +z and pushes the cloud that way: {ledger:?}"
        );
        // The drag took kinetic energy out: the ledger says so, and its turnover bounds it.
        assert!(ledger.force_work < 0.0, "{core}: {ledger:?}");
        assert!(ledger.force_work_turnover >= -ledger.force_work);
        // The final kinetic energy is what the two kinetic tallies leave of the initial
        // one. The last kick (at the end of the run) is in the ledger too, and the
        // summary reads the bodies after it: rounding only, relative to the scale.
        let kinetic = |s: &Simulation| {
            s.bodies()
                .iter()
                .map(|b| 0.5 * b.mass * b.velocity.length_squared())
                .sum::<f64>()
        };
        let initial = kinetic(&Simulation::new(&scenario).unwrap());
        let expected = initial - ledger.impact_dissipation + ledger.force_work;
        let scale = initial + ledger.impact_dissipation + ledger.force_work_turnover;
        assert!(
            (kinetic(&sim) - expected).abs() <= 1e-9 * scale,
            "{core}: {} vs {expected}",
            kinetic(&sim)
        );
    }
}

/// With a force acting and booked, the momentum check stays sharp: a momentum change made
/// outside `Bodies` (here 1e-9 of Σ m|v| per step, on one body) is still caught.
#[test]
fn an_unbooked_impulse_is_caught_while_a_booked_force_acts() {
    /// Nudges the body with the smallest id along x, by writing `Velocity` directly.
    #[derive(Resource, Clone, Copy)]
    struct Nudge(f64);
    fn nudge(
        nudge: Res<Nudge>,
        mut bodies: Query<(&ParticleId, &Mass, &mut Velocity), With<Particle>>,
    ) {
        if let Some((_, m, mut v)) = bodies.iter_mut().min_by_key(|(id, _, _)| id.0) {
            v.0.x += nudge.0 / m.0;
        }
    }
    struct Plugins(f64);
    impl SimPlugin for Plugins {
        fn name(&self) -> &'static str {
            "drag_and_nudge"
        }
        fn build(&self, sim: &mut SimBuilder) {
            sim.insert_resource(Drag).add_force_systems(drag);
            if self.0 > 0.0 {
                sim.insert_resource(Nudge(self.0))
                    .add_systems(StepSystems::Impact, nudge.after(resolve_impacts));
            }
        }
    }
    // The stepped core: every body is current at every stage, so the nudge needs no
    // bookkeeping beyond the write itself.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let mut scenario = Scenario::load(&path).unwrap();
    scenario.time.core = serde_json::from_value(serde_json::json!("stepped")).unwrap();
    let clean = run(&scenario, &[&Plugins(0.0)]);
    assert!(clean.invariants().violations.is_empty());
    let scale = clean.invariants().momentum_scale;
    let nudged = run(&scenario, &[&Plugins(1e-9 * scale)]);
    let report = nudged.invariants();
    assert!(
        has_violation(&report, "total momentum off by"),
        "{:?}",
        report.violations
    );
    assert!(report.max_momentum_error > scenario.diagnostics.tolerance);
}
