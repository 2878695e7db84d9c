//! Hooks at contacts, merges and fragments: typed messages an extension can read
//! (docs/extending.md).
//!
//! The built-in Impact, Merge and Fragment stages (docs/model.md §5–§7) write one
//! message per impact ([`ImpactMessage`]), per merge ([`MergeMessage`]) and per
//! fragmentation ([`FragmentMessage`]) — but only when someone subscribed
//! ([`crate::schedule::SimBuilder::subscribe`], which inserts the `Messages<M>`
//! resource). The built-ins take it as `Option<ResMut<Messages<M>>>`, so a run nobody
//! listens to collects nothing and costs nothing.
//!
//! The buffers rotate once per step, just before the step runs
//! ([`crate::schedule::Simulation::step`]): after a step,
//! [`crate::schedule::Simulation::step_messages`] gives the messages of the step just
//! taken, in the order they were written (impacts in resolution order, which is by
//! stable ids), and a `MessageReader<M>` in the `Last` stage sees each message once.
//!
//! Ids are stable particle ids ([`crate::components::ParticleId`]), never entities, so a
//! tally built from these messages is the same on any thread count and either core.

use bevy_ecs::message::Message;
use bevy_ecs::prelude::*;

pub use bevy_ecs::message::{MessageReader, MessageWriter, Messages};

/// One resolved impact, written by the Impact stage (docs/model.md §5) when someone
/// subscribed.
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct ImpactMessage {
    /// Contact time [s].
    pub time: f64,
    /// Stable ids of the pair, `id_a < id_b`.
    pub id_a: u64,
    pub id_b: u64,
    /// Masses before the impact [kg].
    pub mass_a: f64,
    pub mass_b: f64,
    /// Radii [m].
    pub radius_a: f64,
    pub radius_b: f64,
    /// Approach speed along the normal before the impact, (v_a − v_b)·n̂ > 0 [m/s].
    pub normal_speed: f64,
    /// |tangential relative velocity| before the impact [m/s].
    pub tangential_speed: f64,
    /// Restitution e used (0 for a bond).
    pub restitution: f64,
    /// Heat the impact put into the pair [J]: dissipation (as the `work_heat` reading
    /// books it) plus reaction heat.
    pub heat: f64,
    /// Whether the pair bounced or bonded (and will merge, if merging is on).
    pub outcome: ImpactOutcome,
}

/// What an impact did to the pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImpactOutcome {
    /// The pair separated with restitution e > 0.
    Bounce,
    /// The pair stuck (e = 0): a common velocity, merged by the Merge stage.
    Bond,
}

/// One merge (docs/model.md §6): two bodies became one.
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct MergeMessage {
    /// Time of the merge [s].
    pub time: f64,
    /// Stable ids of the two bodies merged, smaller first.
    pub parents: [u64; 2],
    /// Stable id of the merged body (the smaller parent id survives).
    pub child: u64,
    /// Mass of the merged body [kg].
    pub mass: f64,
}

/// One fragmentation (docs/model.md §7): a body split into pieces.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct FragmentMessage {
    /// Time of the fragmentation [s].
    pub time: f64,
    /// Stable id of the body that split (removed).
    pub parent: u64,
    /// Stable ids of the pieces, in allocation order.
    pub children: Vec<u64>,
    /// Mass of the parent [kg] (the pieces share it equally).
    pub parent_mass: f64,
}

/// Swap `M`'s buffers: what the step about to run writes is then the current update,
/// and the step before's messages stay readable for one more step (bevy's double buffer).
pub(crate) fn rotate<M: Message>(world: &mut World) {
    if let Some(mut messages) = world.get_resource_mut::<Messages<M>>() {
        messages.update();
    }
}
