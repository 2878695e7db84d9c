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
//! - [`batch`]: a generation's (or a scan's) ensembles as one batch of samples for
//!   the task farm ([`crate::farm`]): threads here, and MPI ranks with `--features mpi`;
//! - [`output`]: `generations.csv`, `best.json`, `best_scenario.json`, charts.
//!
//! Samples are handed out one at a time to free workers; each simulation runs
//! single-threaded, and every ensemble takes its samples in sample order, so every
//! output is bit-identical for any thread or rank count.
//!
//! **Honest winners.** A GA that ranks strings by noisy ensemble costs favours the
//! strings whose samples happened to be lucky. After the last generation the best
//! `reevaluate.strings` strings are re-run with `reevaluate.samples` fresh seeds each
//! and re-ranked by that cost, reported as mean ± standard error (`best.json`).
//!
//! **Failed samples.** A sample can fail (cloud placement impossible, step limit,
//! non-finite state). By default (`"on_failure": "error"`) the run stops with an
//! error naming the generation, string, sample, seed and genes — the completed
//! generations stay checkpointed. With `"on_failure": {"penalty": P}` the string's
//! cost becomes P (its ensemble stops at the failure) and `best.json` counts it in
//! `failures`.

pub mod batch;
pub mod checkpoint;
pub mod ensemble;
pub mod ga;
pub mod genes;
pub mod output;
pub mod problem;

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use serde::Serialize;

use crate::farm::{Cluster, Workers};
use batch::{EnsembleBatch, Job, SampleScene};
use ensemble::Accumulator;

pub use ensemble::{Evaluation, StoppingRule, derive_seed, sample_seed, splitmix64};
pub use ga::{Finalist, GaState, GenerationRow, Member};
pub use problem::{InverseError, InverseProblem, InverseSpec};

/// What the driver reports while it runs (for progress displays).
#[derive(Debug, Clone)]
pub enum Event<'a> {
    /// A generation starts: `strings` evaluations to do.
    GenerationStarted {
        /// The generation (0-based).
        generation: usize,
        /// Evaluations to do.
        strings: usize,
    },
    /// One string finished with `samples` samples.
    StringDone {
        /// The generation (0-based).
        generation: usize,
        /// Samples its ensemble took.
        samples: u32,
    },
    /// A generation finished.
    GenerationDone(&'a GenerationRow),
    /// The GA's state after that generation (right after [`Event::GenerationDone`]; for
    /// live views, which show the best string's genes).
    GenerationState(&'a GaState),
    /// The closing check starts: `strings` strings of `samples` samples each.
    CheckStarted {
        /// Strings re-evaluated.
        strings: usize,
        /// Samples each.
        samples: u32,
    },
}

/// Receives (generation, the cost of every sample the generation computed).
pub type SampleTimesHook<'a> = &'a dyn Fn(usize, &[batch::SampleTime]);

/// How to run an inverse problem (`Default`: all cores, fresh run, no progress).
#[derive(Default)]
pub struct Options<'a> {
    /// Worker threads (0 = one per core); per rank with a cluster.
    pub threads: usize,
    /// The MPI ranks to share the samples with (rank 0 only; `--features mpi`).
    pub cluster: Option<&'a Cluster>,
    /// Continue from `DIR/checkpoint.json`.
    pub resume: bool,
    /// Stop after this many generations in this call (for tests of `--resume`).
    pub stop_after: Option<usize>,
    /// Set to stop between samples (Ctrl-C).
    pub cancel: Option<&'a AtomicBool>,
    /// Told each [`Event`] of the run (progress lines, the live view).
    pub progress: Option<&'a (dyn Fn(Event) + Sync)>,
    /// Receives the cost of every sample computed, generation by generation
    /// (the closing check as generation G).
    pub sample_times: Option<SampleTimesHook<'a>>,
}

/// Run (or continue) the GA, writing outputs to `dir` and a checkpoint after every
/// generation, then the closing check of the best strings. Returns the final state
/// (finished, or stopped by `stop_after`).
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
    let workers = Workers {
        threads: options.threads,
        cluster: options.cluster,
    };
    let progress = |e: Event| {
        if let Some(p) = options.progress {
            p(e)
        }
    };
    let names = problem.gene_names();
    let mut ran = 0;
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
        let row = ga::step(spec, (&lower, &upper), &mut state, |g, candidates| {
            let jobs = candidates
                .iter()
                .map(|(i, genes)| {
                    let i = *i;
                    Job {
                        scene: SampleScene::Genes(genes.clone()),
                        seed_of: Box::new(move |s| sample_seed(seed, g, i, s)),
                        keep_radii: true,
                        accumulator: Accumulator::new(
                            &problem.spec.ensemble,
                            &problem.spec.cost,
                            problem.spec.on_failure,
                            (g, i),
                        ),
                        label: ensemble::format_genes(&names, genes),
                        coordinates: (g, i),
                    }
                })
                .collect();
            let on_done = |_: usize, e: &Evaluation| {
                progress(Event::StringDone {
                    generation: g,
                    samples: e.samples,
                })
            };
            let (evals, times) = EnsembleBatch::new(jobs)
                .cancel_on(options.cancel)
                .on_done(Some(&on_done))
                .run(&workers, problem)?;
            if let Some(log) = options.sample_times {
                log(g, &times);
            }
            Ok(evals)
        })?;
        checkpoint::Checkpoint::new(problem, &state).save(dir)?;
        output::write_tables(dir, problem, &state)?;
        progress(Event::GenerationDone(&row));
        progress(Event::GenerationState(&state));
        ran += 1;
    }
    let check = &problem.spec.reevaluate;
    if state.finished && state.finalists.is_empty() && check.strings > 0 {
        state.finalists = reevaluate(problem, &state, &workers, options)?;
        checkpoint::Checkpoint::new(problem, &state).save(dir)?;
    }
    output::write_tables(dir, problem, &state)?;
    if state.finished {
        output::write_charts(dir, problem, &state)?;
    }
    Ok(state)
}

/// Seed of sample `sample` of the closing check of the string ranked `ga_rank`:
/// a stream of its own, so that the check shares no sample with the GA's choice.
pub fn check_seed(seed: u64, ga_rank: usize, sample: u32) -> u64 {
    derive_seed(&[seed, 3, ga_rank as u64, sample as u64])
}

/// The closing check: the best strings, each with a fixed ensemble of fresh seeds,
/// ranked by that cost (NaN last, ties by GA rank).
fn reevaluate(
    problem: &InverseProblem,
    state: &GaState,
    workers: &Workers,
    options: &Options,
) -> Result<Vec<Finalist>, InverseError> {
    let check = problem.spec.reevaluate;
    let seed = problem.spec.ga.seed;
    let names = problem.gene_names();
    let fixed = problem::EnsembleSpec {
        tol: 0.0,
        rule: problem::EnsembleRule::RunningMean,
        min_samples: check.samples,
        max_samples: check.samples,
        track: vec![problem::Tracked::Cost],
    };
    let chosen: Vec<&Member> = state.parents.iter().take(check.strings).collect();
    if let Some(p) = options.progress {
        p(Event::CheckStarted {
            strings: chosen.len(),
            samples: check.samples,
        });
    }
    let last = state.generations_done;
    let jobs = chosen
        .iter()
        .enumerate()
        .map(|(r, m)| Job {
            scene: SampleScene::Genes(m.genes.clone()),
            seed_of: Box::new(move |s| check_seed(seed, r + 1, s)),
            keep_radii: false,
            accumulator: Accumulator::new(
                &fixed,
                &problem.spec.cost,
                problem.spec.on_failure,
                (last, r),
            ),
            label: ensemble::format_genes(&names, &m.genes),
            coordinates: (last, r),
        })
        .collect();
    let (evals, times) = EnsembleBatch::new(jobs)
        .cancel_on(options.cancel)
        .run(workers, problem)?;
    if let Some(log) = options.sample_times {
        log(last, &times);
    }
    let mut finalists: Vec<Finalist> = chosen
        .iter()
        .zip(evals)
        .enumerate()
        .map(|(r, (m, eval))| Finalist {
            ga_rank: r + 1,
            genes: m.genes.clone(),
            eval,
        })
        .collect();
    finalists.sort_by(|a, b| ga::rank_key(a.eval.cost).total_cmp(&ga::rank_key(b.eval.cost)));
    Ok(finalists)
}

/// One point of a one-gene scan.
#[derive(Debug, Clone, Serialize)]
pub struct ScanPoint {
    /// The gene's value.
    pub value: f64,
    /// Its ensemble's cost and means.
    pub eval: Evaluation,
}

/// `x` rounded to 12 significant digits: a scan point as `agglo scan` makes it, so that
/// grids that share a point share its value bit for bit (`exp(ln a + t (ln b − ln a))`
/// lands a few ulps off the round number, and differently on different grids).
pub fn scan_value(x: f64) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    format!("{x:.11e}").parse().unwrap_or(x)
}

/// Evaluate the ensemble of the base scenario with `path` set to each of `values`
/// (the problem's end-time rule, cost and ensemble rule apply; its genes do not).
/// Sample seeds derive from (GA seed, the point's value, sample) — not from the point's
/// index (as before 2026-11-27), so that a finer scan reproduces the coarse scan's
/// points exactly.
pub fn scan(
    problem: &InverseProblem,
    path: &str,
    values: &[f64],
    workers: &Workers,
    cancel: Option<&AtomicBool>,
    progress: Option<&(dyn Fn(usize) + Sync)>,
) -> Result<Vec<ScanPoint>, InverseError> {
    // Fail early, with the field path, on a path the scenario does not have.
    problem
        .scenario_with(path, values.first().copied().unwrap_or(0.0), 0)
        .map_err(|e| InverseError::Other(format!("--gene {path}: {e}")))?;
    let seed = problem.spec.ga.seed;
    let spec = &problem.spec;
    let jobs = values
        .iter()
        .enumerate()
        .map(|(i, &x)| Job {
            scene: SampleScene::Field {
                path: path.to_string(),
                value: x,
            },
            // Domain 3 (2 was the index-based scheme): the value's bits name the point.
            seed_of: Box::new(move |s| derive_seed(&[seed, 3, x.to_bits(), s as u64])),
            keep_radii: false,
            accumulator: Accumulator::new(&spec.ensemble, &spec.cost, spec.on_failure, (0, i)),
            label: format!("{path} = {x:e}"),
            coordinates: (0, i),
        })
        .collect();
    let done = AtomicUsize::new(0);
    let on_done = |_: usize, _: &Evaluation| {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(p) = progress {
            p(n)
        }
    };
    let (evals, _) = EnsembleBatch::new(jobs)
        .cancel_on(cancel)
        .on_done(Some(&on_done))
        .run(workers, problem)?;
    Ok(values
        .iter()
        .zip(evals)
        .map(|(&value, eval)| ScanPoint { value, eval })
        .collect())
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
