//! Stage 3 — merging (docs/model.md §6).
//!
//! Every pair the impact solve bonded becomes one body: masses, momenta, primaries
//! and heat (one C) add; the position is the centre of mass (minimum image); radius
//! and hardness are derived. The body keeps the smaller stable id; the other entity
//! is despawned. Mass and momentum are conserved to rounding. Quantities an extension
//! carries (engine/carried.rs) are combined by their rules.
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
//! Left out in rigid scenes (`physics.merge_mode = "rigid"`): there a bond joins two
//! aggregates in the impact stage (`impact/rigid.rs`) and no body is merged away.
//!
//! Reads: [`ImpactRecords`]. Writes: the survivor's components, despawns the partner,
//! [`SimClock::bodies_reshaped`], [`StepEvents`] (the partner's id); one [`MergeMessage`]
//! per merge when an extension subscribed (engine/hooks.rs).

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::scene::{MergeMode, Physics};
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use agglo_engine::params::{RunBooks, SceneConstants};

use agglo_engine::carried::{CarriedState, Combine, queue_merge};
use agglo_engine::components::{
    Hardness, Mass, Particle, ParticleId, Position, Primaries, Radius, Temperature, Velocity,
};
use agglo_engine::hooks::{MergeMessage, Messages};
use agglo_engine::resources::ImpactRecords;
use agglo_engine::scene::ImpactsPerStep;

/// What a merge reads of both bodies and writes of the survivor.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct MergeBody {
    /// Position [m].
    pub position: &'static mut Position,
    /// Velocity [m/s].
    pub velocity: &'static mut Velocity,
    /// Mass [kg].
    pub mass: &'static mut Mass,
    /// Radius [m].
    pub radius: &'static mut Radius,
    /// Temperature θ [K].
    pub temperature: &'static mut Temperature,
    /// Hardness H [Pa].
    pub hardness: &'static mut Hardness,
    /// The primary grains it is made of.
    pub primaries: &'static mut Primaries,
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
}

type MergeQuery<'w, 's> = Query<'w, 's, MergeBody, With<Particle>>;

/// Stage 3 as a system: merge every pair the impact solve bonded into one body, keeping
/// mass [kg], momentum [kg m/s] and heat [J].
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn merge_bonded(
    records: Res<ImpactRecords>,
    scene: SceneConstants,
    mut bodies: MergeQuery,
    books: RunBooks,
    mut commands: Commands,
    mut messages: Option<ResMut<Messages<MergeMessage>>>,
    carried: Option<Res<CarriedState>>,
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
                (Ok(x), Ok(y)) if y.id.0 < x.id.0 => (b, a),
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
            geometry.min_image(gone.position.0 - keep.position.0)
        } else {
            record.separation
        };
        let MergeBodyItem {
            position: mut pa,
            velocity: mut va,
            mass: mut ma,
            radius: mut ra,
            temperature: mut ta,
            hardness: mut ha,
            primaries: mut na,
            id: id_a,
        } = keep;
        let (vb, mb, tb, nb, id_b) = (
            gone.velocity,
            gone.mass,
            gone.temperature,
            gone.primaries,
            gone.id,
        );
        // Mass is extensive, temperature mass-weighted (one C), primaries extensive.
        let m = Combine::Sum.combine(ma.0, 0.0, mb.0, 0.0);
        let relative_motion = if several_impacts {
            0.5 * ma.0 * mb.0 / m * (va.0 - vb.0).length_squared()
        } else {
            0.0
        };
        // Centre of mass with the image of b that was met (not always the nearest one).
        pa.0 = geometry.wrap(pa.0 + separation * (mb.0 / m));
        va.0 = (ma.0 * va.0 + mb.0 * vb.0) / m;
        ta.0 = Combine::MassWeighted.combine(ta.0, ma.0, tb.0, mb.0);
        if relative_motion > 0.0 {
            ta.0 += relative_motion / (m * material.C);
            ledger.impact_dissipation += relative_motion;
        }
        na.0 = Combine::Sum.combine(na.0, ma.0, nb.0, mb.0);
        if carried.is_some() {
            // The extension's quantities, by their rules, before `b` is despawned.
            queue_merge(&mut commands, (a, ma.0), (b, mb.0));
        }
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

/// Merging of bonded pairs (stage 3).
pub struct MergePlugin;
impl SimPlugin for MergePlugin {
    fn name(&self) -> &'static str {
        "merge"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let physics = *sim.resource::<Physics>();
        if physics.merge_mode == MergeMode::Rigid {
            sim.leave_out(
                "merging: physics.merge_mode = \"rigid\" joins aggregates in the impact stage",
            );
        } else if physics.merging {
            sim.add_core_systems(StepSystems::Merge, merge_bonded);
        } else {
            sim.leave_out("merging off: physics.merging = false");
        }
    }
}
