//! Speed of the inverse problem's building blocks: one P02 ensemble sample (the unit
//! of work of `paper2002_inverse.json`, N = 100, 200 fixed steps), one GA
//! generation on a synthetic cost (the algorithm's own overhead), and the task
//! farm's cost per task when the task itself costs nothing (threads of one process;
//! the MPI round trip is reported by `mpirun … agglo optimize` itself).

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

use agglo::inverse::problem::{GaSpec, StopOn};
use agglo::inverse::{Evaluation, GaState, InverseProblem, ga};
use agglo::prelude::*;

fn p02_sample(c: &mut Criterion) {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios");
    let problem = InverseProblem::load(&dir.join("paper2002_inverse.json")).unwrap();
    // P02 Table 1 rank 1.
    let rank1 = [
        4.326,
        0.633,
        6141.898,
        67.188e6,
        1279.542,
        0.307,
        330.652,
        707351.0,
        5940883.989,
    ];
    let mut seed = 0u64;
    c.bench_function("p02_rank1_one_sample", |b| {
        b.iter(|| {
            seed += 1;
            let s = problem.scenario_for(&rank1, seed).unwrap();
            let mut sim = Simulation::new(&s).unwrap();
            sim.run().unwrap();
            black_box(sim.body_count())
        })
    });
}

fn ga_generation(c: &mut Criterion) {
    let spec = GaSpec {
        strings: 20,
        parents: 6,
        generations: 1000,
        rescale_every: 4,
        shrink: 0.5,
        tol: 0.0,
        stop_on: StopOn::Best,
        seed: 1,
    };
    let lower = vec![0.0; 10];
    let upper = vec![1.0; 10];
    let mut state = GaState::new(lower.clone(), upper.clone());
    c.bench_function("ga_generation_synthetic_10_genes", |b| {
        b.iter(|| {
            if state.finished {
                state = GaState::new(lower.clone(), upper.clone());
            }
            ga::step(&spec, (&lower, &upper), &mut state, |_, candidates| {
                Ok(candidates
                    .iter()
                    .map(|(_, g)| Evaluation {
                        cost: g.iter().map(|x| (x - 0.3) * (x - 0.3)).sum(),
                        samples: 1,
                        ..Default::default()
                    })
                    .collect())
            })
            .unwrap()
        })
    });
}

fn farm_overhead(c: &mut Criterion) {
    use agglo::farm::{Workers, map};
    // 1000 tasks that cost nothing: the time is the farm's own (queue, wake-ups,
    // collection in order), per task = time / 1000.
    let tasks: Vec<u64> = (0..1000).collect();
    for threads in [1, 2] {
        c.bench_function(&format!("farm_1000_empty_tasks_{threads}_threads"), |b| {
            b.iter(|| {
                let out = map(&Workers::local(threads), tasks.clone(), &|x: &u64| x + 1).unwrap();
                black_box(out.len())
            })
        });
    }
}

criterion_group!(benches, p02_sample, ga_generation, farm_overhead);
criterion_main!(benches);
