//! The batch commands over MPI (`cargo test --features mpi`; needs `mpirun`).
//!
//! `mpirun --oversubscribe -n 3 agglo optimize|scan|study accuracy|study readings`
//! must write the same bytes as one process (timings aside); a killed job must leave a checkpoint that `--resume`
//! (with another rank count) finishes to those same bytes; a failing sample must be
//! reported once, by rank 0, and stop every rank.
#![cfg(feature = "mpi")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn agglo() -> &'static str {
    env!("CARGO_BIN_EXE_agglo")
}

/// `mpirun -n ranks agglo args…`, allowed to run as root and on more ranks than cores
/// (CI machines have two).
fn mpirun(ranks: usize) -> Command {
    let mut c = Command::new("mpirun");
    c.args(["--oversubscribe", "-n", &ranks.to_string(), agglo()])
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    c
}

fn check(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A small P02-like problem: 30 grains, 60 fixed steps, `generations` generations.
fn write_problem(dir: &Path, generations: usize, extra: &str) -> PathBuf {
    let text = format!(
        r#"{{
  "name": "mpi_tiny",
  "base": {{
    "name": "mpi_tiny_base", "seed": 1,
    "box": {{ "half_width": 6.5e-6 }},
    "cloud": {{ "count": 30, "size_ratio": 0.633, "v_rel": [4.3, 0, 0], "velocity_distribution": "positive" }},
    "material": {{ "rho": 6141.898, "H0": 67.188e6, "C": 1279.542, "Q": 707351, "alpha": 5940883.989,
                  "mu0": 0.307, "epsilon": 1.0, "theta0": 330.652, "theta_s": 330.652 }},
    "impact": {{ "a0": 0.01, "af": 1.0, "beta": 1e-6, "duration": "p02", "friction_scales_with_adhesion": true }},
    "time": {{ "end": 2.7e-4, "stepping": {{ "fixed": {{ "dt": 1e-6 }} }} {extra} }}
  }},
  "genes": [
    {{ "name": "v0", "path": "cloud.v_rel.0", "min": 0.5, "max": 20 }},
    {{ "name": "s", "path": "cloud.size_ratio", "min": 0.4, "max": 0.8 }}
  ],
  "end_time": {{ "p02": {{ "steps": 60 }} }},
  "cost": {{ "pi02": {{ "target_ratio": 2 }} }},
  "ensemble": {{ "tol": 1e-3, "min_samples": 2, "max_samples": 8, "track": ["mean"] }},
  "ga": {{ "strings": 10, "parents": 4, "generations": {generations}, "rescale_every": 2, "shrink": 0.5, "seed": 7 }},
  "reevaluate": {{ "strings": 2, "samples": 6 }}
}}"#
    );
    let path = dir.join("problem.json");
    std::fs::write(&path, text).unwrap();
    path
}

const OUTPUTS: [&str; 4] = [
    "generations.csv",
    "best.json",
    "best_scenario.json",
    "checkpoint.json",
];

fn assert_same_files(a: &Path, b: &Path, files: &[&str], what: &str) {
    for f in files {
        let (x, y) = (std::fs::read(a.join(f)), std::fs::read(b.join(f)));
        let (x, y) = (
            x.unwrap_or_else(|e| panic!("{}: {e}", a.join(f).display())),
            y.unwrap_or_else(|e| panic!("{}: {e}", b.join(f).display())),
        );
        assert!(x == y, "{f} differs: {what}");
    }
}

fn single_process_optimize(problem: &Path, out: &Path) {
    check(
        Command::new(agglo())
            .args(["optimize", "-q", "--threads", "1"])
            .arg(problem)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap(),
        "single-process optimize",
    );
}

#[test]
fn optimize_on_three_ranks_writes_the_bytes_of_one_process() {
    let tmp = tempfile::tempdir().unwrap();
    let problem = write_problem(tmp.path(), 4, "");
    let one = tmp.path().join("one");
    single_process_optimize(&problem, &one);
    let three = tmp.path().join("three");
    let out = check(
        mpirun(3)
            .args(["optimize", "--out"])
            .arg(&three)
            .arg(&problem)
            .output()
            .unwrap(),
        "mpirun -n 3 optimize",
    );
    assert_same_files(&one, &three, &OUTPUTS, "1 process vs 3 ranks");
    // The other ranks did compute: rank 0 reports what it sent them.
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find(|l| l.contains("MPI: 3 ranks"))
        .unwrap_or_else(|| panic!("no MPI report in:\n{stdout}"));
    let sent: u64 = line
        .split(" sent to other ranks")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("cannot read the task count in `{line}`"));
    assert!(sent > 0, "no task reached another rank: {line}");
}

#[test]
fn scan_and_studies_on_three_ranks_match_one_process() {
    let tmp = tempfile::tempdir().unwrap();
    let problem = write_problem(tmp.path(), 1, "");
    let scan = |cmd: &mut Command, out: &Path| {
        cmd.args([
            "scan",
            "-q",
            "--gene",
            "cloud.v_rel.0",
            "--from",
            "1",
            "--to",
            "12",
        ])
        .args(["--points", "5", "--out"])
        .arg(out)
        .arg(&problem)
        .output()
        .unwrap()
    };
    let (a, b) = (tmp.path().join("scan1"), tmp.path().join("scan3"));
    check(scan(&mut Command::new(agglo()), &a), "scan");
    check(scan(&mut mpirun(3), &b), "mpirun scan");
    assert_same_files(&a, &b, &["scan.csv"], "scan: 1 process vs 3 ranks");

    // The study's timings differ from run to run; every other column must not.
    let two_body = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two_body.json");
    let study = |cmd: &mut Command, out: &Path| {
        cmd.args([
            "study",
            "accuracy",
            "--repeats",
            "1",
            "--seeds",
            "2",
            "--out",
        ])
        .arg(out)
        .arg(&two_body)
        .output()
        .unwrap()
    };
    let (a, b) = (tmp.path().join("acc1"), tmp.path().join("acc3"));
    check(study(&mut Command::new(agglo()), &a), "study accuracy");
    check(study(&mut mpirun(3), &b), "mpirun study accuracy");
    let (x, y) = (
        without_times(&a, "accuracy.csv"),
        without_times(&b, "accuracy.csv"),
    );
    assert!(x.len() > 5, "study too short: {x:?}");
    assert_eq!(x, y, "accuracy.csv (timings aside): 1 process vs 3 ranks");

    // The readings study: every run, timings aside.
    let readings = |cmd: &mut Command, out: &Path| {
        cmd.args(["study", "readings", "--seeds", "3", "--out"])
            .arg(out)
            .arg(&two_body)
            .output()
            .unwrap()
    };
    let (a, b) = (tmp.path().join("read1"), tmp.path().join("read3"));
    check(readings(&mut Command::new(agglo()), &a), "study readings");
    check(readings(&mut mpirun(3), &b), "mpirun study readings");
    for file in ["runs.csv", "readings.csv"] {
        let (x, y) = (without_times(&a, file), without_times(&b, file));
        assert!(x.len() > 3, "{file} too short: {x:?}");
        assert_eq!(x, y, "{file} (timings aside): 1 process vs 3 ranks");
    }
}

/// The lines of a CSV without its timing columns (`wall…`), which differ run to run.
fn without_times(dir: &Path, file: &str) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let timed: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| h.starts_with("wall"))
        .map(|(i, _)| i)
        .collect();
    assert!(!timed.is_empty(), "{file} has no timing column");
    text.lines()
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| !timed.contains(i))
                .map(|(_, c)| c)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect()
}

/// The environment variable MPI gives each rank its number.
fn rank_of(pid: u32) -> Option<usize> {
    let env = std::fs::read(format!("/proc/{pid}/environ")).ok()?;
    env.split(|&b| b == 0)
        .filter_map(|kv| std::str::from_utf8(kv).ok())
        .find_map(|kv| kv.strip_prefix("OMPI_COMM_WORLD_RANK="))
        .and_then(|r| r.parse().ok())
}

/// Pids of the agglo processes writing to `out`.
fn ranks_writing_to(out: &Path) -> Vec<(u32, usize)> {
    let needle = out.display().to_string();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmd) = std::fs::read(format!("/proc/{pid}/cmdline")) else {
            continue;
        };
        let cmd = String::from_utf8_lossy(&cmd).replace('\0', " ");
        if cmd.starts_with(agglo())
            && cmd.contains(&needle)
            && let Some(rank) = rank_of(pid)
        {
            found.push((pid, rank));
        }
    }
    found
}

#[test]
fn a_killed_rank_leaves_a_checkpoint_that_resume_finishes_on_any_rank_count() {
    let tmp = tempfile::tempdir().unwrap();
    let problem = write_problem(tmp.path(), 30, "");
    let whole = tmp.path().join("whole");
    single_process_optimize(&problem, &whole);

    let killed = tmp.path().join("killed");
    let mut job = mpirun(3)
        .args(["optimize", "-q", "--out"])
        .arg(&killed)
        .arg(&problem)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait for the first checkpoint, then kill a rank that is not rank 0.
    let start = Instant::now();
    while !killed.join("checkpoint.json").exists() {
        assert!(start.elapsed() < Duration::from_secs(60), "no checkpoint");
        std::thread::sleep(Duration::from_millis(5));
    }
    let ranks = ranks_writing_to(&killed);
    let (victim, _) = *ranks
        .iter()
        .find(|(_, r)| *r != 0)
        .unwrap_or_else(|| panic!("no worker rank found among {ranks:?}"));
    unsafe {
        libc::kill(victim as i32, libc::SIGKILL);
    }
    let status = job.wait().unwrap();
    let generations_done = |dir: &Path| {
        std::fs::read_to_string(dir.join("generations.csv"))
            .map(|t| t.lines().count() - 1)
            .unwrap_or(0)
    };
    assert!(
        !status.success(),
        "the job survived a killed rank (it had finished {} of 30 generations)",
        generations_done(&killed)
    );
    assert!(
        generations_done(&killed) < 30,
        "the job finished before the kill"
    );
    // Continue on 2 ranks, then compare with the uninterrupted single process.
    check(
        mpirun(2)
            .args(["optimize", "-q", "--resume", "--out"])
            .arg(&killed)
            .arg(&problem)
            .output()
            .unwrap(),
        "resume on 2 ranks",
    );
    assert_same_files(
        &whole,
        &killed,
        &OUTPUTS,
        "uninterrupted vs killed + resumed",
    );
}

#[test]
fn a_failing_sample_is_reported_once_and_stops_every_rank() {
    let tmp = tempfile::tempdir().unwrap();
    // One step allowed, adaptive steps: every sample fails with the step limit.
    let problem = write_problem(tmp.path(), 3, r#", "max_steps": 1"#);
    let text = std::fs::read_to_string(&problem)
        .unwrap()
        .replace(r#""fixed": { "dt": 1e-6 }"#, r#""adaptive": {}"#)
        .replace(r#""end_time": { "p02": { "steps": 60 } },"#, "");
    std::fs::write(&problem, text).unwrap();
    let start = Instant::now();
    let out = mpirun(3)
        .args(["optimize", "-q", "--out"])
        .arg(tmp.path().join("out"))
        .arg(&problem)
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "a failing sample did not fail the job"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.matches("failed with genes").count(),
        1,
        "the failure should be reported exactly once:\n{stderr}"
    );
    assert!(stderr.contains("max_steps"), "{stderr}");
    assert!(start.elapsed() < Duration::from_secs(60));
}

/// A coupling and its cells (id, input, kept state), as `advance_cells` takes them.
type SubgridBatch = (
    agglo::subgrid::Coupling,
    Vec<(
        u64,
        agglo::subgrid::CellInput,
        Option<agglo::subgrid::CellState>,
    )>,
);

/// `agglo::subgrid`'s batch of 256 cells (issue 32): sticky grains at volume fractions
/// 0.01–0.05, 60 bodies per box (`AGGLO_SUBGRID_BODIES` to measure with larger boxes),
/// one replica, Δt = 2e-4 s.
fn subgrid_batch() -> SubgridBatch {
    use agglo::subgrid::*;
    let base = agglo::scenario::Scenario::from_json(
        r#"{ "name": "cells", "seed": 3, "box": { "half_width": 0.01 },
             "cloud": { "count": 2, "radius": 2e-4, "v_rel": [0, 0, 0] },
             "material": { "rho": 1000, "H0": 1e-6, "C": 1000, "theta0": 300 },
             "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 }, "time": { "end": 1 } }"#,
    )
    .unwrap();
    let m0 = 4.0 / 3.0 * std::f64::consts::PI * 2e-4f64.powi(3) * 1000.0;
    let mut c = Coupling::new(base, [0.5, 1.5, 2.5, 1e6].map(|x| x * m0).to_vec()).unwrap();
    let bodies = std::env::var("AGGLO_SUBGRID_BODIES")
        .ok()
        .and_then(|b| b.parse().ok())
        .unwrap_or(60);
    c.bodies = BoxSize::Bodies(bodies);
    c.replicas = 1;
    // Re-lifted boxes, as this test was written and timed (persist is the default).
    c.persist = false;
    let cells = (0..256u64)
        .map(|cell| {
            let phi = 0.01 + 0.04 * (cell % 16) as f64 / 15.0;
            let n = phi / (4.0 / 3.0 * std::f64::consts::PI * 2e-4f64.powi(3));
            let class = |k: usize| ClassInput {
                number_density: if k == 0 { n } else { 0.0 },
                mass: m0 * (k + 1) as f64,
                velocity: [0.1 * (cell / 16) as f64, 0.0, 0.0],
                temperature: 300.0,
                granular_temperature: 1.0,
                granular_anisotropy: agglo::subgrid::ISOTROPIC,
            };
            let input = CellInput {
                classes: (0..3).map(class).collect(),
                gas: GasState {
                    velocity: [0.0; 3],
                    temperature: 300.0,
                    drag: None,
                },
                dt: 2e-4,
            };
            (cell, input, None)
        })
        .collect();
    (c, cells)
}

/// The batch's outputs and states, in cell order, as one byte string.
fn subgrid_bytes(
    results: Vec<
        Result<
            (agglo::subgrid::CellOutput, agglo::subgrid::CellState),
            agglo::subgrid::SubgridError,
        >,
    >,
) -> Vec<u8> {
    let mut bytes = Vec::new();
    for r in results {
        let (o, s) = r.unwrap();
        bytes.extend(o.to_bytes());
        bytes.extend(s.to_bytes());
    }
    bytes
}

/// A persistent batch (issue 37): 24 cells of the batch above (volume fractions
/// 0.01–0.05), K = 3 replicas of 60 bodies, persist on (the default). Two macro steps:
/// the first lifts every box; before the second, each cell's input is what
/// `apply_rates` left, with every other cell stirred (10 % of it replaced by its first
/// input), so that half the boxes resume their snapshots and half are adjusted.
fn persistent_batch() -> SubgridBatch {
    let (mut c, cells) = subgrid_batch();
    c.persist = true;
    c.replicas = 3;
    let cells = cells.into_iter().step_by(11).take(24).collect();
    (c, cells)
}

/// The second step's cells of [`persistent_batch`] from the first step's results: the
/// states carried through their bytes, the inputs as the module doc of
/// `persistent_batch` says.
fn second_step(
    c: &agglo::subgrid::Coupling,
    first: &[(
        u64,
        agglo::subgrid::CellInput,
        Option<agglo::subgrid::CellState>,
    )],
    results: &[Result<
        (agglo::subgrid::CellOutput, agglo::subgrid::CellState),
        agglo::subgrid::SubgridError,
    >],
) -> Vec<(
    u64,
    agglo::subgrid::CellInput,
    Option<agglo::subgrid::CellState>,
)> {
    first
        .iter()
        .zip(results)
        .enumerate()
        .map(|(i, ((cell, input, _), r))| {
            let (out, state) = r.as_ref().unwrap();
            let mut held = agglo::subgrid::apply_rates(c, input, out);
            if i % 2 == 1 {
                for (h, f) in held.classes.iter_mut().zip(&input.classes) {
                    h.number_density = 0.9 * h.number_density + 0.1 * f.number_density;
                }
            }
            let state = agglo::subgrid::CellState::from_bytes(&state.to_bytes()).unwrap();
            (*cell, held, Some(state))
        })
        .collect()
}

/// Both macro steps of [`persistent_batch`] on `workers`: the outputs and states of
/// each, as one byte string.
fn persistent_bytes(workers: &agglo::farm::Workers) -> Vec<u8> {
    let (c, cells) = persistent_batch();
    let first = agglo::subgrid::advance_cells(&c, 0, &cells, workers);
    let second = agglo::subgrid::advance_cells(&c, 1, &second_step(&c, &cells, &first), workers);
    let mut bytes = subgrid_bytes(first);
    bytes.extend(subgrid_bytes(second));
    bytes
}

/// The case a rank program runs (`AGGLO_SUBGRID_CASE`): the one-step re-lifted batch,
/// or the two persistent steps.
fn persistent_case() -> bool {
    std::env::var("AGGLO_SUBGRID_CASE").is_ok_and(|c| c == "persist")
}

/// Run by `mpirun` from the tests below (and a no-op in a plain `cargo test`): rank 0
/// advances the batch over every rank, each rank on `AGGLO_SUBGRID_THREADS` threads
/// (1), and writes its bytes to `AGGLO_SUBGRID_OUT`.
#[test]
fn subgrid_rank_program() {
    let Ok(out) = std::env::var("AGGLO_SUBGRID_OUT") else {
        return;
    };
    let threads = std::env::var("AGGLO_SUBGRID_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(1);
    let cluster = agglo::farm::Cluster::init().expect("MPI initialises once");
    let (c, cells) = match persistent_case() {
        true => persistent_batch(),
        false => subgrid_batch(),
    };
    if cluster.is_root() {
        let workers = agglo::farm::Workers {
            threads,
            cluster: Some(&cluster),
        };
        let started = Instant::now();
        let bytes = match persistent_case() {
            true => persistent_bytes(&workers),
            false => subgrid_bytes(agglo::subgrid::advance_cells(&c, 0, &cells, &workers)),
        };
        let seconds = started.elapsed().as_secs_f64();
        std::fs::write(&out, bytes).unwrap();
        std::fs::write(format!("{out}.seconds"), seconds.to_string()).unwrap();
        cluster.stop(0);
    } else {
        let code = agglo::subgrid::serve(&c, &cluster, threads);
        // MPI is finalised when the cluster is dropped, before the rank leaves.
        drop(cluster);
        assert_eq!(code, 0, "rank 0 stopped this rank with code {code}");
    }
}

#[test]
fn a_subgrid_batch_is_the_same_bytes_on_1_2_and_3_ranks() {
    let dir = tempfile::tempdir().unwrap();
    let (c, cells) = subgrid_batch();
    let local = subgrid_bytes(agglo::subgrid::advance_cells(
        &c,
        0,
        &cells,
        &agglo::farm::Workers::local(1),
    ));
    for ranks in [1, 2, 3] {
        let (bytes, seconds) = subgrid_on_ranks(dir.path(), "relift", ranks, 1);
        eprintln!("256 cells on {ranks} ranks: {seconds} s");
        assert!(
            bytes == local,
            "{ranks} ranks wrote other bytes than one process"
        );
    }
}

/// `mpirun -n ranks` of [`subgrid_rank_program`] for `case` on `threads` threads per
/// rank: its bytes and its seconds (as rank 0 timed them).
fn subgrid_on_ranks(dir: &Path, case: &str, ranks: usize, threads: usize) -> (Vec<u8>, String) {
    let me = std::env::current_exe().unwrap();
    let out = dir.join(format!("{case}_ranks{ranks}_threads{threads}.bin"));
    let status = Command::new("mpirun")
        .args(["--oversubscribe", "-n", &ranks.to_string()])
        .arg(&me)
        .args([
            "--exact",
            "subgrid_rank_program",
            "--test-threads=1",
            "--quiet",
        ])
        .env("AGGLO_SUBGRID_OUT", &out)
        .env("AGGLO_SUBGRID_CASE", case)
        .env("AGGLO_SUBGRID_THREADS", threads.to_string())
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .unwrap();
    check(
        status,
        &format!("the {case} subgrid batch on {ranks} ranks × {threads} threads"),
    );
    let bytes = std::fs::read(&out).unwrap();
    let seconds = std::fs::read_to_string(format!("{}.seconds", out.display())).unwrap_or_default();
    (bytes, seconds)
}

#[test]
fn persistent_subgrid_steps_are_the_same_bytes_on_1_2_and_3_ranks_and_1_and_2_threads() {
    // Issue 37: two macro steps with the kept boxes carried (resumed and adjusted), the
    // outputs and the state bytes of both, against one process on one thread.
    let dir = tempfile::tempdir().unwrap();
    let local = persistent_bytes(&agglo::farm::Workers::local(1));
    // Every cell keeps its three boxes' bodies after the first step, so the second
    // continues them: resumed as they were in the cells left as `apply_rates` put them,
    // adjusted in the stirred ones.
    let (c, cells) = persistent_batch();
    let first = agglo::subgrid::advance_cells(&c, 0, &cells, &agglo::farm::Workers::local(1));
    let states: Vec<_> = first
        .iter()
        .map(|r| r.as_ref().unwrap().1.clone())
        .collect();
    assert!(
        states
            .iter()
            .all(|s| s.keeps_bodies() && s.boxes().len() == 3)
    );
    assert_eq!(
        persistent_bytes(&agglo::farm::Workers::local(2)),
        local,
        "two threads in one process wrote other bytes than one"
    );
    for ranks in [1, 2, 3] {
        for threads in [1, 2] {
            let (bytes, seconds) = subgrid_on_ranks(dir.path(), "persist", ranks, threads);
            eprintln!(
                "2 persistent steps of 24 cells × 3 boxes on {ranks} ranks × {threads} threads: {seconds} s"
            );
            assert!(
                bytes == local,
                "{ranks} ranks × {threads} threads wrote other bytes than one process"
            );
        }
    }
}
