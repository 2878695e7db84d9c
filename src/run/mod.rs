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

pub mod clamp_watch;
pub mod progress;
pub mod signals;

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

use crate::error::SimError;
use crate::live::run::LiveRun;
use crate::live::{LiveOptions, Server, check_options};
use crate::observables::Summary;
use crate::output::{RunTables, TableArgs, TablePaths, write_final_state_with, write_summary};
use crate::record::{Recorder, RecordingReport};
use crate::restart::RestartSnapshot;
use crate::scenario::{Scenario, Stepping};
use crate::schedule::Simulation;
use clamp_watch::{ClampWatch, ClampedWindow};
use progress::Progress;

/// A run to make: the scenario and where each output goes. [`RunPlan::new`] takes the
/// paths from the scenario's `output` section; a front end overrides them (the flags of
/// `agglo run`, the arguments of `Simulation.run` in Python).
#[derive(Debug)]
pub struct RunPlan {
    pub scenario: Scenario,
    /// Continue a stopped run from this checkpoint (`agglo run --resume`).
    pub resume: Option<Resume>,
    /// The tables sampled during the run and their schedule.
    pub tables: TablePaths,
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
}

/// A checkpoint to continue from, and the file it was read from.
#[derive(Debug)]
pub struct Resume {
    pub file: PathBuf,
    pub snapshot: RestartSnapshot,
}

impl RunPlan {
    /// The plan of `agglo run SCENARIO` without flags: every output where the scenario's
    /// `output` section puts it.
    pub fn new(scenario: Scenario) -> anyhow::Result<Self> {
        let tables = TableArgs::default().paths(&scenario.output)?;
        let output = &scenario.output;
        Ok(Self {
            summary: output.summary.clone().map(PathBuf::from),
            final_state: output.final_state.clone().map(PathBuf::from),
            recording: output.mcap.clone().map(PathBuf::from),
            restart: None,
            command_line: String::new(),
            live: None,
            progress: false,
            resume: None,
            tables,
            scenario,
        })
    }

    /// Every output of the plan, with the flag that names it: the recording and the
    /// layout written beside it, the summary, the final state, the tables and the
    /// restart file.
    fn outputs(&self) -> Vec<(&'static str, PathBuf)> {
        let t = &self.tables;
        let mut out: Vec<(&'static str, PathBuf)> = [
            ("--out (the recording)", &self.recording),
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
        if let Some(mcap) = &self.recording {
            out.push((
                "the recording's layout (beside --out)",
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

    /// No two outputs share a file (`--out x.mcap --summary x.mcap` left one of them
    /// lost and exited 0; `--out run.restart` with `output.restart` wrote the recording,
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
    /// else the resumed file, else the section's path, else beside the recording.
    pub fn restart_file(&self) -> Option<PathBuf> {
        crate::restart::restart_path(
            &self.scenario,
            self.restart
                .as_deref()
                .or(self.resume.as_ref().map(|r| r.file.as_path())),
            self.recording.as_deref(),
        )
    }
}

/// Checkpoints written during a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CheckpointsWritten {
    pub count: u64,
    /// Size of the last [bytes].
    pub bytes: u64,
    /// Simulated time of the last [s].
    pub time: f64,
    /// Wall-clock seconds spent writing them.
    pub writing_seconds: f64,
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
    summary_path: Option<PathBuf>,
    final_path: Option<PathBuf>,
    /// What is fed after each step.
    outputs: Outputs,
}

/// The outputs of a [`Run`] fed after each step.
struct Outputs {
    recorder: Option<Recorder>,
    tables: Option<RunTables>,
    live: Option<LiveRun>,
    restart_file: Option<PathBuf>,
    checkpoints: CheckpointsWritten,
    clamp_watch: Option<(ClampWatch, f64)>,
    progress: Option<Progress>,
    /// The first error of an output (the run stops at it; it is reported at the end).
    output_error: Option<anyhow::Error>,
    /// For the restart tests: SIGKILL this process after the given step
    /// (`AGGLO_TEST_SIGKILL_AFTER_STEP`), at a point the test chooses exactly.
    kill_after: Option<u64>,
}

/// What a finished run leaves: the simulation, its summary and what was written.
pub struct RunEnd {
    pub sim: Simulation,
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
        let scenario = &plan.scenario;
        plan.check_paths()?;
        // Before anything is allocated: does the scene fit in memory (recorded or not)?
        if let Some(warning) =
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
        let mut builder = plan
            .tables
            .builder(scenario)
            .context("setting up the scene")?;
        customise(&mut builder)?;
        let mut sim = builder.build().context("setting up the scene")?;
        if let Some(resume) = &plan.resume {
            sim.resume(&resume.snapshot)
                .with_context(|| format!("resuming from {}", resume.file.display()))?;
        }
        let restart_file = plan.restart_file();
        let layout = match &plan.recording {
            Some(path) => Some(write_layout_beside(path, scenario)?),
            None => None,
        };
        // Created after the caller's stop handlers: once the file exists, a stop
        // finalises it.
        let recorder = match &plan.recording {
            Some(path) => Some(Recorder::create(path, &sim, &plan.command_line)?),
            None => None,
        };
        let tables = RunTables::open(&plan.tables, scenario, &sim)?;
        let beside = plan.recording.as_deref().or(plan.summary.as_deref());
        let live = match live_server {
            Some((server, options)) => {
                Some(start_live(server, &options, &sim, scenario, beside, &stop)?)
            }
            None => None,
        };
        let clamp_watch = clamping_floor(scenario).map(|dt_min| {
            let c = sim.clock();
            (
                ClampWatch::new(c.step, sim.counters().clamped_steps),
                dt_min,
            )
        });
        let progress = plan
            .progress
            .then(|| Progress::new(scenario.time.end, scenario.uses_event_core()));
        let kill_after = std::env::var("AGGLO_TEST_SIGKILL_AFTER_STEP")
            .ok()
            .and_then(|v| v.parse::<u64>().ok());
        Ok(Self {
            scenario: plan.scenario,
            sim,
            stop,
            layout,
            summary_path: plan.summary,
            final_path: plan.final_state,
            outputs: Outputs {
                recorder,
                tables,
                live,
                restart_file,
                checkpoints: CheckpointsWritten::default(),
                clamp_watch,
                progress,
                output_error: None,
                kill_after,
            },
        })
    }

    /// The simulation (read it between advances: its clock, counters, bodies).
    pub fn sim(&self) -> &Simulation {
        &self.sim
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
        if self.outputs.output_error.is_some() {
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
            scenario,
            sim,
            stop,
            outputs,
            ..
        } = self;
        let _advancing = signals::Advancing::enter();
        let stuck_at = std::env::var("AGGLO_TEST_STUCK_AT_STEP")
            .ok()
            .and_then(|v| v.parse::<u64>().ok());
        sim.run_until(done, |s| {
            if stuck_at == Some(s.clock().step) {
                // A step that never ends, for the test of the stop watchdog (signals.rs).
                loop {
                    std::thread::sleep(std::time::Duration::from_millis(50));
                }
            }
            signals::step_done();
            if outputs.observe(scenario, s).is_break() || observe(s).is_break() {
                return ControlFlow::Break(());
            }
            if stop.load(Ordering::SeqCst) {
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
    pub fn finish(mut self, outcome: &Result<(), SimError>) -> RunEnd {
        if let Some(bar) = self.outputs.progress.take() {
            bar.finish();
        }
        let mut error = self.outputs.output_error.take();
        let recording = match self.outputs.recorder.take() {
            Some(r) => {
                let path = r.path().to_path_buf();
                match r.finish(&self.sim, outcome) {
                    Ok(report) => Some((path, report)),
                    Err(e) => {
                        error.get_or_insert(e);
                        None
                    }
                }
            }
            None => None,
        };
        // The live view last: with a client connected it may keep serving the final
        // state for a while, and every file must be written before that wait.
        let live = self.outputs.live.take();
        // A table whose writer failed during the run fails again here: the first error
        // is the one told.
        if let Some(t) = self.outputs.tables.take()
            && let Err(e) = t.finish(&self.sim)
        {
            error.get_or_insert(e);
        }
        let bodies = self.sim.bodies();
        let summary = Summary::new(&self.sim, &bodies);
        if let Some(path) = &self.final_path
            && let Err(e) = write_final_state_with(path, &bodies, &self.sim.carried())
        {
            error.get_or_insert(e);
        }
        if let Some(path) = &self.summary_path
            && let Err(e) = write_summary(path, &summary)
        {
            error.get_or_insert(e);
        }
        if let Some(l) = live {
            l.finish(&self.sim, outcome);
        }
        RunEnd {
            summary,
            recording,
            layout: self.layout,
            checkpoints: self
                .outputs
                .restart_file
                .map(|p| (p, self.outputs.checkpoints)),
            output_error: error,
            sim: self.sim,
        }
    }
}

impl Outputs {
    /// After a step: progress, warnings, live frame, recording, tables, checkpoint.
    fn observe(&mut self, scenario: &Scenario, s: &Simulation) -> ControlFlow<()> {
        if let Some(bar) = self.progress.as_mut() {
            bar.update(s);
        }
        if let Some((watch, dt_min)) = self.clamp_watch.as_mut() {
            let c = s.clock();
            if let Some(window) = watch.observe(
                c.step,
                s.counters().clamped_steps,
                std::time::Instant::now(),
            ) {
                let warning = clamping_warning(scenario, *dt_min, c.time, window);
                // Above the progress bar, which also draws on stderr.
                match self.progress.as_ref() {
                    Some(bar) => bar.suspend(|| eprintln!("{warning}")),
                    None => eprintln!("{warning}"),
                }
            }
        }
        if let Some(l) = self.live.as_mut() {
            l.observe(s);
        }
        if let Some(r) = self.recorder.as_mut()
            && let Err(e) = r.observe(s)
        {
            self.output_error = Some(e);
            return ControlFlow::Break(());
        }
        if let Some(t) = self.tables.as_mut()
            && let Err(e) = t.observe(s)
        {
            self.output_error = Some(e);
            return ControlFlow::Break(());
        }
        if let (Some(path), Some(snapshot)) = (&self.restart_file, s.restart_snapshot()) {
            let start = std::time::Instant::now();
            match crate::restart::write(path, scenario, snapshot) {
                Ok(bytes) => {
                    let c = &mut self.checkpoints;
                    c.count += 1;
                    c.bytes = bytes;
                    c.time = snapshot.time();
                    c.writing_seconds += start.elapsed().as_secs_f64();
                }
                Err(e) => {
                    self.output_error = Some(e);
                    return ControlFlow::Break(());
                }
            }
        }
        if self.kill_after == Some(s.clock().step) {
            // Die as a killed job does: no handler runs, nothing is flushed.
            // SAFETY: getpid and kill have no preconditions.
            unsafe { libc::kill(libc::getpid(), libc::SIGKILL) };
        }
        ControlFlow::Continue(())
    }
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

/// Δt_min, if the scene can clamp at it: only the stepped core with adaptive steps does
/// (the event core lands on every contact; fixed steps have no lower bound).
fn clamping_floor(s: &Scenario) -> Option<f64> {
    match s.time.stepping {
        Stepping::Adaptive { dt_min, .. } if !s.uses_event_core() => Some(dt_min),
        _ => None,
    }
}

/// The warning printed (to stderr, even when quiet: it is about a run going wrong) when
/// most steps of a window were clamped.
fn clamping_warning(s: &Scenario, dt_min: f64, t: f64, window: ClampedWindow) -> String {
    format!(
        "warning: at t = {t:.4e} s, {} of the last {} steps were clamped at Δt_min = {dt_min:e} s \
         although a contact was due sooner: contacts are resolved late, and the run advances \
         about Δt_min per step (T/Δt_min = {:.1e} steps, time.max_steps = {}); \
         lower time.stepping.adaptive.dt_min",
        window.clamped,
        window.steps,
        s.time.end / dt_min,
        s.time.max_steps
    )
}
