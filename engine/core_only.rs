//! What only the core plugins call: the wall between the plugin API every extension
//! uses ([`crate::schedule::SimBuilder`]) and the calls that build or explain a core.
//!
//! The built-in plugins (`agglo-systems`) bring [`SimBuilderCore`] into scope; an
//! extension does not need it, and a plugin that does takes on a core's duties: its
//! systems are not checked at build (no refusal of stale reads on the event core, no
//! refusal of writes to the clock, counters and ledgers), it may reach the whole world,
//! and it answers for what the summary says of the core. docs/extending.md, "The plugin
//! API", lists both sides.

use bevy_ecs::prelude::*;
use bevy_ecs::system::ScheduleSystem;

use crate::resources::EventStats;
use crate::schedule::{SimBuilder, StepSystems};

/// The builder calls a core plugin needs beyond [`crate::schedule::SimBuilder`]'s.
pub trait SimBuilderCore {
    /// Add systems to one stage as part of the core: unlike
    /// [`crate::schedule::SimBuilder::add_systems`], they may query bodies' components
    /// directly on the event core (they keep the lazy state themselves) and write the
    /// run's books ([`crate::params::RunBooks`]); `build` does not check them.
    fn add_core_systems<M>(
        &mut self,
        stage: StepSystems,
        systems: impl IntoScheduleConfigs<ScheduleSystem, M>,
    ) -> &mut Self;

    /// The whole world being built (every resource, every body): for a core that reads
    /// the initial cloud (a default time scale from the velocities, the totals the
    /// checks start from).
    fn world_mut(&mut self) -> &mut World;

    /// Run `finish` on the world when `build` is called, after every plugin has been
    /// built (e.g. a core that must see every setting, the field among them).
    fn when_built(&mut self, finish: impl FnOnce(&mut World) + 'static) -> &mut Self;

    /// Say why the scene runs on its core (the plugin that builds the core says it;
    /// listed by `Simulation::pipeline` and `agglo validate`).
    fn explain_core(&mut self, why: impl Into<String>) -> &mut Self;

    /// Have the summary carry a core's own counts: `read` takes them from the world
    /// when a summary is made (the event core reports its [`EventStats`] this way).
    fn report_core_stats(&mut self, read: fn(&World) -> EventStats) -> &mut Self;

    /// For the plugin that resolves impacts: how to add its system applying pending
    /// outcomes (in [`crate::hooks::ImpactOutcomeSystems::Apply`]), used at build only
    /// if an extension added outcome systems.
    fn set_impact_outcome_applier(&mut self, add: fn(&mut Schedule)) -> &mut Self;
}

// Here rather than in schedule/, so that the builder does not depend on the wall
// built around it.
impl SimBuilderCore for SimBuilder {
    fn add_core_systems<M>(
        &mut self,
        stage: StepSystems,
        systems: impl IntoScheduleConfigs<ScheduleSystem, M>,
    ) -> &mut Self {
        self.schedule.add_systems(systems.in_set(stage));
        self
    }

    fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    fn when_built(&mut self, finish: impl FnOnce(&mut World) + 'static) -> &mut Self {
        self.finishers.push(Box::new(finish));
        self
    }

    fn explain_core(&mut self, why: impl Into<String>) -> &mut Self {
        self.core_reason = why.into();
        self
    }

    fn report_core_stats(&mut self, read: fn(&World) -> EventStats) -> &mut Self {
        self.core_stats = Some(read);
        self
    }

    fn set_impact_outcome_applier(&mut self, add: fn(&mut Schedule)) -> &mut Self {
        self.outcome_applier = Some(add);
        self
    }
}
