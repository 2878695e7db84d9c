//! Cost of recording to MCAP at the default rate (Δt_rec = T/300) on
//! `scenarios/paper2004_best.json`: the same run with and without a recorder.
//! Prints the recording's size once.

use std::ops::ControlFlow;
use std::path::Path;

use agglo::prelude::*;
use agglo::record::Recorder;
use criterion::{Criterion, criterion_group, criterion_main};

fn run(scenario: &Scenario, out: Option<&Path>) -> u64 {
    let mut sim = Simulation::new(scenario).expect("scenario builds");
    let mut recorder = out.map(|p| Recorder::create(p, &sim, "bench").expect("recording starts"));
    let outcome = sim.run_with(|s| {
        if let Some(r) = recorder.as_mut() {
            r.observe(s).expect("recording works");
        }
        ControlFlow::Continue(())
    });
    let bytes = match recorder {
        Some(r) => r.finish(&sim, &outcome).expect("recording finishes").bytes,
        None => 0,
    };
    outcome.expect("run finishes");
    bytes
}

fn bench(c: &mut Criterion) {
    let path =
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/paper2004_best.json");
    let scenario = Scenario::load(&path).expect("scenario loads");
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("run.mcap");
    let bytes = run(&scenario, Some(&out));
    eprintln!(
        "paper2004_best recording at the default rate: {bytes} bytes ({:.2} MB)",
        bytes as f64 / 1e6
    );

    let mut group = c.benchmark_group("paper2004_best");
    group.sample_size(10);
    group.bench_function("no_recording", |b| b.iter(|| run(&scenario, None)));
    group.bench_function("recording_default_rate", |b| {
        b.iter(|| run(&scenario, Some(&out)))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
