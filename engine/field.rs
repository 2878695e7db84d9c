//! Fields the cores fly exactly (docs/model.md §4.7): the scenario's `field` section and
//! what it makes of each body's flight.
//!
//! A field acts on every body between events: uniform acceleration g (gravity, or a
//! constant electric field on equal charge-to-mass ratios) and linear drag toward a gas
//! velocity u with a relaxation time τ that depends on the body's mass and radius
//! (Stokes or Epstein drag). Both cores use the closed-form flights of
//! [`crate::laws::flight`]: the stepped core moves every body along its flight each
//! step, the event core predicts contacts and cell crossings along it, so a field
//! costs the event core no extra work per event (g) or a short root search per
//! predicted pair (drag) — not a kick to every body per event, as a general force does
//! (`SimBuilder::add_force_systems`, the slow path).
//!
//! The work and impulse a field does are booked in the energy ledger as force work and
//! force impulse, when a body is brought forward, so the invariant checks stay sharp.

use bevy_ecs::prelude::*;
use glam::DVec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::ValidationIssue;
use crate::laws::flight::Flight;

/// The `field` section: forces every body feels between events. Absent or empty: none.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Field {
    /// Uniform acceleration g [m/s²] on every body, e.g. [0, 0, −9.81].
    #[serde(default, skip_serializing_if = "is_zero")]
    pub gravity: [f64; 3],
    /// Linear drag toward a gas flow (none when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drag: Option<Drag>,
}

fn is_zero(g: &[f64; 3]) -> bool {
    *g == [0.0; 3]
}

/// Linear drag dv/dt = (u − v)/τ toward the gas velocity u.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Drag {
    /// Gas velocity u [m/s] (uniform in space and time).
    #[serde(default)]
    pub gas_velocity: [f64; 3],
    /// How a body's relaxation time τ follows from its mass and radius.
    pub relaxation: Relaxation,
}

/// A body's relaxation time τ [s] from its mass m [kg] and radius b [m].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Relaxation {
    /// The same τ [s] for every body.
    Constant {
        /// τ [s], > 0.
        tau: f64,
    },
    /// Stokes drag in a gas of dynamic viscosity μ [Pa s]: F = 6π μ b (u − v),
    /// τ = m / (6π μ b) (grains much larger than the gas mean free path).
    Stokes {
        /// μ [Pa s], > 0.
        viscosity: f64,
    },
    /// Epstein drag in a gas of density ρ_g [kg/m³] and mean thermal speed v_th [m/s]:
    /// F = (4π/3) ρ_g v_th b² (u − v), τ = m / ((4π/3) ρ_g v_th b²) (grains much smaller
    /// than the mean free path, as in protoplanetary discs).
    Epstein {
        /// ρ_g [kg/m³], > 0.
        gas_density: f64,
        /// v_th [m/s], > 0.
        thermal_speed: f64,
    },
}

/// Which path a field takes on the event core (`agglo validate` says it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldKind {
    /// No field: straight flights.
    None,
    /// Uniform acceleration only: parabolas, relative motion straight.
    Uniform,
    /// Drag (with or without g): exponential flights, contacts by a safeguarded search.
    Drag,
}

impl Field {
    /// True when the field exerts no force (the section can be left out).
    pub fn is_none(&self) -> bool {
        self.kind() == FieldKind::None
    }

    /// g [m/s²].
    pub fn g(&self) -> DVec3 {
        DVec3::from_array(self.gravity)
    }

    /// What kind of flight the field gives.
    pub fn kind(&self) -> FieldKind {
        match (self.drag, self.g() == DVec3::ZERO) {
            (Some(_), _) => FieldKind::Drag,
            (None, false) => FieldKind::Uniform,
            (None, true) => FieldKind::None,
        }
    }

    /// The relaxation time τ [s] of a body of mass `mass` [kg] and radius `radius` [m]
    /// (∞ without drag).
    pub fn relaxation_time(&self, mass: f64, radius: f64) -> f64 {
        let Some(drag) = self.drag else {
            return f64::INFINITY;
        };
        use std::f64::consts::PI;
        match drag.relaxation {
            Relaxation::Constant { tau } => tau,
            Relaxation::Stokes { viscosity } => mass / (6.0 * PI * viscosity * radius),
            Relaxation::Epstein {
                gas_density,
                thermal_speed,
            } => mass / (4.0 / 3.0 * PI * gas_density * thermal_speed * radius * radius),
        }
    }

    /// The flight of a body of relaxation time `tau` [s] (from [`Self::relaxation_time`]).
    pub fn flight_with(&self, tau: f64) -> Flight {
        match self.drag {
            Some(drag) => Flight::Drag {
                terminal: DVec3::from_array(drag.gas_velocity) + self.g() * tau,
                tau,
            },
            None if self.g() != DVec3::ZERO => Flight::Uniform { g: self.g() },
            None => Flight::Ballistic,
        }
    }

    /// The flight of a body of mass `mass` [kg] and radius `radius` [m].
    pub fn flight(&self, mass: f64, radius: f64) -> Flight {
        self.flight_with(self.relaxation_time(mass, radius))
    }

    /// One line for `agglo validate`: the field and the path it takes on each core.
    pub fn describe(&self) -> Option<String> {
        let g = self.g();
        match self.kind() {
            FieldKind::None => None,
            FieldKind::Uniform => Some(format!(
                "field: uniform g = ({:e}, {:e}, {:e}) m/s² — flights are parabolas; the event core \
                 predicts contacts as without a field (relative motion is straight) in a grid \
                 that falls with g: no extra cost per event",
                g.x, g.y, g.z
            )),
            FieldKind::Drag => {
                let how = match self.drag.map(|d| d.relaxation) {
                    Some(Relaxation::Constant { tau }) => format!("τ = {tau:e} s for every body"),
                    Some(Relaxation::Stokes { viscosity }) => {
                        format!("Stokes τ = m/(6π μ b), μ = {viscosity:e} Pa s")
                    }
                    Some(Relaxation::Epstein {
                        gas_density,
                        thermal_speed,
                    }) => format!(
                        "Epstein τ = m/((4π/3) ρ_g v_th b²), ρ_g = {gas_density:e} kg/m³, v_th = {thermal_speed:e} m/s"
                    ),
                    None => unreachable!("kind() is Drag only with drag"),
                };
                Some(format!(
                    "field: linear drag ({how}){} — flights are closed-form exponentials; the \
                     event core finds contacts and cell crossings by a safeguarded root search \
                     along them (O(log N) per event)",
                    if g == DVec3::ZERO {
                        String::new()
                    } else {
                        format!(" with g = ({:e}, {:e}, {:e}) m/s²", g.x, g.y, g.z)
                    }
                ))
            }
        }
    }

    /// Range checks: finite g, positive finite relaxation parameters.
    pub fn issues(&self) -> Vec<ValidationIssue> {
        let mut issues = Vec::new();
        let mut check = |ok: bool, field: &str, allowed: &str, value: String| {
            if !ok {
                issues.push(ValidationIssue {
                    path: field.into(),
                    message: format!("must be {allowed}, got {value}"),
                });
            }
        };
        for (k, g) in self.gravity.iter().enumerate() {
            check(
                g.is_finite() && g.abs() <= 1e12,
                &format!("field.gravity.{k}"),
                "finite with |g| ≤ 1e12 m/s²",
                format!("{g:e}"),
            );
        }
        if let Some(drag) = self.drag {
            for (k, u) in drag.gas_velocity.iter().enumerate() {
                check(
                    u.is_finite() && u.abs() <= 1e5,
                    &format!("field.drag.gas_velocity.{k}"),
                    "finite with |u| ≤ 1e5 m/s",
                    format!("{u:e}"),
                );
            }
            let positive = |x: f64| x.is_finite() && x > 0.0;
            match drag.relaxation {
                Relaxation::Constant { tau } => check(
                    positive(tau),
                    "field.drag.relaxation.constant.tau",
                    "a positive finite time [s]",
                    format!("{tau:e}"),
                ),
                Relaxation::Stokes { viscosity } => check(
                    positive(viscosity),
                    "field.drag.relaxation.stokes.viscosity",
                    "a positive finite viscosity [Pa s]",
                    format!("{viscosity:e}"),
                ),
                Relaxation::Epstein {
                    gas_density,
                    thermal_speed,
                } => {
                    check(
                        positive(gas_density),
                        "field.drag.relaxation.epstein.gas_density",
                        "a positive finite density [kg/m³]",
                        format!("{gas_density:e}"),
                    );
                    check(
                        positive(thermal_speed),
                        "field.drag.relaxation.epstein.thermal_speed",
                        "a positive finite speed [m/s]",
                        format!("{thermal_speed:e}"),
                    );
                }
            }
        }
        issues
    }
}
