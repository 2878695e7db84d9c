//! Extensions in the binary (src/plugins/, `agglo::cli::main_with`): the example
//! programs `charged_grains` and `first_force` are the `agglo` command line with one
//! plugin each, and their sections (`plugins.charged_grains`, `plugins.gyration`) are
//! validated, set, documented, recorded, resumed, scanned and optimised exactly as a
//! built-in section is — each checked here by running the example binary as a user
//! would. The plain `agglo` binary refuses a scene that names a plugin it lacks.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;

use serde_json::Value;

/// The example program `name`, built (as `cargo test` builds examples; a no-op then)
/// beside this test binary, in its profile.
fn example(name: &str) -> PathBuf {
    // One build at a time: concurrent tests would wait on cargo's lock anyway.
    static BUILD: Mutex<()> = Mutex::new(());
    let _one = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().unwrap().parent().unwrap().to_path_buf(); // target/<profile>
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut build = Command::new(cargo);
    build
        .args(["build", "--quiet", "--example", name])
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    if profile_dir.file_name().is_some_and(|p| p == "release") {
        build.arg("--release");
    }
    let status = build.status().expect("cargo runs");
    assert!(status.success(), "cargo build --example {name} failed");
    let path = profile_dir.join("examples").join(name);
    assert!(path.exists(), "{} was not built", path.display());
    path
}

fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios/plugins")
        .join(name)
        .display()
        .to_string()
}

fn run(program: &Path, args: &[&str]) -> Output {
    Command::new(program).args(args).output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A refusal: a non-zero exit (not a panic) whose message contains `words`.
fn refused(out: &Output, words: &str) {
    let text = stderr(out);
    assert!(!out.status.success(), "accepted; expected `{words}`");
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(!text.contains("panicked"), "{text}");
    assert!(text.contains(words), "expected `{words}` in: {text}");
}

#[test]
fn the_section_is_validated_and_set_as_a_built_in_one_is() {
    let bin = example("charged_grains");
    let file = scenario("charged_grains.json");
    let out = run(&bin, &["validate", &file]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The plugin is in the pipeline `validate` prints (its outcome hook).
    assert!(
        stdout(&out).contains("charged_grains::coulomb_sticking"),
        "{}",
        stdout(&out)
    );
    for (set, words) in [
        (
            "plugins.charged_grains.q0=-1",
            "plugins.charged_grains.q0: allowed 0 ≤ q0 ≤ 1e-6 C (got -1)",
        ),
        (
            "plugins.charged_grains.q0=\"big\"",
            "plugins.charged_grains.q0: invalid type: string \"big\", expected f64",
        ),
        (
            "plugins.charged_grains.charge=1",
            "plugins.charged_grains.charge: unknown field `charge`, expected `q0`",
        ),
        (
            "plugins.magnets.b=1",
            "plugins.magnets: this binary has no plugin `magnets`; it has: charged_grains",
        ),
        // A built-in section's refusal, for comparison: the same form.
        (
            "material.rho=-1",
            "material.rho: allowed a finite number > 0 (got -1)",
        ),
    ] {
        refused(&run(&bin, &["validate", &file, "--set", set]), words);
    }
    // --set changes the run: without charges the growth is that of the built-in physics
    // alone, and the summary's name says what was set.
    let dir = tempfile::tempdir().unwrap();
    let summary = |q0: &str| -> Value {
        let path = dir.path().join(format!("{q0}.json"));
        let set = format!("plugins.charged_grains.q0={q0}");
        let out = run(
            &bin,
            &[
                "run",
                &file,
                "-q",
                "--set",
                &set,
                "--summary",
                path.to_str().unwrap(),
            ],
        );
        assert!(out.status.success(), "{}", stderr(&out));
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let (neutral, charged) = (summary("0"), summary("3e-9"));
    assert!(
        neutral["scenario"]
            .as_str()
            .unwrap()
            .contains("plugins.charged_grains.q0=0")
    );
    assert_ne!(neutral["counters"], charged["counters"]);
    assert_ne!(
        neutral["growth"]["growth_ratio"],
        charged["growth"]["growth_ratio"]
    );
}

#[test]
fn the_agglo_command_refuses_a_scene_naming_a_plugin_it_lacks() {
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["validate", &scenario("charged_grains.json")])
        .output()
        .unwrap();
    refused(
        &out,
        "plugins.charged_grains: this binary has no plugin `charged_grains`",
    );
    assert!(
        stderr(&out).contains("agglo::cli::main_with"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn agglo_schema_documents_the_section() {
    let out = run(&example("charged_grains"), &["schema"]);
    assert!(out.status.success());
    let schema: Value = serde_json::from_slice(&out.stdout).unwrap();
    let q0 = &schema["properties"]["plugins"]["properties"]["charged_grains"]["properties"]["q0"];
    assert_eq!(q0["type"], "number", "{schema:#}");
    assert!(q0["description"].as_str().unwrap().contains("[C]"));
    // The plain binary documents the property, with no sections in it.
    let plain = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("schema")
        .output()
        .unwrap();
    let schema: Value = serde_json::from_slice(&plain.stdout).unwrap();
    assert_eq!(
        schema["properties"]["plugins"]["properties"],
        serde_json::json!({})
    );
}

#[test]
fn a_recording_and_a_restart_file_carry_the_section() {
    let bin = example("charged_grains");
    let file = scenario("charged_grains.json");
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).display().to_string();
    // The uninterrupted run, recorded, with checkpoints every 1e-4 s.
    let every = "output.restart.every=1e-4";
    let out = run(
        &bin,
        &[
            "run",
            &file,
            "-q",
            "--set",
            every,
            "--out",
            &p("a.mcap"),
            "--final-state",
            &p("a.csv"),
            "--restart",
            &p("a.restart"),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let a = std::fs::read_to_string(p("a.csv")).unwrap();
    assert!(a.lines().next().unwrap().ends_with(",charge"), "{a}");
    // Run again from the recording's embedded scenario: the same charges, the same end.
    let out = run(
        &bin,
        &[
            "run",
            "--from",
            &p("a.mcap"),
            "-q",
            "--final-state",
            &p("b.csv"),
            // Its checkpoints (the embedded scenario takes them) go here, not to the
            // working directory.
            "--restart",
            &p("b.restart"),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(p("b.csv")).unwrap(), a);
    // Killed after step 120, resumed from its restart file: the same end, bit for bit.
    let out = Command::new(&bin)
        .args([
            "run",
            &file,
            "-q",
            "--set",
            every,
            "--restart",
            &p("r.restart"),
        ])
        .env("AGGLO_TEST_SIGKILL_AFTER_STEP", "120")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let out = run(
        &bin,
        &[
            "run",
            "--resume",
            &p("r.restart"),
            "-q",
            "--final-state",
            &p("c.csv"),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(p("c.csv")).unwrap(), a);
}

#[test]
fn scan_sweeps_the_section_and_optimize_searches_it() {
    let bin = example("charged_grains");
    let problem = scenario("charged_grains_inverse.json");
    let dir = tempfile::tempdir().unwrap();
    let out_dir = |name: &str| dir.path().join(name).display().to_string();
    let gene = "plugins.charged_grains.q0";
    let out = run(
        &bin,
        &[
            "scan",
            &problem,
            "--gene",
            gene,
            "--from",
            "0",
            "--to",
            "2e-8",
            "--points",
            "3",
            // Two worker threads even on one core: the samples are built off the main
            // thread, and must get the plugin there too.
            "--threads",
            "2",
            "-q",
            "--out",
            &out_dir("scan"),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let csv = std::fs::read_to_string(dir.path().join("scan/scan.csv")).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3, "{csv}");
    assert_eq!(rows[0][0], 0.0);
    assert!((rows[2][0] - 2e-8).abs() <= 1e-22, "{csv}");
    // Charges change the growth (columns: value, cost, growth_ratio, …): measured
    // b_f/b0 = 1.36 uncharged and 1.9 at q0 = 1e-8 and 2e-8 — apart by far more than
    // the ensemble's spread.
    assert!(rows[1][2] > rows[0][2] + 0.2, "{csv}");
    // A path that is no field of the section is refused, naming it.
    let out = run(
        &bin,
        &[
            "scan",
            &problem,
            "--gene",
            "plugins.charged_grains.q1",
            "--from",
            "0",
            "--to",
            "1",
            "--points",
            "2",
            "-q",
            "--out",
            &out_dir("bad"),
        ],
    );
    refused(&out, "plugins.charged_grains.q1");

    let out = run(
        &bin,
        &[
            "optimize",
            &problem,
            "--threads",
            "2",
            "-q",
            "--out",
            &out_dir("opt"),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let best: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("opt/best_scenario.json")).unwrap(),
    )
    .unwrap();
    let q0 = best["plugins"]["charged_grains"]["q0"].as_f64().unwrap();
    assert!((0.0..=3e-8).contains(&q0), "{q0}");
    // The GA's best scenario is a scenario of this binary: it validates.
    let out = run(&bin, &["validate", &out_dir("opt/best_scenario.json")]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The inverse file validates as one, naming its gene.
    let out = run(&bin, &["validate", &problem]);
    assert!(stdout(&out).contains("1 genes (q0)"), "{}", stdout(&out));
}

#[test]
fn the_first_force_acts_from_its_section_on_both_cores() {
    let bin = example("first_force");
    let file = scenario("first_force.json");
    let dir = tempfile::tempdir().unwrap();
    let go = |core: &str, sets: &[&str]| -> (Value, String) {
        let tag = format!("{core}{}", sets.join("").replace(['.', '=', '{', '}'], "_"));
        let (summary, end) = (
            dir.path().join(format!("{tag}.json")),
            dir.path().join(format!("{tag}.csv")),
        );
        let core = format!("time.core=\"{core}\"");
        let mut args = vec!["run", &file, "-q", "--set", &core];
        for set in sets {
            args.extend(["--set", set]);
        }
        let (s, e) = (summary.display().to_string(), end.display().to_string());
        args.extend(["--summary", &s, "--final-state", &e]);
        let out = run(&bin, &args);
        assert!(out.status.success(), "{}", stderr(&out));
        (
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap(),
            std::fs::read_to_string(&end).unwrap(),
        )
    };
    for core in ["events", "stepped"] {
        let (turned, turned_end) = go(core, &[]);
        let (_, still_end) = go(core, &["plugins.gyration.omega=0"]);
        assert!(
            turned["plugins"].to_string().contains("gyration"),
            "{core}: {}",
            turned["plugins"]
        );
        assert_ne!(turned_end, still_end, "{core}: the force did nothing");
        // A turn keeps every speed: the force's work is rounding against the kinetic
        // energy it turns (~1e-16 of it per kick; 1e-12 leaves room for 10⁴ kicks),
        // while its impulse (the momentum turned about z) is not zero.
        let e = &turned["energy"];
        let work = e["force_work"].as_f64().unwrap().abs();
        let kinetic = turned["kinetic_energy"].as_f64().unwrap();
        assert!(work <= 1e-12 * kinetic, "{core}: {e}");
        let impulse = &e["force_impulse"];
        assert!(impulse[0].as_f64().unwrap() != 0.0, "{core}: {e}");
        assert_eq!(
            turned["invariant_violations"],
            serde_json::json!([]),
            "{core}"
        );
        if core == "stepped" {
            // On the stepped core every body is current: a turn by 0 is the identity, bit
            // for bit, and the run is the run without the plugin.
            let (_, plain_end) = go(core, &["plugins={}"]);
            assert_eq!(still_end, plain_end);
        }
    }
    refused(
        &run(
            &bin,
            &["validate", &file, "--set", "plugins.gyration.omega=-2e9"],
        ),
        "plugins.gyration.omega: allowed |ω| ≤ 1e9 rad/s (got -2000000000)",
    );
}
