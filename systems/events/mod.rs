//! The event-driven core (docs/model.md §4): a step lands on the next contact and
//! costs O(k log N) for the k bodies it touches.
//!
//! Two systems replace the stepped core's contact detection and step-size choice:
//! - [`pop_due_contacts`] (stage `Contact`) pops every event due now from the
//!   calendar — cell crossings and stale predictions are handled on the way — and
//!   turns the due contacts into this step's [`ContactList`]: sorted by ids, at most
//!   one impact per body; the bodies met are brought to the current time;
//! - [`schedule_next_step`] (stage `TimeStep`) files what the step changed (touched,
//!   spawned, despawned bodies, from [`StepEvents`]), re-predicts those bodies only,
//!   advances the calendar past crossings and stale events to the next real contact,
//!   and sets Δt to reach it (bounded by Δt_max and T).
//!
//! Force systems act at the start of a step, over the interval just completed (see
//! `SimBuilder::add_force_systems`): the bodies they change are filed with the rest.
//!
//! Drift, periodic wrapping and cooling need no system: they happen when a body is
//! brought to the current time (`engine/bodies.rs`).

pub mod calendar;
pub mod cells;
pub mod core;
pub mod resync;
pub mod slot_ids;

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::cloud::PrimaryGrain;
use agglo_engine::field::Field;
use agglo_engine::params::{RunBooks, SceneConstants};
use agglo_engine::scene::TimeControl;
use glam::DVec3;

use self::calendar::EventKind;
use self::core::{EventCore, Trajectory, morton_key};
use agglo_engine::aggregates::MemberOf;
use agglo_engine::bodies::{Clockwork, LazyBody, bring_to};
use agglo_engine::components::{
    Hardness, LocalTime, Mass, Particle, ParticleId, Position, Radius, Temperature, Velocity,
};
use agglo_engine::resources::{
    BoxGeometry, Contact, ContactList, Counters, ForceKicks, SimClock, StepEvents,
};
use agglo_engine::restart::Checkpoints;
use agglo_engine::scene::MergeMode;
use agglo_engine::totals::Totals;

/// Events closer than this (relative to t) count as simultaneous.
const SIMULTANEOUS: f64 = 1e-13;

/// A body met by a due contact: brought to now (every state that changes in flight,
/// writable) and read for the contact's geometry.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct DueBody {
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
    /// Position [m].
    pub position: &'static mut Position,
    /// Velocity [m/s].
    pub velocity: &'static mut Velocity,
    /// Mass [kg].
    pub mass: &'static Mass,
    /// Radius [m].
    pub radius: &'static Radius,
    /// Temperature θ [K].
    pub temperature: &'static mut Temperature,
    /// Hardness H [Pa].
    pub hardness: &'static mut Hardness,
    /// The time the body's state is at [s] (event core: bodies are brought forward lazily).
    pub local_time: &'static mut LocalTime,
}

type LazyQuery<'w, 's> = Query<'w, 's, DueBody, With<Particle>>;

/// What a body's predicted flight is made from: its state at its reference time.
#[derive(QueryData)]
pub struct FlightData {
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
    /// Position [m].
    pub position: &'static Position,
    /// Velocity [m/s].
    pub velocity: &'static Velocity,
    /// Mass [kg].
    pub mass: &'static Mass,
    /// Radius [m].
    pub radius: &'static Radius,
    /// The time the body's state is at [s] (event core: bodies are brought forward lazily).
    pub local_time: &'static LocalTime,
}

type ReadQuery<'w, 's> = Query<'w, 's, FlightData, With<Particle>>;

fn horizon(now: f64) -> f64 {
    now + SIMULTANEOUS * now.abs().max(f64::MIN_POSITIVE)
}

/// Build the core from the bodies in the world (at t = 0) and predict every body; the
/// scene's field, if any, decides how bodies fly (docs/model.md §4.7).
pub fn build_core(world: &mut World, brute_force: bool) -> EventCore {
    // The grid moves with the cloud's mean velocity (see `EventCore`).
    let frame_velocity = mean_velocity(world);
    core_from_world(world, brute_force, frame_velocity, 0.0)
}

/// The mass-weighted mean velocity of the bodies in the world [m/s].
fn mean_velocity(world: &mut World) -> DVec3 {
    let mut momentum = DVec3::ZERO;
    let mut mass = 0.0;
    for (m, v) in world
        .query_filtered::<(&Mass, &Velocity), With<Particle>>()
        .iter(world)
    {
        momentum += m.0 * v.0;
        mass += m.0;
    }
    if mass > 0.0 {
        momentum / mass
    } else {
        DVec3::ZERO
    }
}

/// The core of the bodies in the world, every body predicted from `now` [s] (all must
/// be at their state at `now` or before), with the grid's frame flying from
/// `frame_velocity` at t = 0. A pure function of the world: the restart's rebuild
/// (`resync.rs`) calls it too.
fn core_from_world(
    world: &mut World,
    brute_force: bool,
    frame_velocity: DVec3,
    now: f64,
) -> EventCore {
    let half_width = world.resource::<BoxGeometry>().half_width;
    let primary = world.resource::<PrimaryGrain>().radius;
    let primary_mass = world.resource::<PrimaryGrain>().mass;
    let field = world.get_resource::<Field>().copied().unwrap_or_default();
    let mut rows: Vec<Trajectory> = world
        .query_filtered::<(
            Entity,
            &ParticleId,
            &Position,
            &Velocity,
            &Mass,
            &Radius,
            &LocalTime,
        ), With<Particle>>()
        .iter(world)
        .map(|(e, id, p, v, m, r, t)| Trajectory {
            entity: e,
            id: id.0,
            position: p.0,
            velocity: v.0,
            t_ref: t.0,
            radius: r.0,
            tau: field.relaxation_time(m.0, r.0),
        })
        .collect();
    // Slots in Morton (Z-curve) order of position: bodies close in space get slots close
    // in memory, so the neighbour scans of a prediction stay in cache. Slot numbers never
    // decide anything (ties are broken by stable ids), so any order is deterministic. The
    // key is computed once per body (the sort is O(N log N) comparisons; a checkpoint
    // rebuilds the core, see `resync.rs`).
    rows.sort_by_cached_key(|t| (morton_key(t.position, half_width), t.id));
    let min_radius = rows.iter().map(|t| t.radius).fold(primary, f64::min);
    let mut core = EventCore::new(
        half_width,
        min_radius,
        rows.len(),
        frame_velocity,
        brute_force,
    );
    // The grid's frame starts with the cloud's mean velocity and flies as a primary
    // grain does (falls with g; under drag relaxes to u + g τ0 as the cloud does).
    let tau0 = field.relaxation_time(primary_mass, primary);
    core.set_field(field, tau0);
    let slots: Vec<u32> = rows.into_iter().map(|t| core.insert(t)).collect();
    for slot in slots {
        core.schedule(slot, now);
    }
    core
}

/// Stage `Contact`: this step's contacts from the calendar.
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn pop_due_contacts(
    mut core: ResMut<EventCore>,
    scene: SceneConstants,
    mut bodies: LazyQuery,
    mut contacts: ResMut<ContactList>,
    books: RunBooks,
    mut candidates: Local<Vec<(u64, u64, u32, u32)>>,
    mut taken: Local<Vec<u64>>,
    // Rigid scenes (docs/model.md §6.1): each primary's aggregate, which takes at most
    // one impact per step (never read in coalesce scenes).
    aggregate_of: Query<&MemberOf>,
) {
    let SceneConstants {
        material,
        geometry,
        options,
        field,
        ..
    } = scene;
    let RunBooks {
        clock,
        mut counters,
        mut ledger,
        mut events,
        ..
    } = books;
    contacts.contacts.clear();
    candidates.clear();
    let now = clock.time;
    let due = horizon(now);
    while let Some((slot, event)) = core.peek() {
        if event.time > due {
            break;
        }
        core.prefetch_runner_up();
        // A crossing, refresh or stale prediction is replaced by the body's next event in
        // place (one sift instead of a pop and a push; the calendar's order is by
        // (time, id) alone, so the events come out the same).
        match event.kind {
            EventKind::Crossing { axis, step } => {
                core.cross_and_schedule(slot, axis, step, event.time.max(now));
            }
            EventKind::Refresh => core.schedule(slot, event.time.max(now)),
            EventKind::Contact {
                slot: partner,
                counter,
            } => {
                if !core.is_current(partner, counter) {
                    core.stats.stale += 1;
                    core.schedule(slot, event.time.max(now));
                    continue;
                }
                core.pop();
                let (a, b) = (core.id_of(slot), core.id_of(partner));
                let (sa, sb) = if a < b {
                    (slot, partner)
                } else {
                    (partner, slot)
                };
                candidates.push((a.min(b), a.max(b), sa, sb));
                // This slot's event is used up: predict it again after the step.
                events.repredict.push(slot);
            }
        }
    }
    if candidates.is_empty() {
        return;
    }
    // Ordered by ids; a pair predicted from both sides is one candidate.
    candidates.sort_unstable();
    candidates.dedup_by_key(|c| (c.0, c.1));
    let clockwork = Clockwork::new(&geometry, &material, &options).with_field(field.as_deref());
    let heat_capacity = material.C;
    taken.clear();
    let rigid = options.merge_mode == MergeMode::Rigid;
    for &(_, _, sa, sb) in candidates.iter() {
        let (ea, eb) = (core.entity_of(sa), core.entity_of(sb));
        // What may take one impact this step: a body, or in a rigid scene its aggregate.
        let (ka, kb) = if rigid {
            let of = |e: Entity| aggregate_of.get(e).map_or(e, |m| m.0).to_bits();
            (of(ea), of(eb))
        } else {
            (u64::from(sa), u64::from(sb))
        };
        if taken.contains(&ka) || taken.contains(&kb) {
            counters.deferred_contacts += 1;
            continue;
        }
        let Ok([mut a, mut b]) = bodies.get_many_mut([ea, eb]) else {
            continue;
        };
        // Each body's contribution to the totals before it is brought forward: the heat
        // it loses on the way is tallied in the ledger and shows in its state after.
        let before_a = Totals::of_body(a.mass.0, a.velocity.0, a.temperature.0, heat_capacity);
        let before_b = Totals::of_body(b.mass.0, b.velocity.0, b.temperature.0, heat_capacity);
        for body in [&mut a, &mut b] {
            let lazy = LazyBody::of(
                &mut body.position,
                // Velocity changes only in a field; its change ticks are not used.
                body.velocity.bypass_change_detection(),
                body.mass,
                body.radius,
                &mut body.temperature,
                &mut body.hardness,
                &mut body.local_time,
            );
            bring_to(now, &clockwork, lazy).enter(&mut ledger);
        }
        let reach = a.radius.0 + b.radius.0;
        let relative = a.velocity.0 - b.velocity.0;
        let separation = core.contact_separation(a.position.0, b.position.0, reach, relative);
        let distance = separation.length();
        let normal = separation / distance;
        // Approaching along the line of centres (rounding may say otherwise for a
        // grazing pair: then there is nothing to resolve).
        if distance == 0.0 || relative.dot(normal) <= 0.0 {
            continue;
        }
        taken.push(ka);
        taken.push(kb);
        events.touch(ea, before_a);
        events.touch(eb, before_b);
        contacts.contacts.push(Contact {
            a: ea,
            b: eb,
            id_a: a.id.0,
            id_b: b.id.0,
            normal,
            separation,
            gap: distance - reach,
        });
    }
}

/// A body's trajectory as the world holds it (None if the entity is gone).
fn trajectory_of(bodies: &ReadQuery, field: &Field, entity: Entity) -> Option<Trajectory> {
    let body = bodies.get(entity).ok()?;
    Some(Trajectory {
        entity,
        id: body.id.0,
        position: body.position.0,
        velocity: body.velocity.0,
        t_ref: body.local_time.0,
        radius: body.radius.0,
        tau: field.relaxation_time(body.mass.0, body.radius.0),
    })
}

/// File the step's changes in the core and re-predict the bodies they touched.
fn file_changes(
    core: &mut EventCore,
    events: &mut StepEvents,
    bodies: &ReadQuery,
    field: &Field,
    now: f64,
) {
    let start = events.filed;
    // The slots to re-predict gather in `repredict` (already holding those whose event a
    // step used up): a buffer kept across steps, so nothing is allocated per step.
    let affected = &mut events.repredict;
    for k in events.filed_despawned..events.despawned.len() {
        core.remove(events.despawned[k]);
    }
    events.filed_despawned = events.despawned.len();
    for k in events.filed_spawned..events.spawned.len() {
        let entity = events.spawned[k];
        if let Some(trajectory) = trajectory_of(bodies, field, entity) {
            affected.push(core.insert(trajectory));
        }
    }
    events.filed_spawned = events.spawned.len();
    // Update every touched body before predicting any, so that predictions name the
    // partners' new counters.
    for k in start..events.touched.len() {
        let entity = events.touched[k].0;
        let Some(now_t) = trajectory_of(bodies, field, entity) else {
            continue; // merged away or fragmented: already removed
        };
        let Some(slot) = core.slot_of(now_t.id) else {
            continue;
        };
        let t = core.trajectory(slot);
        let unchanged = t.velocity == now_t.velocity
            && t.radius == now_t.radius
            && t.position == now_t.position
            && t.t_ref == now_t.t_ref;
        if !unchanged {
            core.update(slot, now_t);
        }
        affected.push(slot);
    }
    events.filed = events.touched.len();
    affected.sort_unstable();
    affected.dedup();
    for &slot in affected.iter() {
        if core.slot_alive(slot) {
            core.schedule(slot, now);
        }
    }
    affected.clear();
}

/// Pop crossings, refreshes and stale predictions until the calendar's top is a real
/// contact (or lies beyond `limit`).
fn settle(core: &mut EventCore, now: f64, limit: f64) {
    while let Some((slot, event)) = core.peek() {
        if event.time > limit {
            return;
        }
        core.prefetch_runner_up();
        // Replaced in place, as in `pop_due_contacts`.
        match event.kind {
            EventKind::Crossing { axis, step } => {
                core.cross_and_schedule(slot, axis, step, event.time.max(now));
            }
            EventKind::Refresh => {
                core.schedule(slot, event.time.max(now));
            }
            EventKind::Contact {
                slot: partner,
                counter,
            } => {
                if core.is_current(partner, counter) {
                    return;
                }
                core.stats.stale += 1;
                core.schedule(slot, event.time.max(now));
            }
        }
    }
}

/// Δt to the calendar's next event, bounded by Δt_max and the time left.
fn step_to_next_event(
    core: &EventCore,
    clock: &SimClock,
    end: f64,
    dt_max: f64,
    kicks: &ForceKicks,
    checkpoint: Option<f64>,
) -> f64 {
    let now = clock.time;
    let remaining = (end - now).max(0.0);
    let next = core.peek().map_or(f64::INFINITY, |(_, e)| e.time);
    // Land on the next kick of forces that declared an interval.
    let to_kick = kicks.next().map_or(f64::INFINITY, |t| (t - now).max(0.0));
    // And on the next checkpoint, where the core is rebuilt (`resync.rs`).
    let to_checkpoint = checkpoint.map_or(f64::INFINITY, |t| (t - now).max(0.0));
    (next - now)
        .max(0.0)
        .min(dt_max)
        .min(remaining)
        .min(to_kick)
        .min(to_checkpoint)
}

/// Stage `TimeStep`: re-predict what changed and choose Δt to the next contact.
pub fn schedule_next_step(
    mut core: ResMut<EventCore>,
    mut clock: ResMut<SimClock>,
    time: Res<TimeControl>,
    bodies: ReadQuery,
    mut events: ResMut<StepEvents>,
    field: Option<Res<Field>>,
    // The times steps must land on: force kicks and restart checkpoints.
    (kicks, checkpoints): (Res<ForceKicks>, Option<Res<Checkpoints>>),
) {
    let now = clock.time;
    let field = field.as_deref().copied().unwrap_or_default();
    file_changes(&mut core, &mut events, &bodies, &field, now);
    let dt_max = time.stepping.dt_max();
    let limit = (now + dt_max).min(time.end);
    settle(&mut core, now, limit);
    if core.due_for_renumbering() {
        core.renumber(now);
    }
    clock.clamped_at_min = false;
    let checkpoint = checkpoints.map(|c| c.next());
    clock.dt = step_to_next_event(&core, &clock, time.end, dt_max, &kicks, checkpoint);
}

/// Count the core's missed contacts into the run's counters (stage `Boundary`).
pub fn report_overlaps(core: Res<EventCore>, mut counters: ResMut<Counters>) {
    counters.overlap_violations = core.stats.deep_overlaps;
}
