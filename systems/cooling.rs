//! Stage 6 — cooling between impacts on the stepped core (docs/model.md §8, P04
//! stage II (6.19)–(6.21)). The law and its integrators live in `engine/laws/cooling.rs`; the
//! event core cools each body over its whole interval with [`CoolingLaw::advance`]
//! when the body is read (`engine/bodies.rs`).
//!
//! m C dθ/dt = − hc a_s (θ − θ0) − B a_s ε (θ⁴ − θs⁴), a_s = 4π b², for every body.
//! Integrators (`physics.cooling`): `explicit` (forward Euler, the papers' choice; stable
//! only for Δt ≲ m C / (4 B ε a_s θ³)), `explicit_clamped` (forward Euler stopped at the
//! equilibrium), `implicit` (backward Euler by safeguarded Newton: unconditionally stable,
//! monotone — θ stays between its old value and the equilibrium) and `exact` (the
//! accurate integrator the event core uses). The closed form for hc = 0, θs = 0 is [`radiative_closed_form`].
//!
//! Reads: Δt, masses, radii. Writes: temperatures, hardness, [`EnergyLedger::cooling_loss`].

use bevy_ecs::prelude::*;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::scene::CoolingMethod;
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use agglo_engine::components::{Hardness, Mass, Particle, Radius, Temperature};
use agglo_engine::resources::{EnergyLedger, SimClock};
use agglo_engine::scene::{Material, Physics};

pub use agglo_engine::laws::cooling::{
    CoolingLaw, convective_closed_form, radiative_closed_form,
    radiative_closed_form_with_far_field, radiative_time_to,
};

/// Stage 6 as a system: cool every body over Δt [s] by convection and radiation with the
/// scene's integrator (stepped core).
pub fn cool_bodies(
    material: Res<Material>,
    options: Res<Physics>,
    clock: Res<SimClock>,
    mut bodies: Query<(&Mass, &Radius, &mut Temperature, &mut Hardness), With<Particle>>,
    mut ledger: ResMut<EnergyLedger>,
) {
    let dt = clock.dt;
    if dt <= 0.0 {
        return;
    }
    let mut lost = 0.0;
    for (m, b, mut t, mut h) in &mut bodies {
        let law = CoolingLaw::for_body(&material, m.0, b.0);
        let new = law.step(options.cooling, t.0, dt);
        lost += m.0 * material.C * (t.0 - new);
        t.0 = new;
        h.0 = material.hardness(new);
    }
    ledger.cooling_loss += lost;
}

/// Cooling (stage 6); not scheduled when off or when ε = hc = 0, nor on the event core,
/// which cools each body over the whole interval when it is read (`engine/bodies.rs`).
pub struct CoolingPlugin;
impl SimPlugin for CoolingPlugin {
    fn name(&self) -> &'static str {
        "cooling"
    }
    fn build(&self, sim: &mut SimBuilder) {
        match no_cooling_system(sim) {
            Some(why) => sim.leave_out(why),
            None => sim.add_core_systems(StepSystems::Cooling, cool_bodies),
        };
    }
}

/// Why the scene schedules no cooling system, if it schedules none.
fn no_cooling_system(sim: &SimBuilder) -> Option<&'static str> {
    let material = sim.resource::<Material>();
    if sim.resource::<Physics>().cooling == CoolingMethod::Off {
        Some("cooling off: physics.cooling = \"off\"")
    } else if material.epsilon == 0.0 && material.hc == 0.0 {
        Some("cooling off: ε = hc = 0 (material.epsilon, material.hc)")
    } else if sim.uses_event_core() {
        Some(
            "cooling: done lazily by the event core (each body cooled exactly over its interval when read)",
        )
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn implicit_is_monotone_and_stays_above_the_far_field() {
        let law = CoolingLaw {
            k_convection: 0.0,
            k_radiation: 1e-9,
            theta_gas: 300.0,
            theta_far: 300.0,
        };
        let mut theta = 1e6;
        for _ in 0..50 {
            let next = law.implicit_step(theta, 10.0);
            assert!(next <= theta && next >= 300.0);
            theta = next;
        }
    }
}

#[cfg(test)]
mod backward_euler_root {
    use super::*;

    #[test]
    fn implicit_step_solves_the_backward_euler_equation_to_rounding() {
        let law = CoolingLaw {
            k_convection: 0.0,
            k_radiation: 9e-12,
            theta_gas: 300.0,
            theta_far: 0.0,
        };
        for &theta in &[500.0, 1e4, 1e6] {
            let limit = law.explicit_limit(theta);
            for &f in &[1e-6, 1e-3, 1e-1, 1.0, 100.0] {
                let dt = f * limit;
                let got = law.implicit_step(theta, dt);
                // The root of θ − θ_old − Δt·rate(θ) by 200 bisections on [0, θ_old].
                let g = |t: f64| t - theta - dt * law.rate(t);
                let (mut lo, mut hi) = (0.0, theta);
                for _ in 0..200 {
                    let m = 0.5 * (lo + hi);
                    if g(m) > 0.0 { hi = m } else { lo = m }
                }
                // A few ulps: Newton's last step and the bisection both end at rounding level.
                assert!(
                    (got - lo).abs() <= 1e-14 * lo,
                    "θ = {theta}, Δt/limit = {f}: {got} vs {lo}"
                );
            }
        }
    }
}
