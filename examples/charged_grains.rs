//! Charged grains: per-body state through merges and fragments, and a hook that changes
//! impact outcomes (docs/extending.md).
//!
//! Each grain carries an electric charge q [C], a [`Charge`] component registered with
//! `SimBuilder::carry`: extensive through merges (`Combine::Sum`) and split by mass among
//! the pieces of a fragmentation (`Split::ByMass`). An outcome system in the
//! `ImpactOutcome` stage makes sticking depend on the pair's charges, through the Coulomb
//! energy at contact U = k q_a q_b / (b_a + b_b) against the approach energy
//! E = ½ μ v_n² (μ the reduced mass, v_n the normal approach speed):
//!
//! - like charges with U ≥ E are turned back before they touch: whatever the law
//!   decided, the pair bounces elastically (e = 1; the Coulomb deflection is not flown);
//! - unlike charges whose rebound energy e² E cannot climb out of the well, e² E < |U|,
//!   are captured: the pair bonds, whatever the law decided;
//! - otherwise the impact/heat law's outcome stands.
//!
//! Charge is conserved exactly by the rules, so the total at the end equals the total at
//! the start to rounding (tests/suite/worked_examples.rs checks it to 1e-12 of Σ|q|).
//!
//! The charge scale q0 is the plugin's section of the scenario, `plugins.charged_grains`
//! ([`ChargeLaw`]), and this program is the `agglo` command line with the plugin
//! (`agglo::cli::main_with`): the section is validated, overridden with `--set`, swept by
//! `scan` and searched by `optimize` as a built-in one is (tests/interfaces/extension_binary.rs):
//!
//! ```text
//! cargo run --release --example charged_grains -- run scenarios/plugins/charged_grains.json --final-state final.csv
//! cargo run --release --example charged_grains -- scan scenarios/plugins/charged_grains_inverse.json \
//!     --gene plugins.charged_grains.q0 --from 0 --to 2e-8 --points 5 --out scan_charge
//! cargo run --release --example charged_grains -- optimize scenarios/plugins/charged_grains_inverse.json --out best_charge
//! ```
//!
//! (the final state carries a `charge` column).

use agglo::bevy_ecs::prelude::*;
use agglo::carried::{Carried, Combine, Split};
use agglo::hooks::{ImpactOutcome, PendingImpacts};
use agglo::plugins::{Extension, PluginSection, issue};
use agglo::prelude::*;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Coulomb's constant k = 1/(4π ε0) [N m²/C²].
const COULOMB: f64 = 8.987_551_792_3e9;

/// Electric charge q [C] of a body.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Charge(pub f64);

impl Carried for Charge {
    fn value(&self) -> f64 {
        self.0
    }
    fn from_value(value: f64) -> Self {
        Charge(value)
    }
}

/// How often the charges changed an outcome.
#[derive(Resource, Debug, Default, Clone, Copy, PartialEq)]
pub struct ChargeEffects {
    /// Like-charged pairs turned back (the law would have bonded or bounced inelastically).
    pub repelled: u64,
    /// Unlike-charged pairs captured although the law bounced them.
    pub captured: u64,
}

/// The outcome hook: Coulomb energy at contact against the approach energy.
pub fn coulomb_sticking(
    mut pending: ResMut<PendingImpacts>,
    charges: Query<&Charge>,
    mut effects: ResMut<ChargeEffects>,
) {
    for impact in pending.iter_mut() {
        let p = impact.proposal;
        let (Ok(qa), Ok(qb)) = (charges.get(impact.entity_a), charges.get(impact.entity_b)) else {
            continue;
        };
        let coulomb = COULOMB * qa.0 * qb.0 / (p.radius_a + p.radius_b);
        let reduced = p.mass_a * p.mass_b / (p.mass_a + p.mass_b);
        let approach = 0.5 * reduced * p.normal_speed * p.normal_speed;
        if coulomb >= approach {
            impact.bounce(1.0);
            effects.repelled += 1;
        } else if coulomb < 0.0
            && p.outcome == ImpactOutcome::Bounce
            && p.restitution * p.restitution * approach < -coulomb
        {
            impact.bond();
            effects.captured += 1;
        }
    }
}

/// The charges at t = 0: q0 · u, u ∈ [−1, 1) a hash of the body's stable id (the same
/// on any machine and either core).
pub fn initial_charge(q0: f64, id: u64) -> f64 {
    // splitmix64
    let mut z = id.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    q0 * (2.0 * (z >> 11) as f64 / (1u64 << 53) as f64 - 1.0)
}

/// The plugin's section of the scenario, `plugins.charged_grains`: the charge law.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ChargeLaw {
    /// Charge scale q0 [C]: grain i starts with q0 · u_i, u_i ∈ [−1, 1) a hash of its id.
    /// 0 leaves every grain neutral (the built-in physics alone).
    #[serde(default)]
    pub q0: f64,
}

impl PluginSection for ChargeLaw {
    fn validate(&self) -> Vec<agglo::error::ValidationIssue> {
        // Beyond 1e-6 C a micron grain's surface field exceeds any material's breakdown
        // strength by orders of magnitude: a typo, not a scene.
        if (0.0..=MAX_CHARGE).contains(&self.q0) {
            Vec::new()
        } else {
            vec![issue("q0", "0 ≤ q0 ≤ 1e-6 C", self.q0)]
        }
    }
}

/// The largest charge scale a scene may give [C].
pub const MAX_CHARGE: f64 = 1e-6;

/// The plugin: charges on every body, carried by their rules, and the outcome hook;
/// the charge scale is its section, [`ChargeLaw`].
pub struct ChargedGrains;

impl SimPlugin for ChargedGrains {
    fn name(&self) -> &'static str {
        "charged_grains"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let q0 = sim.resource::<ChargeLaw>().q0;
        sim.carry::<Charge>("charge", Combine::Sum, Split::ByMass)
            .init_resource::<ChargeEffects>()
            .add_impact_outcome_systems(coulomb_sticking)
            .init_each_body(move |body| Charge(initial_charge(q0, body.id)));
    }
}

/// What a run did with the charges.
#[derive(Debug, Clone, Copy)]
pub struct Report {
    /// Σ q at t = 0 and at T [C].
    pub initial_charge: f64,
    pub final_charge: f64,
    /// Σ |q| at t = 0 [C], the scale of the conservation check.
    pub charge_scale: f64,
    pub effects: ChargeEffects,
    pub counters: Counters,
}

/// Σ q and Σ |q| over the bodies, in id order.
fn totals(sim: &Simulation) -> (f64, f64) {
    sim.carried()
        .rows
        .iter()
        .fold((0.0, 0.0), |(sum, abs), (_, values)| {
            let q = values[0].unwrap_or(0.0);
            (sum + q, abs + q.abs())
        })
}

/// Run `scenario` with charges of scale `q0` [C]; the simulation is returned for its
/// final state.
pub fn run(scenario: &Scenario, q0: f64) -> Result<(Simulation, Report), SimError> {
    let mut builder = Simulation::builder(scenario)?;
    builder
        .insert_resource(ChargeLaw { q0 })
        .add_default_plugins()
        .add_plugin(&ChargedGrains);
    let mut sim = builder.build()?;
    let (initial_charge, charge_scale) = totals(&sim);
    sim.run()?;
    let (final_charge, _) = totals(&sim);
    let report = Report {
        initial_charge,
        final_charge,
        charge_scale,
        effects: *sim.world().resource::<ChargeEffects>(),
        counters: sim.counters(),
    };
    Ok((sim, report))
}

/// The `agglo` command line with this plugin: `validate`, `run`, `scan`, `optimize`
/// and the rest read `plugins.charged_grains` as they read a built-in section.
#[allow(dead_code)] // the tests include this file for `run`
fn main() -> std::process::ExitCode {
    agglo::cli::main_with([Extension::with_section::<ChargeLaw>(ChargedGrains)])
}
