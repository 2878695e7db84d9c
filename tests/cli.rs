//! The command line: `run` with its outputs, `validate`, `schema`.

use std::path::Path;
use std::process::Command;

fn agglo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_agglo"))
}

fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
        .display()
        .to_string()
}

#[test]
fn run_writes_a_summary_and_a_final_state_that_agree() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let state = dir.path().join("state.csv");
    let out = agglo()
        .args(["run", &scenario("quick_demo.json"), "--summary"])
        .arg(&summary)
        .arg("--final-state")
        .arg(&state)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let csv = std::fs::read_to_string(&state).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().expect("floats parse back"))
                .collect()
        })
        .collect();
    assert_eq!(rows.len() as u64, s["final_bodies"].as_u64().unwrap());
    assert_eq!(s["initial_bodies"].as_u64().unwrap(), 300);
    // b_f in the summary is the mean of the radius column (index 8).
    let mean_radius = rows.iter().map(|r| r[8]).sum::<f64>() / rows.len() as f64;
    let b_f = s["growth"]["b_f"].as_f64().unwrap();
    assert!(
        (mean_radius - b_f).abs() <= 1e-15 * b_f,
        "{mean_radius} vs {b_f}"
    );
    // Ids are unique and sorted.
    assert!(rows.windows(2).all(|w| w[0][0] < w[1][0]));
    // Every counter the issue asks for is there.
    for key in [
        "impacts",
        "bonds",
        "bounces",
        "fragmentations",
        "fixed_point_iterations",
        "fallbacks",
    ] {
        assert!(s["counters"][key].is_u64(), "missing counter {key}");
    }
    for key in ["pi04", "pi02", "n_f", "b_star"] {
        assert!(s["growth"][key].is_f64(), "missing observable {key}");
    }
    assert!(s["wall_seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(s["invariant_violations"].as_array().unwrap().len(), 0);
}

#[test]
fn schema_is_a_json_schema_of_the_scenario() {
    let out = agglo().arg("schema").output().unwrap();
    assert!(out.status.success());
    let schema: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let props = schema["properties"].as_object().expect("an object schema");
    for key in [
        "box", "cloud", "material", "impact", "time", "physics", "seed",
    ] {
        assert!(props.contains_key(key), "schema lacks {key}");
    }
}

#[test]
fn validate_describes_a_good_scenario() {
    let out = agglo()
        .args(["validate", &scenario("paper2004_best.json")])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("N = 1000") && text.contains("valid"),
        "{text}"
    );
}

#[test]
fn a_run_that_hits_its_step_limit_fails_but_still_writes_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scenario("quick_demo.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["time"]["max_steps"] = 10.into();
    let path = dir.path().join("short.json");
    std::fs::write(&path, v.to_string()).unwrap();
    let state = dir.path().join("state.csv");
    let out = agglo()
        .arg("run")
        .arg(&path)
        .arg("--final-state")
        .arg(&state)
        .arg("-q")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("max_steps"));
    assert!(std::fs::read_to_string(&state).unwrap().lines().count() > 1);
}
