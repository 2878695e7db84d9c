//! Stage 8 — periodic boundary (docs/model.md §9, P02 Remark 2): a coordinate leaving
//! [−D, D] re-enters at the opposite face with the same velocity. P04's
//! "r_ix = −r_ix" is read as the same periodic re-entry. Momentum is untouched.
//!
//! Reads: [`BoxGeometry`]. Writes: positions.

use bevy_ecs::prelude::*;

use agglo_engine::components::{Particle, Position};
use agglo_engine::resources::BoxGeometry;

/// Stage 8 as a system: bring every position back into the periodic box [−D, D]³ [m].
pub fn wrap_positions(
    geometry: Res<BoxGeometry>,
    mut bodies: Query<&mut Position, With<Particle>>,
) {
    let d = geometry.half_width;
    for mut p in &mut bodies {
        let r = p.0;
        if r.x < -d || r.x >= d || r.y < -d || r.y >= d || r.z < -d || r.z >= d {
            p.0 = geometry.wrap(r);
        }
    }
}
