//! Restart snapshots: the whole evolving state of a run at a checkpoint, from which a
//! fresh simulation of the same scene continues bit for bit.
//!
//! A scene with a checkpoint interval h ([`Checkpoints`], inserted by the scene's settings)
//! takes a checkpoint at the end of the first step that reaches k·h, k = 1, 2, …, before
//! the end time T. There every body is brought to the current time (the event core's
//! lazy state), the state is captured into a [`RestartSnapshot`], and the world is then
//! *restored from that snapshot* — bodies respawned in the captured order, run state set,
//! and each plugin's part reloaded (the event core rebuilds its calendar from the bodies,
//! the stepped core forgets its neighbour list). A resumed run builds the same scene
//! afresh and calls the same restore; so an uninterrupted run and any run resumed from
//! one of its snapshots continue from identical worlds, whatever state the capture
//! leaves out that restore rebuilds. The checkpoints are part of the run: a scene with
//! them differs from one without at rounding level on the event core (its predictions
//! restart from the checkpoint), and, on the stepped core, by where its neighbour list
//! is rebuilt (the Δt bound depends on it).
//!
//! Plugins with state of their own register a [`RestartPart`]
//! ([`crate::schedule::SimBuilder::add_restart_part`]): bytes saved with the snapshot
//! and a loader run after the bodies and the engine's run state are restored.
//!
//! Per-body quantities an extension carries (`SimBuilder::carry`) are a part of their
//! own (`carried::restart_part`): each body's values by id.
//!
//! What is not covered, and documented: the scene's generator [`crate::resources::SimRng`], which the engine draws from only
//! while generating the cloud, so a resumed run, which regenerates the same cloud from
//! the same seed before restoring, holds it in the same state (an extension that draws
//! from it during the run is not covered).
//!
//! Encoding: postcard (little-endian, f64 as its 8 bytes, so every value round-trips
//! exactly); the driver adds a checksum and the scenario around it (`src/restart.rs`).

use bevy_ecs::prelude::*;
use serde::{Deserialize, Serialize};

use crate::components::{
    Hardness, LocalTime, Mass, Particle, ParticleBundle, ParticleId, Position, Primaries, Radius,
    StoredBody, Temperature, Velocity,
};
use crate::resources::{
    BoxGeometry, Counters, EnergyLedger, ForceKicks, IdAllocator, InvariantReport, SimClock,
    StateChanged,
};
use crate::scene::TimeControl;

/// Layout version of [`RestartSnapshot`]'s encoding; bumped when it changes.
pub const SNAPSHOT_VERSION: u32 = 1;

/// When a run takes checkpoints: at the first step end reaching each multiple of
/// `every` [s] before the end time (the scenario's `output.restart.every`).
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Checkpoints {
    /// The interval h [s] (positive, finite).
    pub every: f64,
    /// Checkpoints taken so far, k: the next is due at (k + 1)·h.
    pub taken: u64,
}

impl Checkpoints {
    /// Checkpoints every `every` [s], none taken yet.
    pub fn every(every: f64) -> Self {
        Self { every, taken: 0 }
    }

    /// The time the next checkpoint is due [s]. A product, not a running sum, so that
    /// the times do not drift with rounding.
    pub fn next(&self) -> f64 {
        (self.taken + 1) as f64 * self.every
    }

    /// True when a step ending at `now` has reached the next checkpoint (allowing the
    /// rounding of a step that was cut to land on it).
    pub fn due(&self, now: f64) -> bool {
        let next = self.next();
        now >= next - 1e-12 * next
    }

    /// Count every checkpoint time reached by `now` as taken (a long stepped step may
    /// pass several).
    pub fn pass(&mut self, now: f64) {
        if self.due(now) {
            // Jump to about now's checkpoint at once (validation bounds the count by
            // time.max_steps; this also bounds the loop for any snapshot read back).
            let near = (now / self.every - 2.0).min(1e18);
            self.taken = self.taken.max(near as u64);
        }
        while self.due(now) {
            self.taken += 1;
        }
    }
}

/// One body as the snapshot holds it: every component, at its own reference time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodyRow {
    /// The body's stable id ([`ParticleId`]).
    pub id: u64,
    /// Position [m].
    pub position: [f64; 3],
    /// Velocity [m/s].
    pub velocity: [f64; 3],
    /// Mass [kg].
    pub mass: f64,
    /// Radius [m].
    pub radius: f64,
    /// Temperature θ [K].
    pub temperature: f64,
    /// Hardness H [Pa].
    pub hardness: f64,
    /// The primary grains it is made of.
    pub primaries: f64,
    /// The time the body's state is at [s] (event core: bodies are brought forward lazily).
    pub local_time: f64,
}

impl BodyRow {
    fn bundle(&self) -> ParticleBundle {
        ParticleBundle {
            marker: Particle,
            id: ParticleId(self.id),
            position: Position(self.position.into()),
            velocity: Velocity(self.velocity.into()),
            mass: Mass(self.mass),
            radius: Radius(self.radius),
            temperature: Temperature(self.temperature),
            hardness: Hardness(self.hardness),
            primaries: Primaries(self.primaries),
            local_time: LocalTime(self.local_time),
        }
    }
}

/// A plugin's own state in a snapshot: `save` writes it as bytes, `load` sets it from
/// those bytes once the bodies and the engine's run state are restored (it may also
/// rebuild derived structures from the world, as the event core does).
#[derive(Clone, Copy)]
pub struct RestartPart {
    /// Unique name of the part (the snapshot's key).
    pub name: &'static str,
    /// Write the part's state as bytes.
    pub save: fn(&World) -> Vec<u8>,
    /// Set the part's state from those bytes (an error says why they do not read).
    pub load: fn(&mut World, &[u8]) -> Result<(), String>,
}

/// The registered parts, in registration order.
#[derive(Resource, Clone, Default)]
pub struct RestartParts(pub Vec<RestartPart>);

/// Everything a run needs to continue from a checkpoint (see the module doc).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RestartSnapshot {
    /// The snapshot layout's version (a newer one is refused by name).
    pub version: u32,
    /// The clock: time [s], step, Δt [s].
    pub clock: SimClock,
    /// [`Counters`] as a list (its serde form skips zero fields, which a compact
    /// encoding cannot): see [`counters_to_list`].
    pub counters: Vec<u64>,
    /// The energy ledger [J].
    pub ledger: EnergyLedger,
    /// The invariant references and worst errors so far.
    pub report: InvariantReport,
    /// The next stable id a fragment gets.
    pub next_id: u64,
    /// When the force systems kicked last (interval, time of the last kick, kicks so far).
    pub kicks: ForceKicks,
    /// Whether velocities or the body set changed in the last step.
    pub state_changed: bool,
    /// The checkpoint schedule: its interval [s] and the checkpoints taken so far.
    pub checkpoints: Checkpoints,
    /// Bodies in the world's iteration order (restored in that order, so a resumed world
    /// iterates them as the uninterrupted one does).
    pub bodies: Vec<BodyRow>,
    /// Each registered part's bytes, by name.
    pub parts: Vec<(String, Vec<u8>)>,
}

impl RestartSnapshot {
    /// The snapshot as bytes.
    pub fn encode(&self) -> Vec<u8> {
        postcard::to_allocvec(self).expect("a snapshot always encodes")
    }

    /// A snapshot from [`Self::encode`]'s bytes, refusing another layout version.
    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let snapshot: Self = postcard::from_bytes(bytes)
            .map_err(|e| format!("the snapshot does not decode ({e})"))?;
        if snapshot.version != SNAPSHOT_VERSION {
            return Err(format!(
                "the snapshot has layout version {}, this build reads version {SNAPSHOT_VERSION}",
                snapshot.version
            ));
        }
        Ok(snapshot)
    }

    /// Simulated time of the snapshot [s].
    pub fn time(&self) -> f64 {
        self.clock.time
    }

    /// The snapshot describes a state a run of this scene can be in, checked as a
    /// scenario's bodies are (a file altered and its checksum recomputed by hand once
    /// hung or panicked on resume): the clock finite and within [0, T]; every body's
    /// state finite, its mass, radius and temperature positive, its primaries ≥ 1, its
    /// volume below the box's, its own time not past the clock; distinct
    /// ids, none in the range new ids are drawn from; the checkpoint schedule the
    /// scene's. O(N log N). The error names the body and the quantity.
    pub fn check(
        &self,
        half_width: f64,
        end: f64,
        ids: &IdAllocator,
        checkpoints: Option<&Checkpoints>,
    ) -> Result<(), String> {
        let c = &self.clock;
        if !(c.time.is_finite() && c.time >= 0.0 && c.time <= end) {
            return Err(format!(
                "clock.time = {:e} s: allowed 0 ≤ t ≤ T = {end:e} s",
                c.time
            ));
        }
        if !(c.dt.is_finite() && c.dt >= 0.0) {
            return Err(format!("clock.dt = {:e} s: allowed a finite Δt ≥ 0", c.dt));
        }
        for (i, b) in self.bodies.iter().enumerate() {
            let bad = |what: &str, value: String, allowed: &str| {
                Err(format!(
                    "body {i} (id {}): {what} = {value}; allowed {allowed}",
                    b.id
                ))
            };
            if !b.position.iter().chain(&b.velocity).all(|x| x.is_finite()) {
                return bad(
                    "position, velocity",
                    format!("{:?}, {:?}", b.position, b.velocity),
                    "finite numbers",
                );
            }
            let speed = glam::DVec3::from_array(b.velocity).length();
            if speed > crate::scene::MAX_SPEED {
                // A scenario refuses such a speed too; on the event core a body at 7e38
                // m/s crossed cells without end inside one step.
                return bad(
                    "speed",
                    format!("{speed:e} m/s"),
                    &format!("at most {:e} m/s", crate::scene::MAX_SPEED),
                );
            }
            for (what, x) in [
                ("mass", b.mass),
                ("radius", b.radius),
                ("temperature", b.temperature),
            ] {
                if !(x.is_finite() && x > 0.0) {
                    return bad(what, format!("{x:e}"), "a finite number > 0");
                }
            }
            let largest = (6.0 / std::f64::consts::PI).cbrt() * half_width;
            if b.radius > largest {
                return bad(
                    "radius",
                    format!("{:e} m", b.radius),
                    &format!("at most (6/π)^(1/3) D = {largest:e} m (the box's volume)"),
                );
            }
            if !(b.hardness.is_finite() && b.hardness >= 0.0) {
                return bad(
                    "hardness",
                    format!("{:e}", b.hardness),
                    "a finite number ≥ 0",
                );
            }
            if !(b.primaries.is_finite() && b.primaries >= 1.0) {
                return bad(
                    "primaries",
                    format!("{:e}", b.primaries),
                    "a finite number ≥ 1",
                );
            }
            // (A local time of −7e222 s, found by the fuzz harness, had the event core
            // fly the body across cells without end.)
            if !(0.0..=c.time).contains(&b.local_time) {
                return bad(
                    "local time",
                    format!("{:e} s", b.local_time),
                    &format!("a time in [0, {:e}] s (the clock's)", c.time),
                );
            }
            if (self.next_id..ids.end).contains(&b.id) {
                return bad(
                    "id",
                    b.id.to_string(),
                    &format!(
                        "an id outside the range new ids come from, [{}, {})",
                        self.next_id, ids.end
                    ),
                );
            }
        }
        let mut sorted: Vec<u64> = self.bodies.iter().map(|b| b.id).collect();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!("id {} is held by two bodies", w[0]));
        }
        if let Some(scene) = checkpoints {
            let k = &self.checkpoints;
            let due = (c.time / scene.every).floor() + 1.0;
            if k.every != scene.every || k.taken as f64 > due {
                return Err(format!(
                    "checkpoints every {:e} s, {} taken: the scene takes them every {:e} s, at \
                     most {due} by t = {:e} s",
                    k.every, k.taken, scene.every, c.time
                ));
            }
        }
        Ok(())
    }
}

/// The counters as a list, field by field (destructured without `..`: a new counter
/// must be added here, or this fails to compile).
pub fn counters_to_list(c: &Counters) -> Vec<u64> {
    let Counters {
        impacts,
        bonds,
        bounces,
        fragmentations,
        fragments_created,
        fixed_point_iterations,
        fallback_iterations,
        fallbacks,
        unconverged,
        deferred_contacts,
        clamped_steps,
        overlap_violations,
        invariant_violations,
        collapse_elastic,
    } = *c;
    vec![
        impacts,
        bonds,
        bounces,
        fragmentations,
        fragments_created,
        fixed_point_iterations,
        fallback_iterations,
        fallbacks,
        unconverged,
        deferred_contacts,
        clamped_steps,
        overlap_violations,
        invariant_violations,
        collapse_elastic,
    ]
}

/// The inverse of [`counters_to_list`].
pub fn counters_from_list(list: &[u64]) -> Result<Counters, String> {
    let &[
        impacts,
        bonds,
        bounces,
        fragmentations,
        fragments_created,
        fixed_point_iterations,
        fallback_iterations,
        fallbacks,
        unconverged,
        deferred_contacts,
        clamped_steps,
        overlap_violations,
        invariant_violations,
        collapse_elastic,
    ] = list
    else {
        return Err(format!(
            "the snapshot holds {} counters, this build has 14",
            list.len()
        ));
    };
    Ok(Counters {
        impacts,
        bonds,
        bounces,
        fragmentations,
        fragments_created,
        fixed_point_iterations,
        fallback_iterations,
        fallbacks,
        unconverged,
        deferred_contacts,
        clamped_steps,
        overlap_violations,
        invariant_violations,
        collapse_elastic,
    })
}

/// Capture the world's state (bodies as they are: bring them to the current time first
/// for a snapshot at a common time).
pub fn capture(world: &mut World) -> RestartSnapshot {
    let mut query = world.query_filtered::<StoredBody, With<Particle>>();
    let bodies = query
        .iter(world)
        .map(|b| BodyRow {
            id: b.id.0,
            position: b.position.0.to_array(),
            velocity: b.velocity.0.to_array(),
            mass: b.mass.0,
            radius: b.radius.0,
            temperature: b.temperature.0,
            hardness: b.hardness.0,
            primaries: b.primaries.0,
            local_time: b.local_time.0,
        })
        .collect();
    let parts = world
        .get_resource::<RestartParts>()
        .map(|p| p.0.clone())
        .unwrap_or_default()
        .into_iter()
        .map(|part| (part.name.to_string(), (part.save)(world)))
        .collect();
    RestartSnapshot {
        version: SNAPSHOT_VERSION,
        clock: *world.resource::<SimClock>(),
        counters: counters_to_list(world.resource::<Counters>()),
        ledger: *world.resource::<EnergyLedger>(),
        report: world.resource::<InvariantReport>().clone(),
        next_id: world.resource::<IdAllocator>().next,
        kicks: *world.resource::<ForceKicks>(),
        state_changed: world.resource::<StateChanged>().0,
        checkpoints: world
            .get_resource::<Checkpoints>()
            .copied()
            .unwrap_or(Checkpoints::every(f64::INFINITY)),
        bodies,
        parts,
    }
}

/// Set the world to `snapshot`: every body replaced by the snapshot's (spawned in its
/// order), the run state set, then each registered part loaded. The world must hold the
/// same scene (same settings and plugins) as the one captured.
pub fn restore(world: &mut World, snapshot: &RestartSnapshot) -> Result<(), String> {
    snapshot
        .check(
            world.resource::<BoxGeometry>().half_width,
            world.resource::<TimeControl>().end,
            world.resource::<IdAllocator>(),
            world.get_resource::<Checkpoints>(),
        )
        .map_err(|e| format!("the snapshot does not describe a run of this scene: {e}"))?;
    let counters = counters_from_list(&snapshot.counters)?;
    let registered = world
        .get_resource::<RestartParts>()
        .map(|p| p.0.clone())
        .unwrap_or_default();
    let names: Vec<&str> = registered.iter().map(|p| p.name).collect();
    let saved: Vec<&str> = snapshot.parts.iter().map(|(n, _)| n.as_str()).collect();
    if names != saved {
        return Err(format!(
            "the snapshot holds the state of [{}] but this scene's plugins keep [{}]: \
             it was taken from another pipeline",
            saved.join(", "),
            names.join(", ")
        ));
    }
    let old: Vec<Entity> = world
        .query_filtered::<Entity, With<Particle>>()
        .iter(world)
        .collect();
    for entity in old {
        world.despawn(entity);
    }
    world.spawn_batch(snapshot.bodies.iter().map(BodyRow::bundle));
    *world.resource_mut::<SimClock>() = snapshot.clock;
    *world.resource_mut::<Counters>() = counters;
    *world.resource_mut::<EnergyLedger>() = snapshot.ledger;
    *world.resource_mut::<InvariantReport>() = snapshot.report.clone();
    world.resource_mut::<IdAllocator>().next = snapshot.next_id;
    *world.resource_mut::<ForceKicks>() = snapshot.kicks;
    world.resource_mut::<StateChanged>().0 = snapshot.state_changed;
    if world.contains_resource::<Checkpoints>() {
        *world.resource_mut::<Checkpoints>() = snapshot.checkpoints;
    }
    for (part, (_, bytes)) in registered.iter().zip(&snapshot.parts) {
        (part.load)(world, bytes).map_err(|e| format!("restoring {}: {e}", part.name))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_round_trip_field_by_field() {
        let c = Counters {
            impacts: 1,
            bonds: 2,
            bounces: 3,
            fragmentations: 4,
            fragments_created: 5,
            fixed_point_iterations: 6,
            fallback_iterations: 7,
            fallbacks: 8,
            unconverged: 9,
            deferred_contacts: 10,
            clamped_steps: 11,
            overlap_violations: 12,
            invariant_violations: 13,
            collapse_elastic: 14,
        };
        assert_eq!(counters_from_list(&counters_to_list(&c)).unwrap(), c);
        assert!(counters_from_list(&[1, 2]).is_err());
    }

    #[test]
    fn checkpoint_times_are_products_and_pass_several() {
        let mut c = Checkpoints::every(0.1);
        assert_eq!(c.next(), 0.1);
        assert!(!c.due(0.0999));
        // 0.1 + 0.2 is not 0.3 in f64: a step landing on 3h by a sum still counts.
        c.taken = 2;
        assert!(c.due(0.1 + 0.2));
        c.pass(0.75);
        assert_eq!(c.taken, 7);
        assert_eq!(c.next(), 0.8);
    }
}
