//! `agglo::subgrid` (issue 32): a box per cell per macro step. Determinism over threads
//! and submission order, the closed cell against one run, the ballistic kernel and
//! Smoluchowski, re-lifting against one long run, conservation, bad input.

use agglo::farm::Workers;
use agglo::prelude::*;
use agglo::subgrid::*;
use serde_json::json;

use crate::common::scenario;

/// Ballistic aggregation's material: every contact sticks and merges (H0 = 1e-6 Pa),
/// no reaction heat, no cooling; primary radius 2e-4 m, ρ = 1000 kg/m³.
fn sticky_base() -> Scenario {
    scenario(json!({
        "seed": 7,
        "cloud": { "count": 2, "radius": 2e-4 },
        "material": { "rho": 1000, "H0": 1e-6, "C": 1000, "theta0": 300 },
        "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 },
    }))
}

fn primary_mass(c: &Coupling) -> f64 {
    c.primary().1
}

/// Classes by primaries: 1, 2, 3–4, 5–8, 9 and up.
fn coupling(bodies: u32, replicas: u32) -> Coupling {
    let base = sticky_base();
    let b0 = base.primary_radius();
    let m0 = 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) * base.material.rho;
    let edges = [0.5, 1.5, 2.5, 4.5, 8.5, 1e9].map(|x| x * m0).to_vec();
    let mut c = Coupling::new(base, edges).unwrap();
    c.bodies = BoxSize::Bodies(bodies);
    c.replicas = replicas;
    c
}

/// Monomers at volume fraction `phi`, Maxwellian at T_g = 1 m²/s², at rest on average.
fn monomers(c: &Coupling, phi: f64, dt: f64) -> CellInput {
    let m0 = primary_mass(c);
    let b0 = c.primary().0;
    let n = phi / (4.0 / 3.0 * std::f64::consts::PI * b0.powi(3));
    let class = |k: usize| ClassInput {
        number_density: if k == 0 { n } else { 0.0 },
        mass: m0 * [1.0, 2.0, 3.0, 5.0, 9.0][k],
        velocity: [0.0; 3],
        temperature: 300.0,
        granular_temperature: 1.0,
    };
    CellInput {
        classes: (0..5).map(class).collect(),
        gas: GasState {
            velocity: [0.0; 3],
            temperature: 300.0,
            drag: None,
        },
        dt,
    }
}

#[test]
fn a_cell_advances_and_conserves_mass() {
    let c = coupling(300, 2);
    let input = monomers(&c, 0.05, 2e-4);
    let (out, state) = advance_cell(&c, 3, 0, &input, None).unwrap();
    let impacts = out.impact_rate.mean * out.box_volume * out.dt;
    assert!(impacts > 1.0, "no impacts: {out:?}");
    assert_eq!(state.macro_steps(), 1);
    let total: f64 = out.classes.iter().map(|k| k.mass_rate.mean).sum();
    let scale = out.classes[0].mass_rate.mean.abs();
    assert!(total.abs() <= 1e-12 * scale, "{total:e} vs {scale:e}");
}
