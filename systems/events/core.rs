//! The event core's bookkeeping: body slots with their ballistic trajectories, the
//! cell grid and the calendar, and the prediction of each body's next event
//! (docs/model.md §4). Pure data: no ECS queries, so it can be tested and
//! benchmarked alone; `super` connects it to the world.
//!
//! A slot holds a copy of a body's trajectory — position (wrapped into the box) and
//! velocity at its reference time t_ref, its radius and its drag relaxation time —
//! refreshed whenever the body is touched. Between touches a body flies in closed form
//! (docs/model.md §4.7): ballistically, r(t) = r_ref + v (t − t_ref), without a field;
//! on a parabola in a uniform field g; along the drag flight of
//! `agglo_engine::laws::flight` with drag. Predictions need no other state.
//!
//! **Fields.** Under uniform g the grid's frame falls with g: in that frame every body
//! moves in a straight line, and two bodies move in a straight line relative to each
//! other, so crossings and contacts are predicted exactly as without a field. Under
//! drag the frame moves at the terminal velocity of a primary grain; crossings and
//! contacts are found by the safeguarded search of `laws::flight` along the exact
//! flights, limited to the body's next crossing (no later contact can be its next
//! event), so the cost per event stays O(log N).

use bevy_ecs::prelude::*;
use glam::DVec3;

use super::calendar::{Calendar, Event, EventKind, permute_in_place};
use super::cells::{CellGrid, Partner, prefetch, round_fast};
use super::slot_ids::SlotIds;
use agglo_engine::field::{Field, FieldKind};
use agglo_engine::laws::flight::{Flight, Search, contact_search, wall_crossing};
// The exact time to contact along a line, with the grazing rule (laws::flight).
use agglo_engine::laws::flight::line_contact as contact_time;
use agglo_engine::laws::grid::IMAGES;
use agglo_engine::resources::BoxGeometry;

const NONE: u32 = u32::MAX;

/// A pair found overlapping deeper than this fraction of b_i + b_j while approaching,
/// although it did not overlap when the later of the two was last changed, is a
/// contact the core missed.
const DEEP_OVERLAP: f64 = 1e-6;

/// True when a pair at separation `d` (now) with relative velocity `u` approaches while
/// overlapping deeply, but did not overlap `since` seconds ago: a missed contact.
/// (Overlaps made by merging or fragmentation existed when the body was changed.)
#[inline]
fn newly_overlapping(d: DVec3, u: DVec3, reach: f64, since: f64) -> bool {
    d.dot(u) < 0.0
        && d.length() < reach * (1.0 - DEEP_OVERLAP)
        && (d - u * since).length() >= reach * (1.0 - DEEP_OVERLAP)
}

/// A prediction through periodic images is renewed after the partners have moved this
/// fraction of the box side relative to the owner.
const REFRESH_FRACTION: f64 = 0.25;

/// The first contact along curved flights within `horizon` (see `laws::flight`, which
/// applies the grazing rule of [`contact_time`] too); `(t, true)` when the search was cut
/// short and only says "not before t".
#[inline]
fn curved_contact_time(
    d: DVec3,
    va: DVec3,
    vb: DVec3,
    fa: &Flight,
    fb: &Flight,
    reach: f64,
    horizon: f64,
) -> Option<(f64, bool)> {
    match contact_search(d, va, vb, fa, fb, reach, horizon) {
        Search::At(t) => Some((t, false)),
        Search::NotBefore(t) => Some((t, true)),
        Search::Clear => None,
    }
}

/// Offer an event `t` [s] after `now` with tie-breaker `tie`: kept if it is earlier than
/// the best so far (or as early with a smaller tie-breaker).
#[inline]
fn offer(best: &mut Option<(f64, u64, Event)>, now: f64, t: f64, tie: u64, kind: EventKind) {
    if best.is_none_or(|(bt, btie, _)| t < bt || (t == bt && tie < btie)) {
        *best = Some((
            t,
            tie,
            Event {
                time: now + t,
                kind,
            },
        ));
    }
}

/// A slot's earliest contact at its last prediction (partner NONE: none; UNKNOWN: the
/// prediction could not say, so the next one scans every candidate).
#[derive(Debug, Clone, Copy)]
struct Pending {
    /// Absolute time of the contact [s].
    time: f64,
    partner: u32,
    /// The partner's event counter when predicted.
    counter: u32,
}

const UNKNOWN: u32 = u32::MAX - 1;

impl Pending {
    const NONE: Pending = Pending {
        time: f64::INFINITY,
        partner: NONE,
        counter: 0,
    };
    const UNKNOWN: Pending = Pending {
        time: f64::INFINITY,
        partner: UNKNOWN,
        counter: 0,
    };
}

/// What a prediction scans.
#[derive(Debug, Clone, Copy)]
enum Scan {
    /// Every candidate partner.
    Full,
    /// After a crossing from own-level cell `old` along `axis` by `step`: the slab ahead,
    /// against the earliest contact `known` from before (None: there was none).
    Slab {
        old: [u16; 3],
        axis: usize,
        step: i8,
        known: Option<Pending>,
    },
}

/// One body's trajectory as the event core sees it.
#[derive(Debug, Clone, Copy)]
pub struct Trajectory {
    /// The body's entity.
    pub entity: Entity,
    /// The body's stable id ([`ParticleId`]).
    pub id: u64,
    /// Position at `t_ref`, wrapped into [−D, D) [m].
    pub position: DVec3,
    /// Velocity [m/s].
    pub velocity: DVec3,
    /// Reference time t_ref [s].
    pub t_ref: f64,
    /// Radius [m].
    pub radius: f64,
    /// Drag relaxation time τ [s] (∞ without drag).
    pub tau: f64,
}

impl Trajectory {
    fn path(&self) -> Path {
        Path {
            position: self.position,
            velocity: self.velocity,
            t_ref: self.t_ref,
            radius: self.radius,
        }
    }
}

/// The part of a trajectory a prediction reads for every candidate partner: one cache
/// line per body (the entity, id and τ are read only for the partner an event names, and
/// live in arrays of their own), so a neighbour scan touches one line per partner.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct Path {
    /// Position at `t_ref`, wrapped into [−D, D) [m].
    position: DVec3,
    /// Velocity [m/s].
    velocity: DVec3,
    /// Reference time t_ref [s].
    t_ref: f64,
    /// Radius [m].
    radius: f64,
}

impl Path {
    /// Unwrapped position at time t [m] on a straight flight.
    #[inline]
    fn at(&self, t: f64) -> DVec3 {
        self.position + self.velocity * (t - self.t_ref)
    }
}

pub use agglo_engine::resources::EventStats;

/// The event core.
#[derive(Resource, Debug, Clone)]
pub struct EventCore {
    half_width: f64,
    /// Velocity of the frame the grid moves with [m/s]: the mean velocity of the cloud, so
    /// that a bulk drift (P04's v̄ = (10, 10, 100) m/s) causes no cell crossings. Any
    /// constant velocity is correct; only relative positions decide contacts.
    frame_velocity: DVec3,
    /// How the grid's frame flies from `frame_velocity` at t = 0: straight without a
    /// field, falling with g under uniform g (every body then moves in a straight line in
    /// it), as a primary grain under drag (relaxing to its terminal velocity, so the
    /// cloud's bulk motion causes few crossings).
    frame_flight: Flight,
    /// The field bodies fly in, and its kind.
    field: Field,
    kind: FieldKind,
    /// Per slot: the path (hot), the entity and stable id, τ (under drag only: empty
    /// otherwise, ∞ is implied), the event counter, whether a body is there.
    paths: Vec<Path>,
    entities: Vec<Entity>,
    ids: Vec<u64>,
    taus: Vec<f64>,
    counters: Vec<u32>,
    /// Per slot: its earliest contact at its last prediction (see `cross_and_schedule`).
    pending: Vec<Pending>,
    alive: Vec<bool>,
    free: Vec<u32>,
    slot_of_id: SlotIds,
    grid: CellGrid,
    calendar: Calendar,
    /// Predict against every body through every image (the O(N²) reference).
    brute_force: bool,
    /// A prediction's candidate partners (scratch, kept to avoid allocating).
    candidates: Vec<(u32, Partner)>,
    /// Scan only the slab ahead after a crossing when that is exact (on by default).
    slab_scans: bool,
    /// Predictions made when the slots were last renumbered.
    predictions_at_renumber: u64,
    /// Renumber slots periodically (on by default; tests show that it changes no result).
    renumbering: bool,
    /// What the core has counted so far: crossings, stale events, predictions, pair
    /// tests, deep overlaps, renumberings.
    pub stats: EventStats,
}

/// Slots are renumbered in Z-order once this many predictions per live body have been
/// made since the last time: an O(N log N) sort every O(N) events, O(log N) per event.
const RENUMBER_EVERY: u64 = 8;

/// Interleaved bits of a position in [−D, D)³ quantised to 1024 steps per axis: a
/// Z-curve key, so that bodies close in space get slots close in memory.
pub fn morton_key(position: DVec3, half_width: f64) -> u64 {
    let quantise = |x: f64| {
        let f = ((x + half_width) / (2.0 * half_width)).clamp(0.0, 1.0 - f64::EPSILON);
        (f * 1024.0) as u64
    };
    let spread = |mut v: u64| {
        // 10 bits → every third bit of 30.
        v &= 0x3ff;
        v = (v | (v << 16)) & 0x0300_00ff;
        v = (v | (v << 8)) & 0x0300_f00f;
        v = (v | (v << 4)) & 0x030c_30c3;
        (v | (v << 2)) & 0x0924_9249
    };
    spread(quantise(position.x))
        | (spread(quantise(position.y)) << 1)
        | (spread(quantise(position.z)) << 2)
}

impl EventCore {
    /// An empty core for the periodic cube of half-width `half_width` [m].
    pub fn new(
        half_width: f64,
        min_radius: f64,
        bodies: usize,
        frame_velocity: DVec3,
        brute_force: bool,
    ) -> Self {
        Self {
            half_width,
            frame_velocity,
            frame_flight: Flight::Ballistic,
            field: Field::default(),
            kind: FieldKind::None,
            paths: Vec::with_capacity(bodies),
            entities: Vec::with_capacity(bodies),
            ids: Vec::with_capacity(bodies),
            taus: Vec::new(),
            counters: Vec::with_capacity(bodies),
            alive: Vec::with_capacity(bodies),
            free: Vec::new(),
            slot_of_id: SlotIds::with_capacity(bodies),
            grid: CellGrid::new(half_width, min_radius, bodies),
            calendar: Calendar::default(),
            brute_force,
            candidates: Vec::new(),
            slab_scans: true,
            pending: Vec::with_capacity(bodies),
            predictions_at_renumber: 0,
            renumbering: true,
            stats: EventStats::default(),
        }
    }

    /// Carry on the counts of the core this one replaces (the restart's rebuild,
    /// `resync.rs`). The renumbering schedule restarts from them: a rebuilt core's slots
    /// are already in Z-order.
    pub fn carry_stats(&mut self, stats: EventStats) {
        self.stats = stats;
        self.predictions_at_renumber = stats.predictions;
    }

    /// Velocity of the grid's frame at t = 0 [m/s] (kept by restart snapshots).
    pub fn frame_velocity(&self) -> DVec3 {
        self.frame_velocity
    }

    /// Fly bodies in `field` (set before any body is inserted). The grid's frame flies
    /// as a body of relaxation time `tau` [s] would (a primary grain's): under uniform g
    /// it falls with g, under drag it relaxes to that body's terminal velocity.
    pub fn set_field(&mut self, field: Field, tau: f64) {
        self.kind = field.kind();
        self.field = field;
        self.frame_flight = field.flight_with(tau);
    }

    /// Drag relaxation time of a slot's body [s] (∞ without drag).
    #[inline]
    fn tau(&self, slot: u32) -> f64 {
        self.taus
            .get(slot as usize)
            .copied()
            .unwrap_or(f64::INFINITY)
    }

    /// The flight of a slot's body between events.
    #[inline]
    fn flight_of(&self, slot: u32) -> Flight {
        match self.kind {
            FieldKind::None => Flight::Ballistic,
            FieldKind::Uniform => self.frame_flight,
            FieldKind::Drag => self.field.flight_with(self.tau(slot)),
        }
    }

    /// Unwrapped position of a slot's path at `time` [m].
    #[inline]
    fn position_at(&self, slot: u32, p: &Path, time: f64) -> DVec3 {
        match self.kind {
            FieldKind::None => p.at(time),
            _ => {
                self.flight_of(slot)
                    .advance(p.position, p.velocity, time - p.t_ref)
                    .0
            }
        }
    }

    /// Unwrapped position [m] and velocity [m/s] of a slot's path at `time`.
    #[inline]
    fn state_at(&self, slot: u32, p: &Path, time: f64) -> (DVec3, DVec3) {
        match self.kind {
            FieldKind::None => (p.at(time), p.velocity),
            _ => self
                .flight_of(slot)
                .advance(p.position, p.velocity, time - p.t_ref),
        }
    }

    /// Bytes held by the core (slots, grid, calendar).
    pub fn bytes(&self) -> usize {
        self.paths.capacity() * std::mem::size_of::<Path>()
            + self.pending.capacity() * std::mem::size_of::<Pending>()
            + self.entities.capacity() * std::mem::size_of::<Entity>()
            + self.ids.capacity() * 8
            + self.taus.capacity() * 8
            + self.counters.capacity() * 4
            + self.alive.capacity()
            + self.free.capacity() * 4
            + self.slot_of_id.bytes()
            + self.grid.bytes()
            + self.calendar.bytes()
    }

    fn side(&self) -> f64 {
        2.0 * self.half_width
    }

    fn wrap(&self, r: DVec3) -> DVec3 {
        BoxGeometry {
            half_width: self.half_width,
        }
        .wrap(r)
    }

    /// Where the grid's frame has moved by time t, modulo the box [m].
    fn frame_shift(&self, t: f64) -> DVec3 {
        let shift = match self.kind {
            FieldKind::None => self.frame_velocity * t,
            _ => self.frame_flight.displacement(self.frame_velocity, t),
        };
        let side = self.side();
        let k = shift / side;
        shift - side * DVec3::new(round_fast(k.x), round_fast(k.y), round_fast(k.z))
    }

    /// A slot's position at time t in the grid's moving frame [m].
    fn grid_position(&self, slot: u32, time: f64) -> DVec3 {
        let p = &self.paths[slot as usize];
        self.position_at(slot, p, time) - self.frame_shift(time)
    }

    fn min_image(&self, d: DVec3) -> DVec3 {
        let side = self.side();
        d - side * (d / side).round()
    }

    /// The slot of a stable id, if present.
    pub fn slot_of(&self, id: u64) -> Option<u32> {
        self.slot_of_id.get(id)
    }

    /// The trajectory in a slot.
    pub fn trajectory(&self, slot: u32) -> Trajectory {
        let p = &self.paths[slot as usize];
        Trajectory {
            entity: self.entities[slot as usize],
            id: self.ids[slot as usize],
            position: p.position,
            velocity: p.velocity,
            t_ref: p.t_ref,
            radius: p.radius,
            tau: self.tau(slot),
        }
    }

    /// The stable id of a slot's body.
    pub fn id_of(&self, slot: u32) -> u64 {
        self.ids[slot as usize]
    }

    /// The entity of a slot's body.
    pub fn entity_of(&self, slot: u32) -> Entity {
        self.entities[slot as usize]
    }

    /// Store a trajectory in a slot (the position wrapped into the box).
    fn store(&mut self, slot: u32, t: &Trajectory) {
        let s = slot as usize;
        self.paths[s] = Path {
            position: self.wrap(t.position),
            ..t.path()
        };
        self.entities[s] = t.entity;
        self.ids[s] = t.id;
        if self.kind == FieldKind::Drag {
            self.taus[s] = t.tau;
        }
    }

    /// Add a body; returns its slot.
    pub fn insert(&mut self, trajectory: Trajectory) -> u32 {
        let t = trajectory;
        let slot = match self.free.pop() {
            Some(s) => {
                self.alive[s as usize] = true;
                self.counters[s as usize] = self.counters[s as usize].wrapping_add(1);
                s
            }
            None => {
                self.paths.push(t.path());
                self.entities.push(t.entity);
                self.ids.push(t.id);
                if self.kind == FieldKind::Drag {
                    self.taus.push(t.tau);
                }
                self.alive.push(true);
                self.counters.push(0);
                self.pending.push(Pending::UNKNOWN);
                (self.paths.len() - 1) as u32
            }
        };
        self.store(slot, &t);
        self.pending[slot as usize] = Pending::UNKNOWN;
        self.slot_of_id.set(t.id, slot, self.paths.len());
        let x = self.wrap(self.grid_position(slot, t.t_ref));
        self.grid.insert(slot, t.radius, x);
        slot
    }

    /// Remove the body with stable id `id` (merged away or fragmented).
    pub fn remove(&mut self, id: u64) {
        let Some(slot) = self.slot_of(id) else {
            return;
        };
        self.grid.remove(slot);
        self.calendar.remove(slot, &self.ids);
        self.alive[slot as usize] = false;
        // Any prediction naming this slot is now stale.
        self.counters[slot as usize] = self.counters[slot as usize].wrapping_add(1);
        self.slot_of_id.clear(id);
        self.free.push(slot);
    }

    /// A body's trajectory changed (impact, merge, force): store it, re-file it in the
    /// grid, and invalidate every prediction that named it.
    pub fn update(&mut self, slot: u32, trajectory: Trajectory) {
        let t = trajectory;
        self.store(slot, &t);
        self.pending[slot as usize] = Pending::UNKNOWN;
        self.counters[slot as usize] = self.counters[slot as usize].wrapping_add(1);
        // The logical cell must hold the new position (a merged body sits at the centre
        // of mass, which may be in another cell).
        self.grid.remove(slot);
        let x = self.wrap(self.grid_position(slot, t.t_ref));
        self.grid.insert(slot, t.radius, x);
    }

    /// Earliest scheduled event, if any.
    pub fn peek(&self) -> Option<(u32, Event)> {
        self.calendar.peek()
    }

    /// Ask the memory system for the per-slot data of the body whose event likely
    /// comes after the top's ([`Calendar::runner_up`]), so that its cache misses overlap
    /// with the top's work (a hint: no effect on results).
    pub fn prefetch_runner_up(&self) {
        let Some(slot) = self.calendar.runner_up() else {
            return;
        };
        let s = slot as usize;
        prefetch(&self.paths[s]);
        prefetch(&self.pending[s]);
        prefetch(&self.counters[s]);
        prefetch(&self.alive[s]);
        prefetch(&self.ids[s]);
        self.grid.prefetch_crossing(slot);
    }

    /// Remove the earliest event.
    pub fn pop(&mut self) -> Option<(u32, Event)> {
        self.calendar.pop(&self.ids)
    }

    /// True when a contact predicted with partner counter `counter` still holds.
    pub fn is_current(&self, partner: u32, counter: u32) -> bool {
        self.alive[partner as usize] && self.counters[partner as usize] == counter
    }

    /// Process a cell crossing popped from the calendar and file the body's next event,
    /// predicted at `now`. When the body's earliest contact of its last prediction still
    /// holds and contacts are found exactly (straight relative flights, every body
    /// gridded), only the 9 cells of the slab ahead at each level it moved in are new:
    /// they alone are tested, a third of a full prediction. Else it is predicted afresh.
    pub fn cross_and_schedule(&mut self, slot: u32, axis: u8, step: i8, now: f64) {
        let old = self.grid.place_of(slot).map(|(_, cell)| cell);
        self.grid.cross(slot, axis as usize, step);
        self.stats.crossings += 1;
        let scan = match (old, self.known_contact(slot)) {
            (Some(old), Some(known)) => Scan::Slab {
                old,
                axis: axis as usize,
                step,
                known,
            },
            _ => Scan::Full,
        };
        let event = self.predict_by(slot, now, scan);
        self.calendar.set(slot, event, &self.ids);
    }

    /// The slot's earliest contact found at its last prediction, when that is still
    /// known to be its earliest contact (`Some(None)`: it has none), so that a slab
    /// scan may complete it.
    fn known_contact(&self, slot: u32) -> Option<Option<Pending>> {
        if !self.slab_scans || self.kind == FieldKind::Drag || !self.grid.all_gridded() {
            return None;
        }
        let p = self.pending[slot as usize];
        match p.partner {
            UNKNOWN => None,
            NONE => Some(None),
            partner => self.is_current(partner, p.counter).then_some(Some(p)),
        }
    }

    /// Switch the slab scans after crossings on or off (on by default; off, every
    /// crossing predicts afresh — the reference the tests compare against).
    pub fn set_slab_scans(&mut self, on: bool) {
        self.slab_scans = on;
    }

    /// Predict `slot`'s next event from time `now` and file it in the calendar.
    pub fn schedule(&mut self, slot: u32, now: f64) {
        let event = self.predict(slot, now);
        self.calendar.set(slot, event, &self.ids);
    }

    /// The earliest event of `slot` at or after `now`: a contact with a possible partner
    /// or, for a gridded body, leaving its cell. Ties go to the smaller partner id.
    pub fn predict(&mut self, slot: u32, now: f64) -> Option<Event> {
        self.predict_by(slot, now, Scan::Full)
    }

    /// `predict`, scanning every candidate partner or, after a crossing, only the slab
    /// ahead (see `cross_and_schedule`).
    fn predict_by(&mut self, slot: u32, now: f64, scan: Scan) -> Option<Event> {
        self.stats.predictions += 1;
        let me = self.paths[slot as usize];
        // Positions in the grid's frame: relative positions are the same in any frame.
        let shift = self.frame_shift(now);
        let (x_me, v_me) = self.state_at(slot, &me, now);
        let x_me = x_me - shift;
        let curved = self.kind == FieldKind::Drag;
        let f_me = self.flight_of(slot);
        // Leaving the cell, found first: along a curved flight no contact later than it
        // can be the next event, so it bounds the pair searches. It is offered last, so
        // that a contact at the same time wins the tie.
        let crossing = if self.brute_force {
            None
        } else {
            self.next_crossing(slot, x_me, v_me, &me, now)
        };
        // After a crossing, the earliest contact known from before competes with the slab's
        // (its event time kept as it was predicted).
        let mut best: Option<(f64, u64, Event)> = match scan {
            Scan::Slab { known: Some(p), .. } => Some((
                p.time - now,
                self.ids[p.partner as usize],
                Event {
                    time: p.time,
                    kind: EventKind::Contact {
                        slot: p.partner,
                        counter: p.counter,
                    },
                },
            )),
            _ => None,
        };
        let mut tests = 0u64;
        let mut deep = 0u64;
        // Largest relative speed to a partner paired through all images [m/s].
        let mut fastest_any_image = 0.0f64;
        // A buffer kept across predictions: nothing is allocated per event.
        let mut candidates = std::mem::take(&mut self.candidates);
        {
            let paths = &self.paths;
            let ids = &self.ids;
            let alive = &self.alive;
            let counters = &self.counters;
            let grid = &self.grid;
            let core = &*self;
            // My offset inside my cell at each level, computed once per level.
            let mut rel_cache: [Option<DVec3>; 16] = [None; 16];
            let mut pair = |j: u32, how: Partner| {
                let other = &paths[j as usize];
                let (x_other, v_other) = core.state_at(j, other, now);
                let x_other = x_other - shift;
                let u = v_other - v_me;
                let reach = me.radius + other.radius;
                let since = now - me.t_ref.max(other.t_ref);
                // Where the search may stop: the best event so far, or leaving the cell.
                let horizon = best
                    .map_or(f64::INFINITY, |(t, _, _)| t)
                    .min(crossing.map_or(f64::INFINITY, |(t, _, _)| t));
                let f_other = core.flight_of(j);
                let search = |d: DVec3| {
                    if curved {
                        curved_contact_time(d, v_me, v_other, &f_me, &f_other, reach, horizon)
                    } else {
                        contact_time(d, u, reach).map(|t| (t, false))
                    }
                };
                let missed = |d: DVec3| {
                    if curved {
                        // Overlapping and approaching now, and not when the later of
                        // the two was last changed (found along the flights, only for
                        // a pair that overlaps now).
                        if d.dot(u) >= 0.0 || d.length() >= reach * (1.0 - DEEP_OVERLAP) {
                            return false;
                        }
                        let before = me.t_ref.max(other.t_ref);
                        let moved = (core.position_at(j, other, now)
                            - core.position_at(j, other, before))
                            - (core.position_at(slot, &me, now)
                                - core.position_at(slot, &me, before));
                        (d - moved).length() >= reach * (1.0 - DEEP_OVERLAP)
                    } else {
                        newly_overlapping(d, u, reach, since)
                    }
                };
                let found = match how {
                    Partner::Cell { level, offset } => {
                        let k = level as usize;
                        let w = grid.width(k);
                        let rel_me = *rel_cache[k.min(15)]
                            .get_or_insert_with(|| grid.offset_in_cell(slot, k, x_me));
                        let rel_other = grid.offset_in_cell(j, k, x_other);
                        let cells =
                            DVec3::new(offset[0] as f64, offset[1] as f64, offset[2] as f64);
                        let d = cells * w + rel_other - rel_me;
                        tests += 1;
                        deep += missed(d) as u64;
                        search(d)
                    }
                    Partner::AnyImage => {
                        let speed = if curved {
                            f_me.speed_bound(v_me) + f_other.speed_bound(v_other)
                        } else {
                            u.length()
                        };
                        fastest_any_image = fastest_any_image.max(speed);
                        let side = 2.0 * core.half_width;
                        let d0 = {
                            let d = x_other - x_me;
                            let k = d / side;
                            d - side * DVec3::new(round_fast(k.x), round_fast(k.y), round_fast(k.z))
                        };
                        let mut earliest: Option<(f64, bool)> = None;
                        for image in IMAGES {
                            let d = d0 + side * image;
                            tests += 1;
                            if let Some(t) = search(d) {
                                deep += missed(d) as u64;
                                if earliest.is_none_or(|e| t.0 < e.0) {
                                    earliest = Some(t);
                                }
                            }
                        }
                        earliest
                    }
                };
                match found {
                    Some((t, false)) => offer(
                        &mut best,
                        now,
                        t,
                        ids[j as usize],
                        EventKind::Contact {
                            slot: j,
                            counter: counters[j as usize],
                        },
                    ),
                    // The search was cut short: no contact before t, look again then.
                    Some((t, true)) => offer(&mut best, now, t, u64::MAX, EventKind::Refresh),
                    None => {}
                }
            };
            if self.brute_force {
                for j in 0..paths.len() as u32 {
                    if j != slot && alive[j as usize] {
                        pair(j, Partner::AnyImage);
                    }
                }
            } else {
                // Gather the partners, ask for their data, then test them: the misses
                // overlap (see `CellGrid::gather_candidates`).
                match scan {
                    Scan::Full => {
                        let every = (0..paths.len() as u32).filter(|&j| alive[j as usize]);
                        grid.gather_candidates(slot, every, &mut candidates);
                    }
                    Scan::Slab {
                        old, axis, step, ..
                    } => grid.gather_slab(slot, old, axis, step, &mut candidates),
                }
                for &(j, _) in candidates.iter() {
                    prefetch(&paths[j as usize]);
                    grid.prefetch_place(j);
                }
                for &(j, how) in candidates.iter() {
                    pair(j, how);
                }
            }
        }
        candidates.clear();
        self.candidates = candidates;
        // The 27 images around the minimum image hold every contact while the relative
        // displacement stays below half a box (b_i + b_j < L); refresh well before.
        if fastest_any_image > 0.0 {
            let horizon = REFRESH_FRACTION * self.side() / fastest_any_image;
            offer(&mut best, now, horizon, u64::MAX, EventKind::Refresh);
        }
        self.stats.pair_tests += tests;
        self.stats.deep_overlaps += deep;
        // What a slab scan after the next crossing may start from: the earliest contact,
        // when contacts are exact and nothing was cut short or paired through all images.
        self.pending[slot as usize] = match best {
            _ if curved || fastest_any_image > 0.0 || self.brute_force => Pending::UNKNOWN,
            None => Pending::NONE,
            Some((_, _, e)) => match e.kind {
                EventKind::Contact { slot, counter } => Pending {
                    time: e.time,
                    partner: slot,
                    counter,
                },
                _ => Pending::UNKNOWN,
            },
        };
        if let Some((t, axis, step)) = crossing {
            // A contact at the same time wins the tie (u64::MAX): it is the physical event.
            let kind = if step == 0 {
                EventKind::Refresh // a curved search cut short: look again then
            } else {
                EventKind::Crossing { axis, step }
            };
            offer(&mut best, now, t, u64::MAX, kind);
        }
        best.map(|(_, _, e)| e)
    }

    /// When a gridded body at `x` (grid frame, now) with velocity `v` (now) leaves its
    /// cell: a straight line in the grid's frame without a field or under uniform g (the
    /// frame falls with g), the drag flight's safeguarded search under drag.
    fn next_crossing(
        &self,
        slot: u32,
        x: DVec3,
        v: DVec3,
        me: &Path,
        now: f64,
    ) -> Option<(f64, u8, i8)> {
        match self.kind {
            FieldKind::None => self
                .grid
                .crossing(slot, x, me.velocity - self.frame_velocity),
            // v(now) − (V + g now) = v_ref − g t_ref − V: constant in the falling frame.
            FieldKind::Uniform => {
                let g = self.field.g();
                self.grid
                    .crossing(slot, x, me.velocity - g * me.t_ref - self.frame_velocity)
            }
            FieldKind::Drag => {
                let flight = self.flight_of(slot);
                let frame = self.frame_flight;
                let frame_now = frame.velocity(self.frame_velocity, now);
                self.grid.crossing_by(slot, x, |axis, offset, width| {
                    wall_crossing(
                        offset,
                        v,
                        &flight,
                        frame_now,
                        &frame,
                        axis,
                        width,
                        f64::INFINITY,
                    )
                })
            }
        }
    }

    /// The periodic image of `b`'s centre, relative to `a`'s, of the contact due now at
    /// positions `ra`, `rb` with closing velocity `closing` = v_a − v_b: r_b − r_a for that
    /// image [m]. Small bodies meet through the minimum image. A pair large enough to
    /// reach more than one image takes the image in which it touches or overlaps *and*
    /// approaches — the one the calendar predicted (an overlapping, approaching pair is
    /// due at once) — the least deep of them; only when there is none, the image closest
    /// to touching. Taking the image closest to touching alone could pick a separating
    /// image of a pair that is due through another: the contact was then declined, filed
    /// again for the same instant, and the run stalled.
    pub fn contact_separation(&self, ra: DVec3, rb: DVec3, reach: f64, closing: DVec3) -> DVec3 {
        let d0 = self.min_image(rb - ra);
        if reach <= 0.5 * self.half_width {
            return d0;
        }
        let side = self.side();
        let mut nearest = (d0, (d0.length() - reach).abs());
        let mut due: Option<(DVec3, f64)> = None;
        let touch = 1e-9 * reach;
        for d in std::iter::once(d0).chain(IMAGES.iter().map(|&image| d0 + side * image)) {
            let gap = d.length() - reach;
            if gap.abs() < nearest.1 {
                nearest = (d, gap.abs());
            }
            if gap <= touch && closing.dot(d) > 0.0 && due.is_none_or(|(_, g)| gap.abs() < g) {
                due = Some((d, gap.abs()));
            }
        }
        due.map_or(nearest.0, |(d, _)| d)
    }

    /// True when the slot holds a body.
    pub fn slot_alive(&self, slot: u32) -> bool {
        self.alive.get(slot as usize).copied().unwrap_or(false)
    }

    /// Switch the periodic renumbering of slots on or off (on by default).
    pub fn set_renumbering(&mut self, on: bool) {
        self.renumbering = on;
    }

    /// True when enough predictions were made since the last renumbering.
    pub fn due_for_renumbering(&self) -> bool {
        let live = self.paths.len() - self.free.len();
        self.renumbering
            && live > 1
            && self.stats.predictions - self.predictions_at_renumber >= RENUMBER_EVERY * live as u64
    }

    /// Renumber the live slots in Z-order of their positions at `now`, so that a
    /// prediction's neighbours sit close together in memory again after the cloud has
    /// mixed (cache misses otherwise dominate the cost of an event at large N). Every
    /// trajectory, counter, logical cell and scheduled event moves with its body; slot
    /// numbers decide nothing (ties are broken by stable ids), so the run is unchanged.
    pub fn renumber(&mut self, now: f64) {
        let shift = self.frame_shift(now);
        let mut order: Vec<(u64, u64, u32)> = self
            .live_slots()
            .map(|s| {
                let p = &self.paths[s as usize];
                let x = self.wrap(self.position_at(s, p, now) - shift);
                (morton_key(x, self.half_width), self.ids[s as usize], s)
            })
            .collect();
        order.sort_unstable();
        // A full permutation: live slots to 0..live in Z-order, removed ones after them.
        let live = order.len();
        let mut new_of_old = vec![NONE; self.paths.len()];
        for (new, &(_, _, old)) in order.iter().enumerate() {
            new_of_old[old as usize] = new as u32;
        }
        let removed = new_of_old.iter_mut().filter(|n| **n == NONE);
        for (next, n) in (live as u32..).zip(removed) {
            *n = next;
        }
        // Everything moves in place, except the grid's lists, which are rebuilt from the
        // logical cells after the old ones are dropped: the transient memory is a few
        // bytes per body.
        let places: Vec<Option<(u8, [u16; 3])>> = order
            .iter()
            .map(|&(_, _, old)| self.grid.place_of(old))
            .collect();
        self.grid = self.grid.emptied();
        for (new, place) in places.into_iter().enumerate() {
            if let Some((level, cell)) = place {
                self.grid.insert_at(new as u32, level, cell);
            }
        }
        let alive = &self.alive;
        self.calendar.renumber(&new_of_old, |partner| {
            alive[partner as usize].then(|| new_of_old[partner as usize])
        });
        for p in &mut self.pending {
            if p.partner != NONE && p.partner != UNKNOWN {
                *p = match alive[p.partner as usize] {
                    true => Pending {
                        partner: new_of_old[p.partner as usize],
                        ..*p
                    },
                    false => Pending::UNKNOWN,
                };
            }
        }
        permute_in_place(&mut self.pending, new_of_old.clone());
        permute_in_place(&mut self.paths, new_of_old.clone());
        permute_in_place(&mut self.entities, new_of_old.clone());
        permute_in_place(&mut self.ids, new_of_old.clone());
        if !self.taus.is_empty() {
            permute_in_place(&mut self.taus, new_of_old.clone());
        }
        permute_in_place(&mut self.counters, new_of_old);
        self.pending.truncate(live);
        self.paths.truncate(live);
        self.entities.truncate(live);
        self.ids.truncate(live);
        self.taus.truncate(live);
        self.counters.truncate(live);
        for (new, &(_, id, _)) in order.iter().enumerate() {
            self.slot_of_id.set(id, new as u32, live);
        }
        self.alive = vec![true; live];
        self.free.clear();
        self.predictions_at_renumber = self.stats.predictions;
        self.stats.renumberings += 1;
    }

    /// Every live slot.
    pub fn live_slots(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.paths.len() as u32).filter(|&s| self.alive[s as usize])
    }
}
