//! Command-line definitions (clap) and the handlers they dispatch to. Binary only:
//! each handler is a thin layer over the library.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Parser;

mod clamp_watch;
mod inverse;
mod live;
mod progress;
mod ranks;
mod signals;

use agglo::output::{write_final_state_with, write_summary};
use agglo::prelude::*;
use agglo::readable::sci;
use agglo::scenario::Stepping;
use agglo::schedule::Pipeline;
use clamp_watch::ClampWatch;

pub use agglo::cli_args::{Cli, Command, RunArgs, StudyCommand};

/// Parse arguments and run the chosen command (under `mpirun`, rank 0 runs it and the
/// other ranks serve its simulations).
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
        Command::Run(args) => run(*args),
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
    println!(
        "{}: valid — N = {}, b0 = {:.4e} m, volume fraction {:.4}, D = {} m, T = {} s, seed {}",
        s.name,
        s.cloud.count,
        s.primary_radius(),
        s.volume_fraction(),
        sci(s.domain.half_width),
        sci(s.time.end),
        s.seed
    );
    let pipeline = s.pipeline().context("building the scene's pipeline")?;
    print!("{}", pipeline_text(&pipeline));
    if let Some(restart) = &s.output.restart {
        let before_end = (s.time.end / restart.every).ceil() as u64 - 1;
        println!(
            "restart checkpoints: every {} s of simulated time, {before_end} before T \
             (agglo run --resume continues from the last one)",
            sci(restart.every)
        );
    }
    let memory = agglo::memory::MemoryEstimate::of(&s);
    println!("{}", memory.describe());
    if let Some(warning) = memory.check().map_err(anyhow::Error::msg)? {
        eprintln!("{warning}");
    }
    Ok(())
}

/// The pipeline as `validate` prints it: the core and why, the systems in order, and
/// why each other system is left out.
fn pipeline_text(p: &Pipeline) -> String {
    let mut text = format!("core: {} — {}\n", p.core, p.core_reason);
    text += &format!("pipeline ({} systems, in order):\n", p.systems.len());
    for (i, system) in p.systems.iter().enumerate() {
        text += &format!("  {:>2}. {system}\n", i + 1);
    }
    for line in &p.forces {
        text += &format!("{line}\n");
    }
    if p.left_out.is_empty() {
        text += "left out: nothing\n";
    } else {
        text += "left out:\n";
        for line in &p.left_out {
            text += &format!("  - {line}\n");
        }
    }
    text
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

fn run(args: RunArgs) -> anyhow::Result<()> {
    let mut resume_from = None;
    // The restart file resumed from (beside the recording when --resume names one).
    let resumed_file = args.resume.as_deref().map(agglo::restart::restart_file_of);
    let mut scenario = match (&args.scenario, &args.from, &args.resume) {
        (Some(path), ..) => load(path)?,
        (None, Some(recording), _) => {
            let mut s = agglo::record::scenario_from_recording(recording)?;
            // The recording's own output paths would overwrite files (even the recording).
            s.output.summary = None;
            s.output.final_state = None;
            s.output.mcap = None;
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
            s.output.mcap = None;
            s.output.series = None;
            s.output.sizes = None;
            s.output.snapshots = None;
            s.output.collisions = None;
            resume_from = Some(snapshot);
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
    let table_paths = args.tables.paths(&scenario.output)?;
    let summary_path = args
        .summary
        .clone()
        .or_else(|| scenario.output.summary.clone().map(PathBuf::from));
    let final_path = args
        .final_state
        .clone()
        .or_else(|| scenario.output.final_state.clone().map(PathBuf::from));

    let mcap_path = args
        .out
        .clone()
        .or_else(|| scenario.output.mcap.clone().map(PathBuf::from));

    // Before anything is allocated: does the scene fit in memory (recorded or not)?
    if let Some(warning) = agglo::memory::MemoryEstimate::of_run(&scenario, mcap_path.is_some())
        .check()
        .map_err(anyhow::Error::msg)?
    {
        eprintln!("{warning}");
    }
    let live = live::bind_run(&args.live)?;
    let mut sim = table_paths
        .simulation(&scenario)
        .context("setting up the scene")?;
    if let (Some(snapshot), Some(file)) = (&resume_from, &resumed_file) {
        sim.resume(snapshot)
            .with_context(|| format!("resuming from {}", file.display()))?;
        if !args.quiet {
            println!(
                "resuming {} at t = {:e} s (step {}, {} bodies) from {}",
                scenario.name,
                snapshot.time(),
                snapshot.clock.step,
                snapshot.bodies.len(),
                file.display()
            );
        }
    }
    let restart_file = agglo::restart::restart_path(
        &scenario,
        args.restart.as_deref().or(resumed_file.as_deref()),
        mcap_path.as_deref(),
    );
    // Checkpoints written: count, bytes of the last, its time [s], seconds writing.
    let mut checkpoints_written: (u64, u64, f64, f64) = (0, 0, 0.0, 0.0);
    // For the restart tests: SIGKILL this process after the given step, at a point the
    // test chooses exactly (an outside kill lands wherever the run happens to be).
    let kill_after = std::env::var("AGGLO_TEST_SIGKILL_AFTER_STEP")
        .ok()
        .and_then(|v| v.parse::<u64>().ok());

    let stop = signals::StopRequest::install();
    let layout_path = match &mcap_path {
        Some(path) => Some(write_layout_beside(path, &scenario)?),
        None => None,
    };
    // Created after the signal handlers: once the file exists, a stop signal finalises it.
    let mut recorder = match &mcap_path {
        Some(path) => {
            let command_line = live::recorded_command_line(std::env::args());
            Some(agglo::record::Recorder::create(path, &sim, &command_line)?)
        }
        None => None,
    };
    let mut tables = agglo::output::RunTables::open(&table_paths, &scenario, &sim)?;
    let beside = mcap_path.as_deref().or(summary_path.as_deref());
    let mut live = live::start_run(live, &sim, &scenario, beside, &stop.flag())?;
    let mut clamp_watch = clamping_floor(&scenario).map(|dt_min| (ClampWatch::new(0, 0), dt_min));
    let mut record_error: Option<anyhow::Error> = None;
    let show_progress = !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stdout());
    let mut bar = show_progress
        .then(|| progress::Progress::new(scenario.time.end, scenario.uses_event_core()));
    let outcome = sim.run_with(|s| {
        if let Some(bar) = bar.as_mut() {
            bar.update(s);
        }
        if let Some((watch, dt_min)) = clamp_watch.as_mut() {
            let c = s.clock();
            if let Some(window) = watch.observe(
                c.step,
                s.counters().clamped_steps,
                std::time::Instant::now(),
            ) {
                let warning = clamping_warning(&scenario, *dt_min, c.time, window);
                // Above the progress bar, which also draws on stderr.
                match &bar {
                    Some(bar) => bar.suspend(|| eprintln!("{warning}")),
                    None => eprintln!("{warning}"),
                }
            }
        }
        if let Some(l) = live.as_mut() {
            l.observe(s);
        }
        if let Some(r) = recorder.as_mut()
            && let Err(e) = r.observe(s)
        {
            record_error = Some(e);
            return ControlFlow::Break(());
        }
        if let Some(t) = tables.as_mut()
            && let Err(e) = t.observe(s)
        {
            record_error = Some(e);
            return ControlFlow::Break(());
        }
        if let (Some(path), Some(snapshot)) = (&restart_file, s.restart_snapshot()) {
            let start = std::time::Instant::now();
            match agglo::restart::write(path, &scenario, snapshot) {
                Ok(bytes) => {
                    let (count, _, _, seconds) = checkpoints_written;
                    let seconds = seconds + start.elapsed().as_secs_f64();
                    checkpoints_written = (count + 1, bytes, snapshot.time(), seconds);
                }
                Err(e) => {
                    record_error = Some(e);
                    return ControlFlow::Break(());
                }
            }
        }
        if kill_after == Some(s.clock().step) {
            // Die as a killed job does: no handler runs, nothing is flushed.
            // SAFETY: getpid and kill have no preconditions.
            unsafe { libc::kill(libc::getpid(), libc::SIGKILL) };
        }
        if stop.requested() {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    if let Some(bar) = &bar {
        bar.finish();
    }

    // Finalise the recording whatever happened (summary section written), then the rest.
    if let Some(r) = recorder.take() {
        let path = r.path().to_path_buf();
        match r.finish(&sim, &outcome) {
            Ok(rep) if !args.quiet => println!(
                "recorded {} snapshots ({} deletions, {} events) to {} ({:.2} MB); \
                 Foxglove layout fitted to its box: {}",
                rep.snapshots,
                rep.deletions,
                rep.events,
                path.display(),
                rep.bytes as f64 / 1e6,
                layout_path
                    .as_deref()
                    .map_or_else(|| "none".into(), |p| p.display().to_string())
            ),
            Ok(_) => {}
            Err(e) => {
                record_error.get_or_insert(e);
            }
        }
    }
    if let Some(l) = live.take() {
        l.finish(&sim, &outcome);
    }
    if let Some(path) = &restart_file
        && !args.quiet
    {
        let (count, bytes, t, writing) = checkpoints_written;
        match count {
            0 => println!("no checkpoint reached (restart file {})", path.display()),
            _ => println!(
                "{count} checkpoints written to {} (the last at t = {t:e} s, {:.2} MB; \
                 {:.3} s taking them, {writing:.3} s writing them); \
                 continue with `agglo run --resume {}`",
                path.display(),
                bytes as f64 / 1e6,
                sim.checkpoint_seconds(),
                path.display()
            ),
        }
    }
    // Write what we have even when the run failed: nothing is lost. A table whose
    // writer failed during the run fails again here: the first error is the one told.
    if let Some(t) = tables.take()
        && let Err(e) = t.finish(&sim)
    {
        record_error.get_or_insert(e);
    }
    let bodies = sim.bodies();
    let summary = Summary::new(&sim, &bodies);
    if let Some(path) = &final_path {
        write_final_state_with(path, &bodies, &sim.carried())?;
    }
    if let Some(path) = &summary_path {
        write_summary(path, &summary)?;
    }
    if !args.quiet {
        print_report(&summary);
    }
    if let Some(e) = record_error {
        return Err(e.context("recording the run"));
    }
    let outcome = outcome.context("running the scenario");
    match stop.describe() {
        Some(why) => outcome.context(why),
        None => outcome,
    }
}

/// Write the Foxglove layout fitted to the scene's box beside the recording `mcap`.
fn write_layout_beside(mcap: &Path, scenario: &Scenario) -> anyhow::Result<PathBuf> {
    use agglo::record::layout::{layout_path_for, write_fitted_layout};
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

/// The warning printed (even under `--quiet`: it is about a run going wrong, and goes
/// to stderr, which `--quiet` does not silence) when most steps of a window were clamped.
fn clamping_warning(
    s: &Scenario,
    dt_min: f64,
    t: f64,
    window: clamp_watch::ClampedWindow,
) -> String {
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
