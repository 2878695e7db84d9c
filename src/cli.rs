//! Command-line definitions (clap) and the handlers they dispatch to. Binary only:
//! each handler is a thin layer over the library.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

mod inverse;

use agglo::output::{write_final_state, write_summary};
use agglo::prelude::*;

/// Particle agglomeration in thermochemically reacting granular flows.
#[derive(Parser, Debug)]
#[command(name = "agglo", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a scenario to its end time.
    Run(RunArgs),
    /// Check a scenario file and print what it describes.
    Validate {
        /// Scenario file (JSON).
        scenario: PathBuf,
    },
    /// Print the JSON Schema of the scenario format.
    Schema,
    /// Solve an inverse problem: genetic algorithm over ensemble-averaged costs (MODEL.md §12).
    Optimize(inverse::OptimizeArgs),
    /// Scan one scenario field of an inverse problem's base scenario (ensemble cost per point).
    Scan(inverse::ScanArgs),
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Scenario file (JSON).
    pub scenario: PathBuf,
    /// Override the scenario's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the observables and counters as JSON here.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Write one CSV row per body at the end here.
    #[arg(long)]
    pub final_state: Option<PathBuf>,
    /// No progress bar and no end-of-run report.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Parse arguments and run the chosen command.
pub fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Run(args) => run(args),
        Command::Validate { scenario } => validate(&scenario),
        Command::Schema => {
            println!(
                "{}",
                serde_json::to_string_pretty(&Scenario::json_schema())?
            );
            Ok(())
        }
        Command::Optimize(args) => inverse::optimize(args),
        Command::Scan(args) => inverse::scan(args),
    }
}

fn load(path: &Path) -> anyhow::Result<Scenario> {
    Scenario::load(path).with_context(|| format!("loading scenario {}", path.display()))
}

fn validate(path: &Path) -> anyhow::Result<()> {
    let s = load(path)?;
    println!(
        "{}: valid — N = {}, b0 = {:.4e} m, volume fraction {:.4}, D = {:e} m, T = {:e} s, seed {}",
        s.name,
        s.cloud.count,
        s.primary_radius(),
        s.volume_fraction(),
        s.domain.half_width,
        s.time.end,
        s.seed
    );
    Ok(())
}

fn run(args: RunArgs) -> anyhow::Result<()> {
    let mut scenario = load(&args.scenario)?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    let summary_path = args
        .summary
        .clone()
        .or_else(|| scenario.output.summary.clone().map(PathBuf::from));
    let final_path = args
        .final_state
        .clone()
        .or_else(|| scenario.output.final_state.clone().map(PathBuf::from));

    let mut sim = Simulation::new(&scenario).context("setting up the scene")?;

    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        // A second handler cannot be installed (e.g. in tests); the run still works without one.
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
    }
    let show_progress = !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stdout());
    let bar = if show_progress {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% {msg} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Some(bar)
    } else {
        None
    };
    let end = scenario.time.end;
    let outcome = sim.run_with(|s| {
        if let Some(bar) = &bar {
            let c = s.clock();
            if c.step % 64 == 0 {
                bar.set_position((1000.0 * c.time / end) as u64);
                bar.set_message(format!("step {} t = {:.3e} s", c.step, c.time));
            }
        }
        if interrupted.load(Ordering::SeqCst) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }

    // Write what we have even when the run failed: nothing is lost.
    let bodies = sim.bodies();
    let summary = Summary::new(&sim, &bodies);
    if let Some(path) = &final_path {
        write_final_state(path, &bodies)?;
    }
    if let Some(path) = &summary_path {
        write_summary(path, &summary)?;
    }
    if !args.quiet {
        print_report(&summary);
    }
    outcome.context("running the scenario")?;
    Ok(())
}

fn print_report(s: &Summary) {
    let g = &s.growth;
    let c = &s.counters;
    println!(
        "{} (seed {}): t = {:.4e} s in {} steps, {:.3} s wall",
        s.scenario, s.seed, s.time, s.steps, s.wall_seconds
    );
    println!(
        "  bodies {} → {}, b_f/b0 = {:.4}, n_f = {:.3}, Π04 = {:.4}, Π02 = {:.4e}",
        s.initial_bodies, s.final_bodies, g.growth_ratio, g.n_f, g.pi04, g.pi02
    );
    println!(
        "  impacts {} (bonds {}, bounces {}), fragmentations {}, fixed-point iterations {}, fallbacks {}",
        c.impacts, c.bonds, c.bounces, c.fragmentations, c.fixed_point_iterations, c.fallbacks
    );
    println!(
        "  mean θ = {:.2} K, max θ = {:.4e} K; invariant errors: mass {:.1e}, momentum {:.1e}, energy {:.1e}, violations {}",
        s.mean_temperature,
        s.max_temperature,
        s.max_mass_error,
        s.max_momentum_error,
        s.max_energy_error,
        c.invariant_violations
    );
}
