//! The speed/accuracy ladder (`agglo study accuracy`).
//!
//! One scene, one seed, run under a ladder of numerical settings; each run is timed
//! (median wall time of a few repeats; the runs are deterministic, so only the time
//! varies) and compared with a resolved **reference**: adaptive steps with step
//! factor c = 1 (no contact missed, docs/model.md §4), Δt_min = 1e-12 s so that no step
//! is clamped by the papers' lower bound, and a tight fixed-point tolerance.
//!
//! Families (see [`Family`]): the adaptive step factor c, a geometric fixed-Δt ladder
//! (contacts found only as overlaps at step ends), the fixed-point tolerance, the
//! cooling integrator, and the papers' choices (nearest-neighbour contact rule, the
//! P04 Δt bounds, coarse fixed steps, the plain iteration at P04's TOL = 5e-4).
//!
//! Errors against the reference: b_f/b0, final body count N, the Kolmogorov–Smirnov
//! distance between the final radius distributions, total impacts and final mean
//! temperature (all relative except KS), plus each run's own invariant errors. One
//! seed is one realisation of a chaotic many-body system: any perturbation (a looser
//! tolerance, a different step) leads to another realisation, so errors saturate at
//! the seed-to-seed spread. The reference is therefore also run over a few seeds;
//! the mean error of those realisations against the reference seed is the **noise
//! level**: an error below it reads as "within noise".
//!
//! The runs are independent tasks of the farm (`crate::farm`): one thread by
//! default, so that the timings do not share cores; with `--features mpi` each rank
//! times its own runs (put one rank per node, or read the times with that in mind).

use std::path::Path;

use crate::farm::Workers;
use crate::prelude::*;
use crate::scenario::{ContactRule, CoolingMethod, Core, SolverKind, Stepping};

use super::{ks_distance, mean_std, median, num, relative_error, write_csv};

/// Fixed-point tolerance of the reference run.
pub const REFERENCE_TOL: f64 = 1e-14;
/// Δt_min of the reference run [s]: far below any step the scene needs, so never binding
/// except to process a deferred contact (t_c = 0).
pub const REFERENCE_DT_MIN: f64 = 1e-12;
/// P04's fixed-point tolerance (docs/model.md §13).
pub const P04_TOL: f64 = 5e-4;
/// Most steps a fixed-Δt rung may take (keeps the fine end of the ladder affordable).
pub const MAX_FIXED_STEPS: f64 = 400_000.0;

/// A family of numerical settings (one chart series).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// The reference: the finest settings the study affords.
    Reference,
    /// Adaptive step, step factor c.
    Adaptive,
    /// Fixed Δt.
    FixedDt,
    /// Fixed-point tolerance TOL.
    Tolerance,
    /// Cooling integrator.
    Cooling,
    /// The papers' numerical choices.
    Papers,
}

impl Family {
    /// Every family, in chart order.
    pub const ALL: [Family; 6] = [
        Family::Reference,
        Family::Adaptive,
        Family::FixedDt,
        Family::Tolerance,
        Family::Cooling,
        Family::Papers,
    ];

    /// The family's name in `accuracy.csv`.
    pub fn name(self) -> &'static str {
        match self {
            Family::Reference => "reference",
            Family::Adaptive => "adaptive_c",
            Family::FixedDt => "fixed_dt",
            Family::Tolerance => "tolerance",
            Family::Cooling => "cooling",
            Family::Papers => "papers",
        }
    }
}

/// One rung of the ladder.
#[derive(Debug, Clone)]
pub struct Variant {
    /// Its family.
    pub family: Family,
    /// Human-readable setting, e.g. "c = 10" (no commas: it goes into a CSV).
    pub label: String,
    /// The family's numeric parameter (c, Δt [s], TOL; 0 where none).
    pub parameter: f64,
    /// The scene with this setting.
    pub scenario: Scenario,
}

/// Knobs of the study.
#[derive(Debug, Clone)]
pub struct AccuracyOptions {
    /// Timed repeats per setting (median wall time reported).
    pub repeats: usize,
    /// Seeds of the reference ensemble (the scenario's own seed included).
    pub seeds: usize,
    /// Rungs of the fixed-Δt ladder.
    pub fixed_levels: usize,
    /// A published b_f/b0 to mark on the growth chart (e.g. P04's 3.23).
    pub target_growth: Option<f64>,
}

impl Default for AccuracyOptions {
    fn default() -> Self {
        Self {
            repeats: 3,
            seeds: 5,
            fixed_levels: 10,
            target_growth: None,
        }
    }
}

/// What one setting produced.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Measurement {
    /// Median wall time of the repeats [s].
    pub wall_seconds: f64,
    /// Shortest wall time of the repeats [s].
    pub wall_min: f64,
    /// Longest wall time of the repeats [s].
    pub wall_max: f64,
    /// Steps taken.
    pub steps: u64,
    /// b_f / b0 at the end.
    pub growth_ratio: f64,
    /// Bodies at the end.
    pub final_bodies: usize,
    /// Impacts resolved.
    pub impacts: u64,
    /// Mean temperature at the end [K].
    pub mean_temperature: f64,
    /// Final radii over b0.
    pub radii: Vec<f64>,
    /// Worst relative mass error.
    pub max_mass_error: f64,
    /// Worst relative momentum error.
    pub max_momentum_error: f64,
    /// Worst relative energy-ledger error.
    pub max_energy_error: f64,
    /// Impacts that needed the bracketed fallback.
    pub fallbacks: u64,
    /// Impacts whose plain iteration did not converge.
    pub unconverged: u64,
    /// Overlaps left after a step.
    pub overlap_violations: u64,
    /// Steps clamped at Δt_min.
    pub clamped_steps: u64,
    /// Invariant checks that failed (e.g. θ ≤ 0 under explicit cooling).
    pub invariant_violations: u64,
    /// Why the run stopped early, if it did (then the observables are those reached).
    pub failure: Option<String>,
}

/// Errors of a measurement against the reference.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Errors {
    /// Relative error of b_f / b0.
    pub growth: f64,
    /// Relative error of the final body count.
    pub count: f64,
    /// Kolmogorov–Smirnov distance of the final radii.
    pub ks: f64,
    /// Relative error of the impact count.
    pub impacts: f64,
    /// Relative error of the mean temperature.
    pub temperature: f64,
}

impl Errors {
    /// The errors of `m` against `reference`.
    pub fn between(m: &Measurement, reference: &Measurement) -> Self {
        Self {
            growth: relative_error(m.growth_ratio, reference.growth_ratio),
            count: relative_error(m.final_bodies as f64, reference.final_bodies as f64),
            ks: ks_distance(&m.radii, &reference.radii),
            impacts: relative_error(m.impacts as f64, reference.impacts as f64),
            temperature: relative_error(m.mean_temperature, reference.mean_temperature),
        }
    }
}

/// One row of `accuracy.csv`.
#[derive(Debug, Clone)]
pub struct Row {
    /// The setting's family.
    pub family: Family,
    /// The setting, e.g. "c = 10".
    pub label: String,
    /// The family's numeric parameter (c, Δt [s], TOL; 0 where none).
    pub parameter: f64,
    /// What the setting produced.
    pub measurement: Measurement,
    /// Its errors against the reference.
    pub errors: Errors,
    /// b_f/b0 over the study's seeds, for a setting whose single run says little: one
    /// that left impacts unconverged (the papers' plain iteration), whose outcome turns on
    /// which iterate the cap lands on. `None` for the other rows (their spread is the
    /// reference's noise band).
    pub ensemble: Option<Ensemble>,
}

impl Row {
    /// True when the run stopped early.
    pub fn failed(&self) -> bool {
        self.measurement.failure.is_some()
    }
}

/// b_f/b0 of one setting over several seeds (the scenario's own seed first).
#[derive(Debug, Clone, PartialEq)]
pub struct Ensemble {
    /// Seeds run.
    pub seeds: usize,
    /// Seeds whose run failed (left out of the mean).
    pub failed: usize,
    /// Mean b_f/b0 over the runs that did not fail.
    pub growth_mean: f64,
    /// Standard error of that mean (sample standard deviation / √runs; NaN below 2 runs).
    pub growth_se: f64,
}

impl Ensemble {
    fn of(measurements: &[Measurement]) -> Self {
        let growths: Vec<f64> = measurements
            .iter()
            .filter(|m| m.failure.is_none())
            .map(|m| m.growth_ratio)
            .collect();
        let n = growths.len();
        let mean = growths.iter().sum::<f64>() / n as f64;
        let se = if n >= 2 {
            let var = growths.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            (var / n as f64).sqrt()
        } else {
            f64::NAN
        };
        Self {
            seeds: measurements.len(),
            failed: measurements.len() - n,
            growth_mean: if n > 0 { mean } else { f64::NAN },
            growth_se: se,
        }
    }
}

/// The reference over several seeds.
#[derive(Debug, Clone, Default)]
pub struct NoiseBand {
    /// The seeds, the scenario's own first.
    pub seeds: Vec<u64>,
    /// The reference's measurement with each seed.
    pub measurements: Vec<Measurement>,
    /// Each other seed's errors against the reference seed.
    pub errors: Vec<Errors>,
    /// Mean of `errors` per observable: the noise level.
    pub level: Errors,
    /// Mean of b_f/b0 over all seeds.
    pub growth_mean: f64,
    /// Standard deviation of b_f / b0 over the seeds.
    pub growth_std: f64,
}

/// The study's results.
#[derive(Debug, Clone)]
pub struct AccuracyStudy {
    /// The scene's name.
    pub scenario: String,
    /// One row per setting, the reference first.
    pub rows: Vec<Row>,
    /// The reference's spread over seeds.
    pub noise: NoiseBand,
    /// A published b_f / b0 marked on the growth chart.
    pub target_growth: Option<f64>,
}

impl AccuracyStudy {
    /// The reference row (the first).
    pub fn reference(&self) -> &Row {
        &self.rows[0]
    }
}

/// The resolved reference setting of `base`.
pub fn reference_scenario(base: &Scenario) -> Scenario {
    let mut s = base.clone();
    let (dt_max, skin) = match base.time.stepping {
        Stepping::Adaptive { dt_max, skin, .. } => (dt_max, skin),
        Stepping::Fixed { .. } => (1e-3, 1.0),
    };
    s.time.stepping = Stepping::Adaptive {
        step_factor: 1.0,
        dt_min: REFERENCE_DT_MIN,
        dt_max,
        skin,
    };
    s.impact.tol = REFERENCE_TOL;
    s.impact.solver = SolverKind::Safeguarded;
    s.physics.contact_rule = ContactRule::All;
    if s.physics.cooling == CoolingMethod::Explicit {
        s.physics.cooling = CoolingMethod::Implicit;
    }
    // The study measures the numerics; output files and recordings are not wanted.
    s.output = Default::default();
    s
}

fn with_step_factor(reference: &Scenario, c: f64) -> Scenario {
    let mut s = reference.clone();
    if let Stepping::Adaptive { step_factor, .. } = &mut s.time.stepping {
        *step_factor = c;
    }
    s
}

fn with_fixed_dt(reference: &Scenario, dt: f64) -> Scenario {
    let mut s = reference.clone();
    s.time.stepping = Stepping::Fixed { dt };
    s
}

/// Geometric fixed-Δt ladder from fine to coarse: from T / (8 × the reference's steps)
/// (capped at [`MAX_FIXED_STEPS`] steps) to T / 10.
pub fn fixed_ladder(end: f64, reference_steps: u64, levels: usize) -> Vec<f64> {
    let coarse = end / 10.0;
    let fine = (end / (8.0 * reference_steps.max(1) as f64))
        .max(end / MAX_FIXED_STEPS)
        .min(coarse);
    if levels <= 1 {
        return vec![coarse];
    }
    let ratio = (coarse / fine).powf(1.0 / (levels - 1) as f64);
    (0..levels).map(|k| fine * ratio.powi(k as i32)).collect()
}

/// The ladder for `base`, given the reference's step count (which sets the fixed-Δt range).
pub fn ladder(base: &Scenario, reference_steps: u64, options: &AccuracyOptions) -> Vec<Variant> {
    let reference = reference_scenario(base);
    let end = reference.time.end;
    let mut v = Vec::new();
    let mut push = |family, label: String, parameter, scenario| {
        v.push(Variant {
            family,
            label,
            parameter,
            scenario,
        })
    };
    // The same resolved setting on the stepped core (every stage visits every body, skin
    // bound on the step, implicit cooling): what the event core replaced.
    let mut stepped = reference.clone();
    stepped.time.core = Core::Stepped;
    push(Family::Adaptive, "stepped core c = 1".into(), 1.0, stepped);
    for c in [2.0, 5.0, 10.0, 30.0, 100.0] {
        push(
            Family::Adaptive,
            format!("c = {c}"),
            c,
            with_step_factor(&reference, c),
        );
    }
    let dts = fixed_ladder(end, reference_steps, options.fixed_levels);
    for &dt in &dts {
        push(
            Family::FixedDt,
            format!("dt = {dt:.3e} s"),
            dt,
            with_fixed_dt(&reference, dt),
        );
    }
    for tol in [1e-1, 1e-2, P04_TOL, 1e-6, 1e-9, 1e-12] {
        let mut s = reference.clone();
        s.impact.tol = tol;
        push(Family::Tolerance, format!("TOL = {tol:e}"), tol, s);
    }
    // The cooling integrators at the reference step and at a coarse fixed step.
    let coarse_dt = dts[dts.len() * 2 / 3];
    for (method, name) in [
        (CoolingMethod::Explicit, "explicit"),
        (CoolingMethod::Implicit, "implicit"),
        (CoolingMethod::Exact, "exact"),
    ] {
        // The reference (event core) already cools exactly; implicit at c = 1 is the
        // stepped-core row above.
        if method == CoolingMethod::Explicit {
            let mut s = reference.clone();
            s.physics.cooling = method;
            push(Family::Cooling, format!("{name} adaptive c = 1"), 0.0, s);
        }
        let mut s = with_fixed_dt(&reference, coarse_dt);
        s.physics.cooling = method;
        push(
            Family::Cooling,
            format!("{name} dt = {coarse_dt:.3e} s"),
            coarse_dt,
            s,
        );
    }
    // The papers' choices, alone and together.
    let nn = |mut s: Scenario| {
        s.physics.contact_rule = ContactRule::NearestNeighbour;
        s
    };
    let p04_bounds = |mut s: Scenario| {
        if let Stepping::Adaptive { dt_min, dt_max, .. } = &mut s.time.stepping {
            *dt_min = 1e-8;
            *dt_max = 1e-3;
        }
        s
    };
    let plain = |mut s: Scenario| {
        s.impact.solver = SolverKind::Plain;
        s.impact.tol = P04_TOL;
        s
    };
    push(
        Family::Papers,
        "P04 dt bounds [1e-8 1e-3] s c = 1".into(),
        1.0,
        p04_bounds(reference.clone()),
    );
    push(
        Family::Papers,
        "plain iteration TOL = 5e-4".into(),
        0.0,
        plain(reference.clone()),
    );
    for c in [1.0, 10.0] {
        push(
            Family::Papers,
            format!("nearest-neighbour c = {c}"),
            c,
            nn(p04_bounds(with_step_factor(&reference, c))),
        );
    }
    let n = dts.len();
    for &dt in &dts[n / 2..] {
        push(
            Family::Papers,
            format!("nearest-neighbour dt = {dt:.3e} s"),
            dt,
            nn(with_fixed_dt(&reference, dt)),
        );
    }
    // With a0 = 0 the plain iteration 2-cycles 0 ↔ 1 − λ below the critical speed
    // (docs/model.md §5): the last iterate, hence bond or bounce, is set by the parity of
    // the iteration cap. An odd cap shows the other branch.
    let mut odd = plain(reference.clone());
    odd.impact.max_iterations = 101;
    push(
        Family::Papers,
        "plain iteration TOL = 5e-4 odd cap 101".into(),
        0.0,
        odd,
    );
    push(
        Family::Papers,
        "plain + nearest-neighbour c = 1".into(),
        1.0,
        plain(nn(p04_bounds(reference.clone()))),
    );
    for &dt in &dts[n / 2..] {
        push(
            Family::Papers,
            format!("plain + nearest-neighbour dt = {dt:.3e} s"),
            dt,
            plain(nn(with_fixed_dt(&reference, dt))),
        );
    }
    let dt = dts[n * 2 / 3];
    let mut all = plain(nn(with_fixed_dt(&reference, dt)));
    all.physics.cooling = CoolingMethod::Explicit;
    push(
        Family::Papers,
        format!("all papers' choices dt = {dt:.3e} s"),
        dt,
        all,
    );
    v
}

/// Run `scenario` `repeats` times (≥ 1); observables from the first run, the median time.
pub fn measure(scenario: &Scenario, repeats: usize) -> anyhow::Result<Measurement> {
    let mut walls = Vec::new();
    let mut first: Option<Measurement> = None;
    for _ in 0..repeats.max(1) {
        let plan = crate::run::RunPlan::unwritten(scenario.clone());
        let (end, outcome) = crate::run::Run::complete(plan, Vec::new())?;
        let sim = end.sim;
        walls.push(sim.wall_seconds());
        if first.is_none() {
            let s = end.summary;
            let b0 = sim.primary().radius;
            let bodies = sim.bodies();
            first = Some(Measurement {
                steps: s.steps,
                growth_ratio: s.growth.growth_ratio,
                final_bodies: s.final_bodies,
                impacts: s.counters.impacts,
                mean_temperature: s.mean_temperature,
                radii: bodies.iter().map(|b| b.radius / b0).collect(),
                max_mass_error: s.max_mass_error,
                max_momentum_error: s.max_momentum_error,
                max_energy_error: s.max_energy_error,
                fallbacks: s.counters.fallbacks,
                unconverged: s.counters.unconverged,
                overlap_violations: s.counters.overlap_violations,
                clamped_steps: s.counters.clamped_steps,
                invariant_violations: s.counters.invariant_violations,
                failure: outcome.err().map(|e| e.to_string()),
                ..Default::default()
            });
            if let Some(m) = first.as_mut() {
                m.failure = m.failure.take().or_else(|| silent_failure(m));
            }
        }
        // A failed run is not worth timing again.
        if first.as_ref().is_some_and(|m| m.failure.is_some()) {
            break;
        }
    }
    let mut m = first.unwrap_or_default();
    m.wall_seconds = median(&walls);
    m.wall_min = walls.iter().copied().fold(f64::INFINITY, f64::min);
    m.wall_max = walls.iter().copied().fold(0.0, f64::max);
    Ok(m)
}

/// Why a run that ended without an error is still no result: failed invariant checks
/// or a non-finite observable (a NaN mean temperature once let runs that had blown up be
/// charted as results). `None` for a sound run.
fn silent_failure(m: &Measurement) -> Option<String> {
    if m.invariant_violations > 0 {
        Some(format!(
            "{} invariant violations (docs/model.md §12)",
            m.invariant_violations
        ))
    } else if !m.growth_ratio.is_finite() || !m.mean_temperature.is_finite() {
        Some(format!(
            "non-finite observables at the end: b_f/b0 = {}, mean temperature = {}",
            m.growth_ratio, m.mean_temperature
        ))
    } else {
        None
    }
}

/// One run of the study, as a task of the farm: the scene as JSON (postcard cannot
/// carry the scenario's optional fields) and its timed repeats.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct MeasureTask {
    /// The scene, as JSON.
    pub scenario_json: String,
    /// Timed repeats (≥ 1).
    pub repeats: usize,
}

impl MeasureTask {
    fn of(scenario: &Scenario, repeats: usize) -> Self {
        Self {
            scenario_json: scenario.to_json(),
            repeats,
        }
    }
}

/// The worker function of the study (on any thread or rank).
pub fn measure_task(task: &MeasureTask) -> Result<Measurement, String> {
    let scenario = Scenario::from_json(&task.scenario_json).map_err(|e| e.to_string())?;
    measure(&scenario, task.repeats).map_err(|e| format!("{e:#}"))
}

fn measure_all(workers: &Workers, tasks: Vec<MeasureTask>) -> anyhow::Result<Vec<Measurement>> {
    crate::farm::map(workers, tasks, &measure_task)?
        .into_iter()
        .map(|r| r.map_err(|e| anyhow::anyhow!(e)))
        .collect()
}

/// Run the whole study on `base`; `progress` receives one line per finished run.
/// The runs are handed out to `workers` (the reference first, then every other run);
/// give it one thread unless the timings may share the cores.
pub fn run_accuracy(
    base: &Scenario,
    options: &AccuracyOptions,
    workers: &Workers,
    mut progress: impl FnMut(&str),
) -> anyhow::Result<AccuracyStudy> {
    let reference_s = reference_scenario(base);
    // Each seed of the noise band is a task holding its scene as JSON: refused before
    // any run when they cannot fit (`--seeds 4294967295`).
    let task_bytes = MeasureTask::of(&reference_s, 1).scenario_json.len() as f64 + 1024.0;
    crate::memory::fits("seeds", options.seeds, options.seeds as f64 * task_bytes)
        .map_err(anyhow::Error::msg)?;
    let reference = measure_all(
        workers,
        vec![MeasureTask::of(&reference_s, options.repeats)],
    )?
    .pop()
    .ok_or_else(|| anyhow::anyhow!("the reference run returned nothing"))?;
    if let Some(f) = &reference.failure {
        anyhow::bail!("the reference run failed: {f}");
    }
    progress(&format!(
        "reference: {} steps, b_f/b0 = {:.4}, N = {}, {:.3} s",
        reference.steps, reference.growth_ratio, reference.final_bodies, reference.wall_seconds
    ));

    // Everything else at once: the noise band (the reference over other seeds) and the ladder.
    let noise_seeds: Vec<u64> = (1..options.seeds.max(1))
        .map(|k| base.seed.wrapping_add(k as u64))
        .collect();
    let variants = ladder(base, reference.steps, options);
    let mut tasks: Vec<MeasureTask> = noise_seeds
        .iter()
        .map(|&seed| {
            let mut s = reference_s.clone();
            s.seed = seed;
            MeasureTask::of(&s, 1)
        })
        .collect();
    tasks.extend(
        variants
            .iter()
            .map(|v| MeasureTask::of(&v.scenario, options.repeats)),
    );
    let mut measured = measure_all(workers, tasks)?.into_iter();

    let mut noise = NoiseBand {
        seeds: vec![base.seed],
        measurements: vec![reference.clone()],
        ..Default::default()
    };
    for (&seed, m) in noise_seeds.iter().zip(measured.by_ref()) {
        let e = Errors::between(&m, &reference);
        progress(&format!(
            "reference seed {seed}: b_f/b0 = {:.4}, N = {}",
            m.growth_ratio, m.final_bodies
        ));
        noise.seeds.push(seed);
        noise.errors.push(e);
        noise.measurements.push(m);
    }
    let avg = |f: fn(&Errors) -> f64| {
        if noise.errors.is_empty() {
            0.0
        } else {
            noise.errors.iter().map(f).sum::<f64>() / noise.errors.len() as f64
        }
    };
    noise.level = Errors {
        growth: avg(|e| e.growth),
        count: avg(|e| e.count),
        ks: avg(|e| e.ks),
        impacts: avg(|e| e.impacts),
        temperature: avg(|e| e.temperature),
    };
    let growths: Vec<f64> = noise.measurements.iter().map(|m| m.growth_ratio).collect();
    (noise.growth_mean, noise.growth_std) = mean_std(&growths);

    let mut rows = vec![Row {
        family: Family::Reference,
        label: "reference".into(),
        parameter: 1.0,
        errors: Errors::between(&reference, &reference),
        measurement: reference.clone(),
        ensemble: None,
    }];
    let measured: Vec<Measurement> = measured.collect();
    // A setting that left impacts unconverged is run over the noise band's seeds too: its
    // single seed is one draw of a method whose bond-or-bounce turns on the iteration cap.
    let unconverged: Vec<usize> = measured
        .iter()
        .enumerate()
        .filter(|(_, m)| m.failure.is_none() && m.unconverged > 0)
        .map(|(k, _)| k)
        .collect();
    let mut ensemble_tasks = Vec::new();
    for &k in &unconverged {
        for &seed in &noise_seeds {
            let mut s = variants[k].scenario.clone();
            s.seed = seed;
            ensemble_tasks.push(MeasureTask::of(&s, 1));
        }
    }
    let mut ensemble_runs = measure_all(workers, ensemble_tasks)?.into_iter();
    let mut ensembles: Vec<Option<Ensemble>> = vec![None; measured.len()];
    for &k in &unconverged {
        let mut runs = vec![measured[k].clone()];
        runs.extend(ensemble_runs.by_ref().take(noise_seeds.len()));
        ensembles[k] = Some(Ensemble::of(&runs));
    }
    for ((variant, m), ensemble) in variants.into_iter().zip(measured).zip(ensembles) {
        let errors = Errors::between(&m, &reference);
        progress(&format!(
            "{} {}: {} steps, b_f/b0 = {:.4}, error {:.2e}, {:.3} s{}",
            variant.family.name(),
            variant.label,
            m.steps,
            m.growth_ratio,
            errors.growth,
            m.wall_seconds,
            m.failure
                .as_deref()
                .map(|f| format!(" FAILED: {f}"))
                .unwrap_or_default()
        ));
        rows.push(Row {
            family: variant.family,
            label: variant.label,
            parameter: variant.parameter,
            measurement: m,
            errors,
            ensemble,
        });
    }
    Ok(AccuracyStudy {
        scenario: base.name.clone(),
        rows,
        noise,
        target_growth: options.target_growth,
    })
}

/// Header of `accuracy.csv`.
pub const ACCURACY_HEADER: [&str; 33] = [
    "family",
    "label",
    "parameter",
    "status",
    "failure",
    "wall_seconds",
    "wall_min",
    "wall_max",
    "steps",
    "growth_ratio",
    "final_bodies",
    "impacts",
    "mean_temperature",
    "growth_error",
    "count_error",
    "ks_distance",
    "impacts_error",
    "temperature_error",
    "within_noise",
    "max_mass_error",
    "max_momentum_error",
    "max_energy_error",
    "fallbacks",
    "unconverged",
    "overlap_violations",
    "clamped_steps",
    "invariant_violations",
    "noise_growth_error",
    "noise_ks",
    "ensemble_seeds",
    "ensemble_failed",
    "ensemble_growth_mean",
    "ensemble_growth_se",
];

/// Write `accuracy.csv` and `noise.csv` into `dir` (the charts: [`super::write::write_accuracy`]).
pub fn write_accuracy_tables(dir: &Path, study: &AccuracyStudy) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let level = study.noise.level;
    let rows: Vec<Vec<String>> = study
        .rows
        .iter()
        .map(|r| {
            let m = &r.measurement;
            let e = &r.errors;
            let within = !r.failed() && e.growth <= level.growth && e.ks <= level.ks;
            vec![
                r.family.name().into(),
                r.label.clone(),
                num(r.parameter),
                if r.failed() { "failed" } else { "ok" }.into(),
                // A CSV field: the message's commas become semicolons.
                m.failure.as_deref().unwrap_or("").replace(',', ";"),
                num(m.wall_seconds),
                num(m.wall_min),
                num(m.wall_max),
                m.steps.to_string(),
                num(m.growth_ratio),
                m.final_bodies.to_string(),
                m.impacts.to_string(),
                num(m.mean_temperature),
                num(e.growth),
                num(e.count),
                num(e.ks),
                num(e.impacts),
                num(e.temperature),
                within.to_string(),
                num(m.max_mass_error),
                num(m.max_momentum_error),
                num(m.max_energy_error),
                m.fallbacks.to_string(),
                m.unconverged.to_string(),
                m.overlap_violations.to_string(),
                m.clamped_steps.to_string(),
                m.invariant_violations.to_string(),
                num(level.growth),
                num(level.ks),
                r.ensemble.as_ref().map_or(1, |e| e.seeds).to_string(),
                r.ensemble.as_ref().map_or(0, |e| e.failed).to_string(),
                num(r
                    .ensemble
                    .as_ref()
                    .map_or(m.growth_ratio, |e| e.growth_mean)),
                num(r.ensemble.as_ref().map_or(f64::NAN, |e| e.growth_se)),
            ]
        })
        .collect();
    write_csv(&dir.join("accuracy.csv"), &ACCURACY_HEADER, &rows)?;

    let noise_rows: Vec<Vec<String>> = study
        .noise
        .seeds
        .iter()
        .zip(&study.noise.measurements)
        .enumerate()
        .map(|(k, (seed, m))| {
            let e = if k == 0 {
                Errors::default()
            } else {
                study.noise.errors[k - 1]
            };
            vec![
                seed.to_string(),
                num(m.wall_seconds),
                m.steps.to_string(),
                num(m.growth_ratio),
                m.final_bodies.to_string(),
                m.impacts.to_string(),
                num(m.mean_temperature),
                num(e.growth),
                num(e.count),
                num(e.ks),
                num(e.impacts),
                num(e.temperature),
            ]
        })
        .collect();
    write_csv(
        &dir.join("noise.csv"),
        &[
            "seed",
            "wall_seconds",
            "steps",
            "growth_ratio",
            "final_bodies",
            "impacts",
            "mean_temperature",
            "growth_error",
            "count_error",
            "ks_distance",
            "impacts_error",
            "temperature_error",
        ],
        &noise_rows,
    )?;
    Ok(())
}
