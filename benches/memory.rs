//! Peak memory per body (issue 19): the merging peer clouds of `benches/peers/` at
//! N = 1e4, 1e5 and 1e6, built and run to T in this process, no recording.
//!
//! The figure is the process's peak resident memory (VmHWM) over one run, less what it
//! held before the run, divided by N: bytes per body, reported through a criterion
//! measurement of its own, so that `cargo bench --bench memory` keeps a baseline and
//! shows a regression as it does for times. Linux only (`/proc/self/status`; the peak is
//! reset by writing 5 to `/proc/self/clear_refs`).
//!
//! Run: `cargo bench --bench memory`. The figures are in the README's speed section.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use agglo::prelude::*;
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// A `/proc/self/status` field in bytes.
fn status_bytes(field: &str) -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("Linux /proc");
    let line = status
        .lines()
        .find(|l| l.starts_with(field))
        .unwrap_or_else(|| panic!("{field} in /proc/self/status"));
    let kib: f64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("a number of kB");
    kib * 1024.0
}

/// Peak resident bytes of one run of `scenario` above what the process held before.
fn peak_bytes_of_run(scenario: &Scenario) -> f64 {
    std::fs::write("/proc/self/clear_refs", "5").expect("peak reset (Linux ≥ 4.0)");
    let before = status_bytes("VmRSS:");
    let mut sim = Simulation::new(scenario).expect("scene builds");
    sim.run().expect("run finishes");
    black_box(sim.counters());
    let peak = status_bytes("VmHWM:");
    drop(sim);
    peak - before
}

/// Bytes per body, as a criterion measurement (the benches below report the value
/// directly through `iter_custom`).
struct BytesPerBody;

impl Measurement for BytesPerBody {
    type Intermediate = ();
    type Value = f64;
    fn start(&self) {}
    fn end(&self, _: ()) -> f64 {
        0.0
    }
    fn add(&self, a: &f64, b: &f64) -> f64 {
        a + b
    }
    fn zero(&self) -> f64 {
        0.0
    }
    fn to_f64(&self, value: &f64) -> f64 {
        *value
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &BytesFormatter
    }
}

struct BytesFormatter;

impl ValueFormatter for BytesFormatter {
    fn scale_values(&self, _typical: f64, _values: &mut [f64]) -> &'static str {
        "B/body"
    }
    fn scale_throughputs(&self, _: f64, _: &Throughput, _: &mut [f64]) -> &'static str {
        "B/body"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "B/body"
    }
}

fn memory(c: &mut Criterion<BytesPerBody>) {
    let mut group = c.benchmark_group("peak memory, merging cloud");
    // Each sample is one whole run (about 30 s at 1e6); the spread is small (the same
    // run each time), so the minimum of 10 samples is enough.
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(1))
        .measurement_time(Duration::from_secs(1));
    for n in [10_000usize, 100_000, 1_000_000] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("benches/peers/scenes/peer_merge_{n}.json"));
        let scenario = Scenario::load(&path).expect("peer scene");
        group.bench_function(format!("N={n}"), |b| {
            b.iter_custom(|iters| {
                // Every iteration is the same run: its peak, once per iteration, so
                // that criterion's per-iteration value is that peak per body.
                let per_body = peak_bytes_of_run(&scenario) / n as f64;
                per_body * iters as f64
            })
        });
    }
    group.finish();
}

fn bytes_per_body() -> Criterion<BytesPerBody> {
    Criterion::default().with_measurement(BytesPerBody)
}

criterion_group! {
    name = benches;
    config = bytes_per_body();
    targets = memory
}
criterion_main!(benches);
