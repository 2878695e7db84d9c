//! Conservation laws (docs/model.md §10, §14) on real multi-particle runs.

use crate::common;

use agglo::prelude::*;
use common::scenario;
use glam::DVec3;
use serde_json::json;

/// A 1000-grain reacting cloud tuned so that bonding, bouncing and fragmentation all happen.
fn busy_cloud() -> Scenario {
    scenario(json!({
        "name": "busy",
        "seed": 11,
        "box": { "half_width": 0.0075 },
        "cloud": { "count": 1000, "radius": null, "size_ratio": 0.7, "v_mean": [5, -3, 20], "v_rel": [60, 20, 20] },
        "material": {
            "rho": 3000, "H0": 2e5, "C": 1000, "Q": 300, "alpha": 1e3, "gamma": 2e3,
            "mu0": 0.05, "epsilon": 0.5, "theta0": 400, "theta_s": 300
        },
        "impact": { "a0": 0.1, "af": 1.0, "beta": 1.0 },
        "time": { "end": 0.0015 }
    }))
}

fn totals(bodies: &[BodyState]) -> (f64, DVec3, f64) {
    let mass = bodies.iter().map(|b| b.mass).sum();
    let momentum = bodies.iter().map(|b| b.mass * b.velocity).sum();
    let scale = bodies.iter().map(|b| b.mass * b.velocity.length()).sum();
    (mass, momentum, scale)
}

#[test]
fn mass_and_momentum_are_conserved_through_merging_bouncing_and_fragmentation() {
    let mut sim = Simulation::new(&busy_cloud()).expect("builds");
    let (m0, p0, scale) = totals(&sim.bodies());
    sim.run().expect("runs");
    let c = sim.counters();
    assert!(c.bonds > 10, "bonds: {}", c.bonds);
    assert!(c.bounces > 10, "bounces: {}", c.bounces);
    assert!(c.fragmentations > 0, "fragmentations: {}", c.fragmentations);
    let (m1, p1, _) = totals(&sim.bodies());
    // 1e-12: a few thousand additions of positive terms in f64 (ε ≈ 1.1e-16 each).
    assert!(
        (m1 - m0).abs() / m0 <= 1e-12,
        "mass error {}",
        (m1 - m0).abs() / m0
    );
    assert!(
        (p1 - p0).length() / scale <= 1e-12,
        "momentum error {}",
        (p1 - p0).length() / scale
    );
    let report = sim.invariants();
    assert_eq!(c.invariant_violations, 0, "{:?}", report.violations);
    assert_eq!(
        c.overlap_violations, 0,
        "adaptive c = 1 must not miss contacts"
    );
}

#[test]
fn kinetic_energy_lost_equals_heat_gained_without_reactions_or_cooling() {
    let mut s = busy_cloud();
    s.material.alpha = 0.0;
    s.material.gamma = None;
    s.physics.cooling = agglo::scenario::CoolingMethod::Off;
    let heat_capacity = s.material.C;
    let theta0 = s.material.theta0;
    let mut sim = Simulation::new(&s).expect("builds");
    let ke = |b: &[BodyState]| {
        b.iter()
            .map(|b| 0.5 * b.mass * b.velocity.length_squared())
            .sum::<f64>()
    };
    let ke0 = ke(&sim.bodies());
    sim.run().expect("runs");
    let bodies = sim.bodies();
    assert!(sim.counters().impacts > 100);
    let lost = ke0 - ke(&bodies);
    // Heat gained, summed as Σ m C (θ − θ0): every grain started at θ0 and mass is conserved,
    // so this equals the change of Σ m C θ without cancelling two large totals.
    let gained: f64 = bodies
        .iter()
        .map(|b| b.mass * heat_capacity * (b.temperature - theta0))
        .sum();
    assert!(lost > 0.0);
    // 1e-9 relative: rounding of ~1e3 impacts' energy updates, far below any physics error.
    assert!(
        (lost - gained).abs() / lost <= 1e-9,
        "lost {lost}, gained {gained}"
    );
}
