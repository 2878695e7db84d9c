//! Unit tests of `output::step_tables::impact_speeds` (src/output/step_tables/impact_speeds.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::output::step_tables::impact_speeds::*;
use agglo::output::table::read_table;
use agglo::run::{Run, RunPlan, Until};
use agglo::scenario::Scenario;

#[test]
fn a_speed_lands_between_its_bins_edges() {
    // Edges themselves, and speeds just either side of them, over 20 decades.
    for k in -50..50 {
        let edge = lower_edge(k);
        assert_eq!(bin_of(edge), k, "edge {edge}");
        assert_eq!(bin_of(edge * (1.0 + 1e-12)), k);
        assert_eq!(bin_of(edge * (1.0 - 1e-12)), k - 1);
    }
    assert_eq!(bin_of(1.0), 0);
    assert_eq!(bin_of(10.0), 5);
    assert_eq!(bin_of(0.5), -2); // 10^(-2/5) = 0.398 ≤ 0.5 < 10^(-1/5) = 0.631
}

/// The histogram is the collision log's speeds binned step by step: an independent
/// reading of the same impacts (the log writes every impact's speed as it is).
#[test]
fn the_histogram_bins_the_collision_logs_speeds() {
    let text = std::fs::read_to_string("scenarios/quick_demo.json").unwrap();
    let scenario = Scenario::from_json(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (speeds, log) = (dir.path().join("s.csv"), dir.path().join("c.csv"));
    let mut plan = RunPlan::new(scenario).unwrap();
    plan.set_table("impact_speeds", speeds.clone()).unwrap();
    plan.set_table("collisions", log.clone()).unwrap();
    let mut run = Run::start(plan, Default::default()).unwrap();
    let outcome = run.advance(Until::End, &mut |_| std::ops::ControlFlow::Continue(()));
    let end = run.finish(&outcome);
    assert!(outcome.is_ok() && end.output_error.is_none());

    // Over the run, bin by bin: the log's speeds binned here give the same counts.
    let log = read_table(&log).unwrap();
    let mut expected = std::collections::BTreeMap::<i64, i64>::new();
    for v in log.floats("normal_speed").unwrap() {
        *expected.entry(bin_of(v)).or_default() += 1;
    }
    let table = read_table(&speeds).unwrap();
    let (step, bin, count) = (
        table.ints("step").unwrap(),
        table.ints("bin").unwrap(),
        table.ints("count").unwrap(),
    );
    let mut got = std::collections::BTreeMap::<i64, i64>::new();
    for i in 0..table.len() {
        *got.entry(bin[i]).or_default() += count[i];
        // Step by step, each bin once, in order.
        if i > 0 {
            assert!((step[i - 1], bin[i - 1]) < (step[i], bin[i]), "row {i}");
        }
    }
    // Enough impacts, over several bins, that an off-by-one bin or a lost step shows.
    let impacts = end.summary.counters.impacts;
    assert!(impacts > 100 && got.len() > 2, "{impacts} impacts, {got:?}");
    assert_eq!(count.iter().sum::<i64>() as u64, impacts);
    assert_eq!(got, expected);
    let (lower, upper) = (
        table.floats("lower").unwrap(),
        table.floats("upper").unwrap(),
    );
    for i in 0..table.len() {
        assert_eq!(
            (lower[i], upper[i]),
            (lower_edge(bin[i]), lower_edge(bin[i] + 1))
        );
    }
}
