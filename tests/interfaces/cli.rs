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

/// quick_demo with `edit` applied, written to `dir/NAME.json`.
fn edited_scenario(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value),
) -> std::path::PathBuf {
    let text = std::fs::read_to_string(scenario("quick_demo.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut v);
    let path = dir.join(format!("{name}.json"));
    std::fs::write(&path, v.to_string()).unwrap();
    path
}

/// `agglo validate PATH`: its stdout, after checking it succeeded.
fn validate_text(path: &str) -> String {
    let out = agglo().args(["validate", path]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The numbered systems of a `validate` listing (`  3. merge::merge_bonded`).
fn listed_systems(text: &str) -> Vec<String> {
    text.lines()
        .filter_map(|l| l.trim().split_once(". "))
        .filter(|(n, _)| n.parse::<usize>().is_ok())
        .map(|(_, system)| system.to_string())
        .collect()
}

/// The lines under `left out:`.
fn left_out_lines(text: &str) -> Vec<String> {
    text.lines()
        .skip_while(|l| !l.starts_with("left out"))
        .filter_map(|l| l.trim().strip_prefix("- ").map(String::from))
        .collect()
}

#[test]
fn validate_lists_the_pipeline_the_run_runs() {
    let text = validate_text(&scenario("paper2004_best.json"));
    assert!(text.contains("core: event"), "{text}");
    let systems = listed_systems(&text);
    for stage in [
        "events::pop_due_contacts",
        "impact::resolve_impacts",
        "merge::merge_bonded",
        "fragment::fragment_bodies",
        "events::schedule_next_step",
        "diagnostics::check_step_totals",
    ] {
        assert!(systems.iter().any(|s| s == stage), "{stage}: {text}");
    }
    // In pipeline order.
    let at = |name: &str| systems.iter().position(|s| s == name).unwrap();
    assert!(at("events::pop_due_contacts") < at("impact::resolve_impacts"));
    assert!(at("merge::merge_bonded") < at("fragment::fragment_bodies"));
    // The event core cools, drifts and wraps lazily, and says so.
    let left_out = left_out_lines(&text);
    assert!(
        left_out
            .iter()
            .any(|l| l.starts_with("cooling: done lazily by the event core")),
        "{text}"
    );
    assert!(
        left_out
            .iter()
            .any(|l| l.starts_with("drift, boundary: done lazily by the event core")),
        "{text}"
    );
    assert!(!systems.iter().any(|s| s.starts_with("drift::")), "{text}");

    // The run reports the very pipeline validate announced (validate builds a one-body
    // copy of the scene; the run builds the whole cloud).
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let out = agglo()
        .args(["run", &scenario("quick_demo.json"), "-q", "--summary"])
        .arg(&summary)
        .output()
        .unwrap();
    assert!(out.status.success());
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let demo = validate_text(&scenario("quick_demo.json"));
    let from_run: Vec<String> = s["pipeline"]["systems"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect();
    assert_eq!(from_run, listed_systems(&demo));
    assert_eq!(s["pipeline"]["core"], "event");
    let run_left_out: Vec<String> = s["pipeline"]["left_out"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect();
    assert_eq!(run_left_out, left_out_lines(&demo));
}

#[test]
fn validate_says_why_fragmentation_and_cooling_are_left_out() {
    let dir = tempfile::tempdir().unwrap();
    // The stepped core would schedule cooling and fragmentation: this scene needs neither.
    let stepped = |v: &mut serde_json::Value| {
        v["time"]["core"] = "stepped".into();
    };
    let with_both = edited_scenario(dir.path(), "both", stepped);
    let without = edited_scenario(dir.path(), "neither", |v| {
        stepped(v);
        v["material"]["gamma"] = serde_json::Value::Null;
        v["material"]["epsilon"] = 0.into();
        v["material"]["hc"] = 0.into();
    });

    let text = validate_text(with_both.to_str().unwrap());
    assert!(
        text.contains("core: stepped — time.core = \"stepped\""),
        "{text}"
    );
    let systems = listed_systems(&text);
    assert!(
        systems.contains(&"fragment::fragment_bodies".to_string()),
        "{text}"
    );
    assert!(
        systems.contains(&"cooling::cool_bodies".to_string()),
        "{text}"
    );
    assert!(systems.contains(&"drift::drift".to_string()), "{text}");
    assert!(text.contains("left out: nothing"), "{text}");

    let text = validate_text(without.to_str().unwrap());
    let systems = listed_systems(&text);
    assert!(
        !systems
            .iter()
            .any(|s| s.starts_with("fragment::") || s.starts_with("cooling::")),
        "{text}"
    );
    assert!(
        systems.contains(&"impact::resolve_impacts".to_string()),
        "{text}"
    );
    assert_eq!(
        left_out_lines(&text),
        vec![
            "fragmentation off: γ = ∞ (material.gamma = null)".to_string(),
            "cooling off: ε = hc = 0 (material.epsilon, material.hc)".to_string(),
        ],
        "{text}"
    );
}

#[test]
fn validate_says_why_a_scene_runs_on_the_stepped_core() {
    // paper2002_best steps with a fixed Δt, which the event core cannot do.
    let text = validate_text(&scenario("paper2002_best.json"));
    assert!(
        text.contains(
            "core: stepped — time.core = \"auto\", and the event core needs adaptive stepping"
        ),
        "{text}"
    );
}

/// quick_demo on the stepped core with elastic bounces, nothing merging and no heating,
/// so contacts keep coming at the same rate; `dt_min` [s] is the lower step bound.
fn bouncing_stepped_scene(dir: &Path, name: &str, dt_min: f64, end: f64) -> std::path::PathBuf {
    edited_scenario(dir, name, |v| {
        v["time"] = serde_json::json!({
            "end": end,
            "core": "stepped",
            "stepping": { "adaptive": { "dt_min": dt_min, "dt_max": 1e-3, "skin": 2 } }
        });
        v["physics"] = serde_json::json!({
            "merging": false, "fragmentation": false, "cooling": "off"
        });
        v["material"]["alpha"] = 0.into();
        v["impact"] = serde_json::json!({ "a0": 1.0, "af": 1.0, "beta": 1.0 });
    })
}

/// Run `scene` quietly with a summary: (stderr, clamped steps, steps).
fn run_quietly(dir: &Path, scene: &Path) -> (String, u64, u64) {
    let summary = dir.join("summary.json");
    let out = agglo()
        .arg("run")
        .arg(scene)
        .arg("-q")
        .arg("--summary")
        .arg(&summary)
        .output()
        .unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success(), "{stderr}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    (
        stderr,
        s["counters"]["clamped_steps"].as_u64().unwrap(),
        s["steps"].as_u64().unwrap(),
    )
}

#[test]
fn a_run_that_keeps_clamping_at_dt_min_says_so_while_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    // Grains 60 m/s apart at volume fraction 0.18 meet every ~0.1 µs somewhere in the
    // cloud: a 1 µs floor on Δt clamps most steps.
    let scene = bouncing_stepped_scene(dir.path(), "clamping", 1e-6, 3e-3);
    let (stderr, clamped, steps) = run_quietly(dir.path(), &scene);
    assert!(steps >= 2000 && clamped * 2 > steps, "{clamped} of {steps}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    // One warning: the run takes well under the 5 s between two warnings.
    assert_eq!(warnings.len(), 1, "{stderr}");
    assert!(
        warnings[0].contains("of the last 1000 steps were clamped at Δt_min = 1e-6 s"),
        "{stderr}"
    );
}

#[test]
fn a_run_that_clamps_now_and_then_stays_quiet() {
    let dir = tempfile::tempdir().unwrap();
    // A 1 ns floor: only the steps with a touching pair deferred to the next one clamp.
    let scene = bouncing_stepped_scene(dir.path(), "rarely", 1e-9, 5e-4);
    let (stderr, clamped, steps) = run_quietly(dir.path(), &scene);
    assert!(
        steps >= 1000 && clamped > 0 && clamped * 2 < steps,
        "{clamped} of {steps}"
    );
    assert!(!stderr.contains("warning"), "{stderr}");
}
