//! Plain-file outputs of a run: the final state as CSV (one row per body, floats
//! printed with Rust's shortest round-trip formatting so they parse back exactly)
//! and the summary as JSON.

use std::io::Write;
use std::path::Path;

use anyhow::Context;

use crate::carried::CarriedColumns;
use crate::components::BodyState;
use crate::observables::Summary;
use crate::record::Recording;

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
    /// Record the run to this MCAP file (same as `--out`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mcap: Option<String>,
    /// Recording options.
    #[serde(default)]
    pub recording: Recording,
}
