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
//! - [`issues`]: the range checks every section's `issues()` is written with;
//! - [`hooks`]: typed messages at every impact, merge and fragmentation, for
//!   extensions that subscribe;
//! - [`params`]: system parameters grouping what a stage reads and writes together
//!   (read-only views for every plugin, the run's books for the core);
//! - [`core_only`]: the builder calls only the core plugins make;
//! - [`observables`], [`totals`]: what a run measures (docs/model.md §10, §11).
//!
//! Nothing here knows a built-in plugin: `agglo-systems` builds on this crate, and the
//! `agglo` package (drivers and command line) on both. All quantities are SI and `f64`.

#![warn(missing_docs)]

pub mod aggregates;
pub mod bodies;
pub mod carried;
pub mod cloud;
pub mod components;
pub mod core_only;
pub mod error;
pub mod field;
pub mod hooks;
pub mod issues;
pub mod laws;
pub mod observables;
pub mod params;
pub mod particle_cluster;
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

/// What an extension author needs, and no more (docs/extending.md, "The plugin API",
/// says what each item is for): the plugin API, the stages, `Bodies` and the state it
/// hands a closure, the components safe to query directly on either core (the
/// time-dependent ones are read through `Bodies`), carried quantities, the fields, the
/// hooks' messages and outcomes, read-only views of the scene and the run, and the
/// errors. Plumbing (the stored-body tuples, reference times, the run's writable books,
/// the core-only builder calls) stays under its module path.
pub mod prelude {
    pub use crate::bodies::Bodies;
    pub use crate::carried::{Carried, Combine, Split};
    pub use crate::components::{BodyState, Mass, Particle, ParticleId, Primaries, Radius};
    pub use crate::error::{ScenarioError, SimError};
    pub use crate::field::{Drag, Field, Relaxation};
    pub use crate::hooks::{
        FragmentMessage, ImpactMessage, ImpactOutcome, MergeMessage, MessageReader, PendingImpact,
        PendingImpacts,
    };
    pub use crate::observables::Summary;
    pub use crate::params::{RunView, SceneConstants};
    pub use crate::resources::{Counters, EnergyLedger, SimClock};
    pub use crate::scene::Material;
    pub use crate::schedule::{SimBuilder, SimPlugin, Simulation, StepSystems};
}
