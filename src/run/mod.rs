//! One run of a scenario with everything it writes: the tables, the recording and its
//! layout, restart checkpoints, the live view, the progress line, the clamping warnings
//! and the stop flag. `agglo run`, the Python module and any other front end call this
//! same code, so a run started from any of them writes the same bytes.
//!
//! A run is a [`RunPlan`] (the scenario and where each output goes), started as a
//! [`Run`], advanced ([`Run::advance`]: to T, to a time, or by a number of steps; as
//! often as wanted), and finished ([`Run::finish`]): the recording is finalised, the
//! tables closed, the final state and summary written, whatever the outcome — nothing
//! is lost when a run fails or is stopped.
//!
//! It is the one door to a run: the CLI, Python, the ensembles of the inverse problem,
//! the studies and `agglo kernel` all build and step their scenes here — the built-in
//! physics, the registered extensions ([`crate::plugins`]) and what the observers
//! subscribe. A driver that writes no file starts from [`RunPlan::unwritten`] and hands
//! its own observers to [`Run::start_observed`] (or [`Run::complete`], start to finish
//! in one call).
//!
//! ```no_run
//! use agglo::prelude::*;
//! use agglo::run::{Run, RunPlan, Until};
//! let scenario = Scenario::load(std::path::Path::new("scenarios/quick_demo.json"))?;
//! let mut plan = RunPlan::new(scenario)?;
//! plan.summary = Some("summary.json".into());
//! let mut run = Run::start(plan, Default::default())?;
//! let outcome = run.advance(Until::End, &mut |_| std::ops::ControlFlow::Continue(()));
//! let end = run.finish(&outcome);
//! println!("b_f/b0 = {}", end.summary.growth.growth_ratio);
//! # Ok::<(), anyhow::Error>(())
//! ```

mod checkpoints;
pub mod clamp_watch;
mod end_files;
pub mod progress;
mod recording;
pub mod signals;
mod test_switches;

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

use crate::error::SimError;
use crate::live::run::LiveRun;
use crate::live::{LiveOptions, Server, check_options};
use crate::observables::Summary;
pub use crate::observer::CheckpointsWritten;
use crate::observer::{Ending, Observer, Written};
use crate::output::step_tables::{self, StepTable};
use crate::output::{RunTables, SampleSchedule, TableArgs, TablePaths};
use crate::record::{Recorder, RecordingReport};
use crate::restart::RestartSnapshot;
use crate::scenario::Scenario;
use crate::schedule::Simulation;
use agglo_systems::diagnostics::InitialEnergies;
use clamp_watch::ClampWarnings;
use progress::Progress;

/// A run to make: the scenario and where each output goes. [`RunPlan::new`] takes the
/// paths from the scenario's `output` section; a front end overrides them (the flags of
/// `agglo run`, the arguments of `Simulation.run` in Python).
#[derive(Debug, Clone)]
pub struct RunPlan {
    /// The scenario to run.
    pub scenario: Scenario,
    /// Continue a stopped run from this checkpoint (`agglo run --resume`).
    pub resume: Option<Resume>,
    /// With `resume`: build the scene without its initial cloud and give what the run
    /// read of it instead ([`BareResume`]). Ignored without `resume`.
    pub resume_bare: Option<BareResume>,
    /// The tables sampled during the run and their schedule.
    pub tables: TablePaths,
    /// The per-step tables asked for ([`crate::output::step_tables`]) and their files.
    pub step_tables: Vec<(&'static StepTable, PathBuf)>,
    /// The observables and counters as JSON, at the end.
    pub summary: Option<PathBuf>,
    /// One CSV row per body, at the end.
    pub final_state: Option<PathBuf>,
    /// The MCAP recording (a Foxglove layout fitted to the box is written beside it).
    pub recording: Option<PathBuf>,
    /// The restart file, over `output.restart.path` (checkpoints are written only when
    /// the scenario has an `output.restart` section).
    pub restart: Option<PathBuf>,
    /// The command line the recording keeps (metadata only).
    pub command_line: String,
    /// Serve the run live over the Foxglove WebSocket protocol.
    pub live: Option<LiveOptions>,
    /// Draw the progress line on stderr (indicatif draws nothing where stderr is not a
    /// terminal).
    pub progress: bool,
    /// One run of many (an ensemble, a study, `agglo kernel`; [`RunPlan::unwritten`]):
    /// its driver checks the memory of all the runs it holds at once and reports their
    /// failures itself, so the run neither checks its own memory nor warns on stderr
    /// about clamped steps.
    pub one_of_many: bool,
}

/// A checkpoint to continue from, and the file it was read from.
#[derive(Debug, Clone)]
pub struct Resume {
    /// The restart file it was read from (named in errors).
    pub file: PathBuf,
    /// The checkpoint.
    pub snapshot: RestartSnapshot,
}

/// What a run resumed without its scene's initial cloud is given in its place
/// (`SimBuilder::resuming`, `plugins::resuming_builder`): a driver that kept these when
/// the run was first built (a subgrid box, `subgrid::BoxStart`) resumes a small end
/// state without placing, spawning and predicting the whole initial cloud first. The
/// scene must also give `impact.collapse_time` when it has a restitution (its default
/// is drawn from the initial velocities).
#[derive(Debug, Clone, Copy)]
pub struct BareResume {
    /// Bodies the run started with (the invariant checks' full recount cadence).
    pub initial_bodies: usize,
    /// Its kinetic and thermal energy at t = 0 [J] (the energy ledgers' references).
    pub energies: InitialEnergies,
}

impl RunPlan {
    /// The plan of `agglo run SCENARIO` without flags: every output where the scenario's
    /// `output` section puts it.
    pub fn new(scenario: Scenario) -> anyhow::Result<Self> {
        let tables = TableArgs::default().paths(&scenario.output)?;
        let output = &scenario.output;
        let path = |p: &Option<String>| p.clone().map(PathBuf::from);
        Ok(Self {
            summary: path(&output.summary),
            final_state: path(&output.final_state),
            recording: path(&output.recording.path),
            tables,
            one_of_many: false,
            ..Self::unwritten(scenario)
        })
    }

    /// A run of many that writes no file, whatever the scenario's `output` section says:
    /// each run of an ensemble, a study or `agglo kernel`, whose driver reads the
    /// simulation or its own observers ([`Run::start_observed`]) instead.
    pub fn unwritten(scenario: Scenario) -> Self {
        Self {
            summary: None,
            final_state: None,
            recording: None,
            restart: None,
            command_line: String::new(),
            live: None,
            progress: false,
            one_of_many: true,
            resume: None,
            resume_bare: None,
            tables: TablePaths::default(),
            step_tables: Vec::new(),
            scenario,
        }
    }

    /// The names of every table a run can write, as [`RunPlan::set_table`] takes them
    /// (Python's `run(tables=…)`): the sampled ones, the collision log, then the
    /// registered per-step tables.
    pub fn table_names() -> Vec<&'static str> {
        let mut names = vec!["series", "sizes", "snapshots", "collisions"];
        names.extend(step_tables::STEP_TABLES.iter().map(|t| t.name));
        names
    }

    /// Write the table `name` (one of [`RunPlan::table_names`]) to `path`.
    pub fn set_table(&mut self, name: &str, path: PathBuf) -> anyhow::Result<()> {
        let slot = match name {
            "series" => &mut self.tables.series,
            "sizes" => &mut self.tables.sizes,
            "snapshots" => &mut self.tables.snapshots,
            "collisions" => &mut self.tables.collisions,
            _ => {
                let Some(table) = step_tables::find(name) else {
                    anyhow::bail!(
                        "tables: no table `{name}` (allowed: {})",
                        Self::table_names().join(", ")
                    );
                };
                self.step_tables.retain(|(t, _)| t.name != name);
                self.step_tables.push((table, path));
                return Ok(());
            }
        };
        *slot = Some(path);
        Ok(())
    }

    /// Sample the tables on `schedule`, checked as a scenario's `output.sampling` is.
    pub fn set_sampling(&mut self, schedule: SampleSchedule) -> anyhow::Result<()> {
        if let Some((field, allowed, got)) = schedule.problems().first() {
            anyhow::bail!("sampling: {field}: allowed {allowed} (got {got})");
        }
        self.tables.sampling = Some(schedule);
        Ok(())
    }

    /// Every output of the plan, with the flag that names it: the recording and the
    /// layout written beside it, the summary, the final state, the tables and the
    /// restart file.
    fn outputs(&self) -> Vec<(&'static str, PathBuf)> {
        let t = &self.tables;
        let mut out: Vec<(&'static str, PathBuf)> = [
            ("--recording", &self.recording),
            ("--summary", &self.summary),
            ("--final-state", &self.final_state),
            ("--series", &t.series),
            ("--sizes", &t.sizes),
            ("--snapshots", &t.snapshots),
            ("--collisions", &t.collisions),
        ]
        .into_iter()
        .filter_map(|(flag, path)| path.clone().map(|p| (flag, p)))
        .collect();
        out.extend(self.step_tables.iter().map(|(t, p)| (t.flag, p.clone())));
        if let Some(mcap) = &self.recording {
            out.push((
                "the recording's layout (beside --recording)",
                crate::record::layout::layout_path_for(mcap),
            ));
        }
        if let Some(restart) = self.restart_file() {
            out.push((
                "the restart file of this run's checkpoints (--restart FILE or \
                 output.restart.path)",
                restart,
            ));
        }
        out
    }

    /// No two outputs share a file (`--recording x.mcap --summary x.mcap` left one of
    /// them lost and exited 0; `--recording run.restart` with `output.restart` wrote the recording,
    /// then replaced it by the restart file at the first checkpoint), and the final state
    /// is CSV (`--final-state x.parquet` wrote CSV under a Parquet name).
    pub fn check_paths(&self) -> anyhow::Result<()> {
        if let Some(path) = &self.final_state
            && path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("parquet"))
        {
            anyhow::bail!(
                "--final-state {}: the final state is written as CSV; give a .csv name \
                 (for Parquet, --snapshots F.parquet holds every body at each sample, the \
                 last at the end)",
                path.display()
            );
        }
        let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let outputs = self.outputs();
        for (k, (flag, path)) in outputs.iter().enumerate() {
            for (other_flag, other) in &outputs[..k] {
                if absolute(path) == absolute(other) {
                    anyhow::bail!(
                        "{other_flag} and {flag} are the same file, {}: each output needs a \
                         name of its own",
                        path.display()
                    );
                }
            }
        }
        Ok(())
    }

    /// The restart file this plan writes, if the scenario takes checkpoints: `restart`,
    /// else the resumed file, else the section's path, else beside the recording. None
    /// for one run of many ([`RunPlan::unwritten`]): an ensemble's samples, a study's
    /// settings and `agglo kernel`'s seeds would each write (over) the same file.
    pub fn restart_file(&self) -> Option<PathBuf> {
        if self.one_of_many {
            return None;
        }
        crate::restart::restart_path(
            &self.scenario,
            self.restart
                .as_deref()
                .or(self.resume.as_ref().map(|r| r.file.as_path())),
            self.recording.as_deref(),
        )
    }
}

/// How far [`Run::advance`] goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Until {
    /// To the scenario's end time T (the run is then complete).
    End,
    /// To the first step boundary at or after this simulated time [s] (or T). Steps are
    /// not cut to land on it: the run stays the same as one advanced to T in one go.
    Time(f64),
    /// This many more steps (events, on the event core), or to T.
    Steps(u64),
}

/// A run in progress: the simulation and the outputs it writes as it goes.
pub struct Run {
    scenario: Scenario,
    sim: Simulation,
    stop: Arc<AtomicBool>,
    layout: Option<PathBuf>,
    /// Every output, fed after each step and finished in this order.
    observers: Vec<Box<dyn Observer>>,
    /// The first error of an output (the run stops at it; it is reported at the end).
    output_error: Option<anyhow::Error>,
}

/// What a finished run leaves: the simulation, its summary and what was written.
pub struct RunEnd {
    /// The simulation as the run left it.
    pub sim: Simulation,
    /// Its summary at the end.
    pub summary: Summary,
    /// The recording and what it holds, if one was written.
    pub recording: Option<(PathBuf, RecordingReport)>,
    /// The Foxglove layout written beside the recording.
    pub layout: Option<PathBuf>,
    /// The restart file and the checkpoints written to it.
    pub checkpoints: Option<(PathBuf, CheckpointsWritten)>,
    /// The first error of an output (recording, tables, checkpoints, final state,
    /// summary); the run's own outcome is the caller's.
    pub output_error: Option<anyhow::Error>,
    /// What the outputs ask the front end to tell the user, even with -q (the CLI prints
    /// them to stderr, Python adds them to the run's error).
    pub notes: Vec<String>,
}

impl Run {
    /// Check the memory the run needs, bind the live server (a bad address is refused
    /// before any work), build the scene with the built-in physics, resume it if asked,
    /// and open every output (taking the t = 0 sample and snapshot). `stop` is polled
    /// after every step: once set, [`Run::advance`] returns
    /// [`SimError::Interrupted`].
    pub fn start(plan: RunPlan, stop: Arc<AtomicBool>) -> anyhow::Result<Self> {
        Self::start_with(plan, stop, |_| Ok(()))
    }

    /// [`Run::start`] with a last word on the scene's builder (extensions, subscriptions)
    /// before it is built.
    pub fn start_with(
        plan: RunPlan,
        stop: Arc<AtomicBool>,
        customise: impl FnOnce(&mut crate::schedule::SimBuilder) -> anyhow::Result<()>,
    ) -> anyhow::Result<Self> {
        Self::open(plan, stop, Vec::new(), customise)
    }

    /// [`Run::start`] watched also by a driver's `observers` (the kernel accumulator of
    /// `agglo kernel`): each subscribes before the scene is built and begins on the built
    /// scene ([`Observer::subscribe`], [`Observer::begin`]), is fed after the plan's files
    /// and finished with them; its result comes back through its
    /// [`crate::observer::Handback`].
    pub fn start_observed(
        plan: RunPlan,
        stop: Arc<AtomicBool>,
        observers: Vec<Box<dyn Observer>>,
    ) -> anyhow::Result<Self> {
        Self::open(plan, stop, observers, |_| Ok(()))
    }

    /// [`Run::start_observed`] with a last word on the scene's builder (as
    /// [`Run::start_with`]), given after the observers' subscriptions, right before the
    /// scene is built.
    pub fn start_observed_with(
        plan: RunPlan,
        stop: Arc<AtomicBool>,
        observers: Vec<Box<dyn Observer>>,
        customise: impl FnOnce(&mut crate::schedule::SimBuilder) -> anyhow::Result<()>,
    ) -> anyhow::Result<Self> {
        Self::open(plan, stop, observers, customise)
    }

    /// Start `plan` with `observers` (as [`Run::start_observed`]), advance it to T and
    /// finish it: a run of an ensemble, a study or `agglo kernel` in one call. Returns
    /// what the run left and its own outcome (an observer's error is in
    /// [`RunEnd::output_error`]); an error when the scene cannot be built or an observer
    /// cannot begin.
    pub fn complete(
        plan: RunPlan,
        observers: Vec<Box<dyn Observer>>,
    ) -> anyhow::Result<(RunEnd, Result<(), SimError>)> {
        let mut run = Self::start_observed(plan, Arc::default(), observers)?;
        let outcome = run.advance(Until::End, &mut |_| ControlFlow::Continue(()));
        Ok((run.finish(&outcome), outcome))
    }

    /// Build the scene (built-ins, registered extensions, every observer's
    /// subscriptions, then `customise`), resume it, begin the driver's `driven`
    /// observers and open the plan's outputs.
    fn open(
        plan: RunPlan,
        stop: Arc<AtomicBool>,
        mut driven: Vec<Box<dyn Observer>>,
        customise: impl FnOnce(&mut crate::schedule::SimBuilder) -> anyhow::Result<()>,
    ) -> anyhow::Result<Self> {
        let scenario = &plan.scenario;
        plan.check_paths()?;
        // Before anything is allocated: does the scene fit in memory (recorded or not)?
        // (A run of many is checked by its driver, with the others held at once.)
        if !plan.one_of_many
            && let Some(warning) =
                crate::memory::MemoryEstimate::of_run(scenario, plan.recording.is_some())
                    .check()
                    .map_err(anyhow::Error::msg)?
        {
            eprintln!("{warning}");
        }
        let live_server = match &plan.live {
            Some(options) => {
                check_options(options)?;
                let server = Server::bind(options.addr, "agglo run", crate::live::run::topics()?)?;
                Some((server, options.clone()))
            }
            None => None,
        };
        let mut builder = match (&plan.resume, &plan.resume_bare) {
            (Some(resume), Some(bare)) => {
                let mut builder = crate::plugins::resuming_builder(
                    scenario,
                    &resume.snapshot,
                    bare.initial_bodies,
                )
                .context("setting up the scene")?;
                builder.insert_resource(bare.energies);
                builder
            }
            _ => crate::plugins::builder(scenario).context("setting up the scene")?,
        };
        plan.tables.subscribe(&mut builder);
        for (table, _) in &plan.step_tables {
            (table.subscribe)(&mut builder);
        }
        for observer in &driven {
            observer.subscribe(&mut builder);
        }
        customise(&mut builder)?;
        let mut sim = builder.build().context("setting up the scene")?;
        if let Some(resume) = &plan.resume {
            sim.resume(&resume.snapshot)
                .with_context(|| format!("resuming from {}", resume.file.display()))?;
        }
        for observer in &mut driven {
            observer.begin(&sim)?;
        }
        let layout = match &plan.recording {
            Some(path) => Some(write_layout_beside(path, scenario)?),
            None => None,
        };
        let observers = open_observers(&plan, &sim, live_server, &stop, driven)?;
        Ok(Self {
            scenario: plan.scenario,
            sim,
            stop,
            layout,
            observers,
            output_error: None,
        })
    }

    /// The simulation (read it between advances: its clock, counters, bodies).
    pub fn sim(&self) -> &Simulation {
        &self.sim
    }

    /// The simulation, for a driver's reading between advances that needs the world
    /// mutably (a query's state: a subgrid box reads the initial energies its checks
    /// were built with). Not for changing the run: its outputs would not see it.
    pub fn sim_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    /// A restart snapshot of now ([`Simulation::snapshot_now`]): this run and one
    /// resumed from it continue alike.
    pub fn snapshot_now(&mut self) -> Result<RestartSnapshot, SimError> {
        self.sim.snapshot_now()
    }

    /// The scenario being run.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The stop flag this run polls.
    pub fn stop_flag(&self) -> &Arc<AtomicBool> {
        &self.stop
    }

    /// Advance to `until`, feeding every output after each step, then `observe` (a
    /// front end's hooks: `Break` stops the run as the stop flag does). Returns
    /// [`SimError::Interrupted`] when stopped (by the flag, `observe` or a failing
    /// output — that error is told by [`Run::finish`]); the run stays valid and a later
    /// call continues it to the same bytes as an uninterrupted run.
    pub fn advance(
        &mut self,
        until: Until,
        observe: &mut dyn FnMut(&Simulation) -> ControlFlow<()>,
    ) -> Result<(), SimError> {
        if self.output_error.is_some() {
            let c = self.sim.clock();
            return Err(SimError::Interrupted {
                step: c.step,
                time: c.time,
            });
        }
        let first_step = self.sim.clock().step;
        let done = |s: &Simulation| match until {
            Until::End => false,
            Until::Time(t) => s.clock().time >= t,
            Until::Steps(n) => s.clock().step - first_step >= n,
        };
        let Self {
            sim,
            stop,
            observers,
            output_error,
            ..
        } = self;
        let _advancing = signals::Advancing::enter();
        sim.run_until(done, |s| {
            signals::step_done();
            for o in observers.iter_mut() {
                if let Err(e) = o.observe(s) {
                    *output_error = Some(e);
                    return ControlFlow::Break(());
                }
            }
            if observe(s).is_break() || stop.load(Ordering::SeqCst) {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
    }

    /// True once the run reached T.
    pub fn is_finished(&self) -> bool {
        self.sim.is_finished()
    }

    /// Finalise every output whatever `outcome` (the last [`Run::advance`]'s result) was:
    /// the recording gets its last state, outcome and summary section, the live view its
    /// last frame, the tables their last sample; then the final state and summary files.
    pub fn finish(self, outcome: &Result<(), SimError>) -> RunEnd {
        let mut error = self.output_error;
        let bodies = self.sim.bodies();
        let summary = Summary::new(&self.sim, &bodies);
        let end = Ending {
            sim: &self.sim,
            outcome,
            bodies: &bodies,
            summary: &summary,
        };
        let mut written = Written::default();
        // A table whose writer failed during the run fails again here: the first error
        // is the one told.
        for o in self.observers {
            if let Err(e) = o.finish(&end, &mut written) {
                error.get_or_insert(e);
            }
        }
        RunEnd {
            summary,
            recording: written.recording,
            layout: self.layout,
            checkpoints: written.checkpoints,
            output_error: error,
            notes: written.notes,
            sim: self.sim,
        }
    }
}

/// The outputs `plan` asks for, open on the built `sim` (each table takes its t = 0
/// sample), in the order they are fed and finished: the progress line and the warnings
/// first, the files, a driver's `driven` observers, then the live view last (with a
/// client connected it may keep serving the final state a while, and every file must be
/// written before that wait), and a test's switches (which act once the step's outputs
/// are written).
fn open_observers(
    plan: &RunPlan,
    sim: &Simulation,
    live_server: Option<(Server, LiveOptions)>,
    stop: &Arc<AtomicBool>,
    driven: Vec<Box<dyn Observer>>,
) -> anyhow::Result<Vec<Box<dyn Observer>>> {
    let scenario = &plan.scenario;
    let mut observers: Vec<Box<dyn Observer>> = Vec::new();
    let progress = plan
        .progress
        .then(|| Progress::new(scenario.time.end, scenario.uses_event_core()));
    let bar = progress.as_ref().map(Progress::bar);
    if let Some(p) = progress {
        observers.push(Box::new(p));
    }
    if !plan.one_of_many
        && let Some(w) = ClampWarnings::new(scenario, sim, bar)
    {
        observers.push(Box::new(w));
    }
    // Created after the caller's stop handlers: once the file exists, a stop finalises it.
    if let Some(path) = &plan.recording {
        observers.push(Box::new(recording::Recording(Recorder::create(
            path,
            sim,
            &plan.command_line,
        )?)));
    }
    if let Some(tables) = RunTables::open(&plan.tables, scenario, sim)? {
        observers.push(Box::new(tables));
    }
    for (table, path) in &plan.step_tables {
        observers.push((table.open)(path, scenario, sim)?);
    }
    if let Some(path) = plan.restart_file() {
        observers.push(Box::new(checkpoints::Checkpoints::new(
            path,
            scenario.clone(),
        )));
    }
    if let Some(path) = &plan.final_state {
        observers.push(Box::new(end_files::FinalState(path.clone())));
    }
    if let Some(path) = &plan.summary {
        observers.push(Box::new(end_files::SummaryFile(path.clone())));
    }
    observers.extend(driven);
    if let Some((server, options)) = live_server {
        let beside = plan.recording.as_deref().or(plan.summary.as_deref());
        observers.push(Box::new(start_live(
            server, &options, sim, scenario, beside, stop,
        )?));
    }
    if let Some(switches) = test_switches::TestSwitches::from_env() {
        observers.push(Box::new(switches));
    }
    Ok(observers)
}

/// Start serving `sim` on the bound `server`: print the address and the link, write the
/// fitted layout (beside `beside`, a recording or summary, else in the temporary
/// directory), wait for a client if asked.
fn start_live(
    server: Server,
    options: &LiveOptions,
    sim: &Simulation,
    scenario: &Scenario,
    beside: Option<&Path>,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<LiveRun> {
    let layout = match beside {
        Some(p) => crate::record::layout::layout_path_for(p),
        None => {
            std::env::temp_dir().join(format!("agglo-live-{}.layout.json", scenario.file_stem()))
        }
    };
    crate::record::layout::write_fitted_layout(&layout, scenario.domain.half_width)?;
    announce_live(&server, &layout);
    LiveRun::start(server, options, sim, stop)
}

/// A run's error as ensembles and studies record it: a scene the engine refused reads as
/// the engine's [`SimError`] alone (without the "setting up the scene" that
/// [`Run::start`] puts before it), anything else with its whole chain.
pub fn failure_text(e: &anyhow::Error) -> String {
    match e.downcast_ref::<SimError>() {
        Some(sim) => sim.to_string(),
        None => format!("{e:#}"),
    }
}

/// Tell the user where a live server listens and where its layout is (stderr).
pub fn announce_live(server: &Server, layout: &Path) {
    eprintln!(
        "live: serving on {} — in Foxglove open a Foxglove WebSocket connection to it ({}); \
         layout: {}",
        server.url(),
        server.app_link(),
        layout.display()
    );
}

/// Write the Foxglove layout fitted to the scene's box beside the recording `mcap`.
fn write_layout_beside(mcap: &Path, scenario: &Scenario) -> anyhow::Result<PathBuf> {
    use crate::record::layout::{layout_path_for, write_fitted_layout};
    let path = layout_path_for(mcap);
    write_fitted_layout(&path, scenario.domain.half_width)?;
    Ok(path)
}
