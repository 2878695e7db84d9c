//! The rough edges a new user met on a first day (issue 31): `--set` inside a section the
//! scenario leaves out, on a field that does not exist, on `cloud.radius` over a
//! `size_ratio`; `validate` with overrides; times as a person reads them; the licence
//! and citation files; shell completions and the man page.

use std::path::Path;
use std::process::{Command, Output};

use agglo::prelude::*;

fn agglo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_agglo"))
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn quick_demo() -> String {
    root()
        .join("scenarios/quick_demo.json")
        .display()
        .to_string()
}

/// `agglo validate quick_demo.json` with `extra` arguments.
fn validate(extra: &[&str]) -> Output {
    agglo()
        .args(["validate", &quick_demo()])
        .args(extra)
        .output()
        .unwrap()
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `agglo run --help` suggests `--set output.restart.every=1e-3`; no shipped scenario has
/// `output.restart`, so the setting must create the section.
#[test]
fn set_inside_a_section_the_scenario_leaves_out_creates_it() {
    let base = Scenario::load(&root().join("scenarios/quick_demo.json")).unwrap();
    assert!(
        base.output.restart.is_none(),
        "the test needs a scene without it"
    );
    let set = base
        .with_settings(&["output.restart.every=1e-3".into()])
        .expect("the section is created");
    assert_eq!(set.output.restart.as_ref().map(|r| r.every), Some(1e-3));

    let help = text(&agglo().args(["run", "--help"]).output().unwrap()).0;
    assert!(help.contains("--set output.restart.every=1e-3"), "{help}");
    let out = validate(&["--set", "output.restart.every=1e-3"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("restart checkpoints: every 1e-3 s"),
        "{stdout}"
    );
}

#[test]
fn set_on_a_field_that_does_not_exist_names_the_first_missing_segment() {
    let out = validate(&["--set", "nosuch.field=1"]);
    let stderr = text(&out).1;
    assert!(!out.status.success());
    assert!(stderr.contains("unknown field `nosuch`"), "{stderr}");
    assert!(
        !stderr.contains("no field `field`"),
        "names `nosuch`, not `field`: {stderr}"
    );
    // Below an existing section, the segment that is not one of its fields.
    let stderr = text(&validate(&["--set", "cloud.nosuch.x=1"])).1;
    assert!(
        stderr.contains("`cloud.nosuch`") && stderr.contains("unknown field `nosuch`"),
        "{stderr}"
    );
    // Below a value: it says the value is not a section.
    let stderr = text(&validate(&["--set", "time.end.x=1"])).1;
    assert!(stderr.contains("`time.end` is a value"), "{stderr}");
}

#[test]
fn set_radius_over_a_size_ratio_says_how() {
    let out = validate(&["--set", "cloud.radius=1e-4"]);
    let stderr = text(&out).1;
    assert!(!out.status.success());
    assert!(
        stderr.contains("--set cloud.radius=R --set cloud.size_ratio=null"),
        "{stderr}"
    );
    // And what it says works.
    let out = validate(&[
        "--set",
        "cloud.radius=1e-4",
        "--set",
        "cloud.size_ratio=null",
    ]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("b0 = 1e-4 m"), "{stdout}");
}

#[test]
fn validate_takes_set_and_seed() {
    let out = validate(&["--set", "time.end=2e-3", "--seed", "42"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("quick_demo (time.end=2e-3): valid")
            && stdout.contains("T = 2e-3 s")
            && stdout.contains("seed 42"),
        "{stdout}"
    );
    // A bad override is refused as `run` refuses it, naming the field and the range.
    let out = validate(&["--set", "time.end=-1"]);
    let stderr = text(&out).1;
    assert!(!out.status.success());
    assert!(stderr.contains("time.end"), "{stderr}");
}

/// 9e-3 s as a program may compute it (9 × 1e-3) prints as 9e-3.
#[test]
fn times_print_as_a_person_reads_them() {
    assert_ne!(9.0 * 1e-3, 9e-3, "the test needs an inexact time");
    let end = format!("time.end={:e}", 9.0 * 1e-3);
    assert_eq!(end, "time.end=9.000000000000001e-3");
    let out = validate(&["--set", &end]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    // (The scenario's name keeps the setting as typed.)
    assert!(stdout.contains(", T = 9e-3 s,"), "{stdout}");
    assert!(!stdout.contains("T = 9.0"), "{stdout}");
}

#[test]
fn the_licences_and_the_citation_ship() {
    let read =
        |f: &str| std::fs::read_to_string(root().join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
    let cargo = read("Cargo.toml");
    assert!(cargo.contains(r#"license = "MIT OR Apache-2.0""#));
    let mit = read("LICENSE-MIT");
    assert!(mit.starts_with("MIT License") && mit.contains("the agglo developers"));
    let apache = read("LICENSE-APACHE");
    assert!(apache.contains("Apache License") && apache.contains("Version 2.0"));
    let cff = read("CITATION.cff");
    for needed in [
        "cff-version: 1.2.0",
        "title: \"agglo",
        "A computational framework for agglomeration",
        "10.1098/rspa.2004.1277",
        "Large-scale statistical inverse computation of inelastic accretion",
        "Zohdi",
    ] {
        assert!(cff.contains(needed), "CITATION.cff lacks {needed}");
    }
}

/// Every subcommand the parser knows, but the hidden ones and `help`.
fn subcommands() -> Vec<String> {
    agglo::cli_args::command()
        .get_subcommands()
        .filter(|s| !s.is_hide_set())
        .map(|s| s.get_name().to_string())
        .collect()
}

#[test]
fn completions_and_the_man_page_generate_and_name_every_subcommand() {
    let names = subcommands();
    assert!(
        names.len() >= 10 && names.iter().any(|n| n == "run"),
        "{names:?}"
    );
    for shell in ["bash", "zsh", "fish"] {
        let out = agglo().args(["completions", shell]).output().unwrap();
        assert!(out.status.success(), "{shell}");
        let script = String::from_utf8(out.stdout).unwrap();
        for name in &names {
            assert!(
                script.contains(name.as_str()),
                "{shell} completions lack {name}"
            );
        }
        // Flags of a subcommand are completed too.
        assert!(script.contains("live-wait"), "{shell}");
    }
    let out = agglo().arg("man").output().unwrap();
    assert!(out.status.success());
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(
        page.starts_with(".ie") || page.contains(".TH agglo 1"),
        "roff"
    );
    assert!(page.contains(".TH agglo 1"));
    for name in &names {
        assert!(
            page.contains(&format!(".SH \"AGGLO {}\"", name.to_uppercase())),
            "the man page has no section for {name}"
        );
    }
    // A subcommand's flags with their help.
    assert!(page.contains("\\-\\-resume"), "run's flags");
    let bad = agglo().args(["completions", "tcsh"]).output().unwrap();
    assert!(!bad.status.success());
    assert!(
        text(&bad).1.contains("bash"),
        "the allowed shells are named"
    );
}

/// A run that reached its end time has nothing to resume, and says so; one stopped on the
/// way (here by `time.max_steps`) names the command that continues it. Both print their
/// times as a person reads them.
#[test]
fn only_an_unfinished_run_says_continue_with_resume() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        agglo()
            .current_dir(dir.path())
            .args(["run", &quick_demo(), "--set", "output.restart.every=1e-3"])
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--restart", "done.restart"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("3 checkpoints written to done.restart (the last at t = 3e-3 s")
            && stdout.contains("nothing to resume"),
        "{stdout}"
    );
    assert!(!stdout.contains("--resume"), "{stdout}");
    assert!(stdout.contains("): t = 4e-3 s in "), "{stdout}");

    // quick_demo reaches T = 4e-3 s in 1518 steps; 1200 pass two checkpoints.
    let out = run(&["--restart", "cut.restart", "--set", "time.max_steps=1200"]);
    let (stdout, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stdout.contains("2 checkpoints written to cut.restart")
            && stdout.contains("continue with `agglo run --resume cut.restart`"),
        "{stdout}"
    );
    assert!(stderr.contains("of 4e-3 s"), "{stderr}");
}

/// Second first day (issue 42, item 5): a setting of where outputs go leaves the
/// scenario's name (and so the restart file's) alone; `validate` prints b0 to every digit
/// (starting from a table needs it to ~1e-9) and says the fixed part of its memory
/// figure; `study readings --list` needs no `--out`.
#[test]
fn output_settings_keep_the_name_and_validate_prints_what_a_table_needs() {
    let base = Scenario::load(&root().join("scenarios/quick_demo.json")).unwrap();
    let set = base
        .with_settings(&["output.restart.every=1e-3".into()])
        .unwrap();
    assert_eq!(set.name, base.name);
    assert_eq!(set.file_stem(), "quick_demo");
    // A physics setting still names the variant.
    let physics = base.with_settings(&["time.end=2e-3".into()]).unwrap();
    assert!(physics.name.contains("time.end=2e-3"), "{}", physics.name);

    let out = validate(&[]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let b0: f64 = stdout
        .split("b0 = ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no b0 in {stdout}"));
    assert_eq!(b0, base.primary_radius(), "b0 to every digit: {stdout}");
    assert!(stdout.contains("MB fixed + "), "{stdout}");

    let list = agglo()
        .args(["study", "readings", &quick_demo(), "--list"])
        .output()
        .unwrap();
    let (stdout, stderr) = text(&list);
    assert!(list.status.success(), "{stderr}");
    assert!(stdout.starts_with("baseline"), "{stdout}");
}
