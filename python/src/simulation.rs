//! `agglo.Simulation`'s compiled core: one run of a scenario, through `agglo::run` (the
//! code `agglo run` calls), advanced with the GIL released.
//!
//! A simulation is built when it is made (so a scene that cannot be built fails at
//! once). Its outputs — tables, recording, summary and final-state files, the live view —
//! are chosen before the first step (the t = 0 sample is part of them); choosing them
//! then rebuilds the run, which is deterministic, so nothing changes. Once T is reached
//! every output is finalised, as `agglo run` does at its end.
//!
//! Ctrl-C: while stepping, the Python signal handlers are run every
//! [`SIGNAL_CHECK`] of wall time at a step boundary (the GIL taken back for that
//! instant); a `KeyboardInterrupt` stops the run there, leaving it valid: `run()`
//! continues it to the same bytes as an uninterrupted run.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use agglo::error::SimError;
use agglo::output::SampleSchedule;
use agglo::output::table::{Table, read_table};
use agglo::run::{Run, RunPlan, Until};

use crate::errors::{AggloError, agglo_error, guard, scenario_error};
use crate::scenario::Scenario;

/// Wall time between two looks at Python's signal handlers while stepping.
const SIGNAL_CHECK: Duration = Duration::from_millis(50);
/// Steps between two looks at the wall clock.
const CLOCK_CHECK_STEPS: u64 = 16;

/// Where a simulation is.
enum State {
    /// Built, perhaps stepped; outputs open.
    Running(Box<Run>),
    /// Reached T (or closed): outputs finalised.
    Done(Box<Done>),
    /// Only while switching between the two.
    Switching,
}

/// A finished run: its simulation, summary and the tables kept in memory.
struct Done {
    sim: agglo::schedule::Simulation,
    summary: agglo::observables::Summary,
    tables: BTreeMap<String, Table>,
}

/// The inner state, behind a lock (a Python object may be reached from any thread).
struct Inner {
    scenario: agglo::scenario::Scenario,
    state: State,
    /// True once outputs were chosen (they cannot be chosen twice).
    has_outputs: bool,
    /// The run's plan with the outputs chosen (kept to rebuild the run when a hook is
    /// added): `agglo::run`'s own type, so an output it gains is one here too.
    plan: RunPlan,
    /// The Python hooks, called in batches (hooks.rs).
    hooks: Vec<crate::hooks::Hook>,
    /// The snapshot this simulation was unpickled from (kept to rebuild the run).
    resume: Option<agglo::restart::RestartSnapshot>,
    /// True once this object advanced the run (outputs and hooks come before).
    stepped: bool,
    /// The quantities carried from Python (carry.rs).
    carry: Vec<crate::carry::Spec>,
    /// Directory of the tables kept in memory (read back and removed at the end).
    memory_dir: Option<PathBuf>,
    memory_tables: Vec<String>,
}

/// One run of a scenario.
#[pyclass(module = "agglo._agglo", name = "Simulation")]
pub struct Simulation {
    inner: Mutex<Inner>,
    /// The clock of the run while it is locked by `run()`/`step()` (a hook reading
    /// `sim.t` ran into the lock and was told the simulation ran in another thread).
    clock: ClockMirror,
}

/// Time [s] (as bits) and step of the last step taken, stored after every step.
#[derive(Default)]
struct ClockMirror {
    time_bits: std::sync::atomic::AtomicU64,
    step: std::sync::atomic::AtomicU64,
}

impl ClockMirror {
    fn store(&self, time: f64, step: u64) {
        self.time_bits.store(time.to_bits(), Ordering::Relaxed);
        self.step.store(step, Ordering::Relaxed);
    }
    fn time(&self) -> f64 {
        f64::from_bits(self.time_bits.load(Ordering::Relaxed))
    }
}

/// The arguments of `run()` that choose outputs, as Python gave them.
#[derive(Default)]
struct Outputs {
    tables: BTreeMap<String, Option<PathBuf>>,
    sampling: Option<String>,
    recording: Option<PathBuf>,
    summary: Option<PathBuf>,
    final_state: Option<PathBuf>,
    live: Option<String>,
    progress: bool,
    command_line: Option<String>,
}

impl Outputs {
    fn any(&self) -> bool {
        !self.tables.is_empty()
            || self.sampling.is_some()
            || self.recording.is_some()
            || self.summary.is_some()
            || self.final_state.is_some()
            || self.live.is_some()
            || self.progress
    }
}

impl Simulation {
    /// The run of `scenario` (resumed from `resume`, carrying `carry`) with the outputs
    /// its `output` section names, as `agglo run` takes them.
    fn built(
        scenario: agglo::scenario::Scenario,
        resume: Option<agglo::restart::RestartSnapshot>,
        carry: Vec<crate::carry::Spec>,
    ) -> PyResult<Self> {
        let plan = RunPlan::new(scenario.clone()).map_err(scenario_error)?;
        let mut inner = Inner {
            scenario,
            state: State::Switching,
            has_outputs: false,
            plan,
            hooks: Vec::new(),
            resume,
            stepped: false,
            carry,
            memory_dir: None,
            memory_tables: Vec::new(),
        };
        inner.rebuild()?;
        Ok(Self {
            clock: ClockMirror::default(),
            inner: Mutex::new(inner),
        })
    }

    fn lock(&self) -> PyResult<MutexGuard<'_, Inner>> {
        self.inner.try_lock().map_err(|_| {
            AggloError::new_err(
                "this simulation is running (a hook of its own run, or another thread): read \
                 it once run() or step() returns; sim.t and sim.steps can be read meanwhile",
            )
        })
    }
}

impl Inner {
    /// The simulation; an error when the run could not be rebuilt (a failed `run()` with
    /// new outputs or a hook added, after the old run was dropped).
    fn sim(&self) -> PyResult<&agglo::schedule::Simulation> {
        match &self.state {
            State::Running(run) => Ok(run.sim()),
            State::Done(done) => Ok(&done.sim),
            State::Switching => Err(AggloError::new_err(
                "this simulation could not be rebuilt with the outputs or hooks asked \
                 (the error was raised then): make a new Simulation",
            )),
        }
    }

    /// Apply `outputs`: only before the first step, and once.
    fn choose_outputs(&mut self, outputs: Outputs) -> PyResult<()> {
        if !outputs.any() {
            return Ok(());
        }
        if !self.fresh() || self.has_outputs {
            return Err(scenario_error(
                "run: outputs (tables, sampling, recording, summary, final_state, live, progress) are \
                 chosen before the first step, once: make a new Simulation to write them",
            ));
        }
        let mut plan = self.plan.clone();
        plan.progress = outputs.progress;
        plan.command_line = outputs
            .command_line
            .unwrap_or_else(|| "python: agglo.Simulation.run".into());
        // Kept only once every output is accepted (an error leaves the simulation as it was).
        let mut memory_tables = Vec::new();
        let names = RunPlan::table_names();
        for (name, path) in outputs.tables {
            if !names.contains(&name.as_str()) {
                return Err(scenario_error(format!(
                    "run: tables: no table `{name}` (allowed: {})",
                    names.join(", ")
                )));
            }
            let path = match path {
                Some(p) => p,
                None => {
                    let dir = self.memory_dir.get_or_insert_with(memory_dir);
                    std::fs::create_dir_all(&*dir).map_err(|e| {
                        agglo_error(anyhow::anyhow!("creating {}: {e}", dir.display()))
                    })?;
                    memory_tables.push(name.clone());
                    dir.join(format!("{name}.parquet"))
                }
            };
            plan.set_table(&name, path)
                .map_err(|e| scenario_error(format!("run: {e}")))?;
        }
        if let Some(json) = outputs.sampling {
            let schedule: SampleSchedule = serde_json::from_str(&json).map_err(|e| {
                scenario_error(format!(
                    "run: sampling: {e} (give {{\"interval\": {{\"dt\": SECONDS}}}}, \
                     {{\"log\": {{\"per_decade\": K}}}} or {{\"steps\": {{\"every\": K}}}})"
                ))
            })?;
            plan.set_sampling(schedule)
                .map_err(|e| scenario_error(format!("run: {e}")))?;
        }
        if let Some(path) = outputs.recording {
            plan.recording = Some(path);
        }
        if let Some(path) = outputs.summary {
            plan.summary = Some(path);
        }
        if let Some(path) = outputs.final_state {
            plan.final_state = Some(path);
        }
        if let Some(addr) = outputs.live {
            let options = agglo::live::LiveOptions {
                addr: agglo::live::parse_addr(&addr).map_err(scenario_error)?,
                wait: false,
                rate_hz: 10.0,
                max_bodies: 10_000,
                // `run()` returns when the run ends: a notebook cell is not held open
                // for a client (the CLI's --live-linger is for a terminal).
                linger_seconds: 0.0,
                pace: None,
            };
            plan.live = Some(options);
        }
        let before = (
            std::mem::replace(&mut self.plan, plan),
            std::mem::replace(&mut self.memory_tables, memory_tables),
            std::mem::replace(&mut self.has_outputs, true),
        );
        self.rebuild_or_restore(|inner| {
            (inner.plan, inner.memory_tables, inner.has_outputs) = before;
        })
    }

    /// [`Inner::rebuild`]; when it fails (an output that cannot be opened), `restore`
    /// puts back what was there and the run is rebuilt as it was, so that the error
    /// leaves a usable simulation (it left one that refused every later call).
    fn rebuild_or_restore(&mut self, restore: impl FnOnce(&mut Self)) -> PyResult<()> {
        let Err(error) = self.rebuild() else {
            return Ok(());
        };
        restore(self);
        self.rebuild()?;
        Err(error)
    }

    /// Build the run anew from the scenario, the outputs and the hooks' subscriptions
    /// (before the first step only: the run is deterministic, so nothing changes).
    fn rebuild(&mut self) -> PyResult<()> {
        let mut plan = self.plan.clone();
        plan.resume = self.resume.clone().map(|snapshot| agglo::run::Resume {
            file: PathBuf::from("<pickle>"),
            snapshot,
        });
        // Drop the run built before building the new one (its live server, if any,
        // would hold the port).
        self.state = State::Switching;
        let (hooks, carry) = (&self.hooks, &self.carry);
        let run = Run::start_with(plan, Arc::new(AtomicBool::new(false)), |builder| {
            crate::hooks::subscribe(builder, hooks);
            crate::carry::register(builder, carry)
        })
        .map_err(agglo_error)?;
        self.state = State::Running(Box::new(run));
        Ok(())
    }

    /// True before the first step (of this object: an unpickled run may be far along).
    fn fresh(&self) -> bool {
        !self.stepped && matches!(self.state, State::Running(_))
    }

    /// Finalise the outputs with `outcome` and keep the finished simulation.
    /// Finish the run's outputs; the notes they leave for the user (a failed run's final
    /// state is the state at the failure).
    fn finish(&mut self, outcome: &Result<(), SimError>) -> PyResult<Vec<String>> {
        let State::Running(run) = std::mem::replace(&mut self.state, State::Switching) else {
            return Ok(Vec::new());
        };
        let end = run.finish(outcome);
        let notes = end.notes;
        let mut tables = BTreeMap::new();
        let mut error = end.output_error.map(|e| e.context("recording the run"));
        if let Some(dir) = self.memory_dir.take() {
            for name in self.memory_tables.drain(..) {
                let path = dir.join(format!("{name}.parquet"));
                match read_table(&path) {
                    Ok(table) => {
                        tables.insert(name, table);
                    }
                    Err(e) => {
                        error.get_or_insert(e);
                    }
                }
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
        self.state = State::Done(Box::new(Done {
            sim: end.sim,
            summary: end.summary,
            tables,
        }));
        match error {
            Some(e) => Err(agglo_error(e)),
            None => Ok(notes),
        }
    }
}

/// The carried quantities from their Python form.
fn specs(carry: Vec<(String, String, String, Vec<f64>)>) -> PyResult<Vec<crate::carry::Spec>> {
    let mut seen = std::collections::BTreeSet::new();
    carry
        .into_iter()
        .map(|(name, combine, split, init)| {
            if !seen.insert(name.clone()) {
                return Err(scenario_error(format!("carry: `{name}` given twice")));
            }
            crate::carry::Spec::new(name, &combine, &split, init)
        })
        .collect()
}

/// A private directory for the tables kept in memory.
fn memory_dir() -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "agglo-py-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Step `run` to `until` with the GIL released, running Python's signal handlers every
/// [`SIGNAL_CHECK`] and the hooks when due. Returns the run's outcome and the Python
/// error (KeyboardInterrupt, a hook's exception) that stopped it, if one did.
fn advance(
    py: Python<'_>,
    run: &mut Run,
    hooks: &mut [crate::hooks::Hook],
    until: Until,
    clock: &ClockMirror,
) -> (Result<(), SimError>, Option<PyErr>) {
    py.detach(|| {
        let mut raised: Option<PyErr> = None;
        let mut last_check = Instant::now();
        let mut steps = 0u64;
        let outcome = run.advance(until, &mut |s| {
            steps += 1;
            clock.store(s.clock().time, s.clock().step);
            if !hooks.is_empty()
                && let Err(r) = crate::hooks::observe(hooks, s, false)
            {
                raised = Some(r);
                return ControlFlow::Break(());
            }
            if steps.is_multiple_of(CLOCK_CHECK_STEPS) && last_check.elapsed() >= SIGNAL_CHECK {
                last_check = Instant::now();
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    raised = Some(e);
                    return ControlFlow::Break(());
                }
            }
            ControlFlow::Continue(())
        });
        // At T: every hook gets what it still holds.
        if raised.is_none()
            && outcome.is_ok()
            && run.is_finished()
            && !hooks.is_empty()
            && let Err(r) = crate::hooks::observe(hooks, run.sim(), true)
        {
            raised = Some(r);
        }
        (outcome, raised)
    })
}

#[pymethods]
impl Simulation {
    /// A run of `scenario` (its seed, or `seed`), with the built-in physics, carrying
    /// the quantities of `carry`: (name, combine, split, initial values) each.
    #[new]
    #[pyo3(signature = (scenario, seed=None, carry=Vec::new()))]
    fn new(
        scenario: &Scenario,
        seed: Option<u64>,
        carry: Vec<(String, String, String, Vec<f64>)>,
    ) -> PyResult<Self> {
        guard(|| {
            let mut scenario = scenario.inner.clone();
            if let Some(seed) = seed {
                scenario.seed = seed;
            }
            Self::built(scenario, None, specs(carry)?)
        })
    }

    /// Advance to `until` [s] (the first step boundary at or after it; None: to T),
    /// writing the outputs chosen (before the first step): `tables` maps a table name
    /// (series, sizes, snapshots, collisions) to a path, or to None to keep it in memory;
    /// `sampling` is the JSON of `output.sampling`; `recording`, `summary`, `final_state`
    /// are paths; `live` an address to serve the run on; `command_line` what the
    /// recording keeps as its command line. Returns True once T is reached
    /// (the outputs are then finalised).
    #[pyo3(signature = (until=None, tables=None, sampling=None, recording=None, summary=None, final_state=None, live=None, progress=false, command_line=None))]
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        py: Python<'_>,
        until: Option<f64>,
        tables: Option<BTreeMap<String, Option<PathBuf>>>,
        sampling: Option<String>,
        recording: Option<PathBuf>,
        summary: Option<PathBuf>,
        final_state: Option<PathBuf>,
        live: Option<String>,
        progress: bool,
        command_line: Option<String>,
    ) -> PyResult<bool> {
        guard(|| {
            if let Some(t) = until
                && !t.is_finite()
            {
                return Err(scenario_error(format!(
                    "run: until: a finite time [s] (got {t})"
                )));
            }
            let mut inner = self.lock()?;
            inner.choose_outputs(Outputs {
                tables: tables.unwrap_or_default(),
                sampling,
                recording,
                summary,
                final_state,
                live,
                progress,
                command_line,
            })?;
            let until = until.map_or(Until::End, Until::Time);
            self.advance_locked(py, &mut inner, until)
        })
    }

    /// Advance `n` steps (events, on the event core), or to T. Returns True once T is
    /// reached.
    #[pyo3(signature = (n=1))]
    fn step(&self, py: Python<'_>, n: u64) -> PyResult<bool> {
        guard(|| {
            let mut inner = self.lock()?;
            self.advance_locked(py, &mut inner, Until::Steps(n))
        })
    }

    /// Call `function(batch)` with what the run did, in batches: `kind` is "impacts",
    /// "merges", "fragments" (a dict of NumPy columns per batch) or "sample" (a dict with
    /// `t` and `bodies`); `every` [s] of simulated time or `every_events` messages, and
    /// at T. Before the first step only.
    #[pyo3(signature = (kind, function, every=None, every_events=None))]
    fn add_hook(
        &self,
        kind: &str,
        function: Py<PyAny>,
        every: Option<f64>,
        every_events: Option<usize>,
    ) -> PyResult<()> {
        use crate::hooks::{Every, Hook, Kind};
        guard(|| {
            let kind = match kind {
                "impacts" => Kind::Impacts,
                "merges" => Kind::Merges,
                "fragments" => Kind::Fragments,
                "sample" => Kind::Sample,
                other => {
                    return Err(scenario_error(format!(
                        "hook: kind: no `{other}` (impacts, merges, fragments, sample)"
                    )));
                }
            };
            let name = kind.name();
            let every = match (every, every_events) {
                (Some(dt), None) if dt.is_finite() && dt > 0.0 => Every::Time(dt),
                (Some(dt), None) => {
                    return Err(scenario_error(format!(
                        "{name}: every: a time > 0 [s] (got {dt})"
                    )));
                }
                (None, Some(k)) if k >= 1 && kind != Kind::Sample => Every::Count(k),
                (None, Some(k)) if kind == Kind::Sample => {
                    return Err(scenario_error(format!(
                        "{name}: every_events: samples are taken every Δt: give every= (got {k})"
                    )));
                }
                (None, Some(k)) => {
                    return Err(scenario_error(format!(
                        "{name}: every_events: ≥ 1 (got {k})"
                    )));
                }
                (None, None) => {
                    return Err(scenario_error(format!(
                        "{name}: give every=SECONDS or every_events=K"
                    )));
                }
                (Some(_), Some(_)) => {
                    return Err(scenario_error(format!(
                        "{name}: give every= or every_events=, not both"
                    )));
                }
            };
            let mut inner = self.lock()?;
            if !inner.fresh() {
                return Err(scenario_error(format!(
                    "{name}: hooks are added before the first step"
                )));
            }
            let now = inner.sim()?.clock().time;
            inner.hooks.push(Hook::new(kind, every, function, now));
            inner.rebuild_or_restore(|inner| {
                inner.hooks.pop();
            })
        })
    }

    /// Finalise the outputs now (the recording says the run was stopped at this time).
    /// Nothing happens if the run is already finished.
    fn close(&self) -> PyResult<()> {
        guard(|| {
            let mut inner = self.lock()?;
            let c = inner.sim()?.clock();
            // Closed on request: the caller knows the state is not at the end time.
            inner
                .finish(&Err(SimError::Interrupted {
                    step: c.step,
                    time: c.time,
                }))
                .map(drop)
        })
    }

    /// The run as restart-file bytes (`agglo::restart::encode`), taken as a checkpoint
    /// is (every body brought to now): this run and one made from the bytes continue
    /// alike. What `pickle` keeps.
    fn _restart_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        guard(|| {
            let mut inner = self.lock()?;
            let scenario = inner.scenario.clone();
            let State::Running(run) = &mut inner.state else {
                return Err(AggloError::new_err(
                    "a finished simulation is not pickled: keep its results (bodies(), \
                     summary(), the tables) instead",
                ));
            };
            let snapshot = run.snapshot_now().map_err(|e| agglo_error(e.into()))?;
            Ok(PyBytes::new(
                py,
                &agglo::restart::encode(&scenario, &snapshot),
            ))
        })
    }

    /// A simulation continuing from restart-file bytes (`_restart_bytes`, or a restart
    /// file's content). Its scenario's output files are not written (they are the
    /// original run's); choose outputs with `run()`.
    #[staticmethod]
    #[pyo3(signature = (bytes, carry=Vec::new()))]
    fn _from_restart(
        bytes: &[u8],
        carry: Vec<(String, String, String, Vec<f64>)>,
    ) -> PyResult<Self> {
        guard(|| {
            let (mut scenario, snapshot) =
                agglo::restart::decode(std::path::Path::new("<pickle>"), bytes)
                    .map_err(scenario_error)?;
            scenario.output = scenario.output.without_files();
            Self::built(scenario, Some(snapshot), specs(carry)?)
        })
    }

    /// Simulated time [s].
    #[getter]
    fn t(&self) -> PyResult<f64> {
        match self.inner.try_lock() {
            Ok(inner) => Ok(inner.sim()?.clock().time),
            // Running (read from a hook): the time of the last step taken.
            Err(_) => Ok(self.clock.time()),
        }
    }

    /// Steps taken (events, on the event core).
    #[getter]
    fn steps(&self) -> PyResult<u64> {
        match self.inner.try_lock() {
            Ok(inner) => Ok(inner.sim()?.clock().step),
            Err(_) => Ok(self.clock.step.load(Ordering::Relaxed)),
        }
    }

    /// True once T is reached.
    #[getter]
    fn finished(&self) -> PyResult<bool> {
        Ok(matches!(self.lock()?.state, State::Done(_)))
    }

    /// The scenario being run.
    #[getter]
    fn scenario(&self) -> PyResult<Scenario> {
        Ok(Scenario {
            inner: self.lock()?.scenario.clone(),
        })
    }

    /// The counters (impacts, bonds, bounces, …) as JSON text.
    fn counters_json(&self) -> PyResult<String> {
        let counters = self.lock()?.sim()?.counters();
        serde_json::to_string(&counters).map_err(|e| agglo_error(e.into()))
    }

    /// The summary (what `agglo run --summary` writes) as JSON text: of the run so far,
    /// or of the finished run.
    fn summary_json(&self) -> PyResult<String> {
        guard(|| {
            let inner = self.lock()?;
            let summary = match &inner.state {
                State::Done(done) => done.summary.clone(),
                _ => {
                    let sim = inner.sim()?;
                    agglo::observables::Summary::new(sim, &sim.bodies())
                }
            };
            serde_json::to_string_pretty(&summary).map_err(|e| agglo_error(e.into()))
        })
    }

    /// The pipeline: the core, the systems in order, and why the others are left out.
    fn pipeline_json(&self) -> PyResult<String> {
        let inner = self.lock()?;
        serde_json::to_string(inner.sim()?.pipeline()).map_err(|e| agglo_error(e.into()))
    }

    /// Every body now, id-sorted, as a dict of arrays (the `--final-state` columns).
    fn bodies<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard(|| {
            let inner = self.lock()?;
            let sim = inner.sim()?;
            let (bodies, carried) = py.detach(|| (sim.body_columns(), sim.carried()));
            crate::columns::bodies_columns(py, bodies, &carried)
        })
    }

    /// Seconds the engine takes to read every body (`Simulation::bodies`, no conversion):
    /// the reference of `bodies()`'s cost in python/bench.py.
    fn _time_bodies_read(&self, py: Python<'_>) -> PyResult<f64> {
        let inner = self.lock()?;
        let sim = inner.sim()?;
        Ok(py.detach(|| {
            let start = Instant::now();
            let bodies = sim.bodies();
            let seconds = start.elapsed().as_secs_f64();
            drop(bodies);
            seconds
        }))
    }

    /// A table kept in memory (`run(tables={"series": None})`), once the run is
    /// finished, as a dict of columns.
    fn table<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        guard(|| {
            let inner = self.lock()?;
            let State::Done(done) = &inner.state else {
                return Err(AggloError::new_err(format!(
                    "table `{name}`: the tables kept in memory are read when the run is \
                     finished (run() to T, or close())"
                )));
            };
            let table = done.tables.get(name).cloned().ok_or_else(|| {
                scenario_error(format!(
                    "table `{name}`: not kept in memory by this run (kept: {})",
                    done.tables.keys().cloned().collect::<Vec<_>>().join(", ")
                ))
            })?;
            crate::columns::table_columns(py, table)
        })
    }
}

impl Simulation {
    fn advance_locked(&self, py: Python<'_>, inner: &mut Inner, until: Until) -> PyResult<bool> {
        inner.stepped = true;
        let Inner { state, hooks, .. } = inner;
        let State::Running(run) = state else {
            return Ok(true);
        };
        let c = run.sim().clock();
        self.clock.store(c.time, c.step);
        let (outcome, raised) = advance(py, run, hooks, until, &self.clock);
        if let Some(err) = raised {
            // Ctrl-C (or another signal handler's exception): the run stays valid.
            return Err(err);
        }
        let reached_end = run.is_finished();
        match outcome {
            Ok(()) if reached_end => {
                inner.finish(&Ok(()))?;
                Ok(true)
            }
            Ok(()) => Ok(false),
            Err(e) => {
                let message = e.to_string();
                // A failing output or a failed run: finalise what was written, and say
                // what a file written at the failure holds.
                let notes = inner.finish(&Err(e))?;
                let notes: String = notes.iter().map(|n| format!("; note: {n}")).collect();
                Err(AggloError::new_err(format!(
                    "running the scenario: {message}{notes}"
                )))
            }
        }
    }
}

impl Drop for Simulation {
    /// A simulation dropped before T finalises its outputs, so that its recording and
    /// tables are valid files.
    fn drop(&mut self) {
        let inner = self.inner.get_mut().unwrap_or_else(|p| p.into_inner());
        if let State::Running(run) = &inner.state {
            let c = run.sim().clock();
            let _ = inner.finish(&Err(SimError::Interrupted {
                step: c.step,
                time: c.time,
            }));
        }
    }
}
