//! The built-in physics is made of plugins an extension could have written: built here,
//! outside the crate, plugin by plugin through the public API, the default pipeline
//! gives the same run as `Simulation::new`, to the byte.

use std::path::Path;

use agglo::prelude::*;
use agglo::systems::{
    ContactPlugin, CoolingPlugin, DiagnosticsPlugin, FragmentPlugin, ImpactPlugin, MergePlugin,
    MotionPlugin,
};

fn shipped(name: &str) -> Scenario {
    Scenario::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(name),
    )
    .unwrap()
}

/// The summary as JSON, without the one figure that is not a result (the wall time).
fn summary_json(sim: &Simulation) -> String {
    let mut summary = sim.summary();
    summary.wall_seconds = 0.0;
    serde_json::to_string(&summary).unwrap()
}

fn plugin_by_plugin(scenario: &Scenario) -> Simulation {
    let mut builder = Simulation::builder(scenario).unwrap();
    builder
        .add_plugin(&ContactPlugin)
        .add_plugin(&ImpactPlugin)
        .add_plugin(&MergePlugin)
        .add_plugin(&FragmentPlugin)
        .add_plugin(&CoolingPlugin)
        .add_plugin(&MotionPlugin)
        .add_plugin(&DiagnosticsPlugin);
    builder.build().unwrap()
}

fn same_run_both_ways(name: &str) {
    let scenario = shipped(name);
    let mut built_in = Simulation::new(&scenario).unwrap();
    let mut by_hand = plugin_by_plugin(&scenario);
    assert_eq!(
        built_in.pipeline(),
        by_hand.pipeline(),
        "{name}: pipelines differ"
    );
    built_in.run().unwrap();
    by_hand.run().unwrap();
    assert!(built_in.counters().impacts > 0, "{name}: nothing happened");
    assert_eq!(summary_json(&built_in), summary_json(&by_hand), "{name}");
    assert_eq!(
        built_in.bodies(),
        by_hand.bodies(),
        "{name}: final states differ"
    );
}

#[test]
fn paper2004_best_plugin_by_plugin_equals_the_default_pipeline() {
    same_run_both_ways("paper2004_best.json");
}

#[test]
fn paper2002_best_plugin_by_plugin_equals_the_default_pipeline() {
    same_run_both_ways("paper2002_best.json");
}
