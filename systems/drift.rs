//! Stage 7 — drift: r ← r + Δt v (P02 (9), P04 after (6.21)). No external forces.
//!
//! Reads: Δt, velocities. Writes: positions.

use bevy_ecs::prelude::*;

use agglo_engine::components::{Particle, Position, Velocity};
use agglo_engine::resources::SimClock;

/// The system.
pub fn drift(clock: Res<SimClock>, mut bodies: Query<(&mut Position, &Velocity), With<Particle>>) {
    let dt = clock.dt;
    for (mut p, v) in &mut bodies {
        p.0 += dt * v.0;
    }
}
