//! The recording as an output of a run (`--recording`, `output.recording.path`, Python's `recording=`): the [`Recorder`]
//! (src/record/) fed after every step and finished with the run's outcome.

use crate::observer::{Ending, Observer, Written};
use crate::record::Recorder;
use crate::schedule::Simulation;

/// The MCAP recording of a run.
pub struct Recording(pub Recorder);

impl Observer for Recording {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        self.0.observe(sim)
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, written: &mut Written) -> anyhow::Result<()> {
        let path = self.0.path().to_path_buf();
        let report = self.0.finish(end.sim, end.outcome)?;
        written.recording = Some((path, report));
        Ok(())
    }
}
