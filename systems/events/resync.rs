//! The event core at a checkpoint (engine/restart.rs): steps land on each checkpoint
//! time, every body is brought there, and the core is rebuilt from the bodies by the
//! same pure function that builds it at t = 0 — predicting every body from the
//! checkpoint time — with the grid's frame kept as it was (its velocity at t = 0 is
//! saved; its flight follows from the scene's field) and the core's counts carried on.
//! The run that takes the checkpoint and a run resumed from it both rebuild this way,
//! so both continue from the same calendar. Rebuilding rather than saving the calendar
//! keeps the snapshot to the bodies' states, and the core's layout free to change.

use agglo_engine::resources::EventStats;
use agglo_engine::restart::RestartPart;
use agglo_engine::scene::{Core, TimeControl};
use bevy_ecs::prelude::*;
use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::core::EventCore;
use super::core_from_world;

/// What the snapshot keeps of the core.
#[derive(Serialize, Deserialize)]
struct Saved {
    /// The grid frame's velocity at t = 0 [m/s].
    frame_velocity: [f64; 3],
    /// The core's counts so far (the summary reports them).
    stats: EventStats,
}

/// The event core's restart part.
pub fn restart_part() -> RestartPart {
    RestartPart {
        name: "event_core",
        save: |world| {
            let core = world.resource::<EventCore>();
            let saved = Saved {
                frame_velocity: core.frame_velocity().to_array(),
                stats: core.stats,
            };
            postcard::to_allocvec(&saved).expect("the core's state always encodes")
        },
        load: |world, bytes| {
            let saved: Saved = postcard::from_bytes(bytes).map_err(|e| e.to_string())?;
            let frame = DVec3::from_array(saved.frame_velocity);
            // The grid's frame moves with the cloud's mean velocity, so no faster than a
            // body may go (a flipped bit made it ~1e300 m/s, and the rebuilt core crossed
            // cells without end: found by the fuzz harness).
            if !(frame.is_finite() && frame.length() <= agglo_engine::scene::MAX_SPEED) {
                return Err(format!(
                    "the grid's frame velocity {frame} m/s; allowed a finite speed ≤ {:e} m/s",
                    agglo_engine::scene::MAX_SPEED
                ));
            }
            rebuild(world, frame, saved.stats);
            Ok(())
        },
    }
}

/// Replace the core by one rebuilt from the bodies in the world, all at the current
/// time, with the given frame and counts.
fn rebuild(world: &mut World, frame_velocity: DVec3, stats: EventStats) {
    let now = world.resource::<agglo_engine::resources::SimClock>().time;
    let brute_force = world.resource::<TimeControl>().core == Core::EventsBruteForce;
    let mut core = core_from_world(world, brute_force, frame_velocity, now);
    core.carry_stats(stats);
    world.insert_resource(core);
}
