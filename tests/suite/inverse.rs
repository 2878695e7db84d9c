//! The inverse problem (docs/model.md §12): the GA on a synthetic cost, the ensemble
//! stopping rules (the papers' and the standard-error rule) and the standard errors
//! of costs, determinism across thread counts and with speculative samples,
//! checkpoint/resume, the closing check, a short real run re-checked through
//! `agglo run`, and rejection of bad inverse files.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

use agglo::inverse::ensemble::{StoppingRule, samples_needed};
use agglo::inverse::problem::{GaSpec, InverseError, StopOn};
use agglo::inverse::{self, Evaluation, GaState, InverseProblem, Options, ga};

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

fn ga_spec(strings: usize, parents: usize, generations: usize, tol: f64) -> GaSpec {
    GaSpec {
        strings,
        parents,
        generations,
        rescale_every: 5,
        shrink: 0.5,
        tol,
        stop_on: StopOn::Best,
        seed: 11,
    }
}

/// Run the GA on cost(x) = Σ ((x_j − x*_j)/range_j)², minimum 0 at x*.
fn run_synthetic(spec: &GaSpec, calls: &AtomicUsize) -> GaState {
    let lower = vec![-5.0, 0.0, 100.0];
    let upper = vec![5.0, 1.0, 1000.0];
    let target = [1.234, 0.777, 321.0];
    let mut state = GaState::new(lower.clone(), upper.clone());
    while !state.finished {
        ga::step(spec, (&lower, &upper), &mut state, |_, candidates| {
            Ok(candidates
                .iter()
                .map(|(_, genes)| {
                    calls.fetch_add(1, Ordering::Relaxed);
                    let cost = genes
                        .iter()
                        .zip(&target)
                        .zip(lower.iter().zip(&upper))
                        .map(|((x, t), (lo, hi))| ((x - t) / (hi - lo)).powi(2))
                        .sum();
                    Evaluation {
                        cost,
                        samples: 1,
                        ..Default::default()
                    }
                })
                .collect())
        })
        .unwrap();
    }
    state
}

#[test]
fn ga_finds_known_minimum_with_monotone_best_and_paper_evaluation_count() {
    let spec = ga_spec(20, 6, 40, 0.0);
    let calls = AtomicUsize::new(0);
    let state = run_synthetic(&spec, &calls);
    let best = state.best().unwrap();
    // With rescaling every 5 generations (×0.5) the box around x* has shrunk by 2^-7 by
    // the end; a normalised squared error of 1e-4 (1 % of each range) is a loose bound.
    assert!(best.eval.cost < 1e-4, "best cost {}", best.eval.cost);
    assert!((best.genes[0] - 1.234).abs() < 0.1 && (best.genes[2] - 321.0).abs() < 9.0);
    // Parent retention: the best cost never increases.
    for w in state.history.windows(2) {
        assert!(w[1].best_cost <= w[0].best_cost, "best cost rose: {w:?}");
    }
    // docs/model.md §12: S + (G − 1)(S − K) evaluations, parents never re-evaluated.
    let expected = 20 + 39 * (20 - 6);
    assert_eq!(state.total_evaluations, expected);
    assert_eq!(calls.load(Ordering::Relaxed), expected);
    assert_eq!(state.history.len(), 40);
}

#[test]
fn ga_stops_when_best_cost_reaches_tol() {
    let spec = ga_spec(20, 6, 40, 1e-2);
    let calls = AtomicUsize::new(0);
    let state = run_synthetic(&spec, &calls);
    assert!(state.generations_done < 40, "never stopped early");
    assert!(state.best().unwrap().eval.cost <= 1e-2);
    // The generation before the last had not reached tol (otherwise it would have stopped there).
    let n = state.history.len();
    if n >= 2 {
        assert!(state.history[n - 2].best_cost > 1e-2);
    }
}

#[test]
fn ensemble_rule_stops_where_model_says() {
    // Running means 2, 3, 3: the change 0 at sample 3 satisfies |ΔQ̄| ≤ TOL|Q̄|.
    assert_eq!(samples_needed(&[2.0, 4.0, 3.0, 3.0], 1e-6, 2, 100), Some(3));
    // min_samples holds it back, max_samples cuts it short.
    assert_eq!(samples_needed(&[2.0, 4.0, 3.0, 3.0], 1e-6, 4, 100), Some(4));
    assert_eq!(samples_needed(&[2.0, 4.0, 3.0, 3.0], 1e-6, 2, 2), Some(2));
    // The boundary is inclusive: values 1, 3 → means 1, 2, change 1 = 0.5 · 2 (exact in binary).
    assert_eq!(samples_needed(&[1.0, 3.0], 0.5, 2, 10), Some(2));
    assert_eq!(samples_needed(&[1.0, 3.5], 0.5, 2, 10), None);
    // Never stops on the first sample unless max_samples = 1.
    assert_eq!(samples_needed(&[5.0, 5.0], 0.5, 1, 10), Some(2));
    assert_eq!(samples_needed(&[5.0], 0.5, 1, 1), Some(1));
    // Several tracked quantities: every one must settle.
    let mut rule = StoppingRule::new(0.01, 2, 10);
    assert!(!rule.push(&[1.0, 1.0]));
    assert!(!rule.push(&[1.0, 2.0]));
    assert!(rule.push(&[1.0, 2.0]));
    assert_eq!(rule.count(), 3);
}

/// A tiny real problem (P02 set-up, 30 grains, 60 steps): a few seconds in dev.
fn tiny_problem(generations: usize) -> InverseProblem {
    let text = format!(
        r#"{{
  "name": "tiny",
  "base": {{
    "name": "tiny_base", "seed": 1,
    "box": {{ "half_width": 6.5e-6 }},
    "cloud": {{ "count": 30, "size_ratio": 0.633, "v_rel": [4.3, 0, 0], "velocity_distribution": "positive" }},
    "material": {{ "rho": 6141.898, "H0": 67.188e6, "C": 1279.542, "Q": 707351, "alpha": 5940883.989,
                  "mu0": 0.307, "epsilon": 1.0, "theta0": 330.652, "theta_s": 330.652 }},
    "impact": {{ "a0": 0.01, "af": 1.0, "beta": 1e-6, "duration": "p02", "friction_scales_with_adhesion": true }},
    "time": {{ "end": 2.7e-4, "stepping": {{ "fixed": {{ "dt": 1e-6 }} }} }}
  }},
  "genes": [
    {{ "name": "v0", "path": "cloud.v_rel.0", "min": 0.5, "max": 20 }},
    {{ "name": "s", "path": "cloud.size_ratio", "min": 0.4, "max": 0.8 }},
    {{ "name": "theta0", "path": "material.theta0", "min": 280, "max": 370,
       "tied": [ {{ "path": "material.theta_s", "scale": 1 }} ] }}
  ],
  "end_time": {{ "p02": {{ "steps": 60 }} }},
  "cost": {{ "pi02": {{ "target_ratio": 2 }} }},
  "ensemble": {{ "tol": 1e-3, "min_samples": 2, "max_samples": 6, "track": ["mean"] }},
  "ga": {{ "strings": 8, "parents": 2, "generations": {generations}, "rescale_every": 2, "shrink": 0.5, "seed": 5 }},
  "reevaluate": {{ "strings": 2, "samples": 5 }}
}}"#
    );
    InverseProblem::from_json(&text, Path::new(".")).unwrap()
}

fn read(dir: &Path, file: &str) -> String {
    std::fs::read_to_string(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"))
}

#[test]
fn same_seed_gives_identical_outputs_on_one_and_two_threads() {
    let problem = tiny_problem(3);
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("t1"), tmp.path().join("t2"));
    for (dir, threads) in [(&a, 1), (&b, 2)] {
        let opts = Options {
            threads,
            ..Default::default()
        };
        let state = inverse::optimize(&problem, dir, &opts).unwrap();
        assert!(state.finished);
    }
    for f in [
        "generations.csv",
        "best.json",
        "best_scenario.json",
        "checkpoint.json",
    ] {
        assert_eq!(
            read(&a, f),
            read(&b, f),
            "{f} differs between 1 and 2 threads"
        );
    }
    assert!(a.join("convergence.png").exists() && a.join("best_radii.svg").exists());
}

fn agglo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_agglo"))
}

fn write_tiny(dir: &Path, generations: usize) -> PathBuf {
    // Same problem as `tiny_problem`, as a file for the binary.
    let problem = tiny_problem(generations);
    let path = dir.join("tiny_inverse.json");
    std::fs::write(&path, serde_json::to_string_pretty(&problem.spec).unwrap()).unwrap();
    path
}

#[test]
fn resume_after_interruption_gives_the_same_final_files() {
    let tmp = tempfile::tempdir().unwrap();
    let file = write_tiny(tmp.path(), 4);
    let whole = tmp.path().join("whole");
    let parts = tmp.path().join("parts");
    let ok = |c: &mut Command| {
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    ok(agglo()
        .arg("optimize")
        .arg(&file)
        .arg("--out")
        .arg(&whole)
        .arg("-q"));
    // Interrupted after generation 1 (of 0..3), then continued twice (the second
    // --resume of a finished run must change nothing).
    ok(agglo()
        .arg("optimize")
        .arg(&file)
        .arg("--out")
        .arg(&parts)
        .args(["-q", "--stop-after", "2"]));
    assert!(read(&parts, "generations.csv").lines().count() == 3);
    ok(agglo()
        .arg("optimize")
        .arg(&file)
        .arg("--out")
        .arg(&parts)
        .args(["-q", "--resume", "--threads", "1"]));
    ok(agglo()
        .arg("optimize")
        .arg(&file)
        .arg("--out")
        .arg(&parts)
        .args(["-q", "--resume"]));
    for f in [
        "generations.csv",
        "best.json",
        "best_scenario.json",
        "checkpoint.json",
    ] {
        assert_eq!(read(&whole, f), read(&parts, f), "{f} differs after resume");
    }
    // A checkpoint of another problem is refused.
    let other_dir = tmp.path().join("other");
    std::fs::create_dir_all(&other_dir).unwrap();
    let other = write_tiny(&other_dir, 5);
    let out = agglo()
        .arg("optimize")
        .arg(&other)
        .arg("--out")
        .arg(&whole)
        .args(["-q", "--resume"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("different inverse problem"));
}

#[test]
fn a_checkpoint_with_a_flipped_digit_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let file = write_tiny(tmp.path(), 4);
    let dir = tmp.path().join("out");
    let optimize = |resume: bool| {
        let mut c = agglo();
        c.arg("optimize")
            .arg(&file)
            .arg("--out")
            .arg(&dir)
            .arg("-q");
        if resume {
            c.arg("--resume");
        } else {
            c.args(["--stop-after", "2"]);
        }
        c.output().unwrap()
    };
    assert!(optimize(false).status.success());
    let path = dir.join("checkpoint.json");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("\"checksum\":\"crc32:"),
        "no checksum written"
    );
    // Flip one digit of the GA state (the first digit after `"state"`): still valid JSON
    // and a valid checkpoint, but not the one that was written.
    let state_at = text.find("\"state\"").unwrap();
    let (k, digit) = text[state_at..]
        .char_indices()
        .find(|(_, c)| c.is_ascii_digit())
        .map(|(k, c)| (state_at + k, c))
        .unwrap();
    let flipped = if digit == '9' {
        '8'
    } else {
        (digit as u8 + 1) as char
    };
    let mut damaged = text.clone();
    damaged.replace_range(k..k + 1, &flipped.to_string());
    std::fs::write(&path, &damaged).unwrap();
    let out = optimize(true);
    assert!(!out.status.success(), "a damaged checkpoint was resumed");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("checkpoint.json: the content does not match its checksum"),
        "{stderr}"
    );
    // The intact file resumes.
    std::fs::write(&path, &text).unwrap();
    let out = optimize(true);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn best_string_rerun_through_agglo_run_reproduces_its_cost() {
    let tmp = tempfile::tempdir().unwrap();
    let file = write_tiny(tmp.path(), 3);
    let out_dir = tmp.path().join("out");
    let out = agglo()
        .arg("optimize")
        .arg(&file)
        .arg("--out")
        .arg(&out_dir)
        .arg("-q")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let best: serde_json::Value = serde_json::from_str(&read(&out_dir, "best.json")).unwrap();
    // best_scenario.json is the winner of the closing check: its fresh seeds re-run.
    let top = &best["check"]["ranked"][0];
    let reported = top["cost"].as_f64().unwrap();
    let seeds: Vec<u64> = top["seeds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_u64().unwrap())
        .collect();
    assert_eq!(seeds.len() as u64, top["samples"].as_u64().unwrap());
    let best_scenario = out_dir.join("best_scenario.json");
    let sum: f64 = seeds
        .iter()
        .map(|&seed| common::growth_of_agglo_run(&best_scenario, seed, tmp.path()))
        .sum();
    let rerun = (sum / seeds.len() as f64 / 2.0 - 1.0).abs();
    // Same seeds, same scenario: the runs are deterministic, so the re-run agrees to
    // rounding (only the averaging order differs) — far inside the ensemble TOL = 1e-3.
    assert!(
        (rerun - reported).abs() <= 1e-3 * reported.abs().max(1e-12)
            && (rerun - reported).abs() < 1e-12,
        "re-run cost {rerun} vs reported {reported}"
    );
}

fn load_err(text: &str) -> String {
    match InverseProblem::from_json(text, &scenarios_dir()) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

fn with(patch: impl Fn(&mut serde_json::Value)) -> String {
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(scenarios_dir().join("paper2004_inverse.json")).unwrap(),
    )
    .unwrap();
    patch(&mut v);
    v.to_string()
}

#[test]
fn bad_inverse_files_are_rejected_with_field_paths() {
    let e = load_err(&with(|v| v["ga"]["parents"] = 7.into()));
    assert!(e.contains("ga.parents") && e.contains("even"), "{e}");
    let e = load_err(&with(|v| v["ga"]["strigs"] = 7.into()));
    assert!(e.contains("ga") && e.contains("strigs"), "{e}");
    let e = load_err(&with(|v| v["genes"][1]["max"] = 0.1.into()));
    assert!(e.contains("genes.1.max"), "{e}");
    let e = load_err(&with(|v| v["genes"][2]["path"] = "material.rhoo".into()));
    assert!(e.contains("genes.2.path"), "{e}");
    let e = load_err(&with(|v| {
        v["genes"][0]["tied"][1]["path"] = "cloud.v_rel.3".into()
    }));
    assert!(e.contains("genes.0.tied.1.path"), "{e}");
    // A range that leaves the scenario's own limits (s < 0.9) names the scenario field.
    let e = load_err(&with(|v| v["genes"][1]["max"] = 0.95.into()));
    assert!(e.contains("genes") && e.contains("cloud.size_ratio"), "{e}");
    let e = load_err(&with(|v| v["ensemble"]["max_samples"] = 1.into()));
    assert!(e.contains("ensemble.max_samples"), "{e}");
    let e = load_err(&with(|v| {
        v["cost"] = serde_json::json!({"pi02": {"target_ratio": -1}})
    }));
    assert!(e.contains("cost.pi02.target_ratio"), "{e}");
    let e = load_err(&with(|v| v["base"] = "missing.json".into()));
    assert!(e.contains("missing.json"), "{e}");
    let e = load_err(&with(|v| v["ensemble"]["tol"] = "big".into()));
    assert!(e.contains("ensemble.tol"), "{e}");
    // Through the binary: non-zero exit and the field path on stderr.
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("bad_inverse.json");
    std::fs::write(
        &bad,
        with(|v| {
            v["ga"]["shrink"] = 0.0.into();
            v["base"] = scenarios_dir()
                .join("paper2004_best.json")
                .display()
                .to_string()
                .into();
        }),
    )
    .unwrap();
    let out = agglo()
        .arg("optimize")
        .arg(&bad)
        .arg("--out")
        .arg(tmp.path().join("o"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("ga.shrink"));
}

#[test]
fn shipped_inverse_files_load_and_p02_end_time_matches_the_paper() {
    for name in [
        "paper2004_inverse.json",
        "paper2002_inverse.json",
        "inverse_demo.json",
    ] {
        InverseProblem::load(&scenarios_dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let p = InverseProblem::load(&scenarios_dir().join("paper2002_inverse.json")).unwrap();
    // P02 Table 1 rank 1 → T = 2.697e-4 s (docs/model.md §13; 4 significant figures).
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
    let s = p.scenario_for(&rank1, 3).unwrap();
    assert!(
        (s.time.end / 2.697e-4 - 1.0).abs() < 5e-4,
        "T = {}",
        s.time.end
    );
    assert_eq!(s.material.theta_s, 330.652);
    assert_eq!(s.seed, 3);
    // P04: v_rel follows v0 as (v0, 0.1 v0, 0.1 v0).
    let p = InverseProblem::load(&scenarios_dir().join("paper2004_inverse.json")).unwrap();
    let (lo, _) = p.bounds();
    let s = p.scenario_for(&lo, 1).unwrap();
    assert_eq!(s.cloud.v_rel, Some([20.0, 2.0, 2.0]));
    assert_eq!(s.material.gamma, Some(1e15));
}

#[test]
fn failed_sample_is_an_error_naming_the_string_or_a_penalty() {
    // max_steps = 1 makes every sample fail with the step limit. On adaptive steps: a
    // scene whose fixed steps (T/Δt) exceed max_steps is refused when it is validated,
    // so the limit is met while running only when the step count is not known ahead.
    let mut spec = tiny_problem(2).spec;
    spec.end_time = agglo::inverse::problem::EndTimeRule::Scenario;
    if let agglo::inverse::problem::BaseScenario::Inline(v) = &mut spec.base {
        v["time"]["max_steps"] = 1.into();
        v["time"]["stepping"] = serde_json::json!({ "adaptive": {} });
    }
    let p = InverseProblem::new(spec.clone(), Path::new(".")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    match inverse::optimize(&p, tmp.path(), &Options::default()) {
        Err(InverseError::Sample {
            generation: 0,
            sample: 0,
            genes,
            source,
            ..
        }) => {
            assert!(genes.contains("v0 = "));
            assert!(source.to_string().contains("max_steps"), "{source}");
        }
        other => panic!("expected a sample error, got {other:?}"),
    }
    spec.on_failure = agglo::inverse::problem::FailurePolicy::Penalty(9.0);
    let p = InverseProblem::new(spec, Path::new(".")).unwrap();
    let state = inverse::optimize(&p, &tmp.path().join("p"), &Options::default()).unwrap();
    let best = state.best().unwrap();
    assert_eq!((best.eval.cost, best.eval.failures), (9.0, 1));
}

// ---- Honest winners: standard errors, the standard-error rule, the closing check ----

use agglo::inverse::ensemble::{Observables, cost_standard_error, standard_error};
use agglo::inverse::problem::{CostSpec, EnsembleRule};

fn obs(mean: f64, b_star: f64) -> Observables {
    Observables {
        mean,
        b_star,
        ..Default::default()
    }
}

#[test]
fn standard_errors_follow_their_closed_forms() {
    // 2, 4, 6: sample s.d. 2, standard error 2/√3.
    let se = standard_error([2.0, 4.0, 6.0].into_iter()).unwrap();
    assert!((se - 2.0 / 3f64.sqrt()).abs() < 1e-15, "{se}");
    assert_eq!(standard_error([1.0].into_iter()), None);
    let samples = [obs(2.0, 5.0), obs(4.0, 5.0), obs(6.0, 5.0)];
    // Π02 = |m/r_t − 1| is linear in m away from the kink: s.e. = s.e.(m)/r_t.
    let pi02 = cost_standard_error(&CostSpec::Pi02 { target_ratio: 2.0 }, &samples).unwrap();
    assert!((pi02 - se / 2.0).abs() < 1e-15, "{pi02}");
    // Π04 = 1 − m/b*, b* fixed: s.e.(m)/b*.
    let pi04 = cost_standard_error(&CostSpec::Pi04, &samples).unwrap();
    assert!((pi04 - se / 5.0).abs() < 1e-15, "{pi04}");
    // b* moving with m in proportion: m/b* is constant, so the delta method gives 0
    // (to rounding) where the running-mean view would see a spread in both.
    let prop = [obs(2.0, 4.0), obs(4.0, 8.0), obs(6.0, 12.0)];
    let zero = cost_standard_error(&CostSpec::Pi04, &prop).unwrap();
    assert!(zero < 1e-15, "{zero}");
}

#[test]
fn standard_error_rule_waits_for_the_spread_not_for_two_agreeing_samples() {
    // Two samples that agree, then a spread: 3, 3, 1, 5, 3, 3, …
    let mut values = vec![3.0, 3.0, 1.0, 5.0];
    values.resize(30, 3.0);
    // The papers' rule stops on the two agreeing samples.
    assert_eq!(samples_needed(&values, 0.01, 2, 100), Some(2));
    // The standard-error rule (with min_samples = 5, so that a spread can show)
    // stops once s.e. = √(8/(n(n−1))) ≤ 5 % of the mean 3, i.e. n(n−1) ≥ 355.6: n = 20.
    let mut rule = StoppingRule::of_kind(EnsembleRule::StandardError, 0.05, 5, 100);
    let mut stopped = None;
    for n in 1..=values.len() {
        let v = &values[..n];
        let mean = v.iter().sum::<f64>() / n as f64;
        if rule.push_with_errors(&[mean], &[standard_error(v.iter().copied())]) {
            stopped = Some(n);
            break;
        }
    }
    assert_eq!(stopped, Some(20));
    // Without a standard error (one sample) the rule never counts as settled.
    let mut rule = StoppingRule::of_kind(EnsembleRule::StandardError, 0.05, 1, 100);
    assert!(!rule.push_with_errors(&[3.0], &[None]));
}

#[test]
fn closing_check_reranks_the_best_strings_on_fresh_seeds() {
    let problem = tiny_problem(3);
    let tmp = tempfile::tempdir().unwrap();
    let state = inverse::optimize(&problem, tmp.path(), &Options::default()).unwrap();
    let check = problem.spec.reevaluate;
    assert_eq!(
        state.finalists.len(),
        check.strings.min(state.parents.len())
    );
    for w in state.finalists.windows(2) {
        assert!(w[0].eval.cost <= w[1].eval.cost, "not ranked: {w:?}");
    }
    let mut ga_ranks: Vec<usize> = state.finalists.iter().map(|f| f.ga_rank).collect();
    ga_ranks.sort();
    assert_eq!(ga_ranks, (1..=state.finalists.len()).collect::<Vec<_>>());
    let best: serde_json::Value = serde_json::from_str(&read(tmp.path(), "best.json")).unwrap();
    let ga_seeds: Vec<u64> = best["top"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|t| {
            t["seeds"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s.as_u64().unwrap())
        })
        .collect();
    for (f, c) in state
        .finalists
        .iter()
        .zip(best["check"]["ranked"].as_array().unwrap())
    {
        assert_eq!(f.eval.samples, check.samples);
        assert!(f.eval.cost_se.is_some_and(|s| s.is_finite() && s >= 0.0));
        assert_eq!(c["ga_rank"].as_u64().unwrap() as usize, f.ga_rank);
        assert_eq!(c["cost"].as_f64().unwrap(), f.eval.cost);
        let ga = &state.parents[f.ga_rank - 1];
        assert_eq!(f.genes, ga.genes);
        assert_eq!(c["ga_cost"].as_f64().unwrap(), ga.eval.cost);
        // Fresh seeds: none shared with the GA's own ensembles.
        for s in c["seeds"].as_array().unwrap() {
            assert!(!ga_seeds.contains(&s.as_u64().unwrap()));
        }
    }
    // The GA's own figures carry standard errors too (≥ 2 samples each here).
    assert!(best["top"][0]["cost_se"].as_f64().is_some());
    // Rerunning the (finished) problem with --resume does not run the check again.
    let again = inverse::optimize(
        &problem,
        tmp.path(),
        &Options {
            resume: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(again.finalists, state.finalists);
}

#[test]
fn standard_error_rule_in_a_real_ensemble_meets_its_tolerance_or_the_cap() {
    let mut spec = tiny_problem(1).spec;
    spec.ensemble.rule = EnsembleRule::StandardError;
    spec.ensemble.tol = 0.01;
    spec.ensemble.max_samples = 8;
    spec.reevaluate.strings = 0;
    let p = InverseProblem::new(spec, Path::new(".")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let state = inverse::optimize(&p, tmp.path(), &Options::default()).unwrap();
    assert!(state.finalists.is_empty());
    for m in &state.parents {
        let e = &m.eval;
        let se = e.growth_se.unwrap();
        assert!(
            e.samples == 8 || se <= 0.01 * e.means.mean,
            "stopped at {} samples with s.e. {se} > 1 % of {}",
            e.samples,
            e.means.mean
        );
    }
}

#[test]
fn speculative_samples_never_change_an_ensemble() {
    use agglo::farm::Workers;
    use agglo::inverse::batch::{EnsembleBatch, Job, SampleScene};
    use agglo::inverse::ensemble::Accumulator;
    let p = tiny_problem(1);
    let jobs = || -> Vec<Job> {
        [2.0, 6.0, 12.0]
            .iter()
            .enumerate()
            .map(|(i, &v0)| Job {
                scene: SampleScene::Field {
                    path: "cloud.v_rel.0".into(),
                    value: v0,
                },
                seed_of: Box::new(move |s| inverse::derive_seed(&[9, i as u64, s as u64])),
                keep_radii: true,
                accumulator: Accumulator::new(
                    &p.spec.ensemble,
                    &p.spec.cost,
                    p.spec.on_failure,
                    (0, i),
                ),
                label: format!("v0 = {v0}"),
                coordinates: (0, i),
            })
            .collect()
    };
    let (plain, plain_times) = EnsembleBatch::new(jobs())
        .without_speculation()
        .run(&Workers::local(1), &p)
        .unwrap();
    // Without speculation every sample computed is used, and each exactly once.
    assert!(plain_times.iter().all(|t| t.used));
    let total: u32 = plain.iter().map(|e| e.samples).sum();
    assert_eq!(plain_times.len(), total as usize);
    // Four threads on three short jobs: idle threads run ahead speculatively.
    let (spec, spec_times) = EnsembleBatch::new(jobs())
        .run(&Workers::local(4), &p)
        .unwrap();
    assert_eq!(plain, spec);
    assert!(plain.iter().all(|e| e.samples >= 2));
    // The used samples are the same set; any extra ones are marked unused.
    assert_eq!(spec_times.iter().filter(|t| t.used).count(), total as usize);
}

/// A checkpoint altered by hand with its checksum recomputed (issue 33): a state that no
/// run of the problem can be in — a parent's gene far outside its bounds, a search range
/// with lower > upper, more generations done than allowed — is refused on --resume, naming
/// what is wrong.
#[test]
fn an_altered_checkpoint_with_a_recomputed_checksum_is_refused() {
    use agglo::inverse::checkpoint::Checkpoint;
    let problem = tiny_problem(2);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    inverse::optimize(&problem, dir, &Options::default()).unwrap();
    let text = read(dir, "checkpoint.json");
    type Alter = fn(&mut GaState);
    let cases: [(Alter, &str); 3] = [
        (|s| s.parents[0].genes[0] = 1e300, "parent 0, gene 0"),
        (|s| s.lower[0] = s.upper[0] + 1.0, "gene 0 searched"),
        (|s| s.generations_done = 1000, "generations done"),
    ];
    for (alter, words) in cases {
        let mut cp: Checkpoint = serde_json::from_str(&text).unwrap();
        alter(&mut cp.state);
        cp.checksum = None;
        cp.save(dir).unwrap(); // sealed again: the checksum matches the altered content
        let err = Checkpoint::load(dir, &problem).unwrap_err().to_string();
        assert!(
            err.contains("does not describe a run") && err.contains(words),
            "{words}: {err}"
        );
    }
}

/// A scan's seeds follow the point's value, not its index: a finer grid that contains a
/// coarse grid's points gives those points the same ensembles, row for row (before, the
/// value at D = 1e-5 m moved from 2.0105 to 2.0027 between `--points 5` and 25).
#[test]
fn a_finer_scan_reproduces_the_coarse_scans_points() {
    let dir = tempfile::tempdir().unwrap();
    let problem = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/inverse_demo.json");
    let scan = |points: &str| {
        let out = dir.path().join(points);
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
            .args(["scan", problem, "--gene", "cloud.v_rel.0"])
            .args([
                "--from", "1", "--to", "16", "--log", "--points", points, "-q",
            ])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let text = std::fs::read_to_string(out.join("scan.csv")).unwrap();
        text.lines()
            .skip(1)
            .map(|l| (l.split(',').next().unwrap().to_string(), l.to_string()))
            .collect::<Vec<_>>()
    };
    let coarse = scan("3"); // 1, 4, 16 m/s
    let fine = scan("5"); // 1, 2, 4, 8, 16 m/s
    assert_eq!(coarse.len(), 3);
    for (value, row) in &coarse {
        let same = fine.iter().find(|(v, _)| v == value);
        assert_eq!(
            same.map(|(_, r)| r),
            Some(row),
            "the point {value} differs between the grids"
        );
    }
    // The rounded grid lands on the round numbers.
    let values: Vec<&str> = fine.iter().map(|(v, _)| v.as_str()).collect();
    assert_eq!(values, ["1", "2", "4", "8", "16"]);
}
