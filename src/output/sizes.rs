//! `--sizes`: the size distribution n_k(t) at each sample, in long format (one row per
//! sample and non-empty bin): counts by the number of primaries a body holds (exact for
//! a start of equal primaries without fragmentation), or by log-spaced radius bins.
//! In a rigid scene (docs/model.md §6.1) the bins count aggregates, not primaries, and
//! each row also gives its aggregates' mean radius of gyration and filling factor.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::aggregates::AggregateShape;
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

/// The two columns a rigid scene's size table adds after [`SIZES_COLUMNS`].
pub const RIGID_SIZES_COLUMNS: &[Column] = &[
    float(
        "radius_of_gyration",
        "m",
        "rigid scenes: mean radius of gyration of the bin's aggregates",
    ),
    float(
        "filling_factor",
        "-",
        "rigid scenes: mean filling factor Σ a³ / R_c³ (R_c = √(5/3) R_g) of the bin's aggregates",
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
            radius_bin(b.radius, b0)
        };
        *counts.entry(bin).or_default() += 1;
    }
    counts
        .into_iter()
        .map(|(bin, count)| {
            let (lower, upper) = edges(by_primaries, bin, b0);
            (bin, lower, upper, count)
        })
        .collect()
}

/// The rows of one sample of a rigid scene: (bin, lower, upper, count, mean R_g [m],
/// mean filling factor) for every non-empty bin of aggregates, in increasing order. By
/// primaries an aggregate's bin is its k; by radius, that of the sphere of its volume.
pub fn aggregate_size_rows(
    bins: SizeBins,
    shapes: &[AggregateShape],
    b0: f64,
) -> Vec<(i64, f64, f64, u64, f64, f64)> {
    // Per bin: count, Σ R_g, Σ φ (summed in id order: the shapes come sorted by id).
    let mut sums: BTreeMap<i64, (u64, f64, f64)> = BTreeMap::new();
    let by_primaries = bins == SizeBins::Primaries;
    for s in shapes {
        let bin = if by_primaries {
            s.primaries as i64
        } else {
            radius_bin(s.volume_radius, b0)
        };
        let sum = sums.entry(bin).or_default();
        sum.0 += 1;
        sum.1 += s.radius_of_gyration;
        sum.2 += s.filling_factor;
    }
    sums.into_iter()
        .map(|(bin, (count, r_g, phi))| {
            let (lower, upper) = edges(by_primaries, bin, b0);
            let n = count as f64;
            (bin, lower, upper, count, r_g / n, phi / n)
        })
        .collect()
}

/// A rigid scene's row: [`cells`] and the mean R_g and filling factor.
pub fn aggregate_cells(
    t: f64,
    by: &'static str,
    row: (i64, f64, f64, u64, f64, f64),
) -> [Cell<'static>; 8] {
    let [a, b, c, d, e, f] = cells(t, by, (row.0, row.1, row.2, row.3));
    [a, b, c, d, e, f, Cell::F(row.4), Cell::F(row.5)]
}

/// The radius bin j of a radius `b` [m]: b0·10^(j/10) ≤ b < b0·10^((j+1)/10).
fn radius_bin(b: f64, b0: f64) -> i64 {
    // 1e-9 of a bin of slack: a primary whose radius is b0 to rounding is in bin 0.
    (RADIUS_BINS_PER_DECADE * (b / b0).log10() + 1e-9).floor() as i64
}

/// The (lower, upper) edges of bin `bin`.
fn edges(by_primaries: bool, bin: i64, b0: f64) -> (f64, f64) {
    if by_primaries {
        (bin as f64, bin as f64)
    } else {
        let edge = |j: i64| b0 * 10f64.powf(j as f64 / RADIUS_BINS_PER_DECADE);
        (edge(bin), edge(bin + 1))
    }
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
