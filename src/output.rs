//! Plain-file outputs of a run: the final state as CSV (one row per body, floats
//! printed with Rust's shortest round-trip formatting so they parse back exactly)
//! and the summary as JSON.

use std::io::Write;
use std::path::Path;

use anyhow::Context;

use crate::components::BodyState;
use crate::observables::Summary;

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
