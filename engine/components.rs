//! Per-particle state (docs/model.md §1). Every body — a primary grain or an
//! agglomerate of grains — is one entity carrying all of these components.
//!
//! Components hold SI values in `f64`; vectors are [`glam::DVec3`]. The radius and
//! hardness are derived quantities kept as components so that systems can read
//! them without recomputing: whoever changes the mass must update [`Radius`], and
//! whoever changes the [`Temperature`] must update [`Hardness`] (see
//! [`crate::scene::Material::hardness`]).

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use glam::DVec3;

/// Marker for particle entities (resources are entities too in bevy_ecs 0.20,
/// so particle queries filter on this).
#[derive(Component, Debug, Clone, Copy, Default)]
pub struct Particle;

/// Stable particle id: never reused within a run. Used for every ordering that
/// must be deterministic, for recording (Foxglove entity id) and for output.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ParticleId(pub u64);

/// Centre position r [m], kept inside the periodic box [−D, D]³.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Position(pub DVec3);

/// Velocity v [m/s].
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Velocity(pub DVec3);

/// Mass m [kg].
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Mass(pub f64);

/// Radius b [m] = (3 m / (4 π ρ))^(1/3); derived from [`Mass`].
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Radius(pub f64);

/// Lumped (uniform) temperature θ [K].
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Temperature(pub f64);

/// Hardness H [Pa] = H0 · exp(Q / (R θ)); derived from [`Temperature`]; may be +∞.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Hardness(pub f64);

/// Number of primary grains in the body (m / m_primary), as `f64`.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Primaries(pub f64);

/// The time t_ref [s] at which this body's [`Position`], [`Temperature`] and
/// [`Hardness`] hold (docs/model.md §4, lazy state). The event core brings a body to
/// the current time only when something reads it; read bodies through
/// `crate::bodies::Bodies` (or `Simulation::bodies`), which does that for you.
/// The stepped core keeps every body current and does not use it.
#[derive(Component, Debug, Clone, Copy, PartialEq, Default)]
pub struct LocalTime(pub f64);

/// Everything a particle entity is spawned with.
#[derive(Bundle, Debug, Clone)]
pub struct ParticleBundle {
    /// The marker every body carries.
    pub marker: Particle,
    /// The body's stable id ([`ParticleId`]).
    pub id: ParticleId,
    /// Position [m].
    pub position: Position,
    /// Velocity [m/s].
    pub velocity: Velocity,
    /// Mass [kg].
    pub mass: Mass,
    /// Radius [m].
    pub radius: Radius,
    /// Temperature θ [K].
    pub temperature: Temperature,
    /// Hardness H [Pa].
    pub hardness: Hardness,
    /// The primary grains it is made of.
    pub primaries: Primaries,
    /// The time the body's state is at [s] (event core: bodies are brought forward lazily).
    pub local_time: LocalTime,
}

/// Every stored component of a body, read-only, with its reference time: what a copy of
/// the bodies reads (`Simulation::bodies`, restart snapshots).
#[derive(QueryData)]
pub struct StoredBody {
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
    /// Temperature θ [K].
    pub temperature: &'static Temperature,
    /// Hardness H [Pa].
    pub hardness: &'static Hardness,
    /// The primary grains it is made of.
    pub primaries: &'static Primaries,
    /// The time the state holds at [s] (the current time on the stepped core).
    pub local_time: &'static LocalTime,
}

impl StoredBodyItem<'_, '_> {
    /// The body's state as stored, at its reference time `local_time`.
    pub fn state(&self) -> BodyState {
        BodyState::from((
            self.id,
            self.position,
            self.velocity,
            self.mass,
            self.radius,
            self.temperature,
            self.hardness,
            self.primaries,
        ))
    }
}

/// A plain-data copy of one body's state, used for output and by pure functions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    /// The body's stable id ([`ParticleId`]).
    pub id: u64,
    /// Position [m].
    pub position: DVec3,
    /// Velocity [m/s].
    pub velocity: DVec3,
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
}

/// Every body's state as columns, one vector per field of [`BodyState`]
/// ([`crate::schedule::Simulation::body_columns`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BodyColumns {
    /// The body's stable id ([`ParticleId`]).
    pub id: Vec<u64>,
    /// x [m].
    pub x: Vec<f64>,
    /// y [m].
    pub y: Vec<f64>,
    /// z [m].
    pub z: Vec<f64>,
    /// x velocity [m/s].
    pub vx: Vec<f64>,
    /// y velocity [m/s].
    pub vy: Vec<f64>,
    /// z velocity [m/s].
    pub vz: Vec<f64>,
    /// Mass [kg].
    pub mass: Vec<f64>,
    /// Radius [m].
    pub radius: Vec<f64>,
    /// Temperature θ [K].
    pub temperature: Vec<f64>,
    /// Hardness H [Pa].
    pub hardness: Vec<f64>,
    /// The primary grains it is made of.
    pub primaries: Vec<f64>,
}

impl BodyColumns {
    /// Empty columns with room for `n` bodies.
    pub fn with_capacity(n: usize) -> Self {
        let f = || Vec::with_capacity(n);
        Self {
            id: Vec::with_capacity(n),
            x: f(),
            y: f(),
            z: f(),
            vx: f(),
            vy: f(),
            vz: f(),
            mass: f(),
            radius: f(),
            temperature: f(),
            hardness: f(),
            primaries: f(),
        }
    }

    /// Append one body.
    pub fn push(&mut self, b: &BodyState) {
        self.id.push(b.id);
        self.x.push(b.position.x);
        self.y.push(b.position.y);
        self.z.push(b.position.z);
        self.vx.push(b.velocity.x);
        self.vy.push(b.velocity.y);
        self.vz.push(b.velocity.z);
        self.mass.push(b.mass);
        self.radius.push(b.radius);
        self.temperature.push(b.temperature);
        self.hardness.push(b.hardness);
        self.primaries.push(b.primaries);
    }

    /// Bodies in the columns.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// The float columns with their names, in the `--final-state` order.
    pub fn floats(self) -> [(&'static str, Vec<f64>); 11] {
        [
            ("x", self.x),
            ("y", self.y),
            ("z", self.z),
            ("vx", self.vx),
            ("vy", self.vy),
            ("vz", self.vz),
            ("mass", self.mass),
            ("radius", self.radius),
            ("temperature", self.temperature),
            ("hardness", self.hardness),
            ("primaries", self.primaries),
        ]
    }

    /// Put the rows in id order (ids are unique): nothing to do when they already are.
    pub fn sort_by_id(&mut self) {
        if self.id.is_sorted() {
            return;
        }
        let mut order: Vec<u32> = (0..self.id.len() as u32).collect();
        order.sort_unstable_by_key(|&i| self.id[i as usize]);
        fn gather<T: Copy>(v: &mut Vec<T>, order: &[u32]) {
            *v = order.iter().map(|&i| v[i as usize]).collect();
        }
        gather(&mut self.id, &order);
        for v in [
            &mut self.x,
            &mut self.y,
            &mut self.z,
            &mut self.vx,
            &mut self.vy,
            &mut self.vz,
            &mut self.mass,
            &mut self.radius,
            &mut self.temperature,
            &mut self.hardness,
            &mut self.primaries,
        ] {
            gather(v, &order);
        }
    }
}

/// A body's components, as a query reads them.
pub type BodyComponents<'a> = (
    &'a ParticleId,
    &'a Position,
    &'a Velocity,
    &'a Mass,
    &'a Radius,
    &'a Temperature,
    &'a Hardness,
    &'a Primaries,
);

impl From<BodyComponents<'_>> for BodyState {
    fn from((id, p, v, m, b, t, h, n): BodyComponents<'_>) -> Self {
        Self {
            id: id.0,
            position: p.0,
            velocity: v.0,
            mass: m.0,
            radius: b.0,
            temperature: t.0,
            hardness: h.0,
            primaries: n.0,
        }
    }
}

impl BodyState {
    /// The components of this body at t = 0, ready to spawn.
    pub fn bundle(&self) -> ParticleBundle {
        self.bundle_at(0.0)
    }

    /// The components of this body, its state holding at time `t` [s].
    pub fn bundle_at(&self, t: f64) -> ParticleBundle {
        ParticleBundle {
            marker: Particle,
            id: ParticleId(self.id),
            position: Position(self.position),
            velocity: Velocity(self.velocity),
            mass: Mass(self.mass),
            radius: Radius(self.radius),
            temperature: Temperature(self.temperature),
            hardness: Hardness(self.hardness),
            primaries: Primaries(self.primaries),
            local_time: LocalTime(t),
        }
    }
}
