//! Peak memory per body (issue 19): the merging peer clouds of `benches/peers/` at
//! N = 1e4, 1e5 and 1e6, built and run to T in this process, no recording.
//!
//! The figure is the peak resident memory of a whole `agglo run` of the scene (one
//! thread, no recording; the child's ru_maxrss), divided by N: bytes per body, reported
//! through a criterion measurement of its own, so that `cargo bench --bench memory` keeps
//! a baseline and shows a regression as it does for times. (Measured in this process
//! instead, memory freed by one run and kept by the allocator hid the next run's peak.)
//! Linux only.
//!
//! The child is this bench's own executable, started again with `AGGLO_RUN_AS_CLI` set:
//! then its `main` is the `agglo` command's (`agglo::cli::main_with`, the same global
//! allocator), since a bench in a package of its own has no `agglo` binary to hand
//! (`CARGO_BIN_EXE_agglo` is given to the binary's own package only).
//!
//! Run: `cargo bench --bench memory`. The figures are in the README's speed section.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group};

/// Set in the child's environment: run as the `agglo` command.
const RUN_AS_CLI: &str = "AGGLO_RUN_AS_CLI";

#[global_allocator]
static ALLOCATOR: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;

/// Peak resident bytes of a whole `agglo run` of the scene at `path` (one thread, no
/// recording): the kernel's own figure for the finished child (ru_maxrss), so that
/// memory the bench process freed and kept cannot hide a run's peak.
// The child is reaped by wait4 below, which std's wait cannot replace: it also gives
// the child's rusage.
#[allow(clippy::zombie_processes)]
fn peak_bytes_of_run(path: &Path) -> f64 {
    let this = std::env::current_exe().expect("the bench's own path");
    let child = Command::new(this)
        .env(RUN_AS_CLI, "1")
        .args(["run", path.to_str().expect("UTF-8 path"), "--quiet"])
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .spawn()
        .expect("agglo starts");
    let mut status = 0;
    // SAFETY: an all-zero rusage is valid; wait4 fills it for our own child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: waiting once for our own child, not yet waited for.
    let pid = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as libc::pid_t, "wait4 on the run");
    assert!(
        libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0,
        "agglo run failed"
    );
    usage.ru_maxrss as f64 * 1024.0 // KiB on Linux
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
    // Each sample is one whole run (about 25 s at 1e6); the spread is small (the same
    // run each time), so the minimum of 10 samples is enough.
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(1))
        .measurement_time(Duration::from_secs(1));
    for n in [10_000usize, 100_000, 1_000_000] {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .join(format!("benches/peers/scenes/peer_merge_{n}.json"));
        group.bench_function(format!("N={n}"), |b| {
            b.iter_custom(|iters| {
                // Every iteration is the same run: its peak, once per iteration, so
                // that criterion's per-iteration value is that peak per body.
                let per_body = peak_bytes_of_run(&path) / n as f64;
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
fn main() -> std::process::ExitCode {
    if std::env::var_os(RUN_AS_CLI).is_some() {
        return agglo::cli::main_with([]);
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
    std::process::ExitCode::SUCCESS
}
