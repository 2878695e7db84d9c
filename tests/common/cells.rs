//! A closed cell of sticky monomers for the subgrid coupling's tests, shared by both test
//! binaries: the model's tests (`tests/suite/subgrid*.rs`) and the doors' refusals and fuzz
//! tests. Classes by primaries: 1, 2, 3–4, 5–8, 9 and up.

use agglo::prelude::*;
use agglo::subgrid::*;
use serde_json::json;

use super::scenario;

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

/// The mass of one primary (kg) of the coupling's scenario.
fn primary_mass(c: &Coupling) -> f64 {
    c.primary().1
}

/// Classes by primaries: 1, 2, 3–4, 5–8, 9 and up. Boxes re-lifted every step: the
/// tests using this were written for re-lifting (issue 32), so they opt out of the
/// default `persist` and set `persist` or `keep_bodies` where they test those.
pub fn coupling(bodies: u32, replicas: u32) -> Coupling {
    let base = sticky_base();
    let b0 = base.primary_radius();
    let m0 = 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) * base.material.rho;
    let edges = [0.5, 1.5, 2.5, 4.5, 8.5, 1e9].map(|x| x * m0).to_vec();
    let mut c = Coupling::new(base, edges).unwrap();
    c.bodies = BoxSize::Bodies(bodies);
    c.replicas = replicas;
    c.persist = false;
    c
}

/// Monomers at volume fraction `phi`, Maxwellian at T_g = 1 m²/s², at rest on average.
pub fn monomers(c: &Coupling, phi: f64, dt: f64) -> CellInput {
    let m0 = primary_mass(c);
    let b0 = c.primary().0;
    let n = phi / (4.0 / 3.0 * std::f64::consts::PI * b0.powi(3));
    let class = |k: usize| ClassInput {
        number_density: if k == 0 { n } else { 0.0 },
        mass: m0 * [1.0, 2.0, 3.0, 5.0, 9.0][k],
        velocity: [0.0; 3],
        temperature: 300.0,
        granular_temperature: 1.0,
        granular_anisotropy: ISOTROPIC,
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
