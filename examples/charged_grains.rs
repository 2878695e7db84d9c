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
//! the start to rounding; the example checks it to 1e-12 of Σ|q|.
//!
//! Run with `cargo run --release --example charged_grains [-- final.csv]` (the final state,
//! with a `charge` column, is written if a path is given).

use std::path::Path;

use agglo::bevy_ecs::prelude::*;
use agglo::carried::{Carried, Combine, Split};
use agglo::hooks::{ImpactOutcome, PendingImpacts};
use agglo::prelude::*;

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

/// The plugin: charges on every body, carried by their rules, and the outcome hook.
pub struct ChargedGrains {
    /// Charge scale q0 [C].
    pub q0: f64,
}

impl SimPlugin for ChargedGrains {
    fn name(&self) -> &'static str {
        "charged_grains"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.carry::<Charge>("charge", Combine::Sum, Split::ByMass)
            .init_resource::<ChargeEffects>()
            .add_impact_outcome_systems(coulomb_sticking)
            .init_each_body(|body| Charge(initial_charge(self.q0, body.id)));
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
        .add_default_plugins()
        .add_plugin(&ChargedGrains { q0 });
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

#[allow(dead_code)] // the tests include this file for `run`
fn main() -> anyhow::Result<()> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let scenario = Scenario::load(&path)?;
    // Coulomb energy at contact of two primaries at q0 comparable with their approach
    // energy at the scene's speeds (~1e-4 J): charges change outcomes both ways.
    let (sim, r) = run(&scenario, 1e-8)?;
    let c = r.counters;
    println!(
        "{}: {} impacts ({} bonds, {} bounces), {} fragmentations; {} → {} bodies",
        scenario.name,
        c.impacts,
        c.bonds,
        c.bounces,
        c.fragmentations,
        sim.info().initial_bodies,
        sim.body_count()
    );
    println!(
        "charges: {} pairs repelled, {} captured; Σq {:e} C → {:e} C (Σ|q| = {:e} C)",
        r.effects.repelled, r.effects.captured, r.initial_charge, r.final_charge, r.charge_scale
    );
    let drift = (r.final_charge - r.initial_charge).abs() / r.charge_scale;
    anyhow::ensure!(drift <= 1e-12, "charge not conserved: {drift:e} of Σ|q|");
    println!("charge conserved to {drift:.1e} of Σ|q|");
    if let Some(out) = std::env::args().nth(1) {
        agglo::output::write_final_state_with(Path::new(&out), &sim.bodies(), &sim.carried())?;
        println!("final state with charges: {out}");
    }
    Ok(())
}
