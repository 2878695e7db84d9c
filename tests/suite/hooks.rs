//! Hooks at contacts, merges and fragments (engine/hooks.rs): a subscriber sees one
//! message per impact, merge and fragmentation — the same numbers the run's counters
//! report — on both cores, both from the driver (`Simulation::step_messages`) and from a
//! system in the `Last` stage (`MessageReader`); subscribing changes nothing in the run.

use std::path::Path;

use agglo::bevy_ecs::prelude::*;
use agglo::hooks::{FragmentMessage, ImpactMessage, ImpactOutcome, MergeMessage, MessageReader};
use agglo::prelude::*;
use serde_json::json;

/// quick_demo (bonding, bouncing, merging and fragmentation in one short run) on the
/// given core.
fn quick_demo(core: &str) -> Scenario {
    let text = std::fs::read_to_string(Path::new("scenarios/quick_demo.json")).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    crate::common::merge(&mut value, json!({ "time": { "core": core } }));
    Scenario::from_value(value).unwrap()
}

/// What a `Last`-stage system read with `MessageReader`s.
#[derive(Resource, Default)]
struct ReadInLast {
    impacts: u64,
    bonds: u64,
    merges: u64,
    fragmentations: u64,
}

fn tally_in_last(
    mut impacts: MessageReader<ImpactMessage>,
    mut merges: MessageReader<MergeMessage>,
    mut fragments: MessageReader<FragmentMessage>,
    mut seen: ResMut<ReadInLast>,
) {
    for m in impacts.read() {
        seen.impacts += 1;
        seen.bonds += u64::from(m.outcome == ImpactOutcome::Bond);
    }
    seen.merges += merges.read().count() as u64;
    seen.fragmentations += fragments.read().count() as u64;
}

struct Listen;
impl SimPlugin for Listen {
    fn name(&self) -> &'static str {
        "listen"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.subscribe::<ImpactMessage>()
            .subscribe::<MergeMessage>()
            .subscribe::<FragmentMessage>()
            .subscribe::<ImpactMessage>() // twice is once
            .init_resource::<ReadInLast>()
            .add_systems(StepSystems::Last, tally_in_last);
    }
}

#[test]
fn messages_match_the_counters_on_both_cores() {
    for core in ["events", "stepped"] {
        let s = quick_demo(core);
        let mut plain = Simulation::new(&s).unwrap();
        plain.run().unwrap();

        let mut builder = Simulation::builder(&s).unwrap();
        builder.add_default_plugins().add_plugin(&Listen);
        let mut sim = builder.build().unwrap();
        assert_eq!(
            sim.pipeline().core,
            if core == "events" { "event" } else { "stepped" }
        );
        let (mut impacts, mut merges, mut fragments) = (Vec::new(), Vec::new(), Vec::new());
        sim.run_with(|sim| {
            let now = sim.clock().time;
            impacts.extend(sim.step_messages::<ImpactMessage>().copied());
            merges.extend(sim.step_messages::<MergeMessage>().copied());
            fragments.extend(sim.step_messages::<FragmentMessage>().cloned());
            // Every message of the step just taken, none of the step before.
            assert!(
                sim.step_messages::<ImpactMessage>()
                    .all(|m| m.time <= now && m.time >= now - sim.clock().dt - 1e-15),
                "{core}: a message from another step"
            );
            std::ops::ControlFlow::Continue(())
        })
        .unwrap();

        // Subscribing changes nothing in the run.
        assert_eq!(sim.bodies(), plain.bodies(), "{core}");
        let c = sim.counters();
        assert_eq!(c, plain.counters(), "{core}");
        // The scene exercises every hook.
        assert!(
            c.bonds > 0 && c.bounces > 0 && c.fragmentations > 0,
            "{core}: {c:?}"
        );

        let bonds = impacts
            .iter()
            .filter(|m| m.outcome == ImpactOutcome::Bond)
            .count() as u64;
        assert_eq!(impacts.len() as u64, c.impacts, "{core}");
        assert_eq!(bonds, c.bonds, "{core}");
        assert_eq!(impacts.len() as u64 - bonds, c.bounces, "{core}");
        // Merging is on and each body has one impact per step: every bond merges.
        assert_eq!(merges.len() as u64, c.bonds, "{core}");
        assert_eq!(fragments.len() as u64, c.fragmentations, "{core}");
        let pieces: usize = fragments.iter().map(|f| f.children.len()).sum();
        assert_eq!(pieces as u64, c.fragments_created, "{core}");
        // The body count follows from the messages alone.
        assert_eq!(
            sim.body_count(),
            sim.info().initial_bodies - merges.len() + pieces - fragments.len(),
            "{core}"
        );

        // The Last-stage reader saw each message exactly once.
        let seen = sim.world().resource::<ReadInLast>();
        assert_eq!(
            (seen.impacts, seen.bonds, seen.merges, seen.fragmentations),
            (c.impacts, c.bonds, merges.len() as u64, c.fragmentations),
            "{core}"
        );

        for m in &impacts {
            assert!(m.id_a < m.id_b, "{core}: {m:?}");
            assert!(m.normal_speed > 0.0 && m.heat >= 0.0, "{core}: {m:?}");
            match m.outcome {
                ImpactOutcome::Bond => assert_eq!(m.restitution, 0.0),
                ImpactOutcome::Bounce => assert!(m.restitution > 0.0 && m.restitution <= 1.0),
            }
        }
        for m in &merges {
            assert!(
                m.parents[0] < m.parents[1] && m.child == m.parents[0],
                "{m:?}"
            );
        }
        // Pieces get fresh ids, never reused.
        let mut ids: Vec<u64> = fragments.iter().flat_map(|f| f.children.clone()).collect();
        let n = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), n, "{core}");
        assert!(ids.iter().all(|&id| id >= s.cloud.count as u64), "{core}");
    }
}

#[test]
fn nothing_is_collected_without_a_subscriber() {
    let mut sim = Simulation::new(&quick_demo("events")).unwrap();
    sim.step().unwrap();
    assert!(
        sim.world()
            .get_resource::<agglo::hooks::Messages<ImpactMessage>>()
            .is_none()
    );
    assert_eq!(sim.step_messages::<ImpactMessage>().count(), 0);
}
