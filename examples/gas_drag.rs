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
struct SettlingPlugin {
    gravity: DVec3,
    gas: DVec3,
    /// Relaxation time of a primary grain [s].
    tau0: f64,
}

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

fn main() -> anyhow::Result<()> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let base = Scenario::load(&path)?;
    let settling = SettlingPlugin {
        gravity: DVec3::new(0.0, 0.0, -2e4),
        gas: DVec3::new(0.0, 0.0, 20.0),
        tau0: 1e-3,
    };
    for core in ["events", "stepped"] {
        let mut scenario = base.clone();
        scenario.time.core = if core == "events" {
            agglo::scenario::Core::Events
        } else {
            agglo::scenario::Core::Stepped
        };
        for with_field in [false, true] {
            let mut builder = Simulation::builder(&scenario)?;
            builder.add_default_plugins();
            if with_field {
                builder.add_plugin(&settling);
            }
            let mut sim = builder.build()?;
            sim.run()?;
            let s = sim.summary();
            println!(
                "{core:>7} core, {:<22}: {:>5} impacts, {:>4} bonds, b_f/b0 = {:.3}, {:.3} s",
                if with_field {
                    "drag + settling"
                } else {
                    "no field"
                },
                s.counters.impacts,
                s.counters.bonds,
                s.growth.growth_ratio,
                s.wall_seconds
            );
            if with_field && core == "events" {
                for line in &sim.pipeline().forces {
                    println!("    {line}");
                }
            }
        }
    }
    Ok(())
}
