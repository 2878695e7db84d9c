//! Stage 6 — cooling between impacts (docs/model.md §8, P04 stage II (6.19)–(6.21)).
//!
//! m C dθ/dt = − hc a_s (θ − θ0) − B a_s ε (θ⁴ − θs⁴), a_s = 4π b², for every body.
//! Two integrators: `explicit` (forward Euler, the papers' choice; stable only for
//! Δt ≲ m C / (4 B ε a_s θ³)) and `implicit` (backward Euler by safeguarded Newton:
//! unconditionally stable, monotone — θ stays between its old value and the
//! equilibrium). The closed form for hc = 0, θs = 0 is [`radiative_closed_form`].
//!
//! Reads: Δt, masses, radii. Writes: temperatures, hardness, [`EnergyLedger::cooling_loss`].

use bevy_ecs::prelude::*;

use crate::components::{Hardness, Mass, Particle, Radius, Temperature};
use crate::resources::{
    EnergyLedger, MaterialConstants, PhysicsOptions, STEFAN_BOLTZMANN, SimClock,
};
use crate::scenario::CoolingMethod;

/// The cooling law of one body: dθ/dt = −(k_c (θ − θ0) + k_r (θ⁴ − θs⁴)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoolingLaw {
    /// hc a_s / (m C) [1/s].
    pub k_convection: f64,
    /// B ε a_s / (m C) [1/(s K³)].
    pub k_radiation: f64,
    /// Gas temperature θ0 [K].
    pub theta_gas: f64,
    /// Far-field temperature θs [K].
    pub theta_far: f64,
}

impl CoolingLaw {
    /// The law for a sphere of mass `mass` [kg] and radius `radius` [m].
    pub fn for_body(material: &MaterialConstants, mass: f64, radius: f64) -> Self {
        let area = 4.0 * std::f64::consts::PI * radius * radius;
        let mc = mass * material.heat_capacity;
        Self {
            k_convection: material.convection * area / mc,
            k_radiation: STEFAN_BOLTZMANN * material.emissivity * area / mc,
            theta_gas: material.theta_gas,
            theta_far: material.theta_far,
        }
    }

    /// dθ/dt at θ [K/s].
    pub fn rate(&self, theta: f64) -> f64 {
        -(self.k_convection * (theta - self.theta_gas)
            + self.k_radiation * (theta.powi(4) - self.theta_far.powi(4)))
    }

    /// Forward Euler step (P04 (6.21)). Unbounded for large Δt: may go negative or infinite.
    pub fn explicit_step(&self, theta: f64, dt: f64) -> f64 {
        theta + dt * self.rate(theta)
    }

    /// Backward Euler step: solves θ − θ_old − Δt·rate(θ) = 0 by Newton, safeguarded by
    /// the bracket [min(θ_old, θ0, θs), max(θ_old, θ0, θs)] on which the residual changes sign.
    pub fn implicit_step(&self, theta_old: f64, dt: f64) -> f64 {
        let f = |t: f64| t - theta_old - dt * self.rate(t);
        let df = |t: f64| 1.0 + dt * (self.k_convection + 4.0 * self.k_radiation * t.powi(3));
        let mut lo = theta_old.min(self.theta_gas).min(self.theta_far);
        let mut hi = theta_old.max(self.theta_gas).max(self.theta_far);
        if self.k_convection == 0.0 {
            // Without convection θ0 is no attractor: the bracket is [θs, θ_old] (or reversed).
            lo = theta_old.min(self.theta_far);
            hi = theta_old.max(self.theta_far);
        }
        if self.k_radiation == 0.0 && self.k_convection == 0.0 {
            return theta_old;
        }
        let mut t = theta_old;
        for _ in 0..100 {
            let ft = f(t);
            if ft == 0.0 {
                return t;
            }
            if ft > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let mut next = t - ft / df(t);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            // Stop at rounding level. (A looser stop, 1e-8, left errors of ~1e-8 θ for
            // steps far below the explicit limit: the study's cooling map showed it.)
            if (next - t).abs() <= 1e-14 * next.abs() {
                return next;
            }
            t = next;
        }
        t
    }

    /// One step with the chosen method.
    pub fn step(&self, method: CoolingMethod, theta: f64, dt: f64) -> f64 {
        match method {
            CoolingMethod::Off => theta,
            CoolingMethod::Explicit => self.explicit_step(theta, dt),
            CoolingMethod::Implicit => self.implicit_step(theta, dt),
            CoolingMethod::Exact => self.advance(theta, dt),
        }
    }

    /// TEMPORARY: θ after dt by RK4 in u = θ^-3 with many substeps (to be replaced).
    pub fn advance(&self, theta: f64, dt: f64) -> f64 {
        if dt <= 0.0 || (self.k_convection == 0.0 && self.k_radiation == 0.0) {
            return theta;
        }
        let f = |u: f64| {
            let t = u.powf(-1.0 / 3.0);
            -3.0 * self.rate(t) / t.powi(4)
        };
        let n = 2000;
        let h = dt / n as f64;
        let mut u = theta.powi(-3);
        for _ in 0..n {
            let k1 = f(u);
            let k2 = f(u + 0.5 * h * k1);
            let k3 = f(u + 0.5 * h * k2);
            let k4 = f(u + h * k3);
            u += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        u.powf(-1.0 / 3.0)
    }

    /// Forward Euler's stability limit at θ [s]: 1 / (k_c + 4 k_r θ³).
    pub fn explicit_limit(&self, theta: f64) -> f64 {
        1.0 / (self.k_convection + 4.0 * self.k_radiation * theta.powi(3))
    }
}

/// Exact radiative cooling with hc = 0, θs = 0: θ(t) = (θ(0)^{-3} + 3 k t)^{-1/3}, k = k_r.
pub fn radiative_closed_form(theta_initial: f64, k_radiation: f64, t: f64) -> f64 {
    (theta_initial.powi(-3) + 3.0 * k_radiation * t).powf(-1.0 / 3.0)
}

/// The system.
pub fn cool_bodies(
    material: Res<MaterialConstants>,
    options: Res<PhysicsOptions>,
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
        lost += m.0 * material.heat_capacity * (t.0 - new);
        t.0 = new;
        h.0 = material.hardness(new);
    }
    ledger.cooling_loss += lost;
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
