//! The files written once, when a run ends: the final state (`--final-state`, one CSV
//! row per body; after a failed or stopped run, with a note that it holds the bodies then)
//! and the summary (`--summary`, JSON).

use std::path::{Path, PathBuf};

use crate::error::SimError;
use crate::output::{write_final_state_with, write_summary};
use crate::readable::sci;
use crate::schedule::Simulation;

use crate::observer::{Ending, Observer, Written};

/// `--final-state FILE`: every body at the end, sorted by id, with the quantities
/// extensions carry.
pub struct FinalState(pub PathBuf);

impl Observer for FinalState {
    fn observe(&mut self, _: &Simulation) -> anyhow::Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, written: &mut Written) -> anyhow::Result<()> {
        write_final_state_with(&self.0, end.bodies, &end.sim.carried())?;
        if end.outcome.is_err() {
            written.notes.push(failed_final_state_note(&self.0, end));
        }
        Ok(())
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

/// What the final state file of a failed or stopped run holds: the bodies when it failed
/// or stopped, not at the end time, and how many of them carry a non-finite value.
fn failed_final_state_note(path: &Path, end: &Ending<'_>) -> String {
    let bodies = end.bodies;
    let broken = bodies
        .iter()
        .filter(|b| {
            ![b.mass, b.radius, b.temperature, b.primaries]
                .into_iter()
                .chain(b.position.to_array())
                .chain(b.velocity.to_array())
                .all(f64::is_finite)
        })
        .count();
    let clock = end.sim.clock();
    // A stop asked for (a signal, Ctrl-C in Python, a hook) is not a failure: its state
    // is whole, only early.
    let (what, when) = match end.outcome {
        Err(SimError::Interrupted { .. }) => ("was stopped", "the stop"),
        _ => ("failed", "the failure"),
    };
    format!(
        "the run {what}; the final state in {} holds its {} bodies at {when} \
         (t = {} s, step {}), not at the end time, and {broken} of them have a non-finite \
         value",
        path.display(),
        bodies.len(),
        sci(clock.time),
        clock.step
    )
}
