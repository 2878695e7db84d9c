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

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::{Value, json};

use crate::charts::{FONT, Figure, save_png_and_svg};
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

/// The runnable readings that differ from `base` (docs/model.md, "Readings"). A reading
/// that would leave `base` unchanged (e.g. the P02 duration law on a P02 scene) is
/// replaced by its counterpart or left out.
pub fn catalogue(base: &Scenario) -> Vec<Reading> {
    let i = &base.impact;
    let mut out = vec![Reading::new(
        BASELINE,
        "the scenario as given (engine readings)",
        "docs/model.md",
        json!({}),
    )];
    for (rule, what) in [
        ("harmonic", "harmonic mean of H_i and H_j"),
        ("arithmetic", "arithmetic mean of H_i and H_j"),
        ("max", "larger of H_i and H_j (both surfaces must yield)"),
    ] {
        out.push(Reading::new(
            &format!("pair_hardness_{rule}"),
            &format!("G(e) against the {what}"),
            "P02 (20) writes H without saying whose; P04 uses min",
            json!({ "impact": { "pair_hardness": rule } }),
        ));
    }
    out.push(Reading::new(
        "friction_uncapped",
        "the full Coulomb impulse (may reverse sliding)",
        "P04 (4.17) and P02 (7) as printed",
        json!({ "impact": { "friction_cap": "none" } }),
    ));
    out.push(Reading::new(
        "work_heat_twice",
        "the dissipation heats the pair twice: dK plus the deformation work dW",
        "P04 (6.8) and (6.10)",
        json!({ "impact": { "work_heat": "twice" } }),
    ));
    out.push(Reading::new(
        "bond_any_iterate",
        "bond as soon as an iterate from e0 = 0 presses at 2H",
        "P02 (20) in-loop accretion test",
        json!({ "impact": { "bond_test": "any_iterate" } }),
    ));
    out.push(Reading::new(
        "separation_velocities",
        "overlaps removed along each body's own velocity",
        "P02 (8)",
        json!({ "impact": { "separation": "velocities" } }),
    ));
    let (other, law) = match i.duration {
        DurationLaw::P04 => ("duration_p02", "p02"),
        DurationLaw::P02 => ("duration_p04", "p04"),
    };
    out.push(Reading::new(
        other,
        &format!("the other paper's impact-duration law ({law})"),
        "P04 (4.10) against P02 (12)",
        json!({ "impact": { "duration": law } }),
    ));
    let (key, what) = if i.friction_scales_with_adhesion {
        ("friction_constant", "mu = mu0 (P04)")
    } else {
        ("friction_scales_with_adhesion", "mu = mu0 (1 - e) (P02)")
    };
    out.push(Reading::new(
        key,
        what,
        "P04 (4.17) against P02 after (7)",
        json!({ "impact": { "friction_scales_with_adhesion": !i.friction_scales_with_adhesion } }),
    ));
    if i.solver != SolverKind::Plain {
        out.push(Reading::new(
            "solver_plain",
            "the papers' plain iteration alone (last iterate if unconverged)",
            "P04 §6(b); P02 (20)",
            json!({ "impact": { "solver": "plain" } }),
        ));
        // The papers give no iteration cap; where the iteration 2-cycles (a0 = 0,
        // docs/model.md §5.2) its parity decides whether the last iterate is 0 (bond).
        let cap = i.max_iterations + 1;
        out.push(Reading::new(
            "solver_plain_cap_parity",
            &format!(
                "the plain iteration capped at {cap} instead of {} iterations (the other parity)",
                i.max_iterations
            ),
            "neither paper gives a cap",
            json!({ "impact": { "solver": "plain", "max_iterations": cap } }),
        ));
    }
    out.push(Reading::new(
        "solver_closed_form",
        "the closed form's root as the answer (pre-impact hardness; no iteration)",
        "P04 (4.13)-(4.14) corrected (docs/model.md §14)",
        json!({ "impact": { "solver": "closed_form" } }),
    ));
    if i.duration == DurationLaw::P04 {
        out.push(Reading::new(
            "solver_closed_form_printed",
            "P04 (4.14) as printed (spurious lambda in c1) as the answer",
            "P04 (4.14)",
            json!({ "impact": { "solver": "closed_form_printed" } }),
        ));
    }
    if base.physics.contact_rule != ContactRule::NearestNeighbour {
        out.push(Reading::new(
            "contact_nearest_neighbour",
            "a pair meets only if each is the other's nearest neighbour (stepped core)",
            "P04 (6.14) staggering rule",
            json!({ "physics": { "contact_rule": "nearest_neighbour" } }),
        ));
    }
    if base.physics.impacts_per_step == ImpactsPerStep::OnePerBody {
        out.push(Reading::new(
            "every_contact",
            "every contact found in a step is resolved instead of one per body (stepped core)",
            "P04 §6(b), P02 (20): several contacts of one particle not addressed",
            json!({ "physics": { "impacts_per_step": "every_contact" } }),
        ));
    }
    let cools = base.material.epsilon > 0.0 || base.material.hc > 0.0;
    if cools && base.physics.cooling != CoolingMethod::Explicit {
        out.push(Reading::new(
            "cooling_explicit",
            "forward Euler cooling at the scene's steps (stepped core)",
            "P04 (6.21); P02 (19)",
            json!({ "physics": { "cooling": "explicit" } }),
        ));
    }
    if cools && base.physics.cooling != CoolingMethod::ExplicitClamped {
        out.push(Reading::new(
            "cooling_explicit_clamped",
            "forward Euler cooling stopped at the equilibrium instead of crossing it (stepped core)",
            "P04 (6.21); P02 (19) without the blow-up",
            json!({ "physics": { "cooling": "explicit_clamped" } }),
        ));
    }
    if cools && i.duration == DurationLaw::P02 && base.physics.cooling != CoolingMethod::Off {
        // P02 (18)-(19) as printed cool per unit volume: about b/3 (~1e-6 here) times the
        // engine's per-area rate, i.e. practically not at all (docs/model.md §8).
        out.push(Reading::new(
            "cooling_p02_as_printed",
            "no cooling: P02 (18)-(19) per unit volume are ~b/3 times the per-area rate",
            "P02 (18)-(19)",
            json!({ "physics": { "cooling": "off" } }),
        ));
    }
    // Every reading the paper of the scene's duration law prints, taken together.
    let printed: &[&str] = match i.duration {
        DurationLaw::P04 => &[
            "friction_uncapped",
            "solver_plain",
            "contact_nearest_neighbour",
        ],
        DurationLaw::P02 => &[
            "friction_uncapped",
            "bond_any_iterate",
            "separation_velocities",
            "solver_plain",
            "contact_nearest_neighbour",
            "cooling_p02_as_printed",
        ],
    };
    let mut patch = json!({});
    let mut taken = Vec::new();
    for r in out.iter().filter(|r| printed.contains(&r.key.as_str())) {
        merge(&mut patch, &r.patch);
        taken.push(r.key.clone());
    }
    if taken.len() > 1 {
        let paper = match i.duration {
            DurationLaw::P04 => "P04",
            DurationLaw::P02 => "P02",
        };
        out.push(Reading::new(
            "papers_as_printed",
            &format!("all of: {}", taken.join(" + ")),
            &format!("{paper} as printed where it is explicit"),
            patch,
        ));
    }
    if i.duration == DurationLaw::P04 {
        // P04's own experiment: a0, af, β unstated (docs/model.md §13) and two printed
        // statements of the y/z velocity amplitudes; μ's table factor printed as 10⁻².
        if i.a0 == 0.0 {
            out.push(Reading::new(
                "a0_p02",
                "a0 = 0.01 (P02's value) instead of P04's logical choice a0 = 0",
                "P04 §8 does not give a0",
                json!({ "impact": { "a0": 0.01 } }),
            ));
        }
        let vx = base.cloud.v_rel[0];
        if vx > 0.0 && base.cloud.v_rel[1] == 0.1 * vx && base.cloud.v_rel[2] == 0.1 * vx {
            out.push(Reading::new(
                "v_rel_yz_10",
                "y and z amplitudes 10 m/s instead of 0.1 v0",
                "P04 §7 first statement (after (7.4))",
                json!({ "cloud": { "v_rel": [vx, 10.0, 10.0] } }),
            ));
        }
        if base.material.mu0 > 0.0 && base.material.mu0 < 0.01 {
            out.push(Reading::new(
                "mu_as_printed",
                "mu0 x 1e4: Table 2's factor 10^-2 taken as printed (outside P04's own range)",
                "P04 Table 2",
                json!({ "material": { "mu0": base.material.mu0 * 1e4 } }),
            ));
        }
    }
    out
}

/// Arguments of `agglo study readings` (kept here so that `src/cli.rs` only dispatches).
#[derive(clap::Args, Debug, Clone)]
pub struct ReadingsArgs {
    /// Scenario file (JSON).
    pub scenario: std::path::PathBuf,
    /// Output directory.
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Seeds per reading (the scenario's seed and the next ones), ≥ 2 for an error bar.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub seeds: u32,
    /// Set T by P02 (13) with this many fixed steps for every run, as the P02 inverse
    /// problem does (`end_time: {p02: {steps}}` in paper2002_inverse.json: 200).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub p02_steps: Option<u32>,
    /// Run only these readings (comma-separated keys; the baseline always runs).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// The published b_f/b0 to compare with (P04 rank 1: 3.23; P02 rank 1: 2).
    #[arg(long)]
    pub target_growth: Option<f64>,
    /// Override time.max_steps of every run (a run that reaches it counts as failed).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub max_steps: Option<u64>,
    /// Change the scene before the study: PATH=VALUE with a dotted scenario path and a
    /// JSON value, e.g. `--set box.half_width=1e-4` (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Run every combination of readings instead: one group per `--combine`, its
    /// alternatives separated by `|` (a combination takes none or one of each group),
    /// e.g. `--combine solver_plain|solver_plain_cap_parity --combine v_rel_yz_10`.
    #[arg(long, value_name = "KEY|KEY…")]
    pub combine: Vec<String>,
    /// List the readings offered for the scenario and exit.
    #[arg(long)]
    pub list: bool,
    /// Runs at once (0 = one per core; under mpirun, one per rank).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// One run of the study as a task of the farm: the scene, patched and capped, as JSON
/// (so that a rank needs neither the catalogue nor the base scenario).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ReadingTask {
    pub scenario_json: String,
}

/// The worker function of the study (on any thread or rank).
pub fn run_task(task: &ReadingTask) -> Result<RunStats, String> {
    let scenario = Scenario::from_json(&task.scenario_json).map_err(|e| e.to_string())?;
    measure(&scenario)
}

/// `base` with each `PATH=VALUE` applied (VALUE parsed as JSON, else taken as a string);
/// the name gains the settings so the outputs say what ran.
pub fn with_settings(base: &Scenario, settings: &[String]) -> anyhow::Result<Scenario> {
    let mut value = serde_json::to_value(base)?;
    for setting in settings {
        let (path, raw) = setting
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--set {setting}: expected PATH=VALUE"))?;
        let new: Value = serde_json::from_str(raw).unwrap_or_else(|_| Value::from(raw));
        let mut slot = &mut value;
        for key in path.split('.') {
            slot = match slot {
                // A missing key is added; the scenario's own parsing then names it if unknown.
                Value::Object(map) => map.entry(key).or_insert(Value::Null),
                Value::Array(items) => key
                    .parse::<usize>()
                    .ok()
                    .and_then(|k| items.get_mut(k))
                    .ok_or_else(|| anyhow::anyhow!("--set {setting}: no element `{key}`"))?,
                _ => anyhow::bail!("--set {setting}: the scenario has no field `{key}` there"),
            };
        }
        *slot = new;
    }
    let mut scenario = Scenario::from_value(value)
        .map_err(|e| anyhow::anyhow!("--set {}: {e}", settings.join(" ")))?;
    scenario.name = format!("{} ({})", base.name, settings.join(", "));
    Ok(scenario)
}

/// `agglo study readings`: run on `workers`, write, and print the table.
pub fn run_cli(args: &ReadingsArgs, workers: &crate::farm::Workers) -> anyhow::Result<()> {
    let mut base = Scenario::load(&args.scenario)
        .map_err(|e| anyhow::anyhow!("loading scenario {}: {e}", args.scenario.display()))?;
    if !args.set.is_empty() {
        base = with_settings(&base, &args.set)?;
    }
    if args.list {
        for r in catalogue(&base) {
            println!("{:<32} {} ({})", r.key, r.what, r.source);
        }
        return Ok(());
    }
    let options = ReadingsOptions {
        seeds: args.seeds as usize,
        p02_steps: args.p02_steps,
        only: args.only.clone(),
        combine: args
            .combine
            .iter()
            .map(|g| g.split('|').map(str::to_string).collect())
            .collect(),
        target_growth: args.target_growth,
        max_steps: args.max_steps,
    };
    let study = run_readings(&base, &options, workers, |line| eprintln!("{line}"))?;
    write_readings(&args.out, &study)?;
    print!("{}", markdown(&study));
    println!("wrote {}", args.out.join("readings.csv").display());
    Ok(())
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
    pub pi04: f64,
    pub n_f: f64,
    pub final_bodies: usize,
    pub impacts: u64,
    pub bonds: u64,
    pub bounces: u64,
    pub fallbacks: u64,
    pub unconverged: u64,
    /// Reaction heat / impact dissipation: how much of the heat any reading of the
    /// impact's energy split (P04 (6.10) against P02 (14)–(17)) could move.
    pub reaction_over_dissipation: f64,
    pub max_temperature: f64,
    pub invariant_violations: usize,
    pub wall_seconds: f64,
}

/// One run of one reading.
#[derive(Debug, Clone)]
pub struct Run {
    pub reading: usize,
    pub seed: u64,
    /// The run's statistics, or why it failed (a scenario the reading makes invalid, or
    /// a run error such as explicit cooling going unstable).
    pub result: Result<RunStats, String>,
}

/// Ensemble statistics of one reading.
#[derive(Debug, Clone, Default)]
pub struct ReadingSummary {
    pub runs: usize,
    pub failures: usize,
    /// First failure message (empty when none).
    pub failure: String,
    pub growth_mean: f64,
    pub growth_std: f64,
    /// Standard error of the mean b_f/b0.
    pub growth_se: f64,
    pub mass_mean_ratio: f64,
    pub pi04: f64,
    /// Π02 of the ensemble-mean radius, |⟨b_f⟩/(2 b0) − 1| (as the inverse problem).
    pub pi02: f64,
    pub n_f: f64,
    pub final_bodies: f64,
    pub impacts: f64,
    pub bonds: f64,
    pub unconverged: f64,
    pub reaction_over_dissipation: f64,
    /// Mean b_f/b0 minus the baseline's.
    pub delta: f64,
    /// (mean b_f/b0 − published value) / s.e. (NaN without a published value).
    pub z_target: f64,
    /// delta / √(se² + se_baseline²) (0 for the baseline; NaN if both errors are 0 and
    /// delta ≠ 0).
    pub z: f64,
    pub wall_seconds: f64,
}

/// The whole study.
#[derive(Debug, Clone)]
pub struct ReadingsStudy {
    pub scenario: String,
    pub seeds: Vec<u64>,
    pub target_growth: Option<f64>,
    pub p02_steps: Option<u32>,
    pub max_steps: Option<u64>,
    pub readings: Vec<Reading>,
    pub runs: Vec<Run>,
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
    let mut sim = Simulation::new(scenario).map_err(|e| e.to_string())?;
    sim.run().map_err(|e| e.to_string())?;
    let s = sim.summary();
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

/// Write `readings.csv` (one row per reading), `runs.csv` (one row per run),
/// `readings.md` (the table for the docs) and the chart `readings.png`/`.svg` to `dir`.
pub fn write_readings(dir: &Path, study: &ReadingsStudy) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let header = [
        "reading",
        "what",
        "source",
        "runs",
        "failures",
        "growth_mean",
        "growth_std",
        "growth_se",
        "delta",
        "z",
        "z_target",
        "mass_mean_ratio",
        "pi04",
        "pi02",
        "n_f",
        "final_bodies",
        "impacts",
        "bonds",
        "unconverged",
        "reaction_over_dissipation",
        "wall_seconds",
        "failure",
    ];
    let clean = |s: &str| s.replace([',', '\n'], ";");
    let rows: Vec<Vec<String>> = study
        .readings
        .iter()
        .zip(&study.summaries)
        .map(|(r, s)| {
            vec![
                r.key.clone(),
                clean(&r.what),
                clean(&r.source),
                s.runs.to_string(),
                s.failures.to_string(),
                num(s.growth_mean),
                num(s.growth_std),
                num(s.growth_se),
                num(s.delta),
                num(s.z),
                num(s.z_target),
                num(s.mass_mean_ratio),
                num(s.pi04),
                num(s.pi02),
                num(s.n_f),
                num(s.final_bodies),
                num(s.impacts),
                num(s.bonds),
                num(s.unconverged),
                num(s.reaction_over_dissipation),
                num(s.wall_seconds),
                clean(&s.failure),
            ]
        })
        .collect();
    write_csv(&dir.join("readings.csv"), &header, &rows)?;

    let run_header = [
        "reading",
        "seed",
        "growth_ratio",
        "mass_mean_ratio",
        "pi04",
        "n_f",
        "final_bodies",
        "impacts",
        "bonds",
        "bounces",
        "fallbacks",
        "unconverged",
        "reaction_over_dissipation",
        "max_temperature",
        "invariant_violations",
        "wall_seconds",
        "error",
    ];
    let run_rows: Vec<Vec<String>> = study
        .runs
        .iter()
        .map(|run| {
            let key = study.readings[run.reading].key.clone();
            match &run.result {
                Ok(m) => vec![
                    key,
                    run.seed.to_string(),
                    num(m.growth_ratio),
                    num(m.mass_mean_ratio),
                    num(m.pi04),
                    num(m.n_f),
                    m.final_bodies.to_string(),
                    m.impacts.to_string(),
                    m.bonds.to_string(),
                    m.bounces.to_string(),
                    m.fallbacks.to_string(),
                    m.unconverged.to_string(),
                    num(m.reaction_over_dissipation),
                    num(m.max_temperature),
                    m.invariant_violations.to_string(),
                    num(m.wall_seconds),
                    String::new(),
                ],
                Err(e) => {
                    let mut row = vec![key, run.seed.to_string()];
                    row.extend(std::iter::repeat_n(String::new(), run_header.len() - 3));
                    row.push(clean(e));
                    row
                }
            }
        })
        .collect();
    write_csv(&dir.join("runs.csv"), &run_header, &run_rows)?;
    std::fs::write(dir.join("readings.md"), markdown(study))?;
    // One row per reading: beyond MAX_CHART_ROWS (combination runs) the table is the result.
    if study.readings.len() <= MAX_CHART_ROWS {
        let height = 160 + 34 * study.readings.len() as u32;
        save_png_and_svg(dir, "readings", (1000, height), &Chart(study))?;
    }
    Ok(())
}

/// The summary table in Markdown.
pub fn markdown(study: &ReadingsStudy) -> String {
    let mut s = format!(
        "{} — {} seeds ({}…{}){}{}\n\n",
        study.scenario,
        study.seeds.len(),
        study.seeds.first().copied().unwrap_or(0),
        study.seeds.last().copied().unwrap_or(0),
        match study.p02_steps {
            Some(n) => format!(", T from P02 (13) with {n} fixed steps"),
            None => String::new(),
        },
        match study.max_steps {
            Some(n) => format!(", at most {n} steps per run"),
            None => String::new(),
        }
    );
    if let Some(t) = study.target_growth {
        s += &format!("Published b_f/b0: {t}.\n\n");
    }
    s += "| reading | what | b_f/b0 (± s.e.) | Δ vs baseline | z | z vs published | (N0/N_f)^(1/3) | Π04 | Π02 | bonds | failed |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (r, m) in study.readings.iter().zip(&study.summaries) {
        let ok = m.runs - m.failures;
        let (growth, delta, z) = if ok == 0 {
            ("–".to_string(), "–".to_string(), "–".to_string())
        } else {
            (
                format!("{:.3} ± {:.3}", m.growth_mean, m.growth_se),
                if r.key == BASELINE {
                    "–".into()
                } else {
                    format!("{:+.3}", m.delta)
                },
                if r.key == BASELINE {
                    "–".into()
                } else {
                    format!("{:+.1}", m.z)
                },
            )
        };
        let val = |x: f64, p: usize| {
            if ok == 0 {
                "–".to_string()
            } else {
                format!("{x:.p$}")
            }
        };
        let z_target = if ok == 0 || m.z_target.is_nan() {
            "–".to_string()
        } else {
            format!("{:+.1}", m.z_target)
        };
        s += &format!(
            "| `{}` | {} ({}) | {} | {} | {} | {} | {} | {} | {} | {} | {}/{} |\n",
            r.key,
            r.what,
            r.source,
            growth,
            delta,
            z,
            z_target,
            val(m.mass_mean_ratio, 3),
            val(m.pi04, 3),
            val(m.pi02, 4),
            val(m.bonds, 0),
            m.failures,
            m.runs
        );
    }
    if let Some(t) = study.target_growth {
        let close: Vec<_> = study
            .readings
            .iter()
            .zip(&study.summaries)
            .filter(|(_, m)| m.runs > m.failures && m.z_target.abs() <= 2.0)
            .collect();
        if close.is_empty() {
            s += &format!("\nNo reading lands within 2 s.e. of the published {t}.\n");
        } else {
            s += &format!("\nWithin 2 s.e. of the published {t}:\n\n");
            for (r, m) in close {
                s += &format!(
                    "- `{}`: {:.3} ± {:.3} (z = {:+.1}{})\n",
                    r.key,
                    m.growth_mean,
                    m.growth_se,
                    m.z_target,
                    if m.failures > 0 {
                        format!(", {} of {} runs failed", m.failures, m.runs)
                    } else {
                        String::new()
                    }
                );
            }
        }
    }
    let failures: Vec<_> = study
        .readings
        .iter()
        .zip(&study.summaries)
        .filter(|(_, m)| m.failures > 0)
        .collect();
    if !failures.is_empty() {
        s += "\nFailures (first message):\n\n";
        for (r, m) in failures {
            s += &format!("- `{}`: {}\n", r.key, m.failure);
        }
    }
    s
}

fn text(size: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font())
}

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing: {e}")
}

/// Most readings drawn on the chart.
const MAX_CHART_ROWS: usize = 40;

/// Most runs drawn as dots on the chart.
const MAX_DOTS: usize = 1000;

/// b_f/b0 of each reading (mean ± 2 s.e., every run as a dot up to [`MAX_DOTS`]), the baseline's
/// ± 2 s.e. band shaded and the published value drawn across.
struct Chart<'a>(&'a ReadingsStudy);

impl Figure for Chart<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let s = self.0;
        let n = s.readings.len();
        let values = s
            .runs
            .iter()
            .filter_map(|r| r.result.as_ref().ok().map(|m| m.growth_ratio))
            .chain(s.target_growth);
        let (mut g0, mut g1) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| {
            (a.min(g), b.max(g))
        });
        if !g0.is_finite() {
            (g0, g1) = (0.0, 1.0);
        }
        let pad = 0.05 * (g1 - g0).max(0.05);
        let (g0, g1) = (g0 - pad, g1 + pad);
        let labels: Vec<String> = s.readings.iter().map(|r| r.key.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "{}: b_f/b0 under each reading ({} seeds; mean ± 2 s.e.)",
                    s.scenario,
                    s.seeds.len()
                ),
                text(18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(230)
            .build_cartesian_2d(g0..g1, -0.5..(n as f64 - 0.5))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("b_f / b0")
            .y_labels(n)
            .y_label_formatter(&|y| {
                let k = y.round();
                if (y - k).abs() < 1e-6 && k >= 0.0 && (k as usize) < labels.len() {
                    labels[n - 1 - k as usize].clone()
                } else {
                    String::new()
                }
            })
            .label_style(text(13))
            .axis_desc_style(text(14))
            .draw()
            .map_err(err)?;
        let row = |k: usize| (n - 1 - k) as f64;
        let base = &s.summaries[0];
        if base.growth_mean.is_finite() {
            let (m, e) = (base.growth_mean, 2.0 * base.growth_se);
            chart
                .draw_series([Rectangle::new(
                    [(m - e, -0.5), (m + e, n as f64 - 0.5)],
                    RGBColor(200, 200, 200).mix(0.6).filled(),
                )])
                .map_err(err)?;
        }
        if let Some(t) = s.target_growth {
            chart
                .draw_series(LineSeries::new(
                    [(t, -0.5), (t, n as f64 - 0.5)],
                    ShapeStyle::from(&RED).stroke_width(2),
                ))
                .map_err(err)?
                .label(format!("published {t}"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], RED));
        }
        // Every run as a dot, unless there are so many that the SVG would run to megabytes.
        let dots = RGBColor(120, 120, 120);
        let shown = if s.runs.len() <= MAX_DOTS {
            &s.runs[..]
        } else {
            &[]
        };
        chart
            .draw_series(shown.iter().filter_map(|r| {
                r.result
                    .as_ref()
                    .ok()
                    .map(|m| Circle::new((m.growth_ratio, row(r.reading)), 2, dots.filled()))
            }))
            .map_err(err)?;
        let blue = RGBColor(31, 119, 180);
        for (k, m) in s.summaries.iter().enumerate() {
            if !m.growth_mean.is_finite() {
                continue;
            }
            let y = row(k);
            let e = 2.0 * m.growth_se;
            chart
                .draw_series([PathElement::new(
                    [(m.growth_mean - e, y), (m.growth_mean + e, y)],
                    ShapeStyle::from(&blue).stroke_width(3),
                )])
                .map_err(err)?;
            chart
                .draw_series([Circle::new((m.growth_mean, y), 5, blue.filled())])
                .map_err(err)?;
        }
        if s.target_growth.is_some() {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(text(12))
                .position(SeriesLabelPosition::LowerRight)
                .draw()
                .map_err(err)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combinations_take_none_or_one_of_each_group() {
        let base =
            Scenario::from_json(include_str!("../../scenarios/paper2004_best.json")).unwrap();
        let all = catalogue(&base);
        let groups = vec![
            vec![
                "solver_plain".to_string(),
                "solver_plain_cap_parity".to_string(),
            ],
            vec!["v_rel_yz_10".to_string()],
        ];
        let combos = combinations(&all, &groups);
        let keys: Vec<&str> = combos.iter().map(|r| r.key.as_str()).collect();
        assert_eq!(
            keys,
            [
                BASELINE,
                "v_rel_yz_10",
                "solver_plain",
                "solver_plain+v_rel_yz_10",
                "solver_plain_cap_parity",
                "solver_plain_cap_parity+v_rel_yz_10",
            ]
        );
        // The merged patch carries both readings.
        let s = scenario_for(&base, &combos[5], base.seed, None).unwrap();
        assert_eq!(s.impact.max_iterations, 101);
        assert_eq!(s.cloud.v_rel[1], 10.0);
    }

    #[test]
    fn the_catalogue_changes_every_scene_it_is_offered_for() {
        for text in [
            include_str!("../../scenarios/paper2004_best.json"),
            include_str!("../../scenarios/paper2002_best.json"),
        ] {
            let base = Scenario::from_json(text).unwrap();
            let readings = catalogue(&base);
            assert_eq!(readings[0].key, BASELINE);
            let baseline = scenario_for(&base, &readings[0], base.seed, None).unwrap();
            assert_eq!(baseline, base, "the baseline is the scenario itself");
            for r in &readings[1..] {
                let s = scenario_for(&base, r, base.seed, None)
                    .unwrap_or_else(|e| panic!("{}: {e}", r.key));
                assert_ne!(s, base, "{} changes nothing", r.key);
                assert!(!r.what.contains(',') && !r.key.contains(' '), "{}", r.key);
            }
        }
    }
}
