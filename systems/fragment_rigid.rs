//! Stage 4 in rigid scenes (docs/model.md §6.1, "Fragmentation"): an aggregate that
//! absorbed enough energy in this step's impact breaks into its primaries.
//!
//! The criterion is P04's energy balance (5.1)–(5.2), the one of the coalesce mode
//! (`crate::fragment`), with the aggregate taken as the sphere of its volume,
//! b_v = (Σ a_k³)^(1/3): δK the kinetic energy the aggregate lost in the pair's
//! centre-of-mass frame (both sides' when the impact bonded), x = δK / (4π γ b_v²),
//! pieces p = ⌊(1 + x)³⌋. The aggregate breaks when p ≥ k, its number of primaries:
//! then δK pays the surface energy of all k primaries, δZ = γ 4π b_v² (k^{1/3} − 1)
//! ≤ δK. Into its primaries, all of them, rather than at a weakest bond, because the
//! model has no bond that is weaker than another — every bond is one touch of two
//! primaries, held the same way — and the primaries are its smallest pieces, as in the
//! coalesce mode, where no piece is smaller than a grain.
//!
//! Each primary becomes an aggregate of one (its own id), keeping its place, mass and
//! the parent's velocity, so the split moves no mass, momentum or kinetic energy; δZ
//! is taken from the heat as one temperature drop Δθ = −δZ / (M C) of every primary
//! (Σ m_k C Δθ = −δZ) and booked as `fracture_energy`, as in the coalesce mode.
//!
//! Reads: [`ImpactRecords`] (after the impact stage's bonds are applied). Writes: the
//! primaries' temperature and hardness, their aggregates (spawned, despawned),
//! [`agglo_engine::resources::Counters`], [`agglo_engine::totals::EnergyLedger`],
//! [`agglo_engine::resources::StepEvents`] (the primaries touched); one
//! [`FragmentMessage`] per broken aggregate when an extension subscribed.

use bevy_ecs::prelude::*;

use agglo_engine::aggregates::{Aggregate, MemberOf, Members, Offset};
use agglo_engine::bodies::{Clockwork, LazyBody, bring_to};
use agglo_engine::components::Particle;
use agglo_engine::hooks::{FragmentMessage, Messages};
use agglo_engine::params::{RunBooks, SceneConstants};
use agglo_engine::resources::ImpactRecords;
use agglo_engine::totals::Totals;

use crate::events::DueBody;
use agglo_engine::laws::fragmentation::{piece_count, surface_energy};

/// The system: break every aggregate of this step's impacts whose absorbed energy pays
/// the surface energy of all its primaries into them.
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn fragment_aggregates(
    records: Res<ImpactRecords>,
    scene: SceneConstants,
    mut primaries: Query<(DueBody, &MemberOf), With<Particle>>,
    aggregates: Query<(&Aggregate, &Members)>,
    books: RunBooks,
    mut commands: Commands,
    mut messages: Option<ResMut<Messages<FragmentMessage>>>,
    mut absorbed: Local<Vec<(u64, Entity, f64)>>,
) {
    let SceneConstants {
        material,
        geometry,
        options,
        ..
    } = scene;
    let RunBooks {
        clock,
        mut counters,
        mut ledger,
        mut changed,
        mut events,
    } = books;
    if records.records.is_empty() {
        return;
    }
    let gamma = material.surface_energy();
    // (aggregate id, aggregate, absorbed energy): a bond has made one aggregate of two
    // (its primaries all name the keeper by now), which absorbed both sides' energy.
    let aggregate_of = |e: Entity| primaries.get(e).ok().map(|(_, of)| of.0);
    // Kept between steps (a `Local`), so that a step with impacts allocates nothing.
    absorbed.clear();
    for r in &records.records {
        let sides = if r.bonded {
            [Some((r.a, r.lost_a + r.lost_b)), None]
        } else {
            [Some((r.a, r.lost_a)), Some((r.b, r.lost_b))]
        };
        for (primary, energy) in sides.into_iter().flatten() {
            let Some(entity) = aggregate_of(primary) else {
                continue;
            };
            if let Ok((aggregate, _)) = aggregates.get(entity) {
                absorbed.push((aggregate.id, entity, energy));
            }
        }
    }
    // In id order, so that what happens does not depend on the records' order; an
    // aggregate named twice (not expected: one impact per aggregate per step) absorbs
    // the sum.
    absorbed.sort_by(|x, y| x.0.cmp(&y.0).then(x.2.total_cmp(&y.2)));
    absorbed.dedup_by(|later, kept| {
        let same = later.0 == kept.0;
        if same {
            kept.2 += later.2;
        }
        same
    });
    let clockwork = Clockwork::new(&geometry, &material, &options);
    let now = clock.time;
    for &(id, entity, energy) in absorbed.iter() {
        let Ok((aggregate, members)) = aggregates.get(entity) else {
            continue;
        };
        let k = members.entities().len();
        if k < 2 {
            continue;
        }
        let volume: f64 = members
            .entities()
            .iter()
            .filter_map(|&e| primaries.get(e).ok())
            .map(|(p, _)| p.radius.0.powi(3))
            .sum();
        let volume_radius = volume.cbrt();
        if piece_count(energy, volume_radius, gamma) < k as u64 {
            continue;
        }
        let dz = surface_energy(gamma, volume_radius, k as u64);
        let drop = dz / (aggregate.mass * material.C);
        let mut children = Vec::with_capacity(k);
        for &e in members.entities() {
            let Ok((mut p, _)) = primaries.get_mut(e) else {
                continue;
            };
            let before = Totals::of_body(p.mass.0, p.velocity.0, p.temperature.0, material.C);
            events.touch(e, before);
            let lazy = LazyBody::of(
                &mut p.position,
                &mut p.velocity,
                p.mass,
                p.radius,
                &mut p.temperature,
                &mut p.hardness,
                &mut p.local_time,
            );
            bring_to(now, &clockwork, lazy).enter(&mut ledger);
            p.temperature.0 -= drop;
            p.hardness.0 = material.hardness(p.temperature.0);
            let single = commands
                .spawn(Aggregate {
                    id: p.id.0,
                    mass: p.mass.0,
                    velocity: aggregate.velocity,
                })
                .id();
            commands
                .entity(e)
                .insert((MemberOf(single), Offset::default()));
            children.push(p.id.0);
        }
        commands.entity(entity).despawn();
        if let Some(messages) = messages.as_mut() {
            children.sort_unstable();
            messages.write(FragmentMessage {
                time: now,
                parent: id,
                children,
                parent_mass: aggregate.mass,
            });
        }
        counters.fragmentations += 1;
        counters.fragments_created += k as u64;
        ledger.fracture_energy += dz;
        changed.0 = true;
    }
}
