//! Peak memory per body (issue 19): the merging peer clouds of `benches/peers/` at
//! N = 1e4, 1e5 and 1e6, each a whole run to T by the `agglo` binary, no recording.
//!
//! The figure is the peak resident memory of a whole `agglo run` of the scene (one
//! thread, no recording; the child's ru_maxrss), divided by N: bytes per body, reported
//! through a criterion measurement of its own, so that `cargo bench --bench memory` keeps
//! a baseline and shows a regression as it does for times. (Measured in this process
//! instead, memory freed by one run and kept by the allocator hid the next run's peak.)
//! Linux only.
//!
//! The child is the release `agglo` binary itself, built first by `cargo build --release
//! --bin agglo` beside this bench (a bench in a package of its own is not handed it:
//! `CARGO_BIN_EXE_agglo` is given to the binary's own package only). Started as this
//! bench's own executable, the child peaked 0.4–0.7 MB higher (its larger image), which is
//! 4–7 % of the figure at 1e4.
//!
//! Run: `cargo bench --bench memory`. The figures are in the README's speed section.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// The workspace's top directory (this package is `benches/`).
const TOP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// The `agglo` binary of this bench's profile, built (or found current) by the cargo
/// running it: `target/release/agglo` beside this bench's own
/// `target/release/deps/memory-…` (`target/debug/` under `cargo test --benches`).
fn agglo_binary() -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut build = Command::new(cargo);
    build.args(["build", "--quiet", "-p", "agglo", "--bin", "agglo"]);
    if !cfg!(debug_assertions) {
        build.arg("--release");
    }
    let status = build.current_dir(TOP).status().expect("cargo starts");
    assert!(status.success(), "cargo build --bin agglo failed");
    let this = std::env::current_exe().expect("the bench's own path");
    let release = this
        .parent()
        .and_then(Path::parent)
        .expect("target/release/deps/");
    release.join(format!("agglo{}", std::env::consts::EXE_SUFFIX))
}

/// Peak resident bytes of a whole `agglo run` of the scene at `path` (one thread, no
/// recording): the kernel's own figure for the finished child (ru_maxrss), so that
/// memory the bench process freed and kept cannot hide a run's peak.
// The child is reaped by wait4 below, which std's wait cannot replace: it also gives
// the child's rusage.
#[allow(clippy::zombie_processes)]
fn peak_bytes_of_run(agglo: &Path, path: &Path) -> f64 {
    let child = Command::new(agglo)
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
    let agglo = agglo_binary();
    let mut group = c.benchmark_group("peak memory, merging cloud");
    // Each sample is one whole run (about 25 s at 1e6); the spread is small (the same
    // run each time), so the minimum of 10 samples is enough.
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(1))
        .measurement_time(Duration::from_secs(1));
    for n in [10_000usize, 100_000, 1_000_000] {
        let path = Path::new(TOP).join(format!("benches/peers/scenes/peer_merge_{n}.json"));
        group.bench_function(format!("N={n}"), |b| {
            b.iter_custom(|iters| {
                // Every iteration is the same run: its peak, once per iteration, so
                // that criterion's per-iteration value is that peak per body.
                let per_body = peak_bytes_of_run(&agglo, &path) / n as f64;
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
