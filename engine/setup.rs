//! What the engine builds a world from: a [`Scene`], the run description as the engine
//! needs it. `agglo`'s `Scenario` is one; an embedder can write its own.

use bevy_ecs::prelude::*;

use crate::cloud::Cloud;
use crate::error::ScenarioError;
use crate::scene::{BoxGeometry, Material, Physics, TimeControl};

/// A run's description, as the engine needs it to build a world: `agglo`'s `Scenario`
/// is one. The engine reads its own sections through the accessors; every other
/// section the description holds goes into the world through
/// [`Scene::insert_settings`], where the plugin that owns it reads it.
pub trait Scene {
    /// Short name, used in summaries and recordings.
    fn name(&self) -> &str;
    /// Seed of the scene's single random generator.
    fn seed(&self) -> u64;
    /// The periodic box (`box`).
    fn domain(&self) -> &BoxGeometry;
    /// The initial cloud (`cloud`).
    fn cloud(&self) -> &Cloud;
    /// The material (`material`).
    fn material(&self) -> &Material;
    /// End time and step control (`time`).
    fn time(&self) -> &TimeControl;
    /// Which physics runs (`physics`).
    fn physics(&self) -> &Physics;
    /// Check every field of the description; each problem names its field path.
    fn validate(&self) -> Result<(), ScenarioError>;
    /// Insert the sections the engine does not own as resources (e.g. `impact`,
    /// `diagnostics`), and anything the drivers want to find in the world.
    fn insert_settings(&self, world: &mut World);
}
