//! # agglo
//!
//! Particle agglomeration in thermochemically reacting granular flows, after
//! Zohdi (2004, 2002) as specified in `docs/model.md`: a cloud of fine grains in a
//! periodic box collides, heats, softens, bonds, merges, fragments and cools.
//!
//! Three layers, each a crate importing only the one below (docs/architecture.md):
//! the engine (`agglo-engine`: the laws, bodies as `bevy_ecs` entities ([`components`]),
//! scene constants and run state as resources ([`resources`]), the stages of a step
//! ([`schedule::StepSystems`]) and the plugin API ([`schedule::SimPlugin`])); the
//! built-in physics (`agglo-systems`, re-exported as [`systems`]), one plugin per
//! concern written against the engine's public API; and this package, the drivers
//! (recording, inverse problem, studies, task farm) and the command line. A run is
//! described by a JSON [`scenario::Scenario`]; [`schedule::Simulation`] runs it.
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

#![warn(missing_docs)]

pub mod charts;
pub mod cli;
pub mod cli_args;
pub mod cloud_file;
pub mod farm;
pub mod huge_pages;
pub mod inverse;
pub mod kernel;
pub mod live;
pub mod memory;
pub mod observer;
pub mod output;
pub mod plugins;
pub mod record;
pub mod restart;
pub mod run;
pub mod scenario;
pub mod seeds;
pub mod separate;
pub mod study;
pub mod subgrid;
pub mod validate;

// The command line (src/cli.rs) names this crate `agglo`, as a program using it would.
extern crate self as agglo;

// The engine's modules, under the paths users and drivers know them by.
pub use agglo_engine::{
    aggregates, bodies, carried, cloud, components, core_only, error, hooks, laws, observables,
    params, particle_cluster, readable, resources, scene, schedule, setup, totals,
};
/// The built-in physics plugins (the `agglo-systems` crate).
pub use agglo_systems as systems;

// Extensions write systems against the same versions the engine uses.
pub use bevy_ecs;
pub use glam;

/// The types most users need: the engine's prelude (the plugin API, the stages, bodies,
/// read-only views of the scene and the run; docs/extending.md, "The plugin API"), the
/// scenario and the built-in physics.
pub mod prelude {
    pub use crate::plugins::NewSimulation;
    pub use crate::scenario::Scenario;
    pub use agglo_engine::prelude::*;
    pub use agglo_systems::AddDefaultPlugins;
}
