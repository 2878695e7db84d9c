//! The coupling's settings ([`Coupling`]): the base scenario every box is made from,
//! the size classes, the box size (N or a target standard error), the replicas K and
//! whether a cell keeps its bodies between macro steps.

use serde::{Deserialize, Serialize};

use crate::kernel::MassGrid;
use crate::scenario::Scenario;

use super::error::SubgridError;

/// How many bodies a box holds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum BoxSize {
    /// About N bodies: the box volume is V = N / Σ n_k (the class counts are n_k V,
    /// rounded at random, so N is their expectation).
    Bodies(u32),
    /// Bodies enough that the expected impacts over Δt in the K boxes give the cell's
    /// total impact rate a relative standard error of about `relative` (Poisson:
    /// 1/√(impacts)), from the free-molecular kernel of the input classes
    /// (docs/coupling.md); clamped to [`min_bodies`, `max_bodies`].
    TargetSe {
        /// The relative standard error aimed at, > 0.
        relative: f64,
        /// The fewest bodies per box it may choose.
        min_bodies: u32,
        /// The most bodies per box it may choose.
        max_bodies: u32,
    },
}

/// How a flow solver's cells are advanced (the same for every cell of a run).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Coupling {
    /// The scene every box is made from: its `seed` (the base of every box's seed),
    /// the primary grain (`cloud.radius`, or `cloud.size_ratio` with its box and
    /// count: the smallest grain a class may hold), `material` (its `theta0` is
    /// replaced by the gas temperature), `impact`, `physics`, `time.stepping`,
    /// `time.core`, `time.max_steps`, `diagnostics` and `field.gravity`. Its box, its
    /// cloud's bodies and velocities, its end time, its drag and its outputs are not
    /// used: the cell's input sets them.
    pub base: Scenario,
    /// Class edges [kg], strictly increasing, classes k = [e_k, e_{k+1}); bodies
    /// lighter than e_0 count in the first class and bodies from the last edge up in
    /// the last (a flow solver's open end sections), so no mass is ever dropped.
    pub edges: Vec<f64>,
    /// How many bodies a box holds (so its volume).
    pub bodies: BoxSize,
    /// Replica boxes K per cell and step (independent seeds), ≥ 1.
    pub replicas: u32,
    /// Keep each cell's bodies between macro steps (a closed cell, no transport):
    /// the first step lifts the input, later steps continue the same boxes and use
    /// only the input's gas state and Δt (its classes are still checked, not used).
    /// Excludes `persist` (set it to false).
    pub keep_bodies: bool,
    /// Keep each cell's boxes between macro steps and adjust them to the input by what
    /// transport changed since the last step's rates were applied (issue 37 item 3,
    /// [`super::apply_rates`]): bodies removed or added, velocities shifted and
    /// rescaled, per class. With no transport, the closed cell. Excludes `keep_bodies`.
    /// The default ([`Self::new`]): re-lifted chains drift as Δt shrinks, persistent
    /// ones do not (docs/coupling.md). With both false every step lifts afresh.
    pub persist: bool,
    /// Pool the kernel counts and exposure of the boxes into [`super::CellOutput::kernel`].
    pub kernel: bool,
}

/// The largest number of bodies a box may hold.
pub const MAX_BODIES: u32 = 10_000_000;
/// The most replicas per cell.
pub const MAX_REPLICAS: u32 = 100_000;

impl Coupling {
    /// A coupling of `base` on the classes of `edges`, with N = 1000 bodies per box,
    /// K = 4 replicas, persistent boxes (`persist`), no kernel; checked.
    pub fn new(base: Scenario, edges: Vec<f64>) -> Result<Self, SubgridError> {
        let c = Self {
            base,
            edges,
            bodies: BoxSize::Bodies(1000),
            replicas: 4,
            keep_bodies: false,
            persist: true,
            kernel: false,
        };
        c.check()?;
        Ok(c)
    }

    /// The number of classes.
    pub fn classes(&self) -> usize {
        self.edges.len().saturating_sub(1)
    }

    /// The class of a body of mass `m` [kg] (open at both ends, see [`Self::edges`]).
    pub fn class_of(&self, m: f64) -> usize {
        // First edge above m, less one: the class [e_k, e_{k+1}) holding m.
        let above = self.edges.partition_point(|&e| e <= m);
        above.saturating_sub(1).min(self.classes() - 1)
    }

    /// Primary grain radius b0 [m] and mass m0 [kg] of the base scenario.
    pub fn primary(&self) -> (f64, f64) {
        (self.base.primary_radius(), self.base.primary_mass())
    }

    /// The kernel accumulator's grid: the coupling's edges with the open ends closed
    /// at 0⁺ and f64::MAX, so that every body is covered.
    pub fn kernel_grid(&self) -> MassGrid {
        let mut edges = self.edges.clone();
        edges[0] = f64::MIN_POSITIVE;
        let last = edges.len() - 1;
        edges[last] = f64::MAX;
        MassGrid::from_edges(edges, "subgrid classes").expect("checked edges form a grid")
    }

    /// Check every setting; the error names the first field out of range.
    pub fn check(&self) -> Result<(), SubgridError> {
        self.base
            .validate()
            .map_err(|e| SubgridError::config("base", "the scenario", e.to_string()))?;
        let (b0, m0) = self.primary();
        if !(b0.is_finite() && b0 > 0.0 && m0.is_finite()) {
            return Err(SubgridError::config(
                "base.cloud",
                format!("primary radius {b0:e} m"),
                "give cloud.radius [m], a finite radius > 0",
            ));
        }
        if self.edges.len() < 2 {
            return Err(SubgridError::config(
                "edges",
                format!("{} values", self.edges.len()),
                "at least 2 (one class)",
            ));
        }
        if self.classes() > crate::kernel::MAX_CLASSES {
            return Err(SubgridError::config(
                "edges",
                format!("{} classes", self.classes()),
                format!("at most {} classes", crate::kernel::MAX_CLASSES),
            ));
        }
        for (k, &e) in self.edges.iter().enumerate() {
            if !(e.is_finite() && e > 0.0) {
                return Err(SubgridError::config(
                    format!("edges[{k}]"),
                    e,
                    "a finite mass > 0 [kg]",
                ));
            }
            if k > 0 && e <= self.edges[k - 1] {
                return Err(SubgridError::config(
                    format!("edges[{k}]"),
                    e,
                    format!("must be above edges[{}] = {:e}", k - 1, self.edges[k - 1]),
                ));
            }
        }
        match self.bodies {
            BoxSize::Bodies(n) => {
                if !(1..=MAX_BODIES).contains(&n) {
                    return Err(SubgridError::config(
                        "bodies",
                        n,
                        format!("1 ≤ N ≤ {MAX_BODIES}"),
                    ));
                }
            }
            BoxSize::TargetSe {
                relative,
                min_bodies,
                max_bodies,
            } => {
                if !(relative.is_finite() && relative > 0.0) {
                    return Err(SubgridError::config(
                        "bodies.relative",
                        relative,
                        "a finite number > 0",
                    ));
                }
                if !(1..=MAX_BODIES).contains(&max_bodies) || min_bodies > max_bodies {
                    return Err(SubgridError::config(
                        "bodies.min_bodies, bodies.max_bodies",
                        format!("{min_bodies}, {max_bodies}"),
                        format!("1 ≤ min ≤ max ≤ {MAX_BODIES}"),
                    ));
                }
            }
        }
        if self.keep_bodies && self.persist {
            return Err(SubgridError::config(
                "persist",
                "true with keep_bodies",
                "one of the two (persist is the default: set it to false for a closed cell): \
                 keep_bodies ignores the input after the first step, persist adjusts the kept \
                 boxes to it",
            ));
        }
        if !(1..=MAX_REPLICAS).contains(&self.replicas) {
            return Err(SubgridError::config(
                "replicas",
                self.replicas,
                format!("1 ≤ K ≤ {MAX_REPLICAS}"),
            ));
        }
        Ok(())
    }
}
