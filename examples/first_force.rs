//! A first force: charged grains gyrating in a magnetic field, as a plugin with its
//! own scenario section (docs/extending.md opens with this file).
//!
//! Grains of one specific charge q/m in a uniform magnetic field B along z feel the
//! Lorentz force m a = q v × B: each velocity turns about z at the cyclotron frequency
//! ω = (q/m) B [rad/s], the same for every body (charge and mass both add up when grains
//! merge). The force system turns each velocity by the exact angle −ω Δt over the step
//! just taken, so speeds, and the kinetic energy, are unchanged to rounding; between
//! kicks bodies fly straight, which is what the cores predict (docs/model.md §4.7).
//!
//! ω is the scenario section `plugins.gyration` ([`Gyration`]); this program is the
//! `agglo` command line with the plugin, so the section is validated, set, scanned and
//! recorded as a built-in one:
//!
//! ```text
//! cargo run --release --example first_force -- run scenarios/plugins/first_force.json
//! cargo run --release --example first_force -- run scenarios/plugins/first_force.json --set plugins.gyration.omega=0
//! ```

use agglo::bevy_ecs::prelude::*;
use agglo::bodies::Bodies;
use agglo::glam::DVec2;
use agglo::plugins::{Extension, PluginSection, issue};
use agglo::schedule::{SimBuilder, SimPlugin};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The section `plugins.gyration`: the cyclotron frequency ω = (q/m) B [rad/s].
#[derive(Resource, Clone, Serialize, Deserialize, JsonSchema)]
pub struct Gyration {
    /// ω [rad/s]; 0 leaves velocities as they are.
    pub omega: f64,
}

/// The force: every velocity turned about z by −ω Δt.
fn gyrate(field: Res<Gyration>, mut bodies: Bodies) {
    let turn = DVec2::from_angle(-field.omega * bodies.dt());
    bodies.update_all(|b| b.velocity = turn.rotate(b.velocity.truncate()).extend(b.velocity.z));
}

/// The plugin: the force system, kicking after every step.
pub struct Gyrate;

impl SimPlugin for Gyrate {
    fn name(&self) -> &'static str {
        "gyration"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.add_force_systems(gyrate);
    }
}

fn main() -> std::process::ExitCode {
    agglo::cli::main_with([Extension::with_section::<Gyration>(Gyrate)])
}

/// The section's check: beyond 1e9 rad/s a grain would turn about once a nanosecond,
/// faster than any step resolves (a typo, not a scene).
impl PluginSection for Gyration {
    fn validate(&self) -> Vec<agglo::error::ValidationIssue> {
        match self.omega.abs() <= 1e9 {
            true => Vec::new(),
            false => vec![issue("omega", "|ω| ≤ 1e9 rad/s", self.omega)],
        }
    }
}
