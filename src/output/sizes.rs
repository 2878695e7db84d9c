//! `--sizes`: the size distribution n_k(t) at each sample, in long format (one row per
//! sample and non-empty bin): counts by the number of primaries a body holds (exact for
//! a start of equal primaries without fragmentation), or by log-spaced radius bins.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::components::BodyState;

use super::table::{Cell, Column, float, int, text};

/// Radius bins per decade (bin j holds b0·10^(j/10) ≤ b < b0·10^((j+1)/10)).
pub const RADIUS_BINS_PER_DECADE: f64 = 10.0;

/// The columns of the size distribution, in order.
pub const SIZES_COLUMNS: &[Column] = &[
    float("t", "s", "simulated time of the sample"),
    text(
        "by",
        "what the bins count by: `primaries` (monomer count k) or `radius` (log-spaced radius bins)",
    ),
    int(
        "bin",
        "-",
        "by primaries: k, the primaries in a body; by radius: j, with lower = b0·10^(j/10)",
    ),
    float(
        "lower",
        "- or m",
        "lower edge of the bin: k (primaries, inclusive) or b0·10^(j/10) [m] (radius, inclusive)",
    ),
    float(
        "upper",
        "- or m",
        "upper edge: k (primaries, the same: bins are exact counts) or b0·10^((j+1)/10) [m] (radius, exclusive)",
    ),
    int(
        "count",
        "-",
        "bodies in the bin (only non-empty bins are written)",
    ),
];

/// How `--sizes` bins the bodies (`output.size_bins`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SizeBins {
    /// `primaries` when every initial body holds a whole number of primaries and the run
    /// cannot fragment (then every body always does); else `radius`.
    #[default]
    Auto,
    /// By the number of primaries k in a body (rounded to the nearest whole number).
    Primaries,
    /// By log-spaced radius bins, 10 per decade, anchored at b0.
    Radius,
}

impl SizeBins {
    /// The binning `Auto` stands for, given the initial bodies and whether the run can
    /// fragment; other values as they are.
    pub fn resolve(self, initial: &[BodyState], can_fragment: bool) -> SizeBins {
        match self {
            SizeBins::Auto => {
                let whole = initial.iter().all(|b| b.primaries.fract() == 0.0);
                if whole && !can_fragment {
                    SizeBins::Primaries
                } else {
                    SizeBins::Radius
                }
            }
            other => other,
        }
    }
}

/// The rows of one sample at time `t` [s]: (bin, lower, upper, count) for every
/// non-empty bin, in increasing order; `b0` [m] anchors the radius bins.
pub fn size_rows(bins: SizeBins, bodies: &[BodyState], b0: f64) -> Vec<(i64, f64, f64, u64)> {
    let mut counts: BTreeMap<i64, u64> = BTreeMap::new();
    let by_primaries = bins == SizeBins::Primaries;
    for b in bodies {
        let bin = if by_primaries {
            b.primaries.round() as i64
        } else {
            // 1e-9 of a bin of slack: a primary whose radius is b0 to rounding is in bin 0.
            (RADIUS_BINS_PER_DECADE * (b.radius / b0).log10() + 1e-9).floor() as i64
        };
        *counts.entry(bin).or_default() += 1;
    }
    counts
        .into_iter()
        .map(|(bin, count)| {
            if by_primaries {
                (bin, bin as f64, bin as f64, count)
            } else {
                let edge = |j: i64| b0 * 10f64.powf(j as f64 / RADIUS_BINS_PER_DECADE);
                (bin, edge(bin), edge(bin + 1), count)
            }
        })
        .collect()
}

/// Label of the `by` column.
pub fn label(bins: SizeBins) -> &'static str {
    match bins {
        SizeBins::Primaries => "primaries",
        _ => "radius",
    }
}

/// A row of the table.
pub fn cells(t: f64, by: &'static str, row: (i64, f64, f64, u64)) -> [Cell<'static>; 6] {
    [
        Cell::F(t),
        Cell::S(by),
        Cell::I(row.0),
        Cell::F(row.1),
        Cell::F(row.2),
        Cell::I(row.3 as i64),
    ]
}
