//! Plain-file outputs of a run: the final state as CSV (one row per body, floats
//! printed with Rust's shortest round-trip formatting so they parse back exactly)
//! and the summary as JSON.

use std::io::Write;
use std::path::Path;

use anyhow::Context;

use crate::components::BodyState;
use crate::observables::Summary;
use crate::record::Recording;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Header of the final-state CSV.
pub const FINAL_STATE_HEADER: &str = "id,x,y,z,vx,vy,vz,mass,radius,temperature,hardness,primaries";

/// Write one row per body (sorted by id) to `path`.
pub fn write_final_state(path: &Path, bodies: &[BodyState]) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(out, "{FINAL_STATE_HEADER}")?;
    for b in bodies {
        // `{:?}` on f64 is the shortest representation that round-trips exactly.
        writeln!(
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
    /// Record the run to this MCAP file (same as `--out`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mcap: Option<String>,
    /// Recording options.
    #[serde(default)]
    pub recording: Recording,
}
