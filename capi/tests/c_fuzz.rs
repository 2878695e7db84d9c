//! The C interface fuzzed from C (issue 39): `fuzz_doors.c` draws hostile scenarios,
//! options, cell inputs, batches, state bytes and output names from a fixed seed for a
//! bounded time, and checks every call's status and contract. A crash or an abort of
//! the library would end the C process by a signal; a hang, by this test's timeout.

use std::process::Stdio;
use std::time::{Duration, Instant};

mod common;
use common::{c_command, compile_c, crate_dir};

/// Seconds the harness draws new cases for: a few seconds of the suite's time (the
/// whole of `cargo test` runs about a minute in CI).
const BUDGET_SECONDS: f64 = 3.0;

/// A single case that takes this long is a hang (a valid box over Δt = 1e-5 s of 24
/// bodies takes milliseconds).
const TIMEOUT: Duration = Duration::from_secs(120);

#[test]
fn hostile_calls_through_the_c_interface_get_a_status_never_an_abort() {
    let build = tempfile::tempdir().unwrap();
    let exe = compile_c("tests/fuzz_doors.c", build.path());
    // The seed corpus: the shipped scenario the C example runs, mutated by the harness.
    let scenario = crate_dir().join("../scenarios/ballistic_aggregation.json");
    // A fixed seed (reproducible in CI); AGGLO_FUZZ_SEED explores others.
    let seed = std::env::var("AGGLO_FUZZ_SEED").unwrap_or_else(|_| "39".into());
    let mut child = c_command(&exe)
        .arg(&scenario)
        .arg(&seed)
        .arg(BUDGET_SECONDS.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > TIMEOUT {
            child.kill().unwrap();
            panic!("seed {seed}: the harness hung past {TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        status.success(),
        "seed {seed}: {status} (a signal is a crash or an abort):\n{stdout}\n{stderr}"
    );
    // The harness ran cases of every kind, and some of each kind of call were
    // accepted (a harness refused everywhere would test only the first check).
    let line = stdout
        .lines()
        .find(|l| l.starts_with("cases (accepted)"))
        .unwrap_or_else(|| panic!("no summary line:\n{stdout}"));
    let counts: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|t| !t.is_empty())
        .filter_map(|t| t.parse().ok())
        .collect();
    // coupling, cell, batch, state bytes, output: (cases, accepted) each, then seconds.
    assert!(counts.len() >= 10, "{line}");
    for kind in 0..5 {
        let (cases, accepted) = (counts[2 * kind], counts[2 * kind + 1]);
        assert!(cases >= 5 && accepted >= 1, "kind {kind}: {line}");
        assert!(accepted < cases, "kind {kind}: every case accepted: {line}");
    }
    println!("{line}");
}
