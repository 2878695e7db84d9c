//! Stage 1 — contact detection (docs/model.md §4).
//!
//! Gathers the bodies into a table sorted by stable id, finds every pair within
//! the neighbour margin (the skin) with the periodic [`NeighbourGrid`] — reusing the
//! list as a Verlet list while no body has moved more than skin/4 relative to the
//! mean motion and no body was added or removed — and picks this step's
//! contacts: touching (g ≤ tol·(b_i + b_j)) and approaching (w > 0) pairs, deepest
//! first, ties by ids, at most one impact per body per step (the rest are met next
//! step) unless `physics.impacts_per_step = "every_contact"`. With the papers' `nearest_neighbour` rule a pair counts only if one body
//! is the other's nearest neighbour.
//!
//! Reads: positions, velocities, radii, ids; the scene's `time.stepping` and `physics`
//! sections, the primary radius (for the search skin).
//! Writes: [`ContactList`], [`NeighbourTable`] (reused by the time-step system when
//! nothing changed), [`Counters`] (deferred contacts, overlap violations).

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::params::{RunBooks, SceneConstants};
use glam::DVec3;

use agglo_engine::components::{Mass, Particle, ParticleId, Position, Radius, Velocity};
use agglo_engine::laws::grid::{NearPair, NeighbourGrid};
use agglo_engine::resources::{BoxGeometry, CONTACT_TOLERANCE, Contact, ContactList};
use agglo_engine::scene::Stepping;
use agglo_engine::scene::{ContactRule, ImpactsPerStep};

/// The bodies of this step in stable-id order, plus their near pairs.
#[derive(Resource, Debug, Default)]
pub struct NeighbourTable {
    /// Stable ids, one per body, ascending.
    pub ids: Vec<u64>,
    /// The entities, in the order of `ids`.
    pub entities: Vec<Entity>,
    /// Positions [m], in the order of `ids`.
    pub positions: Vec<DVec3>,
    /// Velocities [m/s], in the order of `ids`.
    pub velocities: Vec<DVec3>,
    /// Radii [m], in the order of `ids`.
    pub radii: Vec<f64>,
    /// Masses [kg], in the order of `ids`.
    pub masses: Vec<f64>,
    /// Pairs with gap ≤ margin at the last rebuild (skin, or the contact tolerance for
    /// fixed steps); their `d` and `gap` are current.
    pub pairs: Vec<NearPair>,
    /// Largest displacement of a body since the last rebuild, relative to the
    /// mass-weighted mean displacement [m]. A pair missing from `pairs` has gap
    /// > margin − 2·this, so the list stays complete while that is positive.
    pub max_displacement: f64,
    /// Margin the pairs were searched with [m].
    pub margin: f64,
    built_positions: Vec<DVec3>,
    valid: bool,
    grid: NeighbourGrid,
    order: Vec<(u64, Entity, DVec3, DVec3, f64, f64)>,
}

/// What the stepped core's contact search and step choice read of a body.
#[derive(QueryData)]
pub struct SearchBody {
    /// The body's entity.
    pub entity: Entity,
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
    /// Position [m].
    pub position: &'static Position,
    /// Velocity [m/s].
    pub velocity: &'static Velocity,
    /// Radius [m].
    pub radius: &'static Radius,
    /// Mass [kg].
    pub mass: &'static Mass,
}

/// The stepped core's bodies as the contact search reads them.
pub type BodyQuery<'w, 's> = Query<'w, 's, SearchBody, With<Particle>>;

impl NeighbourTable {
    /// Refill the table from the world and search pairs within `margin` [m].
    pub fn rebuild(&mut self, bodies: &BodyQuery, geometry: &BoxGeometry, margin: f64) {
        self.order.clear();
        for b in bodies.iter() {
            self.order.push((
                b.id.0,
                b.entity,
                b.position.0,
                b.velocity.0,
                b.radius.0,
                b.mass.0,
            ));
        }
        // Query order is not guaranteed: sort by the stable id (nearly sorted → cheap).
        self.order.sort_by_key(|row| row.0);
        self.ids.clear();
        self.entities.clear();
        self.positions.clear();
        self.velocities.clear();
        self.radii.clear();
        self.masses.clear();
        for &(id, e, p, v, r, m) in &self.order {
            self.ids.push(id);
            self.entities.push(e);
            self.positions.push(p);
            self.velocities.push(v);
            self.radii.push(r);
            self.masses.push(m);
        }
        self.grid.pairs_within(
            &self.positions,
            &self.radii,
            geometry.half_width,
            margin,
            &mut self.pairs,
        );
        self.built_positions.clear();
        self.built_positions.extend_from_slice(&self.positions);
        self.max_displacement = 0.0;
        self.margin = margin;
        self.valid = true;
    }

    /// Forget the pair list (bodies were added, removed or resized).
    pub fn invalidate(&mut self) {
        self.valid = false;
    }

    /// Reuse the pair list as a Verlet list if the same bodies are present and none has
    /// moved more than a quarter of the margin relative to the mean motion since the
    /// rebuild; refreshes positions, velocities and pair geometry. False = rebuild.
    pub fn try_reuse(&mut self, bodies: &BodyQuery, geometry: &BoxGeometry) -> bool {
        if !self.valid || self.margin <= 0.0 || bodies.iter().len() != self.ids.len() {
            return false;
        }
        if !self.reload(bodies) {
            return false;
        }
        let mut shift = DVec3::ZERO;
        let mut mass = 0.0;
        for k in 0..self.positions.len() {
            shift +=
                self.masses[k] * geometry.min_image(self.positions[k] - self.built_positions[k]);
            mass += self.masses[k];
        }
        let shift = shift / mass;
        let max = (0..self.positions.len())
            .map(|k| {
                (geometry.min_image(self.positions[k] - self.built_positions[k]) - shift).length()
            })
            .fold(0.0, f64::max);
        if 2.0 * max > 0.5 * self.margin {
            return false;
        }
        self.max_displacement = max;
        self.update_pairs(geometry);
        true
    }

    /// Recompute each pair's separation, following the same periodic image as before:
    /// bodies move far less than half a box between rebuilds, so each component is the
    /// minimum image shifted by the side whenever it jumped by more than half a box.
    fn update_pairs(&mut self, geometry: &BoxGeometry) {
        let side = geometry.side();
        let half = geometry.half_width;
        for pair in &mut self.pairs {
            let (i, j) = (pair.i as usize, pair.j as usize);
            let mut d = geometry.min_image(self.positions[j] - self.positions[i]);
            for k in 0..3 {
                let jump = d[k] - pair.d[k];
                if jump > half {
                    d[k] -= side;
                } else if jump < -half {
                    d[k] += side;
                }
            }
            pair.d = d;
            pair.gap = d.length() - self.radii[i] - self.radii[j];
        }
    }

    /// Refresh positions and velocities in place (same bodies, same pairs): used when
    /// impacts changed velocities and nudged overlapping pairs apart, but no body was
    /// added, removed or resized. Pairs pushed from just outside the margin to just
    /// inside it (by at most an overlap, ~1e-9 b) are not added; they are met next step.
    pub fn refresh(&mut self, bodies: &BodyQuery, geometry: &BoxGeometry) {
        self.reload(bodies);
        self.update_pairs(geometry);
    }

    /// Copy current positions and velocities of the table's bodies from the world;
    /// false if one of them no longer exists (the table is then stale).
    fn reload(&mut self, bodies: &BodyQuery) -> bool {
        let mut all_present = true;
        for k in 0..self.entities.len() {
            match bodies.get(self.entities[k]) {
                Ok(b) => {
                    self.positions[k] = b.position.0;
                    self.velocities[k] = b.velocity.0;
                }
                Err(_) => all_present = false,
            }
        }
        all_present
    }

    /// Closing speed w = (v_i − v_j)·n of a pair (> 0 when approaching).
    #[inline]
    pub fn closing_speed(&self, p: &NearPair) -> f64 {
        let dist = p.d.length();
        if dist == 0.0 {
            return 0.0;
        }
        (self.velocities[p.i as usize] - self.velocities[p.j as usize]).dot(p.d / dist)
    }

    /// True when the pair touches within the contact tolerance.
    #[inline]
    pub fn touching(&self, p: &NearPair) -> bool {
        p.gap <= CONTACT_TOLERANCE * (self.radii[p.i as usize] + self.radii[p.j as usize])
    }
}

/// Margin of the neighbour search [m]: the skin, and never less than the contact tolerance.
/// `b0` [m] is the primary radius (the skin is given in its units).
pub fn search_margin(stepping: &Stepping, b0: f64, table_max_radius: f64) -> f64 {
    stepping
        .search_skin(b0)
        .max(2.0 * CONTACT_TOLERANCE * table_max_radius)
}

/// Scratch for choosing contacts.
#[derive(Resource, Debug, Default)]
pub struct ContactScratch {
    candidates: Vec<(f64, u64, u64, u32)>,
    taken: Vec<bool>,
    nearest: Vec<(f64, u32)>,
    /// Pairs (smaller id, larger id) overlapping at the previous step's detection, sorted.
    overlapping_before: Vec<(u64, u64)>,
    overlapping_now: Vec<(u64, u64)>,
}

impl ContactScratch {
    /// The restart part of the stepped core (engine/restart.rs): the pairs found
    /// overlapping at the last step (a missed contact is a pair that newly overlaps) are
    /// saved; on restore they are set and the neighbour list is rebuilt at the next step.
    pub fn restart_part() -> agglo_engine::restart::RestartPart {
        agglo_engine::restart::RestartPart {
            name: "stepped_contacts",
            save: |world| {
                let pairs = &world.resource::<ContactScratch>().overlapping_before;
                postcard::to_allocvec(pairs).expect("pairs always encode")
            },
            load: |world, bytes| {
                let pairs: Vec<(u64, u64)> =
                    postcard::from_bytes(bytes).map_err(|e| e.to_string())?;
                world.resource_mut::<ContactScratch>().overlapping_before = pairs;
                world.resource_mut::<NeighbourTable>().invalidate();
                Ok(())
            },
        }
    }
}

/// Stage 1 as a system: find this step's contacts (touching, approaching pairs within
/// the contact rule) and list them in resolution order.
pub fn detect_contacts(
    bodies: BodyQuery,
    scene: SceneConstants,
    mut table: ResMut<NeighbourTable>,
    mut scratch: ResMut<ContactScratch>,
    mut contacts: ResMut<ContactList>,
    books: RunBooks,
) {
    let SceneConstants {
        geometry,
        options,
        time,
        primary,
        ..
    } = scene;
    let RunBooks {
        mut clock,
        mut counters,
        mut changed,
        ..
    } = books;
    changed.0 = false;
    if clock.bodies_reshaped || !table.try_reuse(&bodies, &geometry) {
        let max_radius = bodies.iter().map(|b| b.radius.0).fold(0.0, f64::max);
        let margin = search_margin(&time.stepping, primary.radius, max_radius);
        table.rebuild(&bodies, &geometry, margin);
    }
    contacts.contacts.clear();

    let count = table.ids.len();
    let ContactScratch {
        candidates,
        taken,
        nearest,
        overlapping_before,
        overlapping_now,
    } = &mut *scratch;
    overlapping_now.clear();
    candidates.clear();
    if options.contact_rule == ContactRule::NearestNeighbour {
        nearest.clear();
        nearest.resize(count, (f64::INFINITY, u32::MAX));
        for p in &table.pairs {
            for (a, b) in [(p.i, p.j), (p.j, p.i)] {
                // Nearest by gap; ties go to the smaller id (index order = id order).
                let slot = &mut nearest[a as usize];
                if p.gap < slot.0 || (p.gap == slot.0 && b < slot.1) {
                    *slot = (p.gap, b);
                }
            }
        }
    }
    // A pair that newly overlaps (beyond rounding) and approaches after an ordinary step
    // means a contact was missed. Not flagged: steps clamped at Δt_min, the step after
    // merging, fragmentation or a push-apart (a grown body, a placed fragment or a pushed
    // body may overlap a neighbour), and overlaps that already existed at the previous step.
    let check_overlaps = matches!(time.stepping, Stepping::Adaptive { step_factor, .. } if step_factor <= 1.0)
        && !clock.clamped_at_min
        && clock.step > 0
        && !clock.bodies_reshaped
        && !clock.bodies_pushed;
    clock.bodies_reshaped = false;
    clock.bodies_pushed = false;
    for (k, p) in table.pairs.iter().enumerate() {
        let (i, j) = (p.i as usize, p.j as usize);
        let (ia, ib) = (table.ids[i], table.ids[j]);
        let (a, b) = if ia < ib { (ia, ib) } else { (ib, ia) };
        let deep = p.gap < -1e-6 * (table.radii[i] + table.radii[j]);
        if deep {
            overlapping_now.push((a, b));
        }
        if !table.touching(p) || table.closing_speed(p) <= 0.0 {
            continue;
        }
        if check_overlaps && deep && overlapping_before.binary_search(&(a, b)).is_err() {
            counters.overlap_violations += 1;
        }
        if options.contact_rule == ContactRule::NearestNeighbour
            && nearest[i].1 != p.j
            && nearest[j].1 != p.i
        {
            continue;
        }
        candidates.push((p.gap, a, b, k as u32));
    }
    overlapping_now.sort_unstable();
    std::mem::swap(overlapping_before, overlapping_now);
    // Deepest first, ties by (id_i, id_j): a total order, so the choice is deterministic.
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    taken.clear();
    taken.resize(count, false);
    for &(gap, _, _, k) in candidates.iter() {
        let p = table.pairs[k as usize];
        let (i, j) = (p.i as usize, p.j as usize);
        // One impact per body per step, unless the scene reads the papers as taking
        // every contact found (then later contacts see the velocities earlier ones left).
        if (taken[i] || taken[j]) && options.impacts_per_step == ImpactsPerStep::OnePerBody {
            counters.deferred_contacts += 1;
            continue;
        }
        taken[i] = true;
        taken[j] = true;
        // Orient the contact from the smaller id to the larger.
        let (a, b, normal) = if table.ids[i] < table.ids[j] {
            (i, j, p.d.normalize())
        } else {
            (j, i, -p.d.normalize())
        };
        let separation = if a == i { p.d } else { -p.d };
        contacts.contacts.push(Contact {
            a: table.entities[a],
            b: table.entities[b],
            id_a: table.ids[a],
            id_b: table.ids[b],
            normal,
            separation,
            gap,
        });
    }
}
