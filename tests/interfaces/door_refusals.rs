//! Issue 39's findings left open after the first pass: a heat capacity that validated
//! and then made every temperature NaN, a failed run's final state written without a
//! word, subgrid inputs that passed the cell's check and failed inside the lifted box,
//! and ensembles (`agglo kernel`, studies) that allocated from a user's number with no
//! memory check. Each case hung, aborted or misled before; each is refused by name now.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use agglo::prelude::*;
use agglo::subgrid::*;

use crate::common::cells::{coupling, monomers};

fn quick_demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json")
}

fn agglo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(args)
        .output()
        .unwrap()
}

/// Run `agglo args`, which must fail with exit status 1 (a refusal or a failed run,
/// not a crash); what it said on stderr.
fn fails(args: &[&str]) -> String {
    let out = agglo(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    err
}

#[test]
fn a_heat_capacity_beyond_any_material_is_refused_naming_material_c_and_its_range() {
    let dir = tempfile::tempdir().unwrap();
    let final_state = dir.path().join("final.csv");
    let scene = quick_demo();
    let scene = scene.to_str().unwrap();
    for args in [
        vec!["validate", scene, "--set", "material.C=1e200"],
        vec![
            "run",
            scene,
            "-q",
            "--set",
            "material.C=1e200",
            "--final-state",
            final_state.to_str().unwrap(),
        ],
    ] {
        let err = fails(&args);
        assert!(
            err.contains("material.C") && err.contains("0 < C ≤ 1e100 J/(kg·K)"),
            "{args:?}: {err}"
        );
    }
    // Refused before the run: no final state of NaN rows.
    assert!(!final_state.exists());
}

#[test]
fn radiation_too_weak_to_square_cools_to_finite_temperatures() {
    // The largest accepted C, and an emissivity of 1e-160 at an ordinary C: both gave a
    // radiation constant k_r ≈ 5e-171 /(s K³) on quick_demo's grains, whose square
    // underflowed, and every temperature was NaN at step 1.
    for (path, value) in [("C", 1e100), ("epsilon", 1e-160)] {
        let mut s = Scenario::load(&quick_demo()).unwrap();
        match path {
            "C" => s.material.C = value,
            _ => s.material.epsilon = value,
        }
        s.time.end = 4e-4;
        s.validate().unwrap();
        let mut sim = agglo::plugins::simulation(&s).unwrap();
        sim.run()
            .unwrap_or_else(|e| panic!("material.{path} = {value:e}: {e}"));
        let bodies = sim.bodies();
        assert!(
            bodies
                .iter()
                .all(|b| b.temperature.is_finite() && b.temperature > 0.0),
            "material.{path} = {value:e}"
        );
    }
}

#[test]
fn a_failed_run_says_its_final_state_is_the_state_at_the_failure() {
    // Explicit cooling at hc = 1e9 W/(m² K) overshoots to θ = −∞ (docs/model.md §8): the
    // run fails mid-way, after validation.
    let dir = tempfile::tempdir().unwrap();
    let final_state = dir.path().join("final.csv");
    let err = fails(&[
        "run",
        quick_demo().to_str().unwrap(),
        "-q",
        "--set",
        "physics.cooling=\"explicit\"",
        "--set",
        "material.epsilon=1",
        "--set",
        "material.hc=1e9",
        "--final-state",
        final_state.to_str().unwrap(),
    ]);
    let rows = std::fs::read_to_string(&final_state).unwrap();
    let broken = rows
        .lines()
        .skip(1)
        .filter(|l| l.contains("NaN") || l.contains("inf"))
        .count();
    assert!(broken > 0, "the run is expected to fail with a broken body");
    let total = rows.lines().count() - 1;
    assert!(
        err.contains(&format!(
            "note: the run failed; the final state in {} holds its {total} bodies at the failure",
            final_state.display()
        )) && err.contains("not at the end time"),
        "{err}"
    );
    // The count the note gives is the rows' (hardness is ∞ by the law at any θ ≤ 0,
    // so only the columns the note checks are compared: NaN or ±∞ in θ here).
    let hot: usize = rows
        .lines()
        .skip(1)
        .filter(|l| {
            let f: Vec<&str> = l.split(',').collect();
            f[1..10]
                .iter()
                .any(|x| !x.parse::<f64>().unwrap().is_finite())
                || !f[11].parse::<f64>().unwrap().is_finite()
        })
        .count();
    assert!(
        err.contains(&format!("and {hot} of them have a non-finite value")),
        "{hot}: {err}"
    );
}

#[test]
fn subgrid_inputs_that_the_box_would_refuse_are_refused_naming_the_cell_s_field() {
    let c = coupling(300, 2);
    let base = monomers(&c, 0.02, 1e-4);
    let with_class = |edit: &dyn Fn(&mut ClassInput)| {
        let mut input = base.clone();
        edit(&mut input.classes[0]);
        input
    };
    let cases: Vec<(CellInput, &str)> = vec![
        // 1e5 m/s on every axis: |v| = 1.7e5 m/s, each component within the limit.
        (
            with_class(&|k| k.velocity = [1e5; 3]),
            "cell 3: classes[0].velocity = |v| = 1.73205080756887",
        ),
        (
            with_class(&|k| k.granular_temperature = 1e300),
            "cell 3: classes[0].granular_temperature = 1e300",
        ),
        // σ = √T_g = 1e4 m/s: 10 σ reaches the limit with |v| = 0, not with 1 m/s.
        (
            with_class(&|k| {
                k.granular_temperature = 1e8;
                k.velocity = [1.0, 0.0, 0.0];
            }),
            "cell 3: classes[0].granular_temperature = 1e8",
        ),
        (
            with_class(&|k| k.temperature = 1e300),
            "cell 3: classes[0].temperature = 1e300",
        ),
        (
            CellInput {
                gas: GasState {
                    temperature: 1e300,
                    ..base.gas
                },
                ..base.clone()
            },
            "cell 3: gas.temperature = 1e300",
        ),
        (
            CellInput {
                gas: GasState {
                    velocity: [9e4, 9e4, 0.0],
                    ..base.gas
                },
                ..base.clone()
            },
            "cell 3: gas.velocity = |u|",
        ),
    ];
    for (input, needle) in cases {
        let e = advance_cell(&c, 3, 0, &input, None).unwrap_err();
        assert!(
            matches!(e, SubgridError::Input { .. }) && e.to_string().starts_with(needle),
            "{needle}: {e}"
        );
    }
    // The edges themselves pass: 10 σ = 1e5 m/s at rest, a temperature of 1e70 K.
    let edge = with_class(&|k| {
        k.granular_temperature = 1e8;
        k.temperature = 1e70;
    });
    agglo::subgrid::check_input(&c, 3, &edge).unwrap();
}

#[test]
fn agglo_kernel_refuses_a_scene_larger_than_the_memory_before_any_run() {
    // 4e9 bodies need about 2.6 TB: the run aborted allocating (rc 134) where `agglo
    // run` refused the scene.
    let dir = tempfile::tempdir().unwrap();
    let out_file = dir.path().join("k.npz");
    let err = fails(&[
        "kernel",
        quick_demo().to_str().unwrap(),
        "--set",
        "cloud.count=4000000000",
        "--set",
        "cloud.size_ratio=0.01",
        "--bins",
        "dustpy:primary,1,7",
        "--seeds",
        "2",
        "--threads",
        "1",
        "--out",
        out_file.to_str().unwrap(),
        "-q",
    ]);
    assert!(
        err.contains("cloud.count: 4000000000 bodies need about 2600.0 GB (650 B per body)"),
        "{err}"
    );
    assert!(!out_file.exists());
}

#[test]
fn study_seed_counts_are_checked_against_the_memory_before_they_are_listed() {
    let dir = tempfile::tempdir().unwrap();
    // Readings: every reading × 4294967295 seeds, a scene each.
    let err = fails(&[
        "study",
        "readings",
        quick_demo().to_str().unwrap(),
        "--seeds",
        "4294967295",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        err.contains("runs (readings × --seeds) need about") && err.contains("allowed at most"),
        "{err}"
    );
    // Stability: refused before its maps are drawn (they take seconds), not after.
    let err = fails(&[
        "study",
        "stability",
        "--seeds",
        "4294967295",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(err.contains("4294967295 seeds need about"), "{err}");
    // Neither study wrote anything.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // Accuracy and stability, through the library (their seeds are usize there).
    let s = Scenario::load(&quick_demo()).unwrap();
    let options = agglo::study::accuracy::AccuracyOptions {
        seeds: 1 << 40,
        ..Default::default()
    };
    let e =
        agglo::study::accuracy::run_accuracy(&s, &options, &agglo::farm::Workers::local(1), |_| {})
            .unwrap_err()
            .to_string();
    assert!(e.starts_with("1099511627776 seeds need about"), "{e}");
    let e = agglo::study::stability::run_misses(&s, &[1e-6], &[1.0], 1 << 40)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("1099511627776 seeds need about"), "{e}");
}
