//! Per-body quantities named from Python (`carry={"charge": agglo.Carry(...)}`), carried
//! through merges and fragmentations by the engine's built-in combine and split rules
//! (engine/carried.rs), in Rust: Python is never called for them. Each name takes one of
//! [`SLOTS`] generic components; checkpoints and pickles keep them (the engine's
//! restart part for carried quantities).

use agglo::carried::{Carried, Combine, Split};
use agglo::components::{Particle, ParticleId};
// The Python front is a driver, not an extension: it sets every body's initial values.
use agglo::core_only::SimBuilderCore;
use agglo::schedule::SimBuilder;
use bevy_ecs::prelude::*;

use crate::errors::scenario_error;
use pyo3::PyResult;

/// Quantities a simulation may carry from Python.
pub const SLOTS: usize = 8;

/// The K-th Python-named quantity of a body.
#[derive(Component, Clone, Copy)]
pub struct Slot<const K: usize>(f64);

impl<const K: usize> Carried for Slot<K> {
    fn value(&self) -> f64 {
        self.0
    }
    fn from_value(value: f64) -> Self {
        Slot(value)
    }
}

/// One quantity: its name, rules and initial values.
#[derive(Clone, Debug)]
pub struct Spec {
    pub name: String,
    pub combine: Combine,
    pub split: Split,
    /// One value for every body, or one per body in id order.
    pub init: Vec<f64>,
}

impl Spec {
    /// A quantity from the names of its rules (as `agglo.Carry` gives them).
    pub fn new(name: String, combine: &str, split: &str, init: Vec<f64>) -> PyResult<Self> {
        let combine = match combine {
            "sum" => Combine::Sum,
            "mass_weighted" => Combine::MassWeighted,
            "max" => Combine::Max,
            "min" => Combine::Min,
            other => {
                return Err(scenario_error(format!(
                    "carry[{name:?}]: combine: no `{other}` (sum, mass_weighted, max, min)"
                )));
            }
        };
        let split = match split {
            "by_mass" => Split::ByMass,
            "copy" => Split::Copy,
            other => {
                return Err(scenario_error(format!(
                    "carry[{name:?}]: split: no `{other}` (by_mass, copy)"
                )));
            }
        };
        if init.is_empty() || init.iter().any(|v| !v.is_finite()) {
            return Err(scenario_error(format!(
                "carry[{name:?}]: init: finite values, one or one per body"
            )));
        }
        Ok(Self {
            name,
            combine,
            split,
            init,
        })
    }
}

/// Register `specs` on the scene being built and give every body its initial values.
pub fn register(builder: &mut SimBuilder, specs: &[Spec]) -> anyhow::Result<()> {
    anyhow::ensure!(
        specs.len() <= SLOTS,
        "carry: at most {SLOTS} quantities (got {})",
        specs.len()
    );
    let world = builder.world_mut();
    let mut q = world.query_filtered::<(Entity, &ParticleId), With<Particle>>();
    let mut bodies: Vec<(u64, Entity)> = q.iter(world).map(|(e, id)| (id.0, e)).collect();
    bodies.sort_unstable_by_key(|b| b.0);
    for (k, spec) in specs.iter().enumerate() {
        anyhow::ensure!(
            spec.init.len() == 1 || spec.init.len() == bodies.len(),
            "carry[{:?}]: init: one value or one per body ({} bodies; got {})",
            spec.name,
            bodies.len(),
            spec.init.len()
        );
        let value = |i: usize| spec.init[if spec.init.len() == 1 { 0 } else { i }];
        macro_rules! slot {
            ($($k:literal)*) => {
                match k {
                    $($k => {
                        builder.carry::<Slot<$k>>(&spec.name, spec.combine, spec.split);
                        let world = builder.world_mut();
                        for (i, &(_, e)) in bodies.iter().enumerate() {
                            world.entity_mut(e).insert(Slot::<$k>(value(i)));
                        }
                    })*
                    _ => unreachable!("at most SLOTS quantities, checked above"),
                }
            };
        }
        slot!(0 1 2 3 4 5 6 7);
    }
    Ok(())
}
