//! `agglo study readings` on the command line: its arguments, `--set`, and the handler.

use super::*;

/// Arguments of `agglo study readings` (kept here so that `src/cli.rs` only dispatches).
#[derive(clap::Args, Debug, Clone)]
pub struct ReadingsArgs {
    /// Scenario file (JSON).
    pub scenario: std::path::PathBuf,
    /// Output directory (not needed with --list).
    #[arg(long, required_unless_present = "list")]
    pub out: Option<std::path::PathBuf>,
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
    #[arg(long, value_parser = crate::cli_args::threads_arg, default_value_t = 0)]
    pub threads: usize,
}

/// `agglo study readings`: run on `workers`, write, and print the table.
pub fn run_cli(args: &ReadingsArgs, workers: &crate::farm::Workers) -> anyhow::Result<()> {
    let mut base = Scenario::load(&args.scenario)
        .map_err(|e| anyhow::anyhow!("loading scenario {}: {e}", args.scenario.display()))?;
    if !args.set.is_empty() {
        base = base.with_settings(&args.set)?;
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
    let out = args
        .out
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("--out: the output directory is required"))?;
    let study = run_readings(&base, &options, workers, |line| eprintln!("{line}"))?;
    write_readings(out, &study)?;
    print!("{}", markdown(&study));
    println!("wrote {}", out.join("readings.csv").display());
    Ok(())
}
