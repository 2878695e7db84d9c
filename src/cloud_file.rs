//! `cloud.from_file`: explicit bodies read from a table with the columns of
//! `--final-state` / `--snapshots` (CSV, or Parquet when the name ends in `.parquet`),
//! so a run can start from another's end state, or from bodies a script wrote.
//!
//! Columns: `x`, `y`, `z` [m] required; `vx`, `vy`, `vz` [m/s] (all three or none:
//! without them velocities are drawn from the cloud's distribution), `id`, `mass` [kg],
//! `radius` [m], `temperature` [K], `primaries` optional; `hardness` is accepted and
//! ignored (it follows θ); with a `t` column only the rows of the largest t are taken
//! (the last sample of `--snapshots`). Any other column is refused, to catch a typo, and
//! so is a column named twice. Ids are labels, any u64 read exactly (docs/model.md §2).
//! A CSV file is read as CSV (quoted fields; pandas' unnamed index column is left out).

use std::path::Path;

use anyhow::{Context, bail};

use crate::cloud::PlacedBody;
use crate::output::snapshots::SNAPSHOT_COLUMNS;
use crate::output::table::read_table;

/// The bodies of the table at `path`, in its row order.
pub fn load_bodies(path: &Path) -> anyhow::Result<Vec<PlacedBody>> {
    let table = read_table(path)?;
    // A body table has the columns of --snapshots (t first) and --final-state.
    let known = || SNAPSHOT_COLUMNS.iter().map(|c| c.name);
    for name in &table.names {
        // pandas' `to_parquet(index=True)` (its default for a non-range index) stores the
        // index as `__index_level_0__`: not a column of the bodies, and no reason to refuse.
        if name.starts_with("__index_level_") {
            continue;
        }
        if !known().any(|k| k == name) {
            bail!(
                "{}: unknown column `{name}` (allowed: {})",
                path.display(),
                known().collect::<Vec<_>>().join(", ")
            );
        }
    }
    let has = |name: &str| table.column(name).is_some();
    let floats = |name: &str| -> anyhow::Result<Option<Vec<f64>>> {
        has(name)
            .then(|| table.floats(name))
            .transpose()
            .with_context(|| format!("{}", path.display()))
    };
    let [x, y, z] = ["x", "y", "z"].map(&floats);
    let (x, y, z) = match (x?, y?, z?) {
        (Some(x), Some(y), Some(z)) => (x, y, z),
        _ => bail!("{}: columns x, y and z are required", path.display()),
    };
    let velocity = match (floats("vx")?, floats("vy")?, floats("vz")?) {
        (Some(vx), Some(vy), Some(vz)) => Some((vx, vy, vz)),
        (None, None, None) => None,
        _ => bail!("{}: give all of vx, vy, vz or none", path.display()),
    };
    let ids = has("id")
        .then(|| table.ids("id"))
        .transpose()
        .with_context(|| format!("{}", path.display()))?;
    let (mass, radius, temperature, primaries) = (
        floats("mass")?,
        floats("radius")?,
        floats("temperature")?,
        floats("primaries")?,
    );
    // The rows of the last sample, when the table holds several.
    let rows: Vec<usize> = match floats("t")? {
        Some(t) => {
            // A time that is not a number belongs to no sample: refused by its row (it
            // was dropped without a word, with the bodies of that row).
            if let Some(k) = t.iter().position(|t| !t.is_finite()) {
                bail!(
                    "{}: row {} (data row, from 1): t = {}: allowed a finite time [s]; the \
                     rows of the last t are the bodies",
                    path.display(),
                    k + 1,
                    t[k]
                );
            }
            let last = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (0..t.len()).filter(|&k| t[k] == last).collect()
        }
        None => (0..x.len()).collect(),
    };
    if rows.is_empty() {
        bail!("{}: no bodies (the table has no rows)", path.display());
    }
    rows.into_iter()
        .map(|k| {
            let id = ids.as_ref().map(|ids| ids[k]);
            Ok(PlacedBody {
                position: [x[k], y[k], z[k]],
                velocity: velocity.as_ref().map(|(vx, vy, vz)| [vx[k], vy[k], vz[k]]),
                primaries: primaries.as_ref().map_or(1.0, |p| p[k]),
                id,
                temperature: temperature.as_ref().map(|v| v[k]),
                mass: mass.as_ref().map(|v| v[k]),
                radius: radius.as_ref().map(|v| v[k]),
            })
        })
        .collect()
}
