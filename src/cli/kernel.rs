//! `agglo kernel`: parse the flags, run the ensemble ([`agglo::kernel::measure`]) and
//! write the files ([`agglo::kernel::write_files`]).

use std::path::PathBuf;

use anyhow::Context;

use agglo::kernel::{self, MassGrid, Sampling, Window};

/// Units of the kernel file.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// m³/s, s/m³, kg, m/s.
    Si,
    /// cm³/s, s/cm³, g, cm/s (DustPy's units).
    Cgs,
}

#[derive(clap::Args, Debug)]
#[command(after_help = "\
GRID is one of
  edges:m0,m1,...                  class edges in kg, increasing; class k = [m_k, m_k+1)
  dustpy:mmin,mmax,bins_per_decade DustPy's grid (grams, as sim.ini.grid.mmin/mmax/Nmbpd);
                                   class k holds sim.grid.m[k]
  openfoam:d0,d1,...               OpenFOAM size groups' diameters dSph in m, increasing
Every body must lie inside the grid, at the start and throughout (else the run stops,
naming the body). Rates follow K n_i n_j (i != j) and 1/2 K n_i^2 (i = j); K = counts/exposure.
Example:
  agglo kernel scenarios/ballistic_aggregation.json --bins dustpy:4e-12,1e-8,7 \\
      --seeds 8 --window 0:0.05 --units cgs --out kernel.npz --parquet kernel.parquet")]
pub struct KernelArgs {
    /// Scenario file (JSON).
    pub scenario: PathBuf,
    /// The mass grid (see below).
    #[arg(long, value_name = "GRID")]
    pub bins: String,
    /// Runs (seeds): the scenario's seed and the next S − 1, pooled.
    #[arg(long, value_name = "S", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub seeds: u32,
    /// Worker threads (0 = one per core); the file is the same for any number.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Count impacts and exposure only for T0 ≤ t < T1 [s].
    #[arg(long, value_name = "T0:T1", conflicts_with = "burn_in")]
    pub window: Option<String>,
    /// Count from T0 [s] to the end of each run.
    #[arg(long, value_name = "T0")]
    pub burn_in: Option<f64>,
    /// Units of the file.
    #[arg(long, value_enum, default_value_t = Units::Si)]
    pub units: Units,
    /// Write the arrays here (NumPy .npz).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write them as a long table here (Parquet; FILE must end in .parquet).
    #[arg(long, value_name = "FILE")]
    pub parquet: Option<PathBuf>,
    /// Times per run at which the relative speed of all pairs is sampled, ≥ 1.
    #[arg(long, value_name = "N", default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    pub speed_samples: u32,
    /// Pairs drawn per pair of classes at each of those times, ≥ 1.
    #[arg(long, value_name = "P", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    pub speed_pairs: u32,
    /// Override a scenario field: PATH=VALUE (repeatable), as `agglo run --set`.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// No line per run.
    #[arg(long, short)]
    pub quiet: bool,
}

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
    let grid = MassGrid::parse(&args.bins, scenario.material.rho)?;
    let window = window(&args)?;
    let sampling = Sampling {
        times: args.speed_samples,
        pairs: args.speed_pairs,
    };
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
