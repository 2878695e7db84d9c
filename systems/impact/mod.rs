//! Stage 2 — the impact / heat solve (docs/model.md §5).
//!
//! For every contact of this step (in the order contact detection chose), solve
//! the staggered fixed point e* = G(e*) of restitution, impact duration, contact
//! area, impulsive force, friction, heating and thermal softening, then either
//! bond the pair (common velocity, marked for merging) or bounce it with e*.
//!
//! Reads: [`ContactList`], [`Material`], [`ImpactModel`] (the scenario's `impact`
//! section, defined in `settings.rs`).
//! Writes: velocities, temperatures, hardness and positions (a bouncing pair that
//! overlaps is pushed apart to touching) of the pair; [`ImpactRecords`],
//! [`Counters`], [`EnergyLedger`], [`StateChanged`]; one [`ImpactMessage`] per impact
//! when an extension subscribed (engine/hooks.rs).
//!
//! With the constant-restitution law (`impact.restitution = {"constant": e}`, docs/model.md
//! §5.4) the solve is [`constant_restitution_outcome`] instead, with the TC model
//! ([`CollapseGuard`]) against inelastic collapse.
//!
//! When an extension added impact-outcome systems (engine/hooks.rs), this stage solves
//! every contact, files it in [`PendingImpacts`] and stops; the extension's systems may
//! change outcomes, and [`apply_impact_outcomes`] applies them, recomputing a changed one
//! from the law at the restitution chosen (so the ledgers stay right).
//!
//! In rigid scenes (`physics.merge_mode = "rigid"`, docs/model.md §6.1) the system is
//! [`rigid::resolve_rigid_contacts`] instead: the same law between two aggregates.
//!
//! The solve itself is the plain function [`solve_pair`] in `engine/laws/impact.rs`, free
//! of ECS types, so it can be tested against the closed form of docs/model.md §14 and
//! benchmarked alone; this module is the system around it.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use agglo_engine::aggregates::spawn_singletons;
use agglo_engine::params::{RunBooks, SceneConstants};
use agglo_engine::scene::{Material, MergeMode, Physics};

use agglo_engine::components::{
    Hardness, Mass, Particle, ParticleId, Position, Radius, Temperature, Velocity,
};
use agglo_engine::hooks::{
    ImpactMessage, ImpactOutcome, ImpactOutcomeSystems, Messages, OutcomeChange, PendingImpact,
    PendingImpacts,
};
use agglo_engine::resources::{
    BoxGeometry, Contact, ContactList, Counters, EnergyLedger, ImpactRecord, ImpactRecords,
    SimClock,
};
// The law (pure numerics) lives in the engine's laws; this module is its system.
pub use agglo_engine::laws::impact::*;
pub mod rigid;
mod settings;
pub use settings::{ImpactModel, RestitutionLaw};

/// The pair law's input for this scene: the `impact` section and the material's
/// constants, gathered once per step.
pub fn pair_model(material: &Material, settings: &ImpactModel) -> PairModel {
    PairModel {
        a0: settings.a0,
        af: settings.af,
        beta: settings.beta,
        duration: settings.duration,
        friction_scales_with_adhesion: settings.friction_scales_with_adhesion,
        mu0: material.mu0,
        alpha: material.alpha,
        heat_capacity: material.C,
        h0: material.H0,
        activation_energy: material.Q,
        tol: settings.tol,
        max_iterations: settings.max_iterations,
        solver: settings.solver,
        pair_hardness: settings.pair_hardness,
        friction_cap: settings.friction_cap,
        bond_test: settings.bond_test,
        work_heat: settings.work_heat,
    }
}

/// What an impact reads and writes of each body of the pair.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct ImpactBody {
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
}

type ImpactQuery<'w, 's> = Query<'w, 's, ImpactBody, With<Particle>>;

/// The message an impact writes for extensions (engine/hooks.rs), from the pair before
/// the impact and the outcome.
fn impact_message(
    time: f64,
    contact: &Contact,
    a: &PairBody,
    b: &PairBody,
    out: &PairOutcome,
    model: &PairModel,
) -> ImpactMessage {
    let relative = a.velocity - b.velocity;
    let normal_speed = relative.dot(contact.normal);
    ImpactMessage {
        time,
        id_a: contact.id_a,
        id_b: contact.id_b,
        mass_a: a.mass,
        mass_b: b.mass,
        radius_a: a.radius,
        radius_b: b.radius,
        normal_speed,
        tangential_speed: (relative - normal_speed * contact.normal).length(),
        restitution: out.restitution,
        heat: out.dissipated * work_heat_factor(model.work_heat) + out.reaction_heat,
        outcome: if out.bonded {
            ImpactOutcome::Bond
        } else {
            ImpactOutcome::Bounce
        },
    }
}

/// The TC model (Luding & McNamara 1998; docs/model.md §5.4) for the constant law: the
/// time of each body's last impact, by stable id; a pair either of whose bodies had an
/// impact less than t_c ago bounces elastically.
#[derive(Resource, Debug, Default)]
pub struct CollapseGuard {
    /// t_c [s]; 0 switches the model off.
    pub t_c: f64,
    last: HashMap<u64, f64>,
}

impl CollapseGuard {
    /// The guard with collapse time `t_c` [s] (0: off) and no impact seen yet.
    pub fn new(t_c: f64) -> Self {
        Self {
            t_c,
            last: HashMap::new(),
        }
    }

    /// The restart part of the TC model (engine/restart.rs): each body's last impact
    /// time, saved in id order.
    pub fn restart_part() -> agglo_engine::restart::RestartPart {
        agglo_engine::restart::RestartPart {
            name: "collapse_guard",
            save: |world| {
                let mut last: Vec<(u64, f64)> = world
                    .resource::<CollapseGuard>()
                    .last
                    .iter()
                    .map(|(&id, &t)| (id, t))
                    .collect();
                last.sort_unstable_by_key(|x| x.0);
                postcard::to_allocvec(&last).expect("times always encode")
            },
            load: |world, bytes| {
                let last: Vec<(u64, f64)> =
                    postcard::from_bytes(bytes).map_err(|e| e.to_string())?;
                world.resource_mut::<CollapseGuard>().last = last.into_iter().collect();
                Ok(())
            },
        }
    }

    /// The restitution the pair (id_a, id_b) takes at time `now` [s] under constant `e`,
    /// and whether the TC model made it elastic; records the impact.
    pub fn restitution(&mut self, id_a: u64, id_b: u64, now: f64, e: f64) -> (f64, bool) {
        let recent = |id| {
            self.last
                .get(&id)
                .is_some_and(|&t: &f64| now - t < self.t_c)
        };
        let elastic = self.t_c > 0.0 && e < 1.0 && (recent(id_a) || recent(id_b));
        self.last.insert(id_a, now);
        self.last.insert(id_b, now);
        (if elastic { 1.0 } else { e }, elastic)
    }
}

/// The default t_c [s] of the TC model: 1e-3 b0 / v_s, v_s the rms speed of the
/// bodies' velocities about their mean (docs/model.md §5.4); 0 when v_s = 0.
pub fn default_collapse_time(b0: f64, velocities: &[glam::DVec3]) -> f64 {
    if velocities.is_empty() {
        return 0.0;
    }
    let n = velocities.len() as f64;
    let mean = velocities.iter().copied().sum::<glam::DVec3>() / n;
    let spread = (velocities
        .iter()
        .map(|v| (*v - mean).length_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    if spread > 0.0 {
        1e-3 * b0 / spread
    } else {
        0.0
    }
}

/// Solve one contact at time `now` [s] with the scene's law; true when the TC model made
/// it elastic.
fn solve(
    (model, settings): (&PairModel, &ImpactModel),
    a: &PairBody,
    b: &PairBody,
    contact: &Contact,
    now: f64,
    guard: Option<&mut CollapseGuard>,
) -> (PairOutcome, bool) {
    match settings.restitution {
        None => (solve_pair(model, a, b, contact.normal), false),
        Some(RestitutionLaw::Constant(e)) => {
            let (e, elastic) = match guard {
                Some(guard) => guard.restitution(contact.id_a, contact.id_b, now, e),
                None => (e, false),
            };
            (
                constant_restitution_outcome(model, a, b, contact.normal, e),
                elastic,
            )
        }
    }
}

/// The outcome a hook chose, from the law at that restitution.
fn redo(
    model: &PairModel,
    settings: &ImpactModel,
    solved: &Solved,
    change: OutcomeChange,
) -> PairOutcome {
    let (a, b, n) = (&solved.a, &solved.b, solved.contact.normal);
    let fp = |e| FixedPoint {
        e,
        iterations: solved.out.iterations,
        fallback_iterations: solved.out.fallback_iterations,
        method: solved.out.method,
    };
    let constant = settings.restitution.is_some();
    match change {
        OutcomeChange::Bond if constant => {
            // The granular-gas law has no contact area: no reaction heat.
            let smooth = PairModel {
                alpha: 0.0,
                ..*model
            };
            bonded_outcome(&smooth, a, b, n, fp(0.0))
        }
        OutcomeChange::Bond => bonded_outcome(model, a, b, n, fp(0.0)),
        OutcomeChange::Bounce { restitution } => {
            // NaN counts as 0; the rest is clamped to [0, 1].
            let e = if restitution >= 0.0 {
                restitution.min(1.0)
            } else {
                0.0
            };
            if constant {
                constant_restitution_outcome(model, a, b, n, e)
            } else {
                bounce_outcome(model, a, b, n, fp(e))
            }
        }
    }
}

/// What applying an outcome writes besides the pair: the books and the messages.
struct Apply<'a> {
    model: PairModel,
    settings: &'a ImpactModel,
    material: &'a Material,
    geometry: &'a BoxGeometry,
    clock: &'a mut SimClock,
    counters: &'a mut Counters,
    ledger: &'a mut EnergyLedger,
    records: &'a mut ImpactRecords,
    messages: Option<&'a mut Messages<ImpactMessage>>,
}

impl Apply<'_> {
    /// Apply one solved impact to the pair and the books.
    fn apply(
        &mut self,
        contact: &Contact,
        (body_a, body_b): (&PairBody, &PairBody),
        out: &PairOutcome,
        a: ImpactBodyItem<'_, '_>,
        b: ImpactBodyItem<'_, '_>,
    ) {
        let ImpactBodyItem {
            position: mut pa,
            velocity: mut va,
            mass: ma,
            radius: ra,
            temperature: mut ta,
            hardness: mut ha,
        } = a;
        let ImpactBodyItem {
            position: mut pb,
            velocity: mut vb,
            mass: mb,
            radius: rb,
            temperature: mut tb,
            hardness: mut hb,
        } = b;
        let (material, geometry, settings) = (self.material, self.geometry, self.settings);
        va.0 = out.velocity_i;
        vb.0 = out.velocity_j;
        ta.0 = out.temperature_i;
        tb.0 = out.temperature_j;
        ha.0 = material.hardness(ta.0);
        hb.0 = material.hardness(tb.0);

        if !out.bonded {
            // Push an overlapping pair apart along n to touching; the centre of mass stays.
            // The image met may not be the nearest one when bodies are large.
            let distance = contact.separation.length();
            let overlap = ra.0 + rb.0 - distance;
            if overlap > 0.0 {
                self.clock.bodies_pushed = true;
                match settings.separation {
                    Separation::Normal => {
                        let total = ma.0 + mb.0;
                        pa.0 = geometry.wrap(pa.0 - contact.normal * (overlap * mb.0 / total));
                        pb.0 = geometry.wrap(pb.0 + contact.normal * (overlap * ma.0 / total));
                    }
                    Separation::Velocities => {
                        // P02 (8): each body moves b (1 − δ) along its own outgoing
                        // velocity (none if it is at rest), δ = |r_ij| / (b_i + b_j).
                        let shortfall = 1.0 - distance / (ra.0 + rb.0);
                        pa.0 = geometry.wrap(pa.0 + va.0.normalize_or_zero() * (ra.0 * shortfall));
                        pb.0 = geometry.wrap(pb.0 + vb.0.normalize_or_zero() * (rb.0 * shortfall));
                    }
                }
            }
        }

        self.book(contact, (body_a, body_b), out);
    }

    /// Book one applied impact: the message for extensions, the counters, the energy
    /// ledger and the impact record.
    fn book(
        &mut self,
        contact: &Contact,
        (body_a, body_b): (&PairBody, &PairBody),
        out: &PairOutcome,
    ) {
        if let Some(messages) = self.messages.as_mut() {
            messages.write(impact_message(
                self.clock.time,
                contact,
                body_a,
                body_b,
                out,
                &self.model,
            ));
        }
        let counters = &mut *self.counters;
        counters.impacts += 1;
        if out.bonded {
            counters.bonds += 1;
        } else {
            counters.bounces += 1;
        }
        counters.fixed_point_iterations += u64::from(out.iterations);
        counters.fallback_iterations += u64::from(out.fallback_iterations);
        match out.method {
            SolveMethod::FixedPoint
            | SolveMethod::ClosedForm
            | SolveMethod::Seeded
            | SolveMethod::IterateBonded => {}
            SolveMethod::Fallback => counters.fallbacks += 1,
            SolveMethod::Unconverged => counters.unconverged += 1,
        }
        let ledger = &mut *self.ledger;
        ledger.reaction_heat += out.reaction_heat;
        ledger.impact_dissipation += out.dissipated;
        match self.model.work_heat {
            WorkHeat::Once => {}
            WorkHeat::Twice => ledger.double_counted_heat += out.dissipated,
            // The dissipation left the pair instead of heating it.
            WorkHeat::None => ledger.double_counted_heat -= out.dissipated,
        }
        self.records.records.push(ImpactRecord {
            a: contact.a,
            b: contact.b,
            id_a: contact.id_a,
            id_b: contact.id_b,
            normal: contact.normal,
            separation: contact.separation,
            bonded: out.bonded,
            lost_a: out.lost_i,
            lost_b: out.lost_j,
        });
    }
}

/// A contact solved and not yet applied (only when outcome hooks are present).
#[derive(Debug, Clone, Copy)]
struct Solved {
    contact: Contact,
    a: PairBody,
    b: PairBody,
    out: PairOutcome,
}

/// The step's solved contacts awaiting the outcome hooks, aligned with [`PendingImpacts`].
#[derive(Resource, Debug, Default)]
pub struct SolvedImpacts(Vec<Solved>);

fn pair_bodies(a: &ImpactBodyItem<'_, '_>, b: &ImpactBodyItem<'_, '_>) -> (PairBody, PairBody) {
    let body = |x: &ImpactBodyItem<'_, '_>| PairBody {
        mass: x.mass.0,
        radius: x.radius.0,
        velocity: x.velocity.0,
        temperature: x.temperature.0,
    };
    (body(a), body(b))
}

/// The system: resolve every contact of [`ContactList`] in order (or, with outcome
/// hooks, solve them and leave them in [`PendingImpacts`] for [`apply_impact_outcomes`]).
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn resolve_impacts(
    contacts: Res<ContactList>,
    scene: SceneConstants,
    settings: Res<ImpactModel>,
    mut bodies: ImpactQuery,
    mut records: ResMut<ImpactRecords>,
    books: RunBooks,
    mut messages: Option<ResMut<Messages<ImpactMessage>>>,
    mut pending: Option<ResMut<PendingImpacts>>,
    mut solved: ResMut<SolvedImpacts>,
    mut guard: Option<ResMut<CollapseGuard>>,
) {
    let SceneConstants {
        material, geometry, ..
    } = scene;
    let RunBooks {
        mut clock,
        mut counters,
        mut ledger,
        mut changed,
        ..
    } = books;
    records.records.clear();
    if contacts.contacts.is_empty() {
        return;
    }
    let model = pair_model(&material, &settings);
    let now = clock.time;
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
        let Ok([a, b]) = bodies.get_many_mut([contact.a, contact.b]) else {
            continue;
        };
        let (body_a, body_b) = pair_bodies(&a, &b);
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
        if let Some(pending) = pending.as_mut() {
            let proposal = impact_message(now, contact, &body_a, &body_b, &out, &model);
            pending.push(PendingImpact::new(proposal, contact.a, contact.b));
            solved.0.push(Solved {
                contact: *contact,
                a: body_a,
                b: body_b,
                out,
            });
            continue;
        }
        apply.apply(contact, (&body_a, &body_b), &out, a, b);
    }
    changed.0 = true;
}

/// Applies the step's impacts after the outcome hooks (stage 2b,
/// [`ImpactOutcomeSystems::Apply`]): the law's outcome, or the one a hook chose,
/// recomputed from the law at that restitution.
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn apply_impact_outcomes(
    mut pending: ResMut<PendingImpacts>,
    mut solved: ResMut<SolvedImpacts>,
    scene: SceneConstants,
    settings: Res<ImpactModel>,
    mut bodies: ImpactQuery,
    mut records: ResMut<ImpactRecords>,
    books: RunBooks,
    mut messages: Option<ResMut<Messages<ImpactMessage>>>,
) {
    let impacts = pending.take();
    let solved = std::mem::take(&mut solved.0);
    if impacts.is_empty() {
        return;
    }
    let SceneConstants {
        material, geometry, ..
    } = scene;
    let RunBooks {
        mut clock,
        mut counters,
        mut ledger,
        ..
    } = books;
    let model = pair_model(&material, &settings);
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
    for (hook, s) in impacts.iter().zip(&solved) {
        let Ok([a, b]) = bodies.get_many_mut([s.contact.a, s.contact.b]) else {
            continue;
        };
        let out = match hook.change() {
            None => s.out,
            Some(change) => redo(&model, &settings, s, change),
        };
        apply.apply(&s.contact, (&s.a, &s.b), &out, a, b);
    }
}

/// Adds [`apply_impact_outcomes`] where it runs (for
/// [`agglo_engine::core_only::SimBuilderCore::set_impact_outcome_applier`]).
pub fn add_outcome_applier(schedule: &mut Schedule) {
    schedule.add_systems(apply_impact_outcomes.in_set(ImpactOutcomeSystems::Apply));
}

/// The impact / heat solve (stage 2).
pub struct ImpactPlugin;
impl SimPlugin for ImpactPlugin {
    fn name(&self) -> &'static str {
        "impact"
    }
    fn build(&self, sim: &mut SimBuilder) {
        // The scene's `impact` section, or the defaults when it gives none.
        sim.init_resource::<ImpactModel>()
            .init_resource::<SolvedImpacts>();
        if sim.resource::<Physics>().merge_mode == MergeMode::Rigid {
            // Every body starts as an aggregate of one primary (docs/model.md §6.1).
            spawn_singletons(sim.world_mut());
            sim.add_core_systems(StepSystems::Impact, rigid::resolve_rigid_contacts)
                .add_restart_part(rigid::restart_part());
        } else {
            sim.add_core_systems(StepSystems::Impact, resolve_impacts)
                .set_impact_outcome_applier(add_outcome_applier);
        }
        let settings = *sim.resource::<ImpactModel>();
        if settings.restitution.is_some() {
            // The TC model against inelastic collapse (docs/model.md §5.4).
            let t_c = settings.collapse_time.unwrap_or_else(|| {
                let b0 = sim.resource::<agglo_engine::cloud::PrimaryGrain>().radius;
                let world = sim.world_mut();
                let mut query = world.query_filtered::<(&ParticleId, &Velocity), With<Particle>>();
                let mut bodies: Vec<_> = query.iter(world).map(|(id, v)| (id.0, v.0)).collect();
                bodies.sort_by_key(|b| b.0); // sums in id order, not entity order
                let velocities: Vec<_> = bodies.into_iter().map(|b| b.1).collect();
                default_collapse_time(b0, &velocities)
            });
            if t_c > 0.0 {
                sim.insert_resource(CollapseGuard::new(t_c))
                    .add_restart_part(CollapseGuard::restart_part());
            }
        }
    }
}
