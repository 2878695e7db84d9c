//! The tables a run writes (`--series`, `--sizes`, `--snapshots`): read back in both
//! formats with the crate's own reader and checked against the simulation itself.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use agglo::output::table::{Table, read_table};
use agglo::output::{RunTables, SampleSchedule, TablePaths};
use agglo::prelude::*;
use serde_json::json;

use crate::common::scenario;

/// A small merging cloud on the event core with cooling (so the event core's lazy
/// bodies and its pending cooling loss are exercised), no fragmentation.
fn merging_cloud() -> Scenario {
    scenario(json!({
        "box": { "half_width": 0.005 },
        "cloud": { "count": 200, "radius": null, "size_ratio": 0.6, "v_mean": [0, 0, 0], "v_rel": [40, 40, 40] },
        "material": { "rho": 3000, "H0": 2e5, "C": 1000, "Q": 300, "alpha": 1e3,
                      "epsilon": 0.5, "theta0": 400, "theta_s": 300 },
        "impact": { "a0": 0.1, "af": 1.0, "beta": 1.0 },
        "time": { "end": 0.002 }
    }))
}

fn paths(dir: &Path, ext: &str, sampling: SampleSchedule) -> TablePaths {
    TablePaths {
        series: Some(dir.join(format!("series.{ext}"))),
        sizes: Some(dir.join(format!("sizes.{ext}"))),
        snapshots: Some(dir.join(format!("snapshots.{ext}"))),
        collisions: None,
        sampling: Some(sampling),
    }
}

/// What the observer saw after each sampled step: (t, bodies sorted by id).
type Seen = Vec<(f64, Vec<BodyState>)>;

/// Run `s` writing the tables to `paths`, and keep the bodies at every step whose
/// number is a multiple of `every` (and at t = 0 and the end), read independently.
fn run_and_watch(s: &Scenario, paths: &TablePaths, every: u64) -> (Seen, Summary) {
    let mut sim = Simulation::new(s).unwrap();
    let mut seen = vec![(0.0, sim.bodies())];
    let mut tables = RunTables::open(paths, s, &sim).unwrap().unwrap();
    sim.run_with(|sim| {
        tables.observe(sim).unwrap();
        let c = sim.clock();
        if c.step % every == 0 {
            seen.push((c.time, sim.bodies()));
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    let end = sim.clock().time;
    if seen.last().unwrap().0 < end {
        seen.push((end, sim.bodies()));
    }
    tables.finish(&sim).unwrap();
    (seen, sim.summary())
}

fn f(t: &Table, name: &str) -> Vec<f64> {
    t.floats(name).unwrap()
}

#[test]
fn series_rows_are_the_bodies_at_the_sample_times_in_csv_and_parquet() {
    let s = merging_cloud();
    assert!(
        s.uses_event_core(),
        "the test is meant for the lazy event core"
    );
    let dir = tempfile::tempdir().unwrap();
    let every = 25;
    let (seen, summary) = run_and_watch(
        &s,
        &paths(dir.path(), "csv", SampleSchedule::Steps { every }),
        every,
    );
    run_and_watch(
        &s,
        &paths(dir.path(), "parquet", SampleSchedule::Steps { every }),
        every,
    );
    let csv = read_table(&dir.path().join("series.csv")).unwrap();
    let parquet = read_table(&dir.path().join("series.parquet")).unwrap();
    // Both formats keep every f64 bit (CSV prints shortest round-trip floats).
    assert_eq!(csv, parquet);
    assert_eq!(
        csv.len(),
        seen.len(),
        "one row per sample, t = 0 and the end included"
    );
    assert!(
        summary.counters.bonds > 5,
        "the cloud must merge: {:?}",
        summary.counters
    );
    let c = summary.counters;
    for (row, (t, bodies)) in seen.iter().enumerate() {
        assert_eq!(f(&csv, "t")[row], *t);
        assert_eq!(csv.ints("bodies").unwrap()[row], bodies.len() as i64);
        // Same bodies, same summation order (by id): equal to the bit.
        let ke: f64 = bodies
            .iter()
            .map(|b| 0.5 * b.mass * b.velocity.length_squared())
            .sum();
        assert_eq!(f(&csv, "kinetic_energy")[row], ke);
        let m2: f64 = bodies.iter().map(|b| b.mass * b.mass).sum();
        assert_eq!(f(&csv, "m2")[row], m2);
        let max_theta = bodies
            .iter()
            .map(|b| b.temperature)
            .fold(f64::MIN, f64::max);
        assert_eq!(f(&csv, "max_temperature")[row], max_theta);
    }
    let last = csv.len() - 1;
    assert_eq!(csv.ints("bonds").unwrap()[last], c.bonds as i64);
    assert_eq!(csv.ints("impacts").unwrap()[last], c.impacts as i64);
    // Without fragmentation each merge removes one body.
    let merges = csv.ints("merges").unwrap();
    assert_eq!(
        merges[last],
        (summary.initial_bodies - summary.final_bodies) as i64
    );
    assert_eq!(f(&csv, "kinetic_energy")[last], summary.kinetic_energy);
    assert_eq!(f(&csv, "thermal_energy")[last], summary.thermal_energy);
    // At the end the series adds the heat each body lost since it was last touched, which
    // the ledger books as one sum when the run brings every body to T: the same terms,
    // grouped differently (200 terms: a few ulps).
    let (series_loss, ledger_loss) = (f(&csv, "cooling_loss")[last], summary.energy.cooling_loss);
    assert!(
        (series_loss - ledger_loss).abs() <= 1e-13 * ledger_loss,
        "{series_loss} vs {ledger_loss}"
    );
    assert!(summary.energy.cooling_loss > 0.0, "the scene must cool");
}

#[test]
fn series_energy_closes_at_every_sample_with_the_pending_cooling_loss() {
    // On the event core the ledger books a body's cooling only when the body is next
    // touched; the series adds the heat lost since, so E + L − R is the same at every
    // sample (no fragmentation, forces or external heat here).
    let s = merging_cloud();
    let dir = tempfile::tempdir().unwrap();
    run_and_watch(
        &s,
        &paths(dir.path(), "csv", SampleSchedule::Interval { dt: 1e-4 }),
        1_000_000,
    );
    let t = read_table(&dir.path().join("series.csv")).unwrap();
    let (ke, th, loss, heat) = (
        f(&t, "kinetic_energy"),
        f(&t, "thermal_energy"),
        f(&t, "cooling_loss"),
        f(&t, "reaction_heat"),
    );
    let e0 = ke[0] + th[0];
    let mut lagging = 0;
    for k in 0..t.len() {
        let closed = ke[k] + th[k] + loss[k] - heat[k];
        // Rounding over ~1e3 impacts of energies ~e0: 1e-9 relative is far above it.
        assert!(
            (closed - e0).abs() < 1e-9 * (e0 + heat[k] + loss[k]),
            "sample {k}: {closed} vs {e0}"
        );
        lagging += usize::from(loss[k] > 0.0);
    }
    assert!(lagging > 3, "cooling must show in the samples");
    assert_eq!(t.len(), 21, "t = 0, then every 1e-4 s to T = 2e-3 s");
}

#[test]
fn series_ledgers_close_at_every_sample_in_a_field() {
    // Under uniform g on the event core each body gains kinetic energy and momentum as it
    // flies, booked only when it is next touched: the series adds the field's pending
    // work and impulse, so E − W_forces + L − R and P − J_forces stay put at every sample.
    let mut s = merging_cloud();
    s.field = agglo::scenario::Field {
        gravity: [0.0, -3e3, -1e4],
        drag: None,
    };
    let dir = tempfile::tempdir().unwrap();
    run_and_watch(
        &s,
        &paths(dir.path(), "csv", SampleSchedule::Interval { dt: 1e-4 }),
        1_000_000,
    );
    let t = read_table(&dir.path().join("series.csv")).unwrap();
    let (ke, th, loss, heat, work) = (
        f(&t, "kinetic_energy"),
        f(&t, "thermal_energy"),
        f(&t, "cooling_loss"),
        f(&t, "reaction_heat"),
        f(&t, "force_work"),
    );
    let (pz, jz) = (f(&t, "momentum_z"), f(&t, "force_impulse_z"));
    let e0 = ke[0] + th[0];
    for k in 0..t.len() {
        let closed = ke[k] + th[k] + loss[k] - heat[k] - work[k];
        // Rounding over ~1e3 impacts of energies ~e0 and the work: 1e-9 relative.
        let scale = e0 + heat[k] + loss[k] + work[k].abs();
        assert!(
            (closed - e0).abs() < 1e-9 * scale,
            "sample {k}: {closed} vs {e0}"
        );
        let p = pz[k] - jz[k];
        assert!(
            (p - pz[0]).abs() < 1e-9 * jz[k].abs().max(1e-30),
            "sample {k}: P_z − J_z"
        );
    }
    assert!(work[t.len() - 1] > 0.1 * ke[0], "the field must do work");
}

#[test]
fn sizes_count_every_body_and_conserve_the_primaries() {
    let s = merging_cloud();
    let dir = tempfile::tempdir().unwrap();
    let (seen, _) = run_and_watch(
        &s,
        &paths(dir.path(), "parquet", SampleSchedule::Steps { every: 40 }),
        40,
    );
    let sizes = read_table(&dir.path().join("sizes.parquet")).unwrap();
    let csv_dir = tempfile::tempdir().unwrap();
    run_and_watch(
        &s,
        &paths(csv_dir.path(), "csv", SampleSchedule::Steps { every: 40 }),
        40,
    );
    assert_eq!(
        sizes,
        read_table(&csv_dir.path().join("sizes.csv")).unwrap()
    );
    // No fragmentation and a start of single primaries: binned by monomer count.
    assert!(sizes.texts("by").unwrap().iter().all(|b| b == "primaries"));
    let (ts, bins, counts) = (
        f(&sizes, "t"),
        sizes.ints("bin").unwrap(),
        sizes.ints("count").unwrap(),
    );
    for (t, bodies) in &seen {
        let rows: Vec<usize> = (0..ts.len()).filter(|&k| ts[k] == *t).collect();
        let n: i64 = rows.iter().map(|&k| counts[k]).sum();
        let primaries: i64 = rows.iter().map(|&k| bins[k] * counts[k]).sum();
        assert_eq!(n, bodies.len() as i64, "t = {t}");
        assert_eq!(primaries, 200, "t = {t}: Σ k n_k = N0");
        for &k in &rows {
            let expected = bodies
                .iter()
                .filter(|b| b.primaries.round() as i64 == bins[k])
                .count();
            assert_eq!(counts[k], expected as i64);
        }
    }
}

#[test]
fn snapshots_hold_every_body_and_end_with_the_final_state() {
    let s = merging_cloud();
    let dir = tempfile::tempdir().unwrap();
    let (seen, _) = run_and_watch(
        &s,
        &paths(dir.path(), "parquet", SampleSchedule::Steps { every: 100 }),
        100,
    );
    let snap = read_table(&dir.path().join("snapshots.parquet")).unwrap();
    let csv_dir = tempfile::tempdir().unwrap();
    run_and_watch(
        &s,
        &paths(csv_dir.path(), "csv", SampleSchedule::Steps { every: 100 }),
        100,
    );
    assert_eq!(
        snap,
        read_table(&csv_dir.path().join("snapshots.csv")).unwrap()
    );
    let total: usize = seen.iter().map(|(_, b)| b.len()).sum();
    assert_eq!(snap.len(), total);
    let (ids, x, vz, th) = (
        snap.ints("id").unwrap(),
        f(&snap, "x"),
        f(&snap, "vz"),
        f(&snap, "temperature"),
    );
    let mut row = 0;
    for (_, bodies) in &seen {
        for b in bodies {
            assert_eq!(ids[row], b.id as i64);
            assert_eq!(x[row], b.position.x);
            assert_eq!(vz[row], b.velocity.z);
            assert_eq!(th[row], b.temperature);
            row += 1;
        }
    }
}

fn agglo(args: &[&str], dir: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

#[test]
fn agglo_run_writes_the_tables_the_flags_and_the_scenario_name() {
    let dir = tempfile::tempdir().unwrap();
    let scene: PathBuf = dir.path().join("scene.json");
    let mut s = merging_cloud();
    s.output.sizes = Some("from_scenario.csv".into());
    std::fs::write(&scene, s.to_json()).unwrap();
    let out = agglo(
        &[
            "run",
            "scene.json",
            "-q",
            "--series",
            "s.parquet",
            "--sample-log",
            "4",
            "--final-state",
            "final.csv",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let series = read_table(&dir.path().join("s.parquet")).unwrap();
    let t = f(&series, "t");
    // Log-spaced from T/1e4 = 2e-7 s to T = 2e-3 s at 4 per decade: t = 0, then at most
    // 17 scheduled times (fewer when one step passes two of them), and T.
    assert!(t.len() > 8 && t.len() <= 19, "{t:?}");
    assert!(t.windows(2).all(|w| w[1] > w[0]));
    assert_eq!(*t.last().unwrap(), 0.002);
    assert!(
        dir.path().join("from_scenario.csv").exists(),
        "output.sizes is honoured"
    );
    // The last sample is the final state.
    let final_state = read_table(&dir.path().join("final.csv")).unwrap();
    let last = series.len() - 1;
    assert_eq!(
        series.ints("bodies").unwrap()[last],
        final_state.len() as i64
    );
    let mass: f64 = f(&final_state, "mass").iter().sum();
    assert_eq!(f(&series, "mass")[last], mass);

    let bad = agglo(
        &[
            "run",
            "scene.json",
            "-q",
            "--series",
            "s.csv",
            "--sample-every=-1",
        ],
        dir.path(),
    );
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("interval.dt") && err.contains("> 0"), "{err}");
}

/// Keys of a JSON object, nested keys joined with `.` (arrays are values).
fn keys(v: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    if let serde_json::Value::Object(map) = v {
        for (k, v) in map {
            let name = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            if v.is_object() {
                keys(v, &name, out);
            } else {
                out.push(name);
            }
        }
    }
}

#[test]
fn every_summary_key_is_documented_and_every_documented_key_exists() {
    use agglo::output::schema::SUMMARY_KEYS;
    let mut seen = Vec::new();
    // The event core's summary has `events`; the stepped core's does not.
    for core in ["events", "stepped"] {
        let mut s = merging_cloud();
        s.time.core = serde_json::from_value(json!(core)).unwrap();
        if core == "stepped" {
            s.time.end = 2e-4;
        }
        let mut sim = Simulation::new(&s).unwrap();
        sim.run().unwrap();
        keys(&serde_json::to_value(sim.summary()).unwrap(), "", &mut seen);
    }
    // A rigid scene's summary has `aggregates` (docs/model.md §6.1): sticky primaries.
    let mut s = merging_cloud();
    s.material.H0 = 1e-6;
    s.material.gamma = None;
    s.physics.merge_mode = agglo::scene::MergeMode::Rigid;
    // Stopped while several aggregates of k ≥ 2 remain (the fit needs two).
    s.time.end = 2e-4;
    let mut sim = Simulation::new(&s).unwrap();
    sim.run().unwrap();
    keys(&serde_json::to_value(sim.summary()).unwrap(), "", &mut seen);
    for k in &seen {
        assert!(
            SUMMARY_KEYS.iter().any(|d| d.name == k),
            "summary key `{k}` is not documented"
        );
    }
    for d in SUMMARY_KEYS {
        assert!(
            seen.iter().any(|k| k == d.name),
            "documented key `{}` is not in a summary",
            d.name
        );
    }
}

#[test]
fn docs_outputs_md_is_what_agglo_schema_outputs_prints() {
    let docs =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/outputs.md"))
            .unwrap();
    let printed = agglo(
        &["schema", "--outputs"],
        Path::new(env!("CARGO_MANIFEST_DIR")),
    );
    assert!(printed.status.success());
    assert_eq!(
        docs,
        String::from_utf8(printed.stdout).unwrap(),
        "regenerate: agglo schema --outputs > docs/outputs.md"
    );
}

#[test]
fn run_set_overrides_fields_and_is_checked_like_the_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.json"), merging_cloud().to_json()).unwrap();
    let out = agglo(
        &[
            "run",
            "scene.json",
            "-q",
            "--set",
            "time.end=1e-4",
            "--set",
            "cloud.count=50",
            "--summary",
            "s.json",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(summary["time"], json!(1e-4));
    assert_eq!(summary["initial_bodies"], json!(50));
    let bad = agglo(
        &["run", "scene.json", "-q", "--set", "material.rho=-1"],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("material.rho") && err.contains("> 0"),
        "{err}"
    );
    let typo = agglo(
        &["run", "scene.json", "-q", "--set", "time.ned=1"],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&typo.stderr);
    assert!(!typo.status.success() && err.contains("ned"), "{err}");
}

/// Run `s` through the door of every run with only the collision log, at `path`; the
/// summary.
fn run_logging_collisions(s: &Scenario, path: &Path) -> Summary {
    let mut plan = agglo::run::RunPlan::unwritten(s.clone());
    plan.tables.collisions = Some(path.to_path_buf());
    let (end, outcome) = agglo::run::Run::complete(plan, Vec::new()).unwrap();
    outcome.unwrap();
    assert!(end.output_error.is_none(), "{:?}", end.output_error);
    end.summary
}

#[test]
fn collision_log_has_one_row_per_impact_and_its_heat_is_the_ledgers() {
    let s = merging_cloud();
    let dir = tempfile::tempdir().unwrap();
    let summary = run_logging_collisions(&s, &dir.path().join("c.parquet"));
    run_logging_collisions(&s, &dir.path().join("c.csv"));
    let log = read_table(&dir.path().join("c.parquet")).unwrap();
    assert_eq!(log, read_table(&dir.path().join("c.csv")).unwrap());
    let c = summary.counters;
    assert_eq!(log.len() as u64, c.impacts);
    let outcome = log.texts("outcome").unwrap();
    let count = |o: &str| outcome.iter().filter(|x| *x == o).count() as u64;
    // No fragmentation in this scene: every row is a bounce or a bond, as counted.
    assert_eq!(
        (count("bounce"), count("bond"), count("fragment")),
        (c.bounces, c.bonds, 0)
    );
    let heat: f64 = f(&log, "heat").iter().sum();
    let e = summary.energy;
    let booked = e.impact_dissipation + e.reaction_heat + e.double_counted_heat;
    // The same terms summed in another grouping: rounding only.
    assert!(
        (heat - booked).abs() <= 1e-12 * booked,
        "{heat} vs {booked}"
    );
    let (a, b, t) = (
        log.ints("id_a").unwrap(),
        log.ints("id_b").unwrap(),
        f(&log, "t"),
    );
    assert!(a.iter().zip(&b).all(|(a, b)| a < b), "id_a < id_b");
    assert!(t.windows(2).all(|w| w[0] <= w[1]), "in time order");
    assert!(f(&log, "normal_speed").iter().all(|&v| v > 0.0));
    let e_bond: Vec<f64> = f(&log, "restitution");
    for (k, o) in outcome.iter().enumerate() {
        assert_eq!(o == "bond", e_bond[k] == 0.0, "row {k}: a bond has e = 0");
    }
}

#[test]
fn collision_log_marks_impacts_whose_bodies_fragmented() {
    let s =
        Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = run_logging_collisions(&s, &dir.path().join("c.csv"));
    let log = read_table(&dir.path().join("c.csv")).unwrap();
    let c = summary.counters;
    assert!(c.fragmentations > 0, "quick_demo fragments");
    let outcome = log.texts("outcome").unwrap();
    let fragments = outcome.iter().filter(|o| *o == "fragment").count() as u64;
    // Each fragmentation follows an impact of its step; an impact can break both bodies.
    assert!(
        fragments > 0 && fragments <= c.fragmentations,
        "{fragments} vs {c:?}"
    );
    let bounces = outcome.iter().filter(|o| *o == "bounce").count() as u64;
    let bonds = outcome.iter().filter(|o| *o == "bond").count() as u64;
    assert_eq!(bounces + bonds + fragments, c.impacts);
    assert!(bounces <= c.bounces && bonds <= c.bonds);
}

/// `Simulation::body_columns` (the Python module's bodies) holds what `bodies()` reads,
/// field by field, in id order — after merges and fragments have reordered the world.
#[test]
fn body_columns_are_the_bodies_as_columns() {
    for core in ["events", "stepped"] {
        let text = std::fs::read_to_string("scenarios/quick_demo.json").unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        crate::common::merge(&mut v, serde_json::json!({ "time": { "core": core } }));
        let s = agglo::prelude::Scenario::from_value(v).unwrap();
        let mut sim = agglo::prelude::Simulation::new(&s).unwrap();
        for _ in 0..300 {
            sim.step().unwrap();
        }
        assert!(
            sim.counters().fragmentations > 0 && sim.counters().bonds > 0,
            "{core}"
        );
        let rows = sim.bodies();
        let columns = sim.body_columns();
        let mut from_rows = agglo::components::BodyColumns::with_capacity(rows.len());
        for b in &rows {
            from_rows.push(b);
        }
        assert_eq!(columns, from_rows, "{core}");
    }
}
