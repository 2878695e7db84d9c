//! # agglo-systems
//!
//! The built-in physics, one module per concern, each registered through the same
//! public [`SimPlugin`] API that extensions use (see `examples/`): this crate depends
//! on `agglo-engine` alone, so nothing a built-in does is out of an extension's reach.
//!
//! Each plugin looks at the scenario and adds its systems only if the scene needs
//! them (docs/model.md §3, last line): no cooling system when ε = hc = 0 or cooling is
//! `off`, no fragmentation when γ is ∞, no diagnostics when switched off. The plugin
//! that leaves a system out says why ([`SimBuilder::leave_out`]), so `agglo validate`,
//! the summary and the recording can show it. The stage order lives in the engine
//! ([`StepSystems`](agglo_engine::schedule::StepSystems)); [`default_plugins`] lists the
//! built-ins and [`NewBuiltinSimulation`] builds a simulation with them. Each plugin sits in the
//! file of the systems it schedules; they call the core-only builder calls
//! ([`agglo_engine::core_only::SimBuilderCore`]) besides the ones every plugin has.

#![warn(missing_docs)]

pub mod boundary;
pub mod contact;
mod contact_plugin;
pub mod cooling;
pub mod diagnostics;
pub mod drift;
pub mod events;
pub mod fragment;
pub mod fragment_rigid;
pub mod impact;
pub mod merge;
pub mod time_step;

pub use contact_plugin::ContactPlugin;
pub use cooling::CoolingPlugin;
pub use diagnostics::DiagnosticsPlugin;
pub use drift::MotionPlugin;
pub use fragment::FragmentPlugin;
pub use impact::ImpactPlugin;
pub use merge::MergePlugin;

use agglo_engine::error::SimError;
use agglo_engine::schedule::{SimBuilder, SimPlugin, Simulation};
use agglo_engine::setup::Scene;

/// The built-in physics in pipeline order. A scene that needs less gets fewer systems:
/// each plugin decides from the scenario.
pub fn default_plugins() -> Vec<Box<dyn SimPlugin>> {
    vec![
        Box::new(ContactPlugin),
        Box::new(ImpactPlugin),
        Box::new(MergePlugin),
        Box::new(FragmentPlugin),
        Box::new(CoolingPlugin),
        Box::new(MotionPlugin),
        Box::new(DiagnosticsPlugin),
    ]
}

/// `Simulation::new(&scene)` with the built-in physics alone, for a program that uses
/// the engine without the `agglo` package (whose prelude's `Simulation::new` adds the
/// registered extensions too). Bring the trait into scope to call it.
pub trait NewBuiltinSimulation {
    /// The scene with the built-in physics ([`default_plugins`]).
    fn new(scene: &dyn Scene) -> Result<Self, SimError>
    where
        Self: Sized;
}

impl NewBuiltinSimulation for Simulation {
    fn new(scene: &dyn Scene) -> Result<Self, SimError> {
        let mut builder = Simulation::builder(scene)?;
        builder.add_plugins(default_plugins());
        builder.build()
    }
}

/// The old name of [`NewBuiltinSimulation`]: a trait named like a plugin group (issue
/// 40). Kept so that programs importing it still build, with a warning.
#[deprecated(note = "renamed NewBuiltinSimulation (agglo_systems::NewBuiltinSimulation)")]
pub trait DefaultPlugins {
    /// The scene with the built-in physics ([`default_plugins`]).
    fn new(scene: &dyn Scene) -> Result<Self, SimError>
    where
        Self: Sized;
}

#[allow(deprecated)]
impl<T: NewBuiltinSimulation> DefaultPlugins for T {
    fn new(scene: &dyn Scene) -> Result<Self, SimError> {
        <T as NewBuiltinSimulation>::new(scene)
    }
}

/// [`SimBuilder::add_default_plugins`]: the built-ins, in pipeline order.
pub trait AddDefaultPlugins {
    /// Add the built-in physics (each plugin schedules only what the scene needs).
    fn add_default_plugins(&mut self) -> &mut Self;
}

impl AddDefaultPlugins for SimBuilder {
    fn add_default_plugins(&mut self) -> &mut Self {
        self.add_plugins(default_plugins())
    }
}
