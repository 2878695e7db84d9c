//! # agglo-engine
//!
//! The engine of agglo (docs/architecture.md): what every physics plugin, built-in or
//! extension, is written against.
//!
//! - [`laws`]: pure numerics (the cooling law and its closed forms);
//! - [`components`]: a body as a `bevy_ecs` entity (mass, radius, velocity,
//!   temperature, hardness, stable id);
//! - [`resources`]: scene constants and run state (material, box, clock, counters,
//!   ledgers, the data handed from stage to stage);
//! - [`bodies`]: [`bodies::Bodies`], bodies brought to the current time, the one way
//!   for a plugin to read or change a body;
//! - [`schedule`]: the stages of a step ([`schedule::StepSystems`], written once), the
//!   plugin trait ([`schedule::SimPlugin`]), the builder and the [`schedule::Simulation`]
//!   that steps the world;
//! - [`setup`], [`scene`], [`cloud`], [`error`]: the [`setup::Scene`] a run is built
//!   from, the sections of it the engine owns (box, material, time, physics), the initial
//!   cloud and its section, and the typed errors;
//! - [`field`]: the fields the cores fly exactly (uniform g, linear drag), the `field` section;
//! - [`carried`]: per-body state an extension adds, carried through merges and
//!   fragmentations by its rules;
//! - [`hooks`]: typed messages at every impact, merge and fragmentation, for
//!   extensions that subscribe;
//! - [`params`]: system parameters grouping what a stage reads and writes together;
//! - [`observables`], [`totals`]: what a run measures (docs/model.md §10, §11).
//!
//! Nothing here knows a built-in plugin: `agglo-systems` builds on this crate, and the
//! `agglo` package (drivers and command line) on both. All quantities are SI and `f64`.

pub mod bodies;
pub mod carried;
pub mod cloud;
pub mod components;
pub mod error;
pub mod field;
pub mod hooks;
pub mod laws;
pub mod observables;
pub mod params;
pub mod readable;
pub mod resources;
pub mod restart;
pub mod scene;
pub mod schedule;
pub mod setup;
pub mod totals;

// Plugins write systems against the same versions the engine uses.
pub use bevy_ecs;
pub use glam;

/// What a plugin author needs: the body components, the `Bodies` access, the clock and
/// run-state resources, the stages and the plugin API.
pub mod prelude {
    pub use crate::bodies::Bodies;
    pub use crate::carried::{Carried, Combine, Split};
    pub use crate::components::*;
    pub use crate::error::{ScenarioError, SimError};
    pub use crate::field::{Drag, Field, Relaxation};
    pub use crate::hooks::{
        FragmentMessage, ImpactMessage, ImpactOutcome, ImpactOutcomeSystems, MergeMessage,
        MessageReader, MessageWriter, Messages, OutcomeChange, PendingImpact, PendingImpacts,
    };
    pub use crate::observables::{Growth, RadiusStats, Summary};
    pub use crate::params::{RunBooks, SceneConstants};
    pub use crate::resources::{Counters, EnergyLedger, SimClock};
    pub use crate::scene::Material;
    pub use crate::schedule::{SimBuilder, SimPlugin, Simulation, StepSystems};
    pub use crate::setup::Scene;
}
