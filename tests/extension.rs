//! New physics from outside the crate: a plugin adds a gas-drag system through the
//! public API, and its effect matches the closed form.

use agglo::bevy_ecs::prelude::*;
use agglo::glam::DVec3;
use agglo::prelude::*;

/// Linear drag toward the gas velocity: dv/dt = −(v − u)/τ, integrated exactly per step.
#[derive(Resource, Clone, Copy)]
struct Drag {
    tau: f64,
    gas: DVec3,
}

fn apply_drag(
    drag: Res<Drag>,
    clock: Res<SimClock>,
    mut bodies: Query<&mut Velocity, With<Particle>>,
) {
    let decay = (-clock.dt / drag.tau).exp();
    for mut v in &mut bodies {
        v.0 = drag.gas + (v.0 - drag.gas) * decay;
    }
}

struct DragPlugin(Drag);
impl SimPlugin for DragPlugin {
    fn name(&self) -> &'static str {
        "gas_drag"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.insert_resource(self.0)
            .add_systems(StepSystems::Cooling, apply_drag);
    }
}

#[test]
fn a_plugin_from_outside_the_crate_adds_physics_in_its_stage() {
    let scenario = Scenario::from_json(
        r#"{ "name": "drag", "seed": 1, "box": { "half_width": 0.01 },
             "cloud": { "count": 1, "radius": 0.001, "v_rel": [0, 0, 0],
                        "bodies": [ { "position": [0, 0, 0], "velocity": [10, 0, 0] } ] },
             "material": { "rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300 },
             "time": { "end": 0.01, "stepping": { "fixed": { "dt": 1e-4 } } } }"#,
    )
    .unwrap();
    let drag = Drag {
        tau: 0.004,
        gas: DVec3::new(0.0, 2.0, 0.0),
    };
    let mut builder = Simulation::builder(&scenario).unwrap();
    builder.add_default_plugins().add_plugin(&DragPlugin(drag));
    let mut sim = builder.build().unwrap();
    assert!(sim.plugins().contains(&"gas_drag"));
    let systems = sim.systems().join(" ");
    assert!(systems.contains("apply_drag"), "{systems}");
    // The scene needs no cooling (ε = hc = 0) and no fragmentation (γ = ∞): not scheduled.
    assert!(
        !systems.contains("cool_bodies") && !systems.contains("fragment_bodies"),
        "{systems}"
    );
    assert!(systems.contains("detect_contacts") && systems.contains("resolve_impacts"));
    sim.run().unwrap();
    let v = sim.bodies()[0].velocity;
    let decay = (-0.01f64 / 0.004).exp();
    let expected = drag.gas + (DVec3::new(10.0, 0.0, 0.0) - drag.gas) * decay;
    // Exact per-step integration of a linear ODE: only rounding separates the two.
    assert!((v - expected).length() < 1e-12, "{v} vs {expected}");
}
