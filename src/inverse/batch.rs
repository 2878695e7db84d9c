//! Many ensembles at once, as one batch of the task farm (`crate::farm`).
//!
//! A batch is a list of jobs — the strings of a generation, the points of a scan,
//! the finalists of the closing check — each an ensemble whose length is decided
//! by its stopping rule. The unit of work handed to a worker is one *sample*, so a
//! batch keeps every thread and rank busy even when a few long strings are left.
//!
//! Results are fed to each job's [`Accumulator`] strictly in sample order,
//! whichever worker computed them and whenever they arrived; the evaluations are
//! therefore identical for any number of threads or ranks.
//!
//! Which samples to start: first every sample a job certainly needs (up to its
//! `min_samples`, then the next one after each result that did not stop it), in job
//! order. When no such sample is left and a worker is idle, the batch starts a
//! *speculative* sample — the next one of the job with the fewest samples running
//! ahead of what it needs. A speculative sample the ensemble turns out not to need
//! is dropped unread (counted in [`EnsembleBatch::wasted`]), never used.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::farm::{Dispatcher, FarmError, Workers};

use super::ensemble::{Accumulator, Evaluation, Progress, SampleOutcome, run_sample};
use super::problem::{InverseError, InverseProblem};

/// How one sample's scene is made from the base scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SampleScene {
    /// The problem's genes set to these values.
    Genes(Vec<f64>),
    /// One scenario field set to a value (a scan).
    Field {
        /// The field's dotted path.
        path: String,
        /// Its value.
        value: f64,
    },
}

/// One sample to compute: everything a worker on any rank needs besides the problem.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleTask {
    /// The job's position in its batch.
    pub job: usize,
    /// The sample's index in its ensemble.
    pub sample: u32,
    /// The sample's scene seed.
    pub seed: u64,
    /// The scene: gene values or one field set.
    pub scene: SampleScene,
    /// Keep the final radii (for the histogram).
    pub keep_radii: bool,
}

/// A sample's outcome and the seconds its worker spent on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleReport {
    /// The sample's result, or why it failed.
    pub outcome: SampleOutcome,
    /// Wall-clock seconds its worker spent [s].
    pub seconds: f64,
}

/// Compute one sample of `problem` (the worker function of every inverse batch).
pub fn run_task(problem: &InverseProblem, task: &SampleTask) -> SampleReport {
    let start = Instant::now();
    let scenario = match &task.scene {
        SampleScene::Genes(genes) => problem.scenario_for(genes, task.seed),
        SampleScene::Field { path, value } => problem.scenario_with(path, *value, task.seed),
    };
    let outcome = run_sample(scenario, task.keep_radii);
    SampleReport {
        outcome,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// The cost of one computed sample (`--sample-times`): where the time of a batch goes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SampleTime {
    /// The job's position in its batch.
    pub job: usize,
    /// The sample's index in its ensemble.
    pub sample: u32,
    /// Wall-clock seconds its worker spent [s].
    pub seconds: f64,
    /// False for a speculative sample its ensemble did not need.
    pub used: bool,
}

/// Called with (job, evaluation) as each ensemble of a batch completes.
pub type DoneHook<'a> = &'a dyn Fn(usize, &Evaluation);

/// One ensemble of a batch.
pub struct Job {
    /// The scene: gene values or one field set.
    pub scene: SampleScene,
    /// The scene seed of each sample.
    pub seed_of: Box<dyn Fn(u32) -> u64 + Send + Sync>,
    /// Keep the final radii (for the histogram).
    pub keep_radii: bool,
    /// The ensemble being filled, with its stopping rule.
    pub accumulator: Accumulator,
    /// "name = value, …" for error messages.
    pub label: String,
    /// (generation, string) for error messages.
    pub coordinates: (usize, usize),
}

struct JobState {
    job: Job,
    /// Samples started so far (0..started).
    started: u32,
    /// Results that arrived ahead of their turn.
    pending: BTreeMap<u32, SampleOutcome>,
    result: Option<Evaluation>,
}

impl JobState {
    /// Samples this ensemble is certain to need, given the results used so far.
    fn needed(&self) -> u32 {
        let a = &self.job.accumulator;
        a.min_samples().max(a.count() + 1).min(a.max_samples())
    }
}

/// A batch of ensembles: the [`Dispatcher`] of the inverse problem and of scans.
pub struct EnsembleBatch<'a> {
    jobs: Vec<JobState>,
    cancel: Option<&'a AtomicBool>,
    on_done: Option<DoneHook<'a>>,
    failure: Option<InverseError>,
    speculate: bool,
    wasted: u64,
    remaining: usize,
    /// (job, sample, seconds) of every result received.
    times: Vec<(usize, u32, f64)>,
}

impl<'a> EnsembleBatch<'a> {
    /// A batch of `jobs`, no hooks yet.
    pub fn new(jobs: Vec<Job>) -> Self {
        let remaining = jobs.len();
        Self {
            jobs: jobs
                .into_iter()
                .map(|job| JobState {
                    job,
                    started: 0,
                    pending: BTreeMap::new(),
                    result: None,
                })
                .collect(),
            cancel: None,
            on_done: None,
            failure: None,
            speculate: true,
            wasted: 0,
            remaining,
            times: Vec::new(),
        }
    }

    /// Stop starting samples once `cancel` is set (the batch then ends `Interrupted`).
    pub fn cancel_on(mut self, cancel: Option<&'a AtomicBool>) -> Self {
        self.cancel = cancel;
        self
    }

    /// Called with (job, evaluation) as each ensemble completes.
    pub fn on_done(mut self, f: Option<DoneHook<'a>>) -> Self {
        self.on_done = f;
        self
    }

    /// Start only samples that are certainly needed (no speculation).
    pub fn without_speculation(mut self) -> Self {
        self.speculate = false;
        self
    }

    /// Samples computed but not needed by their ensemble.
    pub fn wasted(&self) -> u64 {
        self.wasted
    }

    fn cancelled(&self) -> bool {
        self.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
    }

    fn start(&mut self, j: usize) -> SampleTask {
        let st = &mut self.jobs[j];
        let sample = st.started;
        st.started += 1;
        SampleTask {
            job: j,
            sample,
            seed: (st.job.seed_of)(sample),
            scene: st.job.scene.clone(),
            keep_radii: st.job.keep_radii,
        }
    }

    /// Run the batch on `workers`; the evaluations in job order and the cost of
    /// every sample computed.
    pub fn run(
        mut self,
        workers: &Workers,
        problem: &InverseProblem,
    ) -> Result<(Vec<Evaluation>, Vec<SampleTime>), InverseError> {
        workers
            .run(&mut self, &|t: &SampleTask| run_task(problem, t))
            .map_err(|e: FarmError| InverseError::Other(e.to_string()))?;
        let times = std::mem::take(&mut self.times);
        let evals = self.into_results()?;
        let times = times
            .into_iter()
            .map(|(job, sample, seconds)| SampleTime {
                job,
                sample,
                seconds,
                used: sample < evals[job].samples,
            })
            .collect();
        Ok((evals, times))
    }

    /// The evaluations in job order, or the failure that stopped the batch.
    pub fn into_results(self) -> Result<Vec<Evaluation>, InverseError> {
        if let Some(f) = self.failure {
            return Err(f);
        }
        self.jobs
            .into_iter()
            .map(|st| st.result.ok_or(InverseError::Interrupted))
            .collect()
    }
}

impl Dispatcher for EnsembleBatch<'_> {
    type Task = SampleTask;
    type Output = SampleReport;

    fn next_task(&mut self) -> Option<SampleTask> {
        if self.failure.is_some() || self.cancelled() {
            return None;
        }
        let open = |st: &JobState| st.result.is_none();
        if let Some(j) = self
            .jobs
            .iter()
            .position(|st| open(st) && st.started < st.needed())
        {
            return Some(self.start(j));
        }
        if !self.speculate {
            return None;
        }
        let j = self
            .jobs
            .iter()
            .enumerate()
            .filter(|(_, st)| open(st) && st.started < st.job.accumulator.max_samples())
            .min_by_key(|(j, st)| (st.started.saturating_sub(st.needed()), *j))
            .map(|(j, _)| j)?;
        Some(self.start(j))
    }

    fn complete(&mut self, task: SampleTask, report: SampleReport) {
        self.times.push((task.job, task.sample, report.seconds));
        let output = report.outcome;
        let st = &mut self.jobs[task.job];
        if st.result.is_some() || self.failure.is_some() {
            self.wasted += 1;
            return;
        }
        st.pending.insert(task.sample, output);
        while let Some(outcome) = st.pending.remove(&st.job.accumulator.count()) {
            match st.job.accumulator.push(outcome) {
                Progress::More => {}
                Progress::Done(eval) => {
                    self.wasted += st.pending.len() as u64;
                    st.pending.clear();
                    if let Some(f) = self.on_done {
                        f(task.job, &eval);
                    }
                    st.result = Some(eval);
                    self.remaining -= 1;
                    break;
                }
                Progress::Failed { sample, failure } => {
                    let (generation, string) = st.job.coordinates;
                    self.failure = Some(InverseError::Sample {
                        generation,
                        string,
                        sample,
                        seed: (st.job.seed_of)(sample),
                        genes: st.job.label.clone(),
                        source: failure,
                    });
                    break;
                }
            }
        }
    }

    fn finished(&self) -> bool {
        self.remaining == 0 || self.failure.is_some() || self.cancelled()
    }
}
