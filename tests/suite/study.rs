//! `agglo study`: the accuracy ladder end to end on a small scene, and the stability
//! maps against what docs/model.md §5, §8 and §14 predict.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use agglo::prelude::*;
use agglo::study::stability::{
    self, COOLING_STEPS, PairGrid, PairSetup, StabilityOptions, cooling_grid, cooling_law,
    cooling_map, pair_map,
};

/// A small P04-like scene: 60 grains, bonding at 185 m/s (critical speed ≈ 8 m/s), no
/// reaction heat (α = 0) so explicit cooling stays tame and the run is fast.
fn small_scene() -> Scenario {
    let mut s = Scenario::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/study_accuracy.json"
    )))
    .unwrap();
    s.name = "study_test".into();
    s.cloud.count = 60;
    s.material.alpha = 0.0;
    s.time.end = 0.004;
    s
}

fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

fn f(row: &HashMap<String, String>, key: &str) -> f64 {
    row[key]
        .parse()
        .unwrap_or_else(|_| panic!("{key} = {}", row[key]))
}

#[test]
fn accuracy_study_runs_end_to_end_and_writes_its_csvs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, small_scene().to_json()).unwrap();
    let out = dir.path().join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["study", "accuracy"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--repeats", "1", "--seeds", "2", "--target-growth", "3.23"])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    for file in [
        "accuracy.csv",
        "noise.csv",
        "accuracy_error.png",
        "accuracy_error.svg",
        "accuracy_growth.png",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let rows = read_csv(&out.join("accuracy.csv"));
    let noise = read_csv(&out.join("noise.csv"));
    assert_eq!(noise.len(), 2, "one row per seed");

    // The reference row compares the reference with itself: every error is exactly 0.
    let reference = &rows[0];
    assert_eq!(reference["family"], "reference");
    for key in [
        "growth_error",
        "count_error",
        "ks_distance",
        "impacts_error",
        "temperature_error",
    ] {
        assert_eq!(f(reference, key), 0.0, "{key}");
    }
    assert!(rows.len() > 25, "the whole ladder ran: {} rows", rows.len());
    for family in ["adaptive_c", "fixed_dt", "tolerance", "cooling", "papers"] {
        assert!(rows.iter().any(|r| r["family"] == family), "{family}");
    }
    for r in &rows {
        assert!(f(r, "wall_seconds") >= 0.0 && f(r, "steps") > 0.0, "{r:?}");
        // A run is a result only when it is sound: no invariant violations, finite
        // observables; a failed one says why.
        match r["status"].as_str() {
            "ok" => {
                assert_eq!(f(r, "invariant_violations"), 0.0, "{r:?}");
                assert!(f(r, "growth_ratio").is_finite(), "{r:?}");
                assert!(f(r, "mean_temperature").is_finite(), "{r:?}");
                assert!(r["failure"].is_empty(), "{r:?}");
            }
            "failed" => assert!(!r["failure"].is_empty(), "a failure without a why: {r:?}"),
            other => panic!("status {other}"),
        }
        // A setting that left impacts unconverged is an ensemble over the study's seeds.
        if r["status"] == "ok" && f(r, "unconverged") > 0.0 {
            assert_eq!(f(r, "ensemble_seeds"), 2.0, "{r:?}");
            let (mean, se) = (f(r, "ensemble_growth_mean"), f(r, "ensemble_growth_se"));
            assert!(mean.is_finite() && mean >= 1.0, "{r:?}");
            assert!(se.is_finite() || f(r, "ensemble_failed") > 0.0, "{r:?}");
        } else {
            assert_eq!(f(r, "ensemble_seeds"), 1.0, "{r:?}");
        }
    }
    assert!(
        rows.iter()
            .any(|r| r["status"] == "ok" && f(r, "unconverged") > 0.0),
        "no unconverged setting: the ensemble rows went untested"
    );

    // Fixed-Δt ladder, fine to coarse. One seed is one realisation of a chaotic system,
    // so intermediate rungs scatter within the noise; the monotone cases are the ends of
    // the ladder: ten steps over T (a particle moves ~50 radii per step) must miss far
    // more collisions, and get b_f/b0 further off, than the finest rung.
    let fixed: Vec<_> = rows.iter().filter(|r| r["family"] == "fixed_dt").collect();
    let (fine, coarse) = (fixed[0], fixed[fixed.len() - 1]);
    assert!(f(fine, "parameter") < f(coarse, "parameter"));
    assert!(
        f(coarse, "impacts_error") > f(fine, "impacts_error"),
        "impacts: coarse {} fine {}",
        coarse["impacts_error"],
        fine["impacts_error"]
    );
    assert!(
        f(coarse, "growth_error") > f(fine, "growth_error"),
        "growth: coarse {} fine {}",
        coarse["growth_error"],
        fine["growth_error"]
    );
    assert!(f(coarse, "impacts") < f(fine, "impacts"));
}

#[test]
fn study_rejects_bad_arguments_with_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["study", "accuracy", "no_such_file.json", "--out", "x"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no_such_file.json"));
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["study", "stability", "--out", "x", "--seeds", "0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--seeds"));
}

#[test]
fn plain_iteration_fails_exactly_where_model_14_predicts() {
    let grid = PairGrid::default();
    let cells = pair_map(&PairSetup::cold(), &grid);
    assert_eq!(cells.len(), grid.a0s.len() * grid.speed_ratios.len());
    let mut failures = 0;
    for c in &cells {
        // Skip the grid point at the critical speed itself, where λ = 1 up to rounding.
        if (c.speed_ratio - 1.0).abs() < 1e-9 {
            continue;
        }
        // docs/model.md §14: at a0 = 0, G(e) = 1 − λ/(1 − e) maps 0 → 1 − λ → 0: every
        // sub-critical speed (λ < 1) 2-cycles. For a0 > 0, |G'(e*)| =
        // (1 − e*)(1 − a0)/(1 − (1 − a0) e*) < 1, so it converges (in ≲ 28/a0 iterations
        // near the critical speed, far below the budget); above critical G(0) = 0 at once.
        let predicted_failure = c.a0 == 0.0 && c.speed_ratio < 1.0;
        assert_eq!(
            !c.plain_converged(),
            predicted_failure,
            "a0 = {}, v/v_c = {}: plain {:?}",
            c.a0,
            c.speed_ratio,
            c.plain
        );
        failures += usize::from(!c.plain_converged());
        // The safeguarded solver converges everywhere, to the closed form (tolerance:
        // TOL = 1e-12 on e ∈ [0, 1], plus rounding in G, well inside 1e-9).
        assert!(c.safeguarded_converged(), "{c:?}");
        let exact = c.closed_form.unwrap();
        assert!(
            (c.safeguarded.e - exact).abs() < 1e-9,
            "a0 = {}, v/v_c = {}: {} vs {exact}",
            c.a0,
            c.speed_ratio,
            c.safeguarded.e
        );
        if c.plain_converged() {
            assert!((c.plain.e - exact).abs() < 1e-9, "{c:?}");
        }
    }
    assert_eq!(failures, 19, "speeds 0.05 … 0.95 × critical at a0 = 0");
}

#[test]
fn safeguarded_solver_converges_everywhere_with_softening() {
    let cells = pair_map(&PairSetup::softening(), &PairGrid::default());
    for c in &cells {
        assert!(c.safeguarded_converged(), "{c:?}");
        assert!((0.0..=1.0).contains(&c.safeguarded.e));
        assert!(c.closed_form.is_none());
    }
}

#[test]
fn explicit_cooling_is_flagged_above_its_limit_and_implicit_never() {
    let law = cooling_law();
    let (dts, thetas) = cooling_grid();
    let cells = cooling_map(&law, &dts, &thetas);
    let mut flagged = 0;
    for c in &cells {
        let r = c.dt / c.limit;
        assert!(!c.implicit_unstable, "implicit at Δt/limit = {r}");
        // Never flagged below the limit (forward Euler is monotone there).
        if r <= 1.0 {
            assert!(!c.explicit_unstable, "explicit flagged at Δt/limit = {r}");
        }
        // With θs = 0 the first explicit step is θ0 (1 − r/4): negative beyond 4 × limit
        // (margin 1e-9 for rounding in r).
        if r > 4.0 * (1.0 + 1e-9) {
            assert!(
                c.explicit_unstable,
                "explicit not flagged at Δt/limit = {r}"
            );
        }
        if r < 4.0 * (1.0 - 1e-9) {
            assert!(!c.explicit_unstable, "explicit flagged at Δt/limit = {r}");
        }
        // Well below the limit both are accurate: first-order error ~ (steps · r)/something,
        // so r ≤ 1e-6 over 10 steps gives ≲ 1e-5.
        if r <= 1e-6 {
            assert!(c.explicit_error < 1e-5 && c.implicit_error < 1e-5, "{c:?}");
        }
        flagged += usize::from(c.explicit_unstable);
    }
    assert!(flagged > 100, "the grid reaches far beyond the limit");
    assert_eq!(COOLING_STEPS, 10);
}

#[test]
fn stability_study_writes_its_csvs_and_charts() {
    let dir = tempfile::tempdir().unwrap();
    let options = StabilityOptions {
        pair_grid: PairGrid {
            speed_ratios: vec![0.5, 1.5],
            a0s: vec![0.0, 0.5],
        },
        seeds: 1,
        runs: false,
    };
    let mut scene = small_scene();
    scene.cloud.count = 30;
    let study = stability::run_stability(&scene, &options, |_| {}).unwrap();
    agglo::study::write::write_stability(dir.path(), &study).unwrap();
    for file in [
        "pair_map.csv",
        "pair_map_softening.csv",
        "cooling_map.csv",
        "tunnelling_kinematic.csv",
        "pair_map.png",
        "cooling_map.png",
        "tunnelling.png",
    ] {
        assert!(dir.path().join(file).is_file(), "{file} missing");
    }
    let rows = read_csv(&dir.path().join("pair_map.csv"));
    assert_eq!(rows.len(), 4);
    // Kinematics: a step shorter than any contact misses nothing; the miss fraction
    // grows (weakly) with Δt once steps are long enough to pass through a grain.
    let kin = &study.kinematic;
    assert_eq!(kin[0].missed_fraction(), 0.0);
    let last = kin.last().unwrap();
    assert!(
        last.colliding > 0 && last.missed_fraction() > 0.5,
        "{last:?}"
    );
}
