//! Contact detection and the step size (docs/model.md §4): no missed collision for c ≤ 1,
//! tunnelling with coarse fixed steps, and bodies larger than half the box.

use crate::common;

use agglo::prelude::*;
use common::scenario;
use serde_json::{Value, json};

const B0: f64 = 1e-3;

/// A small fast grain at x = −8 mm aimed at a slow 8-grain body (radius 2 b0) at x = +2 mm.
fn bullet(stepping: Value) -> Scenario {
    scenario(json!({
        "cloud": { "count": 2, "radius": B0, "bodies": [
            { "position": [-0.008, 0, 0], "velocity": [100, 0, 0] },
            { "position": [0.002, 0, 0], "velocity": [1, 0, 0], "primaries": 8 }
        ]},
        // Hard grains: they bounce (no merging), so exactly one impact is expected.
        "material": { "H0": 1e12 },
        "time": { "end": 1e-4, "stepping": stepping }
    }))
}

#[test]
fn adaptive_steps_catch_a_fast_grain_that_a_coarse_fixed_step_lets_through() {
    // Gap 7 mm at 99 m/s closing: contact at t ≈ 70.7 µs, well inside one 1e-4 s step.
    let mut adaptive = Simulation::new(&bullet(json!({ "adaptive": { "dt_max": 1e-3 } }))).unwrap();
    adaptive.run().unwrap();
    assert_eq!(
        adaptive.counters().impacts,
        1,
        "the adaptive step lands on the contact"
    );
    assert_eq!(adaptive.counters().overlap_violations, 0);
    let v = adaptive.bodies();
    assert!(
        v[0].velocity.x < 0.0,
        "the bullet bounced back: {}",
        v[0].velocity.x
    );

    // One fixed step of 1e-4 s moves the bullet 10 mm: it ends on the far side without overlap.
    let mut fixed = Simulation::new(&bullet(json!({ "fixed": { "dt": 1e-4 } }))).unwrap();
    fixed.run().unwrap();
    assert_eq!(
        fixed.counters().impacts,
        0,
        "the fixed step tunnels: the documented failure"
    );
    assert!(fixed.bodies()[0].velocity.x > 0.0);
}

#[test]
fn contact_happens_at_the_exact_ballistic_time() {
    // Stop just after the analytic contact time: the impact must already have happened,
    // and stopping just before it: not yet.
    let contact = (0.010 - 3.0 * B0) / 99.0; // centre gap 10 mm minus b + 2b, closing at 99 m/s
    for (end, impacts) in [(contact * (1.0 - 1e-6), 0), (contact * (1.0 + 1e-6), 1)] {
        let mut s = bullet(json!({ "adaptive": {} }));
        s.time.end = end;
        let mut sim = Simulation::new(&s).unwrap();
        sim.run().unwrap();
        assert_eq!(sim.counters().impacts, impacts, "end = {end}");
    }
}

/// A body of radius 1.05 D (larger than half the box: it overlaps its own periodic images).
fn giant(extra: Vec<Value>) -> Scenario {
    let d = 0.01;
    let primaries = (1.05 * d / B0).powi(3);
    let mut bodies =
        vec![json!({ "position": [0, 0, 0], "velocity": [30, 10, -5], "primaries": primaries })];
    bodies.extend(extra);
    scenario(json!({
        "cloud": { "count": bodies.len(), "radius": B0, "bodies": bodies },
        "material": { "H0": 1e12 },
        "time": { "end": 2e-3 }
    }))
}

#[test]
fn a_body_larger_than_half_the_box_never_meets_itself() {
    let mut sim = Simulation::new(&giant(vec![])).unwrap();
    sim.run().unwrap();
    assert_eq!(sim.counters().impacts, 0);
    let b = &sim.bodies()[0];
    assert!(b.position.is_finite() && (b.velocity.x - 30.0).abs() < 1e-12);
}

#[test]
fn a_body_larger_than_half_the_box_still_meets_its_neighbours() {
    // A grain in the free corner, 1.56 D from the centre, flying at the giant.
    let corner = 0.009;
    let speed = 50.0;
    let dir = -1.0 / 3f64.sqrt();
    let grain = json!({ "position": [corner, corner, corner], "velocity": [speed * dir, speed * dir, speed * dir] });
    let mut s = giant(vec![grain]);
    s.cloud.bodies[0].velocity = Some([0.0, 0.0, 0.0]);
    let gap = 3f64.sqrt() * corner - 1.05 * 0.01 - B0;
    s.time.end = 1.001 * gap / speed;
    let mut sim = Simulation::new(&s).unwrap();
    sim.run().unwrap();
    assert_eq!(
        sim.counters().impacts,
        1,
        "met exactly once, at t = gap / speed"
    );
    assert_eq!(sim.counters().overlap_violations, 0);
}
