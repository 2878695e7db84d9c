//! Stage 7 — drift: r ← r + Δt v (P02 (9), P04 after (6.21)), or, in a field, each body
//! along its closed-form flight over Δt (docs/model.md §4.7): a parabola under uniform
//! g, the drag flight under linear drag. The field's work and impulse go into the
//! energy ledger as force work and force impulse.
//!
//! Reads: Δt, velocities, the field. Writes: positions (and velocities in a field), the
//! ledger.

use bevy_ecs::prelude::*;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};
use glam::DVec3;

use agglo_engine::components::{Mass, Particle, Position, Radius, Velocity};
use agglo_engine::field::{Field, FieldKind};
use agglo_engine::resources::{EnergyLedger, SimClock};

/// Stage 7 as a system: move every body over Δt [s] — a straight line, or its closed-form
/// flight in the field — and book the field's work [J] and impulse [kg m/s].
pub fn drift(
    clock: Res<SimClock>,
    field: Option<Res<Field>>,
    mut ledger: ResMut<EnergyLedger>,
    mut bodies: Query<(&mut Position, &mut Velocity, &Mass, &Radius), With<Particle>>,
) {
    let dt = clock.dt;
    let field = field.filter(|f| f.kind() != FieldKind::None);
    let Some(field) = field else {
        for (mut p, v, _, _) in &mut bodies {
            p.0 += dt * v.0;
        }
        return;
    };
    let (mut work, mut work_turnover) = (0.0, 0.0);
    let (mut impulse, mut impulse_turnover) = (DVec3::ZERO, 0.0);
    for (mut p, mut v, m, b) in &mut bodies {
        let before = v.0;
        let (x, after) = field.flight(m.0, b.0).advance(p.0, before, dt);
        p.0 = x;
        v.0 = after;
        let w = 0.5 * m.0 * (after.length_squared() - before.length_squared());
        let j = m.0 * (after - before);
        work += w;
        work_turnover += w.abs();
        impulse += j;
        impulse_turnover += j.length();
    }
    ledger.force_work += work;
    ledger.force_work_turnover += work_turnover;
    ledger.force_impulse = (DVec3::from_array(ledger.force_impulse) + impulse).to_array();
    ledger.force_impulse_turnover += impulse_turnover;
}

/// Drift (stage 7) and periodic wrapping (stage 8); on the event core both happen when
/// a body is read, so nothing is scheduled.
pub struct MotionPlugin;
impl SimPlugin for MotionPlugin {
    fn name(&self) -> &'static str {
        "motion"
    }
    fn build(&self, sim: &mut SimBuilder) {
        if sim.uses_event_core() {
            sim.leave_out(
                "drift, boundary: done lazily by the event core (each body moved and wrapped when read)",
            );
            return;
        }
        sim.add_core_systems(StepSystems::Drift, drift)
            .add_core_systems(StepSystems::Boundary, crate::boundary::wrap_positions);
    }
}
