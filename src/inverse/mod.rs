//! The inverse problem (docs/model.md §11–§13): find the scenario parameters that
//! minimise an ensemble-averaged agglomeration cost with the genetic algorithm of
//! P04 §7 / P02 §6.
//!
//! - [`problem`]: the inverse file (base scenario, genes, cost, ensemble rule, GA
//!   settings) and its validation with field paths;
//! - [`genes`]: set a numeric scenario field by dotted path;
//! - [`ensemble`]: the ensemble cost with the stopping rule and derived seeds;
//! - [`ga`]: the genetic algorithm, one generation at a time;
//! - [`checkpoint`]: the state saved after every generation (`--resume`);
//! - [`output`]: `generations.csv`, `best.json`, `best_scenario.json`, charts.
//!
//! Strings (and scan points) are evaluated in parallel with rayon; each simulation
//! runs single-threaded in its worker and results are collected in index order, so
//! every output is bit-identical for any thread count.
//!
//! **Failed samples.** A sample can fail (cloud placement impossible, step limit,
//! non-finite state). By default (`"on_failure": "error"`) the run stops with an
//! error naming the generation, string, sample, seed and genes — the completed
//! generations stay checkpointed. With `"on_failure": {"penalty": P}` the string's
//! cost becomes P (its ensemble stops at the failure) and `best.json` counts it in
//! `failures`.

pub mod checkpoint;
pub mod ensemble;
pub mod ga;
pub mod genes;
pub mod output;
pub mod problem;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;
use serde::Serialize;

pub use ensemble::{Evaluation, StoppingRule, derive_seed, sample_seed, splitmix64};
pub use ga::{GaState, GenerationRow, Member};
pub use problem::{InverseError, InverseProblem, InverseSpec};

/// What the driver reports while it runs (for progress displays).
#[derive(Debug, Clone)]
pub enum Event<'a> {
    /// A generation starts: `strings` evaluations to do.
    GenerationStarted { generation: usize, strings: usize },
    /// One string finished with `samples` samples.
    StringDone { generation: usize, samples: u32 },
    /// A generation finished.
    GenerationDone(&'a GenerationRow),
}

/// How to run an inverse problem (`Default`: all cores, fresh run, no progress).
#[derive(Default)]
pub struct Options<'a> {
    /// Worker threads (0 = one per core).
    pub threads: usize,
    /// Continue from `DIR/checkpoint.json`.
    pub resume: bool,
    /// Stop after this many generations in this call (for tests of `--resume`).
    pub stop_after: Option<usize>,
    /// Set to stop between samples (Ctrl-C).
    pub cancel: Option<&'a AtomicBool>,
    pub progress: Option<&'a (dyn Fn(Event) + Sync)>,
}

fn pool(threads: usize) -> Result<rayon::ThreadPool, InverseError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| InverseError::Other(format!("thread pool: {e}")))
}

/// Run (or continue) the GA, writing outputs to `dir` and a checkpoint after every
/// generation. Returns the final state (finished, or stopped by `stop_after`).
pub fn optimize(
    problem: &InverseProblem,
    dir: &Path,
    options: &Options,
) -> Result<GaState, InverseError> {
    std::fs::create_dir_all(dir).map_err(|source| InverseError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let (lower, upper) = problem.bounds();
    let mut state = if options.resume {
        checkpoint::Checkpoint::load(dir, problem)?
    } else {
        GaState::new(lower.clone(), upper.clone())
    };
    let spec = &problem.spec.ga;
    let seed = spec.seed;
    let progress = |e: Event| {
        if let Some(p) = options.progress {
            p(e)
        }
    };
    let mut ran = 0;
    pool(options.threads)?.install(|| -> Result<(), InverseError> {
        while !state.finished && options.stop_after.is_none_or(|n| ran < n) {
            let g = state.generations_done;
            let strings = if g == 0 {
                spec.strings
            } else {
                spec.strings - spec.parents
            };
            progress(Event::GenerationStarted {
                generation: g,
                strings,
            });
            let row = ga::step(spec, (&lower, &upper), &mut state, |g, i, genes| {
                let e = ensemble::evaluate(problem, genes, seed, g, i, true, options.cancel)?;
                progress(Event::StringDone {
                    generation: g,
                    samples: e.samples,
                });
                Ok(e)
            })?;
            checkpoint::Checkpoint::new(problem, &state).save(dir)?;
            output::write_tables(dir, problem, &state)?;
            progress(Event::GenerationDone(&row));
            ran += 1;
        }
        Ok(())
    })?;
    output::write_tables(dir, problem, &state)?;
    if state.finished {
        output::write_charts(dir, problem, &state)?;
    }
    Ok(state)
}

/// One point of a one-gene scan.
#[derive(Debug, Clone, Serialize)]
pub struct ScanPoint {
    pub value: f64,
    pub eval: Evaluation,
}

/// Evaluate the ensemble of the base scenario with `path` set to each of `values`
/// (the problem's end-time rule, cost and ensemble rule apply; its genes do not).
/// Sample seeds derive from (GA seed, point index, sample).
pub fn scan(
    problem: &InverseProblem,
    path: &str,
    values: &[f64],
    threads: usize,
    cancel: Option<&AtomicBool>,
    progress: Option<&(dyn Fn(usize) + Sync)>,
) -> Result<Vec<ScanPoint>, InverseError> {
    // Fail early, with the field path, on a path the scenario does not have.
    problem
        .scenario_with(path, values.first().copied().unwrap_or(0.0), 0)
        .map_err(|e| InverseError::Other(format!("--gene {path}: {e}")))?;
    let seed = problem.spec.ga.seed;
    let spec = &problem.spec;
    let done = std::sync::atomic::AtomicUsize::new(0);
    pool(threads)?.install(|| {
        values
            .par_iter()
            .enumerate()
            .map(|(i, &x)| {
                let seed_of = |s: u32| derive_seed(&[seed, 2, i as u64, s as u64]);
                let eval = ensemble::evaluate_with(
                    &spec.ensemble,
                    &spec.cost,
                    spec.on_failure,
                    |s| problem.scenario_with(path, x, seed_of(s)),
                    seed_of,
                    &format!("{path} = {x:e}"),
                    (0, i),
                    false,
                    cancel,
                )?;
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(p) = progress {
                    p(n)
                }
                Ok(ScanPoint { value: x, eval })
            })
            .collect()
    })
}

/// Write `scan.csv` and the chart `scan.{png,svg}` (b̄_f/b0 against the scanned value).
pub fn write_scan(
    dir: &Path,
    problem: &InverseProblem,
    path: &str,
    points: &[ScanPoint],
    log_x: bool,
) -> Result<(), InverseError> {
    use std::fmt::Write as _;
    std::fs::create_dir_all(dir).map_err(|source| InverseError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let mut csv = String::from(
        "value,cost,growth_ratio,n_f,std_dev_ratio,skewness,kurtosis,samples,failures,end_time\n",
    );
    for (i, p) in points.iter().enumerate() {
        let end = problem
            .scenario_with(path, p.value, 0)
            .map(|s| s.time.end)
            .unwrap_or(f64::NAN);
        let m = &p.eval.means;
        let _ = i;
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{}",
            p.value,
            p.eval.cost,
            m.mean,
            m.mean.powi(3),
            m.std_dev,
            m.skewness,
            m.kurtosis,
            p.eval.samples,
            p.eval.failures,
            end
        );
    }
    let file = dir.join("scan.csv");
    std::fs::write(&file, csv).map_err(|source| InverseError::Io {
        path: file.display().to_string(),
        source,
    })?;
    let xy: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.value, p.eval.means.mean))
        .collect();
    let reference = match problem.spec.cost {
        problem::CostSpec::Pi02 { target_ratio } => {
            Some((target_ratio, format!("target b_f/b0 = {target_ratio}")))
        }
        _ => None,
    };
    crate::charts::save_png_and_svg(
        dir,
        "scan",
        (900, 600),
        &output::LineChart {
            title: format!("{}: ensemble b_f/b0 against {path}", problem.spec.name),
            x_label: path.to_string(),
            y_label: "b_f / b0 (ensemble mean)".into(),
            points: &xy,
            log_x,
            reference,
        },
    )
    .map_err(|e| InverseError::Other(format!("chart: {e:#}")))
}
