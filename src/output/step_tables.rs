//! Tables written after every step (rather than at the samples of `output.sampling`):
//! each is one file under `step_tables/` holding a [`StepTable`] — its name, flag,
//! columns, what it subscribes and the [`Observer`] it opens — and one line in the
//! registry at the bottom of this file. From that line it is an `agglo run` flag
//! ([`StepTableArgs`]), a name Python's `Simulation.run(tables=…)` takes
//! ([`crate::run::RunPlan::set_table`]), a section of `agglo schema --outputs`
//! (docs/outputs.md) and a path the run checks against its other outputs.

use std::path::{Path, PathBuf};

use crate::observer::Observer;
use crate::scenario::Scenario;
use crate::schedule::{SimBuilder, Simulation};

use super::table::Column;

/// A table written after every step: what it is called, what it holds, and how it is
/// opened.
pub struct StepTable {
    /// The name Python's `run(tables={NAME: path})` takes (snake case).
    pub name: &'static str,
    /// The flag of `agglo run` that writes it, `--` and the name in kebab case.
    pub flag: &'static str,
    /// The flag's help line.
    pub help: &'static str,
    /// What one row is (docs/outputs.md).
    pub rows: &'static str,
    /// The columns, with units (docs/outputs.md).
    pub columns: &'static [Column],
    /// Have the builder collect the messages the table reads, before the scene is built.
    pub subscribe: fn(&mut SimBuilder),
    /// Create the file at the path (CSV, or Parquet for `.parquet`) on the built
    /// simulation.
    pub open: fn(&Path, &Scenario, &Simulation) -> anyhow::Result<Box<dyn Observer>>,
}

impl std::fmt::Debug for StepTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "StepTable({})", self.name)
    }
}

impl StepTable {
    /// The flag without its leading dashes, as clap takes it.
    fn long(&self) -> &'static str {
        self.flag.trim_start_matches('-')
    }
}

/// The registered table called `name`.
pub fn find(name: &str) -> Option<&'static StepTable> {
    STEP_TABLES.iter().copied().find(|t| t.name == name)
}

/// The flags of `agglo run` for the registered tables: `--FLAG FILE` each, one added
/// per registry line (clap's `Args`, written by hand since the list is not a struct).
#[derive(Debug, Clone, Default)]
pub struct StepTableArgs(pub Vec<(&'static StepTable, PathBuf)>);

impl clap::FromArgMatches for StepTableArgs {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut args = Self::default();
        args.update_from_arg_matches(matches)?;
        Ok(args)
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        for &table in STEP_TABLES {
            if let Some(path) = matches.get_one::<PathBuf>(table.name) {
                self.0.retain(|(t, _)| t.name != table.name);
                self.0.push((table, path.clone()));
            }
        }
        Ok(())
    }
}

impl clap::Args for StepTableArgs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        STEP_TABLES.iter().fold(cmd, |cmd, table| {
            cmd.arg(
                clap::Arg::new(table.name)
                    .long(table.long())
                    .value_name("FILE")
                    .value_parser(clap::value_parser!(PathBuf))
                    .help(table.help),
            )
        })
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// Declares each table's module (`step_tables/NAME.rs`, holding `pub const TABLE`)
/// and lists it in [`STEP_TABLES`].
macro_rules! registry {
    ($($table:ident),* $(,)?) => {
        $(pub mod $table;)*
        /// Every per-step table, in the order `agglo schema --outputs` lists them.
        pub const STEP_TABLES: &[&StepTable] = &[$(&$table::TABLE),*];
    };
}

// The registry: one line per table, the name of its file in step_tables/ (kept one a
// line by hand, so that adding a table is adding a line).
#[rustfmt::skip]
registry! {
    impact_speeds,
}
