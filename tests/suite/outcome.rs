//! Changing an impact's outcome: extension systems in the `ImpactOutcome` stage
//! (engine/hooks.rs) and the constant-restitution law (`impact.restitution`,
//! docs/model.md §5.4) with its TC model against inelastic collapse. Whatever the outcome,
//! mass, momentum and the energy ledgers must close (docs/model.md §10).

use std::path::Path;

use agglo::bevy_ecs::prelude::*;
use agglo::glam::DVec3;
use agglo::hooks::{ImpactOutcome, PendingImpacts};
use agglo::prelude::*;
use serde_json::json;

use crate::common::{merge, pair, scenario};

fn quick_demo(core: &str) -> Scenario {
    let text = std::fs::read_to_string(Path::new("scenarios/quick_demo.json")).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    merge(&mut value, json!({ "time": { "core": core } }));
    Scenario::from_value(value).unwrap()
}

/// The ledgers closed to the default tolerance (1e-9, docs/model.md §10) all run long.
fn assert_ledgers_close(sim: &Simulation, what: &str) {
    let r = sim.invariants();
    assert!(r.violations.is_empty(), "{what}: {:?}", r.violations);
    assert_eq!(sim.counters().invariant_violations, 0, "{what}");
    for (name, e) in [
        ("mass", r.max_mass_error),
        ("momentum", r.max_momentum_error),
        ("energy", r.max_energy_error),
        ("kinetic", r.max_kinetic_error),
        ("thermal", r.max_thermal_error),
    ] {
        assert!(e <= 1e-9, "{what}: {name} error {e:e}");
    }
}

/// Every bond the law decides becomes a bounce with e = 0.3.
fn no_sticking(mut pending: ResMut<PendingImpacts>) {
    for p in pending.iter_mut() {
        if p.proposal.outcome == ImpactOutcome::Bond {
            p.bounce(0.3);
        }
    }
}

/// Every impact bonds.
fn always_stick(mut pending: ResMut<PendingImpacts>) {
    for p in pending.iter_mut() {
        p.bond();
    }
}

fn with_hook<M>(s: &Scenario, hook: impl IntoScheduleConfigs<ScheduleSystem, M>) -> Simulation {
    let mut builder = Simulation::builder(s).unwrap();
    builder
        .add_impact_outcome_systems(hook)
        .add_default_plugins();
    builder.build().unwrap()
}

use agglo::bevy_ecs::schedule::IntoScheduleConfigs;
use agglo::bevy_ecs::system::ScheduleSystem;

#[test]
fn a_hook_changes_outcomes_and_the_ledgers_still_close() {
    for core in ["events", "stepped"] {
        let s = quick_demo(core);
        let mut plain = Simulation::new(&s).unwrap();
        plain.run().unwrap();
        assert!(
            plain.counters().bonds > 0,
            "{core}: the law bonds in this scene"
        );

        // Registered before the built-in plugins: the order does not matter.
        let mut sim = with_hook(&s, no_sticking);
        assert!(sim.systems().iter().any(|x| x.ends_with("no_sticking")));
        assert!(
            sim.systems()
                .iter()
                .any(|x| x.ends_with("apply_impact_outcomes"))
        );
        sim.run().unwrap();
        let c = sim.counters();
        assert_eq!(c.bonds, 0, "{core}");
        assert_eq!(c.bounces, c.impacts, "{core}");
        assert!(c.impacts > 0);
        // No merge: only fragmentation changes the body count, and only upwards.
        assert!(sim.body_count() >= sim.info().initial_bodies, "{core}");
        assert_ledgers_close(&sim, &format!("{core}, no sticking"));

        let mut sim = with_hook(&s, always_stick);
        sim.run().unwrap();
        let c = sim.counters();
        assert_eq!((c.bounces, c.bonds), (0, c.impacts), "{core}");
        assert!(sim.body_count() < plain.body_count(), "{core}");
        assert_ledgers_close(&sim, &format!("{core}, always stick"));
    }
}

/// A hook that changes nothing gives the run without it, to the bit (the deferred
/// application is the same arithmetic in the same order).
#[test]
fn a_hook_that_changes_nothing_changes_nothing() {
    fn look(pending: Res<PendingImpacts>, mut seen: Local<usize>) {
        *seen += pending.len();
    }
    for core in ["events", "stepped"] {
        let s = quick_demo(core);
        let mut plain = Simulation::new(&s).unwrap();
        plain.run().unwrap();
        let mut sim = with_hook(&s, look);
        sim.run().unwrap();
        assert_eq!(sim.bodies(), plain.bodies(), "{core}");
        assert_eq!(sim.counters(), plain.counters(), "{core}");
        assert_eq!(sim.ledger(), plain.ledger(), "{core}");
    }
}

#[test]
fn outcome_hooks_are_refused_when_a_body_may_have_several_impacts_a_step() {
    let s = scenario(json!({
        "time": { "stepping": { "fixed": { "dt": 1e-5 } } },
        "physics": { "impacts_per_step": "every_contact" }
    }));
    let mut builder = Simulation::builder(&s).unwrap();
    builder
        .add_default_plugins()
        .add_impact_outcome_systems(no_sticking);
    let err = builder.build().err().expect("refused").to_string();
    assert!(err.contains("impacts_per_step"), "{err}");
}

/// Head-on pair at ±1 m/s, frictionless and unreactive (μ0 = α = 0), on either law.
fn head_on(impact: serde_json::Value) -> Scenario {
    let mut patch = pair(-0.0015, 1.0, 0.0015, -1.0);
    merge(
        &mut patch,
        json!({ "material": { "mu0": 0, "alpha": 0 }, "impact": impact, "time": { "end": 0.002 } }),
    );
    scenario(patch)
}

#[test]
fn the_constant_law_bounces_with_e_and_books_the_lost_energy() {
    let e = 0.4;
    for (work_heat, heated) in [("once", true), ("none", false)] {
        let s = head_on(json!({ "restitution": { "constant": e }, "work_heat": work_heat }));
        let mut sim = Simulation::new(&s).unwrap();
        let theta0 = sim.bodies()[0].temperature;
        sim.run().unwrap();
        let c = sim.counters();
        assert_eq!((c.impacts, c.bounces, c.bonds), (1, 1, 0));
        let b = sim.bodies();
        // Equal masses head on: each leaves at e × 1 m/s, reversed (rounding only).
        assert!(
            (b[0].velocity - DVec3::new(-e, 0.0, 0.0)).length() < 1e-14,
            "{b:?}"
        );
        assert!(
            (b[1].velocity - DVec3::new(e, 0.0, 0.0)).length() < 1e-14,
            "{b:?}"
        );
        // Lost: ½ μ (1 − e²) v_n² with μ = m/2, v_n = 2 m/s.
        let m = b[0].mass;
        let lost = 0.5 * (m / 2.0) * (1.0 - e * e) * 4.0;
        let l = sim.ledger();
        assert!((l.impact_dissipation - lost).abs() < 1e-12 * lost);
        assert_eq!(l.reaction_heat, 0.0);
        let heat = m * 1000.0 * (b[0].temperature + b[1].temperature - 2.0 * theta0);
        if heated {
            assert!((heat - lost).abs() < 1e-9 * lost, "{heat} vs {lost}");
        } else {
            assert_eq!(heat, 0.0);
            assert!((l.double_counted_heat + lost).abs() < 1e-12 * lost);
        }
        assert_ledgers_close(&sim, work_heat);
    }
}

/// The constant law as an outcome hook: every impact bounces with e. On a frictionless,
/// unreactive pair the law's own bounce at that e is the granular-gas bounce.
#[test]
fn the_constant_law_as_an_outcome_hook() {
    fn bounce_half(mut pending: ResMut<PendingImpacts>) {
        for p in pending.iter_mut() {
            p.bounce(0.5);
        }
    }
    let mut by_option =
        Simulation::new(&head_on(json!({ "restitution": { "constant": 0.5 } }))).unwrap();
    by_option.run().unwrap();
    let mut by_hook = with_hook(&head_on(json!({})), bounce_half);
    by_hook.run().unwrap();
    let (a, b) = (by_option.bodies(), by_hook.bodies());
    for (x, y) in a.iter().zip(&b) {
        // Two formulas of the same bounce: rounding apart.
        assert!((x.velocity - y.velocity).length() < 1e-14, "{x:?} {y:?}");
        assert!((x.temperature - y.temperature).abs() < 1e-12 * x.temperature);
    }
    assert_eq!(by_hook.counters().bounces, 1);
}

#[test]
fn restitution_outside_zero_one_is_refused_with_the_field() {
    for bad in [1.5, -0.1] {
        let mut v = serde_json::to_value(head_on(json!({}))).unwrap();
        merge(
            &mut v,
            json!({ "impact": { "restitution": { "constant": bad } } }),
        );
        let err = Scenario::from_value(v).expect_err("refused").to_string();
        assert!(
            err.contains("impact.restitution.constant") && err.contains("0 ≤ e ≤ 1"),
            "{err}"
        );
    }
}

/// Three bodies in a line at e = 0.05 < 7 − 4√3: the middle one bounces between the
/// outer two infinitely often in finite time (inelastic collapse; McNamara & Young
/// 1994). Without the TC model the event core can only grind to its step limit; with it
/// the run finishes in a handful of steps.
#[test]
fn the_tc_model_stops_the_collapse_of_three_bodies() {
    let three = |collapse_time: serde_json::Value| {
        scenario(json!({
            "box": { "half_width": 0.01 },
            "cloud": { "count": 3, "bodies": [
                { "position": [-0.004, 0, 0], "velocity": [1, 0, 0] },
                { "position": [0, 0, 0], "velocity": [0, 0, 0] },
                { "position": [0.004, 0, 0], "velocity": [-1, 0, 0] } ] },
            "impact": { "restitution": { "constant": 0.05 }, "collapse_time": collapse_time },
            "time": { "end": 0.01, "core": "events", "max_steps": 20000 }
        }))
    };
    let mut sim = Simulation::new(&three(json!(null))).unwrap();
    sim.run().unwrap();
    assert!(sim.clock().step < 100, "{} steps", sim.clock().step);
    assert!(sim.counters().collapse_elastic > 0);
    assert_ledgers_close(&sim, "three bodies, TC");

    let mut off = Simulation::new(&three(json!(0.0))).unwrap();
    let err = off
        .run()
        .expect_err("collapse without TC stalls")
        .to_string();
    assert!(err.contains("max_steps"), "{err}");
    // Stalled at the collapse time, well before T.
    assert!(off.clock().time < 0.005);
}

/// The case: 1000 bodies at e = 0.5 and volume fraction 0.2 on the event core,
/// run to T = 5 s — about 77 impacts per body (measured: 38 436 impacts), as the cloud
/// cools by Haff's law — reach T, with the ledgers closed.
#[test]
fn a_dense_inelastic_cloud_runs_to_the_end() {
    // φ = N (4/3)π b³ / (2D)³ = 0.2 with b = 1 mm.
    let n = 1000.0;
    let d = (n * 4.0 / 3.0 * std::f64::consts::PI * 1e-9 / 0.2).cbrt() / 2.0;
    let s = scenario(json!({
        "seed": 3,
        "box": { "half_width": d },
        "cloud": { "count": 1000, "radius": 0.001, "v_rel": [1, 1, 1] },
        "impact": { "restitution": { "constant": 0.5 } },
        "time": { "end": 5.0, "core": "events", "stepping": { "adaptive": { "dt_max": 1.0 } } }
    }));
    let mut sim = Simulation::new(&s).unwrap();
    assert_eq!(sim.pipeline().core, "event");
    sim.run().unwrap();
    assert_eq!(sim.clock().time, 5.0);
    let c = sim.counters();
    assert!(c.impacts > 20 * 1000, "{c:?}"); // many impacts per body
    assert_eq!(c.bonds, 0);
    assert_ledgers_close(&sim, "dense cloud");
    // The cloud cooled: most of its kinetic energy was dissipated.
    let l = sim.ledger();
    let k: f64 = sim
        .bodies()
        .iter()
        .map(|b| 0.5 * b.mass * b.velocity.length_squared())
        .sum();
    assert!(
        l.impact_dissipation > 5.0 * k,
        "{} vs {k}",
        l.impact_dissipation
    );
}
