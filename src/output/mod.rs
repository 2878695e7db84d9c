//! Plain-file outputs of a run and the `output` section that names them: the final
//! state as CSV (one row per body, floats printed with Rust's shortest round-trip
//! formatting so they parse back exactly), the summary as JSON, and the tables sampled
//! while the run runs — time series, size distribution, snapshots, collision log ([`run`]; CSV, or
//! Parquet when the path ends in `.parquet`, [`table`]). Every column and summary key,
//! with its unit: [`schema`], docs/outputs.md.

pub mod collisions;
#[doc(hidden)]
pub mod column;
pub mod offload;
#[doc(hidden)]
pub mod parquet_sink;
pub mod run_tables;
/// The old name of [`run_tables`] ("run" named five things: issue 40).
#[deprecated(note = "renamed agglo::output::run_tables")]
pub mod run {
    pub use super::run_tables::*;
}
pub mod sampling;
pub mod schema;
pub mod series;
pub mod sizes;
pub mod snapshots;
pub mod step_tables;
pub mod table;

use std::io::Write;
use std::path::{Path, PathBuf};

pub use run_tables::{RunTables, TablePaths, TablesReport};
pub use sampling::SampleSchedule;
pub use sizes::SizeBins;

use anyhow::Context;

use crate::carried::CarriedColumns;
use crate::components::BodyState;
use crate::error::ValidationIssue;
use crate::observables::Summary;
use crate::record::Recording;
use agglo_engine::issues::Issues;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Header of the final-state CSV.
pub const FINAL_STATE_HEADER: &str = "id,x,y,z,vx,vy,vz,mass,radius,temperature,hardness,primaries";

/// Write one row per body (sorted by id) to `path`.
pub fn write_final_state(path: &Path, bodies: &[BodyState]) -> anyhow::Result<()> {
    write_final_state_with(path, bodies, &CarriedColumns::default())
}

/// Write one row per body (sorted by id) to `path`, with the quantities extensions
/// carry (engine/carried.rs) as named columns after the built-in ones (an empty field
/// where a body lacks one). `carried` holds the same bodies in the same order, or no
/// columns at all (then the file is exactly [`write_final_state`]'s).
pub fn write_final_state_with(
    path: &Path,
    bodies: &[BodyState],
    carried: &CarriedColumns,
) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    let extra = !carried.names.is_empty();
    if extra {
        anyhow::ensure!(
            carried.rows.len() == bodies.len()
                && carried.rows.iter().zip(bodies).all(|(r, b)| r.0 == b.id),
            "carried columns do not match the bodies"
        );
        writeln!(out, "{FINAL_STATE_HEADER},{}", carried.names.join(","))?;
    } else {
        writeln!(out, "{FINAL_STATE_HEADER}")?;
    }
    for (i, b) in bodies.iter().enumerate() {
        // `{:?}` on f64 is the shortest representation that round-trips exactly.
        write!(
            out,
            "{},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
            b.id,
            b.position.x,
            b.position.y,
            b.position.z,
            b.velocity.x,
            b.velocity.y,
            b.velocity.z,
            b.mass,
            b.radius,
            b.temperature,
            b.hardness,
            b.primaries
        )?;
        if extra {
            for v in &carried.rows[i].1 {
                match v {
                    Some(v) => write!(out, ",{v:?}")?,
                    None => write!(out, ",")?,
                }
            }
        }
        writeln!(out)?;
    }
    out.flush()?;
    Ok(())
}

/// Write the summary as pretty JSON.
pub fn write_summary(path: &Path, summary: &Summary) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(summary)?;
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Output options. Recording options live here too.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Write the summary JSON here (same as `--summary`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub summary: Option<String>,
    /// Write the final state CSV here (same as `--final-state`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_state: Option<String>,
    /// Deprecated: the old name of `output.recording.path`, where a scenario's loading
    /// moves it (so a scenario as recordings embed it never holds it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mcap: Option<String>,
    /// Write the time series here (same as `--series`; Parquet if it ends in `.parquet`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<String>,
    /// Write the size distribution here (same as `--sizes`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sizes: Option<String>,
    /// Write per-body snapshots here (same as `--snapshots`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snapshots: Option<String>,
    /// Write one row per impact here (same as `--collisions`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collisions: Option<String>,
    /// When the series, sizes and snapshots are sampled (default: every T/100; the
    /// `--sample-*` flags override).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampling: Option<SampleSchedule>,
    /// How `--sizes` bins the bodies.
    #[serde(default, skip_serializing_if = "is_auto")]
    pub size_bins: SizeBins,
    /// Recording options.
    #[serde(default)]
    pub recording: Recording,
    /// Restart checkpoints (`agglo run --resume`); none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restart: Option<crate::restart::RestartSettings>,
}

fn is_auto(bins: &SizeBins) -> bool {
    *bins == SizeBins::Auto
}

impl Output {
    /// Range problems of the `output` section, by full path (checkpoints are counted against the `time` section's step cap).
    pub fn issues(&self, time: &crate::scene::TimeControl) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        let r = &self.recording;
        if let Some(dt) = r.interval {
            v.positive("output.recording.interval", dt);
        }
        v.positive("output.recording.playback_seconds", r.playback_seconds);
        if let Some(restart) = &self.restart {
            v.positive("output.restart.every", restart.every);
            // A checkpoint is taken at a step end, at most one per step (the event core
            // cuts a step to land on each): more checkpoints than the run may take steps
            // would never finish (1e-300 s once wrote a synced file every step).
            v.step_count_fits(
                "output.restart.every",
                "checkpoints T/every",
                time.end,
                restart.every,
                time.max_steps,
            );
        }
        if let Some(schedule) = &self.sampling {
            for (field, allowed, got) in schedule.problems() {
                v.push(&format!("output.sampling.{field}"), allowed, got);
            }
        }
        v.issues
    }

    /// This section with every file path cleared (summary, final state, recording,
    /// tables, checkpoints), keeping what says how the run is sampled and recorded: for
    /// runs that must not write the files a scenario names (an ensemble's, a copy's).
    pub fn without_files(&self) -> Self {
        Self {
            summary: None,
            final_state: None,
            mcap: None,
            series: None,
            sizes: None,
            snapshots: None,
            collisions: None,
            restart: None,
            ..self.clone()
        }
    }
}

/// The flags of `agglo run` that ask for the sampled tables; each overrides its field
/// of the `output` section.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct TableArgs {
    /// Write the time series here, one row per sample (CSV; Parquet if FILE ends in .parquet).
    #[arg(long, value_name = "FILE")]
    pub series: Option<PathBuf>,
    /// Write the size distribution n_k(t) here, long format (t, by, bin, lower, upper, count).
    #[arg(long, value_name = "FILE")]
    pub sizes: Option<PathBuf>,
    /// Write every body at every sample here (t, then the --final-state columns).
    #[arg(long, value_name = "FILE")]
    pub snapshots: Option<PathBuf>,
    /// Write one row per impact here (t, ids, masses, radii, normal and tangential speed,
    /// restitution, heat, outcome).
    #[arg(long, value_name = "FILE")]
    pub collisions: Option<PathBuf>,
    /// Sample every SECONDS of simulated time.
    #[arg(long, value_name = "SECONDS", group = "sample")]
    pub sample_every: Option<f64>,
    /// Sample log-spaced in time, PER_DECADE samples per decade from T/10⁴.
    #[arg(long, value_name = "PER_DECADE", group = "sample")]
    pub sample_log: Option<u32>,
    /// Sample every K steps (on the event core: every K events).
    #[arg(long, value_name = "K", group = "sample")]
    pub sample_steps: Option<u64>,
}

impl TableArgs {
    /// The tables to write: the flags over the scenario's `output` section. A schedule
    /// from the flags is checked as the scenario's is.
    pub fn paths(&self, output: &Output) -> anyhow::Result<TablePaths> {
        let or = |flag: &Option<PathBuf>, field: &Option<String>| {
            flag.clone().or_else(|| field.clone().map(PathBuf::from))
        };
        let flag = match (self.sample_every, self.sample_log, self.sample_steps) {
            (Some(dt), _, _) => Some(SampleSchedule::Interval { dt }),
            (_, Some(per_decade), _) => Some(SampleSchedule::Log {
                first: None,
                per_decade,
            }),
            (_, _, Some(every)) => Some(SampleSchedule::Steps { every }),
            _ => None,
        };
        if let Some(schedule) = &flag
            && let Some((field, allowed, got)) = schedule.problems().first()
        {
            anyhow::bail!("--sample-*: {field}: allowed {allowed} (got {got})");
        }
        Ok(TablePaths {
            series: or(&self.series, &output.series),
            sizes: or(&self.sizes, &output.sizes),
            snapshots: or(&self.snapshots, &output.snapshots),
            collisions: or(&self.collisions, &output.collisions),
            sampling: flag.or(output.sampling),
        })
    }
}
