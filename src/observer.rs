//! What watches a run: an [`Observer`] is handed the simulation after every step and
//! once at the end, whatever the outcome. Every output of a [`crate::run::Run`] is one — the
//! progress line, the clamping warnings, the recording, the sampled tables, the
//! per-step tables of [`crate::output::step_tables`], the checkpoints, the final state
//! and summary files, the live view, a test's kill switch — and the run feeds them in
//! the order it holds them, so a new output is a type here, not a field in the loop.
//!
//! An observer made before the scene — a driver's, such as the kernel accumulator of
//! `agglo kernel`, given to [`crate::run::Run::start_observed`] — says through the trait
//! what it subscribes at build ([`Observer::subscribe`]: the messages it reads) and reads
//! the built scene once before the first step ([`Observer::begin`]); its result goes back
//! to the driver through a [`Handback`]. The files, opened on the built scene, have their
//! subscriptions said by whoever opens them
//! ([`crate::output::step_tables::StepTable::subscribe`], `TablePaths::subscribe`) and
//! their flag or section by the plan ([`crate::run::RunPlan`]). This module sits below
//! the outputs it names (it imports none of them but the recording's report), so each
//! can implement it.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crate::components::BodyState;
use crate::error::SimError;
use crate::observables::Summary;
use crate::record::RecordingReport;
use crate::schedule::{SimBuilder, Simulation};

/// One output of a run, fed after every step and finished once.
/// `Send`: a run moves between threads (Python releases the GIL while it steps).
pub trait Observer: Send {
    /// Before the scene is built: subscribe the messages this observer reads (none by
    /// default). Asked only of the observers a driver hands to
    /// [`crate::run::Run::start_observed`].
    fn subscribe(&self, _builder: &mut SimBuilder) {}
    /// Once the scene is built (and resumed), before the first step; an error refuses
    /// the run. Asked only of the observers a driver hands to
    /// [`crate::run::Run::start_observed`].
    fn begin(&mut self, _sim: &Simulation) -> anyhow::Result<()> {
        Ok(())
    }
    /// After a step. An error stops the run at this step (it is told when the run
    /// finishes; the other outputs are finished all the same).
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()>;
    /// At the end of the run (reached T, stopped or failed): write what is left and
    /// close. `written` collects what the front end reports.
    fn finish(self: Box<Self>, end: &Ending<'_>, written: &mut Written) -> anyhow::Result<()>;
}

/// What an observer is given at the end of a run.
pub struct Ending<'a> {
    /// The simulation as the run left it.
    pub sim: &'a Simulation,
    /// The last advance's result (the recording and the live view say it).
    pub outcome: &'a Result<(), SimError>,
    /// Every body now, sorted by id.
    pub bodies: &'a [BodyState],
    /// The summary of the run.
    pub summary: &'a Summary,
}

/// What the observers wrote that the front end reports (`agglo run`'s closing lines).
#[derive(Default)]
pub struct Written {
    /// The recording and what it holds.
    pub recording: Option<(PathBuf, RecordingReport)>,
    /// The restart file and the checkpoints written to it.
    pub checkpoints: Option<(PathBuf, CheckpointsWritten)>,
    /// What the front end must tell the user about a file besides that it was written
    /// (e.g. a failed run's final state is not the state at the end time).
    pub notes: Vec<String>,
}

/// Checkpoints written during a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CheckpointsWritten {
    /// Checkpoints written.
    pub count: u64,
    /// Size of the last [bytes].
    pub bytes: u64,
    /// Simulated time of the last [s].
    pub time: f64,
    /// Wall-clock seconds spent writing them.
    pub writing_seconds: f64,
}

/// The way an observer hands its result back to the driver that made it: both hold a
/// clone; the observer [`Handback::put`]s its result when it finishes, the driver
/// [`Handback::take`]s it after [`crate::run::Run::finish`] (`None`: the observer had
/// nothing to hand back, e.g. the run failed).
pub struct Handback<T>(Arc<Mutex<Option<T>>>);

impl<T> Handback<T> {
    /// An empty hand-back.
    pub fn new() -> Self {
        Self(Arc::new(Mutex::new(None)))
    }

    /// Leave `value` for the driver (replacing one left before).
    pub fn put(&self, value: T) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(value);
    }

    /// What the observer left, if anything.
    pub fn take(&self) -> Option<T> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
}

impl<T> Clone for Handback<T> {
    fn clone(&self) -> Self {
        Self(self.0.clone())
    }
}

impl<T> Default for Handback<T> {
    fn default() -> Self {
        Self::new()
    }
}
