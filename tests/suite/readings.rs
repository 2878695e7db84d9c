//! The model's readings (docs/model.md, "Readings"): each alternative reading of the
//! papers on two bodies, against a closed form or an exact kinematic prediction, and
//! the defaults unchanged.

use crate::common;

use agglo::prelude::*;
use agglo::resources::hardness;
use agglo::scenario::{BondTest, DurationLaw, FrictionCap, PairHardness, SolverKind};
use agglo::systems::impact::{PairBody, PairModel, closed_form_restitution, solve_pair};
use common::{merge, pair, scenario};
use glam::DVec3;
use serde_json::json;

const RHO: f64 = 2000.0;
const H0: f64 = 1e4;
const B0: f64 = 1e-3;

fn grain(velocity: DVec3, temperature: f64) -> PairBody {
    PairBody {
        mass: 4.0 / 3.0 * std::f64::consts::PI * B0.powi(3) * RHO,
        radius: B0,
        velocity,
        temperature,
    }
}

fn model(a0: f64, q: f64, heat_capacity: f64) -> PairModel {
    PairModel {
        a0,
        af: 1.0,
        beta: 1.0,
        duration: DurationLaw::P04,
        friction_scales_with_adhesion: false,
        mu0: 0.0,
        alpha: 0.0,
        heat_capacity,
        h0: H0,
        activation_energy: q,
        tol: 1e-12,
        max_iterations: 100,
        solver: SolverKind::Safeguarded,
        pair_hardness: PairHardness::Min,
        friction_cap: FrictionCap::Sticking,
        bond_test: BondTest::FixedPoint,
        work_heat: Default::default(),
    }
}

#[test]
fn each_pair_hardness_rule_gives_the_closed_form_with_its_own_hardness() {
    // Two identical grains at different temperatures: H_i ≠ H_j. A heat capacity of
    // 1e30 J/(kg K) keeps the impact from heating them (ΔT ~ 1e-31 K), so H stays fixed
    // and docs/model.md §14's closed form holds with H = the rule's pair hardness.
    let q = 5e3; // exp(Q/(Rθ)): 7.42 at 300 K, 2.72 at 600 K
    let (ti, tj) = (300.0, 600.0);
    let (hi, hj) = (hardness(H0, q, ti), hardness(H0, q, tj));
    assert!(
        hi > 2.0 * hj,
        "the two hardnesses must differ clearly: {hi} {hj}"
    );
    let vp = 2.0; // λ = 2ρv²/(3Hβ) between 0.07 and 0.2: every rule bounces
    let expected_h = [
        (PairHardness::Min, hj),
        (PairHardness::Harmonic, 2.0 * hi * hj / (hi + hj)),
        (PairHardness::Arithmetic, 0.5 * (hi + hj)),
        (PairHardness::Max, hi),
    ];
    let mut last = -1.0;
    for (rule, h) in expected_h {
        let mut m = model(0.3, q, 1e30);
        m.pair_hardness = rule;
        let out = solve_pair(
            &m,
            &grain(DVec3::X * vp, ti),
            &grain(-DVec3::X * vp, tj),
            DVec3::X,
        );
        let lambda = 2.0 * RHO * vp * vp / (3.0 * h);
        let expected = closed_form_restitution(0.3, 1.0, lambda);
        assert!(!out.bonded, "{rule:?}");
        // 1e-9: the solver's tolerance is 1e-12 relative; the rest is rounding.
        assert!(
            (out.restitution - expected).abs() < 1e-9,
            "{rule:?}: e = {}, closed form {expected}",
            out.restitution
        );
        // A harder pair rebounds more: min < harmonic < arithmetic < max.
        assert!(out.restitution > last, "{rule:?} out of order");
        last = out.restitution;
    }
}

#[test]
fn pair_hardness_rules_handle_an_infinite_hardness_without_nan() {
    use agglo::systems::impact::pair_hardness;
    let inf = f64::INFINITY;
    assert_eq!(pair_hardness(PairHardness::Min, inf, 3.0), 3.0);
    assert_eq!(pair_hardness(PairHardness::Harmonic, inf, 3.0), 6.0);
    assert_eq!(pair_hardness(PairHardness::Arithmetic, inf, 3.0), inf);
    assert_eq!(pair_hardness(PairHardness::Max, inf, 3.0), inf);
    assert_eq!(pair_hardness(PairHardness::Harmonic, inf, inf), inf);
    // Both rules that see the infinite hardness give a fully elastic impact.
    for rule in [PairHardness::Arithmetic, PairHardness::Max] {
        let mut m = model(0.3, 1e6, 1000.0);
        m.pair_hardness = rule;
        let out = solve_pair(
            &m,
            &grain(DVec3::X * 10.0, 100.0), // Q/(Rθ) ≈ 1203 > 700: H = ∞
            &grain(-DVec3::X * 10.0, 1e6),
            DVec3::X,
        );
        assert_eq!(out.restitution, 1.0, "{rule:?}");
        assert!(out.velocity_i.is_finite() && out.temperature_i.is_finite());
    }
}

/// Two grains that meet exactly head on at x = ±b0 while sliding past each other in y
/// at relative speed 2w: starting offsets in y cancel at the contact.
fn oblique(v: f64, w: f64, mu0: f64, cap: &str) -> Simulation {
    let gap_time = (0.004 - 2.0 * B0) / (2.0 * v);
    let s = scenario(json!({
        "cloud": {
            "count": 2,
            "bodies": [
                { "position": [-0.002, -w * gap_time, 0], "velocity": [v, w, 0] },
                { "position": [0.002, w * gap_time, 0], "velocity": [-v, -w, 0] }
            ]
        },
        "material": { "mu0": mu0 },
        "impact": { "a0": 0.5, "friction_cap": cap },
        "time": { "end": 2.0 * gap_time }
    }));
    let mut sim = Simulation::new(&s).expect("builds");
    sim.run().expect("runs, with every energy ledger closing");
    assert_eq!(sim.counters().impacts, 1, "{cap}");
    sim
}

#[test]
fn uncapped_friction_reverses_the_sliding_by_the_coulomb_impulse_and_the_ledgers_close() {
    // Below the critical speed (≈ 2.74 m/s) the pair bounces with e from §14. The
    // Coulomb impulse μ m (1 + e) v changes each grain's y velocity by μ (1 + e) v, so
    // the slip 2w becomes 2w − 2μ(1 + e)v: with μ = 0.5, v = 2, w = 0.1 it reverses.
    let (v, w, mu) = (2.0, 0.1, 0.5);
    let lambda = 2.0 * RHO * v * v / (3.0 * H0);
    let e = closed_form_restitution(0.5, 1.0, lambda);
    let slip_after = |sim: &Simulation| {
        let b = sim.bodies();
        b[0].velocity.y - b[1].velocity.y
    };

    let capped = oblique(v, w, mu, "sticking");
    assert!(
        slip_after(&capped).abs() < 1e-12,
        "the cap stops the sliding exactly: slip {}",
        slip_after(&capped)
    );

    let uncapped = oblique(v, w, mu, "none");
    let expected = 2.0 * w - 2.0 * mu * (1.0 + e) * v;
    assert!(
        expected < -2.0 * w,
        "the test needs a reversal larger than the slip"
    );
    // Closed form to 1e-9 m/s: e to 1e-12 relative, the rest rounding of ~1 m/s values.
    assert!(
        (slip_after(&uncapped) - expected).abs() < 1e-9,
        "slip {} vs {expected}",
        slip_after(&uncapped)
    );
    // Reversing the slip by more than its size creates kinetic energy; it is tallied as
    // negative dissipation, so the ledgers (checked every step) closed and it shows here.
    let created = 0.5 * 0.5 * grain(DVec3::ZERO, 0.0).mass * (expected.powi(2) - 4.0 * w * w);
    let normal_loss = grain(DVec3::ZERO, 0.0).mass * v * v * (1.0 - e * e);
    let dissipation = uncapped.ledger().impact_dissipation;
    assert!(
        (dissipation - (normal_loss - created)).abs() < 1e-9 * normal_loss,
        "dissipation {dissipation} vs {}",
        normal_loss - created
    );
}

#[test]
fn p04_double_counted_work_heats_a_bouncing_pair_by_exactly_w_more() {
    // A head-on bounce below the critical speed, no reaction heat, no softening, no
    // cooling: the pair's heat is W once (P02 (14)–(17)) or 2W (P04 (6.10)).
    let heat_of = |work_heat: &str| {
        let mut patch = pair(-0.002, 2.0, 0.002, -2.0);
        merge(
            &mut patch,
            json!({ "impact": { "work_heat": work_heat }, "time": { "end": 0.002 } }),
        );
        let mut sim = Simulation::new(&scenario(patch)).expect("builds");
        sim.run().expect("runs, with the ledgers closing");
        assert_eq!(sim.counters().bounces, 1, "{work_heat}");
        let c = 1000.0;
        let heat: f64 = sim
            .bodies()
            .iter()
            .map(|b| b.mass * c * (b.temperature - 300.0))
            .sum();
        (heat, sim.ledger())
    };
    let (once, ledger_once) = heat_of("once");
    let (twice, ledger_twice) = heat_of("twice");
    let w = ledger_once.impact_dissipation;
    assert!(w > 0.0);
    // The motion is the same (Q = 0: heat does not feed back), so W is too.
    assert_eq!(ledger_twice.impact_dissipation, w);
    // 1e-9: temperature rises of ~1e-3 K on 300 K carry rounding ~1e-13 relative to W.
    assert!((once - w).abs() < 1e-9 * w, "once: {once} vs W = {w}");
    assert!(
        (twice - 2.0 * w).abs() < 1e-9 * w,
        "twice: {twice} vs 2W = {}",
        2.0 * w
    );
    assert_eq!(
        ledger_twice.double_counted_heat, w,
        "the created heat is tallied"
    );
    assert_eq!(ledger_once.double_counted_heat, 0.0);
}

#[test]
fn p04_printed_closed_form_gives_its_own_wrong_restitution() {
    // Identical grains head on, a0 = 0, af = 1, no heating: the corrected closed form is
    // e = 1 − √λ (docs/model.md §14); P04 (4.14) as printed, e² − (λ + 2) e + (1 − λ) = 0,
    // gives e = [(λ + 2) − √(λ² + 8λ)]/2 instead.
    let rho = RHO;
    for lambda in [0.1, 0.25, 0.6] {
        let vp = (lambda * 3.0 * H0 / (2.0 * rho)).sqrt();
        let e_of = |solver: &str| {
            let mut patch = pair(-0.002, vp, 0.002, -vp);
            merge(
                &mut patch,
                json!({ "impact": { "a0": 0.0, "solver": solver }, "time": { "end": 0.002 / vp + 1e-4 } }),
            );
            let mut sim = Simulation::new(&scenario(patch)).expect("builds");
            sim.run().expect("runs");
            assert_eq!(sim.counters().bounces, 1, "{solver} at λ = {lambda}");
            let b = sim.bodies();
            (b[1].velocity.x - b[0].velocity.x) / (2.0 * vp)
        };
        let corrected = 1.0 - lambda.sqrt();
        let printed = ((lambda + 2.0) - (lambda * lambda + 8.0 * lambda).sqrt()) / 2.0;
        // 1e-9: the roots are exact to rounding; velocities add rounding of ~1e-16.
        for (solver, expected) in [
            ("closed_form", corrected),
            ("safeguarded", corrected),
            ("closed_form_printed", printed),
        ] {
            let e = e_of(solver);
            assert!(
                (e - expected).abs() < 1e-9,
                "{solver}, λ = {lambda}: e = {e} vs {expected}"
            );
        }
        assert!(
            printed < corrected - 0.01,
            "the printed form dissipates more at λ = {lambda}"
        );
    }
    // The printed form is refused with P02's duration law, naming the field.
    let text = std::fs::read_to_string("scenarios/paper2002_best.json").unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["impact"]["solver"] = json!("closed_form_printed");
    let err = Scenario::from_value(v).unwrap_err().to_string();
    assert!(
        err.contains("impact.solver") && err.contains("p04"),
        "{err}"
    );
}

#[test]
fn clamped_explicit_cooling_stops_at_the_equilibrium_where_forward_euler_goes_negative() {
    use agglo::systems::cooling::CoolingLaw;
    // Radiation only (equilibrium θs = 300 K), a step far beyond the explicit limit.
    let law = CoolingLaw {
        k_convection: 0.0,
        k_radiation: 1e-12,
        theta_gas: 300.0,
        theta_far: 300.0,
    };
    let (theta, dt) = (1e6, 1.0); // rate ≈ −1e12 K/s: forward Euler lands at ≈ −1e12 K
    assert!(law.explicit_step(theta, dt) < 0.0);
    assert_eq!(law.explicit_clamped_step(theta, dt), 300.0);
    // Within the stable range the two are the same step, bit for bit.
    let small = 1e-9;
    assert_eq!(
        law.explicit_clamped_step(theta, small),
        law.explicit_step(theta, small)
    );
    // Below the equilibrium it heats, again without crossing.
    assert_eq!(law.explicit_clamped_step(100.0, 1e9), 300.0);
    // In a run: the hot pair of a bond cools to θs with the clamp; P04's scene, which
    // breaks with plain forward Euler, runs (a short stretch of it).
    let mut s = Scenario::load(std::path::Path::new("scenarios/paper2004_best.json")).unwrap();
    s.time.end = 2e-3;
    s.physics.cooling = agglo::scenario::CoolingMethod::ExplicitClamped;
    assert!(
        !s.uses_event_core(),
        "explicit cooling runs on the stepped core"
    );
    let mut sim = Simulation::new(&s).unwrap();
    sim.run().expect("runs without invariant errors");
    assert!(sim.summary().invariant_violations.is_empty());
    assert!(
        sim.bodies()
            .iter()
            .all(|b| b.temperature >= 300.0 * (1.0 - 1e-12))
    );
}

/// Λ at which P02 (20)'s first iterate e1 = 1 − Λ already presses at 2H (two identical
/// grains, P02 duration law, af = 1): Λ(2 − Λ)² = a0 + (1 − a0)Λ, by bisection.
fn first_iterate_threshold(a0: f64) -> f64 {
    let f = |l: f64| l * (2.0 - l).powi(2) - a0 - (1.0 - a0) * l;
    let (mut lo, mut hi) = (0.0, 0.5);
    assert!(f(lo) < 0.0 && f(hi) > 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// A head-on pair with P02's duration law at Λ = ρw²/(6βH0) (w the closing speed).
fn p02_head_on(lambda: f64, bond_test: &str) -> Simulation {
    let w = (6.0 * H0 * lambda / RHO).sqrt();
    let mut patch = pair(-0.002, 0.5 * w, 0.002, -0.5 * w);
    merge(
        &mut patch,
        json!({
            "impact": { "a0": 0.01, "duration": "p02", "bond_test": bond_test },
            "time": { "end": 0.004 / w }
        }),
    );
    let mut sim = Simulation::new(&scenario(patch)).expect("builds");
    sim.run().expect("runs");
    assert_eq!(sim.counters().impacts, 1);
    sim
}

#[test]
fn p02_in_loop_accretion_bonds_from_the_first_iterate_threshold_not_at_lambda_1() {
    let threshold = first_iterate_threshold(0.01);
    // docs/model.md §5.3: about 0.0033, i.e. ~6 % of the critical speed (Λ ∝ w²).
    assert!((threshold - 0.0033).abs() < 1e-4, "{threshold}");
    for lambda in [threshold * 1.001, 0.5, 0.99] {
        let fixed = p02_head_on(lambda, "fixed_point");
        assert_eq!(
            fixed.counters().bounces,
            1,
            "Λ = {lambda}: e* > 0 below Λ = 1"
        );
        let any = p02_head_on(lambda, "any_iterate");
        assert_eq!(
            any.counters().bonds,
            1,
            "Λ = {lambda}: an iterate presses at 2H"
        );
        assert_eq!(any.bodies().len(), 1);
    }
    // Nearly elastic impacts converge without any iterate reaching 2H (Λ = 1e-4,
    // e* ≈ 0.98, where the iteration contracts): the solve then goes on exactly as under
    // `fixed_point`, so the two runs are bit-identical.
    let fixed = p02_head_on(1e-4, "fixed_point");
    let any = p02_head_on(1e-4, "any_iterate");
    assert_eq!(any.counters().bounces, 1);
    assert_eq!(fixed.bodies(), any.bodies());
}

/// One stepped-core run with a fixed step that first finds the pair overlapping; the
/// light grain (1 primary) at −x meets the heavy one (8 primaries, radius 2 b0) and the
/// centre of mass is at rest. Returns (before, after) of the impact step and Δt.
fn overlapping_bounce(separation: &str) -> (Vec<BodyState>, Vec<BodyState>, f64) {
    let dt = 1e-4;
    let s = scenario(json!({
        "cloud": {
            "count": 2,
            "bodies": [
                { "position": [-0.004, 0, 0], "velocity": [2.0, 0, 0] },
                { "position": [0.002, 0, 0], "velocity": [-0.25, 0, 0], "primaries": 8.0 }
            ]
        },
        "impact": { "a0": 0.5, "separation": separation },
        "time": { "end": 0.01, "stepping": { "fixed": { "dt": dt } } }
    }));
    let mut sim = Simulation::new(&s).expect("builds");
    loop {
        let before = sim.bodies();
        sim.step().expect("steps");
        if sim.counters().impacts == 1 {
            return (before, sim.bodies(), dt);
        }
        assert!(!sim.is_finished(), "the pair never met");
    }
}

#[test]
fn separation_readings_move_the_pair_as_printed() {
    for reading in ["normal", "velocities"] {
        let (before, after, dt) = overlapping_bounce(reading);
        assert_eq!(after.len(), 2, "{reading}: the pair bounces");
        let (bi, bj) = (before[0].radius, before[1].radius);
        let distance = before[1].position.x - before[0].position.x;
        let overlap = bi + bj - distance;
        assert!(
            overlap > 1e-6,
            "{reading}: the step must find an overlap, got {overlap}"
        );
        // Separation move = position after − position before − Δt · outgoing velocity.
        let moved =
            |k: usize| after[k].position.x - before[k].position.x - dt * after[k].velocity.x;
        let (mi, mj) = (before[0].mass, before[1].mass);
        let expected = match reading {
            // Along n̂ to touching, in inverse proportion to mass.
            "normal" => (-overlap * mj / (mi + mj), overlap * mi / (mi + mj)),
            // P02 (8): b (1 − δ) along each outgoing velocity (−x for i, +x for j here).
            _ => {
                let shortfall = 1.0 - distance / (bi + bj);
                assert!(after[0].velocity.x < 0.0 && after[1].velocity.x > 0.0);
                (-bi * shortfall, bj * shortfall)
            }
        };
        // 1e-15 m: positions ~1e-3 m carry rounding ~1e-19 m per operation.
        assert!(
            (moved(0) - expected.0).abs() < 1e-15 && (moved(1) - expected.1).abs() < 1e-15,
            "{reading}: moved ({}, {}) vs {expected:?}",
            moved(0),
            moved(1)
        );
        let com_shift = (mi * moved(0) + mj * moved(1)) / (mi + mj);
        if reading == "normal" {
            assert!(
                com_shift.abs() < 1e-15,
                "the centre of mass stays: {com_shift}"
            );
        } else {
            // P02 (8) shifts it, here by (m_j b_j − m_i b_i)/(m_i + m_j) (1 − δ) = 5/9 of
            // the overlap (docs/model.md §5.3).
            assert!(
                com_shift > 0.5 * overlap,
                "{com_shift} vs overlap {overlap}"
            );
        }
    }
}

#[test]
fn explicit_defaults_change_nothing() {
    // The readings at their defaults neither appear in the scenario JSON nor change it.
    let text = std::fs::read_to_string("scenarios/paper2004_best.json").unwrap();
    let plain = Scenario::from_json(&text).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    merge(
        &mut value,
        json!({ "impact": {
            "pair_hardness": "min", "friction_cap": "sticking",
            "bond_test": "fixed_point", "separation": "normal"
        }}),
    );
    let explicit = Scenario::from_value(value).unwrap();
    assert_eq!(plain, explicit);
    let json = plain.to_json();
    for key in ["pair_hardness", "friction_cap", "bond_test", "separation"] {
        assert!(!json.contains(key), "{key} written at its default");
    }
}

#[test]
fn an_unknown_reading_is_refused_with_its_field() {
    let text = std::fs::read_to_string("scenarios/two_body.json").unwrap();
    let bad = text.replace(
        "\"beta\": 1.0",
        "\"beta\": 1.0, \"pair_hardness\": \"softest\"",
    );
    assert_ne!(bad, text);
    let err = Scenario::from_json(&bad).unwrap_err().to_string();
    assert!(err.contains("impact.pair_hardness"), "{err}");
    assert!(err.contains("min"), "names the allowed values: {err}");
}

mod study {
    //! `agglo study readings`: the baseline is the plain run bit for bit, the study does
    //! not depend on the thread count, and P02 runs use the inverse problem's end time.

    use std::path::Path;

    use agglo::farm::Workers;
    use agglo::inverse::InverseProblem;
    use agglo::prelude::*;
    use agglo::study::readings::{
        BASELINE, ReadingsOptions, catalogue, measure, run_readings, scenario_for, write_readings,
    };

    fn load(name: &str) -> Scenario {
        Scenario::load(
            &Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenarios")
                .join(name),
        )
        .unwrap()
    }

    fn options(only: &[&str]) -> ReadingsOptions {
        ReadingsOptions {
            seeds: 2,
            only: only.iter().map(|s| s.to_string()).collect(),
            target_growth: Some(3.23),
            ..Default::default()
        }
    }

    #[test]
    fn the_baseline_is_agglo_run_bit_for_bit_and_threads_change_nothing() {
        let base = load("paper2004_best.json");
        let study = run_readings(
            &base,
            &options(&["pair_hardness_max"]),
            &Workers::local(2),
            |_| {},
        )
        .unwrap();
        assert_eq!(study.readings[0].key, BASELINE);
        assert_eq!(study.seeds, vec![2004, 2005]);
        for run in study.runs.iter().filter(|r| r.reading == 0) {
            // The plain run of the file with that seed, as `agglo run --seed` makes it.
            let mut plain = base.clone();
            plain.seed = run.seed;
            let mut direct = measure(&plain).unwrap();
            let mut got = run.result.clone().unwrap();
            (direct.wall_seconds, got.wall_seconds) = (0.0, 0.0);
            assert_eq!(got, direct, "seed {}", run.seed);
            assert_eq!(
                got.growth_ratio.to_bits(),
                direct.growth_ratio.to_bits(),
                "b_f/b0 bit for bit"
            );
        }
        // The same study on one thread: identical runs.
        let single = run_readings(
            &base,
            &options(&["pair_hardness_max"]),
            &Workers::local(1),
            |_| {},
        )
        .unwrap();
        for (a, b) in study.runs.iter().zip(&single.runs) {
            let (mut x, mut y) = (a.result.clone().unwrap(), b.result.clone().unwrap());
            (x.wall_seconds, y.wall_seconds) = (0.0, 0.0);
            assert_eq!((a.reading, a.seed, x), (b.reading, b.seed, y));
        }
        // The files come out, and the table names every reading run.
        let dir = tempfile::tempdir().unwrap();
        write_readings(dir.path(), &study).unwrap();
        let table = std::fs::read_to_string(dir.path().join("readings.md")).unwrap();
        assert!(table.contains("`baseline`") && table.contains("`pair_hardness_max`"));
        let csv = std::fs::read_to_string(dir.path().join("runs.csv")).unwrap();
        assert_eq!(
            csv.lines().count(),
            1 + 2 * 2,
            "header + 2 readings × 2 seeds"
        );
        assert!(dir.path().join("readings.png").exists());
    }

    #[test]
    fn p02_runs_take_the_inverse_problems_end_time() {
        let base = load("paper2002_best.json");
        let problem = InverseProblem::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper2002_inverse.json"),
        )
        .unwrap();
        let baseline = &catalogue(&base)[0];
        for seed in [2002, 77] {
            let ours = scenario_for(&base, baseline, seed, Some(200)).unwrap();
            // The inverse problem's scenario at the shipped D (its base is the same file).
            let theirs = problem.scenario_with("box.half_width", 1e-5, seed).unwrap();
            assert_eq!(ours, theirs, "seed {seed}");
        }
    }

    #[test]
    fn an_unknown_reading_is_refused_with_the_list() {
        let base = load("paper2002_best.json");
        let err = run_readings(&base, &options(&["a0_p02"]), &Workers::local(1), |_| {})
            .unwrap_err()
            .to_string();
        // a0_p02 is a reading of P04's scene only.
        assert!(
            err.contains("a0_p02") && err.contains("bond_any_iterate"),
            "{err}"
        );
    }
}

mod settings {
    use agglo::prelude::*;
    use agglo::study::readings::with_settings;

    #[test]
    fn set_changes_the_scene_and_refuses_unknown_fields() {
        let base = Scenario::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenarios/paper2002_best.json"
        )))
        .unwrap();
        let s = with_settings(
            &base,
            &[
                "box.half_width=1e-4".into(),
                "impact.pair_hardness=max".into(),
            ],
        )
        .unwrap();
        assert_eq!(s.domain.half_width, 1e-4);
        assert_eq!(s.impact.pair_hardness, agglo::scenario::PairHardness::Max);
        assert!(s.name.contains("box.half_width=1e-4"));
        let err = with_settings(&base, &["box.half_widht=1e-4".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("half_widht"), "{err}");
        let err = with_settings(&base, &["box.half_width=-1".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("box.half_width"), "{err}");
    }
}

mod command_line {
    use std::process::Command;

    fn agglo() -> Command {
        Command::new(env!("CARGO_BIN_EXE_agglo"))
    }

    const TWO_BODY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/two_body.json");

    /// `agglo run FILE --seed S --summary` for each seed, and `agglo study readings` over
    /// the same seeds: the study's baseline runs and its ensemble mean agree bit for bit.
    #[test]
    fn the_study_agrees_with_a_loop_of_agglo_run_bit_for_bit() {
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/paper2004_best.json");
        let dir = tempfile::tempdir().unwrap();
        let seeds = [2004u64, 2005, 2006];
        let direct: Vec<f64> = seeds
            .iter()
            .map(|&seed| super::common::growth_of_agglo_run(scene.as_ref(), seed, dir.path()))
            .collect();
        let study_dir = dir.path().join("study");
        let out = agglo()
            .args([
                "study", "readings", scene, "--seeds", "3", "--only", "a0_p02", "--out",
            ])
            .arg(&study_dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // runs.csv: reading, seed, growth_ratio, … (shortest round-trip floats).
        let runs = std::fs::read_to_string(study_dir.join("runs.csv")).unwrap();
        let baseline: Vec<(u64, f64)> = runs
            .lines()
            .skip(1)
            .filter(|l| l.starts_with("baseline,"))
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                (f[1].parse().unwrap(), f[2].parse().unwrap())
            })
            .collect();
        assert_eq!(baseline.len(), 3);
        for (seed, growth) in &baseline {
            let k = seeds.iter().position(|s| s == seed).unwrap();
            assert_eq!(growth.to_bits(), direct[k].to_bits(), "seed {seed}");
        }
        // The ensemble mean is the mean of those runs, in seed order.
        let mean = direct.iter().sum::<f64>() / 3.0;
        let table = std::fs::read_to_string(study_dir.join("readings.csv")).unwrap();
        let row = table.lines().find(|l| l.starts_with("baseline,")).unwrap();
        let header: Vec<&str> = table.lines().next().unwrap().split(',').collect();
        let col = header.iter().position(|h| *h == "growth_mean").unwrap();
        let got: f64 = row.split(',').nth(col).unwrap().parse().unwrap();
        assert_eq!(
            got.to_bits(),
            mean.to_bits(),
            "ensemble mean {got} vs {mean}"
        );
    }

    #[test]
    fn study_readings_writes_its_files_and_refuses_unknown_readings() {
        let dir = tempfile::tempdir().unwrap();
        let out = agglo()
            .args(["study", "readings", TWO_BODY, "--seeds", "2", "--out"])
            .arg(dir.path())
            .args(["--only", "pair_hardness_max,bond_any_iterate"])
            .args(["--set", "impact.a0=0.3"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let table = String::from_utf8_lossy(&out.stdout);
        assert!(table.contains("two_body (impact.a0=0.3)"), "{table}");
        // Two grains at 3 m/s each bond under every reading: b_f/b0 = 2^(1/3).
        assert!(
            table.contains("| `bond_any_iterate` |") && table.contains("1.260"),
            "{table}"
        );
        for file in [
            "readings.csv",
            "runs.csv",
            "readings.md",
            "readings.png",
            "readings.svg",
        ] {
            assert!(dir.path().join(file).exists(), "{file}");
        }

        let listed = agglo()
            .args(["study", "readings", TWO_BODY, "--out"])
            .arg(dir.path())
            .arg("--list")
            .output()
            .unwrap();
        assert!(String::from_utf8_lossy(&listed.stdout).contains("separation_velocities"));

        let bad = agglo()
            .args(["study", "readings", TWO_BODY, "--out"])
            .arg(dir.path())
            .args(["--only", "softest_hardness"])
            .output()
            .unwrap();
        assert!(!bad.status.success());
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            err.contains("softest_hardness") && err.contains("pair_hardness_max"),
            "{err}"
        );
    }
}

/// `physics.impacts_per_step`: one impact per body per step (the engine) or every
/// contact found in the step (a reading of the papers, which do not say).
mod impacts_per_step {
    use super::*;

    /// A at −x moving +v, B at rest in the middle, C at +x moving −v, radii 1 mm and
    /// gaps g = 1e-7 m. With Δt = 2g/v the first step ends with both pairs overlapping
    /// by g, so the second step finds both contacts (fixed steps: stepped core).
    fn three_in_a_line(v: f64, every: bool) -> Scenario {
        let g = 1e-7;
        let x = 0.002 + g;
        let dt = 2.0 * g / v;
        scenario(json!({
            "cloud": {
                "count": 3,
                "bodies": [
                    { "position": [-x, 0, 0], "velocity": [v, 0, 0] },
                    { "position": [0, 0, 0], "velocity": [0, 0, 0] },
                    { "position": [x, 0, 0], "velocity": [-v, 0, 0] }
                ]
            },
            "physics": {
                "impacts_per_step": if every { "every_contact" } else { "one_per_body" },
                "fragmentation": false
            },
            "time": { "end": 2.0 * dt, "stepping": { "fixed": { "dt": dt } } }
        }))
    }

    fn momentum(sim: &Simulation) -> DVec3 {
        sim.bodies().iter().map(|b| b.mass * b.velocity).sum()
    }

    #[test]
    fn every_contact_resolves_both_contacts_of_the_middle_body_in_one_step() {
        for (every, impacts, deferred) in [(false, 1, 1), (true, 2, 0)] {
            let s = three_in_a_line(50.0, every);
            assert!(!s.uses_event_core());
            let mut sim = Simulation::new(&s).unwrap();
            let p0 = momentum(&sim);
            sim.run().unwrap();
            let c = sim.counters();
            assert_eq!(
                (c.impacts, c.deferred_contacts),
                (impacts, deferred),
                "every_contact = {every}"
            );
            // Momentum is conserved whatever the order (zero here, to rounding of 2·m·v).
            let m = sim.bodies()[0].mass;
            assert!(
                (momentum(&sim) - p0).length() <= 1e-12 * m * 50.0,
                "every = {every}"
            );
        }
    }

    #[test]
    fn bonds_that_chain_in_one_step_make_one_body() {
        // Fast enough that every impact bonds (above the critical speed). One impact per
        // body: A and B merge, C waits; every contact: A–B and B–C bond in the same step
        // and the chain becomes one body.
        for (every, bodies_left) in [(false, 2), (true, 1)] {
            let s = three_in_a_line(50.0, every);
            let mut sim = Simulation::new(&s).unwrap();
            let mass: f64 = sim.bodies().iter().map(|b| b.mass).sum();
            sim.run().unwrap();
            let c = sim.counters();
            assert_eq!(c.bonds, if every { 2 } else { 1 }, "every = {every}");
            let after = sim.bodies();
            assert_eq!(after.len(), bodies_left, "every = {every}");
            let total: f64 = after.iter().map(|b| b.mass).sum();
            assert!((total - mass).abs() <= 1e-14 * mass);
            assert_eq!(after.iter().map(|b| b.primaries).sum::<f64>(), 3.0);
            assert!(momentum(&sim).length() <= 1e-12 * mass * 50.0);
            // The energy ledgers close: in the chain, the relative motion a later impact
            // gave a bonded pair is heat of the merged body, tallied as dissipation.
            let summary = sim.summary();
            assert!(
                summary.invariant_violations.is_empty(),
                "every = {every}: {:?}",
                summary.invariant_violations
            );
            if every {
                // The chain keeps the smallest id of the three (A's) and sits at the centre of mass.
                assert_eq!(after[0].id, 0);
                assert!(
                    after[0].position.length() < 1e-9,
                    "centre of mass at the origin"
                );
            }
        }
    }

    #[test]
    fn the_event_core_refuses_every_contact_by_name() {
        let mut s = three_in_a_line(1.0, true);
        s.time.stepping = agglo::scenario::Stepping::Adaptive {
            step_factor: 1.0,
            dt_min: 1e-12,
            dt_max: 1e-3,
            skin: 0.5,
        };
        s.time.core = agglo::scenario::Core::Events;
        let err = s.validate().unwrap_err().to_string();
        assert!(
            err.contains("time.core") && err.contains("impacts_per_step"),
            "{err}"
        );
    }
}
