//! Per-body extension state through merges and fragmentations (engine/carried.rs): a
//! charge-like component (extensive, split by mass) keeps its total to rounding, a label
//! combined by max is copied into pieces, and `--final-state` writes both as named
//! columns after the built-in ones.

use std::path::Path;

use agglo::bevy_ecs::prelude::*;
use agglo::carried::{Carried, Combine, Split};
use agglo::output::{FINAL_STATE_HEADER, write_final_state_with};
use agglo::prelude::*;
use serde_json::json;

#[derive(Component, Clone, Copy)]
struct Charge(f64);
impl Carried for Charge {
    fn value(&self) -> f64 {
        self.0
    }
    fn from_value(value: f64) -> Self {
        Charge(value)
    }
}

#[derive(Component, Clone, Copy)]
struct Label(f64);
impl Carried for Label {
    fn value(&self) -> f64 {
        self.0
    }
    fn from_value(value: f64) -> Self {
        Label(value)
    }
}

struct Carry;
impl SimPlugin for Carry {
    fn name(&self) -> &'static str {
        "carry"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.carry::<Charge>("charge", Combine::Sum, Split::ByMass)
            .carry::<Label>("label", Combine::Max, Split::Copy);
        sim.init_each_body(|body| {
            // Charges of both signs and several magnitudes, a label per body.
            let q = 1e-12 * ((body.id as f64 * 0.618_033_988_75).fract() - 0.5);
            (Charge(q), Label(body.id as f64))
        });
    }
}

#[test]
fn carried_quantities_follow_merges_and_fragments() {
    for core in ["events", "stepped"] {
        let text = std::fs::read_to_string(Path::new("scenarios/quick_demo.json")).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        crate::common::merge(&mut v, json!({ "time": { "core": core } }));
        let s = Scenario::from_value(v).unwrap();
        let mut builder = Simulation::builder(&s).unwrap();
        builder.add_default_plugins().add_plugin(&Carry);
        let mut sim = builder.build().unwrap();
        let before = sim.carried();
        assert_eq!(before.names, ["charge", "label"]);
        let total = |c: &agglo::carried::CarriedColumns| -> (f64, f64) {
            c.rows.iter().fold((0.0, 0.0), |(s, a), r| {
                let q = r.1[0].unwrap();
                (s + q, a + q.abs())
            })
        };
        let (q0, scale) = total(&before);
        sim.run().unwrap();
        let c = sim.counters();
        assert!(c.bonds > 0 && c.fragmentations > 0, "{core}: {c:?}");
        let after = sim.carried();
        assert_eq!(after.rows.len(), sim.body_count());
        let (q1, _) = total(&after);
        // Sums and equal splits: only rounding, ~1e-16 of the charge moved per event.
        assert!((q1 - q0).abs() <= 1e-12 * scale, "{core}: {q0:e} → {q1:e}");
        // The largest label survives every merge (max) and every split (copy).
        let max_label = |c: &agglo::carried::CarriedColumns| {
            c.rows
                .iter()
                .map(|r| r.1[1].unwrap())
                .fold(f64::MIN, f64::max)
        };
        assert_eq!(max_label(&after), max_label(&before));
        // Every body has both, pieces included.
        assert!(after.rows.iter().all(|r| r.1.iter().all(Option::is_some)));
        // The whole cloud's charge, as the recording's /stats carries it.
        let totals = sim.carried_totals();
        assert_eq!(totals[0].0, "charge");
        assert!((totals[0].1 - q1).abs() <= 1e-12 * scale);

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("final.csv");
        write_final_state_with(&path, &sim.bodies(), &after).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            format!("{FINAL_STATE_HEADER},charge,label")
        );
        let first = lines.next().unwrap();
        assert_eq!(first.split(',').count(), 14, "{first}");
        let q: f64 = first.split(',').nth(12).unwrap().parse().unwrap();
        assert_eq!(q, after.rows[0].1[0].unwrap()); // round-trips exactly
    }
}

#[test]
fn the_combine_and_split_rules() {
    assert_eq!(Combine::Sum.combine(1.0, 2.0, 3.0, 6.0), 4.0);
    assert_eq!(Combine::MassWeighted.combine(1.0, 2.0, 3.0, 6.0), 2.5);
    assert_eq!(Combine::Max.combine(1.0, 2.0, 3.0, 6.0), 3.0);
    assert_eq!(Combine::Min.combine(1.0, 2.0, 3.0, 6.0), 1.0);
    assert_eq!(
        Combine::Function(|a, ma, b, mb| a * ma - b * mb).combine(1.0, 2.0, 3.0, 6.0),
        -16.0
    );
    assert_eq!(Split::ByMass.split(6.0, 3), 2.0);
    assert_eq!(Split::Copy.split(6.0, 3), 6.0);
    assert_eq!(Split::Function(|v, p| v - p as f64).split(6.0, 3), 3.0);
}

#[test]
fn snapshots_carry_the_registered_quantities_as_columns() {
    use agglo::output::table::read_table;
    use agglo::output::{RunTables, SampleSchedule, TablePaths};
    let text = std::fs::read_to_string(Path::new("scenarios/quick_demo.json")).unwrap();
    let s = Scenario::from_json(&text).unwrap();
    for ext in ["csv", "parquet"] {
        let dir = tempfile::tempdir().unwrap();
        let snapshots = dir.path().join(format!("snapshots.{ext}"));
        let paths = TablePaths {
            series: None,
            sizes: None,
            snapshots: Some(snapshots.clone()),
            collisions: None,
            sampling: Some(SampleSchedule::Interval { dt: 1e-3 }),
        };
        let mut builder = Simulation::builder(&s).unwrap();
        builder.add_default_plugins().add_plugin(&Carry);
        let mut sim = builder.build().unwrap();
        let mut tables = RunTables::open(&paths, &s, &sim).unwrap().unwrap();
        sim.run_with(|sim| {
            tables.observe(sim).unwrap();
            std::ops::ControlFlow::Continue(())
        })
        .unwrap();
        tables.finish(&sim).unwrap();
        let table = read_table(&snapshots).unwrap();
        let (t, charge) = (table.floats("t").unwrap(), table.floats("charge").unwrap());
        assert!(table.floats("label").is_ok(), "{ext}: a label column");
        // Every sample holds the same total charge (to rounding), and the last sample's
        // values are the simulation's own.
        let scale: f64 = charge.iter().map(|q| q.abs()).sum::<f64>() / 5.0;
        let mut samples: Vec<f64> = t.clone();
        samples.dedup();
        assert!(samples.len() >= 4, "{ext}: {samples:?}");
        let totals: Vec<f64> = samples
            .iter()
            .map(|&ts| {
                t.iter()
                    .zip(&charge)
                    .filter(|(a, _)| **a == ts)
                    .map(|(_, q)| q)
                    .sum()
            })
            .collect();
        for total in &totals {
            assert!(
                (total - totals[0]).abs() <= 1e-12 * scale,
                "{ext}: {totals:?}"
            );
        }
        let last = *samples.last().unwrap();
        let final_charges: Vec<f64> = t
            .iter()
            .zip(&charge)
            .filter(|(a, _)| **a == last)
            .map(|(_, q)| *q)
            .collect();
        let expected: Vec<f64> = sim.carried().rows.iter().map(|r| r.1[0].unwrap()).collect();
        assert_eq!(final_charges, expected, "{ext}");
    }
}

#[test]
fn carried_quantities_survive_checkpoints_and_resume_bit_for_bit() {
    use agglo::restart::RestartSnapshot;
    use std::ops::ControlFlow;
    for core in ["events", "stepped"] {
        let text = std::fs::read_to_string(Path::new("scenarios/quick_demo.json")).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        crate::common::merge(
            &mut v,
            json!({ "time": { "core": core }, "output": { "restart": { "every": 1e-3 } } }),
        );
        let s = Scenario::from_value(v).unwrap();
        let build = || {
            let mut builder = Simulation::builder(&s).unwrap();
            builder.add_default_plugins().add_plugin(&Carry);
            builder.build().unwrap()
        };
        let mut sim = build();
        let mut snapshots = Vec::new();
        sim.run_with(|s| {
            if let Some(snapshot) = s.restart_snapshot() {
                snapshots.push(snapshot.encode());
            }
            ControlFlow::Continue(())
        })
        .unwrap();
        assert_eq!(snapshots.len(), 3, "{core}: checkpoints at 1, 2, 3 ms");
        let end = (format!("{:?}", sim.bodies()), sim.carried());
        assert!(
            end.1
                .rows
                .iter()
                .all(|(_, v)| v.iter().all(Option::is_some))
        );
        for (k, bytes) in snapshots.iter().enumerate() {
            let mut resumed = build();
            resumed
                .resume(&RestartSnapshot::decode(bytes).unwrap())
                .unwrap();
            resumed.run().unwrap();
            assert!(
                format!("{:?}", resumed.bodies()) == end.0,
                "{core}: resumed from snapshot {k}, the bodies differ"
            );
            assert_eq!(
                resumed.carried(),
                end.1,
                "{core}: snapshot {k}, carried values"
            );
        }
    }
}
