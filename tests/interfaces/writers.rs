//! Writers off the simulation thread (`src/output/offload.rs`): the files a run writes
//! are byte for byte those written on the simulation thread (`AGGLO_WRITERS=inline`),
//! and a writer's error ends the run naming the file.

use std::path::Path;
use std::process::{Command, Output};

/// `agglo run` of quick_demo in `dir` with every table and a recording, writers as
/// `threading` says (`inline` or `thread`).
fn run_quick_demo(dir: &Path, threading: &str) -> Output {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("run")
        .arg(&scene)
        .args([
            "-q",
            "--set",
            "time.end=0.002",
            "--out",
            "run.mcap",
            "--series",
            "series.csv",
            "--sizes",
            "sizes.parquet",
            "--snapshots",
            "snapshots.csv",
            "--collisions",
            "collisions.parquet",
            "--sample-steps",
            "5",
        ])
        .env("AGGLO_WRITERS", threading)
        .current_dir(dir)
        .output()
        .unwrap()
}

const FILES: [&str; 5] = [
    "run.mcap",
    "series.csv",
    "sizes.parquet",
    "snapshots.csv",
    "collisions.parquet",
];

#[test]
fn threaded_writers_write_the_bytes_of_the_inline_ones() {
    let (inline, threaded) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    for (dir, threading) in [(&inline, "inline"), (&threaded, "thread")] {
        let out = run_quick_demo(dir.path(), threading);
        assert!(
            out.status.success(),
            "{threading}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for name in FILES {
        let a = std::fs::read(inline.path().join(name)).unwrap();
        let b = std::fs::read(threaded.path().join(name)).unwrap();
        assert!(!a.is_empty(), "{name} is empty");
        assert!(
            a == b,
            "{name}: {} bytes inline, {} threaded",
            a.len(),
            b.len()
        );
    }
    // Long enough to cross the hand-overs: several batches of snapshot rows.
    let rows = std::fs::read_to_string(threaded.path().join("snapshots.csv"))
        .unwrap()
        .lines()
        .count();
    assert!(
        rows > 2 * agglo::output::table::BATCH_ROWS,
        "{rows} snapshot lines"
    );
}

#[cfg(target_os = "linux")]
#[test]
fn a_table_that_cannot_be_written_fails_the_run_naming_it() {
    // /dev/full opens but every write fails (no space left on the device).
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json");
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("run")
        .arg(&scene)
        .args([
            "-q",
            "--set",
            "time.end=0.001",
            "--snapshots",
            "/dev/full",
            "--sample-steps",
            "1",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/dev/full"), "{err}");
    assert!(err.to_lowercase().contains("no space"), "{err}");
}
