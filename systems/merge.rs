//! Stage 3 — merging (docs/model.md §6).
//!
//! Every pair the impact solve bonded becomes one body: masses, momenta, primaries
//! and heat (one C) add; the position is the centre of mass (minimum image); radius
//! and hardness are derived. The body keeps the smaller stable id; the other entity
//! is despawned. Mass and momentum are conserved to rounding.
//!
//! Reads: [`ImpactRecords`]. Writes: the survivor's components, despawns the partner,
//! [`SimClock::bodies_reshaped`], [`StepEvents`] (the partner's id).

use bevy_ecs::prelude::*;

use crate::components::{
    Hardness, Mass, Particle, Position, Primaries, Radius, Temperature, Velocity,
};
use crate::resources::{BoxGeometry, ImpactRecords, MaterialConstants, SimClock, StepEvents};

type MergeQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static mut Position,
        &'static mut Velocity,
        &'static mut Mass,
        &'static mut Radius,
        &'static mut Temperature,
        &'static mut Hardness,
        &'static mut Primaries,
    ),
    With<Particle>,
>;

/// The system.
pub fn merge_bonded(
    records: Res<ImpactRecords>,
    material: Res<MaterialConstants>,
    geometry: Res<BoxGeometry>,
    mut bodies: MergeQuery,
    mut clock: ResMut<SimClock>,
    mut events: ResMut<StepEvents>,
    mut commands: Commands,
) {
    for record in records.records.iter().filter(|r| r.bonded) {
        let Ok([a, b]) = bodies.get_many_mut([record.a, record.b]) else {
            continue;
        };
        let (mut pa, mut va, mut ma, mut ra, mut ta, mut ha, mut na) = a;
        let (_, vb, mb, _, tb, _, nb) = b;
        let m = ma.0 + mb.0;
        // Centre of mass with the image of b that was met (not always the nearest one).
        pa.0 = geometry.wrap(pa.0 + record.separation * (mb.0 / m));
        va.0 = (ma.0 * va.0 + mb.0 * vb.0) / m;
        ta.0 = (ma.0 * ta.0 + mb.0 * tb.0) / m;
        na.0 += nb.0;
        ma.0 = m;
        ra.0 = material.radius_of_mass(m);
        ha.0 = material.hardness(ta.0);
        commands.entity(record.b).despawn();
        events.despawned.push(record.id_b);
        clock.bodies_reshaped = true;
    }
}
