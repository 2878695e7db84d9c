//! The walls a plugin can see (issue 29, item 4): whatever stage an extension adds a
//! system to, the build refuses one that would read stale body state on the event core
//! or write the run's books (clock, counters, ledgers) on either core; read-only views
//! (`RunView`) and `Bodies` are accepted, and what a core plugin adds through the
//! core-only trait is not checked.
//!
//! The stage tests build the extension alone (no built-in plugins), so that nothing but
//! the refusal can reject it: next to a built-in system that writes the same component,
//! the schedule's ambiguity check would refuse it first.

use crate::common::scenario;

use agglo::bevy_ecs::prelude::*;
use agglo::components::Position;
use agglo::core_only::SimBuilderCore;
use agglo::prelude::*;
use serde_json::json;

fn on_core(core: &str) -> Scenario {
    scenario(json!({ "time": { "core": core } }))
}

/// Reads positions directly: stale on the event core.
fn peek_positions(bodies: Query<&Position, With<Particle>>, mut seen: Local<f64>) {
    *seen += bodies.iter().map(|p| p.0.x).sum::<f64>();
}

/// `system` added to `stage` by an extension, alone, on `core`: the build's verdict.
fn build_with<M>(
    core: &str,
    stage: StepSystems,
    system: impl IntoScheduleConfigs<agglo::bevy_ecs::system::ScheduleSystem, M>,
) -> Result<Simulation, SimError> {
    let mut builder = Simulation::builder(&on_core(core)).unwrap();
    builder.add_systems(stage, system);
    builder.build()
}

fn assert_stale_read_refused(stage: StepSystems) {
    let error = build_with("events", stage, peek_positions)
        .err()
        .unwrap_or_else(|| panic!("{stage:?}: a direct Position query was accepted"))
        .to_string();
    assert!(error.contains("peek_positions"), "{stage:?}: {error}");
    assert!(error.contains("Position"), "{stage:?}: {error}");
    assert!(error.contains("Bodies"), "{stage:?}: {error}");
    // On the stepped core every body is current at every stage: the query is fine.
    build_with("stepped", stage, peek_positions)
        .unwrap_or_else(|e| panic!("{stage:?}: refused on the stepped core: {e}"));
}

macro_rules! stale_read_refused_in {
    ($($test:ident: $stage:ident,)*) => {
        $(
            #[test]
            fn $test() {
                assert_stale_read_refused(StepSystems::$stage);
            }
        )*
        /// The stages the tests above cover, in the order they are listed.
        const TESTED: &[StepSystems] = &[$(StepSystems::$stage),*];
    };
}

stale_read_refused_in! {
    stale_read_refused_in_first: First,
    stale_read_refused_in_forces_stage: Forces,
    stale_read_refused_in_contact: Contact,
    stale_read_refused_in_impact: Impact,
    stale_read_refused_in_impact_outcome: ImpactOutcome,
    stale_read_refused_in_merge: Merge,
    stale_read_refused_in_fragment: Fragment,
    stale_read_refused_in_time_step: TimeStep,
    stale_read_refused_in_cooling: Cooling,
    stale_read_refused_in_drift: Drift,
    stale_read_refused_in_boundary: Boundary,
    stale_read_refused_in_diagnostics: Diagnostics,
    stale_read_refused_in_last: Last,
}

#[test]
fn every_stage_is_covered_by_a_test() {
    // A stage added to the pipeline without a test here fails this.
    assert_eq!(TESTED, &StepSystems::ORDER[..]);
}

#[test]
fn stale_read_refused_in_force_systems_and_outcome_hooks() {
    let mut builder = Simulation::builder(&on_core("events")).unwrap();
    builder.add_force_systems(peek_positions);
    let error = builder.build().err().expect("refused").to_string();
    assert!(error.contains("peek_positions"), "{error}");
    // The impact-outcome hooks (ImpactOutcomeSystems::Decide), with the impact plugin
    // that applies them.
    let mut builder = Simulation::builder(&on_core("events")).unwrap();
    builder
        .add_plugin(&agglo::systems::ImpactPlugin)
        .add_impact_outcome_systems(peek_positions);
    let error = builder.build().err().expect("refused").to_string();
    assert!(error.contains("peek_positions"), "{error}");
}

fn count_my_own(mut counters: ResMut<Counters>) {
    counters.impacts += 1;
}

fn stop_the_clock(mut clock: ResMut<SimClock>) {
    clock.dt = 0.0;
}

fn heat_unbooked(mut ledger: ResMut<EnergyLedger>) {
    ledger.external_heat += 1.0;
}

#[test]
fn writes_to_the_clock_counters_and_ledger_are_refused_on_both_cores() {
    for core in ["events", "stepped"] {
        for stage in [StepSystems::First, StepSystems::Impact, StepSystems::Last] {
            let counters = build_with(core, stage, count_my_own)
                .err()
                .expect("refused");
            let text = counters.to_string();
            assert!(
                text.contains("count_my_own") && text.contains("Counters"),
                "{text}"
            );
            assert!(text.contains("RunView"), "{text}");
            let clock = build_with(core, stage, stop_the_clock)
                .err()
                .expect("refused");
            assert!(clock.to_string().contains("SimClock"), "{clock}");
            let ledger = build_with(core, stage, heat_unbooked)
                .err()
                .expect("refused");
            assert!(ledger.to_string().contains("EnergyLedger"), "{ledger}");
        }
        let mut builder = Simulation::builder(&on_core(core)).unwrap();
        builder.add_force_systems(count_my_own);
        assert!(
            builder.build().is_err(),
            "{core}: a force system wrote Counters"
        );
    }
}

/// What the reading system saw at each step: (t, step, impacts) from `RunView`, and the
/// body count from `Bodies`, in one system.
#[derive(Resource, Default)]
struct Seen(Vec<(f64, u64, u64, usize)>);

fn read_views(run: RunView, bodies: Bodies, mut seen: ResMut<Seen>) {
    seen.0
        .push((run.now(), run.step(), run.counters().impacts, bodies.len()));
}

#[test]
fn run_view_and_bodies_are_accepted_and_read_the_run() {
    for core in ["events", "stepped"] {
        let s = scenario(json!({
            "time": { "core": core },
            "cloud": { "count": 2, "bodies": [
                { "position": [-0.003, 0, 0], "velocity": [3, 0, 0] },
                { "position": [0.003, 0, 0], "velocity": [-3, 0, 0] }
            ] }
        }));
        let mut builder = Simulation::builder(&s).unwrap();
        builder
            .add_default_plugins()
            .init_resource::<Seen>()
            .add_systems(StepSystems::Last, read_views);
        let mut sim = builder.build().expect("read-only views are accepted");
        let mut step_start = 0.0;
        sim.run_with(|sim| {
            let (t, step, impacts, n) = *sim.world().resource::<Seen>().0.last().unwrap();
            // `Last` runs after the step's events, before the clock advances: the
            // step's start time and number, the counts with this step's impacts.
            let clock = sim.clock();
            assert_eq!(step + 1, clock.step, "{core}");
            assert_eq!(t, step_start, "{core}");
            step_start = clock.time;
            assert_eq!(impacts, sim.counters().impacts, "{core}");
            assert_eq!(n, sim.body_count(), "{core}");
            std::ops::ControlFlow::Continue(())
        })
        .unwrap();
        let seen = &sim.world().resource::<Seen>().0;
        assert_eq!(
            seen.len() as u64,
            sim.clock().step,
            "{core}: one reading a step"
        );
        assert!(sim.counters().impacts >= 1, "{core}: the pair never met");
    }
}

#[test]
fn a_core_plugin_is_not_checked() {
    // The same direct write, added through the core-only trait: the plugin answers for it.
    let mut builder = Simulation::builder(&on_core("events")).unwrap();
    builder.add_core_systems(StepSystems::Impact, (peek_positions, count_my_own));
    builder
        .build()
        .expect("core systems are the core's business");
}

#[derive(Component, Clone, Copy)]
struct Tag(u64);

#[test]
fn init_each_body_gives_every_body_its_component_in_id_order() {
    let s = scenario(json!({ "cloud": { "count": 5 } }));
    let mut builder = Simulation::builder(&s).unwrap();
    let mut order = Vec::new();
    builder.init_each_body(|body| {
        order.push(body.id);
        Tag(body.id * 10)
    });
    let mut sorted = order.clone();
    sorted.sort_unstable();
    assert_eq!(order, sorted, "visited in id order");
    assert_eq!(order.len(), 5);
    let mut sim = builder.build().unwrap();
    let world = sim.world_mut();
    let mut q = world.query::<(&ParticleId, &Tag)>();
    let tags: Vec<(u64, u64)> = q.iter(world).map(|(id, t)| (id.0, t.0)).collect();
    assert_eq!(tags.len(), 5);
    assert!(tags.iter().all(|&(id, t)| t == id * 10), "{tags:?}");
}

#[test]
fn a_plugin_cannot_replace_the_run_state() {
    let mut builder = Simulation::builder(&on_core("events")).unwrap();
    builder.insert_resource(Counters::default());
    let error = builder.build().err().expect("refused").to_string();
    assert!(
        error.contains("insert_resource") && error.contains("Counters"),
        "{error}"
    );
    let mut builder = Simulation::builder(&on_core("stepped")).unwrap();
    builder.init_resource::<SimClock>();
    let error = builder.build().err().expect("refused").to_string();
    assert!(
        error.contains("init_resource") && error.contains("SimClock"),
        "{error}"
    );
    // A resource of its own is the plugin's business.
    let mut builder = Simulation::builder(&on_core("events")).unwrap();
    builder.init_resource::<Seen>();
    builder.build().expect("its own resource");
}
