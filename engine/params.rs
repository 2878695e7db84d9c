//! System parameters that group what a stage reads and writes together, so that a
//! system names the scene and the run's books once instead of resource by resource:
//! [`SceneConstants`] and [`RunView`] for every plugin, [`RunBooks`] for the core
//! plugins only (an extension's system that writes the books is refused at build;
//! docs/extending.md, "What an extension may write").

use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;

use crate::cloud::PrimaryGrain;
use crate::field::Field;
use crate::resources::{BoxGeometry, Counters, EnergyLedger, SimClock, StateChanged, StepEvents};
use crate::scene::{Material, Physics, TimeControl};

/// The scene's constants, read only: the material and its primary grain, the periodic
/// box, the physics options, the time control and the field.
#[derive(SystemParam)]
pub struct SceneConstants<'w> {
    /// The material.
    pub material: Res<'w, Material>,
    /// The primary grain (radius b0 [m], mass [kg]).
    pub primary: Res<'w, PrimaryGrain>,
    /// The end time and stepping.
    pub time: Res<'w, TimeControl>,
    /// The periodic box.
    pub geometry: Res<'w, BoxGeometry>,
    /// The physics options.
    pub options: Res<'w, Physics>,
    /// The field bodies fly in between events, if the scene has one.
    pub field: Option<Res<'w, Field>>,
}

/// The run's clock and counters, read only: what an extension's system may know of the
/// run (the time, the step length, the step number, the events so far). Usable beside
/// [`crate::bodies::Bodies`]; the energy ledger is `Res<EnergyLedger>` in a system
/// without `Bodies` (which writes it), or [`crate::schedule::Simulation::ledger`].
#[derive(SystemParam)]
pub struct RunView<'w> {
    clock: Res<'w, SimClock>,
    counters: Res<'w, Counters>,
}

impl RunView<'_> {
    /// The clock: t [s], the step length Δt [s] and the step number L.
    pub fn clock(&self) -> &SimClock {
        &self.clock
    }
    /// The run's event counts so far (impacts, bonds, merges, fragmentations, …).
    pub fn counters(&self) -> &Counters {
        &self.counters
    }
    /// The current time t [s].
    pub fn now(&self) -> f64 {
        self.clock.time
    }
    /// Length of the step being taken, Δt [s].
    pub fn dt(&self) -> f64 {
        self.clock.dt
    }
    /// The number of steps taken, L.
    pub fn step(&self) -> u64 {
        self.clock.step
    }
}

/// For the core plugins (an extension's system that writes these is refused at build):
/// the run's books that a stage changing bodies writes: the clock (and its flags),
/// the event counters, the energy ledger, whether velocities or the body set changed,
/// and what happened to which body this step (for the event core and the checks).
#[derive(SystemParam)]
pub struct RunBooks<'w> {
    /// The clock: time [s], step, Δt [s].
    pub clock: ResMut<'w, SimClock>,
    /// The event counters.
    pub counters: ResMut<'w, Counters>,
    /// The energy ledger [J].
    pub ledger: ResMut<'w, EnergyLedger>,
    /// Whether velocities or the body set changed this step.
    pub changed: ResMut<'w, StateChanged>,
    /// What happened to which body this step.
    pub events: ResMut<'w, StepEvents>,
}
