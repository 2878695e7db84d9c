//! System parameters that group what a stage reads and writes together, so that a
//! system names the scene and the run's books once instead of resource by resource.
//! Built-in plugins and extensions use the same ones.

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
    pub material: Res<'w, Material>,
    pub primary: Res<'w, PrimaryGrain>,
    pub time: Res<'w, TimeControl>,
    pub geometry: Res<'w, BoxGeometry>,
    pub options: Res<'w, Physics>,
    /// The field bodies fly in between events, if the scene has one.
    pub field: Option<Res<'w, Field>>,
}

/// The run's books that a stage changing bodies writes: the clock (and its flags),
/// the event counters, the energy ledger, whether velocities or the body set changed,
/// and what happened to which body this step (for the event core and the checks).
#[derive(SystemParam)]
pub struct RunBooks<'w> {
    pub clock: ResMut<'w, SimClock>,
    pub counters: ResMut<'w, Counters>,
    pub ledger: ResMut<'w, EnergyLedger>,
    pub changed: ResMut<'w, StateChanged>,
    pub events: ResMut<'w, StepEvents>,
}
