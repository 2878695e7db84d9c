//! Restarts bit for bit (engine/restart.rs, src/restart.rs): a run with checkpoints,
//! resumed from any of its snapshots, ends in exactly the state of the uninterrupted run
//! — in process from every snapshot, on both cores, in fields and under the constant
//! restitution law; and through the binary after SIGKILL at chosen steps, and after an
//! outside SIGKILL, SIGINT, SIGTERM or SIGHUP (each on both cores). A restart file with
//! a flipped digit is refused, naming the file.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use agglo::prelude::*;
use agglo::restart::RestartSnapshot;
use serde_json::{Value, json};

const BIN: &str = env!("CARGO_BIN_EXE_agglo");

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// quick_demo (300 grains: bonds, bounces, fragments, cooling) with `patch` merged in.
fn quick_demo(patch: Value) -> Value {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json"),
    )
    .unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    crate::common::merge(&mut v, patch);
    v
}

/// Every body's state, bit for bit (Debug prints each f64 in its shortest exact form).
fn state(sim: &Simulation) -> String {
    format!("{:?}", sim.bodies())
}

/// The counters a resumed run must reproduce.
fn counts(sim: &Simulation) -> String {
    format!(
        "{:?} {:?} {:?} {}",
        sim.counters(),
        sim.core_stats(),
        sim.ledger(),
        sim.clock().step
    )
}

/// Run `scene` with checkpoints, keeping every snapshot (through its bytes, as a file
/// holds it); resume a fresh simulation from each and check that it ends where the
/// uninterrupted run ended. Returns the number of snapshots.
fn resumes_bit_for_bit(what: &str, scene: Value) -> usize {
    let scenario = Scenario::from_value(scene).unwrap();
    let mut sim = Simulation::new(&scenario).unwrap();
    let mut snapshots = Vec::new();
    sim.run_with(|s| {
        if let Some(snapshot) = s.restart_snapshot() {
            snapshots.push(snapshot.encode());
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(
        snapshots.len() >= 3,
        "{what}: {} snapshots",
        snapshots.len()
    );
    let (end, end_counts) = (state(&sim), counts(&sim));
    for (k, bytes) in snapshots.iter().enumerate() {
        let snapshot = RestartSnapshot::decode(bytes).unwrap();
        let mut resumed = Simulation::new(&scenario).unwrap();
        resumed.resume(&snapshot).unwrap();
        resumed.run().unwrap();
        assert!(
            state(&resumed) == end,
            "{what}: resumed from snapshot {k} (t = {:e}), the final state differs",
            snapshot.time()
        );
        assert_eq!(counts(&resumed), end_counts, "{what}: snapshot {k}");
    }
    snapshots.len()
}

#[test]
fn event_core_resumes_bit_for_bit_from_every_snapshot() {
    let scene = quick_demo(json!({ "output": { "restart": { "every": 5e-4 } } }));
    let n = resumes_bit_for_bit("event core", scene);
    assert_eq!(n, 7, "checkpoints at 0.5, 1, …, 3.5 ms of T = 4 ms");
}

#[test]
fn stepped_core_resumes_bit_for_bit_from_every_snapshot() {
    for stepping in [
        json!({ "adaptive": { "step_factor": 0.5 } }),
        json!({ "fixed": { "dt": 2e-6 } }),
    ] {
        let scene = quick_demo(json!({
            "time": { "core": "stepped", "stepping": stepping },
            "output": { "restart": { "every": 5e-4 } }
        }));
        resumes_bit_for_bit(&format!("stepped core, {stepping}"), scene);
    }
}

#[test]
fn runs_in_fields_resume_bit_for_bit() {
    let gravity = json!({ "gravity": [0, 0, -9.81] });
    let drag = json!({ "gravity": [0, 0, -9.81], "drag": { "gas_velocity": [0, 0, 1],
                       "relaxation": { "constant": { "tau": 1e-3 } } } });
    for field in [gravity, drag] {
        for core in ["events", "stepped"] {
            let scene = quick_demo(json!({
                "field": field,
                "time": { "core": core },
                "output": { "restart": { "every": 5e-4 } }
            }));
            resumes_bit_for_bit(&format!("{core} core in {field}"), scene);
        }
    }
}

#[test]
fn constant_restitution_with_its_collapse_guard_resumes_bit_for_bit() {
    // The TC model keeps each body's last impact time: part of the snapshot.
    let scene = quick_demo(json!({
        "material": { "gamma": null },
        "impact": { "restitution": { "constant": 0.8 } },
        "output": { "restart": { "every": 5e-4 } }
    }));
    resumes_bit_for_bit("constant restitution", scene);
}

/// On the event core a checkpoint restarts every prediction from the checkpoint time,
/// which changes the run at rounding level; over the first millisecond of quick_demo
/// (904 impacts) that is still below 1e-9 radii, the same events in the same order.
/// (Over many more impacts the differences grow as any rounding change does in a
/// many-body run: at 4 ms, 1500 impacts, they reach ~1e-5 radii with the same counts.)
#[test]
fn checkpoints_change_the_event_core_only_at_rounding_level() {
    let plain = Scenario::from_value(quick_demo(json!({ "time": { "end": 1e-3 } }))).unwrap();
    let with = Scenario::from_value(quick_demo(json!({
        "time": { "end": 1e-3 },
        "output": { "restart": { "every": 1e-4 } }
    })))
    .unwrap();
    let mut a = Simulation::new(&plain).unwrap();
    let mut b = Simulation::new(&with).unwrap();
    a.run().unwrap();
    b.run().unwrap();
    // The same events happen: same counts of impacts, bonds and bounces.
    let (ca, cb) = (a.counters(), b.counters());
    assert_eq!(
        (ca.impacts, ca.bonds, ca.bounces),
        (cb.impacts, cb.bonds, cb.bounces)
    );
    let (ba, bb) = (a.bodies(), b.bodies());
    assert_eq!(ba.len(), bb.len());
    let worst = ba
        .iter()
        .zip(&bb)
        .map(|(x, y)| (x.position - y.position).length() / x.radius)
        .fold(0.0, f64::max);
    assert!(
        worst > 0.0,
        "checkpoints changed nothing: the test lost its point"
    );
    assert!(worst < 1e-9, "positions differ by {worst:e} radii");
}

/// The stepped core's state is complete at every step end: with fixed steps (no Δt bound
/// from the neighbour list, which a checkpoint rebuilds) checkpoints change nothing.
#[test]
fn checkpoints_leave_a_fixed_step_stepped_run_unchanged() {
    let fixed = json!({ "core": "stepped", "stepping": { "fixed": { "dt": 2e-6 } } });
    let plain = Scenario::from_value(quick_demo(json!({ "time": fixed }))).unwrap();
    let with = Scenario::from_value(quick_demo(json!({
        "time": fixed,
        "output": { "restart": { "every": 5e-4 } }
    })))
    .unwrap();
    let mut a = Simulation::new(&plain).unwrap();
    let mut b = Simulation::new(&with).unwrap();
    a.run().unwrap();
    let mut taken = 0;
    b.run_with(|s| {
        taken += usize::from(s.restart_snapshot().is_some());
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(taken, 7);
    assert!(
        state(&a) == state(&b),
        "checkpoints changed a fixed-step run"
    );
    assert_eq!(counts(&a), counts(&b));
}

// ---- through the binary ----

/// Write `scene` to DIR/NAME.json.
fn write_scene(dir: &Path, name: &str, scene: &Value) -> PathBuf {
    let path = dir.join(format!("{name}.json"));
    std::fs::write(&path, scene.to_string()).unwrap();
    path
}

/// `agglo run` in `dir` (where a default restart file goes) with a final state and a
/// summary named after `tag`.
fn run_cmd(args: &[&str], dir: &Path, tag: &str) -> Command {
    let mut cmd = Command::new(BIN);
    cmd.current_dir(dir)
        .args(args)
        .args(["-q", "--final-state"])
        .arg(dir.join(format!("{tag}.csv")))
        .arg("--summary")
        .arg(dir.join(format!("{tag}.json")))
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    cmd
}

/// The summary without its wall-clock field.
fn summary(dir: &Path, tag: &str) -> Value {
    let text = std::fs::read_to_string(dir.join(format!("{tag}.json"))).unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    v.as_object_mut().unwrap().remove("wall_seconds");
    v
}

/// Assert that the run tagged `tag` ended as the uninterrupted run `full` did: the same
/// final-state bytes and the same summary (wall time aside).
fn assert_same_end(dir: &Path, full: &str, tag: &str) {
    let a = std::fs::read(dir.join(format!("{full}.csv"))).unwrap();
    let b = std::fs::read(dir.join(format!("{tag}.csv"))).unwrap();
    assert!(
        a == b,
        "{tag}: final state differs from the uninterrupted run's"
    );
    assert_eq!(summary(dir, full), summary(dir, tag), "{tag}: summary");
}

fn resume(restart: &Path, dir: &Path, tag: &str) {
    let out = run_cmd(&["run", "--resume", s(restart)], dir, tag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// SIGKILL at several steps (the binary kills itself after the step the test names),
/// then resume: the end equals the uninterrupted run's, on `core`.
fn killed_and_resumed(core: &str) {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let scene = quick_demo(json!({
        "time": { "core": core },
        "output": { "restart": { "every": 5e-4 } }
    }));
    let path = write_scene(dir, "scene", &scene);
    let out = run_cmd(&["run", s(&path)], dir, "full").output().unwrap();
    assert!(out.status.success());
    let steps = summary(dir, "full")["steps"].as_u64().unwrap();
    for fraction in [0.55, 0.8, 0.97] {
        let kill_at = (steps as f64 * fraction) as u64;
        let tag = format!("killed_{kill_at}");
        let restart = dir.join(format!("{tag}.restart"));
        let out = Command::new(BIN)
            .current_dir(dir)
            .args(["run", s(&path), "-q", "--restart", s(&restart)])
            .env("AGGLO_TEST_SIGKILL_AFTER_STEP", kill_at.to_string())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .unwrap();
        assert_eq!(out.signal(), Some(libc::SIGKILL), "{core}: step {kill_at}");
        assert!(restart.exists(), "{core}: no checkpoint by step {kill_at}");
        resume(&restart, dir, &tag);
        assert_same_end(dir, "full", &tag);
    }
}

#[test]
fn sigkill_at_several_steps_then_resume_ends_as_the_uninterrupted_run_event_core() {
    killed_and_resumed("events");
}

#[test]
fn sigkill_at_several_steps_then_resume_ends_as_the_uninterrupted_run_stepped_core() {
    killed_and_resumed("stepped");
}

/// A run of quick_demo to T = 0.1 s (seconds of wall time), checkpointing every 2 ms.
fn long_scene(core: &str) -> Value {
    quick_demo(json!({
        "time": { "end": 0.1, "core": core },
        "output": { "restart": { "every": 2e-3 } }
    }))
}

/// Wait until the restart file exists (a checkpoint was written).
fn wait_for(path: &Path) {
    let start = Instant::now();
    while !path.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no checkpoint within two minutes"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A real signal from outside, wherever the run happens to be, then resume. With
/// `recorded`, the run records to run.mcap, its restart file goes beside it by default,
/// and `--resume run.mcap` finds it there.
fn signalled_and_resumed(signal: i32, core: &str, recorded: bool) {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let path = write_scene(dir, "long", &long_scene(core));
    let (mcap, restart) = (dir.join("run.mcap"), dir.join("run.restart"));
    let mut cmd = match recorded {
        true => run_cmd(&["run", s(&path), "--out", s(&mcap)], dir, "stopped"),
        false => run_cmd(&["run", s(&path), "--restart", s(&restart)], dir, "stopped"),
    };
    let mut child = cmd.spawn().unwrap();
    wait_for(&restart);
    // SAFETY: kill(2) on our own child, not yet waited for.
    unsafe { assert_eq!(libc::kill(child.id() as libc::pid_t, signal), 0) };
    let status = child.wait().unwrap();
    assert!(!status.success(), "the run ended before the signal");
    resume(if recorded { &mcap } else { &restart }, dir, "resumed");
    let out = run_cmd(&["run", s(&path)], dir, "full").output().unwrap();
    assert!(out.status.success());
    assert_same_end(dir, "full", "resumed");
}

#[test]
fn outside_sigkill_then_resume_ends_as_the_uninterrupted_run() {
    signalled_and_resumed(libc::SIGKILL, "events", false);
}

#[test]
fn sigterm_then_resume_from_the_recording_ends_as_the_uninterrupted_run() {
    signalled_and_resumed(libc::SIGTERM, "stepped", true);
}

#[test]
fn a_flipped_digit_in_a_restart_file_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let scene = quick_demo(json!({ "output": { "restart": { "every": 1e-3 } } }));
    let path = write_scene(dir, "scene", &scene);
    let restart = dir.join("run.restart");
    let out = run_cmd(&["run", s(&path), "--restart", s(&restart)], dir, "full")
        .output()
        .unwrap();
    assert!(out.status.success());
    let mut bytes = std::fs::read(&restart).unwrap();
    // The seed in the embedded scenario: 7 → 8.
    let at = bytes
        .windows(9)
        .position(|w| w == b"\"seed\": 7")
        .expect("the embedded scenario names its seed");
    bytes[at + 8] = b'8';
    let damaged = dir.join("damaged.restart");
    std::fs::write(&damaged, &bytes).unwrap();
    let out = run_cmd(&["run", "--resume", s(&damaged)], dir, "damaged")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("damaged.restart") && stderr.contains("does not match its checksum"),
        "{stderr}"
    );
    assert!(!dir.join("damaged.csv").exists(), "nothing is run");
    // A file cut short is refused too.
    std::fs::write(&damaged, &bytes[..bytes.len() / 2]).unwrap();
    let out = run_cmd(&["run", "--resume", s(&damaged)], dir, "damaged")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("damaged.restart"),
        "{stderr}"
    );
}

#[test]
fn sigint_then_resume_ends_as_the_uninterrupted_run_event_core() {
    signalled_and_resumed(libc::SIGINT, "events", true);
}

#[test]
fn sighup_then_resume_ends_as_the_uninterrupted_run_event_core() {
    signalled_and_resumed(libc::SIGHUP, "events", false);
}

#[test]
fn sigterm_then_resume_ends_as_the_uninterrupted_run_event_core() {
    signalled_and_resumed(libc::SIGTERM, "events", false);
}

#[test]
fn sigint_then_resume_ends_as_the_uninterrupted_run_stepped_core() {
    signalled_and_resumed(libc::SIGINT, "stepped", false);
}

#[test]
fn sighup_then_resume_ends_as_the_uninterrupted_run_stepped_core() {
    signalled_and_resumed(libc::SIGHUP, "stepped", true);
}

#[test]
fn outside_sigkill_then_resume_ends_as_the_uninterrupted_run_stepped_core() {
    signalled_and_resumed(libc::SIGKILL, "stepped", false);
}

/// One run of many (an ensemble's sample, a study's setting, `agglo kernel`'s seed:
/// `RunPlan::unwritten`) writes no checkpoints, even when its scenario asks for them:
/// each would write over the same file (the fuzz tests left `fuzz_seed.restart` in the
/// working directory after the kernel began to run through `Run`).
#[test]
fn one_run_of_many_writes_no_checkpoints() {
    use agglo::run::{Run, RunPlan};
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("sample.restart");
    let scene = quick_demo(json!({
        "time": { "end": 2e-4 },
        "output": { "restart": { "every": 5e-5, "path": s(&file) } }
    }));
    let scenario = Scenario::from_value(scene).unwrap();
    let (_, outcome) = Run::complete(RunPlan::unwritten(scenario.clone()), Vec::new()).unwrap();
    outcome.unwrap();
    assert!(!file.exists(), "one run of many wrote {}", file.display());
    // The same scenario as a run of its own writes them.
    let (_, outcome) = Run::complete(RunPlan::new(scenario).unwrap(), Vec::new()).unwrap();
    outcome.unwrap();
    assert!(
        file.exists(),
        "a run of its own wrote no {}",
        file.display()
    );
}
