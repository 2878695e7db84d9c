//! Scenario files: every shipped scenario loads and runs its set-up; bad input gets a
//! clear error naming the field and the allowed range, a non-zero exit, and no panic.

use std::path::{Path, PathBuf};
use std::process::Command;

use agglo::prelude::*;

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

/// Inverse-problem and layout files live beside the scenarios but are other formats.
fn is_run_scenario(path: &Path) -> bool {
    let name = path.file_name().unwrap().to_string_lossy();
    name.ends_with(".json")
        && !name.contains("inverse")
        && !name.contains("layout")
        && !name.starts_with("study_")
        && !name.starts_with("scan_")
}

#[test]
fn every_shipped_scenario_loads_and_builds() {
    let mut checked = 0;
    for entry in std::fs::read_dir(scenarios_dir()).unwrap() {
        let path = entry.unwrap().path();
        if !is_run_scenario(&path) {
            continue;
        }
        let s = Scenario::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        Simulation::new(&s).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // Round trip: what we write, we read back identically.
        assert_eq!(Scenario::from_json(&s.to_json()).unwrap(), s);
        checked += 1;
    }
    assert!(
        checked >= 4,
        "expected the shipped scenarios, found {checked}"
    );
}

/// Run `agglo validate` on a scenario text; return (exit success, stderr).
fn validate_text(text: &str) -> (bool, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.json");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("validate")
        .arg(&path)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The two-body scenario with one edit applied to its JSON.
fn edited(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let text = std::fs::read_to_string(scenarios_dir().join("two_body.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut v);
    serde_json::to_string(&v).unwrap()
}

fn assert_rejected(text: &str, needles: &[&str]) {
    let (ok, stderr) = validate_text(text);
    assert!(!ok, "accepted: {text}");
    assert!(!stderr.contains("panicked"), "panicked: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "missing {needle:?} in: {stderr}");
    }
}

#[test]
fn unknown_field_is_named() {
    assert_rejected(
        &edited(|v| v["material"]["density"] = 3.0.into()),
        &["material", "density"],
    );
}

#[test]
fn missing_required_field_is_named() {
    assert_rejected(
        &edited(|v| {
            v["material"].as_object_mut().unwrap().remove("rho");
        }),
        &["rho"],
    );
}

#[test]
fn wrong_type_is_named() {
    assert_rejected(&edited(|v| v["time"]["end"] = "soon".into()), &["time.end"]);
}

#[test]
fn negative_radius_is_rejected_with_its_range() {
    assert_rejected(
        &edited(|v| v["cloud"]["radius"] = (-1e-3).into()),
        &["cloud.radius", "> 0"],
    );
}

#[test]
fn size_ratio_at_or_above_0_9_is_rejected() {
    assert_rejected(
        &edited(|v| {
            v["cloud"].as_object_mut().unwrap().remove("radius");
            v["cloud"]["size_ratio"] = 0.9.into();
        }),
        &["cloud.size_ratio", "0 < s < 0.9"],
    );
}

#[test]
fn non_positive_end_time_is_rejected() {
    assert_rejected(
        &edited(|v| v["time"]["end"] = 0.0.into()),
        &["time.end", "> 0"],
    );
}

#[test]
fn a0_above_af_is_rejected() {
    assert_rejected(
        &edited(|v| {
            v["impact"]["a0"] = 0.9.into();
            v["impact"]["af"] = 0.5.into();
        }),
        &["impact.a0", "a0 ≤ af"],
    );
}

#[test]
fn nan_is_rejected() {
    // JSON has no NaN: the literal is a parse error, reported with its location.
    let text = edited(|v| v["material"]["H0"] = 1.0.into()).replace("\"H0\":1.0", "\"H0\":NaN");
    assert_rejected(&text, &["material.H0"]);
}

#[test]
fn every_problem_is_reported_at_once() {
    assert_rejected(
        &edited(|v| {
            v["material"]["rho"] = (-5.0).into();
            v["material"]["epsilon"] = 2.0.into();
        }),
        &["material.rho", "material.epsilon", "0 ≤ ε ≤ 1"],
    );
}

#[test]
fn impossible_packing_fails_with_a_clear_error_and_nonzero_exit() {
    let text = edited(|v| {
        let cloud = v["cloud"].as_object_mut().unwrap();
        cloud.remove("radius");
        cloud.remove("bodies");
        v["cloud"]["count"] = 2000.into();
        v["cloud"]["size_ratio"] = 0.899.into(); // v_f ≈ 0.380: at the jamming limit of random sequential addition (≈ 0.38)
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dense.json");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("run")
        .arg(&path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("cloud placement failed"), "{stderr}");
    assert!(!stderr.contains("panicked"));
}

#[test]
fn missing_file_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["run", "/nonexistent/scenario.json"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/scenario.json"));
}

#[test]
fn every_shipped_inverse_file_validates_through_the_cli() {
    let mut checked = 0;
    for entry in std::fs::read_dir(scenarios_dir()).unwrap() {
        let path = entry.unwrap().path();
        if !path
            .file_name()
            .unwrap()
            .to_string_lossy()
            .contains("inverse")
        {
            continue;
        }
        let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
            .arg("validate")
            .arg(&path)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains("valid inverse problem"), "{stdout}");
        checked += 1;
    }
    assert!(
        checked >= 3,
        "expected the three shipped inverse files, found {checked}"
    );
}
