//! The event core's cost per event (issue 8): the peer clouds of `benches/peers/`
//! (the same scenes REBOUND runs) at N = 1e3, 1e4, 1e5.
//!
//! - `bounce/N`: 2000 steps of the bouncing cloud from a fresh start (every step is one
//!   impact: the time per step is the time per collision, pair solve included);
//! - `merge/N`: the merging cloud run to T (every contact bonds; N − 1 events at most);
//! - `field/…`: 2000 collisions of the bouncing cloud at N = 1e4 without a field, under
//!   uniform g and under Epstein drag with settling (docs/model.md §4.7): the cost per
//!   event a field adds on the event core (issue 17: within 1.5× of no field).
//!
//! Run: `cargo bench --bench events`. The figures are in the README's speed section.

use std::path::Path;
use std::time::Duration;

use agglo::prelude::*;
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};

/// The allocator of the `agglo` binary (large blocks on transparent huge pages), so that
/// the bench times what a run does.
#[global_allocator]
static ALLOCATOR: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;

fn peer(variant: &str, n: usize) -> Scenario {
    Scenario::load(
        &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .join("benches/peers/scenes")
            .join(format!("peer_{variant}_{n}.json")),
    )
    .expect("peer scene")
}

/// Time `steps` steps of `scenario` from a fresh start (set-up not timed).
fn time_steps(b: &mut criterion::Bencher, scenario: &Scenario, steps: u64) {
    b.iter_batched(
        || Simulation::new(scenario).unwrap(),
        |mut sim| {
            for _ in 0..steps {
                sim.step().unwrap();
            }
            sim.counters().impacts
        },
        BatchSize::PerIteration,
    )
}

fn bounce(c: &mut Criterion) {
    let steps = 2000u64;
    let mut group = c.benchmark_group("bounce");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    group.throughput(Throughput::Elements(steps));
    for n in [1_000, 10_000, 100_000] {
        let scenario = peer("bounce", n);
        group.bench_function(
            format!("N={n}, {steps} collisions (elements = collisions)"),
            |b| time_steps(b, &scenario, steps),
        );
    }
    group.finish();
}

fn merge(c: &mut Criterion) {
    let mut group = c.benchmark_group("merge");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    for n in [1_000, 10_000, 100_000] {
        let scenario = peer("merge", n);
        group.bench_function(format!("N={n} to T"), |b| {
            b.iter_batched(
                || Simulation::new(&scenario).unwrap(),
                |mut sim| {
                    sim.run().unwrap();
                    sim.counters().bonds
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

fn field(c: &mut Criterion) {
    let steps = 2000u64;
    let mut group = c.benchmark_group("field");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    group.throughput(Throughput::Elements(steps));
    let plain = peer("bounce", 10_000);
    // τ0 = 1 ms for a primary (Epstein: τ = ρ b / (ρ_g v_th)); g τ0 = 10 m/s.
    let (tau0, thermal_speed) = (1e-3, 400.0);
    let rho_g = plain.material.rho * plain.primary_radius() / (tau0 * thermal_speed);
    let fields = [
        ("no field", Field::default()),
        (
            "uniform g",
            Field {
                gravity: [0.0, 0.0, -1e4],
                drag: None,
            },
        ),
        (
            "Epstein drag + g",
            Field {
                gravity: [0.0, 0.0, -1e4],
                drag: Some(Drag {
                    gas_velocity: [0.0, 0.0, 0.0],
                    relaxation: Relaxation::Epstein {
                        gas_density: rho_g,
                        thermal_speed,
                    },
                }),
            },
        ),
    ];
    for (name, f) in fields {
        let mut scenario = plain.clone();
        scenario.field = f;
        group.bench_function(
            format!("N=10000, {name}, {steps} collisions (elements = collisions)"),
            |b| time_steps(b, &scenario, steps),
        );
    }
    group.finish();
}

criterion_group!(benches, bounce, merge, field);
criterion_main!(benches);
