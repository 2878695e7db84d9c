//! The build-time checks on an extension's systems: what they may read on the event
//! core (bodies through `Bodies` only) and which of the run's books they may not write.

use bevy_ecs::component::ComponentId;
use bevy_ecs::prelude::*;

use crate::bodies::BodiesGate;
use crate::components::{Hardness, LocalTime, Position, Temperature, Velocity};
use crate::error::SimError;
use crate::resources::*;

use super::short_name;

/// The systems added through the API open to every plugin ([`SimBuilder::add_systems`],
/// [`SimBuilder::add_impact_outcome_systems`]): the ones [`SimBuilder::build`] checks.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct ExtensionSystems;

/// Refuse an extension's system that would read stale state or write the run's books.
/// Checked for the systems in `only` (those added through the API open to every plugin,
/// whatever the stage) or, with `None`, every system of `schedule` (the forces):
/// - on the event core (`lazy`), one that queries a body's time-dependent state without
///   [`crate::bodies::Bodies`] (docs/model.md §4: it would read each body at its own
///   reference time, not now, silently);
/// - on either core, one that writes the clock, the counters, the invariant report or the
///   records the stages hand on (they are the core's; an extension reads them through
///   [`crate::params::RunView`]), or the energy ledger or the step's events other than
///   through `Bodies` (which books what it changes).
///
/// Exclusive systems (`&mut World`) cannot be inspected and are let through.
pub(super) fn refuse_unsafe_access(
    schedule: &Schedule,
    only: Option<bevy_ecs::schedule::InternedSystemSet>,
    world: &World,
    lazy: bool,
) -> Result<(), SimError> {
    let ids = |list: &[(Option<ComponentId>, &'static str)]| -> Vec<(ComponentId, &'static str)> {
        list.iter()
            .filter_map(|&(id, name)| Some((id?, name)))
            .collect()
    };
    let gate = world.component_id::<BodiesGate>();
    let lazy_state = ids(&[
        (world.component_id::<Position>(), "Position"),
        (world.component_id::<Velocity>(), "Velocity"),
        (world.component_id::<Temperature>(), "Temperature"),
        (world.component_id::<Hardness>(), "Hardness"),
        (world.component_id::<LocalTime>(), "LocalTime"),
    ]);
    // Resources are components of their own entity in bevy_ecs 0.20.
    let books = ids(&[
        (world.component_id::<SimClock>(), "SimClock"),
        (world.component_id::<Counters>(), "Counters"),
        (world.component_id::<InvariantReport>(), "InvariantReport"),
        (
            world.component_id::<crate::resources::NonFiniteState>(),
            "NonFiniteState",
        ),
        (world.component_id::<StateChanged>(), "StateChanged"),
        (world.component_id::<ContactList>(), "ContactList"),
        (world.component_id::<ImpactRecords>(), "ImpactRecords"),
        (world.component_id::<IdAllocator>(), "IdAllocator"),
        (world.component_id::<ForceKicks>(), "ForceKicks"),
    ]);
    let booked_by_bodies = ids(&[
        (world.component_id::<EnergyLedger>(), "EnergyLedger"),
        (world.component_id::<StepEvents>(), "StepEvents"),
    ]);
    // A set no system was put in is unknown to the schedule: nothing to check.
    let checked: Option<std::collections::HashSet<_>> = only.map(|set| {
        schedule
            .graph()
            .systems_in_set(set)
            .map(|keys| keys.iter().copied().collect())
            .unwrap_or_default()
    });
    let systems = schedule
        .systems_with_access()
        .map_err(|e| SimError::Schedule(format!("{e:?}")))?;
    for (key, system) in systems {
        if checked.as_ref().is_some_and(|keys| !keys.contains(&key)) {
            continue;
        }
        let bevy_ecs::system::SystemAccess::Shared(access) = system.access() else {
            continue;
        };
        let access = access.combined_access();
        let through_bodies = gate.is_some_and(|g| access.has_read(g));
        let name = || short_name(&system.name().to_string());
        let stale: Vec<&str> = lazy_state
            .iter()
            .filter(|(id, _)| access.has_read(*id) || access.has_write(*id))
            .map(|(_, name)| *name)
            .collect();
        if lazy && !through_bodies && !stale.is_empty() {
            return Err(SimError::Schedule(format!(
                "system `{}` queries {} directly, but this scene runs on the event core, where \
                 each body holds its state at its own reference time (docs/model.md §4): the \
                 query would read stale state. Read and write bodies through the `Bodies` \
                 system parameter (agglo::bodies::Bodies), which brings each body to the \
                 current time and has the event core re-predict what changes; or run the scene \
                 on the stepped core (time.core = \"stepped\")",
                name(),
                stale.join(", ")
            )));
        }
        let written: Vec<&str> = books
            .iter()
            .chain(booked_by_bodies.iter().filter(|_| !through_bodies))
            .filter(|(id, _)| access.has_write(*id))
            .map(|(_, name)| *name)
            .collect();
        if !written.is_empty() {
            return Err(SimError::Schedule(format!(
                "system `{}` writes {}, which belong to the core: an extension reads the clock \
                 and counters (agglo::params::RunView) and changes bodies through `Bodies`, \
                 which books the work and heat it adds in the energy ledger \
                 (docs/extending.md, \"What an extension may write\")",
                name(),
                written.join(", ")
            )));
        }
    }
    Ok(())
}
