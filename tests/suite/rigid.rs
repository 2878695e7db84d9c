//! Rigid aggregates (`physics.merge_mode = "rigid"`, docs/model.md §6.1): contacts at
//! the closed-form time between primaries of different aggregates, never inside one;
//! conservation and the ledgers over a cluster–cluster run; the shape of the aggregates
//! it grows (connected, never overlapping, the fractal fit); the refusals.

use crate::common;

use agglo::aggregates::{
    AggregateShape, AggregateSummary, FIT_MIN_PRIMARIES, aggregate_shapes, fractal_fit,
};
use agglo::glam::DVec3;
use agglo::prelude::*;
use agglo::resources::{BoxGeometry, EnergyLedger};
use common::merge;
use serde_json::{Value, json};

const B: f64 = 1e-3;

/// A sticky (H0 = 1e-6 Pa: every impact bonds), cold, non-fragmenting rigid scene.
fn rigid(patch: Value) -> Scenario {
    let mut base = json!({
        "name": "rigid",
        "seed": 1,
        "box": { "half_width": 0.05 },
        "cloud": { "count": 2, "radius": B, "v_rel": [0, 0, 0] },
        "material": { "rho": 2000, "H0": 1e-6, "C": 1000, "theta0": 300 },
        "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 },
        "time": { "end": 0.1 },
        "physics": { "merge_mode": "rigid", "fragmentation": false }
    });
    merge(&mut base, patch);
    Scenario::from_value(base).expect("rigid test scenario is valid")
}

/// Step `sim` to its end; the time of each step in which impacts happened (contacts are
/// resolved at the step's start time on the event core).
fn impact_times(sim: &mut Simulation) -> Vec<f64> {
    let mut times = Vec::new();
    while !sim.is_finished() {
        let (t, before) = (sim.clock().time, sim.counters().impacts);
        sim.step().expect("steps");
        for _ in before..sim.counters().impacts {
            times.push(t);
        }
    }
    times
}

/// A dimer A forms at rest (bodies 0 and 1 meet head on along y at t1), then a monomer B
/// flying along −x at the height of A's upper primary touches that primary — not the
/// centre of mass, where a coalesced sphere would sit — at the closed-form time t2.
fn dimer_and_monomer(speed: f64) -> Scenario {
    rigid(json!({
        "cloud": {
            "count": 3,
            "bodies": [
                { "position": [-0.015, -0.01, 0], "velocity": [0, 1, 0] },
                { "position": [-0.015, 0.01, 0], "velocity": [0, -1, 0] },
                { "position": [0.03, B, 0], "velocity": [-speed, 0, 0] }
            ]
        }
    }))
}

#[test]
fn aggregates_meet_at_the_closed_form_time_of_their_touching_primaries() {
    let speed = 2.0;
    let mut sim = Simulation::new(&dimer_and_monomer(speed)).expect("builds");
    let times = impact_times(&mut sim);
    // t1: the gap 0.02 − 2b closes at 2 m/s; A then rests with its primaries at y = ±b.
    let t1 = (0.02 - 2.0 * B) / 2.0;
    // t2: B's centre reaches x = −0.015 + 2b, touching A's upper primary (y = b).
    let t2 = (0.03 - (-0.015 + 2.0 * B)) / speed;
    assert_eq!(
        times.len(),
        2,
        "exactly two impacts (none between primaries of one aggregate): {times:?}"
    );
    // The core solves each contact time in closed form: rounding of a few operations on
    // numbers of order 1e-2 (1e-14 relative would show a drift, a wrong time is ≥ 1e-4).
    for (t, expected) in times.iter().zip([t1, t2]) {
        assert!(
            (t - expected).abs() <= 1e-12 * expected,
            "impact at {t:e} s, closed form {expected:e} s"
        );
    }
    // One aggregate of all three, moving together with the total momentum over 3m.
    let bodies = sim.bodies();
    let v = DVec3::new(-speed / 3.0, 0.0, 0.0);
    for b in &bodies {
        assert_eq!(b.velocity, bodies[0].velocity, "one velocity, to the bit");
        assert!((b.velocity - v).length() <= 1e-15 * speed, "{}", b.velocity);
    }
    let shapes = aggregate_shapes(sim.world());
    assert_eq!(shapes.len(), 1);
    assert_eq!((shapes[0].id, shapes[0].primaries), (0, 3));
    // The monomer touches the upper primary: centres 2b apart along x, same y.
    let (upper, monomer) = (bodies[1].position, bodies[2].position);
    let d = upper - monomer;
    let d = d - 0.1 * (d / 0.1).round();
    assert!(
        ((d.length() - 2.0 * B) / B).abs() <= 1e-9,
        "touching primaries {d} apart"
    );
    // R_g of the three centres (0, −b), (0, b), (2b, b) about their mean (2b/3, b/3):
    // R_g² = (20/9 + 8/9 + 20/9) b² / 3 = 16/9 b², R_g = 4b/3.
    let rg = 4.0 / 3.0 * B;
    assert!(
        (shapes[0].radius_of_gyration - rg).abs() <= 1e-12 * rg,
        "R_g {:e}, exact {rg:e}",
        shapes[0].radius_of_gyration
    );
}

#[test]
fn a_rigid_aggregate_straddling_the_periodic_boundary_keeps_its_shape() {
    // The same dimer-and-monomer, moved so that the aggregate forms across x = ±D: the
    // offsets (unwrapped) give the same R_g while the positions wrap one by one.
    let mut s = dimer_and_monomer(2.0);
    for body in &mut s.cloud.bodies {
        let x = body.position[0] + 0.015 + 0.05 - 0.0005;
        body.position[0] = x - 0.1 * ((x + 0.05) / 0.1).floor();
    }
    let mut sim = Simulation::new(&s).expect("builds");
    let times = impact_times(&mut sim);
    assert_eq!(times.len(), 2, "{times:?}");
    let shapes = aggregate_shapes(sim.world());
    let rg = 4.0 / 3.0 * B;
    assert_eq!(shapes[0].primaries, 3);
    assert!((shapes[0].radius_of_gyration - rg).abs() <= 1e-12 * rg);
}

/// A dilute cluster–cluster scene: `n` monomers at volume fraction 1e-3, Maxwellian
/// velocities (T_g = 1 m²/s²) without drift, every contact sticking.
fn cluster_cluster(n: usize, end: f64, seed: u64) -> Scenario {
    let b0: f64 = 5.76e-5;
    // (2D)³ φ = n (4/3) π b0³ with φ = 1e-3.
    let half_width = 0.5 * (n as f64 * 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) / 1e-3).cbrt();
    rigid(json!({
        "seed": seed,
        "box": { "half_width": half_width },
        "cloud": {
            "count": n,
            "radius": b0,
            "v_rel": null,
            "velocity_distribution": "maxwell",
            "granular_temperature": 1.0,
            "remove_drift": true
        },
        "material": { "rho": 1000 },
        "time": { "end": end }
    }))
}

fn momentum_and_scale(bodies: &[BodyState]) -> (DVec3, f64) {
    let p = bodies.iter().map(|b| b.mass * b.velocity).sum();
    let scale = bodies.iter().map(|b| b.mass * b.velocity.length()).sum();
    (p, scale)
}

fn kinetic(bodies: &[BodyState]) -> f64 {
    bodies
        .iter()
        .map(|b| 0.5 * b.mass * b.velocity.length_squared())
        .sum()
}

#[test]
fn a_cluster_cluster_run_conserves_mass_and_momentum_and_closes_its_ledgers() {
    let s = cluster_cluster(600, 0.4, 7);
    let mut sim = Simulation::new(&s).expect("builds");
    let start = sim.bodies();
    sim.run().expect("runs");
    let end = sim.bodies();
    let summary = sim.summary();
    assert!(summary.counters.bonds >= 300, "{:?}", summary.counters);
    assert_eq!(summary.counters.bounces, 0);
    assert_eq!(end.len(), start.len(), "primaries are never merged away");
    // Mass: the primaries are untouched; the aggregates' masses are their sums.
    let mass: f64 = start.iter().map(|b| b.mass).sum();
    assert_eq!(mass, end.iter().map(|b| b.mass).sum::<f64>());
    // Momentum: each bond conserves it to rounding (~1e-16 of Σ m|v| per bond; a few
    // hundred bonds stay far below 1e-12, a wrong reduced mass is of order 1).
    let ((p0, scale), (p1, _)) = (momentum_and_scale(&start), momentum_and_scale(&end));
    assert!(
        (p1 - p0).length() <= 1e-12 * scale,
        "momentum {p0} → {p1} (scale {scale:e})"
    );
    // The kinetic energy lost is exactly what the ledger booked as impact dissipation
    // (1e-12 of the initial energy: rounding of every bond's sums, see diagnostics).
    let ledger = sim.ledger();
    let lost = kinetic(&start) - kinetic(&end);
    assert!(
        (lost - ledger.impact_dissipation).abs() <= 1e-12 * kinetic(&start),
        "lost {lost:e} J, booked {:e} J",
        ledger.impact_dissipation
    );
    // The heat the law made is in the temperatures (one C for all, no cooling).
    let c = s.material.C;
    let heat: f64 = end
        .iter()
        .map(|b| b.mass * c * (b.temperature - 300.0))
        .sum();
    assert!(
        (heat - ledger.impact_dissipation - ledger.reaction_heat).abs()
            <= 1e-9 * ledger.impact_dissipation,
        "heat {heat:e} J, booked {:e} J",
        ledger.impact_dissipation + ledger.reaction_heat
    );
    // The run's own checks found nothing.
    assert!(summary.invariant_violations.is_empty());
    assert!(summary.max_momentum_error <= 1e-12 && summary.max_energy_error <= 1e-12);
    assert_eq!(summary.counters.overlap_violations, 0);
}

/// The primaries of each aggregate (by the `aggregate` column of the final state): one
/// velocity to the bit, connected by touching contacts, and no two primaries of the
/// whole run overlap (O(N²) here: a test of a few hundred bodies).
fn assert_aggregates_are_rigid_and_connected(sim: &Simulation) {
    let bodies = sim.bodies();
    let carried = sim.carried();
    let column = carried
        .names
        .iter()
        .position(|n| n == "aggregate")
        .expect("an aggregate column");
    let of: Vec<u64> = carried
        .rows
        .iter()
        .map(|r| r.1[column].expect("every primary has an aggregate") as u64)
        .collect();
    let side = 2.0 * sim.world().resource::<BoxGeometry>().half_width;
    let n = bodies.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let d = bodies[j].position - bodies[i].position;
            let d = d - side * (d / side).round();
            let reach = bodies[i].radius + bodies[j].radius;
            // Touching pairs sit at reach to rounding of positions (≤ 1e-9 reach).
            assert!(
                d.length() >= reach * (1.0 - 1e-9),
                "primaries {} and {} overlap: {:e} < {reach:e}",
                bodies[i].id,
                bodies[j].id,
                d.length()
            );
            if of[i] == of[j] {
                assert_eq!(bodies[i].velocity, bodies[j].velocity);
                if d.length() <= reach * (1.0 + 1e-9) {
                    let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                    parent[ri] = rj;
                }
            }
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            if of[i] == of[j] {
                assert_eq!(
                    root(&mut parent, i),
                    root(&mut parent, j),
                    "aggregate {} is not connected by touching primaries",
                    of[i]
                );
            }
        }
    }
    // The aggregate id is its smallest primary id.
    for (i, b) in bodies.iter().enumerate() {
        assert!(of[i] <= b.id);
    }
}

/// scenarios/bcca.json with `edit` applied, run to its end: the scene and the finished run.
fn bcca(edit: impl FnOnce(&mut Scenario)) -> (Scenario, Simulation) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/bcca.json");
    let mut scene = Scenario::load(&path).expect("scenarios/bcca.json loads");
    edit(&mut scene);
    let mut sim = Simulation::new(&scene).expect("builds");
    sim.run().expect("runs");
    (scene, sim)
}

/// D_f, k_f of the aggregates of a finished run, fitted over k ≥ `min_k`.
fn fit(sim: &Simulation, min_k: usize) -> (f64, f64, usize) {
    let shapes: Vec<AggregateShape> = aggregate_shapes(sim.world());
    let f = fractal_fit(&shapes, sim.primary().radius, min_k).expect("aggregates to fit");
    (f.dimension, f.prefactor, f.aggregates)
}

/// Issue 41's check of a ballistic cluster–cluster run: the mean aggregate holds at least
/// 100 primaries and D_f of the fit over k ≥ `FIT_MIN_PRIMARIES` lies in 1.85–2.05 (the
/// literature's 1.9–1.95 widened by the seed-to-seed spread). Returns the run's aggregate
/// summary and the fit (D_f, k_f, aggregates used).
fn grown_to_a_mean_of_a_hundred_in_issue_41s_band(
    sim: &Simulation,
) -> (AggregateSummary, (f64, f64, usize)) {
    let summary = sim.summary().aggregates.expect("aggregates");
    assert!(summary.mean_primaries >= 100.0, "{summary:?}");
    let (d_f, k_f, used) = fit(sim, FIT_MIN_PRIMARIES);
    assert!(
        (1.85..=2.05).contains(&d_f),
        "D_f = {d_f} over {used} aggregates, k_f = {k_f}"
    );
    (summary, (d_f, k_f, used))
}

#[test]
fn cluster_cluster_aggregates_are_connected_rigid_and_open() {
    // 1000 monomers to a mean of ≈ 30 per aggregate (≈ 30 aggregates): a loose fit.
    // Seeds 1–8 of this scene gave D_f = 1.96, 1.86, 1.85, 1.88, 1.93, 1.90, 1.92, 1.76
    // over their 13–28 aggregates of k ≥ 5 (mean 1.88, spread 0.06): the band is ±4
    // spreads. Chains (D_f = 1) or compact clusters (D_f = 3) fall far outside.
    let mut sim = Simulation::new(&cluster_cluster(1000, 0.2, 7)).expect("builds");
    sim.run().expect("runs");
    assert_aggregates_are_rigid_and_connected(&sim);
    let summary = sim
        .summary()
        .aggregates
        .expect("a rigid run summarises its aggregates");
    assert!(summary.mean_primaries >= 20.0, "{summary:?}");
    let (d_f, k_f, used) = fit(&sim, FIT_MIN_PRIMARIES);
    assert!(
        (1.64..=2.12).contains(&d_f),
        "D_f = {d_f} over {used} aggregates, k_f = {k_f}"
    );
}

#[test]
fn ten_thousand_primaries_grow_to_a_mean_of_a_hundred_with_an_open_fractal_dimension() {
    // The shipped scenarios/bcca.json (≈ 2 s): 1e4 primaries at volume fraction 1e-3, every
    // contact sticks, to t = 0.5 s. Seeds 1, 2, 3 gave D_f = 1.87, 1.97, 1.92 (SE of each
    // fit ≈ 0.04) with k_f = 1.36, 1.17, 1.27 and means of 169, 167, 161 primaries. The
    // band is issue 41's, the literature's ballistic cluster–cluster 1.9–1.95 widened by
    // the seed-to-seed spread (0.05).
    let (_, sim) = bcca(|_| {});
    let (summary, _) = grown_to_a_mean_of_a_hundred_in_issue_41s_band(&sim);
    // What docs/model.md §6.1 quotes of this deterministic run, to its digits.
    assert_eq!(summary.count, 59);
    assert!((summary.mean_primaries - 169.5).abs() < 0.05);
    let fractal = summary.fractal.expect("a fit");
    assert_eq!(fractal.aggregates, 51);
    assert!((fractal.dimension - 1.87).abs() < 0.005, "{fractal:?}");
    assert!((fractal.dimension_se - 0.04).abs() < 0.005, "{fractal:?}");
    assert!((fractal.prefactor - 1.36).abs() < 0.005, "{fractal:?}");
    // The mean filling factor Σa³/R_c³ of its aggregates of k ≥ 5 (docs/model.md §6.1).
    let phi = summary.mean_filling_factor.expect("aggregates of k ≥ 5");
    assert!((phi - 0.0993).abs() < 5e-5, "{phi}");
}

#[test]
#[ignore = "two more 1e4 runs (≈ 5 s): cargo test --test suite rigid -- --ignored"]
fn other_seeds_of_bcca_give_what_the_docs_quote() {
    // docs/model.md §6.1: seeds 2 and 3 of scenarios/bcca.json give D_f = 1.97 and 1.92.
    for (seed, quoted) in [(2, 1.97), (3, 1.92)] {
        let (_, sim) = bcca(|scene| scene.seed = seed);
        let (d_f, _, _) = fit(&sim, FIT_MIN_PRIMARIES);
        assert!((d_f - quoted).abs() < 0.005, "seed {seed}: D_f = {d_f}");
    }
}

#[test]
#[ignore = "1e5 primaries, ≈ 40 s: cargo test --release --test suite rigid -- --ignored"]
fn a_hundred_thousand_primaries_grow_to_a_mean_of_a_hundred() {
    // Measured (dev profile, one thread, 39 s wall): 679 aggregates, mean k = 147,
    // D_f = 1.909 ± 0.013, k_f = 1.33 over the 550 with k ≥ 5.
    // scenarios/bcca.json with 10× the primaries in a box 10^(1/3) wider (φ kept), as
    // `agglo run scenarios/bcca.json --set cloud.count=100000 --set box.half_width=0.021544`.
    let (mut scene, sim) = bcca(|scene| {
        scene.cloud.count = 100_000;
        scene.domain.half_width = 0.021544;
    });
    let (summary, (d_f, k_f, used)) = grown_to_a_mean_of_a_hundred_in_issue_41s_band(&sim);
    // What docs/model.md §6.1 quotes of this deterministic run, to its digits.
    assert_eq!(summary.count, 679);
    assert!((summary.mean_primaries - 147.0).abs() < 0.5);
    assert_eq!(used, 550);
    assert!((d_f - 1.909).abs() < 0.0005 && (k_f - 1.33).abs() < 0.005);
    let (d_2, k_2, used_2) = fit(&sim, 2);
    assert_eq!(used_2, 626);
    assert!((d_2 - 1.850).abs() < 0.0005 && (k_2 - 1.53).abs() < 0.005);
    let (d_20, _, _) = fit(&sim, 20);
    assert!((d_20 - 1.93).abs() < 0.005, "k ≥ 20: D_f = {d_20}");
    let (d_100, _, _) = fit(&sim, 100);
    assert!((d_100 - 1.86).abs() < 0.005, "k ≥ 100: D_f = {d_100}");
    // The cost figures docs/model.md §6.1 quotes, to their digits, and the same cloud's
    // in coalesce mode.
    let near = |x: u64, quoted: f64| ((x as f64 - quoted) / quoted).abs() < 0.005;
    let rigid = sim.core_stats().expect("event core");
    assert!(near(rigid.crossings, 2.44e7) && near(rigid.predictions, 2.62e7));
    assert!(near(rigid.pair_tests, 2.66e8), "{rigid:?}");
    assert_eq!(sim.counters().bonds, 99_321);
    let not_by_crossings = rigid.predictions - rigid.crossings;
    assert!(near(not_by_crossings, 1.8e6) && (not_by_crossings - 100_000) / 99_321 == 17);
    scene.physics.merge_mode = agglo::scene::MergeMode::Coalesce;
    let mut coalesce = Simulation::new(&scene).expect("builds");
    coalesce.run().expect("runs");
    let stats = coalesce.core_stats().expect("event core");
    assert!(near(stats.crossings, 1.06e7) && near(stats.predictions, 1.08e7));
    assert!(near(stats.pair_tests, 1.17e7), "{stats:?}");
}

#[test]
fn the_same_rigid_scene_and_seed_give_the_same_bytes() {
    let run = || {
        let mut sim = Simulation::new(&cluster_cluster(300, 0.3, 3)).expect("builds");
        sim.run().expect("runs");
        (sim.bodies(), sim.carried(), sim.ledger())
    };
    assert_eq!(run(), run());
}

fn refusal(patch: Value) -> String {
    let mut base = json!({
        "name": "rigid",
        "seed": 1,
        "box": { "half_width": 0.05 },
        "cloud": { "count": 2, "radius": B, "v_rel": [0, 0, 0] },
        "material": { "rho": 2000, "H0": 1e-6, "C": 1000, "theta0": 300, "gamma": null },
        "time": { "end": 0.1 },
        "physics": { "merge_mode": "rigid" }
    });
    merge(&mut base, patch);
    Scenario::from_value(base).expect_err("refused").to_string()
}

#[test]
fn what_rigid_does_not_support_yet_is_refused_naming_the_field() {
    let stepped = refusal(json!({ "time": { "core": "stepped" } }));
    assert!(
        stepped.contains("time.core") && stepped.contains("rigid"),
        "{stepped}"
    );
    let fixed = refusal(json!({ "time": { "stepping": { "fixed": { "dt": 1e-4 } } } }));
    assert!(
        fixed.contains("time.core") && fixed.contains("event core"),
        "{fixed}"
    );
    let field = refusal(json!({ "field": { "gravity": [0, 0, -9.81] } }));
    assert!(
        field.contains("field") && field.contains("rigid"),
        "{field}"
    );
    let unmerged = refusal(json!({ "physics": { "merging": false } }));
    assert!(unmerged.contains("physics.merging"), "{unmerged}");
}

#[test]
fn a_rigid_run_resumes_bit_for_bit_from_every_snapshot() {
    // Checkpoints every 0.04 s of a 0.2 s cluster–cluster run; each snapshot, through
    // its bytes, resumed in a fresh simulation ends in the uninterrupted run's state,
    // aggregates included (the restart part `rigid_aggregates`).
    let mut scene = cluster_cluster(400, 0.2, 5);
    scene.output.restart = Some(agglo::restart::RestartSettings {
        every: 0.04,
        path: None,
    });
    let mut sim = Simulation::new(&scene).expect("builds");
    let mut snapshots = Vec::new();
    sim.run_with(|s| {
        if let Some(snapshot) = s.restart_snapshot() {
            snapshots.push(snapshot.encode());
        }
        std::ops::ControlFlow::Continue(())
    })
    .expect("runs");
    assert!(snapshots.len() >= 3, "{} snapshots", snapshots.len());
    let end = |sim: &Simulation| {
        format!(
            "{:?} {:?} {:?} {:?}",
            sim.bodies(),
            sim.carried(),
            aggregate_shapes(sim.world()),
            sim.ledger()
        )
    };
    let expected = end(&sim);
    assert!(sim.counters().bonds > 100, "{:?}", sim.counters());
    for (k, bytes) in snapshots.iter().enumerate() {
        let snapshot = agglo::restart::RestartSnapshot::decode(bytes).expect("decodes");
        let mut resumed = Simulation::new(&scene).expect("builds");
        resumed.resume(&snapshot).expect("resumes");
        resumed.run().expect("runs");
        assert!(end(&resumed) == expected, "resumed from snapshot {k}");
    }
}

#[test]
fn a_bounce_between_aggregates_exchanges_the_impulse_of_their_masses() {
    // A dimer forms fast enough to bond (each at 3 v_c), then a monomer arrives slowly
    // (0.3 v_c, below bonding) at the height of its upper primary and bounces. The
    // outcome is the pair law's for bodies of the aggregates' masses 2m and m: the
    // whole dimer takes the impulse J/(2m), the monomer −J/m, momentum is conserved.
    let (h0, rho) = (1e4, 2000.0);
    let v_c = agglo::systems::impact::critical_speed(1.0, h0, 1.0, rho);
    let s = rigid(json!({
        "material": { "H0": h0, "rho": rho },
        "cloud": {
            "count": 3,
            "bodies": [
                { "position": [-0.015, -0.01, 0], "velocity": [0, 3.0 * v_c, 0] },
                { "position": [-0.015, 0.01, 0], "velocity": [0, -3.0 * v_c, 0] },
                { "position": [0.03, B, 0], "velocity": [-0.3 * v_c, 0, 0] }
            ]
        },
        "time": { "end": 0.06 / (0.3 * v_c) }
    }));
    let mut sim = Simulation::new(&s).expect("builds");
    let m = sim.primary().mass;
    sim.run().expect("runs");
    let counters = sim.counters();
    assert_eq!((counters.bonds, counters.bounces), (1, 1), "{counters:?}");
    let bodies = sim.bodies();
    assert_eq!(
        bodies[0].velocity, bodies[1].velocity,
        "the dimer moves as one"
    );
    // The reference: the law for the two aggregates as bodies of their masses and
    // velocities, with the touching primaries' radii; the contact's first body is the
    // dimer's (smaller ids), the normal +x from it to the monomer. Q = 0: hardness, and
    // so the law, does not depend on the temperatures.
    let model = agglo::systems::impact::pair_model(&s.material, &s.impact);
    let body = |mass: f64, velocity: DVec3| agglo::systems::impact::PairBody {
        mass,
        radius: B,
        velocity,
        temperature: 300.0,
    };
    let u = 0.3 * v_c;
    let law = agglo::systems::impact::solve_pair(
        &model,
        &body(2.0 * m, DVec3::ZERO),
        &body(m, DVec3::new(-u, 0.0, 0.0)),
        DVec3::X,
    );
    assert!(!law.bonded);
    // The run reaches the contact by its own arithmetic: the same law to rounding.
    for (got, want) in [
        (bodies[0].velocity, law.velocity_i),
        (bodies[2].velocity, law.velocity_j),
    ] {
        assert!(
            (got - want).length() <= 1e-12 * u,
            "{got} against the law's {want}"
        );
    }
    let p: DVec3 = bodies.iter().map(|b| b.mass * b.velocity).sum();
    assert!(
        (p - DVec3::new(-0.3 * v_c * m, 0.0, 0.0)).length() <= 1e-14 * m * v_c,
        "momentum {p}"
    );
    // 1D impact of masses 2m (at rest) and m (at −u): J = μ (1 + e) u, μ = 2m/3, so the
    // dimer moves at −(1 + e) u/3 and the monomer at −u + 2(1 + e) u/3 (with the primary's
    // mass m for the dimer instead, they would be −(1 + e) u/2 and −u + (1 + e) u/2).
    let e = law.restitution;
    assert!(e > 0.0 && e < 1.0, "restitution {e}");
    let (dimer_after, monomer_after) = (-(1.0 + e) * u / 3.0, -u + 2.0 * (1.0 + e) * u / 3.0);
    assert!((bodies[0].velocity.x - dimer_after).abs() <= 1e-12 * u);
    assert!((bodies[2].velocity.x - monomer_after).abs() <= 1e-12 * u);
}

#[test]
fn without_bonds_a_rigid_run_is_the_coalesce_run_bit_for_bit() {
    // The peers' bounce cloud (1000 hard grains, only bounces): every aggregate stays a
    // single primary, and a single primary is exactly a sphere of the coalesce mode —
    // the same law, velocities, temperatures and push-apart, to the bit.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("benches/peers/scenes/peer_bounce_1000.json");
    let run = |mode: &str| {
        let mut scene = Scenario::load(&path).expect("the peers' scene loads");
        scene.time.end = 2e-3;
        scene.physics.merge_mode = match mode {
            "rigid" => agglo::scene::MergeMode::Rigid,
            _ => agglo::scene::MergeMode::Coalesce,
        };
        let mut sim = Simulation::new(&scene).expect("builds");
        sim.run().expect("runs");
        (sim.bodies(), sim.counters(), sim.ledger())
    };
    let (coalesce, rigid) = (run("coalesce"), run("rigid"));
    assert!(coalesce.1.bounces > 1000, "{:?}", coalesce.1);
    assert_eq!(coalesce.1.bonds, 0);
    assert!(coalesce == rigid, "{:?}\n{:?}", coalesce.1, rigid.1);
}

/// Each aggregate's radius of gyration from the final state alone: its primaries (by the
/// `aggregate` column) unwrapped across the periodic boundary by walking its touching
/// pairs (each step the minimum image of a separation of 2a, far below half the box),
/// then R_g of the centres, mass-weighted. Sorted by aggregate id: (id, k, R_g).
fn radii_of_gyration_from_the_final_state(sim: &Simulation) -> Vec<(u64, usize, f64)> {
    let bodies = sim.bodies();
    let carried = sim.carried();
    let column = carried.names.iter().position(|n| n == "aggregate").unwrap();
    let of: Vec<u64> = carried
        .rows
        .iter()
        .map(|r| r.1[column].unwrap() as u64)
        .collect();
    let side = 2.0 * sim.world().resource::<BoxGeometry>().half_width;
    let image = |d: DVec3| d - side * (d / side).round();
    let mut ids: Vec<u64> = of.clone();
    ids.sort_unstable();
    ids.dedup();
    ids.into_iter()
        .map(|id| {
            let members: Vec<usize> = (0..bodies.len()).filter(|&i| of[i] == id).collect();
            let mut unwrapped: Vec<Option<DVec3>> = vec![None; members.len()];
            unwrapped[0] = Some(bodies[members[0]].position);
            let mut queue = vec![0];
            while let Some(p) = queue.pop() {
                for q in 0..members.len() {
                    let (a, b) = (&bodies[members[p]], &bodies[members[q]]);
                    let d = image(b.position - a.position);
                    if unwrapped[q].is_none() && d.length() <= (a.radius + b.radius) * (1.0 + 1e-9)
                    {
                        unwrapped[q] = Some(unwrapped[p].unwrap() + d);
                        queue.push(q);
                    }
                }
            }
            let x: Vec<(f64, DVec3)> = members
                .iter()
                .zip(&unwrapped)
                .map(|(&i, u)| (bodies[i].mass, u.expect("connected")))
                .collect();
            let mass: f64 = x.iter().map(|p| p.0).sum();
            let centre = x.iter().map(|p| p.0 * p.1).sum::<DVec3>() / mass;
            let spread: f64 = x
                .iter()
                .map(|p| p.0 * (p.1 - centre).length_squared())
                .sum();
            (id, members.len(), (spread / mass).sqrt())
        })
        .collect()
}

#[test]
fn the_size_table_of_a_rigid_scene_counts_aggregates_with_their_shape() {
    use agglo::output::table::read_table;
    use agglo::output::{RunTables, SampleSchedule, TablePaths};
    let s = cluster_cluster(300, 0.3, 3);
    let dir = tempfile::tempdir().unwrap();
    let paths = TablePaths {
        sizes: Some(dir.path().join("sizes.csv")),
        sampling: Some(SampleSchedule::Steps { every: 50 }),
        ..TablePaths::default()
    };
    let mut sim = Simulation::new(&s).unwrap();
    let mut tables = RunTables::open(&paths, &s, &sim).unwrap().unwrap();
    sim.run_with(|sim| {
        tables.observe(sim).unwrap();
        std::ops::ControlFlow::Continue(())
    })
    .unwrap();
    tables.finish(&sim).unwrap();
    let table = read_table(&dir.path().join("sizes.csv")).unwrap();
    let (t, bin, count) = (
        table.floats("t").unwrap(),
        table.ints("bin").unwrap(),
        table.ints("count").unwrap(),
    );
    let (r_g, phi) = (
        table.floats("radius_of_gyration").unwrap(),
        table.floats("filling_factor").unwrap(),
    );
    let a = sim.primary().radius;
    let mut samples = t.clone();
    samples.dedup();
    assert!(samples.len() >= 3, "{samples:?}");
    for &ts in &samples {
        let rows: Vec<usize> = (0..t.len()).filter(|&k| t[k] == ts).collect();
        // Bins by k: every primary in exactly one aggregate.
        let primaries: i64 = rows.iter().map(|&k| bin[k] * count[k]).sum();
        assert_eq!(primaries, 300, "t = {ts}: Σ k n_k = N");
        for &k in &rows {
            // Closed forms (centres only): a monomer's R_g is 0 and it fills itself; a
            // dimer's centres sit a from their middle, R_g = a, φ = 2a³/(√(5/3) a)³; a
            // trimer lies between the triangle (R_g = 2a/√3) and the line (2a·√(2/3)).
            let rel = 1e-12; // rounding of the offsets, sums of a few terms
            match bin[k] {
                1 => assert!(
                    r_g[k] == 0.0 && phi[k] == 1.0,
                    "t = {ts}: {} {}",
                    r_g[k],
                    phi[k]
                ),
                2 => {
                    assert!((r_g[k] / a - 1.0).abs() < rel, "dimer R_g {}", r_g[k] / a);
                    let expected = 2.0 / (5.0f64 / 3.0).powf(1.5);
                    assert!(
                        (phi[k] / expected - 1.0).abs() < 1e-11,
                        "dimer φ {}",
                        phi[k]
                    );
                }
                3 => {
                    let (lo, hi) = (2.0 / 3f64.sqrt(), 2.0 * (2.0f64 / 3.0).sqrt());
                    assert!(
                        r_g[k] / a > lo * (1.0 - rel) && r_g[k] / a < hi * (1.0 + rel),
                        "trimer R_g {}",
                        r_g[k] / a
                    );
                }
                _ => assert!(phi[k] > 0.0 && phi[k] < 1.0, "φ = {}", phi[k]),
            }
        }
    }
    // The last sample against the final state unwrapped on its own: the bins' counts
    // and mean R_g (relative 1e-9: positions are wrapped, offsets are not).
    let last = *samples.last().unwrap();
    let independent = radii_of_gyration_from_the_final_state(&sim);
    let summary = sim.summary().aggregates.unwrap();
    let rows: Vec<usize> = (0..t.len()).filter(|&k| t[k] == last).collect();
    assert_eq!(
        rows.iter().map(|&k| count[k]).sum::<i64>() as usize,
        summary.count
    );
    assert_eq!(independent.len(), summary.count);
    for &k in &rows {
        let of_k: Vec<f64> = independent
            .iter()
            .filter(|x| x.1 as i64 == bin[k])
            .map(|x| x.2)
            .collect();
        assert_eq!(of_k.len() as i64, count[k], "k = {}", bin[k]);
        let mean = of_k.iter().sum::<f64>() / of_k.len() as f64;
        assert!(
            (r_g[k] - mean).abs() <= 1e-9 * a,
            "k = {}: table {} against {mean}",
            bin[k],
            r_g[k]
        );
    }
}

#[test]
fn a_rigid_scene_with_outcome_hooks_is_refused_naming_the_merge_mode() {
    use agglo::hooks::PendingImpacts;
    fn hook(_pending: agglo::bevy_ecs::prelude::ResMut<PendingImpacts>) {}
    let mut builder = Simulation::builder(&dimer_and_monomer(1.0)).unwrap();
    builder
        .add_default_plugins()
        .add_impact_outcome_systems(hook);
    let err = builder.build().err().expect("refused").to_string();
    assert!(
        err.contains("physics.merge_mode")
            && err.contains("rigid")
            && !err.contains("add the impact plugin"),
        "{err}"
    );
}

#[test]
fn validate_counts_the_aggregates_of_a_rigid_scene_in_its_memory_estimate() {
    use agglo::memory::{MemoryEstimate, RIGID_BYTES_PER_BODY};
    let rigid_scene = cluster_cluster(1000, 0.1, 1);
    let mut coalesce = rigid_scene.clone();
    coalesce.physics.merge_mode = agglo::scene::MergeMode::Coalesce;
    let (r, c) = (
        MemoryEstimate::of(&rigid_scene),
        MemoryEstimate::of(&coalesce),
    );
    assert_eq!(r.bytes - c.bytes, 1000.0 * RIGID_BYTES_PER_BODY);
}

/// Ballistic particle–cluster aggregation (agglo::particle_cluster): every monomer
/// after the seed touches an earlier primary where it stopped and overlaps none; the
/// same seed grows the same aggregate bit for bit. O(N²) here: 2000 primaries.
#[test]
fn particle_cluster_monomers_stick_where_they_first_touch() {
    use agglo::particle_cluster::grow;
    let a = 1e-6;
    let g = grow(2000, a, 7);
    assert_eq!(g, grow(2000, a, 7));
    assert_eq!(g.centres.len(), 2000);
    assert_eq!(g.fired, 2000 - 1 + g.missed);
    assert!(g.missed > 0, "the lines are drawn wider than the aggregate");
    for (k, x) in g.centres.iter().enumerate().skip(1) {
        let closest = g.centres[..k]
            .iter()
            .map(|y| (*x - *y).length())
            .fold(f64::INFINITY, f64::min);
        // It stopped at first touch: 2a from a primary, to the rounding of a line
        // point a few tens of a from the origin (1e-12 relative).
        assert!(
            (closest / (2.0 * a) - 1.0).abs() < 1e-12,
            "primary {k}: nearest earlier centre at {} a",
            closest / a
        );
        // Later arrivals never overlap it either.
        for y in &g.centres[k + 1..] {
            assert!((*x - *y).length() >= 2.0 * a * (1.0 - 1e-12));
        }
    }
    // The R_g kept during the growth is the final aggregate's (one pass against two).
    let rg = *g.radius_of_gyration.last().unwrap();
    assert!((rg / g.shape().radius_of_gyration - 1.0).abs() < 1e-12);
}

#[test]
fn particle_cluster_aggregates_are_compact_with_the_known_filling_factor() {
    use agglo::particle_cluster::grow;
    // Four aggregates of 10⁴ primaries (≈ 0.2 s each in the debug profile). Seeds 1–8
    // gave D_f over the last decade of growth (R_g against k for k = 10³..10⁴, one
    // aggregate) 2.98, 2.94, 2.89, 2.88, 2.99, 2.84, 2.86, 3.22 (mean 2.95, spread
    // 0.12), and over k = 10..10² 2.68, 2.21, 2.83, …: the local dimension rises to 3,
    // the dimension of ballistic particle–cluster aggregates (Meakin 1984; Kozasa, Blum
    // & Mukai 1992, A&A 263, 423). The mean of four is within 0.06 (one SE) of the
    // mean of eight; the band 2.8–3.15 is 3 ± 2.5 SE, a little wider above.
    let mut d_f = Vec::new();
    let mut early = Vec::new();
    let mut filling = Vec::new();
    let mut core = Vec::new();
    for seed in 1..=4 {
        let g = grow(10_000, 1.0, seed);
        let fit = |from, to| {
            fractal_fit(&g.history(from, to), 1.0, from)
                .expect("a fit")
                .dimension
        };
        d_f.push(fit(1000, 10_000));
        early.push(fit(10, 100));
        let shape = g.shape();
        filling.push(shape.filling_factor);
        core.push(g.filling_factor_within(0.5 * shape.radius_of_gyration));
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    assert!((2.8..=3.15).contains(&mean(&d_f)), "D_f {d_f:?}");
    assert!(mean(&early) < mean(&d_f), "{early:?} then {d_f:?}");
    // The filling factor Σa³/R_c³ with R_c = √(5/3) R_g, the measure of Kozasa, Blum &
    // Mukai (1992), whose large BPCA aggregates have porosity 0.85–0.87, φ ≈ 0.13–0.15.
    // Measured: 0.127, 0.135, 0.131, 0.134 (seeds 5–8: 0.137, 0.131, 0.134, 0.123).
    // The band 0.12–0.16 is the literature's range widened by the seed spread (0.005).
    assert!(
        filling.iter().all(|f| (0.12..=0.16).contains(f)),
        "{filling:?}"
    );
    // Inside 0.5 R_g about the centre of mass (primaries cut by the sphere counted by
    // their exact lens): 0.183, 0.183, 0.181, 0.184 — denser than the ≈ 0.15 the issue
    // quotes, and falling with size (2000 primaries: 0.20–0.22; 10⁵: 0.153, the ignored
    // test below); the band 0.17–0.20 is the measured spread of seeds 1–8
    // (0.181–0.192) with a margin of half of it.
    assert!(core.iter().all(|f| (0.17..=0.20).contains(f)), "{core:?}");
}

#[test]
#[ignore = "10⁵ primaries, ≈ 11 s (debug profile): cargo test --test suite rigid -- --ignored"]
fn a_hundred_thousand_primary_particle_cluster_aggregate_has_what_the_docs_quote() {
    use agglo::particle_cluster::grow;
    // docs/aggregates.md quotes this deterministic run (seed 1): 178 683 monomers fired
    // for 10⁵ primaries; D_f 2.98 over k = 10⁴..10⁵; filling factor 0.127 (R_c
    // measure) and 0.153 inside 0.5 R_g — the ≈ 0.15 of large BPCA aggregates.
    let g = grow(100_000, 1.0, 1);
    assert_eq!(g.fired, 178_683);
    let fit = fractal_fit(&g.history(10_000, 100_000), 1.0, 10_000).unwrap();
    assert!((fit.dimension - 2.982).abs() < 5e-4, "{fit:?}");
    let shape = g.shape();
    assert!((shape.radius_of_gyration - 71.53).abs() < 5e-3, "{shape:?}");
    assert!((shape.filling_factor - 0.1270).abs() < 5e-5, "{shape:?}");
    let core = g.filling_factor_within(0.5 * shape.radius_of_gyration);
    assert!((core - 0.1528).abs() < 5e-5, "{core}");
}

/// A dimer formed at rest at the origin (bodies 0 and 1 head on along y at ±1 m/s, so
/// 1 sits on top), then monomer 2 flying along −x at `speed` onto the upper primary,
/// with fragmentation on (γ = 5 J/m²).
fn dimer_hit_by_a_monomer(speed: f64) -> Scenario {
    rigid(json!({
        "cloud": {
            "count": 3,
            "bodies": [
                { "position": [0, -0.003, 0], "velocity": [0, 1, 0] },
                { "position": [0, 0.003, 0], "velocity": [0, -1, 0] },
                { "position": [0.03, B, 0], "velocity": [-speed, 0, 0] }
            ]
        },
        "material": { "gamma": 5.0 },
        "time": { "end": 0.05 },
        "physics": { "fragmentation": true }
    }))
}

#[test]
fn an_aggregate_that_absorbs_enough_breaks_into_its_primaries_with_the_ledgers_closing() {
    // P04's balance for the sphere of the aggregate's volume, b_v = k^{1/3} a: it breaks
    // into its k primaries when (1 + x)³ ≥ k, x = δK / (4π γ b_v²). Forming the dimer
    // absorbs δK = ½ (m/2) (2 m/s)² = m (x = 0.08 < 2^{1/3} − 1 = 0.26: it holds); the
    // monomer bonding to it at v absorbs δK = ½ (2m/3) v² = m v²/3, x = 0.0214 v²/(m²/s²),
    // which reaches 3^{1/3} − 1 = 0.442 at v = 4.5 m/s: 10 m/s breaks the trimer, 2 m/s
    // does not.
    let kept = {
        let mut sim = Simulation::new(&dimer_hit_by_a_monomer(2.0)).unwrap();
        sim.run().unwrap();
        sim
    };
    assert_eq!(kept.summary().counters.bonds, 2);
    assert_eq!(kept.summary().counters.fragmentations, 0);
    assert_eq!(kept.summary().aggregates.unwrap().count, 1);
    assert_eq!(kept.ledger().fracture_energy, 0.0);

    let s = dimer_hit_by_a_monomer(10.0);
    let mut sim = Simulation::new(&s).unwrap();
    let start = sim.bodies();
    sim.run().unwrap();
    let end = sim.bodies();
    let summary = sim.summary();
    assert_eq!(summary.counters.bonds, 2, "{:?}", summary.counters);
    assert_eq!(summary.counters.fragmentations, 1);
    assert_eq!(summary.counters.fragments_created, 3);
    // Three aggregates of one, each its own primary, all with the trimer's velocity
    // (the split moves nothing), in the places where they touched.
    let aggregates = aggregate_shapes(sim.world());
    assert_eq!(aggregates.len(), 3);
    assert!(aggregates.iter().all(|a| a.primaries == 1));
    assert_eq!(
        aggregates.iter().map(|a| a.id).collect::<Vec<_>>(),
        [0, 1, 2]
    );
    let v = end[0].velocity;
    assert!(end.iter().all(|b| b.velocity == v));
    assert!((v - DVec3::new(-10.0 / 3.0, 0.0, 0.0)).length() < 1e-12 * 10.0);
    // Mass exact; momentum to rounding (1e-12 of Σ m|v|: three impacts' sums).
    let mass: f64 = start.iter().map(|b| b.mass).sum();
    assert_eq!(mass, end.iter().map(|b| b.mass).sum::<f64>());
    let ((p0, scale), (p1, _)) = (momentum_and_scale(&start), momentum_and_scale(&end));
    assert!((p1 - p0).length() <= 1e-12 * scale, "{p0} → {p1}");
    // δZ = γ 4π b_v² (3^{1/3} − 1) with b_v = 3^{1/3} a, booked as fracture energy and
    // taken from the heat: Σ m C (θ − θ0) = dissipation + reaction heat − δZ (1e-9:
    // sums of temperatures of 300 K against rises of millikelvins).
    let ledger = sim.ledger();
    let b_v = 3f64.cbrt() * B;
    let dz = 5.0 * 4.0 * std::f64::consts::PI * b_v * b_v * (3f64.cbrt() - 1.0);
    assert!(
        (ledger.fracture_energy / dz - 1.0).abs() < 1e-12,
        "{:e} against {dz:e}",
        ledger.fracture_energy
    );
    assert_fracture_books_close(&s, &start, &end, &ledger);
    assert!(summary.invariant_violations.is_empty());
    assert!(
        summary.max_energy_error <= 1e-12,
        "{}",
        summary.max_energy_error
    );
}

#[test]
fn a_cluster_cluster_run_with_fragmentation_conserves_and_books_the_fracture_energy() {
    // γ = 5e-3 J/m² on the 600-primary cloud: 1562 bonds and 698 aggregates broken into
    // 1683 primaries (measured), so breaking is common and follows bonds closely.
    let mut s = cluster_cluster(600, 0.4, 7);
    s.material.gamma = Some(5e-3);
    s.physics.fragmentation = true;
    let mut sim = Simulation::new(&s).expect("builds");
    let start = sim.bodies();
    sim.run().expect("runs");
    let end = sim.bodies();
    let summary = sim.summary();
    assert!(
        summary.counters.fragmentations >= 100,
        "{:?}",
        summary.counters
    );
    assert_aggregates_are_rigid_and_connected(&sim);
    let mass: f64 = start.iter().map(|b| b.mass).sum();
    assert_eq!(mass, end.iter().map(|b| b.mass).sum::<f64>());
    let ((p0, scale), (p1, _)) = (momentum_and_scale(&start), momentum_and_scale(&end));
    assert!((p1 - p0).length() <= 1e-12 * scale, "{p0} → {p1}");
    // Breaking moves no kinetic energy: what was lost is the impacts' dissipation, and
    // the heat is dissipation + reaction heat − fracture energy (tolerances as in the
    // run without fragmentation above).
    let ledger = sim.ledger();
    assert!(ledger.fracture_energy > 0.0);
    assert_fracture_books_close(&s, &start, &end, &ledger);
    assert!(summary.invariant_violations.is_empty());
    assert!(summary.max_momentum_error <= 1e-12 && summary.max_energy_error <= 1e-12);
    assert_eq!(summary.counters.overlap_violations, 0);
}

#[test]
fn papers_best_case_in_rigid_mode_grows_what_the_docs_quote() {
    // scenarios/paper2004_best_rigid.json (0.4 s): P04's best case, bonds joining rigid
    // aggregates. docs/model.md §6.1 quotes this deterministic run (seed 2004).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios/paper2004_best_rigid.json");
    let s = Scenario::load(&path).expect("loads");
    let mut sim = Simulation::new(&s).expect("builds");
    sim.run().expect("runs");
    let summary = sim.summary();
    assert_eq!(
        summary.final_bodies, 1000,
        "primaries are never merged away"
    );
    assert_eq!(
        (summary.counters.bonds, summary.counters.bounces),
        (985, 423)
    );
    let aggregates = summary.aggregates.expect("aggregates");
    assert_eq!((aggregates.count, aggregates.max_primaries), (15, 794));
    let phi = aggregates.mean_filling_factor.expect("k ≥ 5 aggregates");
    assert!((phi - 0.225).abs() < 5e-4, "{phi}");
    let fractal = aggregates.fractal.expect("a fit");
    assert!((fractal.dimension - 2.46).abs() < 5e-3, "{fractal:?}");
    assert!(summary.invariant_violations.is_empty());
    assert!(summary.max_momentum_error <= 1e-12 && summary.max_energy_error <= 1e-12);
}

#[test]
fn a_rigid_recording_colours_each_primary_by_its_aggregate() {
    use agglo::record::messages::{SINGLE_PRIMARY_RGB, aggregate_rgb};
    use foxglove::Decode;
    use foxglove::schemas::SceneUpdate;
    use std::collections::BTreeMap;
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("rigid.json");
    // To t = 0.1 s: aggregates of up to 55 primaries and 11 primaries still alone.
    std::fs::write(&scene, cluster_cluster(300, 0.1, 3).to_json()).unwrap();
    let (mcap, last) = (dir.path().join("run.mcap"), dir.path().join("final.csv"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["run", "-q"])
        .arg(&scene)
        .arg("--recording")
        .arg(&mcap)
        .arg("--final-state")
        .arg(&last)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Each primary's aggregate, from the final state's last column.
    let text = std::fs::read_to_string(&last).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().ends_with(",aggregate"));
    let of: BTreeMap<String, u64> = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].to_string(),
                f[f.len() - 1].parse::<f64>().unwrap() as u64,
            )
        })
        .collect();
    let mut sizes: BTreeMap<u64, usize> = BTreeMap::new();
    for id in of.values() {
        *sizes.entry(*id).or_default() += 1;
    }
    assert!(sizes.values().any(|&k| k >= 2) && sizes.values().any(|&k| k == 1));
    // The last /particles snapshot is the final state: every primary in its
    // aggregate's colour, grey when alone.
    let buf = std::fs::read(&mcap).unwrap();
    let update = mcap::MessageStream::new(&buf)
        .unwrap()
        .map(|m| m.unwrap())
        .filter(|m| m.channel.topic == "/particles")
        .last()
        .map(|m| SceneUpdate::decode(&m.data[..]).unwrap())
        .expect("a snapshot");
    assert_eq!(update.entities.len(), of.len());
    let mut grey = 0;
    for e in &update.entities {
        let c = e.spheres[0].color.unwrap();
        let aggregate = of[&e.id];
        let k = sizes[&aggregate];
        assert_eq!(
            [c.r, c.g, c.b],
            aggregate_rgb(aggregate, k),
            "primary {}",
            e.id
        );
        grey += usize::from(k == 1 && [c.r, c.g, c.b] == SINGLE_PRIMARY_RGB);
    }
    assert_eq!(grey, sizes.values().filter(|&&k| k == 1).count());
}

/// Breaking moves no kinetic energy: the kinetic energy lost is the impacts' dissipation
/// (to rounding of the sums), and the heat gained (from 300 K) is dissipation + reaction
/// heat − fracture energy (to 1e-9 of the dissipation: the temperatures' rounding).
fn assert_fracture_books_close(
    s: &Scenario,
    start: &[BodyState],
    end: &[BodyState],
    ledger: &EnergyLedger,
) {
    let lost = kinetic(start) - kinetic(end);
    assert!((lost - ledger.impact_dissipation).abs() <= 1e-12 * kinetic(start));
    let heat: f64 = end
        .iter()
        .map(|b| b.mass * s.material.C * (b.temperature - 300.0))
        .sum();
    let booked = ledger.impact_dissipation + ledger.reaction_heat - ledger.fracture_energy;
    assert!(
        (heat - booked).abs() <= 1e-9 * ledger.impact_dissipation,
        "heat {heat:e} J, booked {booked:e} J"
    );
}
