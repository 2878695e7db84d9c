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
    /// Stable id of the first body (`id_a < id_b`).
    pub id_a: u64,
    /// Stable id of the second body (`id_a < id_b`).
    pub id_b: u64,
    /// Mass of the first body before the impact [kg].
    pub mass_a: f64,
    /// Mass of the second body before the impact [kg].
    pub mass_b: f64,
    /// Radius of the first body [m].
    pub radius_a: f64,
    /// Radius of the second body [m].
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

/// The one place where an extension may change an impact's outcome before it is applied
/// (docs/extending.md): systems added with
/// [`crate::schedule::SimBuilder::add_impact_outcome_systems`] run in
/// [`ImpactOutcomeSystems::Decide`], after the impact law has solved every contact of
/// the step and before anything is applied, and may call [`PendingImpact::bond`] or
/// [`PendingImpact::bounce`] on any entry of [`PendingImpacts`]. The impact stage then
/// applies each outcome, recomputing a changed one from the law at the chosen
/// restitution (velocities, heat, the pieces' absorbed energy), so that momentum and the
/// energy ledgers (docs/model.md §10) stay right whatever the hook decides.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImpactOutcomeSystems {
    /// Extensions look at the pending impacts and change outcomes.
    Decide,
    /// The impact plugin applies them (and writes the [`ImpactMessage`]s).
    Apply,
}

/// An outcome chosen by a hook in place of the law's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutcomeChange {
    /// The pair sticks: common velocity, and it merges if merging is on.
    Bond,
    /// The pair bounces with this restitution, clamped to [0, 1] (0: perfectly
    /// inelastic along the normal, but no bond).
    Bounce {
        /// e ∈ [0, 1].
        restitution: f64,
    },
}

/// One impact of the step, solved but not yet applied.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PendingImpact {
    /// What the law would do: the message the impact will write if nobody changes it
    /// (pair ids, masses, radii, approach speeds, restitution, heat, outcome).
    pub proposal: ImpactMessage,
    /// The entity of `proposal.id_a`, to read extension components (e.g.
    /// `Query<&Charge>::get(entity_a)`).
    pub entity_a: Entity,
    /// The entity of `proposal.id_b`.
    pub entity_b: Entity,
    change: Option<OutcomeChange>,
}

impl PendingImpact {
    /// An impact as the law solved it, unchanged (the impact stage makes these).
    pub fn new(proposal: ImpactMessage, entity_a: Entity, entity_b: Entity) -> Self {
        Self {
            proposal,
            entity_a,
            entity_b,
            change: None,
        }
    }
    /// Make the pair stick.
    pub fn bond(&mut self) {
        self.change = Some(OutcomeChange::Bond);
    }
    /// Make the pair bounce with restitution `e` (clamped to [0, 1]).
    pub fn bounce(&mut self, restitution: f64) {
        self.change = Some(OutcomeChange::Bounce { restitution });
    }
    /// Undo a change: the law's outcome again.
    pub fn keep(&mut self) {
        self.change = None;
    }
    /// The change asked for, if any (the last call wins).
    pub fn change(&self) -> Option<OutcomeChange> {
        self.change
    }
}

/// The impacts of the step awaiting their outcome, in resolution order (by stable ids).
/// Present only when an extension added outcome systems; entries can be changed but
/// not added, removed or reordered.
#[derive(Resource, Debug, Default)]
pub struct PendingImpacts {
    impacts: Vec<PendingImpact>,
}

impl PendingImpacts {
    /// The step's impacts, in resolution order.
    pub fn iter(&self) -> std::slice::Iter<'_, PendingImpact> {
        self.impacts.iter()
    }
    /// The step's impacts, to change their outcome ([`PendingImpact`]).
    pub fn iter_mut(&mut self) -> std::slice::IterMut<'_, PendingImpact> {
        self.impacts.iter_mut()
    }
    /// How many impacts the step has.
    pub fn len(&self) -> usize {
        self.impacts.len()
    }
    /// True when the step has no impact.
    pub fn is_empty(&self) -> bool {
        self.impacts.is_empty()
    }
    /// For the impact stage: file an impact the law solved.
    pub fn push(&mut self, impact: PendingImpact) {
        self.impacts.push(impact);
    }
    /// For the impact stage: take the step's impacts to apply them.
    pub fn take(&mut self) -> Vec<PendingImpact> {
        std::mem::take(&mut self.impacts)
    }
}
