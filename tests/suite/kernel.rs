//! `agglo kernel` and `agglo::kernel`: the measured kernel against ballistic theory, the
//! exposure against closed forms, the counts against the collision log, pooling, and
//! the grids it refuses.

use std::ops::ControlFlow;
use std::path::Path;
use std::process::Command;

use agglo::farm::Workers;
use agglo::kernel::{self, Accumulator, Estimate, MassGrid, Sampling, Window};
use agglo::output::collisions::{self, CollisionLog};
use agglo::output::table::read_table;
use agglo::prelude::*;
use serde_json::json;

use crate::common::{pair, scenario};

fn shipped(name: &str) -> Scenario {
    Scenario::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(name),
    )
    .unwrap()
}

/// Edges from `lo` to `hi` [kg], a factor 2 apart (the last at or above `hi`).
fn doubling(lo: f64, hi: f64) -> MassGrid {
    let mut edges = vec![lo];
    while *edges.last().unwrap() < hi {
        edges.push(edges.last().unwrap() * 2.0);
    }
    MassGrid::from_edges(edges, "test").unwrap()
}

/// Run `sim` to its end with `accs` observing it (begun before the first step).
fn run_observed(sim: &mut Simulation, accs: &mut [&mut Accumulator]) {
    for a in accs.iter_mut() {
        a.begin(sim).unwrap();
    }
    sim.run_with(|s| {
        for a in accs.iter_mut() {
            a.observe(s).unwrap();
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    for a in accs.iter_mut() {
        a.end_run(sim).unwrap();
    }
}

/// Ballistic aggregation at the shipped scene's volume fraction 0.05, N = 2000, over the
/// first 1e-4 s (a tenth of the mean free time ≈ 1 ms, so that the monomers that
/// collide have not yet depleted the fast end of the Maxwellian), 40 seeds.
///
/// Closed form (docs/model.md §14): with each velocity component N(0, T_g), the relative
/// velocity of two bodies has variance 2T_g per component and mean speed
/// ⟨|Δv|⟩ = √(16 T_g/π); the dilute kernel is π(2b)²⟨|Δv|⟩ and the dense one multiplies
/// it by the Enskog factor χ = (1 − v_f/2)/(1 − v_f)³ (Carnahan–Starling contact value).
#[test]
fn monomer_kernel_in_ballistic_aggregation_is_enskogs() {
    let base = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=2000".into(), "time.end=1e-4".into()])
        .unwrap();
    let b = base.primary_radius();
    let m0 = base.primary_mass();
    // Class 0 the monomers, class 1 the dimers, then wider.
    let grid = MassGrid::from_edges(vec![0.5 * m0, 1.5 * m0, 2.5 * m0, 1e3 * m0], "test").unwrap();
    let seeds = kernel::seeds(&base, 40);
    let acc = kernel::measure(
        &base,
        &grid,
        Window::default(),
        Sampling::default(),
        &seeds,
        &Workers::local(2),
        |_| {},
    )
    .unwrap();
    let e = Estimate::of(&acc);
    let (k, se_poisson, se_seeds) = (
        e.floats("kernel")[0],
        e.floats("kernel_se_poisson")[0],
        e.floats("kernel_se_seeds")[0],
    );
    let t_g = 1.0; // the scene's granular temperature [m²/s²]
    let mean_dv = (16.0 * t_g / std::f64::consts::PI).sqrt();
    let v_f = base.volume_fraction();
    let chi = (1.0 - 0.5 * v_f) / (1.0 - v_f).powi(3);
    let theory = std::f64::consts::PI * (2.0 * b).powi(2) * mean_dv * chi;
    let counts = e.ints("counts_total")[0];
    assert!(counts > 3000, "{counts} monomer impacts: the SE is ≈ 1/√C");
    // Both error estimates measure the same scatter (Poisson counts, 40 seeds): they agree
    // to the ±11 % a 40-sample standard deviation scatters by, with room to spare.
    assert!(
        (se_seeds / se_poisson - 1.0).abs() < 0.35,
        "{se_seeds} vs {se_poisson}"
    );
    // 3 standard errors: a correct kernel fails this 0.3 % of the time; a kernel off by
    // the Enskog factor (+13.7 % at v_f = 0.05) or without the ½ on the diagonal fails.
    assert!(
        (k - theory).abs() <= 3.0 * se_seeds.max(se_poisson),
        "K_11 = {k:e} ± {se_seeds:e} m³/s, theory {theory:e} (χ = {chi})"
    );
    // The sampled relative speed over all monomer pairs is the Maxwellian mean (2 %: 16
    // samples × 256 draws ≈ 4000 draws of a speed whose spread is 0.42 of its mean, ±0.7 %,
    // plus the slow depletion of the fast monomers over the window).
    let rel = e.floats("relative_speed_mean")[0];
    assert!((rel / mean_dv - 1.0).abs() < 0.02, "{rel} vs {mean_dv}");
    let geometric = e.floats("geometric_kernel")[0];
    assert!((geometric / (theory / chi) - 1.0).abs() < 0.02);
    // Every contact sticks.
    let p = e.floats("probability");
    assert_eq!(p[0], 1.0);
}

/// The exposure of a pair that merges: two monomers 2 mm apart closing at 2 m/s meet at
/// t_c = (gap)/(closing speed); until then one monomer pair exists, after it none.
/// The sampled speeds describe the epoch K describes (issue 38, D4). Over a run that
/// coarsens 2000 monomers for 0.2 s (about 200 initial free times), K_11 = ΣC/ΣE weighs
/// each moment by the monomer exposure then, nearly all of it early; the geometric kernel
/// π(2b)²⟨|Δv|⟩ of the monomer pairs times the Enskog factor must be that K. With 16
/// evenly spread samples (the first at 6 ms, after most monomers merged) the two differed
/// by 27 %; sampled every 1/4 of the bodies merged and weighted by exposure, by 0.2 %.
#[test]
fn sampled_geometric_kernel_describes_the_epoch_of_k() {
    let base = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=2000".into(), "time.end=0.2".into()])
        .unwrap();
    let m0 = base.primary_mass();
    let grid = MassGrid::from_edges(vec![0.5 * m0, 1.5 * m0, 2.5 * m0, 1e4 * m0], "test").unwrap();
    let acc = kernel::measure(
        &base,
        &grid,
        Window::default(),
        Sampling::default(),
        &kernel::seeds(&base, 8),
        &Workers::local(2),
        |_| {},
    )
    .unwrap();
    let e = Estimate::of(&acc);
    let (k, se) = (e.floats("kernel")[0], e.floats("kernel_se_seeds")[0]);
    let geometric = e.floats("geometric_kernel")[0];
    let v_f = base.volume_fraction();
    let chi = (1.0 - 0.5 * v_f) / (1.0 - v_f).powi(3);
    // 5 %: three standard errors of K (1.6 % from 8 seeds) plus the draws' own scatter
    // (≈ 0.3 %); the old sampling was off by 27 %.
    assert!(se / k < 0.02, "{se} / {k}");
    assert!(
        (k / (chi * geometric) - 1.0).abs() < 0.05,
        "K_11 = {k:e}, χ·geometric = {:e}",
        chi * geometric
    );
}

/// The start-up transient of the monomer kernel (issue 38, item 7) and the burn-in that
/// removes it (docs/kernel.md, "Start-up transient"). The random initial placement has
/// no contact correlation yet, so the monomer kernel starts below Enskog's value (which
/// assumes the fluid's contact value χ) and reaches it within about 1e-4 s, a tenth of
/// the mean free time. 256 seeds of 2000 monomers, four windows of the same runs:
/// measured −4.4 % (0–25 µs, −3.6 SE), −3.9 % (25–50 µs), −1.6 % (50–100 µs), −0.2 %
/// (100–200 µs, −0.3 SE).
#[test]
fn burn_in_removes_the_start_up_transient() {
    let base = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=2000".into(), "time.end=2e-4".into()])
        .unwrap();
    let b = base.primary_radius();
    let m0 = base.primary_mass();
    let grid = MassGrid::from_edges(vec![0.5 * m0, 1.5 * m0, 1e4 * m0], "test").unwrap();
    let windows = [(0.0, 2.5e-5), (2.5e-5, 5e-5), (5e-5, 1e-4), (1e-4, 2e-4)];
    let mut accs: Vec<Accumulator> = windows
        .iter()
        .map(|&(t0, t1)| {
            Accumulator::new(
                grid.clone(),
                Window::new(t0, t1).unwrap(),
                Sampling::default(),
            )
        })
        .collect();
    for seed in kernel::seeds(&base, 256) {
        let mut s = base.clone();
        s.seed = seed;
        let mut sim = kernel::simulation(&s).unwrap();
        let mut refs: Vec<&mut Accumulator> = accs.iter_mut().collect();
        run_observed(&mut sim, &mut refs);
    }
    let v_f = base.volume_fraction();
    let chi = (1.0 - 0.5 * v_f) / (1.0 - v_f).powi(3);
    let theory =
        std::f64::consts::PI * (2.0 * b).powi(2) * (16.0 / std::f64::consts::PI).sqrt() * chi;
    let deviation = |acc: &Accumulator| {
        let e = Estimate::of(acc);
        let (k, se) = (e.floats("kernel")[0], e.floats("kernel_se_seeds")[0]);
        ((k - theory) / se, k / theory - 1.0)
    };
    let measured: Vec<(f64, f64)> = accs.iter().map(deviation).collect();
    // docs/kernel.md's table, to the digits quoted (deterministic runs).
    for (&(_, relative), quoted) in measured.iter().zip([-0.044, -0.039, -0.016, -0.002]) {
        assert!(
            (relative - quoted).abs() < 5e-4,
            "{measured:?} against the documented {quoted}"
        );
    }
    // Without a burn-in the first 25 µs are low by ≈ 4 % (≈ 3.5 standard errors): more
    // than 2.5 SE, so a start that already had the fluid's pair structure would show here
    // (and this test, and the docs, would change with it).
    let (early_se, early) = measured[0];
    assert!(early_se < -2.5, "0–25 µs: {early:.4} ({early_se:.1} SE)");
    // After a burn-in of 1e-4 s: Enskog's value within 3 standard errors (0.7 % each).
    let (late_se, late) = measured[3];
    assert!(
        late_se.abs() < 3.0,
        "100–200 µs: {late:.4} ({late_se:.1} SE)"
    );
}

#[test]
fn exposure_is_the_time_integral_of_the_pairs() {
    // Soft material: the pair bonds and merges at contact.
    let mut s = scenario(pair(-0.002, 1.0, 0.002, -1.0));
    s.material.H0 = 1e-6;
    s.time.end = 0.004;
    let b = s.cloud.radius.unwrap();
    let m0 = s.material.rho * 4.0 / 3.0 * std::f64::consts::PI * b.powi(3);
    let grid = MassGrid::from_edges(vec![0.5 * m0, 1.5 * m0, 2.5 * m0], "test").unwrap();
    let mut acc = Accumulator::new(grid, Window::default(), Sampling::default());
    let mut sim = kernel::simulation(&s).unwrap();
    run_observed(&mut sim, &mut [&mut acc]);
    assert_eq!(sim.body_count(), 1, "the pair merged");
    let e = Estimate::of(&acc);
    let v = (2.0 * s.domain.half_width).powi(3);
    let t_c = (0.004 - 2.0 * b) / 2.0;
    let exposure = e.floats("exposure");
    // ½N(N − 1) = 1 pair over [0, t_c]; contact time to rounding of the time-to-contact root.
    assert!(
        (exposure[0] * v / t_c - 1.0).abs() < 1e-9,
        "{} vs {t_c}",
        exposure[0] * v
    );
    // One body in class 1 afterwards: ½·1·0 = 0 pairs; none across the classes.
    assert_eq!(&exposure[1..], &[0.0, 0.0, 0.0]);
    assert_eq!(e.ints("counts"), &[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    assert!((e.floats("kernel")[0] - 1.0 / exposure[0]).abs() <= 1e-12 / exposure[0]);
}

/// No motion, no impact: E = ½N(N − 1) T / V exactly, and the upper bound is −ln 0.05 / E.
#[test]
fn exposure_without_events_is_closed_form_and_bounds_the_kernel() {
    let s = scenario(json!({ "cloud": { "count": 20 }, "time": { "end": 0.25 } }));
    let b = s.cloud.radius.unwrap();
    let m0 = s.material.rho * 4.0 / 3.0 * std::f64::consts::PI * b.powi(3);
    let grid = MassGrid::from_edges(vec![0.5 * m0, 1.5 * m0], "test").unwrap();
    let mut acc = Accumulator::new(
        grid,
        Window::new(0.0625, 0.1875).unwrap(),
        Sampling::default(),
    );
    let mut sim = kernel::simulation(&s).unwrap();
    run_observed(&mut sim, &mut [&mut acc]);
    let e = Estimate::of(&acc);
    let v = (2.0 * s.domain.half_width).powi(3);
    let expected = 0.5 * 20.0 * 19.0 * 0.125 / v;
    assert!((e.floats("exposure")[0] / expected - 1.0).abs() < 1e-12);
    assert!(e.floats("kernel")[0] == 0.0);
    let upper = e.floats("kernel_upper95")[0];
    assert!((upper * expected / kernel::ZERO_COUNT_UPPER_95 - 1.0).abs() < 1e-12);
}

/// Bounces, bonds and fragments (quick_demo): the counts per outcome and per pair of
/// classes are the collision log's, row for row, and a fragmenting pair's mass ends up
/// whole in the products.
#[test]
fn counts_are_the_collision_logs() {
    let s = shipped("quick_demo.json");
    let m0 = s.material.rho * 4.0 / 3.0 * std::f64::consts::PI * s.primary_radius().powi(3);
    let grid = doubling(0.4 * m0, 400.0 * m0);
    let mut builder = Simulation::builder(&s).unwrap();
    builder.add_default_plugins();
    collisions::subscribe(&mut builder);
    kernel::subscribe(&mut builder);
    let mut sim = builder.build().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.csv");
    let mut log = CollisionLog::create(&path).unwrap();
    let mut acc = Accumulator::new(grid.clone(), Window::default(), Sampling::default());
    acc.begin(&sim).unwrap();
    sim.run_with(|s| {
        log.observe(s).unwrap();
        acc.observe(s).unwrap();
        ControlFlow::Continue(())
    })
    .unwrap();
    // The class counts, followed from the merge and fragment messages alone, are the
    // bodies' at the end.
    let mut binned = vec![0u64; grid.classes()];
    for b in sim.bodies() {
        binned[grid.class_of(b.mass).unwrap()] += 1;
    }
    assert_eq!(acc.live_counts().unwrap(), &binned[..]);
    acc.end_run(&sim).unwrap();
    log.finish().unwrap();
    let table = read_table(&path).unwrap();
    let outcome = table.texts("outcome").unwrap();
    let (ma, mb) = (
        table.floats("mass_a").unwrap(),
        table.floats("mass_b").unwrap(),
    );
    let nm = grid.classes();
    let mut expected = vec![0i64; 3 * nm * nm];
    for ((o, a), b) in outcome.iter().zip(&ma).zip(&mb) {
        let o = kernel::OUTCOMES.iter().position(|x| x == o).unwrap();
        let (i, j) = (grid.class_of(*a).unwrap(), grid.class_of(*b).unwrap());
        expected[o * nm * nm + i * nm + j] += 1;
        if i != j {
            expected[o * nm * nm + j * nm + i] += 1;
        }
    }
    let e = Estimate::of(&acc);
    assert_eq!(e.ints("counts"), &expected[..]);
    let c = sim.counters();
    let total: i64 = (0..nm)
        .flat_map(|i| (i..nm).map(move |j| (i, j)))
        .map(|(i, j)| e.ints("counts_total")[i * nm + j])
        .sum();
    assert_eq!(total as u64, c.impacts);
    assert_eq!(table.len() as u64, c.impacts);
    let fragments = expected[2 * nm * nm..].iter().sum::<i64>();
    assert!(fragments > 0 && c.bounces > 0 && c.bonds > 0, "{c:?}");
    // Where a pair fragmented, its products hold all of its mass (rounding only).
    let fractions = e.floats("fragment_mass_fraction");
    for p in 0..nm * nm {
        let row = &fractions[p * nm..(p + 1) * nm];
        if !row[0].is_nan() {
            let sum: f64 = row.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "pair {p}: {sum}");
        }
    }
}

/// Two accumulators on the halves of one run's time, pooled, give the whole run's K:
/// counts exactly, exposure to rounding (the whole adds one interval where the halves
/// add its two parts).
#[test]
fn pooling_two_halves_gives_the_whole() {
    let s = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=1000".into(), "time.end=2e-3".into()])
        .unwrap();
    let m0 = s.material.rho * 4.0 / 3.0 * std::f64::consts::PI * s.primary_radius().powi(3);
    let grid = doubling(0.7 * m0, 2000.0 * m0);
    let half = 1e-3;
    let mut whole = Accumulator::new(grid.clone(), Window::default(), Sampling::default());
    let mut first = Accumulator::new(
        grid.clone(),
        Window::new(0.0, half).unwrap(),
        Sampling::default(),
    );
    let mut second = Accumulator::new(
        grid,
        Window::new(half, f64::INFINITY).unwrap(),
        Sampling::default(),
    );
    let mut sim = kernel::simulation(&s).unwrap();
    run_observed(&mut sim, &mut [&mut whole, &mut first, &mut second]);
    first.merge(&second).unwrap();
    let (a, b) = (Estimate::of(&whole), Estimate::of(&first));
    assert_eq!(a.ints("counts"), b.ints("counts"));
    assert!(a.ints("counts_total").iter().sum::<i64>() > 500);
    for name in ["exposure", "kernel"] {
        for (x, y) in a.floats(name).iter().zip(b.floats(name)) {
            assert!(
                (x.is_nan() && y.is_nan()) || (x - y).abs() <= 1e-12 * x.abs(),
                "{name}: {x} vs {y}"
            );
        }
    }
}

/// The file's numbers are the same for any number of worker threads (runs pooled in
/// seed order).
#[test]
fn ensemble_is_the_same_on_any_thread_count() {
    let s = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=300".into(), "time.end=2e-3".into()])
        .unwrap();
    let grid = MassGrid::parse("dustpy:1e-4,10,5", s.material.rho).unwrap();
    let run = |threads| {
        let acc = kernel::measure(
            &s,
            &grid,
            Window::default(),
            Sampling::default(),
            &kernel::seeds(&s, 5),
            &Workers::local(threads),
            |_| {},
        )
        .unwrap();
        Estimate::of(&acc).arrays(false, "", "")
    };
    let (one, two) = (run(1), run(2));
    // Bit for bit (NaN compares unequal, so compare the bytes written).
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(
            kernel::write::npy_bytes(a),
            kernel::write::npy_bytes(b),
            "{}",
            a.name
        );
    }
}

#[test]
fn bad_grids_are_refused_naming_the_problem() {
    let refused = |spec: &str| MassGrid::parse(spec, 1000.0).unwrap_err().to_string();
    assert!(refused("edges:1e-9,3e-9,2e-9").contains("must increase strictly"));
    assert!(refused("edges:1e-9").contains("zero bins"));
    assert!(refused("edges:").contains("not a number"));
    assert!(refused("dustpy:1e-5,1e-1,0").contains("bins_per_decade"));
    assert!(refused("dustpy:1e-1,1e-5,7").contains("mmax"));
    assert!(refused("openfoam:1e-4").contains("zero bins"));
    assert!(refused("cubes:1,2").contains("expected `edges:"));
    assert!(refused("dustpy:1e-12,1e30,10").contains("at most 300"));
    // A grid that misses bodies at the start: refused when the run starts.
    let s = scenario(json!({ "cloud": { "count": 5 } }));
    let m0 = s.material.rho * 4.0 / 3.0 * std::f64::consts::PI * s.cloud.radius.unwrap().powi(3);
    let grid = MassGrid::from_edges(vec![2.0 * m0, 4.0 * m0], "test").unwrap();
    let sim = kernel::simulation(&s).unwrap();
    let err = Accumulator::new(grid, Window::default(), Sampling::default())
        .begin(&sim)
        .unwrap_err()
        .to_string();
    assert!(err.contains("misses 5 of the 5 bodies"), "{err}");
    // On a DustPy grid, given in grams, the message speaks grams.
    let m0_g = m0 * 1e3;
    let spec = format!("dustpy:{:e},{:e},7", 2.0 * m0_g, 1e3 * m0_g);
    let grid = MassGrid::parse(&spec, s.material.rho).unwrap();
    let err = Accumulator::new(grid, Window::default(), Sampling::default())
        .begin(&sim)
        .unwrap_err()
        .to_string();
    // (The first 6 digits: m0 here is computed in another order than the bodies' mass.)
    let digits = format!("{m0_g:e}");
    assert!(err.contains(&format!("lightest {}", &digits[..7])), "{err}");
    assert!(err.contains("e-3 g,"), "{err}");
    assert!(err.contains(" g, ") && !err.contains("kg"), "{err}");
    // `dustpy:primary,…`: the first point is the scenario's primary mass [g].
    let grid = MassGrid::for_scenario("dustpy:primary,1,7", &s).unwrap();
    assert!(
        (grid.centres[0] / m0 - 1.0).abs() < 1e-12,
        "{}",
        grid.centres[0]
    );
    let decades = (1.0 / m0_g).log10().ceil() as usize;
    assert_eq!(grid.classes(), decades * 7 + 1);
    assert!(refused("dustpy:primary,1,7").contains("primary mass"));
    // And from the command line: a clear message and a non-zero exit, no panic.
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args([
            "kernel",
            "scenarios/quick_demo.json",
            "--bins",
            "edges:1e-9,1e-10",
        ])
        .args(["--out", "/nonexistent/never_written.npz"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("value 1 (1e-10) is not above value 0 (1e-9)"),
        "{stderr}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["kernel", "scenarios/quick_demo.json", "--bins", "edges:1,2"])
        .args(["--window", "0.5:0.1", "--out", "/nonexistent/x.npz"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--window: allowed 0 ≤ T0 < T1"), "{stderr}");
    // quick_demo's primaries (1.796e-3 g) lie above this DustPy grid: said in grams.
    // (A writable --out: a missing directory is refused before the run, issue 39.)
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args([
            "kernel",
            "scenarios/quick_demo.json",
            "--bins",
            "dustpy:1e-7,1e-3,7",
        ])
        .arg("--out")
        .arg(dir.path().join("x.npz"))
        .arg("-q")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("misses 300 of the 300 bodies") && stderr.contains("lightest 1.79594"),
        "{stderr}"
    );
    assert!(
        stderr.contains("e-3 g") && !stderr.contains("kg"),
        "{stderr}"
    );
}

/// The long table holds the .npz arrays element by element (NaN left out), in the
/// file's units, and the scenario as text.
#[test]
fn long_table_holds_the_arrays() {
    let s = shipped("ballistic_aggregation.json")
        .with_settings(&["cloud.count=300".into(), "time.end=2e-3".into()])
        .unwrap();
    let grid = MassGrid::parse("dustpy:1e-4,10,5", s.material.rho).unwrap();
    let acc = kernel::measure_one(&s, &grid, Window::default(), Sampling::default(), 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (npz, long) = (dir.path().join("k.npz"), dir.path().join("k.parquet"));
    kernel::write_files(&acc, &s, true, &npz, Some(&long)).unwrap();
    let table = read_table(&long).unwrap();
    let names = table.texts("array").unwrap();
    let (i, j) = (table.ints("i").unwrap(), table.ints("j").unwrap());
    let (value, unit) = (table.floats("value").unwrap(), table.texts("unit").unwrap());
    let e = Estimate::of(&acc);
    let nm = grid.classes();
    let kernel_si = e.floats("kernel");
    let rows: Vec<usize> = (0..names.len()).filter(|&r| names[r] == "kernel").collect();
    assert_eq!(rows.len(), kernel_si.iter().filter(|k| !k.is_nan()).count());
    assert!(!rows.is_empty());
    for r in rows {
        let k = kernel_si[i[r] as usize * nm + j[r] as usize];
        assert_eq!(unit[r], "cm^3/s");
        assert!((value[r] / (k * 1e6) - 1.0).abs() < 1e-15 || value[r] == k * 1e6);
    }
    let texts = table.texts("text").unwrap();
    let scenario = (0..names.len()).find(|&r| names[r] == "scenario").unwrap();
    assert_eq!(Scenario::from_json(&texts[scenario]).unwrap(), s);
    // A CSV long table could not hold that text: refused.
    let err = kernel::write_files(&acc, &s, true, &npz, Some(&dir.path().join("k.csv")))
        .unwrap_err()
        .to_string();
    assert!(err.contains("Parquet only"), "{err}");
    // The npz is a zip whose every member is a .npy: magic and version 1.0.
    let bytes = std::fs::read(&npz).unwrap();
    assert_eq!(&bytes[..4], b"PK\x03\x04");
    let npy = kernel::write::npy_bytes(&e.arrays(true, "", "")[0]);
    assert_eq!(&npy[..8], b"\x93NUMPY\x01\x00");
    let header_len = u16::from_le_bytes([npy[8], npy[9]]) as usize;
    assert_eq!(
        (10 + header_len) % 64,
        0,
        "data starts on a 64-byte boundary"
    );
}
