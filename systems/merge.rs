//! Stage 3 — merging (docs/model.md §6).
//!
//! Every pair the impact solve bonded becomes one body: masses, momenta, primaries
//! and heat (one C) add; the position is the centre of mass (minimum image); radius
//! and hardness are derived. The body keeps the smaller stable id; the other entity
//! is despawned. Mass and momentum are conserved to rounding.
//!
//! When a body bonds more than once in a step (`physics.impacts_per_step =
//! "every_contact"`), the bonds chain: a pair whose body was already absorbed merges
//! into the body that absorbed it, with the separation taken afresh from the merged
//! centres, so a cluster of any shape becomes one body. A bonded pair then need not
//! move together any more (a later impact of the step moved one of them): the kinetic
//! energy of their relative motion, ½ m_a m_b/(m_a + m_b) |v_a − v_b|², is lost in the
//! merge and becomes heat of the merged body, tallied as impact dissipation so that
//! the ledgers close. With one impact per body it is zero and not computed.
//!
//! Reads: [`ImpactRecords`]. Writes: the survivor's components, despawns the partner,
//! [`SimClock::bodies_reshaped`], [`StepEvents`] (the partner's id); one [`MergeMessage`]
//! per merge when an extension subscribed (engine/hooks.rs).

use std::collections::HashMap;

use bevy_ecs::prelude::*;

use agglo_engine::params::{RunBooks, SceneConstants};

use agglo_engine::components::{
    Hardness, Mass, Particle, ParticleId, Position, Primaries, Radius, Temperature, Velocity,
};
use agglo_engine::hooks::{MergeMessage, Messages};
use agglo_engine::resources::ImpactRecords;
use agglo_engine::scene::ImpactsPerStep;

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
        &'static ParticleId,
    ),
    With<Particle>,
>;

/// The system.
pub fn merge_bonded(
    records: Res<ImpactRecords>,
    scene: SceneConstants,
    mut bodies: MergeQuery,
    books: RunBooks,
    mut commands: Commands,
    mut messages: Option<ResMut<Messages<MergeMessage>>>,
) {
    let SceneConstants {
        material,
        geometry,
        options,
        ..
    } = scene;
    let RunBooks {
        mut clock,
        mut ledger,
        mut events,
        ..
    } = books;
    let several_impacts = options.impacts_per_step == ImpactsPerStep::EveryContact;
    // Absorbed entity → the entity it merged into (only when bonds chain in one step).
    let mut absorbed: HashMap<Entity, Entity> = HashMap::new();
    let survivor = |absorbed: &HashMap<Entity, Entity>, mut e: Entity| {
        while let Some(&s) = absorbed.get(&e) {
            e = s;
        }
        e
    };
    for record in records.records.iter().filter(|r| r.bonded) {
        let (a, b) = (survivor(&absorbed, record.a), survivor(&absorbed, record.b));
        if a == b {
            continue; // already one body
        }
        // The survivor keeps the smaller id (contacts come oriented that way; a chained
        // pair may not be), and a chained pair's separation is taken from the centres
        // as they are now.
        let chained = (a, b) != (record.a, record.b);
        let (a, b) = if chained {
            match (bodies.get(a), bodies.get(b)) {
                (Ok(x), Ok(y)) if y.7.0 < x.7.0 => (b, a),
                (Ok(_), Ok(_)) => (a, b),
                _ => continue,
            }
        } else {
            (a, b)
        };
        let Ok([keep, gone]) = bodies.get_many_mut([a, b]) else {
            continue;
        };
        let separation = if chained {
            geometry.min_image(gone.0.0 - keep.0.0)
        } else {
            record.separation
        };
        let (mut pa, mut va, mut ma, mut ra, mut ta, mut ha, mut na, id_a) = keep;
        let (_, vb, mb, _, tb, _, nb, id_b) = gone;
        let m = ma.0 + mb.0;
        let relative_motion = if several_impacts {
            0.5 * ma.0 * mb.0 / m * (va.0 - vb.0).length_squared()
        } else {
            0.0
        };
        // Centre of mass with the image of b that was met (not always the nearest one).
        pa.0 = geometry.wrap(pa.0 + separation * (mb.0 / m));
        va.0 = (ma.0 * va.0 + mb.0 * vb.0) / m;
        ta.0 = (ma.0 * ta.0 + mb.0 * tb.0) / m;
        if relative_motion > 0.0 {
            ta.0 += relative_motion / (m * material.C);
            ledger.impact_dissipation += relative_motion;
        }
        na.0 += nb.0;
        ma.0 = m;
        ra.0 = material.radius_of_mass(m);
        ha.0 = material.hardness(ta.0);
        if let Some(messages) = messages.as_mut() {
            messages.write(MergeMessage {
                time: clock.time,
                parents: [id_a.0, id_b.0],
                child: id_a.0,
                mass: m,
            });
        }
        commands.entity(b).despawn();
        events.despawned.push(id_b.0);
        if several_impacts {
            // Only then can a later record of the step name `b` (no allocation otherwise).
            absorbed.insert(b, a);
        }
        clock.bodies_reshaped = true;
    }
}
