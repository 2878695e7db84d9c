//! The command line: the handlers the clap definitions (src/cli_args.rs) dispatch to,
//! each a thin layer over the library, and the entry points of a program — `agglo`
//! itself ([`main_with`] with no extensions) or a user's own binary that adds its
//! plugins ([`main_with`] with them; docs/extending.md).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;

mod inverse;
mod kernel;
#[doc(hidden)]
pub mod live;
mod ranks;

use agglo::prelude::*;
use agglo::readable::sci;
use agglo::run::signals::StopRequest;
use agglo::run::{Resume, Run, RunEnd, RunPlan, Until};

pub use agglo::cli_args::{Cli, Command, RunArgs, StudyCommand};

/// The `agglo` command with `extensions` beside the built-in physics: every command
/// (run, validate, schema, scan, optimize, study, kernel) sees them and their scenario
/// sections, on every worker thread and MPI rank. A user's binary is
///
/// ```no_run
/// # use agglo::prelude::*;
/// # struct MyPlugin;
/// # impl SimPlugin for MyPlugin {
/// #     fn name(&self) -> &'static str { "my_plugin" }
/// #     fn build(&self, _: &mut SimBuilder) {}
/// # }
/// fn main() -> std::process::ExitCode {
///     agglo::cli::main_with([agglo::plugins::Extension::plugin(MyPlugin)])
/// }
/// ```
///
/// Errors print with their causes and exit with status 1, as `agglo` does.
pub fn main_with(extensions: impl IntoIterator<Item = agglo::plugins::Extension>) -> ExitCode {
    restore_default_sigpipe();
    for extension in extensions {
        if let Err(e) = agglo::plugins::register(extension) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    match main_reporting_output_failures() {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// `print!` panics when standard output cannot be written (`agglo schema > /dev/full`:
/// "failed printing to stdout: No space left on device", exit 101). That one panic
/// becomes an error naming standard output and a failing exit; any other panic goes on
/// as before. Files the command wrote before it are complete: a report is printed last.
fn main_reporting_output_failures() -> anyhow::Result<()> {
    fn output_failure(payload: &(dyn std::any::Any + Send)) -> Option<String> {
        let text = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())?;
        text.starts_with("failed printing to std")
            .then(|| text.to_string())
    }
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if output_failure(info.payload()).is_none() {
            default_hook(info);
        }
    }));
    match std::panic::catch_unwind(main) {
        Ok(result) => result,
        Err(payload) => match output_failure(payload.as_ref()) {
            Some(text) => Err(anyhow::anyhow!(
                "cannot write to standard output or standard error ({text}): is the disk \
                 full, or the file it is redirected to not writable?"
            )),
            None => std::panic::resume_unwind(payload),
        },
    }
}

/// Rust ignores SIGPIPE, so `println!` into a closed pipe (`agglo … | head`) panics.
/// Restore the default action: the process ends quietly, like any Unix filter.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called once at start-up, before any thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Parse arguments and run the chosen command (under `mpirun`, rank 0 runs it and the
/// other ranks serve its simulations), with the extensions registered so far.
pub fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let cluster = ranks::join();
    if let Some(code) = ranks::serve(cluster.as_ref(), &cli.command) {
        // MPI_Finalize before leaving (without the feature there is nothing to drop).
        #[allow(clippy::drop_non_drop)]
        drop(cluster);
        std::process::exit(code);
    }
    let result = dispatch(cli.command, cluster.as_ref());
    ranks::finish(cluster.as_ref(), result.is_ok());
    result
}

fn dispatch(command: Command, cluster: Option<&agglo::farm::Cluster>) -> anyhow::Result<()> {
    match command {
        Command::Run(args) => run_command(*args),
        Command::Validate {
            scenario,
            set,
            seed,
        } => validate(&scenario, &set, seed),
        Command::Completions { shell } => {
            use std::io::Write;
            std::io::stdout().write_all(&agglo::cli_args::completions(shell))?;
            Ok(())
        }
        Command::Man => {
            use std::io::Write;
            std::io::stdout().write_all(&agglo::cli_args::man_page()?)?;
            Ok(())
        }
        Command::Study(study) => run_study(study, cluster),
        Command::Schema { outputs: true } => {
            print!("{}", agglo::output::schema::outputs_markdown());
            Ok(())
        }
        Command::Schema { outputs: false } => {
            println!(
                "{}",
                serde_json::to_string_pretty(&Scenario::json_schema())?
            );
            Ok(())
        }
        Command::Inspect { file, json } => {
            let report = agglo::record::inspect(&file)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
            Ok(())
        }
        Command::Layout { file, out } => layout(&file, out),
        Command::Optimize(args) => inverse::optimize(args, cluster),
        Command::Scan(args) => inverse::scan(args, cluster),
        Command::Kernel(args) => kernel::kernel(*args),
    }
}

fn load(path: &Path) -> anyhow::Result<Scenario> {
    Scenario::load(path).with_context(|| format!("loading scenario {}", path.display()))
}

fn validate(path: &Path, settings: &[String], seed: Option<u64>) -> anyhow::Result<()> {
    if is_inverse_file(path) {
        anyhow::ensure!(
            settings.is_empty() && seed.is_none(),
            "{}: --set and --seed apply to scenario files; an inverse problem's base \
             scenario is checked as it is written",
            path.display()
        );
        let problem = agglo::inverse::InverseProblem::load(path)
            .with_context(|| format!("loading inverse problem {}", path.display()))?;
        println!(
            "{}: valid inverse problem — {} genes ({}), base scenario {}",
            path.display(),
            problem.dimension(),
            problem.gene_names().join(", "),
            problem.base.name
        );
        return Ok(());
    }
    let mut s = load(path)?;
    if !settings.is_empty() {
        s = s.with_settings(settings)?;
    }
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let report = agglo::validate::report(&s)?;
    print!("{}", report.text);
    if let Some(warning) = report.warning {
        eprintln!("{warning}");
    }
    Ok(())
}

/// `agglo layout`: a layout fitted to an existing recording's box.
fn layout(recording: &Path, out: Option<PathBuf>) -> anyhow::Result<()> {
    use agglo::record::layout::{box_half_width, layout_path_for, write_fitted_layout};
    let d = box_half_width(recording)?;
    let path = out.unwrap_or_else(|| layout_path_for(recording));
    let fit = write_fitted_layout(&path, d)?;
    println!(
        "wrote {} (D = {d:e} m: camera distance {:e} m, near plane {:e} m); \
         in Foxglove: Layouts → Import from file",
        path.display(),
        fit.distance,
        fit.near
    );
    Ok(())
}

/// An inverse-problem file rather than a scenario: its top level has `genes`.
fn is_inverse_file(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
        .is_some_and(|v| v.get("genes").is_some())
}

fn run_command(args: RunArgs) -> anyhow::Result<()> {
    let plan = run_plan(&args)?;
    let resumed = plan.resume.as_ref().map(|r| {
        (
            r.file.clone(),
            r.snapshot.time(),
            r.snapshot.clock.step,
            r.snapshot.bodies.len(),
        )
    });
    let name = plan.scenario.name.clone();
    let stop = StopRequest::install();
    let mut run = Run::start(plan, stop.flag())?;
    if let Some((file, t, step, bodies)) = resumed
        && !args.quiet
    {
        println!(
            "resuming {name} at t = {} s (step {step}, {bodies} bodies) from {}",
            sci(t),
            file.display()
        );
    }
    let outcome = run.advance(Until::End, &mut |_| ControlFlow::Continue(()));
    let end = run.finish(&outcome);
    if !args.quiet {
        print_outputs(&end, outcome.is_ok());
        print_report(&end.summary);
    }
    for note in &end.notes {
        // Even with -q: a failed run's final state is not the state at the end time, and
        // some of its rows may be NaN (issue 39: they were written without a word).
        eprintln!("note: {note}");
    }
    if let Some(e) = end.output_error {
        return Err(e.context("recording the run"));
    }
    let outcome = outcome.context("running the scenario");
    match stop.describe() {
        Some(why) => outcome.context(why),
        None => outcome,
    }
}

/// The plan of `agglo run`: the scenario (from a file, a recording or a restart file,
/// with `--set` and `--seed`) and the flags over its `output` section.
fn run_plan(args: &RunArgs) -> anyhow::Result<RunPlan> {
    let mut resume = None;
    let mut scenario = match (&args.scenario, &args.from, &args.resume) {
        (Some(path), ..) => load(path)?,
        (None, Some(recording), _) => {
            let mut s = agglo::record::scenario_from_recording(recording)?;
            // The recording's own output paths would overwrite files (even the recording).
            s.output.summary = None;
            s.output.final_state = None;
            s.output.recording.path = None;
            // Its checkpoints are part of the run; its restart file is not this one's.
            if let Some(restart) = s.output.restart.as_mut() {
                restart.path = None;
            }
            s
        }
        (None, None, Some(file)) => {
            let (mut s, snapshot) = agglo::restart::read(file)?;
            // The stopped run's outputs would be overwritten by this continuation's.
            s.output.summary = None;
            s.output.final_state = None;
            s.output.recording.path = None;
            s.output.series = None;
            s.output.sizes = None;
            s.output.snapshots = None;
            s.output.collisions = None;
            // The restart file resumed from (beside the recording when --resume names one).
            resume = Some(Resume {
                file: agglo::restart::restart_file_of(file),
                snapshot,
            });
            s
        }
        (None, None, None) => {
            anyhow::bail!("give a scenario file, --from RECORDING or --resume RESTART")
        }
    };
    if !args.set.is_empty() {
        scenario = scenario.with_settings(&args.set)?;
    }
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    let mut plan = RunPlan::new(scenario)?;
    plan.tables = args.tables.paths(&plan.scenario.output)?;
    plan.step_tables = args.step_tables.0.clone();
    plan.resume = resume;
    if let Some(path) = &args.summary {
        plan.summary = Some(path.clone());
    }
    if let Some(path) = &args.final_state {
        plan.final_state = Some(path.clone());
    }
    if let Some(path) = &args.recording {
        plan.recording = Some(path.clone());
    }
    plan.restart = args.restart.clone();
    plan.command_line = live::recorded_command_line(std::env::args());
    plan.live = live::options(&args.live)?;
    plan.progress = !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stdout());
    Ok(plan)
}

/// What the run wrote: the recording and its layout, the checkpoints (and, when the run
/// did not reach its end time, how to continue it).
fn print_outputs(end: &RunEnd, finished: bool) {
    if let Some((path, rep)) = &end.recording {
        println!(
            "recorded {} snapshots ({} deletions, {} events) to {} ({:.2} MB); \
             Foxglove layout fitted to its box: {}",
            rep.snapshots,
            rep.deletions,
            rep.events,
            path.display(),
            rep.bytes as f64 / 1e6,
            end.layout
                .as_deref()
                .map_or_else(|| "none".into(), |p| p.display().to_string())
        );
    }
    if let Some((path, written)) = &end.checkpoints {
        match written.count {
            0 => println!("no checkpoint reached (restart file {})", path.display()),
            count => println!(
                "{count} checkpoints written to {} (the last at t = {} s, {:.2} MB; \
                 {:.3} s taking them, {:.3} s writing them); {}",
                path.display(),
                sci(written.time),
                written.bytes as f64 / 1e6,
                end.sim.checkpoint_seconds(),
                written.writing_seconds,
                if finished {
                    "the run reached its end time: nothing to resume".to_string()
                } else {
                    format!("continue with `agglo run --resume {}`", path.display())
                }
            ),
        }
    }
}

fn print_report(s: &Summary) {
    let g = &s.growth;
    let c = &s.counters;
    println!(
        "{} (seed {}): t = {} s in {} steps, {:.3} s wall",
        s.scenario,
        s.seed,
        sci(s.time),
        s.steps,
        s.wall_seconds
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

fn run_study(command: StudyCommand, cluster: Option<&agglo::farm::Cluster>) -> anyhow::Result<()> {
    use agglo::study::{accuracy, stability};
    match command {
        StudyCommand::Accuracy {
            scenario,
            out,
            repeats,
            seeds,
            target_growth,
            threads,
        } => {
            let base = load(&scenario)?;
            let options = accuracy::AccuracyOptions {
                repeats: repeats as usize,
                seeds: seeds as usize,
                target_growth,
                ..Default::default()
            };
            let workers = agglo::farm::Workers {
                threads: ranks::threads(threads, cluster),
                cluster,
            };
            let study =
                accuracy::run_accuracy(&base, &options, &workers, |line| eprintln!("{line}"))?;
            if let Some(line) = ranks::report(cluster) {
                eprintln!("{line}");
            }
            agglo::study::write::write_accuracy(&out, &study)?;
            println!("wrote {}", out.join("accuracy.csv").display());
        }
        StudyCommand::Stability {
            out,
            scenario,
            seeds,
        } => {
            let scene = match scenario {
                Some(path) => load(&path)?,
                None => Scenario::from_json(agglo::study::STUDY_SCENARIO)
                    .context("the built-in study scene")?,
            };
            let options = stability::StabilityOptions {
                seeds: seeds as usize,
                ..Default::default()
            };
            let study = stability::run_stability(&scene, &options, |line| eprintln!("{line}"))?;
            agglo::study::write::write_stability(&out, &study)?;
            println!("wrote {}", out.display());
        }
        StudyCommand::Readings(args) => {
            let workers = agglo::farm::Workers {
                threads: ranks::threads(args.threads, cluster),
                cluster,
            };
            agglo::study::readings::run_cli(&args, &workers)?;
            if let Some(line) = ranks::report(cluster) {
                eprintln!("{line}");
            }
        }
    }
    Ok(())
}
