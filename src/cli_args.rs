//! The command line's definitions (clap): every subcommand and flag of `agglo`, and
//! nothing that runs them (the binary's `src/cli.rs` dispatches to the library).
//!
//! In the library rather than the binary so that tests parse command lines with the real
//! parser (`Cli::try_parse_from`: the guides' examples are checked that way,
//! tests/interfaces/docs.rs) and so that the shell completions and the man page are generated
//! from it (`agglo completions`, `agglo man`).

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use crate::live::DEFAULT_ADDR;

/// Particle agglomeration in thermochemically reacting granular flows.
#[derive(Parser, Debug)]
#[command(name = "agglo", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    /// The subcommand.
    pub command: Command,
}

#[derive(Subcommand, Debug)]
/// The subcommands of `agglo`.
pub enum Command {
    /// Run a scenario to its end time.
    Run(Box<RunArgs>),
    /// Check a scenario (or inverse-problem) file and print what it describes, with the
    /// pipeline it will run and why the other systems are left out.
    Validate {
        /// Scenario file (JSON).
        scenario: PathBuf,
        /// Override a scenario field before checking it, as `agglo run --set` does:
        /// PATH=VALUE (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
    },
    /// Print the JSON Schema of the scenario format (or, with --outputs, every output's
    /// columns and summary keys with their units).
    Schema {
        /// Print the outputs' columns and keys (docs/outputs.md) instead.
        #[arg(long)]
        outputs: bool,
    },
    /// Summarise an MCAP recording: channels, counts, duration, scenario, final statistics.
    Inspect {
        /// Recording (MCAP) written by `agglo run --recording`.
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write a Foxglove layout fitted to a recording's box (camera distance and near plane
    /// from its half-width D).
    Layout {
        /// Recording (MCAP) written by `agglo run --recording`.
        file: PathBuf,
        /// Where to write the layout [default: next to the recording, RUN.layout.json].
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
    /// Numerical studies: speed against accuracy, and where methods fail.
    #[command(subcommand)]
    Study(StudyCommand),
    /// Solve an inverse problem: genetic algorithm over ensemble-averaged costs (docs/model.md §12).
    Optimize(OptimizeArgs),
    /// Scan one scenario field of an inverse problem's base scenario (ensemble cost per point).
    Scan(ScanArgs),
    /// Measure collision kernels and outcome probabilities on a coagulation code's mass
    /// grid (DustPy, OpenFOAM population balance, explicit edges) over an ensemble of
    /// seeds; write them as .npz (and a long Parquet table). Arrays and units:
    /// docs/outputs.md, "agglo kernel"; method: docs/kernel.md.
    Kernel(Box<KernelArgs>),
    /// Print a shell completion script: `agglo completions bash > ~/.local/share/bash-completion/completions/agglo`
    /// (zsh: into a directory of $fpath as `_agglo`; fish: ~/.config/fish/completions/agglo.fish).
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the man page (roff), generated from these definitions: `agglo man > agglo.1`,
    /// then `man ./agglo.1`.
    Man,
}

/// The command-line parser as clap builds it (for completions, the man page, tests).
pub fn command() -> clap::Command {
    <Cli as clap::CommandFactory>::command()
}

/// The completion script of `shell` for `agglo`.
pub fn completions(shell: clap_complete::Shell) -> Vec<u8> {
    let mut out = Vec::new();
    clap_complete::generate(shell, &mut command(), "agglo", &mut out);
    out
}

/// The man page of `agglo` (roff): the top-level page, listing the subcommands with
/// their descriptions, followed by one section per subcommand with its flags.
pub fn man_page() -> std::io::Result<Vec<u8>> {
    let cmd = command();
    let mut out = Vec::new();
    clap_mangen::Man::new(cmd.clone()).render(&mut out)?;
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        let name = format!("agglo {}", sub.get_name());
        let sub = sub.clone().display_name(name.clone()).bin_name(name);
        // The subcommand's options as a section of the same page.
        let man = clap_mangen::Man::new(sub.clone());
        out.extend_from_slice(
            format!(".SH \"AGGLO {}\"\n", sub.get_name().to_uppercase()).as_bytes(),
        );
        man.render_description_section(&mut out)?;
        man.render_synopsis_section(&mut out)?;
        man.render_options_section(&mut out)?;
        if sub.has_subcommands() {
            man.render_subcommands_section(&mut out)?;
        }
    }
    Ok(out)
}

#[derive(Subcommand, Debug)]
/// The studies of `agglo study`.
pub enum StudyCommand {
    /// Run one scene under a ladder of numerical settings; write accuracy.csv and charts.
    Accuracy {
        /// Scenario file (JSON).
        scenario: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Timed repeats per setting (median wall time), ≥ 1.
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
        repeats: u32,
        /// Seeds of the reference ensemble (noise band), ≥ 1.
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
        seeds: u32,
        /// A published b_f/b0 to draw on the growth chart (e.g. 3.23 for P04).
        #[arg(long)]
        target_growth: Option<f64>,
        /// Runs at once (1: timings do not share cores; 0 = one per core).
        #[arg(long, value_parser = threads_arg, default_value_t = 1)]
        threads: usize,
    },
    /// Stability maps of the pair solve and cooling, and missed collisions against step size.
    Stability {
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Scene of the step-size study (default: the built-in study scene).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Seeds of the step-size study, ≥ 1.
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
        seeds: u32,
    },
    /// Run one scene under each alternative reading of the papers over an ensemble of seeds;
    /// write readings.csv, runs.csv, readings.md and a chart.
    Readings(crate::study::readings::ReadingsArgs),
}

#[derive(clap::Args, Debug)]
/// The arguments of `agglo run`.
pub struct RunArgs {
    /// Scenario file (JSON).
    #[arg(required_unless_present_any = ["from", "resume"], conflicts_with_all = ["from", "resume"])]
    pub scenario: Option<PathBuf>,
    /// Continue a stopped or killed run from the last checkpoint in its restart file
    /// (written by a scene with `output.restart`; given the run's recording, the restart
    /// file beside it): the final state and summary counters are those of the
    /// uninterrupted run. The scenario is the one embedded in the file;
    /// its output paths are ignored (pass --recording / --final-state / --summary / tables);
    /// checkpoints go on being written to the same file (or --restart).
    #[arg(long, value_name = "RESTART", conflicts_with_all = ["from", "set", "seed"])]
    pub resume: Option<PathBuf>,
    /// Write restart checkpoints to this file (overrides `output.restart.path`; the
    /// interval is `output.restart.every`, e.g. `--set output.restart.every=1e-3`).
    #[arg(long, value_name = "FILE")]
    pub restart: Option<PathBuf>,
    /// Re-run the scenario embedded in this recording (MCAP); the output paths it names are
    /// ignored (pass --recording / --final-state / --summary).
    #[arg(long, value_name = "RECORDING")]
    pub from: Option<PathBuf>,
    /// Record the run to this MCAP file for Foxglove (overrides `output.recording.path`); a
    /// Foxglove layout fitted to the box is written beside it (RUN.layout.json).
    /// `--out` is its old name, still accepted.
    #[arg(long, value_name = "FILE", visible_alias = "out")]
    pub recording: Option<PathBuf>,
    /// Override the scenario's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the observables and counters as JSON here.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Write one CSV row per body at the end here.
    #[arg(long)]
    pub final_state: Option<PathBuf>,
    /// Time series, size distribution and snapshots, and when they are sampled.
    #[command(flatten)]
    pub tables: crate::output::TableArgs,
    /// The per-step tables (src/output/step_tables/).
    #[command(flatten)]
    pub step_tables: crate::output::step_tables::StepTableArgs,
    /// Override a scenario field: PATH=VALUE, VALUE parsed as JSON (else a string), e.g.
    /// `--set time.end=0.01 --set cloud.size_ratio=0.3` (repeatable; checked as the file is).
    /// A field inside a section the scenario leaves out creates the section
    /// (`--set output.restart.every=1e-3`); `null` removes an optional field (`--set
    /// cloud.radius=1e-4 --set cloud.size_ratio=null`).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// No progress bar and no end-of-run report (warnings still go to stderr).
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    /// Serving the run live (`--live`).
    pub live: LiveArgs,
}

#[derive(clap::Args, Debug)]
/// The arguments of `agglo optimize`.
pub struct OptimizeArgs {
    /// Inverse-problem file (JSON).
    pub problem: PathBuf,
    /// Output directory (generations.csv, best.json, best_scenario.json, charts, checkpoint.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Continue the run checkpointed in --out.
    #[arg(long)]
    pub resume: bool,
    /// Worker threads (default: one per core; under mpirun, one per rank).
    #[arg(long, value_parser = threads_arg, default_value_t = 0)]
    pub threads: usize,
    /// No progress display and no report.
    #[arg(long, short)]
    pub quiet: bool,
    /// Stop after this many generations (the run can be continued with --resume).
    #[arg(long, hide = true)]
    pub stop_after: Option<usize>,
    /// Write the compute time of every sample here (CSV: generation, string, sample,
    /// seconds, used): where the time goes, and what a cluster would make of it.
    #[arg(long, value_name = "FILE")]
    pub sample_times: Option<PathBuf>,
    #[command(flatten)]
    /// Serving the GA live (`--live`).
    pub live: LiveInverseArgs,
}

#[derive(clap::Args, Debug)]
/// The arguments of `agglo scan`.
pub struct ScanArgs {
    /// Inverse-problem file (JSON): its base scenario, end-time rule, cost and ensemble rule are used.
    pub problem: PathBuf,
    /// Scenario field to scan (dotted path, e.g. `box.half_width`).
    #[arg(long)]
    pub gene: String,
    #[arg(long)]
    /// The scan's first value.
    pub from: f64,
    #[arg(long)]
    /// The scan's last value.
    pub to: f64,
    /// Number of points (≥ 2).
    #[arg(long, default_value_t = 9)]
    pub points: usize,
    /// Space the points logarithmically.
    #[arg(long)]
    pub log: bool,
    /// Output directory (scan.csv, scan.png/svg).
    #[arg(long)]
    pub out: PathBuf,
    /// Worker threads (default: one per core; under mpirun, one per rank).
    #[arg(long, value_parser = threads_arg, default_value_t = 0)]
    pub threads: usize,
    #[arg(long, short)]
    /// Print no progress lines.
    pub quiet: bool,
}

/// The live flags of `agglo run`.
#[derive(clap::Args, Debug, Clone)]
pub struct LiveArgs {
    /// Serve the run live over the Foxglove WebSocket protocol on ADDR (HOST:PORT,
    /// default 127.0.0.1:8765): in Foxglove, open a connection → Foxglove WebSocket →
    /// ws://ADDR. Same channels as a recording (--recording); the results are unchanged.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub live: Option<String>,
    /// With --live: hold the start until a client subscribes.
    #[arg(long, requires = "live")]
    pub live_wait: bool,
    /// With --live: frames per second of wall-clock time, at most (0.001 ≤ HZ ≤ 1000).
    #[arg(long, value_name = "HZ", default_value_t = 10.0, requires = "live")]
    pub live_rate: f64,
    /// With --live: bodies drawn per frame, about, at most (a deterministic subset by
    /// id when the cloud is larger; /stats always covers every body).
    #[arg(long, value_name = "N", default_value_t = 10_000, requires = "live")]
    pub live_bodies: usize,
    /// With --live: when the run ends with a client connected, keep serving its final
    /// state until the client disconnects or SECONDS pass (0 ≤ SECONDS ≤ 86400; 0: close
    /// at once). Every output is written before the wait.
    #[arg(long, value_name = "SECONDS", default_value_t = crate::live::DEFAULT_LINGER_SECONDS, requires = "live")]
    pub live_linger: f64,
    /// With --live: run no faster than RATE simulated seconds per wall-clock second, so
    /// that a short run can be watched (e.g. 1e-3 shows T = 0.01 s over 10 s). Only
    /// waits: every output is the same as without it.
    #[arg(long, value_name = "RATE", requires = "live")]
    pub live_pace: Option<f64>,
}

/// The live flags of `agglo optimize`.
#[derive(clap::Args, Debug, Clone)]
pub struct LiveInverseArgs {
    /// Serve each generation live over the Foxglove WebSocket protocol on ADDR
    /// (HOST:PORT, default 127.0.0.1:8765); the layout is written as DIR/live.layout.json.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub live: Option<String>,
    /// With --live: hold the start until a client subscribes.
    #[arg(long, requires = "live")]
    pub live_wait: bool,
}

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
                                   class k holds sim.grid.m[k]; mmin `primary`: the
                                   scenario's primary mass (the file's mass_centres[0])
  openfoam:d0,d1,...               OpenFOAM size groups' diameters dSph in m, increasing
Every body must lie inside the grid, at the start and throughout (else the run stops,
naming the body). Rates follow K n_i n_j (i != j) and 1/2 K n_i^2 (i = j); K = counts/exposure.
Example:
  agglo kernel scenarios/ballistic_aggregation.json --bins dustpy:1e-5,1,7 \\
      --seeds 8 --window 0:0.05 --units cgs --out kernel.npz --parquet kernel.parquet")]
/// The arguments of `agglo kernel`.
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
    #[arg(long, value_parser = threads_arg, default_value_t = 0)]
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
    /// Times per run at which the relative speed of all pairs is sampled, 1 to 1000000.
    #[arg(long, value_name = "N", default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    pub speed_samples: u32,
    /// Pairs drawn per pair of classes at each of those times, 1 to 4096 (at 4096 every
    /// pair of the 64 bodies drawn per class is taken once).
    #[arg(long, value_name = "P", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    pub speed_pairs: u32,
    /// Override a scenario field: PATH=VALUE (repeatable), as `agglo run --set`.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// No line per run.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `--threads N`: a count of worker threads, 0 ≤ N ≤ [`crate::farm::MAX_THREADS`].
pub fn threads_arg(text: &str) -> Result<usize, String> {
    let n: usize = text.parse().map_err(|_| {
        format!(
            "allowed a whole number 0 ≤ threads ≤ {} (got {text})",
            crate::farm::MAX_THREADS
        )
    })?;
    crate::farm::check_threads(n)
}
