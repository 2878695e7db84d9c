//! The readings study (`agglo study readings`): how much each of the model's readings
//! of the papers moves the headline result of a scene.
//!
//! Where P04 and P02 are silent, ambiguous or wrong, the engine takes a decision
//! (docs/model.md, "What the papers leave open or get wrong", and its "Readings"
//! section). Each runnable alternative is a **reading**: a patch to the scenario —
//! a reading option (`impact.pair_hardness`, `impact.friction_cap`, `impact.bond_test`,
//! `impact.separation`), an existing option (`impact.duration`, `impact.solver`,
//! `physics.contact_rule`, `physics.cooling`, …) or a value the papers print in two
//! ways. The study runs the scene as shipped (the **baseline**: the engine's own
//! readings) and every reading over the same seeds, and reports each reading's
//! ensemble mean b_f/b0 with its standard error, its difference from the baseline in
//! units of the combined standard error, and the paper's published value.
//!
//! Seeds are the scenario's own seed and the next ones (seed, seed + 1, …), so the
//! baseline's first run is exactly `agglo run SCENARIO`, bit for bit (tested), and a
//! reading and the baseline see the same initial clouds. Runs are independent and are
//! spread over threads; the results do not depend on the thread count.
//!
//! `--p02-steps S` applies the inverse problem's P02 end-time rule (P02 (13), T from
//! the scenario and S fixed steps, [`crate::inverse::problem::p02_end_time`]) to every
//! run after the reading's patch, so the numbers compare with `agglo scan` and
//! `agglo optimize` on `paper2002_inverse.json`.

use serde_json::{Value, json};

use crate::inverse::problem::p02_end_time;
use crate::observables::P02_TARGET_RATIO;
use crate::prelude::*;
use crate::scenario::{
    ContactRule, CoolingMethod, DurationLaw, ImpactsPerStep, SolverKind, Stepping,
};

use super::{mean_std, num, write_csv};

/// One alternative reading of the papers, as a patch merged over the scenario.
#[derive(Debug, Clone)]
pub struct Reading {
    /// Short key (no commas or spaces), e.g. `pair_hardness_max`.
    pub key: String,
    /// What the reading does, in the scenario's terms (no commas: it goes into a CSV).
    pub what: String,
    /// Where the papers support it.
    pub source: String,
    /// JSON merged over the scenario (objects merge, other values replace).
    pub patch: Value,
}

impl Reading {
    fn new(key: &str, what: &str, source: &str, patch: Value) -> Self {
        Self {
            key: key.into(),
            what: what.into(),
            source: source.into(),
            patch,
        }
    }
}

/// The baseline: the scenario as given, with the engine's own readings.
pub const BASELINE: &str = "baseline";

mod catalogue;
mod cli;
mod report;

pub use crate::scenario::with_settings;
pub use catalogue::catalogue;
pub use cli::{ReadingsArgs, run_cli};
pub use report::{markdown, write_readings};

/// One run of the study as a task of the farm: the scene, patched and capped, as JSON
/// (so that a rank needs neither the catalogue nor the base scenario).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ReadingTask {
    /// The scene, patched and capped, as JSON.
    pub scenario_json: String,
}

/// The worker function of the study (on any thread or rank).
pub fn run_task(task: &ReadingTask) -> Result<RunStats, String> {
    let scenario = Scenario::from_json(&task.scenario_json).map_err(|e| e.to_string())?;
    measure(&scenario)
}

/// Knobs of the study.
#[derive(Debug, Clone)]
pub struct ReadingsOptions {
    /// Seeds per reading: the scenario's seed and the next `seeds − 1`.
    pub seeds: usize,
    /// Apply P02 (13)'s end time with this many fixed steps to every run.
    pub p02_steps: Option<u32>,
    /// Run only these readings (keys; the baseline is always run). Empty: all.
    pub only: Vec<String>,
    /// Instead of the readings one at a time, every combination: one group per entry,
    /// each group a set of mutually exclusive readings of which a combination takes none
    /// or one (e.g. `["solver_plain", "solver_plain_cap_parity"]`).
    pub combine: Vec<Vec<String>>,
    /// The paper's published b_f/b0, drawn on the chart and compared in the table.
    pub target_growth: Option<f64>,
    /// Override `time.max_steps` of every run (bounds runs a reading makes very slow).
    pub max_steps: Option<u64>,
}

impl Default for ReadingsOptions {
    fn default() -> Self {
        Self {
            seeds: 10,
            p02_steps: None,
            only: Vec::new(),
            combine: Vec::new(),
            target_growth: None,
            max_steps: None,
        }
    }
}

/// What one run produced.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunStats {
    /// Number-average b_f / b0 (docs/model.md §11).
    pub growth_ratio: f64,
    /// (N0 / N_final)^(1/3): the radius of the mean-mass body over b0, the reading of
    /// b_f under which n_f = (b_f/b0)³ is P04's "average mass" ratio.
    pub mass_mean_ratio: f64,
    /// Π04 = 1 − b̄_f / b* (P04 (7.1)).
    pub pi04: f64,
    /// n_f = (b_f / b0)³.
    pub n_f: f64,
    /// Bodies at the end.
    pub final_bodies: usize,
    /// Impacts resolved.
    pub impacts: u64,
    /// Impacts that bonded.
    pub bonds: u64,
    /// Impacts that bounced.
    pub bounces: u64,
    /// Impacts that needed the bracketed fallback.
    pub fallbacks: u64,
    /// Impacts whose plain iteration did not converge.
    pub unconverged: u64,
    /// Reaction heat / impact dissipation: how much of the heat any reading of the
    /// impact's energy split (P04 (6.10) against P02 (14)–(17)) could move.
    pub reaction_over_dissipation: f64,
    /// Highest temperature at the end [K].
    pub max_temperature: f64,
    /// Invariant checks that failed.
    pub invariant_violations: usize,
    /// Wall time of the run [s].
    pub wall_seconds: f64,
}

/// One run of one reading.
#[derive(Debug, Clone)]
pub struct Run {
    /// The reading's index in the study's list.
    pub reading: usize,
    /// The run's seed.
    pub seed: u64,
    /// The run's statistics, or why it failed (a scenario the reading makes invalid, or
    /// a run error such as explicit cooling going unstable).
    pub result: Result<RunStats, String>,
}

/// Ensemble statistics of one reading.
#[derive(Debug, Clone, Default)]
pub struct ReadingSummary {
    /// Runs made.
    pub runs: usize,
    /// Runs that failed.
    pub failures: usize,
    /// First failure message (empty when none).
    pub failure: String,
    /// Mean b_f / b0 over the runs that succeeded.
    pub growth_mean: f64,
    /// Its standard deviation over those runs.
    pub growth_std: f64,
    /// Standard error of the mean b_f/b0.
    pub growth_se: f64,
    /// Mean (N0 / N_final)^(1/3).
    pub mass_mean_ratio: f64,
    /// Mean Π04.
    pub pi04: f64,
    /// Π02 of the ensemble-mean radius, |⟨b_f⟩/(2 b0) − 1| (as the inverse problem).
    pub pi02: f64,
    /// Mean n_f.
    pub n_f: f64,
    /// Mean bodies at the end.
    pub final_bodies: f64,
    /// Mean impacts.
    pub impacts: f64,
    /// Mean bonds.
    pub bonds: f64,
    /// Mean unconverged impacts.
    pub unconverged: f64,
    /// Mean reaction heat / impact dissipation.
    pub reaction_over_dissipation: f64,
    /// Mean b_f/b0 minus the baseline's.
    pub delta: f64,
    /// (mean b_f/b0 − published value) / s.e. (NaN without a published value).
    pub z_target: f64,
    /// delta / √(se² + se_baseline²) (0 for the baseline; NaN if both errors are 0 and
    /// delta ≠ 0).
    pub z: f64,
    /// Mean wall time per run [s].
    pub wall_seconds: f64,
}

/// The whole study.
#[derive(Debug, Clone)]
pub struct ReadingsStudy {
    /// The base scene's name.
    pub scenario: String,
    /// The seeds every reading runs with.
    pub seeds: Vec<u64>,
    /// A published b_f / b0 the readings are compared with.
    pub target_growth: Option<f64>,
    /// P02's end-time rule with this many fixed steps, if used.
    pub p02_steps: Option<u32>,
    /// The step cap of each run, if set.
    pub max_steps: Option<u64>,
    /// The readings, the baseline first.
    pub readings: Vec<Reading>,
    /// Every run, reading by reading, seed by seed.
    pub runs: Vec<Run>,
    /// One summary per reading, in `readings`' order.
    pub summaries: Vec<ReadingSummary>,
}

fn merge(base: &mut Value, patch: &Value) {
    match (base, patch) {
        (Value::Object(b), Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k.clone()).or_insert(Value::Null), v);
            }
        }
        (b, p) => *b = p.clone(),
    }
}

/// The scenario of `reading` at `seed`, with the P02 end-time rule when asked for.
pub fn scenario_for(
    base: &Scenario,
    reading: &Reading,
    seed: u64,
    p02_steps: Option<u32>,
) -> Result<Scenario, ScenarioError> {
    scenario_capped(base, reading, seed, p02_steps, None)
}

/// [`scenario_for`] with `time.max_steps` overridden when given.
pub fn scenario_capped(
    base: &Scenario,
    reading: &Reading,
    seed: u64,
    p02_steps: Option<u32>,
    max_steps: Option<u64>,
) -> Result<Scenario, ScenarioError> {
    let mut value = serde_json::to_value(base).expect("a scenario serialises"); // ok: plain data
    merge(&mut value, &reading.patch);
    value["seed"] = Value::from(seed);
    if let Some(n) = max_steps {
        value["time"]["max_steps"] = Value::from(n);
    }
    let mut scenario = Scenario::from_value(value)?;
    if let Some(steps) = p02_steps {
        let end = p02_end_time(&scenario);
        scenario.time.end = end;
        scenario.time.stepping = Stepping::Fixed {
            dt: end / f64::from(steps),
        };
        scenario.validate()?;
    }
    Ok(scenario)
}

/// Run one scenario and measure it.
pub fn measure(scenario: &Scenario) -> Result<RunStats, String> {
    let start = std::time::Instant::now();
    let plan = crate::run::RunPlan::unwritten(scenario.clone());
    let (end, outcome) =
        crate::run::Run::complete(plan, Vec::new()).map_err(|e| crate::run::failure_text(&e))?;
    outcome.map_err(|e| e.to_string())?;
    let s = end.summary;
    // A run that broke an invariant (e.g. explicit cooling driving θ to −∞, docs/model.md
    // §8) has no meaningful growth: it counts as failed, with the first violation.
    if let Some(first) = s.invariant_violations.first() {
        return Err(format!(
            "{} invariant violation(s), first: {first}",
            s.invariant_violations.len()
        ));
    }
    let c = s.counters;
    Ok(RunStats {
        growth_ratio: s.growth.growth_ratio,
        mass_mean_ratio: (s.initial_bodies as f64 / s.final_bodies as f64).cbrt(),
        pi04: s.growth.pi04,
        n_f: s.growth.n_f,
        final_bodies: s.final_bodies,
        impacts: c.impacts,
        bonds: c.bonds,
        bounces: c.bounces,
        fallbacks: c.fallbacks,
        unconverged: c.unconverged,
        reaction_over_dissipation: if s.energy.impact_dissipation != 0.0 {
            s.energy.reaction_heat / s.energy.impact_dissipation
        } else {
            f64::NAN
        },
        max_temperature: s.max_temperature,
        invariant_violations: s.invariant_violations.len(),
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Every combination of the groups' readings (none or one per group), the baseline
/// (nothing taken) first; patches are merged in group order, keys joined by `+`.
pub fn combinations(all: &[Reading], groups: &[Vec<String>]) -> Vec<Reading> {
    let find = |key: &str| all.iter().find(|r| r.key == key).cloned();
    let mut out = vec![all[0].clone()];
    for group in groups {
        let mut next = Vec::new();
        for combo in &out {
            next.push(combo.clone());
            for key in group {
                let Some(r) = find(key) else { continue };
                let mut patch = combo.patch.clone();
                merge(&mut patch, &r.patch);
                let (key, what) = if combo.key == BASELINE {
                    (r.key.clone(), r.what.clone())
                } else {
                    (
                        format!("{}+{}", combo.key, r.key),
                        format!("{}; {}", combo.what, r.what),
                    )
                };
                next.push(Reading {
                    key,
                    what,
                    source: "combination".into(),
                    patch,
                });
            }
        }
        out = next;
    }
    out
}

/// Run the baseline and every selected reading over the seeds.
/// The runs are handed out to `workers` (threads, and MPI ranks with `--features mpi`);
/// the results do not depend on how many.
pub fn run_readings(
    base: &Scenario,
    options: &ReadingsOptions,
    workers: &crate::farm::Workers,
    log: impl Fn(&str),
) -> anyhow::Result<ReadingsStudy> {
    anyhow::ensure!(options.seeds >= 1, "--seeds must be ≥ 1");
    let all = catalogue(base);
    for key in options.only.iter().chain(options.combine.iter().flatten()) {
        anyhow::ensure!(
            all.iter().any(|r| &r.key == key),
            "unknown reading `{key}` for this scene; available: {}",
            all.iter()
                .map(|r| r.key.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let readings: Vec<Reading> = if options.combine.is_empty() {
        all.into_iter()
            .filter(|r| {
                r.key == BASELINE || options.only.is_empty() || options.only.contains(&r.key)
            })
            .collect()
    } else {
        combinations(&all, &options.combine)
    };
    // Before listing them: a scene per run (readings × seeds), and the scenes the
    // workers run at once (`--seeds 4294967295` would list 34 GB of seeds alone).
    let runs = readings.len().saturating_mul(options.seeds);
    let per_run = crate::memory::scenario_bytes(base) + std::mem::size_of::<RunStats>() as f64;
    crate::memory::fits("runs (readings × --seeds)", runs, runs as f64 * per_run)
        .map_err(anyhow::Error::msg)?;
    if let Some(warning) = crate::memory::MemoryEstimate::of_runs(base, runs, workers.threads)
        .check()
        .map_err(anyhow::Error::msg)?
    {
        log(&warning);
    }
    let seeds: Vec<u64> = (0..options.seeds as u64)
        .map(|k| base.seed.wrapping_add(k))
        .collect();
    let jobs: Vec<(usize, u64)> = (0..readings.len())
        .flat_map(|r| seeds.iter().map(move |&s| (r, s)))
        .collect();
    // Scenes are built here; a reading whose scene is invalid fails without a run.
    let scenes: Vec<Result<Scenario, String>> = jobs
        .iter()
        .map(|&(r, seed)| {
            scenario_capped(
                base,
                &readings[r],
                seed,
                options.p02_steps,
                options.max_steps,
            )
            .map_err(|e| e.to_string())
        })
        .collect();
    let (runnable, tasks): (Vec<usize>, Vec<ReadingTask>) = scenes
        .iter()
        .enumerate()
        .filter_map(|(k, s)| {
            s.as_ref().ok().map(|s| {
                (
                    k,
                    ReadingTask {
                        scenario_json: s.to_json(),
                    },
                )
            })
        })
        .unzip();
    let report = |k: usize, result: &Result<RunStats, String>| {
        let (r, seed) = jobs[k];
        match result {
            Ok(m) => log(&format!(
                "{} seed {seed}: b_f/b0 = {:.4} ({:.2} s)",
                readings[r].key, m.growth_ratio, m.wall_seconds
            )),
            Err(e) => log(&format!("{} seed {seed}: failed: {e}", readings[r].key)),
        }
    };
    let measured = crate::farm::map_with_progress(workers, tasks, &run_task, |i, result| {
        report(runnable[i], result)
    })?;
    let mut measured = runnable.into_iter().zip(measured).peekable();
    let runs: Vec<Run> = jobs
        .iter()
        .zip(scenes)
        .enumerate()
        .map(|(k, (&(r, seed), scene))| {
            let result = match scene {
                Err(e) => {
                    report(k, &Err(e.clone()));
                    Err(e)
                }
                Ok(_) => match measured.next_if(|(j, _)| *j == k) {
                    Some((_, m)) => m,
                    None => Err("the run returned nothing".into()),
                },
            };
            Run {
                reading: r,
                seed,
                result,
            }
        })
        .collect();
    let mut summaries: Vec<ReadingSummary> = (0..readings.len())
        .map(|r| summarise(runs.iter().filter(|run| run.reading == r)))
        .collect();
    for s in summaries.iter_mut() {
        s.z_target = match options.target_growth {
            Some(t) if s.growth_mean != t => (s.growth_mean - t) / s.growth_se,
            Some(_) => 0.0,
            None => f64::NAN,
        };
    }
    let (m0, se0) = (summaries[0].growth_mean, summaries[0].growth_se);
    for s in summaries.iter_mut().skip(1) {
        s.delta = s.growth_mean - m0;
        let se = (s.growth_se.powi(2) + se0.powi(2)).sqrt();
        s.z = if s.delta == 0.0 { 0.0 } else { s.delta / se };
    }
    Ok(ReadingsStudy {
        scenario: base.name.clone(),
        seeds,
        target_growth: options.target_growth,
        p02_steps: options.p02_steps,
        max_steps: options.max_steps,
        readings,
        runs,
        summaries,
    })
}

fn summarise<'a>(runs: impl Iterator<Item = &'a Run>) -> ReadingSummary {
    let mut ok = Vec::new();
    let mut out = ReadingSummary::default();
    for run in runs {
        out.runs += 1;
        match &run.result {
            Ok(m) => ok.push(m),
            Err(e) => {
                out.failures += 1;
                if out.failure.is_empty() {
                    out.failure = e.clone();
                }
            }
        }
    }
    if ok.is_empty() {
        out.growth_mean = f64::NAN;
        return out;
    }
    let mean =
        |f: &dyn Fn(&RunStats) -> f64| ok.iter().map(|m| f(m)).sum::<f64>() / ok.len() as f64;
    let growth: Vec<f64> = ok.iter().map(|m| m.growth_ratio).collect();
    let (gm, gs) = mean_std(&growth);
    out.growth_mean = gm;
    out.growth_std = gs;
    out.growth_se = gs / (ok.len() as f64).sqrt();
    out.mass_mean_ratio = mean(&|m| m.mass_mean_ratio);
    out.pi04 = mean(&|m| m.pi04);
    out.pi02 = (gm / P02_TARGET_RATIO - 1.0).abs();
    out.n_f = mean(&|m| m.n_f);
    out.final_bodies = mean(&|m| m.final_bodies as f64);
    out.impacts = mean(&|m| m.impacts as f64);
    out.bonds = mean(&|m| m.bonds as f64);
    out.unconverged = mean(&|m| m.unconverged as f64);
    out.reaction_over_dissipation = mean(&|m| m.reaction_over_dissipation);
    out.wall_seconds = mean(&|m| m.wall_seconds);
    out
}
