//! Stop signals: SIGINT, SIGTERM and SIGHUP each stop `agglo run` at its next step with
//! every output written (a finalised recording, the summary, the final state) and a
//! non-zero exit naming the signal; a second stop signal ends the process at once,
//! leaving a recording whose complete chunks a reader still recovers.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_agglo");

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// quick_demo run for 0.4 s of simulated time (seconds of wall time), recording every
/// step, with a summary and a final state asked for.
struct LongRun {
    child: Child,
    mcap: PathBuf,
    summary: PathBuf,
    final_state: PathBuf,
}

fn long_run(dir: &Path) -> LongRun {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json"),
    )
    .unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["time"]["end"] = serde_json::json!(0.4);
    v["output"] = serde_json::json!({ "recording": { "every_steps": 1 } });
    let scenario = dir.join("long.json");
    std::fs::write(&scenario, v.to_string()).unwrap();
    let (mcap, summary, final_state) = (
        dir.join("run.mcap"),
        dir.join("summary.json"),
        dir.join("final.csv"),
    );
    let child = Command::new(BIN)
        .args(["run", s(&scenario), "-q", "--out", s(&mcap)])
        .args(["--summary", s(&summary), "--final-state", s(&final_state)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    LongRun {
        child,
        mcap,
        summary,
        final_state,
    }
}

/// Wait until the recording holds more than 50 kB: the handlers are installed (the file
/// is created after them) and the run is under way.
fn wait_until_running(mcap: &Path) {
    let start = Instant::now();
    while std::fs::metadata(mcap).map(|m| m.len()).unwrap_or(0) <= 50_000 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "recording did not grow"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Wait until the recording holds at least one complete chunk. The writer streams each
/// chunk to disk as it fills (about 1 MiB of messages before compression) and patches
/// its header when it closes, so a file that has merely grown may hold only a torn
/// first chunk: a run ended at once then leaves no channel to read.
fn wait_for_a_complete_chunk(mcap: &Path) {
    let start = Instant::now();
    loop {
        let out = Command::new(BIN)
            .args(["inspect", "--json", s(mcap)])
            .output()
            .unwrap();
        let chunks = serde_json::from_slice::<serde_json::Value>(&out.stdout)
            .ok()
            .and_then(|r| r["chunks"].as_u64())
            .unwrap_or(0);
        if chunks > 0 {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no complete chunk within a minute"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn send(signal: &str, child: &Child) {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success(), "kill -{signal} failed");
}

fn inspect(mcap: &Path) -> serde_json::Value {
    let out: Output = Command::new(BIN)
        .args(["inspect", s(mcap), "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// One signal: the run stops cleanly, says which signal stopped it, and writes everything.
fn stops_cleanly_on(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let run = long_run(dir.path());
    wait_until_running(&run.mcap);
    send(signal, &run.child);
    let out = run.child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{signal}: {stderr}");
    assert!(
        stderr.contains(&format!("stopped by SIG{signal}")) && stderr.contains("interrupted"),
        "{signal}: {stderr}"
    );
    // The recording is finalised, and the summary and final state describe the same,
    // unfinished run.
    let report = inspect(&run.mcap);
    assert_eq!(report["finalised"], true, "{signal}: {report}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&run.summary).unwrap()).unwrap();
    let time = summary["time"].as_f64().unwrap();
    assert!(time > 0.0 && time < 0.4, "{signal}: stopped at t = {time}");
    let rows = std::fs::read_to_string(&run.final_state)
        .unwrap()
        .lines()
        .count()
        - 1;
    assert_eq!(rows as u64, summary["final_bodies"].as_u64().unwrap());
    // The final state is whole, only early: the note says stopped, not failed.
    assert!(
        stderr.contains(&format!(
            "note: the run was stopped; the final state in {} holds its {rows} bodies at the stop",
            run.final_state.display()
        )) && stderr.contains("0 of them have a non-finite value")
            && !stderr.contains("failed"),
        "{signal}: {stderr}"
    );
}

#[test]
fn sigint_stops_a_run_with_every_output_written() {
    stops_cleanly_on("INT");
}

#[test]
fn sigterm_stops_a_run_with_every_output_written() {
    stops_cleanly_on("TERM");
}

#[test]
fn sighup_stops_a_run_with_every_output_written() {
    stops_cleanly_on("HUP");
}

#[test]
fn a_second_signal_ends_the_run_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let run = long_run(dir.path());
    wait_for_a_complete_chunk(&run.mcap);
    // Two different stop signals back to back (two of the same kind may merge into one
    // while pending): whichever is delivered first asks for a clean stop, the other ends
    // the process at once with 128 + its number (SIGINT 2, SIGTERM 15), not the clean
    // stop's 1.
    let pid = run.child.id() as libc::pid_t;
    // SAFETY: kill(2) on our own child process, which has not been waited for yet.
    unsafe {
        assert_eq!(libc::kill(pid, libc::SIGTERM), 0);
        assert_eq!(libc::kill(pid, libc::SIGINT), 0);
    }
    let out = run.child.wait_with_output().unwrap();
    let code = out.status.code();
    assert!(code == Some(130) || code == Some(143), "exit {code:?}");
    // Whatever reached the disk is readable: the scenario and the complete chunks.
    let report = inspect(&run.mcap);
    assert_eq!(report["scenario"], "quick_demo");
    assert!(report["channels"][0]["messages"].as_u64().unwrap() > 0);
}

/// Runs on several threads at once share the stop watchdog's step counters: a step that
/// ended on one thread after another read the clock made `now - last` overflow (a panic
/// in debug builds, inside every threaded ensemble of the Python module).
#[test]
fn runs_stepping_on_several_threads_at_once() {
    use agglo::run::{Run, RunPlan, Until};
    use std::ops::ControlFlow;
    let text = std::fs::read_to_string("scenarios/quick_demo.json").unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    // About 2·10⁴ steps a run, so that two threads' step ends interleave many times.
    crate::common::merge(&mut v, serde_json::json!({ "cloud": { "count": 2000 } }));
    let s = agglo::prelude::Scenario::from_value(v).unwrap();
    std::thread::scope(|scope| {
        for _ in 0..2 {
            scope.spawn(|| {
                let plan = RunPlan::new(s.clone()).unwrap();
                let mut run = Run::start(plan, Default::default()).unwrap();
                let outcome = run.advance(Until::End, &mut |_| ControlFlow::Continue(()));
                outcome.unwrap();
                assert!(run.is_finished());
            });
        }
    });
}
