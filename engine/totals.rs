//! Totals of the conserved (or tallied) quantities over bodies: mass, momentum and the
//! two parts of the energy (docs/model.md §10). Plain arithmetic, no ECS: the invariant
//! checks, the event core's running totals and [`crate::bodies::Bodies`]' ledger entries
//! all add bodies up the same way, here.

use glam::DVec3;

/// Totals of the conserved (or tallied) quantities.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Totals {
    /// Mass [kg].
    pub mass: f64,
    /// Momentum Σ m v [kg m/s].
    pub momentum: DVec3,
    /// Σ m |v| [kg m/s].
    pub momentum_scale: f64,
    /// Kinetic energy Σ ½ m v² [J].
    pub kinetic: f64,
    /// Thermal energy Σ m C θ [J].
    pub thermal: f64,
}

impl Totals {
    /// One body's contribution: mass [kg], velocity [m/s], temperature [K], C [J/(kg K)].
    pub fn of_body(mass: f64, velocity: DVec3, temperature: f64, heat_capacity: f64) -> Self {
        Self {
            mass,
            momentum: mass * velocity,
            momentum_scale: mass * velocity.length(),
            kinetic: 0.5 * mass * velocity.length_squared(),
            thermal: mass * heat_capacity * temperature,
        }
    }

    /// Kinetic plus thermal energy [J].
    pub fn energy(&self) -> f64 {
        self.kinetic + self.thermal
    }
}

/// Sum the totals over (mass, velocity, temperature) rows.
pub fn totals(rows: impl Iterator<Item = (f64, DVec3, f64)>, heat_capacity: f64) -> Totals {
    let mut t = Totals::default();
    for (m, v, theta) in rows {
        let body = Totals::of_body(m, v, theta, heat_capacity);
        t.mass += body.mass;
        t.momentum += body.momentum;
        t.momentum_scale += body.momentum_scale;
        t.kinetic += body.kinetic;
        t.thermal += body.thermal;
    }
    t
}
