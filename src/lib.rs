//! # agglo
//!
//! Particle agglomeration in thermochemically reacting granular flows, after
//! Zohdi (2004, 2002) as specified in `docs/model.md`: a cloud of fine grains in a
//! periodic box collides, heats, softens, bonds, merges, fragments and cools.
//!
//! Particles are `bevy_ecs` entities ([`components`]); scene constants and run state
//! are resources ([`resources`]); the step is a schedule of ordered system sets
//! ([`schedule::StepSystems`]) filled by plugins ([`schedule::SimPlugin`]), the
//! built-in physics living in [`systems`]. A run is described by a JSON
//! [`scenario::Scenario`]; [`schedule::Simulation`] runs it.
//!
//! ```no_run
//! use agglo::prelude::*;
//! let scenario = Scenario::load(std::path::Path::new("scenarios/quick_demo.json"))?;
//! let mut sim = Simulation::new(&scenario)?;
//! sim.run()?;
//! println!("b_f/b0 = {}", sim.summary().growth.growth_ratio);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! All quantities are SI and `f64`.

pub mod charts;
pub mod cloud;
pub mod components;
pub mod error;
pub mod farm;
pub mod inverse;
pub mod observables;
pub mod output;
pub mod record;
pub mod resources;
pub mod scenario;
pub mod schedule;
pub mod study;

#[path = "../systems/mod.rs"]
pub mod systems;

// Extensions write systems against the same versions the engine uses.
pub use bevy_ecs;
pub use glam;

/// The types most users need.
pub mod prelude {
    pub use crate::components::*;
    pub use crate::error::{ScenarioError, SimError};
    pub use crate::observables::{Growth, RadiusStats, Summary};
    pub use crate::resources::{Counters, EnergyLedger, MaterialConstants, SimClock};
    pub use crate::scenario::Scenario;
    pub use crate::schedule::{SimBuilder, SimPlugin, Simulation, StepSystems};
}
