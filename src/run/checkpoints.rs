//! The restart checkpoints of a run (`output.restart`, `agglo run --resume`): after a
//! step at which the simulation took a snapshot, it is written to the restart file.

use std::path::PathBuf;

use crate::scenario::Scenario;
use crate::schedule::Simulation;

use crate::observer::{CheckpointsWritten, Ending, Observer, Written};

/// Writes each checkpoint the simulation takes to one restart file.
pub struct Checkpoints {
    path: PathBuf,
    /// Embedded in every checkpoint (a restart file is a scenario and a state).
    scenario: Scenario,
    written: CheckpointsWritten,
}

impl Checkpoints {
    pub fn new(path: PathBuf, scenario: Scenario) -> Self {
        Self {
            path,
            scenario,
            written: CheckpointsWritten::default(),
        }
    }
}

impl Observer for Checkpoints {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let Some(snapshot) = sim.restart_snapshot() else {
            return Ok(());
        };
        let start = std::time::Instant::now();
        let bytes = crate::restart::write(&self.path, &self.scenario, snapshot)?;
        let w = &mut self.written;
        w.count += 1;
        w.bytes = bytes;
        w.time = snapshot.time();
        w.writing_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    fn finish(self: Box<Self>, _: &Ending<'_>, written: &mut Written) -> anyhow::Result<()> {
        written.checkpoints = Some((self.path, self.written));
        Ok(())
    }
}
