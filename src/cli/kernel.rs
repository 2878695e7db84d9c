//! `agglo kernel` (flags: `agglo::cli_args::KernelArgs`): run the ensemble
//! ([`agglo::kernel::measure`]) and write the files ([`agglo::kernel::write_files`]).

use anyhow::Context;

use agglo::cli_args::{KernelArgs, Units};
use agglo::kernel::{self, MassGrid, Sampling, Window};

/// `--window T0:T1` or `--burn-in T0`.
fn window(args: &KernelArgs) -> anyhow::Result<Window> {
    let (start, end) = match (&args.window, args.burn_in) {
        (Some(text), _) => {
            let (a, b) = text
                .split_once(':')
                .with_context(|| format!("--window: expected T0:T1 in seconds (got `{text}`)"))?;
            let parse = |s: &str, what: &str| {
                s.trim()
                    .parse::<f64>()
                    .with_context(|| format!("--window: {what} `{s}` is not a number"))
            };
            (parse(a, "T0")?, parse(b, "T1")?)
        }
        (None, Some(t0)) => (t0, f64::INFINITY),
        (None, None) => (0.0, f64::INFINITY),
    };
    Ok(Window::new(start, end)?)
}

pub fn kernel(args: KernelArgs) -> anyhow::Result<()> {
    let mut scenario = super::load(&args.scenario)?;
    if !args.set.is_empty() {
        scenario = scenario.with_settings(&args.set)?;
    }
    if let Some(path) = &args.parquet
        && !agglo::output::table::is_parquet(path)
    {
        // The long table holds the scenario's JSON, which a CSV cell cannot.
        anyhow::bail!(
            "--parquet {}: the name must end in .parquet",
            path.display()
        );
    }
    // Everything that can be refused is, before the first run: the grid, the sampling,
    // the ensemble's memory and the outputs' directories.
    let grid = MassGrid::for_scenario(&args.bins, &scenario)?;
    let window = window(&args)?;
    let sampling = Sampling {
        times: args.speed_samples,
        pairs: args.speed_pairs,
    };
    sampling.check().map_err(anyhow::Error::msg)?;
    kernel::check_seeds(args.seeds, &grid)
        .map_err(|e| anyhow::anyhow!("--seeds {}: {e}", args.seeds))?;
    kernel::write::check_writable(&args.out, "--out")?;
    if let Some(path) = &args.parquet {
        kernel::write::check_writable(path, "--parquet")?;
    }
    let seeds = kernel::seeds(&scenario, args.seeds);
    let workers = agglo::farm::Workers::local(args.threads);
    let quiet = args.quiet;
    let acc = kernel::measure(
        &scenario,
        &grid,
        window,
        sampling,
        &seeds,
        &workers,
        |line| {
            if !quiet {
                eprintln!("{line}");
            }
        },
    )?;
    kernel::write_files(
        &acc,
        &scenario,
        args.units == Units::Cgs,
        &args.out,
        args.parquet.as_deref(),
    )?;
    if !quiet {
        let impacts: u64 = (0..acc.classes() * acc.classes())
            .map(|p| acc.pooled.total(p))
            .sum();
        println!(
            "wrote {} ({} classes, {} runs, {impacts} impacts){}",
            args.out.display(),
            acc.classes(),
            acc.runs,
            args.parquet
                .as_ref()
                .map_or_else(String::new, |p| format!(" and {}", p.display()))
        );
    }
    Ok(())
}
