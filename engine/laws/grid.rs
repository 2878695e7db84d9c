//! The periodic neighbour search used by contact detection and step-size
//! selection (docs/model.md §4): every pair whose gap is at most a margin, found in
//! O(N) for any radius distribution.
//!
//! Bodies are binned into a *hierarchy* of periodic cell grids: level k has cells
//! at least h0·2^k wide, h0 = 2 b_min + margin, and a body sits at the lowest level
//! whose cells are at least 2b + margin wide. A body searches its own level (half
//! shell of 14 cells) and every coarser level (27 cells, since those cells are
//! sized for the coarser level's largest body), so an
//! agglomerate that grows to hundreds of grains — even past half the box — is
//! still found by its neighbours, and never by itself. A level with fewer than
//! three cells per side is scanned whole, using the minimum image.
//!
//! Pure data in, pairs out: no ECS types, so it is unit-tested and benchmarked alone.

use glam::DVec3;

/// One pair within the margin: indices into the input arrays, in either order,
/// `d` = r_j − r_i for one periodic image of j (the minimum image, unless the bodies are
/// large enough that several images are in reach: then one entry per image),
/// `gap` = |d| − b_i − b_j.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearPair {
    /// Index of the first body.
    pub i: u32,
    /// Index of the second body.
    pub j: u32,
    /// r_j − r_i for this image [m].
    pub d: DVec3,
    /// |d| − b_i − b_j [m] (negative: overlap).
    pub gap: f64,
}

#[derive(Debug, Default, Clone)]
struct Level {
    /// Cells per side.
    n: usize,
    /// Cell width [m].
    width: f64,
    /// Largest radius in this level [m].
    max_radius: f64,
    /// Body indices in this level, sorted by cell.
    members: Vec<u32>,
    /// cell c holds members[start[c]..start[c + 1]].
    start: Vec<u32>,
    /// Scratch for the counting sort (kept to avoid per-step allocation).
    fill: Vec<u32>,
    sorted: Vec<u32>,
}

/// Reusable scratch space for the search (no per-step allocation once warm).
#[derive(Debug, Default, Clone)]
pub struct NeighbourGrid {
    levels: Vec<Level>,
    level_of: Vec<u8>,
    cell_of: Vec<u32>,
}

impl NeighbourGrid {
    /// All pairs with gap ≤ `margin` in the periodic cube [−half_width, half_width)³,
    /// appended to `out` (cleared first). Each unordered pair appears exactly once.
    pub fn pairs_within(
        &mut self,
        positions: &[DVec3],
        radii: &[f64],
        half_width: f64,
        margin: f64,
        out: &mut Vec<NearPair>,
    ) {
        out.clear();
        let count = positions.len();
        if count < 2 {
            return;
        }
        let side = 2.0 * half_width;
        let b_min = radii.iter().copied().fold(f64::INFINITY, f64::min);
        let h0 = (2.0 * b_min + margin).max(f64::MIN_POSITIVE);

        // Level of each body: smallest k with h0·2^k ≥ 2b + margin.
        self.level_of.clear();
        let mut top = 0usize;
        for &b in radii {
            let need = (2.0 * b + margin) / h0;
            let k = if need <= 1.0 {
                0
            } else {
                (need.log2().ceil() as usize).min(60)
            };
            // Rounding in log2 can leave h0·2^k a hair short: bump once if so.
            let k = if h0 * 2f64.powi(k as i32) < 2.0 * b + margin {
                k + 1
            } else {
                k
            };
            top = top.max(k);
            self.level_of.push(k as u8);
        }
        if self.levels.len() < top + 1 {
            self.levels.resize_with(top + 1, Level::default);
        }
        for level in &mut self.levels {
            level.members.clear();
            level.max_radius = 0.0;
        }
        for (idx, &k) in self.level_of.iter().enumerate() {
            let level = &mut self.levels[k as usize];
            level.members.push(idx as u32);
            level.max_radius = level.max_radius.max(radii[idx]);
        }

        // Bin each level: counting sort of members by cell.
        self.cell_of.resize(count, 0);
        for (k, level) in self.levels.iter_mut().enumerate().take(top + 1) {
            if level.members.is_empty() {
                continue;
            }
            let h = h0 * 2f64.powi(k as i32);
            // Cap the cell count near the member count so very dilute levels stay cheap.
            let by_size = ((side / h).floor() as usize).max(1);
            let by_count = ((8.0 * level.members.len() as f64).cbrt().ceil() as usize).max(1);
            level.n = by_size.min(by_count).max(1);
            level.width = side / level.n as f64;
            let n = level.n;
            let cells = n * n * n;
            level.start.clear();
            level.start.resize(cells + 1, 0);
            for &m in &level.members {
                let c = cell_index(positions[m as usize], half_width, level.width, n);
                self.cell_of[m as usize] = c as u32;
                level.start[c + 1] += 1;
            }
            for c in 0..cells {
                level.start[c + 1] += level.start[c];
            }
            level.fill.clear();
            level.fill.extend_from_slice(&level.start);
            level.sorted.clear();
            level.sorted.resize(level.members.len(), 0);
            for &m in &level.members {
                let c = self.cell_of[m as usize] as usize;
                level.sorted[level.fill[c] as usize] = m;
                level.fill[c] += 1;
            }
            std::mem::swap(&mut level.members, &mut level.sorted);
        }

        // Positions lie in [−D, D), so every component of a difference lies in (−2D, 2D):
        // one conditional shift is the minimum image (much cheaper than `round`).
        let half = half_width;
        let wrap1 = |x: f64| {
            if x > half {
                x - side
            } else if x < -half {
                x + side
            } else {
                x
            }
        };
        let min_image = |d: DVec3| DVec3::new(wrap1(d.x), wrap1(d.y), wrap1(d.z));
        // Visit bodies cell by cell (members are sorted by cell): neighbours are then
        // close in memory. The pairs' order depends only on the input, never on timing.
        let order = self.levels.iter().flat_map(|level| level.members.iter());
        for &i in order {
            let i = i as usize;
            let ki = self.level_of[i] as usize;
            let ri = positions[i];
            let bi = radii[i];
            // Search this level and the coarser ones: a level's cells are sized for its own
            // largest body, so a smaller body needs only a 27-cell window there.
            for (kl, level) in self.levels.iter().enumerate().skip(ki) {
                if level.members.is_empty() {
                    continue;
                }
                let same_level = kl == ki;
                // `only_after`: within one level, report each pair from its lower index only.
                let mut visit = |j: u32, only_after: bool| {
                    let ju = j as usize;
                    if ju == i || (only_after && ju < i) {
                        return;
                    }
                    let d = min_image(positions[ju] - ri);
                    let reach = bi + radii[ju] + margin;
                    if reach <= half {
                        // Only the nearest image can be within reach.
                        let dist2 = d.length_squared();
                        if dist2 <= reach * reach {
                            let gap = dist2.sqrt() - bi - radii[ju];
                            out.push(NearPair {
                                i: i as u32,
                                j,
                                d,
                                gap,
                            });
                        }
                        return;
                    }
                    // Bodies larger than a quarter of the box: several periodic images of
                    // the partner may be within reach, and any of them can be met.
                    for image in IMAGES {
                        let di = d + side * image;
                        let dist2 = di.length_squared();
                        if dist2 <= reach * reach {
                            let gap = dist2.sqrt() - bi - radii[ju];
                            out.push(NearPair {
                                i: i as u32,
                                j,
                                d: di,
                                gap,
                            });
                        }
                    }
                };
                let n = level.n;
                let reach = bi + level.max_radius + margin;
                let s = (reach / level.width).ceil() as usize;
                if 2 * s + 1 >= n {
                    for &j in &level.members {
                        visit(j, same_level);
                    }
                    continue;
                }
                let c = cell_coords(ri, half_width, level.width, n);
                // |offset| ≤ s < n/2 here, so one conditional add wraps (no integer division).
                let ni = n as isize;
                let wrap = |x: isize| {
                    if x < 0 {
                        x + ni
                    } else if x >= ni {
                        x - ni
                    } else {
                        x
                    }
                };
                let cell_at = |dx: isize, dy: isize, dz: isize| {
                    let x = wrap(c[0] as isize + dx) as usize;
                    let y = wrap(c[1] as isize + dy) as usize;
                    let z = wrap(c[2] as isize + dz) as usize;
                    (z * n + y) * n + x
                };
                let members_of = |cell: usize| {
                    &level.members[level.start[cell] as usize..level.start[cell + 1] as usize]
                };
                if same_level && s == 1 {
                    // Half shell: the own cell (higher indices only) and 13 forward neighbours,
                    // so each pair of this level is met once, from one side.
                    for &j in members_of(cell_at(0, 0, 0)) {
                        visit(j, true);
                    }
                    for &(dx, dy, dz) in &HALF_SHELL {
                        for &j in members_of(cell_at(dx, dy, dz)) {
                            visit(j, false);
                        }
                    }
                    continue;
                }
                let s = s as isize;
                for dz in -s..=s {
                    for dy in -s..=s {
                        for dx in -s..=s {
                            for &j in members_of(cell_at(dx, dy, dz)) {
                                visit(j, same_level);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The 27 lattice translations (in box sides) of a partner's nearest periodic images.
/// Two bodies together hold at most the whole volume fraction (< 0.39), so b_i + b_j
/// stays below one box side and images further away can never be in reach.
pub const IMAGES: [DVec3; 27] = {
    let mut images = [DVec3::ZERO; 27];
    let mut k = 0;
    while k < 27 {
        images[k] = DVec3::new(
            (k % 3) as f64 - 1.0,
            ((k / 3) % 3) as f64 - 1.0,
            (k / 9) as f64 - 1.0,
        );
        k += 1;
    }
    images
};

/// The 13 neighbour offsets "after" the own cell in (z, y, x) order.
const HALF_SHELL: [(isize, isize, isize); 13] = [
    (1, 0, 0),
    (-1, 1, 0),
    (0, 1, 0),
    (1, 1, 0),
    (-1, -1, 1),
    (0, -1, 1),
    (1, -1, 1),
    (-1, 0, 1),
    (0, 0, 1),
    (1, 0, 1),
    (-1, 1, 1),
    (0, 1, 1),
    (1, 1, 1),
];

#[inline]
fn cell_coords(r: DVec3, half_width: f64, width: f64, n: usize) -> [usize; 3] {
    let f = |x: f64| (((x + half_width) / width).floor().max(0.0) as usize).min(n - 1);
    [f(r.x), f(r.y), f(r.z)]
}

#[inline]
fn cell_index(r: DVec3, half_width: f64, width: f64, n: usize) -> usize {
    let [x, y, z] = cell_coords(r, half_width, width, n);
    (z * n + y) * n + x
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng, rngs::StdRng};

    /// Every (i < j, image) within reach, with the separation from i to that image of j
    /// rounded to 1e-9 so that the grid's and this list's entries compare exactly.
    fn brute(pos: &[DVec3], radii: &[f64], hw: f64, margin: f64) -> Vec<(u32, u32, [i64; 3])> {
        let side = 2.0 * hw;
        let mut v = Vec::new();
        for i in 0..pos.len() {
            for j in i + 1..pos.len() {
                let d = pos[j] - pos[i];
                let d = d - side * (d / side).round();
                let reach = radii[i] + radii[j] + margin;
                for image in IMAGES {
                    let di = d + side * image;
                    if di.length() <= reach {
                        v.push((i as u32, j as u32, key(di)));
                    }
                }
            }
        }
        v.sort();
        v
    }

    fn key(d: DVec3) -> [i64; 3] {
        [d.x, d.y, d.z].map(|x| (x * 1e9).round() as i64)
    }

    #[test]
    fn matches_brute_force_for_mixed_sizes_including_a_body_past_half_the_box() {
        let mut rng = StdRng::seed_from_u64(7);
        let hw = 1.0;
        let mut pos = Vec::new();
        let mut radii = Vec::new();
        for _ in 0..400 {
            pos.push(DVec3::new(
                rng.random_range(-hw..hw),
                rng.random_range(-hw..hw),
                rng.random_range(-hw..hw),
            ));
            radii.push(rng.random_range(0.01..0.04));
        }
        radii[3] = 0.3;
        radii[10] = 1.2; // larger than half the box: touches its own images
        let mut grid = NeighbourGrid::default();
        let mut out = Vec::new();
        grid.pairs_within(&pos, &radii, hw, 0.02, &mut out);
        // Orient every entry from the lower index to the higher one.
        let mut got: Vec<(u32, u32, [i64; 3])> = out
            .iter()
            .map(|p| {
                if p.i < p.j {
                    (p.i, p.j, key(p.d))
                } else {
                    (p.j, p.i, key(-p.d))
                }
            })
            .collect();
        got.sort();
        let before = got.len();
        got.dedup();
        assert_eq!(before, got.len(), "a pair image was reported twice");
        assert!(out.iter().all(|p| p.i != p.j), "a body met itself");
        // The giant (radius 1.2 D) meets some neighbours through two images at once.
        assert!(got.windows(2).any(|w| w[0].0 == w[1].0 && w[0].1 == w[1].1));
        assert_eq!(got, brute(&pos, &radii, hw, 0.02));
    }
}
