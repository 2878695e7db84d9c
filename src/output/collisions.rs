//! `--collisions`: one row per impact (docs/model.md §5), read from the engine's hooks
//! ([`crate::hooks::ImpactMessage`], and [`crate::hooks::FragmentMessage`] for the
//! outcome) after each step, and written as it comes: CSV through a buffered writer,
//! Parquet in row groups of [`super::table::ROW_GROUP_ROWS`] rows, so memory stays
//! bounded however many impacts a run has. The messages exist only when this log is
//! asked for ([`subscribe`]): other runs collect nothing.

use std::path::Path;

use anyhow::Context;

use crate::hooks::{FragmentMessage, ImpactMessage, ImpactOutcome};
use crate::schedule::{SimBuilder, Simulation};

use super::table::{Cell, Column, TableWriter, float, id, text};

/// The columns of the collision log, in order.
pub const COLLISION_COLUMNS: &[Column] = &[
    float("t", "s", "contact time"),
    id("id_a", "-", "stable id of the first body (id_a < id_b)"),
    id("id_b", "-", "stable id of the second body"),
    float("mass_a", "kg", "mass of body a before the impact"),
    float("mass_b", "kg", "mass of body b before the impact"),
    float("radius_a", "m", "radius of body a"),
    float("radius_b", "m", "radius of body b"),
    float(
        "normal_speed",
        "m/s",
        "approach speed along the line of centres before the impact (> 0)",
    ),
    float(
        "tangential_speed",
        "m/s",
        "magnitude of the tangential relative velocity before the impact",
    ),
    float("restitution", "-", "restitution e used (0 for a bond)"),
    float(
        "heat",
        "J",
        "heat the impact put into the pair: dissipation plus reaction heat",
    ),
    text(
        "outcome",
        "`bounce`, `bond`, or `fragment` (either body, or the body the bond made, fragmented in the same step)",
    ),
];

/// Have `builder` collect what the collision log reads.
pub fn subscribe(builder: &mut SimBuilder) {
    builder.subscribe::<ImpactMessage>();
    builder.subscribe::<FragmentMessage>();
}

/// The collision log of one run, open.
pub struct CollisionLog {
    table: TableWriter,
    /// Bodies that fragmented in the step being logged (scratch, reused).
    fragmented: Vec<u64>,
}

impl CollisionLog {
    /// Create the log at `path` (CSV or Parquet by its extension) and write its header.
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        Ok(Self {
            table: TableWriter::create(path, "collisions", COLLISION_COLUMNS)?,
            fragmented: Vec::new(),
        })
    }

    /// After a step: one row per impact of the step, in the order the engine resolved
    /// them (by stable ids).
    pub fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        self.fragmented.clear();
        self.fragmented
            .extend(sim.step_messages::<FragmentMessage>().map(|f| f.parent));
        for m in sim.step_messages::<ImpactMessage>() {
            let outcome = if self
                .fragmented
                .iter()
                .any(|&id| id == m.id_a || id == m.id_b)
            {
                "fragment"
            } else {
                match m.outcome {
                    ImpactOutcome::Bounce => "bounce",
                    ImpactOutcome::Bond => "bond",
                }
            };
            self.table
                .row(&[
                    Cell::F(m.time),
                    Cell::U(m.id_a),
                    Cell::U(m.id_b),
                    Cell::F(m.mass_a),
                    Cell::F(m.mass_b),
                    Cell::F(m.radius_a),
                    Cell::F(m.radius_b),
                    Cell::F(m.normal_speed),
                    Cell::F(m.tangential_speed),
                    Cell::F(m.restitution),
                    Cell::F(m.heat),
                    Cell::S(outcome),
                ])
                .context("writing the collision log")?;
        }
        Ok(())
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.table.rows()
    }

    /// Write what is buffered and close the file.
    pub fn finish(self) -> anyhow::Result<()> {
        self.table.finish()
    }
}
