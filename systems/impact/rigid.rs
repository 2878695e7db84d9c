//! Stage 2 in rigid scenes (`physics.merge_mode = "rigid"`, docs/model.md §6.1): the
//! impact / heat solve between two aggregates, at the pair of primaries that touched.
//!
//! The law is the spheres' (`solve_pair`, or the constant restitution with its TC guard)
//! with each side's body taken as its aggregate: the aggregate's mass and velocity, the
//! touching primary's radius and temperature (the contact's own). Without rotation an
//! aggregate responds to an impulse at any of its primaries as a point mass, so the
//! reduced mass along the normal is M_A M_B / (M_A + M_B) and the outcome's velocities
//! are the aggregates' new velocities, given to every primary.
//!
//! Heat: the law heats each side by ΔQ = M C Δθ (its mass is the aggregate's); every
//! primary of the aggregate rises by the same Δθ, so Σ m_k C Δθ = ΔQ and the ledger
//! closes. Temperatures stay per primary (each cools alone as a free sphere between
//! touches; shielding inside an aggregate is left out).
//!
//! A bond joins the two aggregates: the one with the larger id hands its primaries to the
//! other (their offsets moved into its frame through the contact's separation, the
//! periodic image met), and its entity is despawned. The momentum is conserved exactly
//! (the law's common velocity), the kinetic energy lost is the law's dissipation, booked
//! as for spheres. A bounce changes the two aggregates' velocities; a bouncing pair
//! found overlapping (by rounding) is pushed apart as spheres are, each aggregate whole.
//! An aggregate of one primary is thus exactly a sphere of the coalesce mode.
//!
//! Every primary of both aggregates is brought to now and filed as touched, so the event
//! core re-predicts them: O(k_A + k_B) per contact.

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use glam::DVec3;

use agglo_engine::aggregates::{Aggregate, MemberOf, Members, Offset};
use agglo_engine::bodies::{Clockwork, LazyBody, bring_to};
use agglo_engine::components::{Particle, ParticleId};
use agglo_engine::hooks::{ImpactMessage, Messages};
use agglo_engine::params::{RunBooks, SceneConstants};
use agglo_engine::resources::{ContactList, ImpactRecords};
use agglo_engine::totals::Totals;

use agglo_engine::resources::Contact;

use crate::events::DueBody;

use super::{Apply, CollapseGuard, ImpactModel, PairBody, Separation, pair_model, solve};

/// What a rigid impact reads and writes of each primary of the two aggregates: what the
/// event core brings forward of any body ([`DueBody`]), and the primary's place in its
/// aggregate.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct RigidPrimary {
    /// The primary as a body (its velocity is the aggregate's).
    pub body: DueBody,
    /// Centre relative to the aggregate's fixed point [m].
    pub offset: &'static mut Offset,
    /// The aggregate.
    pub member_of: &'static MemberOf,
}

/// The system: resolve every contact of [`ContactList`] between two aggregates.
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn resolve_rigid_contacts(
    contacts: Res<ContactList>,
    scene: SceneConstants,
    settings: Res<ImpactModel>,
    mut primaries: Query<RigidPrimary, With<Particle>>,
    mut aggregates: Query<(&mut Aggregate, &Members)>,
    mut records: ResMut<ImpactRecords>,
    books: RunBooks,
    mut messages: Option<ResMut<Messages<ImpactMessage>>>,
    (mut guard, mut commands): (Option<ResMut<CollapseGuard>>, Commands),
) {
    let SceneConstants {
        material,
        geometry,
        options,
        ..
    } = scene;
    let RunBooks {
        mut clock,
        mut counters,
        mut ledger,
        mut changed,
        mut events,
    } = books;
    records.records.clear();
    if contacts.contacts.is_empty() {
        return;
    }
    let model = pair_model(&material, &settings);
    let now = clock.time;
    // Rigid scenes have no field (refused at validation): primaries fly straight.
    let clockwork = Clockwork::new(&geometry, &material, &options);
    let heat_capacity = material.C;
    let mut apply = Apply {
        model,
        settings: &settings,
        material: &material,
        geometry: &geometry,
        clock: &mut clock,
        counters: &mut counters,
        ledger: &mut ledger,
        records: &mut records,
        messages: messages.as_deref_mut(),
    };
    for contact in &contacts.contacts {
        // The touching primaries, already brought to now by contact detection.
        let (Ok(pa), Ok(pb)) = (primaries.get(contact.a), primaries.get(contact.b)) else {
            continue;
        };
        let (agg_a, agg_b) = (pa.member_of.0, pb.member_of.0);
        let (ra, theta_a, off_a) = (pa.body.radius.0, pa.body.temperature.0, pa.offset.0);
        let (rb, theta_b, off_b) = (pb.body.radius.0, pb.body.temperature.0, pb.offset.0);
        if agg_a == agg_b {
            continue; // one aggregate: its primaries never approach each other
        }
        let Ok([(mut ga, members_a), (mut gb, members_b)]) =
            aggregates.get_many_mut([agg_a, agg_b])
        else {
            continue;
        };
        let body_a = PairBody {
            mass: ga.mass,
            radius: ra,
            velocity: ga.velocity,
            temperature: theta_a,
        };
        let body_b = PairBody {
            mass: gb.mass,
            radius: rb,
            velocity: gb.velocity,
            temperature: theta_b,
        };
        let (out, elastic) = solve(
            (&model, &settings),
            &body_a,
            &body_b,
            contact,
            now,
            guard.as_deref_mut(),
        );
        if elastic {
            apply.counters.collapse_elastic += 1;
        }
        // The law's heat per side, as a rise shared by every primary of the side.
        let rise_a = out.temperature_i - theta_a;
        let rise_b = out.temperature_j - theta_b;
        // A bond hands the primaries of the aggregate with the larger id to the other,
        // each offset moved by `shift` into the keeper's frame: x_b − x_a is the
        // separation met, so a primary of B lies at off_a + s + (off_k − off_b).
        let s = contact.separation;
        let keep_a = ga.id < gb.id;
        let (shift_a, shift_b) = match (out.bonded, keep_a) {
            (false, _) => (DVec3::ZERO, DVec3::ZERO),
            (true, true) => (DVec3::ZERO, off_a + s - off_b),
            (true, false) => (off_b - s - off_a, DVec3::ZERO),
        };
        // A bouncing pair found overlapping (by rounding, on the event core) is pushed
        // apart to touching as spheres are (§5.3), each aggregate moving whole.
        let (push_a, push_b) = if out.bonded {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            push_apart(
                settings.separation,
                contact,
                (ra, rb),
                (ga.mass, gb.mass),
                (out.velocity_i, out.velocity_j),
            )
        };
        if push_a != DVec3::ZERO || push_b != DVec3::ZERO {
            apply.clock.bodies_pushed = true;
        }
        for (members, touching, velocity, temperature, rise, shift, push) in [
            (
                members_a,
                contact.a,
                out.velocity_i,
                out.temperature_i,
                rise_a,
                shift_a,
                push_a,
            ),
            (
                members_b,
                contact.b,
                out.velocity_j,
                out.temperature_j,
                rise_b,
                shift_b,
                push_b,
            ),
        ] {
            for &e in members.entities() {
                let Ok(mut p) = primaries.get_mut(e) else {
                    continue;
                };
                let before = Totals::of_body(
                    p.body.mass.0,
                    p.body.velocity.0,
                    p.body.temperature.0,
                    heat_capacity,
                );
                events.touch(e, before);
                let lazy = LazyBody::of(
                    &mut p.body.position,
                    &mut p.body.velocity,
                    p.body.mass,
                    p.body.radius,
                    &mut p.body.temperature,
                    &mut p.body.hardness,
                    &mut p.body.local_time,
                );
                bring_to(now, &clockwork, lazy).enter(&mut *apply.ledger);
                p.body.velocity.0 = velocity;
                // The touching primary takes the law's temperature, the others its rise
                // (so an aggregate of one is exactly a sphere of the coalesce mode).
                p.body.temperature.0 = if e == touching {
                    temperature
                } else {
                    p.body.temperature.0 + rise
                };
                p.body.hardness.0 = material.hardness(p.body.temperature.0);
                p.offset.0 += shift;
                if push != DVec3::ZERO {
                    p.body.position.0 = geometry.wrap(p.body.position.0 + push);
                }
            }
        }
        ga.velocity = out.velocity_i;
        gb.velocity = out.velocity_j;
        if out.bonded {
            let (keep, gone, gone_members) = if keep_a {
                (agg_a, agg_b, members_b)
            } else {
                (agg_b, agg_a, members_a)
            };
            let mass = ga.mass + gb.mass;
            ga.mass = mass;
            gb.mass = mass;
            for &e in gone_members.entities() {
                commands.entity(e).insert(MemberOf(keep));
            }
            commands.entity(gone).despawn();
        }
        apply.book(contact, (&body_a, &body_b), &out);
    }
    changed.0 = true;
}

/// How far each aggregate of a bouncing pair moves so that its touching primaries
/// overlap no more [m]: the spheres' rule (§5.3, `impact.separation`) with the
/// aggregates' masses and outgoing velocities and the touching primaries' radii; zero
/// when they do not overlap.
fn push_apart(
    separation: Separation,
    contact: &Contact,
    (ra, rb): (f64, f64),
    (ma, mb): (f64, f64),
    (va, vb): (DVec3, DVec3),
) -> (DVec3, DVec3) {
    let distance = contact.separation.length();
    let overlap = ra + rb - distance;
    if overlap <= 0.0 {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    match separation {
        Separation::Normal => {
            let total = ma + mb;
            (
                -(contact.normal * (overlap * mb / total)),
                contact.normal * (overlap * ma / total),
            )
        }
        Separation::Velocities => {
            let shortfall = 1.0 - distance / (ra + rb);
            (
                va.normalize_or_zero() * (ra * shortfall),
                vb.normalize_or_zero() * (rb * shortfall),
            )
        }
    }
}

/// One aggregate as a restart snapshot keeps it: id, mass [kg], velocity [m/s], and its
/// primaries in the order they joined, each by stable id with its offset [m].
type SavedAggregate = (u64, f64, DVec3, Vec<(u64, DVec3)>);

/// The restart part of rigid scenes (engine/restart.rs): every aggregate with its
/// primaries, so that a resumed run continues bit for bit (the members' order is kept:
/// it is the order a contact brings them forward in).
pub fn restart_part() -> agglo_engine::restart::RestartPart {
    agglo_engine::restart::RestartPart {
        name: "rigid_aggregates",
        save: |world| {
            let mut saved: Vec<SavedAggregate> = Vec::new();
            if let Some(mut query) = world.try_query::<(&Aggregate, &Members)>() {
                for (aggregate, members) in query.iter(world) {
                    let primaries = members
                        .entities()
                        .iter()
                        .filter_map(|&e| {
                            let id = world.get::<ParticleId>(e)?.0;
                            Some((id, world.get::<Offset>(e)?.0))
                        })
                        .collect();
                    saved.push((aggregate.id, aggregate.mass, aggregate.velocity, primaries));
                }
            }
            saved.sort_by_key(|a| a.0);
            postcard::to_allocvec(&saved).expect("aggregates always encode")
        },
        load: |world, bytes| {
            let saved: Vec<SavedAggregate> =
                postcard::from_bytes(bytes).map_err(|e| e.to_string())?;
            let old: Vec<Entity> = world
                .query_filtered::<Entity, With<Aggregate>>()
                .iter(world)
                .collect();
            for entity in old {
                world.despawn(entity);
            }
            let by_id: std::collections::HashMap<u64, Entity> = world
                .query_filtered::<(Entity, &ParticleId), With<Particle>>()
                .iter(world)
                .map(|(e, id)| (id.0, e))
                .collect();
            for (id, mass, velocity, primaries) in saved {
                let aggregate = world.spawn(Aggregate { id, mass, velocity }).id();
                for (primary, offset) in primaries {
                    let Some(&entity) = by_id.get(&primary) else {
                        return Err(format!(
                            "aggregate {id} names primary {primary}, which the snapshot lacks"
                        ));
                    };
                    world
                        .entity_mut(entity)
                        .insert((MemberOf(aggregate), Offset(offset)));
                }
            }
            Ok(())
        },
    }
}
