//! Extensions in the binary: plugins a program registers beside the built-in physics,
//! each with an optional section of the scenario, `plugins.NAME` (docs/extending.md).
//!
//! A section is a type ([`PluginSection`]: serde, JSON Schema and a range check) that
//! gets what a built-in section gets: `agglo schema` documents it, parsing and
//! [`Scenario::validate`] check it (each problem named by its full path,
//! `plugins.charged_grains.q0`, with the allowed range), `--set` and the inverse
//! problem's genes address it by that path, and the recording and restart file embed
//! it with the scenario. During a build it is a resource of the world: the plugin reads
//! it in `build` (`SimBuilder::resource`) and its systems read it as `Res<S>`.
//!
//! The registry is one list per process, filled before anything is parsed (by
//! [`crate::cli::main_with`], or by [`register`] in a program that drives the library
//! itself), so every simulation the drivers build — a run, each sample of an ensemble
//! on a worker thread, a study, another MPI rank running the same binary — gets the same
//! plugins. A plugin with a section is built only into scenes that carry its section (a
//! scene runs only what it needs); one without is built into every scene. A scenario
//! naming a plugin the binary does not have is refused, naming it and listing the ones
//! the binary has.

pub(crate) mod registry;

pub use registry::{Extension, PluginSection, Sections, add_extensions, issue, names, register};

use crate::error::SimError;
use crate::scenario::Scenario;
use crate::schedule::{SimBuilder, Simulation};

/// The scenario's builder with the built-in physics and the registered extensions:
/// what every driver builds from.
pub fn builder(scenario: &Scenario) -> Result<SimBuilder, SimError> {
    registry::build(scenario, &scenario.plugins)
}

/// [`builder`] for a simulation to be resumed from `snapshot` next, whose run started
/// with `initial_bodies` bodies (`SimBuilder::resuming`: the scene's initial cloud is
/// neither placed nor spawned; what else must be given is listed there).
pub fn resuming_builder(
    scenario: &Scenario,
    snapshot: &agglo_engine::restart::RestartSnapshot,
    initial_bodies: usize,
) -> Result<SimBuilder, SimError> {
    let builder = SimBuilder::resuming(scenario, snapshot, initial_bodies)?;
    Ok(registry::with_plugins(builder, &scenario.plugins))
}

/// The scenario's simulation with the built-in physics and the registered extensions.
pub fn simulation(scenario: &Scenario) -> Result<Simulation, SimError> {
    builder(scenario)?.build()
}

/// `Simulation::new(&scenario)` from `agglo::prelude`: the scene with the built-in
/// physics and every registered extension, as every driver builds it ([`simulation`]).
/// (`agglo_systems::NewBuiltinSimulation::new` builds the built-ins alone, for programs that
/// use the engine without this package.)
pub trait NewSimulation {
    /// The scenario's simulation with the built-in physics and the registered extensions.
    fn new(scenario: &Scenario) -> Result<Self, SimError>
    where
        Self: Sized;
}

impl NewSimulation for Simulation {
    fn new(scenario: &Scenario) -> Result<Self, SimError> {
        simulation(scenario)
    }
}
