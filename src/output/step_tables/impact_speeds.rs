//! `--impact-speeds FILE`: after every step with impacts, a histogram of the step's
//! impact speeds (the approach speed along the line of centres, `normal_speed` of
//! `--collisions`), one row per non-empty bin.
//!
//! The bins are log-spaced, [`BINS_PER_DECADE`] per decade, on fixed edges
//! 10^(k/5) m/s: a scene's speeds span decades (a cooling cloud slows from 10² to 10⁻²
//! m/s), and fixed edges need no guess of the range before the run and let tables of
//! different runs be added bin by bin. Speeds are read from the engine's
//! [`ImpactMessage`]s, collected only when this table is asked for.

use std::path::Path;

use anyhow::Context;

use crate::hooks::ImpactMessage;
use crate::observer::{Ending, Observer, Written};
use crate::output::table::{Cell, Column, TableWriter, float, int};
use crate::scenario::Scenario;
use crate::schedule::{SimBuilder, Simulation};

use super::StepTable;

/// Bins per decade of speed.
pub const BINS_PER_DECADE: i64 = 5;

/// The registry entry.
pub const TABLE: StepTable = StepTable {
    name: "impact_speeds",
    flag: "--impact-speeds",
    help: "Write a histogram of each step's impact speeds here (t, step, bin, lower, upper, \
           count; 5 log-spaced bins per decade of m/s)",
    rows: "one row per step with impacts and non-empty speed bin, in bin order; bin k covers \
           10^(k/5) ≤ v < 10^((k+1)/5) m/s, v the approach speed along the line of centres",
    columns: COLUMNS,
    subscribe,
    open,
};

const COLUMNS: &[Column] = &[
    float("t", "s", "time at the end of the step"),
    int("step", "-", "step number (event core: event number)"),
    int("bin", "-", "bin index k: 10^(k/5) ≤ v < 10^((k+1)/5) m/s"),
    float("lower", "m/s", "the bin's lower edge, 10^(k/5)"),
    float("upper", "m/s", "the bin's upper edge, 10^((k+1)/5)"),
    int("count", "-", "impacts of the step in the bin (> 0)"),
];

fn subscribe(builder: &mut SimBuilder) {
    builder.subscribe::<ImpactMessage>();
}

fn open(path: &Path, _: &Scenario, _: &Simulation) -> anyhow::Result<Box<dyn Observer>> {
    Ok(Box::new(ImpactSpeeds {
        table: TableWriter::create(path, "impact_speeds", COLUMNS)?,
        bins: Vec::new(),
    }))
}

/// The lower edge of bin `k` [m/s].
pub fn lower_edge(k: i64) -> f64 {
    10f64.powf(k as f64 / BINS_PER_DECADE as f64)
}

/// The bin of speed `v` > 0 [m/s]: `lower_edge(k) ≤ v < lower_edge(k + 1)`, the
/// logarithm's rounding corrected against the edges themselves.
pub fn bin_of(v: f64) -> i64 {
    let mut k = (v.log10() * BINS_PER_DECADE as f64).floor() as i64;
    if v < lower_edge(k) {
        k -= 1;
    } else if v >= lower_edge(k + 1) {
        k += 1;
    }
    k
}

/// The table, open.
struct ImpactSpeeds {
    table: TableWriter,
    /// The step's bins (scratch, reused): the bin of each impact.
    bins: Vec<i64>,
}

impl Observer for ImpactSpeeds {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        self.bins.clear();
        // A speed of 0 (or not finite) has no log bin; an impact approaches (v > 0).
        self.bins.extend(
            sim.step_messages::<ImpactMessage>()
                .map(|m| m.normal_speed)
                .filter(|v| *v > 0.0 && v.is_finite())
                .map(bin_of),
        );
        if self.bins.is_empty() {
            return Ok(());
        }
        self.bins.sort_unstable();
        let c = sim.clock();
        for run in self.bins.chunk_by(|a, b| a == b) {
            let k = run[0];
            self.table
                .row(&[
                    Cell::F(c.time),
                    Cell::I(c.step as i64),
                    Cell::I(k),
                    Cell::F(lower_edge(k)),
                    Cell::F(lower_edge(k + 1)),
                    Cell::I(run.len() as i64),
                ])
                .context("writing the impact speeds")?;
        }
        Ok(())
    }

    fn finish(self: Box<Self>, _: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        self.table.finish()
    }
}
