//! Bodies at the current time: the one way to read or write a body (docs/model.md §4).
//!
//! The event core keeps each body's state at its own reference time t_ref
//! ([`LocalTime`]): position, temperature and hardness (and, in a field, velocity) are
//! brought up to the current time only when something reads them. [`bring_to`] does
//! that in place (flight with periodic wrap — a straight line, or the field's closed
//! form, docs/model.md §4.7 — then cooling over the whole interval with the accurate
//! integrator of docs/model.md §8); [`state_at`] computes the same without writing
//! (snapshots).
//!
//! Extensions read and write bodies through the [`Bodies`] system parameter: every
//! body it hands out is at the current time, and every body it changes is reported to
//! the event core, which re-predicts its events. New physics therefore never sees
//! stale state and never leaves stale predictions behind. With the stepped core every
//! body is already current and the parameter only records what changed. What a change
//! does to the energy goes into the ledger (docs/model.md §10): the kinetic energy it
//! makes as force work, the thermal energy as external heat.

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use bevy_ecs::system::SystemParam;
use glam::DVec3;

use crate::components::{
    BodyState, Hardness, LocalTime, Mass, Particle, ParticleId, Position, Primaries, Radius,
    Temperature, Velocity,
};
use crate::field::Field;
use crate::laws::cooling::CoolingLaw;
use crate::params::SceneConstants;
use crate::resources::{BoxGeometry, EnergyLedger, LazyState, SimClock, StepEvents};
use crate::scene::{CoolingMethod, Material, Physics};
use crate::totals::Totals;

/// What bringing a body forward needs: the box, the material (borrowed from the
/// scene's resources), whether the scene cools, and the field bodies fly in.
#[derive(Debug, Clone, Copy)]
pub struct Clockwork<'a> {
    /// The periodic box (wrapping, cell crossings).
    pub geometry: &'a BoxGeometry,
    /// The material (heat capacity and cooling constants).
    pub material: &'a Material,
    /// True when the scene cools (ε > 0 or hc > 0, cooling not off).
    pub cools: bool,
    /// The field, if the scene has one that moves bodies (None: straight flights).
    pub field: Option<&'a Field>,
}

impl<'a> Clockwork<'a> {
    /// The clockwork of a scene: its box, material and physics options (which say whether
    /// it cools).
    pub fn new(geometry: &'a BoxGeometry, material: &'a Material, options: &Physics) -> Self {
        Self {
            geometry,
            material,
            cools: material.cools() && options.cooling != CoolingMethod::Off,
            field: None,
        }
    }

    /// The same, with bodies flying in `field` (ignored when it exerts no force).
    pub fn with_field(mut self, field: Option<&'a Field>) -> Self {
        self.field = field.filter(|f| f.kind() != crate::field::FieldKind::None);
        self
    }

    /// Temperature after `dt` [s] of cooling from θ [K] (exact to ~1e-12).
    pub fn cooled(&self, theta: f64, mass: f64, radius: f64, dt: f64) -> f64 {
        if !self.cools || dt <= 0.0 {
            return theta;
        }
        CoolingLaw::for_body(self.material, mass, radius).advance(theta, dt)
    }
}

impl SceneConstants<'_> {
    /// What bringing a body of this scene forward needs.
    pub fn clockwork(&self) -> Clockwork<'_> {
        Clockwork::new(&self.geometry, &self.material, &self.options)
            .with_field(self.field.as_deref())
    }
}

/// One body on the event core as [`bring_to`] sees it: what changes as it is brought
/// forward (position, temperature, hardness, reference time, and velocity in a field)
/// and what does not (mass, radius) between impacts.
pub struct LazyBody<'a> {
    /// Position at `t_ref` [m].
    pub position: &'a mut DVec3,
    /// Velocity at `t_ref` [m/s].
    pub velocity: &'a mut DVec3,
    /// Mass [kg].
    pub mass: f64,
    /// Radius [m].
    pub radius: f64,
    /// Temperature at `t_ref` [K].
    pub temperature: &'a mut f64,
    /// Hardness at `t_ref` [Pa].
    pub hardness: &'a mut f64,
    /// The body's reference time t_ref [s].
    pub t_ref: &'a mut f64,
}

impl<'a> LazyBody<'a> {
    /// A body's components as [`bring_to`] advances them.
    pub fn of(
        position: &'a mut Position,
        velocity: &'a mut Velocity,
        mass: &Mass,
        radius: &Radius,
        temperature: &'a mut Temperature,
        hardness: &'a mut Hardness,
        local_time: &'a mut LocalTime,
    ) -> Self {
        LazyBody {
            position: &mut position.0,
            velocity: &mut velocity.0,
            mass: mass.0,
            radius: radius.0,
            temperature: &mut temperature.0,
            hardness: &mut hardness.0,
            t_ref: &mut local_time.0,
        }
    }
}

/// What bringing a body forward moved, for the energy ledger (docs/model.md §10).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Brought {
    /// Heat lost by cooling [J].
    pub cooling_loss: f64,
    /// Kinetic energy the field made, ½ m (|v_after|² − |v_before|²) [J].
    pub work: f64,
    /// Momentum the field made, m (v_after − v_before) [kg m/s].
    pub impulse: DVec3,
}

impl Brought {
    /// Add another body's account.
    pub fn add(&mut self, other: &Brought) {
        self.cooling_loss += other.cooling_loss;
        self.work += other.work;
        self.impulse += other.impulse;
    }

    /// Enter it in the ledger: cooling as cooling loss, the field's work and impulse as
    /// force work and force impulse (with their turnovers, the checks' scales). The
    /// turnovers are the account's own absolute values: enter one body at a time, or
    /// a sum whose parts share their signs, to keep them tight.
    pub fn enter(&self, ledger: &mut EnergyLedger) {
        ledger.cooling_loss += self.cooling_loss;
        if self.work != 0.0 || self.impulse != DVec3::ZERO {
            ledger.force_work += self.work;
            ledger.force_work_turnover += self.work.abs();
            let impulse = DVec3::from_array(ledger.force_impulse) + self.impulse;
            ledger.force_impulse = impulse.to_array();
            ledger.force_impulse_turnover += self.impulse.length();
        }
    }
}

/// Bring one body from its reference time to `now` in place; returns what that moved
/// in the energy ledger (the heat it lost by cooling, the field's work and impulse).
pub fn bring_to(now: f64, clockwork: &Clockwork, body: LazyBody) -> Brought {
    let dt = now - *body.t_ref;
    if dt <= 0.0 {
        return Brought::default();
    }
    let mut brought = Brought::default();
    match clockwork.field {
        None => {
            *body.position = clockwork
                .geometry
                .wrap(*body.position + *body.velocity * dt)
        }
        Some(field) => {
            let before = *body.velocity;
            let (x, v) = field
                .flight(body.mass, body.radius)
                .advance(*body.position, before, dt);
            *body.position = clockwork.geometry.wrap(x);
            *body.velocity = v;
            brought.work = 0.5 * body.mass * (v.length_squared() - before.length_squared());
            brought.impulse = body.mass * (v - before);
        }
    }
    let before = *body.temperature;
    let after = clockwork.cooled(before, body.mass, body.radius, dt);
    if after != before {
        *body.temperature = after;
        *body.hardness = clockwork.material.hardness(after);
    }
    *body.t_ref = now;
    brought.cooling_loss = body.mass * clockwork.material.C * (before - after);
    brought
}

/// A body's state at `now` without changing it (for snapshots and summaries).
pub fn state_at(body: &BodyState, t_ref: f64, now: f64, clockwork: &Clockwork) -> BodyState {
    let mut b = *body;
    let mut t_ref = t_ref;
    bring_to(
        now,
        clockwork,
        LazyBody {
            position: &mut b.position,
            velocity: &mut b.velocity,
            mass: body.mass,
            radius: body.radius,
            temperature: &mut b.temperature,
            hardness: &mut b.hardness,
            t_ref: &mut t_ref,
        },
    );
    b
}

/// What `Bodies` reads of a body, and writes: the state that changes in flight and
/// by forces (mass, radius and primaries change only by merging and fragmentation).
#[derive(QueryData)]
#[query_data(mutable)]
struct BodyData {
    entity: Entity,
    id: &'static ParticleId,
    position: &'static mut Position,
    velocity: &'static mut Velocity,
    mass: &'static Mass,
    radius: &'static Radius,
    temperature: &'static mut Temperature,
    hardness: &'static mut Hardness,
    primaries: &'static Primaries,
    local_time: &'static mut LocalTime,
}

/// Bodies at the current time, for systems that add physics (forces, heating, …).
///
/// ```
/// use agglo_engine::bodies::Bodies;
/// use bevy_ecs::prelude::*;
/// use glam::DVec3;
///
/// /// Relaxation toward a gas velocity u [m/s] with time τ [s] (a plugin's own resource).
/// #[derive(Resource)]
/// struct GasPull { gas: DVec3, tau: f64 }
///
/// fn gas_pull(pull: Res<GasPull>, mut bodies: Bodies) {
///     let decay = (-bodies.dt() / pull.tau).exp();
///     bodies.update_all(|b| b.velocity = pull.gas + (b.velocity - pull.gas) * decay);
/// }
/// # let _ = IntoSystem::into_system(gas_pull);
/// ```
/// Position, velocity and temperature written in the closure are kept (hardness follows
/// the temperature); mass, radius, primaries and id are read-only here — bodies change
/// size only by merging and fragmentation. The change in a body's kinetic energy is
/// tallied as force work ([`EnergyLedger::force_work`]), the change in its thermal
/// energy as external heat ([`EnergyLedger::external_heat`]), so the invariant checks
/// of docs/model.md §10 hold with any extension.
#[derive(SystemParam)]
pub struct Bodies<'w, 's> {
    query: Query<'w, 's, BodyData, With<Particle>>,
    clock: Res<'w, SimClock>,
    scene: SceneConstants<'w>,
    lazy: Res<'w, LazyState>,
    ledger: ResMut<'w, EnergyLedger>,
    events: ResMut<'w, StepEvents>,
    /// Marks a system as reading bodies through `Bodies` (see [`BodiesGate`]).
    _gate: Res<'w, BodiesGate>,
}

/// The mark of [`Bodies`]: a system that reads this resource reads bodies through
/// `Bodies`. On the event core, `SimBuilder::build` refuses an extension system that
/// queries a body's time-dependent state (position, velocity, temperature, hardness,
/// reference time) without it: such a query would see each body at its own reference
/// time, not now (docs/model.md §4). Not for reading by hand.
#[derive(Resource, Debug, Default, Clone, Copy)]
pub struct BodiesGate;

impl Bodies<'_, '_> {
    /// The current time t [s].
    pub fn now(&self) -> f64 {
        self.clock.time
    }

    /// Length of the step being taken, Δt [s].
    pub fn dt(&self) -> f64 {
        self.clock.dt
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.query.iter().len()
    }

    /// True when the scene holds no body.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A body's state at the current time (read only: nothing is written).
    pub fn get(&self, entity: Entity) -> Option<BodyState> {
        let body = self.query.get(entity).ok()?;
        let state = BodyState::from((
            body.id,
            body.position,
            body.velocity,
            body.mass,
            body.radius,
            body.temperature,
            body.hardness,
            body.primaries,
        ));
        if !self.lazy.0 {
            return Some(state);
        }
        let clockwork = self.scene.clockwork();
        Some(state_at(
            &state,
            body.local_time.0,
            self.clock.time,
            &clockwork,
        ))
    }

    /// Change one body: it is brought to the current time, `change` edits it, and the
    /// event core re-predicts it. False if the entity is not a body.
    pub fn update(&mut self, entity: Entity, change: impl FnOnce(&mut BodyState)) -> bool {
        let now = self.clock.time;
        let lazy = self.lazy.0;
        let clockwork = self.scene.clockwork();
        let Ok(row) = self.query.get_mut(entity) else {
            return false;
        };
        let tally = apply(row, now, lazy, &clockwork, &mut self.events, change);
        tally.enter(&mut self.ledger);
        true
    }

    /// Change every body (in no particular order; `change` must not depend on it).
    pub fn update_all(&mut self, mut change: impl FnMut(&mut BodyState)) {
        let now = self.clock.time;
        let lazy = self.lazy.0;
        let clockwork = self.scene.clockwork();
        let mut tally = Tally::default();
        for row in self.query.iter_mut() {
            tally.add(&apply(
                row,
                now,
                lazy,
                &clockwork,
                &mut self.events,
                &mut change,
            ));
        }
        tally.enter(&mut self.ledger);
    }
}

/// What changing bodies through [`Bodies`] moved, for the energy ledger [J].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Tally {
    /// Heat lost by cooling while the bodies were brought to the current time.
    cooling_loss: f64,
    /// Kinetic energy the change made, after − before (the force work).
    work: f64,
    /// |after − before| of the kinetic energy, summed per body.
    work_turnover: f64,
    /// Thermal energy the change made, m C (θ_after − θ_before).
    heat: f64,
    /// Momentum the change made, m (v_after − v_before) [kg m/s].
    impulse: DVec3,
    /// |m (v_after − v_before)|, summed per body [kg m/s].
    impulse_turnover: f64,
}

impl Tally {
    fn add(&mut self, other: &Tally) {
        self.cooling_loss += other.cooling_loss;
        self.work += other.work;
        self.work_turnover += other.work_turnover;
        self.heat += other.heat;
        self.impulse += other.impulse;
        self.impulse_turnover += other.impulse_turnover;
    }

    fn enter(&self, ledger: &mut EnergyLedger) {
        ledger.cooling_loss += self.cooling_loss;
        ledger.force_work += self.work;
        ledger.force_work_turnover += self.work_turnover;
        ledger.external_heat += self.heat;
        let impulse = DVec3::from_array(ledger.force_impulse) + self.impulse;
        ledger.force_impulse = impulse.to_array();
        ledger.force_impulse_turnover += self.impulse_turnover;
    }
}

/// Bring a body to `now` (lazy core), record its state before the change, apply it;
/// returns what it moved in the energy ledger.
fn apply(
    row: BodyDataItem<'_, '_>,
    now: f64,
    lazy: bool,
    clockwork: &Clockwork,
    events: &mut StepEvents,
    change: impl FnOnce(&mut BodyState),
) -> Tally {
    let BodyDataItem {
        entity,
        id,
        position: mut p,
        velocity: mut v,
        mass: m,
        radius: b,
        temperature: mut t,
        hardness: mut h,
        primaries: n,
        local_time: mut lt,
    } = row;
    // The contribution before the body is brought forward: the heat it loses on the
    // way is tallied in the ledger and shows in its state after.
    let c = clockwork.material.C;
    events.touch(entity, Totals::of_body(m.0, v.0, t.0, c));
    let mut tally = Tally::default();
    let mut flown = Brought::default();
    if lazy {
        let lazy = LazyBody::of(&mut p, &mut v, m, b, &mut t, &mut h, &mut lt);
        flown = bring_to(now, clockwork, lazy);
        tally.cooling_loss = flown.cooling_loss;
    }
    // Energies before and after, computed as `contribution` computes them, so the
    // ledger moves by exactly the difference the diagnostics' running totals see.
    let before = Totals::of_body(m.0, v.0, t.0, c);
    let mut state = BodyState::from((id, &*p, &*v, m, b, &*t, &*h, n));
    let velocity_before = v.0;
    change(&mut state);
    p.0 = clockwork.geometry.wrap(state.position);
    v.0 = state.velocity;
    if state.temperature != t.0 {
        t.0 = state.temperature;
        h.0 = clockwork.material.hardness(t.0);
    }
    let after = Totals::of_body(m.0, v.0, t.0, c);
    tally.work = after.kinetic - before.kinetic;
    tally.work_turnover = tally.work.abs();
    tally.heat = after.thermal - before.thermal;
    tally.impulse = m.0 * (v.0 - velocity_before);
    tally.impulse_turnover = tally.impulse.length();
    // The field's flight up to now is force work and impulse too (each with its own
    // turnover: it and the change need not share a sign).
    if flown.work != 0.0 || flown.impulse != DVec3::ZERO {
        tally.work += flown.work;
        tally.work_turnover += flown.work.abs();
        tally.impulse += flown.impulse;
        tally.impulse_turnover += flown.impulse.length();
    }
    tally
}
