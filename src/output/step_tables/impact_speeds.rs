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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::table::read_table;
    use crate::run::{Run, RunPlan, Until};

    #[test]
    fn a_speed_lands_between_its_bins_edges() {
        // Edges themselves, and speeds just either side of them, over 20 decades.
        for k in -50..50 {
            let edge = lower_edge(k);
            assert_eq!(bin_of(edge), k, "edge {edge}");
            assert_eq!(bin_of(edge * (1.0 + 1e-12)), k);
            assert_eq!(bin_of(edge * (1.0 - 1e-12)), k - 1);
        }
        assert_eq!(bin_of(1.0), 0);
        assert_eq!(bin_of(10.0), 5);
        assert_eq!(bin_of(0.5), -2); // 10^(-2/5) = 0.398 ≤ 0.5 < 10^(-1/5) = 0.631
    }

    /// The histogram is the collision log's speeds binned step by step: an independent
    /// reading of the same impacts (the log writes every impact's speed as it is).
    #[test]
    fn the_histogram_bins_the_collision_logs_speeds() {
        let text = std::fs::read_to_string("scenarios/quick_demo.json").unwrap();
        let scenario = Scenario::from_json(&text).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let (speeds, log) = (dir.path().join("s.csv"), dir.path().join("c.csv"));
        let mut plan = RunPlan::new(scenario).unwrap();
        plan.set_table("impact_speeds", speeds.clone()).unwrap();
        plan.set_table("collisions", log.clone()).unwrap();
        let mut run = Run::start(plan, Default::default()).unwrap();
        let outcome = run.advance(Until::End, &mut |_| std::ops::ControlFlow::Continue(()));
        let end = run.finish(&outcome);
        assert!(outcome.is_ok() && end.output_error.is_none());

        // Over the run, bin by bin: the log's speeds binned here give the same counts.
        let log = read_table(&log).unwrap();
        let mut expected = std::collections::BTreeMap::<i64, i64>::new();
        for v in log.floats("normal_speed").unwrap() {
            *expected.entry(bin_of(v)).or_default() += 1;
        }
        let table = read_table(&speeds).unwrap();
        let (step, bin, count) = (
            table.ints("step").unwrap(),
            table.ints("bin").unwrap(),
            table.ints("count").unwrap(),
        );
        let mut got = std::collections::BTreeMap::<i64, i64>::new();
        for i in 0..table.len() {
            *got.entry(bin[i]).or_default() += count[i];
            // Step by step, each bin once, in order.
            if i > 0 {
                assert!((step[i - 1], bin[i - 1]) < (step[i], bin[i]), "row {i}");
            }
        }
        // Enough impacts, over several bins, that an off-by-one bin or a lost step shows.
        let impacts = end.summary.counters.impacts;
        assert!(impacts > 100 && got.len() > 2, "{impacts} impacts, {got:?}");
        assert_eq!(count.iter().sum::<i64>() as u64, impacts);
        assert_eq!(got, expected);
        let (lower, upper) = (table.floats("lower").unwrap(), table.floats("upper").unwrap());
        for i in 0..table.len() {
            assert_eq!((lower[i], upper[i]), (lower_edge(bin[i]), lower_edge(bin[i] + 1)));
        }
    }
}
