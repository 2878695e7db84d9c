//! `agglo::subgrid` cost (issue 32): one cell per macro step at the P04 conditions
//! (scenarios/paper2004_best.json: monomers at volume fraction 0.26, v̄ = (10, 10, 100)
//! m/s, velocity variance (184.7², 18.47², 18.47²)/3 m²/s², i.e. 3866 m²/s² on
//! average) in boxes of 10³ bodies over Δt = 1 ms, one replica, on one core; and its
//! parts: lifting, building the box's simulation, restriction. Before the timings it
//! prints the spread of the growth rate over 16 replicas, from which the standard error
//! for K replicas is s/√K.
//!
//! Run: `cargo bench --bench subgrid`. Figures are in docs/coupling.md.

use std::path::Path;
use std::time::{Duration, Instant};

use agglo::prelude::*;
use agglo::subgrid::*;
use criterion::{Criterion, criterion_group, criterion_main};

const DT: f64 = 1e-3;

fn p04() -> (Coupling, CellInput) {
    let base = Scenario::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join("paper2004_best.json"),
    )
    .expect("shipped scenario");
    let side = 2.0 * base.domain.half_width;
    let n = base.cloud.count as f64 / side.powi(3);
    let theta0 = base.material.theta0;
    let v_rel = base.cloud.v_rel.expect("P04 gives v_rel");
    let tg = v_rel.iter().map(|v| v * v / 3.0).sum::<f64>() / 3.0;
    let v_mean = base.cloud.v_mean;
    let m0 = 4.0 / 3.0 * std::f64::consts::PI * base.primary_radius().powi(3) * base.material.rho;
    let edges = [0.5, 1.5, 2.5, 4.5, 8.5, 16.5, 32.5, 64.5, 1e6]
        .map(|x| x * m0)
        .to_vec();
    let mut c = Coupling::new(base, edges).expect("coupling");
    c.bodies = BoxSize::Bodies(1000);
    c.replicas = 1;
    c.check().expect("coupling");
    let classes = (0..c.classes())
        .map(|k| ClassInput {
            number_density: if k == 0 { n } else { 0.0 },
            mass: c.edges[k].max(m0),
            velocity: v_mean,
            temperature: theta0,
            granular_temperature: tg,
        })
        .collect();
    let input = CellInput {
        classes,
        gas: GasState {
            velocity: [0.0; 3],
            temperature: theta0,
            drag: None,
        },
        dt: DT,
    };
    (c, input)
}

/// The growth rate (1/n) Σ_k dn_k/dt of one cell over 16 replicas, with its standard
/// error, and what the standard error is for K replicas (s/√K, s = SE·√16: the
/// replicas are independent), over Δt = 0.01, 0.1 and 1 ms.
fn spread() {
    for dt in [DT / 100.0, DT / 10.0, DT] {
        let (mut c, mut input) = p04();
        c.replicas = 16;
        input.dt = dt;
        let start = Instant::now();
        let (out, _) = advance_cell(&c, 0, 0, &input, None).expect("cell");
        let seconds = start.elapsed().as_secs_f64();
        let n: f64 = input.classes.iter().map(|k| k.number_density).sum();
        let (rate, se) = (out.number_rate.mean / n, out.number_rate.se / n);
        let impacts = out.impact_rate.mean * out.box_volume * dt;
        let merged = -out.number_rate.mean * out.box_volume * dt;
        eprintln!(
            "P04 cell, N = 1000, Δt = {dt} s, 16 replicas in {seconds:.2} s ({impacts:.0} \
             impacts, {merged:.0} bodies fewer per box): growth rate (1/n) Σ dn_k/dt = \
             {rate:.4e} ± {se:.2e} 1/s"
        );
        let s = se * 4.0;
        for k in [1.0f64, 4.0, 16.0, 64.0] {
            eprintln!(
                "  K = {k:>2}: SE of the growth rate {:.2} % of it",
                100.0 * s / k.sqrt() / rate.abs()
            );
        }
    }
}

fn cells(c: &mut Criterion) {
    spread();
    let (coupling, input) = p04();
    let volume = box_volume(&coupling, 0, &input).unwrap();
    let mut group = c.benchmark_group("subgrid_p04");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("cell N=1000 K=1 dt=1ms", |b| {
        let mut step = 0;
        b.iter(|| {
            step += 1;
            advance_cell(&coupling, 0, step, &input, None).unwrap()
        })
    });
    let short = CellInput {
        dt: DT / 10.0,
        ..input.clone()
    };
    group.bench_function("cell N=1000 K=1 dt=0.1ms", |b| {
        let mut step = 0;
        b.iter(|| {
            step += 1;
            advance_cell(&coupling, 0, step, &short, None).unwrap()
        })
    });
    group.bench_function("lift N=1000", |b| {
        let mut seed = 0;
        b.iter(|| {
            seed += 1;
            lift(&coupling, 0, &input, volume, seed).unwrap()
        })
    });
    let scenario = lift(&coupling, 0, &input, volume, 1).unwrap();
    group.bench_function("validate lifted N=1000", |b| {
        b.iter(|| scenario.validate().unwrap())
    });
    group.bench_function("build box N=1000", |b| {
        b.iter(|| agglo::kernel::simulation(&scenario).unwrap())
    });
    let sim = agglo::kernel::simulation(&scenario).unwrap();
    group.bench_function("restrict N=1000", |b| {
        b.iter(|| ClassSums::of(&coupling, &sim.bodies()))
    });
    group.finish();
}

criterion_group!(benches, cells);
criterion_main!(benches);
