//! What the ECS world keeps beside the bodies (issue 19, memory per body): bevy_ecs 0.20
//! stores each resource on an entity of its own, in a sparse set sized by that entity's
//! index, and keeps a message per component of every despawned entity until its trackers
//! are cleared. Both grew with N (100 MB and 168 MB on a merging 1e6 cloud); these tests
//! fail if either comes back.

use crate::common::scenario;

use agglo::bevy_ecs::prelude::{Entity, With};
use agglo::prelude::*;
use serde_json::json;

/// Every resource lives on an entity whose index is below every body's: a resource's
/// sparse array then spans a few hundred indices, not the whole cloud.
#[test]
fn resources_sit_below_every_body() {
    let s = scenario(json!({
        "cloud": { "count": 3000, "radius": 1e-5, "v_rel": [1, 1, 1] },
        "time": { "end": 1e-6 }
    }));
    for core in ["events", "stepped"] {
        let mut s = s.clone();
        s.time.core = serde_json::from_value(json!(core)).unwrap();
        let mut sim = Simulation::new(&s).unwrap();
        sim.step().unwrap();
        let world = sim.world_mut();
        let lowest_body = world
            .query_filtered::<Entity, With<Particle>>()
            .iter(world)
            .map(|e| e.index().index())
            .min()
            .unwrap();
        let resources: Vec<u32> = world
            .resource_entities()
            .iter()
            .map(|(_, e)| e.index().index())
            .collect();
        assert!(
            resources.len() > 20,
            "{core}: {} resources",
            resources.len()
        );
        let highest = resources.iter().max().unwrap();
        assert!(
            *highest < lowest_body,
            "{core}: a resource on entity index {highest}, above the lowest body's {lowest_body}"
        );
    }
}

/// A merging run keeps no removal messages from earlier steps: the world's trackers are
/// cleared every step (bevy keeps the last two updates), so what is left after the run
/// is what the last steps despawned, not one message per component of every merge.
#[test]
fn despawned_bodies_leave_no_messages_behind() {
    let s = scenario(json!({
        "cloud": { "count": 400, "radius": 2e-4, "v_rel": [20, 20, 20] },
        "material": { "H0": 1e-3 },
        "impact": { "a0": 0.0, "af": 1.0, "beta": 1.0 },
        "time": { "end": 2e-3 }
    }));
    let mut sim = Simulation::new(&s).unwrap();
    sim.run().unwrap();
    let merged = sim.counters().bonds;
    assert!(merged >= 100, "the scene must merge: {merged} bonds");
    let kept: usize = sim
        .world()
        .removed_components()
        .iter()
        .map(|(_, messages)| messages.len())
        .sum();
    // Ten components per body: without clearing, 10 × (bonds) messages stay.
    assert!(
        kept < merged as usize,
        "{kept} removal messages kept after {merged} merges"
    );
}
