//! New physics from outside the crate: linear gas drag as a plugin.
//!
//! A `SimPlugin` inserts its parameters as a resource and adds a force system with
//! `add_force_systems`. The system reads and writes bodies through `Bodies`, which
//! brings each body to the current time first (the event core keeps bodies at their
//! own reference times) and has the event core re-predict every body it changed.
//! Run with `cargo run --release --example gas_drag`.

use agglo::bevy_ecs::prelude::*;
use agglo::bodies::Bodies;
use agglo::glam::DVec3;
use agglo::prelude::*;

/// dv/dt = −(v − u)/τ toward the gas velocity u, integrated exactly over each step.
#[derive(Resource, Clone, Copy)]
struct GasDrag {
    /// Relaxation time τ [s].
    tau: f64,
    /// Gas velocity u [m/s].
    gas: DVec3,
}

fn apply_gas_drag(drag: Res<GasDrag>, mut bodies: Bodies) {
    let decay = (-bodies.dt() / drag.tau).exp();
    bodies.update_all(|b| b.velocity = drag.gas + (b.velocity - drag.gas) * decay);
}

struct GasDragPlugin(GasDrag);

impl SimPlugin for GasDragPlugin {
    fn name(&self) -> &'static str {
        "gas_drag"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.insert_resource(self.0)
            .add_force_systems(apply_gas_drag);
    }
}

fn main() -> anyhow::Result<()> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let scenario = Scenario::load(&path)?;
    for tau in [f64::INFINITY, 1e-3, 1e-4] {
        let mut builder = Simulation::builder(&scenario)?;
        builder.add_default_plugins();
        if tau.is_finite() {
            builder.add_plugin(&GasDragPlugin(GasDrag {
                tau,
                gas: DVec3::new(0.0, 0.0, 20.0),
            }));
        }
        let mut sim = builder.build()?;
        sim.run()?;
        let s = sim.summary();
        println!(
            "τ = {tau:>8.1e} s: {} impacts, {} bonds, b_f/b0 = {:.3}",
            s.counters.impacts, s.counters.bonds, s.growth.growth_ratio
        );
    }
    Ok(())
}
