//! Engine speed: the P04 best case end to end (event core), a dilute cloud's
//! throughput at N = 100 000, the pair solve alone (closed form, seeded, plain), and the
//! set-up of 10⁶ explicit bodies (checks over the neighbour grid; from a file too).
//!
//! Run: `cargo bench --bench engine`. Figures are reported in the issue notes and README.

use std::path::Path;
use std::time::Duration;

use agglo::prelude::*;
use agglo::scenario::{CoolingMethod, Stepping};
use agglo::systems::impact::{PairBody, PairModel, solve_pair};
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;

fn load(name: &str) -> Scenario {
    Scenario::load(
        &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .join("scenarios")
            .join(name),
    )
    .expect("shipped scenario")
}

fn paper2004(c: &mut Criterion) {
    let scenario = load("paper2004_best.json");
    let mut group = c.benchmark_group("paper2004_best");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("N=1000 to T=0.01 s", |b| {
        b.iter_batched(
            || Simulation::new(&scenario).unwrap(),
            |mut sim| {
                sim.run().unwrap();
                sim.counters().impacts
            },
            BatchSize::PerIteration,
        )
    });
    group.finish();
}

/// N = 100 000 at volume fraction 0.05, no impacts possible in the measured steps
/// (all grains move together: v_rel = 0, so every step is Δt_max and no pair approaches).
fn dilute(c: &mut Criterion) {
    let mut scenario = load("quick_demo.json");
    scenario.cloud.count = 100_000;
    scenario.cloud.radius = None;
    // v_f = (π/6) s³ = 0.05
    scenario.cloud.size_ratio = Some((0.05 * 6.0 / std::f64::consts::PI).cbrt());
    scenario.domain.half_width = 0.05;
    scenario.cloud.v_mean = [1.0, 2.0, 3.0];
    scenario.cloud.v_rel = Some([0.0, 0.0, 0.0]);
    scenario.material.gamma = None;
    scenario.physics.cooling = CoolingMethod::Off;
    scenario.diagnostics.invariants = false;
    scenario.time.stepping = Stepping::Adaptive {
        step_factor: 1.0,
        dt_min: 1e-8,
        dt_max: 1e-5,
        skin: 0.5,
    };
    scenario.time.end = 1.0;
    // The stepped core: the event core does no per-body work in a step without events.
    scenario.time.core = agglo::scenario::Core::Stepped;
    let steps = 20u64;
    let mut group = c.benchmark_group("dilute_cloud");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(30));
    group.throughput(Throughput::Elements(steps * 100_000));
    let mut sim = Simulation::new(&scenario).unwrap();
    group.bench_function(
        "N=100000 v_f=0.05, 20 steps (elements = particle-steps)",
        |b| {
            b.iter(|| {
                for _ in 0..steps {
                    sim.step().unwrap();
                }
                assert_eq!(sim.counters().impacts, 0);
            })
        },
    );
    group.finish();
}

fn pair_solve(c: &mut Criterion) {
    let body = |v: f64| PairBody {
        mass: 4.0 / 3.0 * std::f64::consts::PI * 1e-9 * 2000.0,
        radius: 1e-3,
        velocity: DVec3::X * v,
        temperature: 300.0,
    };
    let mut model = PairModel {
        a0: 0.5,
        af: 1.0,
        beta: 1.0,
        duration: agglo::scenario::DurationLaw::P04,
        friction_scales_with_adhesion: false,
        mu0: 0.1,
        alpha: 0.0,
        heat_capacity: 1000.0,
        h0: 1e4,
        activation_energy: 0.0,
        tol: 1e-12,
        max_iterations: 100,
        solver: agglo::scenario::SolverKind::Safeguarded,
        pair_hardness: Default::default(),
        friction_cap: Default::default(),
        bond_test: Default::default(),
        work_heat: Default::default(),
    };
    c.bench_function("pair solve a0=0.5, Q=0 (closed form)", |b| {
        b.iter(|| solve_pair(&model, &body(2.0), &body(-2.0), DVec3::X))
    });
    model.a0 = 0.0;
    c.bench_function("pair solve a0=0, Q=0 (closed form)", |b| {
        b.iter(|| solve_pair(&model, &body(2.0), &body(-2.0), DVec3::X))
    });
    // With softening the closed form is a bracket end: Illinois finishes the solve.
    model.activation_energy = 2e3;
    model.alpha = 1e3;
    c.bench_function("pair solve a0=0, Q>0 (seeded Illinois)", |b| {
        b.iter(|| solve_pair(&model, &body(2.0), &body(-2.0), DVec3::X))
    });
    model.solver = agglo::scenario::SolverKind::Plain;
    model.max_iterations = 100;
    c.bench_function("pair solve a0=0, Q>0 (papers' iteration, cap 100)", |b| {
        b.iter(|| solve_pair(&model, &body(2.0), &body(-2.0), DVec3::X))
    });
}

/// 10⁶ explicit bodies on a jittered 100³ lattice (volume fraction 0.11), each with its
/// velocity: the scenario's checks (box, ids, masses, overlaps) run once when the
/// scenario is parsed and again in `Simulation::new`, as in `agglo run`.
fn explicit_setup(c: &mut Criterion) {
    let n_side = 100usize;
    let half = 0.05;
    let spacing = 2.0 * half / n_side as f64;
    let radius = 0.3 * spacing;
    let mut state: u64 = 1;
    let mut jitter = || {
        // A small LCG: reproducible jitter of ±0.1 spacing without another dependency.
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2 * spacing
    };
    let mut bodies = Vec::with_capacity(n_side.pow(3));
    for i in 0..n_side {
        for j in 0..n_side {
            for k in 0..n_side {
                let at = |n: usize| -half + (n as f64 + 0.5) * spacing;
                let position = [at(i) + jitter(), at(j) + jitter(), at(k) + jitter()];
                bodies.push(agglo::scenario::PlacedBody {
                    position,
                    velocity: Some([jitter() * 1e3, jitter() * 1e3, jitter() * 1e3]),
                    primaries: 1.0,
                    ..Default::default()
                });
            }
        }
    }
    let mut scenario = load("quick_demo.json");
    scenario.domain.half_width = half;
    scenario.cloud.count = bodies.len();
    scenario.cloud.size_ratio = None;
    scenario.cloud.radius = Some(radius);
    scenario.cloud.v_mean = [0.0; 3];
    scenario.cloud.v_rel = None;
    scenario.cloud.bodies = bodies;
    scenario.validate().expect("the lattice is valid");
    // The stepped core: the set-up proper (checks, bodies spawned, plugins built). The
    // event core adds its initial calendar, the events plugin's business, not measured here.
    scenario.time.core = agglo::scenario::Core::Stepped;
    let mut group = c.benchmark_group("explicit_bodies");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function(
        "N=1e6 Scenario::validate (what agglo validate checks)",
        |b| b.iter(|| scenario.validate().unwrap()),
    );
    group.bench_function(
        "N=1e6 Simulation::new, stepped core (validates again)",
        |b| b.iter(|| Simulation::new(&scenario).unwrap().body_count()),
    );
    // The same bodies as a --final-state CSV, loaded through cloud.from_file.
    let dir = std::env::temp_dir().join(format!("agglo-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("bodies.csv");
    let sim = Simulation::new(&scenario).unwrap();
    agglo::output::write_final_state(&csv, &sim.bodies()).unwrap();
    drop(sim);
    let mut from_file = scenario.clone();
    from_file.cloud.bodies.clear();
    from_file.cloud.count = 0;
    from_file.cloud.from_file = Some(csv.display().to_string());
    let text = from_file.to_json();
    group.bench_function("N=1e6 from_file CSV: parse + read + validate", |b| {
        b.iter(|| Scenario::from_json(&text).unwrap().cloud.count)
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, paper2004, dilute, pair_solve, explicit_setup);
criterion_main!(benches);
