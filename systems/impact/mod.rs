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
//! The solve itself is the plain function [`solve_pair`] in `engine/laws/impact.rs`, free
//! of ECS types, so it can be tested against the closed form of docs/model.md §14 and
//! benchmarked alone; this module is the system around it.

use bevy_ecs::prelude::*;

use agglo_engine::params::{RunBooks, SceneConstants};
use agglo_engine::scene::Material;

use agglo_engine::components::{Hardness, Mass, Particle, Position, Radius, Temperature, Velocity};
use agglo_engine::hooks::{ImpactMessage, ImpactOutcome, Messages};
use agglo_engine::resources::{Contact, ContactList, ImpactRecord, ImpactRecords};
// The law (pure numerics) lives in the engine's laws; this module is its system.
pub use agglo_engine::laws::impact::*;
mod settings;
pub use settings::ImpactModel;

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

type ImpactQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static mut Position,
        &'static mut Velocity,
        &'static Mass,
        &'static Radius,
        &'static mut Temperature,
        &'static mut Hardness,
    ),
    With<Particle>,
>;

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

/// The system: resolve every contact of [`ContactList`] in order.
pub fn resolve_impacts(
    contacts: Res<ContactList>,
    scene: SceneConstants,
    settings: Res<ImpactModel>,
    mut bodies: ImpactQuery,
    mut records: ResMut<ImpactRecords>,
    books: RunBooks,
    mut messages: Option<ResMut<Messages<ImpactMessage>>>,
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
    for contact in &contacts.contacts {
        let Ok([a, b]) = bodies.get_many_mut([contact.a, contact.b]) else {
            continue;
        };
        let (mut pa, mut va, ma, ra, mut ta, mut ha) = a;
        let (mut pb, mut vb, mb, rb, mut tb, mut hb) = b;
        let body_a = PairBody {
            mass: ma.0,
            radius: ra.0,
            velocity: va.0,
            temperature: ta.0,
        };
        let body_b = PairBody {
            mass: mb.0,
            radius: rb.0,
            velocity: vb.0,
            temperature: tb.0,
        };
        let out = solve_pair(&model, &body_a, &body_b, contact.normal);
        if let Some(messages) = messages.as_mut() {
            messages.write(impact_message(
                clock.time, contact, &body_a, &body_b, &out, &model,
            ));
        }
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
                clock.bodies_pushed = true;
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
        ledger.reaction_heat += out.reaction_heat;
        ledger.impact_dissipation += out.dissipated;
        if model.work_heat == WorkHeat::Twice {
            ledger.double_counted_heat += out.dissipated;
        }
        records.records.push(ImpactRecord {
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
    changed.0 = true;
}
