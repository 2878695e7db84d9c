//! The lifted box's pair structure (issue 37 item 4; docs/model.md §15).
//!
//! Random sequential addition (lift.rs) does not leave the equilibrium hard-sphere
//! fluid's pair structure: at φ = 0.26 its contact value, and with it the first-instant
//! impact rate, is 0.898 ± 0.004 of Carnahan–Starling's (docs/coupling.md).
//! A few sweeps of hard-core Metropolis displacement moves relax the packing toward the
//! equilibrium fluid (every non-overlapping configuration is equally likely, which these
//! moves sample), so that the box's first impacts are the flow's, not the placement's.
//!
//! Each sweep tries one move per body, in body order: a displacement drawn uniformly in a
//! cube of half-width [`STEP`] × the body's radius, accepted when the body overlaps no
//! other (periodic images included). Neighbours come from a cell grid at least one
//! largest diameter wide, so a sweep is O(N).

use crate::cloud::PlacedBody;

use super::stream::Stream;

/// Sweeps given to a box lifted at volume fraction ≥ [`EQUILIBRATE_FROM`] over a short
/// step (lift.rs, `needs_sweeps`; docs/coupling.md gives the contact value against
/// sweeps).
pub const SWEEPS: u32 = 20;

/// Below this volume fraction a lifted box keeps its random sequential packing: its
/// contact value is within about 1 % of the equilibrium fluid's (docs/coupling.md), and
/// the sweeps would cost more than they change.
pub const EQUILIBRATE_FROM: f64 = 0.1;

/// A move's half-width in units of the moving body's radius (a step of 0.3 radii
/// relaxed the contact value about half as fast per sweep).
pub const STEP: f64 = 1.0;

/// Cell list over the periodic cube [−side/2, side/2)³.
struct Cells {
    side: f64,
    per_side: usize,
    members: Vec<Vec<usize>>,
}

impl Cells {
    fn new(side: f64, width: f64, bodies: &[PlacedBody]) -> Self {
        let per_side = ((side / width).floor() as usize).clamp(1, 64);
        let mut cells = Self {
            side,
            per_side,
            members: vec![Vec::new(); per_side.pow(3)],
        };
        for (i, b) in bodies.iter().enumerate() {
            let c = cells.index(b.position);
            cells.members[c].push(i);
        }
        cells
    }

    fn coordinates(&self, p: [f64; 3]) -> [usize; 3] {
        p.map(|x| {
            let u = (x / self.side + 0.5) * self.per_side as f64;
            // `as` truncates toward 0 and saturates: the floor for u ≥ 0, and 0 below
            // (as `floor().max(0.0)`, without a call to floor).
            (u as usize).min(self.per_side - 1)
        })
    }

    fn index(&self, p: [f64; 3]) -> usize {
        self.flat(self.coordinates(p))
    }

    /// Per axis, true when the cells around cell `c` along it do not cross the periodic
    /// boundary and there are at least five a side: a body in them is then less than two
    /// cell widths ≤ 0.4 side away from a point of cell `c` along that axis (plus
    /// roundings of an ulp's order in the cell a position is given), so its minimum image
    /// is the plain difference d — `nearest_whole(d / side)` is exactly 0 for
    /// |d / side| < 0.5, and d − side·0 is d, bit for bit.
    fn inside(&self, c: [usize; 3]) -> [bool; 3] {
        let n = self.per_side;
        c.map(|c| n >= 5 && c >= 1 && c + 2 <= n)
    }

    /// The cells around cell `c` (each once, also when there are fewer than three a
    /// side): the first of the returned count. In no particular order: a move is free
    /// when no body of any of them overlaps, whatever the order they are looked at in.
    fn around(&self, c: [usize; 3]) -> ([usize; 27], usize) {
        let n = self.per_side;
        // Per axis the neighbour indices, c − 1, c, c + 1 wrapped (by comparison: a
        // remainder per axis was a quarter of the sweeps' instructions), or every index,
        // each times the axis's stride.
        let axis = |i: usize, stride: usize| -> ([usize; 3], usize) {
            if n >= 3 {
                let below = if i == 0 { n - 1 } else { i - 1 };
                let above = if i + 1 == n { 0 } else { i + 1 };
                ([below * stride, i * stride, above * stride], 3)
            } else {
                ([0, stride, 2 * stride], n)
            }
        };
        let ((xs, nx), (ys, ny), (zs, nz)) = (axis(c[0], n * n), axis(c[1], n), axis(c[2], 1));
        let mut out = [0usize; 27];
        let mut count = 0;
        for &x in &xs[..nx] {
            for &y in &ys[..ny] {
                for &z in &zs[..nz] {
                    out[count] = x + y + z;
                    count += 1;
                }
            }
        }
        (out, count)
    }

    /// The index of cell `c`.
    fn flat(&self, c: [usize; 3]) -> usize {
        (c[0] * self.per_side + c[1]) * self.per_side + c[2]
    }
}

/// `x.round()` (half away from zero), without a call to round where |x| < 1.5, as a
/// minimum image's d / side always is: at most one box side apart. The one difference,
/// +0 for round's −0 on (−0.5, 0], changes d − side·r only for d = −0 (−0 for +0) and
/// its square, which is all the sweeps use, never. With the
/// cells' truncation for floor, the sweeps of 8 re-lifted P04 held states take 0.80 of
/// the instructions they took with the calls (callgrind, dev profile: 759 → 608 M), and
/// the boxes are the same bit for bit.
#[doc(hidden)]
pub fn nearest_whole(x: f64) -> f64 {
    if x.abs() >= 1.5 || x.is_nan() {
        x.round()
    } else if x >= 0.5 {
        1.0
    } else if x <= -0.5 {
        -1.0
    } else {
        0.0
    }
}

/// The radius [m] of each body (as lifting sized it).
fn radii(bodies: &[PlacedBody], radius_of: impl Fn(&PlacedBody) -> f64) -> Vec<f64> {
    bodies.iter().map(radius_of).collect()
}

/// Give `bodies` (no overlaps, inside the periodic cube of side `side` [m]) `sweeps`
/// Metropolis sweeps; `radius_of` gives a body's radius. Returns the fraction of moves
/// accepted.
pub(crate) fn equilibrate(
    bodies: &mut [PlacedBody],
    side: f64,
    radius_of: impl Fn(&PlacedBody) -> f64,
    sweeps: u32,
    rng: &mut Stream,
) -> f64 {
    if bodies.len() < 2 || sweeps == 0 {
        return 0.0;
    }
    let radius = radii(bodies, radius_of);
    let largest = radius.iter().cloned().fold(0.0, f64::max);
    let mut cells = Cells::new(side, 2.0 * largest, bodies);
    let half = 0.5 * side;
    let wrap = |x: f64| x - side * ((x + half) / side).floor();
    let (mut tried, mut accepted) = (0u64, 0u64);
    // The positions apart from the rest of each body, side by side in memory.
    let mut positions: Vec<[f64; 3]> = bodies.iter().map(|b| b.position).collect();
    for _ in 0..sweeps {
        for i in 0..bodies.len() {
            let old = positions[i];
            let d = STEP * radius[i];
            let new = [0, 1, 2].map(|x| wrap(old[x] + d * (2.0 * rng.uniform() - 1.0)));
            tried += 1;
            let at = cells.coordinates(new);
            let (near, count) = cells.around(at);
            let inside = cells.inside(at);
            let free = near[..count].iter().all(|&c| {
                cells.members[c].iter().all(|&j| {
                    if j == i {
                        return true;
                    }
                    let q = positions[j];
                    let mut d2 = 0.0;
                    for x in 0..3 {
                        let d = new[x] - q[x];
                        // Along an axis the neighbour cells do not cross the boundary
                        // on, the image is d itself: the same bits as through
                        // nearest_whole (`Cells::inside`), without a division.
                        let d = if inside[x] {
                            d
                        } else {
                            d - side * nearest_whole(d / side)
                        };
                        d2 += d * d;
                    }
                    let reach = radius[i] + radius[j];
                    d2 >= reach * reach
                })
            });
            if !free {
                continue;
            }
            accepted += 1;
            let (from, to) = (cells.index(old), cells.flat(at));
            if from != to {
                let at = cells.members[from].iter().position(|&j| j == i);
                if let Some(at) = at {
                    cells.members[from].swap_remove(at);
                }
                cells.members[to].push(i);
            }
            positions[i] = new;
        }
    }
    for (body, p) in bodies.iter_mut().zip(positions) {
        body.position = p;
    }
    accepted as f64 / tried as f64
}
