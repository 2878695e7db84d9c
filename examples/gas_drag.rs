//! New physics from outside the crate: gas drag and settling as a field.
//!
//! Grains in a gas relax toward the gas velocity u with a relaxation time τ that grows
//! with their size (Epstein drag: τ = ρ b / (ρ_g v_th) for a sphere of density ρ and
//! radius b), and settle under gravity toward u + g τ: merged grains settle faster than
//! primaries and sweep them up — differential settling, a classic agglomeration
//! mechanism. A plugin declares the field with `SimBuilder::set_field`; both cores fly
//! it in closed form (docs/model.md §4.7), so on the event core it costs a short root
//! search per predicted pair instead of a kick to every body every event.
//!
//! The example runs the scene on the event core and on the stepped core (short steps)
//! with and without the field and prints what each did.
//! Run with `cargo run --release --example gas_drag`.

use agglo::glam::DVec3;
use agglo::prelude::*;

/// Epstein drag toward `gas` with settling under `gravity`, τ0 for a primary grain.
pub struct SettlingPlugin {
    /// g [m/s²].
    pub gravity: DVec3,
    /// Gas velocity u [m/s].
    pub gas: DVec3,
    /// Relaxation time of a primary grain [s].
    pub tau0: f64,
}

/// The example's settling: g = 2e4 m/s² (g τ0 = 20 m/s, the scene's random speeds), gas
/// flowing up at 20 m/s so that primaries hover and merged grains fall through them.
pub const SETTLING: SettlingPlugin = SettlingPlugin {
    gravity: DVec3::new(0.0, 0.0, -2e4),
    gas: DVec3::new(0.0, 0.0, 20.0),
    tau0: 1e-3,
};

impl SimPlugin for SettlingPlugin {
    fn name(&self) -> &'static str {
        "settling"
    }
    fn build(&self, sim: &mut SimBuilder) {
        // τ = ρ b / (ρ_g v_th): pick ρ_g v_th so that a primary has τ0.
        let rho = sim.resource::<Material>().rho;
        let b0 = sim.resource::<agglo::cloud::PrimaryGrain>().radius;
        let thermal_speed = 400.0; // m/s
        let gas_density = rho * b0 / (self.tau0 * thermal_speed);
        sim.set_field(Field {
            gravity: self.gravity.to_array(),
            drag: Some(Drag {
                gas_velocity: self.gas.to_array(),
                relaxation: Relaxation::Epstein {
                    gas_density,
                    thermal_speed,
                },
            }),
        });
    }
}

/// Run `scenario` with the built-in physics, and the settling field if `settling`.
pub fn run(scenario: &Scenario, settling: Option<&SettlingPlugin>) -> anyhow::Result<Simulation> {
    let mut builder = Simulation::builder(scenario)?;
    builder.add_default_plugins();
    if let Some(plugin) = settling {
        builder.add_plugin(plugin);
    }
    let mut sim = builder.build()?;
    sim.run()?;
    Ok(sim)
}

fn main() -> anyhow::Result<()> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let base = Scenario::load(&path)?;
    for core in [
        agglo::scenario::Core::Events,
        agglo::scenario::Core::Stepped,
    ] {
        let mut scenario = base.clone();
        scenario.time.core = core;
        for settling in [None, Some(&SETTLING)] {
            let sim = run(&scenario, settling)?;
            let s = sim.summary();
            println!(
                "{:>7} core, {:<15}: {:>5} impacts, {:>4} bonds, b_f/b0 = {:.3}, {:.3} s",
                sim.pipeline().core,
                if settling.is_some() {
                    "drag + settling"
                } else {
                    "no field"
                },
                s.counters.impacts,
                s.counters.bonds,
                s.growth.growth_ratio,
                s.wall_seconds
            );
            if settling.is_some() && sim.pipeline().core == "event" {
                for line in &sim.pipeline().forces {
                    println!("    {line}");
                }
            }
        }
    }
    Ok(())
}
