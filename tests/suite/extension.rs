//! New physics from outside the crate: a plugin adds a gas-drag force through the
//! public API (`add_force_systems` + the `Bodies` parameter), its effect matches the
//! closed form on both cores, and on the event core the forced bodies are re-predicted
//! so that no contact is missed.

use crate::common;

use agglo::bevy_ecs::prelude::*;
use agglo::bodies::Bodies;
use agglo::glam::DVec3;
use agglo::prelude::*;
use common::scenario;
use serde_json::json;

/// Linear drag toward the gas velocity: dv/dt = −(v − u)/τ, integrated exactly per step.
#[derive(Resource, Clone, Copy)]
struct Drag {
    tau: f64,
    gas: DVec3,
}

fn apply_drag(drag: Res<Drag>, mut bodies: Bodies) {
    let decay = (-bodies.dt() / drag.tau).exp();
    bodies.update_all(|b| b.velocity = drag.gas + (b.velocity - drag.gas) * decay);
}

struct DragPlugin(Drag);
impl SimPlugin for DragPlugin {
    fn name(&self) -> &'static str {
        "gas_drag"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.insert_resource(self.0).add_force_systems(apply_drag);
    }
}

fn one_grain(stepping: serde_json::Value) -> Scenario {
    scenario(json!({
        "cloud": { "count": 1, "radius": 0.001, "v_rel": [0, 0, 0],
                   "bodies": [ { "position": [0, 0, 0], "velocity": [10, 0, 0] } ] },
        "time": { "end": 0.01, "stepping": stepping }
    }))
}

fn with_drag(s: &Scenario, drag: Drag) -> Simulation {
    let mut builder = Simulation::builder(s).unwrap();
    builder.add_default_plugins().add_plugin(&DragPlugin(drag));
    builder.build().unwrap()
}

#[test]
fn a_plugin_from_outside_the_crate_adds_physics_in_its_stage() {
    let drag = Drag {
        tau: 0.004,
        gas: DVec3::new(0.0, 2.0, 0.0),
    };
    // Fixed steps (stepped core) and the event core (steps of Δt_max with one body).
    for stepping in [
        json!({ "fixed": { "dt": 1e-4 } }),
        json!({ "adaptive": { "dt_max": 1e-4 } }),
    ] {
        let s = one_grain(stepping.clone());
        let mut sim = with_drag(&s, drag);
        assert!(sim.plugins().contains(&"gas_drag"));
        let systems = sim.systems().join(" ");
        assert!(systems.contains("apply_drag"), "{systems}");
        // The scene needs no cooling (ε = hc = 0) and no fragmentation (γ = ∞): not scheduled.
        assert!(
            !systems.contains("cool_bodies") && !systems.contains("fragment_bodies"),
            "{systems}"
        );
        assert!(systems.contains("resolve_impacts"));
        sim.run().unwrap();
        let b = sim.bodies()[0];
        let decay = (-0.01f64 / 0.004).exp();
        let expected = drag.gas + (DVec3::new(10.0, 0.0, 0.0) - drag.gas) * decay;
        // Exact per-step integration of a linear ODE: only rounding separates the two.
        assert!(
            (b.velocity - expected).length() < 1e-12,
            "{stepping}: {} vs {expected}",
            b.velocity
        );
    }
}

#[test]
fn forced_bodies_are_re_predicted_on_the_event_core() {
    // Two grains at rest, 6 mm apart; a force pushes the left one into the right one.
    // Without re-prediction the event core would never see them approach (their
    // ballistic prediction is "never").
    let s = scenario(json!({
        "cloud": { "count": 2, "radius": 0.001, "bodies": [
            { "position": [-0.003, 0, 0], "velocity": [0, 0, 0] },
            { "position": [0.003, 0, 0], "velocity": [0, 0, 0] } ] },
        "material": { "H0": 1e12 },
        "time": { "end": 0.01, "stepping": { "adaptive": { "dt_max": 1e-4 } } }
    }));
    assert!(s.uses_event_core());
    // A force on grain 0 only (uniform drag would move both grains alike).
    #[derive(Resource, Clone, Copy)]
    struct Jet;
    fn jet(_: Res<Jet>, mut bodies: Bodies) {
        let dt = bodies.dt();
        bodies.update_all(|b| {
            if b.id == 0 {
                b.velocity.x += 2000.0 * dt; // 2000 m/s² on grain 0 only
            }
        });
    }
    struct JetPlugin;
    impl SimPlugin for JetPlugin {
        fn name(&self) -> &'static str {
            "jet"
        }
        fn build(&self, sim: &mut SimBuilder) {
            sim.insert_resource(Jet).add_force_systems(jet);
        }
    }
    // Kicks at the end of each 0.1 ms interval: after k intervals grain 0 has moved
    // a Δt² k(k − 1)/2, so the 4 mm gap closes between k = 20 (3.8 mm) and 21 (4.2 mm).
    let run = |end: f64| {
        let mut s = s.clone();
        s.time.end = end;
        let mut builder = Simulation::builder(&s).unwrap();
        builder.add_default_plugins().add_plugin(&JetPlugin);
        let mut sim = builder.build().unwrap();
        sim.run().unwrap();
        sim
    };
    assert_eq!(run(1.95e-3).counters().impacts, 0, "not yet at 1.95 ms");
    let sim = run(2.15e-3);
    assert_eq!(
        sim.counters().impacts,
        1,
        "the pushed grain met its neighbour"
    );
    assert_eq!(sim.counters().overlap_violations, 0);
    let b = sim.bodies();
    assert!(
        b[1].velocity.x > 0.0,
        "the struck grain moves on: {}",
        b[1].velocity
    );
}
