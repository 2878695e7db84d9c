//! The files written once, when a run ends: the final state (`--final-state`, one CSV
//! row per body) and the summary (`--summary`, JSON).

use std::path::PathBuf;

use crate::output::{write_final_state_with, write_summary};
use crate::schedule::Simulation;

use crate::observer::{Ending, Observer, Written};

/// `--final-state FILE`: every body at the end, sorted by id, with the quantities
/// extensions carry.
pub struct FinalState(pub PathBuf);

impl Observer for FinalState {
    fn observe(&mut self, _: &Simulation) -> anyhow::Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        write_final_state_with(&self.0, end.bodies, &end.sim.carried())
    }
}

/// `--summary FILE`: the observables and counters of the run.
pub struct SummaryFile(pub PathBuf);

impl Observer for SummaryFile {
    fn observe(&mut self, _: &Simulation) -> anyhow::Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        write_summary(&self.0, end.summary)
    }
}
