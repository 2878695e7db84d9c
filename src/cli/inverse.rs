//! `agglo optimize` and `agglo scan`: thin handlers over [`agglo::inverse`].

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use agglo::farm::{Cluster, Workers};
use agglo::inverse::{self, Event, InverseProblem, Options};

use super::ranks;

pub use agglo::cli_args::{OptimizeArgs, ScanArgs};

fn load(path: &Path) -> anyhow::Result<InverseProblem> {
    InverseProblem::load(path)
        .with_context(|| format!("loading inverse problem {}", path.display()))
}

/// The flag a stop signal (SIGINT, SIGTERM, SIGHUP) sets: the batch then stops starting
/// samples and the checkpoint of the last finished generation stays the one to resume.
fn interrupt_flag() -> Arc<AtomicBool> {
    agglo::run::signals::StopRequest::install().flag()
}

/// The base scenes the threads run at once must fit together (the problem's own check
/// covers one).
fn check_runs_at_once(problem: &InverseProblem, threads: usize) -> anyhow::Result<()> {
    if let Some(warning) =
        agglo::memory::MemoryEstimate::of_runs(&problem.base, usize::MAX, threads)
            .check()
            .map_err(|e| anyhow::anyhow!("--threads {threads}: {e}"))?
    {
        eprintln!("{warning}");
    }
    Ok(())
}

pub fn optimize(args: OptimizeArgs, cluster: Option<&Cluster>) -> anyhow::Result<()> {
    let problem = load(&args.problem)?;
    check_runs_at_once(&problem, args.threads)?;
    let ga = &problem.spec.ga;
    let cancel = interrupt_flag();
    let live = super::live::start_inverse(&args.live, &problem, &args.out, &cancel)?;
    let show = !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr());
    let bar = show.then(|| {
        let bar = ProgressBar::new(0);
        bar.set_style(
            ProgressStyle::with_template(
                "[{elapsed_precise}] gen {prefix} {bar:30} {pos}/{len} strings  {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    });
    let start = Instant::now();
    let evals = AtomicU64::new(0);
    let samples = AtomicU64::new(0);
    let generations_run = AtomicU64::new(0);
    let best = std::sync::Mutex::new((f64::NAN, f64::NAN));
    let generations = ga.generations;
    let on_event = |e: Event| {
        if let Some(live) = &live {
            live.on_event(&e);
        }
        let Some(bar) = &bar else { return };
        match e {
            Event::GenerationStarted {
                generation,
                strings,
            } => {
                bar.set_prefix(format!("{}/{generations}", generation + 1));
                bar.set_length(strings as u64);
                bar.set_position(0);
            }
            Event::StringDone { samples: s, .. } => {
                let n = evals.fetch_add(1, Ordering::Relaxed) + 1;
                let total_samples = samples.fetch_add(s as u64, Ordering::Relaxed) + s as u64;
                bar.inc(1);
                let t = start.elapsed().as_secs_f64();
                let (b, m) = *best.lock().unwrap_or_else(|p| p.into_inner());
                bar.set_message(format!(
                    "best {b:.5e}  mean top K {m:.5e}  samples/string {:.1}  {:.2} evals/s",
                    total_samples as f64 / n as f64,
                    n as f64 / t.max(1e-9),
                ));
            }
            Event::CheckStarted { strings, samples } => {
                bar.set_prefix("check");
                bar.set_length(0);
                bar.println(format!(
                    "closing check: the best {strings} strings, {samples} fresh samples each"
                ));
            }
            Event::GenerationDone(row) => {
                *best.lock().unwrap_or_else(|p| p.into_inner()) = (row.best_cost, row.mean_top_k);
                // ETA from this process's pace (a resumed run started later than generation 0).
                let t = start.elapsed().as_secs_f64();
                let ran = generations_run.fetch_add(1, Ordering::Relaxed) + 1;
                let left = generations.saturating_sub(row.generation + 1);
                let eta = t / ran as f64 * left as f64;
                bar.println(format!(
                    "generation {:>3}: best {:.6e}, mean top K {:.6e}, {} strings, {:.1} samples/string, ETA ≤ {:.0} s",
                    row.generation,
                    row.best_cost,
                    row.mean_top_k,
                    row.evaluations,
                    row.samples as f64 / row.evaluations.max(1) as f64,
                    eta
                ));
            }
            Event::GenerationState(_) => {}
        }
    };
    let times_csv = std::sync::Mutex::new(String::from("generation,string,sample,seconds,used\n"));
    let log_times = |g: usize, times: &[inverse::batch::SampleTime]| {
        use std::fmt::Write as _;
        let mut csv = times_csv.lock().unwrap_or_else(|p| p.into_inner());
        for t in times {
            let _ = writeln!(csv, "{g},{},{},{},{}", t.job, t.sample, t.seconds, t.used);
        }
    };
    let options = Options {
        threads: ranks::threads(args.threads, cluster),
        cluster,
        resume: args.resume,
        stop_after: args.stop_after,
        cancel: Some(&cancel),
        progress: Some(&on_event),
        sample_times: args.sample_times.is_some().then_some(&log_times as _),
    };
    let result = inverse::optimize(&problem, &args.out, &options);
    if let Some(live) = &live {
        live.finish();
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    if let Some(path) = &args.sample_times {
        let csv = times_csv.into_inner().unwrap_or_else(|p| p.into_inner());
        std::fs::write(path, csv).with_context(|| format!("writing {}", path.display()))?;
    }
    let state = result.with_context(|| format!("optimising {}", args.problem.display()))?;
    if !args.quiet {
        let names = problem.gene_names();
        if let Some(b) = state.best() {
            println!(
                "{}: {} generations, {} strings evaluated, {:.1} s wall{}",
                problem.spec.name,
                state.generations_done,
                state.total_evaluations,
                start.elapsed().as_secs_f64(),
                if state.finished {
                    ""
                } else {
                    " (not finished: continue with --resume)"
                }
            );
            println!(
                "  best cost {:.6e}, b_f/b0 = {:.4}, n_f = {:.3}, {} samples",
                b.eval.cost,
                b.eval.means.mean,
                b.eval.means.mean.powi(3),
                b.eval.samples
            );
            for (n, x) in names.iter().zip(&b.genes) {
                println!("  {n:>12} = {x:.6e}");
            }
            if let Some(w) = state.finalists.first() {
                println!(
                    "  closing check, {} fresh samples per string: winner GA rank {}, cost {:.6e} ± {:.2e}, \
                     b_f/b0 = {:.4} ± {:.4} (the GA's own figure: {:.6e})",
                    w.eval.samples,
                    w.ga_rank,
                    w.eval.cost,
                    w.eval.cost_se.unwrap_or(f64::NAN),
                    w.eval.means.mean,
                    w.eval.growth_se.unwrap_or(f64::NAN),
                    state.parents[w.ga_rank - 1].eval.cost
                );
            }
            println!("  outputs in {}", args.out.display());
        }
        if let Some(line) = ranks::report(cluster) {
            println!("  {line}");
        }
    }
    Ok(())
}

pub fn scan(args: ScanArgs, cluster: Option<&Cluster>) -> anyhow::Result<()> {
    let problem = load(&args.problem)?;
    check_runs_at_once(&problem, args.threads)?;
    anyhow::ensure!(
        args.points >= 2,
        "--points: allowed ≥ 2 (got {})",
        args.points
    );
    // Each point keeps its value, its evaluation and its row: refused before any of
    // them is allocated when they cannot fit (1e11 points aborted on an allocation).
    agglo::memory::fits("points", args.points, args.points as f64 * 512.0)
        .map_err(|e| anyhow::anyhow!("--points: {e}"))?;
    anyhow::ensure!(
        args.from.is_finite() && args.to.is_finite(),
        "--from/--to: allowed finite numbers"
    );
    anyhow::ensure!(
        !args.log || (args.from > 0.0 && args.to > 0.0),
        "--log: --from and --to must be > 0"
    );
    let n = args.points;
    // Each point is rounded to 12 significant digits, so that a point two grids share
    // (1e-5 on `--points 5` and on `--points 25`) is the same number on both, and with
    // seeds that follow the value it is the same ensemble.
    let values: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            if args.log {
                (args.from.ln() + t * (args.to.ln() - args.from.ln())).exp()
            } else {
                args.from + t * (args.to - args.from)
            }
        })
        .map(inverse::scan_value)
        .collect();
    let cancel = interrupt_flag();
    let show = !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr());
    let bar = show.then(|| {
        let bar = ProgressBar::new(n as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "[{elapsed_precise}] {bar:30} {pos}/{len} points (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    });
    let on_point = |k: usize| {
        if let Some(bar) = &bar {
            bar.set_position(k as u64)
        }
    };
    let start = Instant::now();
    let points = inverse::scan(
        &problem,
        &args.gene,
        &values,
        &Workers {
            threads: ranks::threads(args.threads, cluster),
            cluster,
        },
        Some(&cancel),
        Some(&on_point),
    );
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let points = points.context("scanning")?;
    inverse::write_scan(&args.out, &problem, &args.gene, &points, args.log)?;
    if !args.quiet {
        println!(
            "{}: {} points of {} in {:.1} s",
            problem.spec.name,
            n,
            args.gene,
            start.elapsed().as_secs_f64()
        );
        for p in &points {
            println!(
                "  {:>12.4e}: b_f/b0 = {:.4}, cost {:.4e}, {} samples",
                p.value, p.eval.means.mean, p.eval.cost, p.eval.samples
            );
        }
        println!("  outputs in {}", args.out.display());
        if let Some(line) = ranks::report(cluster) {
            println!("  {line}");
        }
    }
    Ok(())
}
