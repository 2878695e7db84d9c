//! Physics against closed forms (docs/model.md §14), on real runs of the engine.

use crate::common;

use agglo::prelude::*;
use agglo::systems::cooling::radiative_closed_form;
use agglo::systems::impact::{closed_form_restitution, critical_speed};
use common::{merge, pair, scenario};
use serde_json::json;

const RHO: f64 = 2000.0;
const H0: f64 = 1e4;
const B0: f64 = 1e-3;

/// Run a head-on pair of identical grains, each approaching at `vp`, through one impact.
fn head_on(a0: f64, af: f64, beta: f64, vp: f64) -> (Simulation, Vec<BodyState>) {
    let mut patch = pair(-0.002, vp, 0.002, -vp);
    merge(
        &mut patch,
        json!({
            "impact": { "a0": a0, "af": af, "beta": beta },
            // Long enough for the grains (gap 2 mm) to meet even at the slowest speed.
            "time": { "end": 0.002 / vp + 1e-4 }
        }),
    );
    let s = scenario(patch);
    let mut sim = Simulation::new(&s).expect("builds");
    sim.run().expect("runs");
    let bodies = sim.bodies();
    (sim, bodies)
}

#[test]
fn restitution_matches_the_closed_form_over_speeds_and_a0() {
    for &a0 in &[0.01, 0.5] {
        let vc = critical_speed(1.0, H0, 1.0, RHO);
        for k in 1..=12 {
            let vp = vc * k as f64 / 13.0; // strictly below critical: every case bounces
            let (sim, bodies) = head_on(a0, 1.0, 1.0, vp);
            assert_eq!(sim.counters().impacts, 1, "a0 = {a0}, vp = {vp}");
            assert_eq!(bodies.len(), 2);
            let lambda = 2.0 * RHO * vp * vp / (3.0 * H0 * 1.0);
            let expected = closed_form_restitution(a0, 1.0, lambda);
            // e = separation speed / approach speed along the line of centres.
            let e = (bodies[1].velocity.x - bodies[0].velocity.x) / (2.0 * vp);
            // 1e-9: the solver converges to TOL = 1e-12 relative; the velocity update adds rounding only.
            assert!(
                (e - expected).abs() <= 1e-9,
                "a0 = {a0}, vp = {vp}: e = {e}, closed form {expected}"
            );
        }
    }
}

#[test]
fn bonding_starts_exactly_at_the_critical_speed() {
    let vc = critical_speed(1.0, H0, 1.0, RHO);
    let (below, bodies_below) = head_on(0.5, 1.0, 1.0, vc * (1.0 - 1e-6));
    assert_eq!(below.counters().bounces, 1);
    assert_eq!(
        bodies_below.len(),
        2,
        "just below critical the pair bounces"
    );
    let (above, bodies_above) = head_on(0.5, 1.0, 1.0, vc * (1.0 + 1e-6));
    assert_eq!(above.counters().bonds, 1);
    assert_eq!(
        bodies_above.len(),
        1,
        "just above critical the pair bonds and merges"
    );
    // The merged body holds both grains: radius 2^(1/3) b0.
    assert!((bodies_above[0].radius / (B0 * 2f64.cbrt()) - 1.0).abs() < 1e-12);
}

#[test]
fn papers_logical_choice_a0_0_is_solved_by_the_closed_form_seed() {
    // a0 = 0, af = 1, β = 1 (P04's "logical choice"): the plain iteration cycles 0 ↔ 1 − λ
    // (systems/impact.rs tests its fallback); the solver starts from the closed form,
    // which is the fixed point here (Q = 0): one evaluation of G, no fallback.
    let vc = critical_speed(1.0, H0, 1.0, RHO);
    let vp = 0.6 * vc;
    let (sim, bodies) = head_on(0.0, 1.0, 1.0, vp);
    let c = sim.counters();
    assert_eq!(c.impacts, 1);
    assert_eq!(c.fallbacks, 0);
    assert_eq!(c.fixed_point_iterations + c.fallback_iterations, 1);
    let lambda = 2.0 * RHO * vp * vp / (3.0 * H0);
    let e = (bodies[1].velocity.x - bodies[0].velocity.x) / (2.0 * vp);
    // Rounding only: velocities of ~10 m/s carry ~1e-15 relative error.
    assert!((e - closed_form_restitution(0.0, 1.0, lambda)).abs() <= 1e-12);
}

/// One hot grain cooling by radiation alone (hc = 0, θs = 0) with a fixed step.
fn cool(method: &str, dt: f64, end: f64, theta0: f64) -> f64 {
    let s = scenario(json!({
        "cloud": { "count": 1, "bodies": [ { "position": [0, 0, 0], "velocity": [0, 0, 0] } ] },
        "material": { "theta0": theta0, "theta_s": 0.0, "epsilon": 1.0, "hc": 0.0 },
        "time": { "end": end, "stepping": { "fixed": { "dt": dt } } },
        "physics": { "cooling": method },
        "diagnostics": { "invariants": false }
    }));
    let mut sim = Simulation::new(&s).expect("builds");
    sim.run().expect("runs");
    sim.bodies()[0].temperature
}

fn radiation_rate() -> f64 {
    // k = B ε a_s / (m C) for the 1 mm grain of the helper scenario.
    let area = 4.0 * std::f64::consts::PI * B0 * B0;
    let mass = 4.0 / 3.0 * std::f64::consts::PI * B0.powi(3) * RHO;
    agglo::resources::STEFAN_BOLTZMANN * area / (mass * 1000.0)
}

#[test]
fn implicit_cooling_converges_to_the_radiative_closed_form() {
    let theta0 = 3000.0;
    let k = radiation_rate();
    let end = 20.0; // several cooling times: θ falls from 3000 K to about 1000 K
    let exact = radiative_closed_form(theta0, k, end);
    assert!(exact < 0.5 * theta0, "the test must cover real cooling");
    let coarse = (cool("implicit", end / 200.0, end, theta0) - exact).abs() / exact;
    let fine = (cool("implicit", end / 400.0, end, theta0) - exact).abs() / exact;
    // Backward Euler is first order: halving Δt halves the error (ratio 2 ± 10 %).
    assert!(fine < 1e-2, "relative error {fine}");
    let ratio = coarse / fine;
    assert!((ratio - 2.0).abs() < 0.2, "convergence ratio {ratio}");
}

#[test]
fn explicit_cooling_fails_above_its_limit_while_implicit_stays_accurate() {
    // A 10^8 K grain: the explicit limit 1 / (4 k θ³) is far below the step.
    let theta0: f64 = 1e8;
    let k = radiation_rate();
    let limit = 1.0 / (4.0 * k * theta0.powi(3));
    let dt = 100.0 * limit;
    let end = 50.0 * dt;
    let exact = radiative_closed_form(theta0, k, end);
    let explicit = cool("explicit", dt, end, theta0);
    let implicit = cool("implicit", dt, end, theta0);
    let explicit_broken =
        !explicit.is_finite() || explicit <= 0.0 || (explicit / exact).log10().abs() > 2.0;
    assert!(explicit_broken, "explicit gave {explicit} vs exact {exact}");
    assert!(implicit > 0.0 && implicit <= theta0);
    // Backward Euler is monotone and, for this decay, errs high by less than a factor 2.
    assert!(
        (implicit - exact).abs() / exact < 1.0,
        "implicit {implicit} vs {exact}"
    );
}

/// One grain at θ(0) on the event core with hc = 0 and far-field θs: its temperature
/// and the tallied cooling loss at T.
fn cool_lazily(theta0: f64, theta_s: f64, end: f64, dt_max: f64) -> (f64, f64) {
    let s = scenario(json!({
        "cloud": { "count": 1, "bodies": [ { "position": [0, 0, 0], "velocity": [3, 0, 0] } ] },
        "material": { "theta0": theta0, "theta_s": theta_s, "epsilon": 1.0, "hc": 0.0 },
        "time": { "end": end, "stepping": { "adaptive": { "dt_max": dt_max } } }
    }));
    assert!(s.uses_event_core());
    let mut sim = Simulation::new(&s).expect("builds");
    sim.run().expect("runs");
    (sim.bodies()[0].temperature, sim.ledger().cooling_loss)
}

#[test]
fn the_event_core_cools_exactly_over_any_interval_even_right_after_a_1e9_k_impact() {
    // The body is never touched, so its temperature is advanced over the whole run in
    // one interval: from 10 µs (radiation stiff: k θ³ ≈ 1e16 /s) to 100 s.
    let k = radiation_rate();
    let mass = 4.0 / 3.0 * std::f64::consts::PI * B0.powi(3) * RHO;
    for &(end, dt_max) in &[(1e-5, 1e-3), (1e-2, 1e-3), (100.0, 1.0)] {
        let (theta, lost) = cool_lazily(1e9, 0.0, end, dt_max);
        let exact = radiative_closed_form(1e9, k, end);
        // docs/model.md §8 asks for 1e-9; the integrator is exact to rounding.
        assert!(
            (theta - exact).abs() <= 1e-9 * exact,
            "T = {end}: {theta} vs {exact}"
        );
        // The ledger tallies exactly the heat the grain lost (C = 1000 J/(kg K)).
        let heat = mass * 1000.0 * (1e9 - theta);
        assert!((lost - heat).abs() <= 1e-12 * heat, "{lost} vs {heat}");
    }
    // With a far field (θs = 300 K; relaxation time 1/(4 k θs³) ≈ 110 s) the grain
    // cools towards θs and never below it.
    let (theta, _) = cool_lazily(1e9, 300.0, 200.0, 10.0);
    assert!(theta > 300.0 && theta < 400.0, "{theta}");
    let reference =
        agglo::systems::cooling::radiative_closed_form_with_far_field(1e9, k, 300.0, 200.0);
    assert!(
        (theta - reference).abs() <= 1e-9 * reference,
        "{theta} vs {reference}"
    );
}
