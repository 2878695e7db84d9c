//! The hierarchical periodic cell grid of the event core (docs/model.md §4).
//!
//! Level k is a periodic grid of n_k³ cubic cells of width w_k = L / n_k, with
//! n_{k+1} = n_k / 2 (or n_k / 3 at the coarse end: 9 → 3), so a coarse cell is exactly
//! 2 × 2 × 2 (or 3 × 3 × 3) fine cells. A body lives
//! ("is native") at the finest level whose cells are at least its diameter wide, and
//! is also listed in every coarser level's cells. Two bodies can touch only if their
//! cells are adjacent at the coarser of their two levels, so a body finds every
//! possible partner by scanning
//! - the 27 cells around it at its own level (every body of that level or finer),
//! - the 27 cells around it at each coarser level (natives of that level only),
//! - every body of the "whole-box" level: bodies too large for any gridded level
//!   (fewer than 3 cells per side), which are paired through all 27 periodic images.
//!
//! With at least 3 cells per side the 27 neighbour cells are distinct, and the image
//! of a partner is the one given by the cell offset: separations are computed from
//! each body's offset inside its *logical* cell, so rounding at the box faces can
//! never pick the wrong image. Cell membership changes only at crossing events.
//!
//! Lists are intrusive doubly-linked lists over body slots: insert, remove and move
//! are O(1) and nothing is allocated per event.

use glam::DVec3;

const NONE: u32 = u32::MAX;

/// Finest grid at most this many cells per side (cell coordinates are stored as u16).
const MAX_CELLS_PER_SIDE: u32 = 1024;

/// Cells wider than this many radii of the smallest body…
const WIDTH_SLACK: f64 = 1.0 + 1e-9;

/// One intrusive list family: a head per cell, links per slot.
#[derive(Debug, Default, Clone)]
struct Lists {
    head: Vec<u32>,
    next: Vec<u32>,
    prev: Vec<u32>,
}

impl Lists {
    fn with_cells(cells: usize) -> Self {
        Self {
            head: vec![NONE; cells],
            next: Vec::new(),
            prev: Vec::new(),
        }
    }

    fn ensure(&mut self, slot: u32) {
        let need = slot as usize + 1;
        if self.next.len() < need {
            self.next.resize(need, NONE);
            self.prev.resize(need, NONE);
        }
    }

    fn push(&mut self, cell: usize, slot: u32) {
        self.ensure(slot);
        let old = self.head[cell];
        self.next[slot as usize] = old;
        self.prev[slot as usize] = NONE;
        if old != NONE {
            self.prev[old as usize] = slot;
        }
        self.head[cell] = slot;
    }

    fn unlink(&mut self, cell: usize, slot: u32) {
        let (n, p) = (self.next[slot as usize], self.prev[slot as usize]);
        if p != NONE {
            self.next[p as usize] = n;
        } else {
            self.head[cell] = n;
        }
        if n != NONE {
            self.prev[n as usize] = p;
        }
    }

    fn iter(&self, cell: usize) -> impl Iterator<Item = u32> + '_ {
        let mut at = self.head[cell];
        std::iter::from_fn(move || {
            if at == NONE {
                return None;
            }
            let here = at;
            at = self.next[here as usize];
            Some(here)
        })
    }

    fn bytes(&self) -> usize {
        4 * (self.head.capacity() + self.next.capacity() + self.prev.capacity())
    }

    /// Append every body of a list from `first` on (but `skip`) to `out`, found `how`.
    fn push_from(&self, first: u32, skip: u32, how: Partner, out: &mut Vec<(u32, Partner)>) {
        let mut j = first;
        while j != NONE {
            if j != skip {
                out.push((j, how));
            }
            j = self.next[j as usize];
        }
    }
}

#[derive(Debug, Clone)]
struct Level {
    /// Cells per side (≥ 3).
    n: u32,
    /// Cell width [m].
    width: f64,
    /// Largest radius that is native here [m].
    capacity: f64,
    /// True once a body has been native here: only then are the lists kept (memory:
    /// a cloud of primaries uses the finest level alone).
    active: bool,
    /// Bodies of this level or finer, per cell (kept while active).
    all: Lists,
    /// Bodies native to this level, per cell (kept while active, above level 0: only
    /// finer bodies read it, and there are none below level 0).
    native: Lists,
    /// Number of bodies native to this level (coarse levels are skipped while empty).
    natives: u32,
}

/// A slot's level and cell at that level.
#[derive(Debug, Clone, Copy)]
struct Place {
    cell: [u16; 3],
    level: u8,
}

/// Where a partner was found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Partner {
    /// Through the cell offset: separation = offset·w + rel_j − rel_i at this level.
    Cell {
        /// The grid level both bodies are compared at.
        level: u8,
        /// The partner's cell relative to the owner's, per axis (−1, 0 or +1).
        offset: [i8; 3],
    },
    /// A whole-box pair: every periodic image must be considered.
    AnyImage,
}

/// The grid. Slots are the event core's body slots.
#[derive(Debug, Clone)]
pub struct CellGrid {
    half_width: f64,
    levels: Vec<Level>,
    /// Natives of the whole-box level.
    whole: Lists,
    /// Level of each slot (levels.len() = whole-box), or u8::MAX if absent.
    /// Where each slot is: its level (levels.len() = whole-box, u8::MAX = absent) and
    /// its cell at that level (gridded levels only). One array, so a partner costs one
    /// memory access.
    place: Vec<Place>,
}

impl CellGrid {
    /// Levels for a periodic cube of half-width `half_width` [m] whose smallest body has
    /// radius `min_radius` [m]; `bodies` caps the finest cell count near the body count
    /// (very dilute clouds would otherwise get mostly empty cells).
    pub fn new(half_width: f64, min_radius: f64, bodies: usize) -> Self {
        let side = 2.0 * half_width;
        let by_size = (side / (2.0 * min_radius * WIDTH_SLACK)).floor();
        let by_count = (4.0 * bodies.max(1) as f64).cbrt().ceil().max(3.0);
        let most = by_size.min(by_count).min(MAX_CELLS_PER_SIDE as f64) as u32;
        let mut levels = Vec::new();
        if most >= 3 {
            // Largest n ≤ most of the form m·2^p, m ∈ {1, 3, 9, 27}: halving, then
            // dividing by 3, ends at 3 or 4 cells per side, so that large bodies stay
            // gridded up to radius L/8; and above 24 cells n falls at most 1/4 short of
            // `most` (with 2^p and 3·2^p alone, up to 1/3: 64 for most = 74 at N = 1e5,
            // 1.55× the bodies per cell, and the pair tests, of N = 1e3; now 72).
            let mut n = 3u32;
            for candidate in (3..=most).rev() {
                let odd = candidate >> candidate.trailing_zeros();
                if matches!(odd, 1 | 3 | 9 | 27) {
                    n = candidate;
                    break;
                }
            }
            loop {
                let width = side / n as f64;
                levels.push(Level {
                    n,
                    width,
                    capacity: width / (2.0 * WIDTH_SLACK),
                    active: false,
                    all: Lists::default(),
                    native: Lists::default(),
                    natives: 0,
                });
                // Each coarser level's cells are whole blocks of the finer level's.
                if n.is_multiple_of(2) && n / 2 >= 3 {
                    n /= 2;
                } else if n.is_multiple_of(3) && n / 3 >= 3 {
                    n /= 3;
                } else {
                    break;
                }
            }
        }
        Self {
            half_width,
            levels,
            whole: Lists::with_cells(1),
            place: Vec::new(),
        }
    }

    /// Cells per side of each gridded level.
    pub fn cells_per_side(&self) -> Vec<u32> {
        self.levels.iter().map(|l| l.n).collect()
    }

    /// Bytes held (for the memory figure).
    pub fn bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.all.bytes() + l.native.bytes())
            .sum::<usize>()
            + self.whole.bytes()
            + std::mem::size_of::<Place>() * self.place.capacity()
    }

    /// The level a body of radius `radius` [m] belongs to.
    pub fn level_for(&self, radius: f64) -> u8 {
        self.levels
            .iter()
            .position(|l| radius <= l.capacity)
            .unwrap_or(self.levels.len()) as u8
    }

    /// Level of a slot (None if absent).
    pub fn level_of(&self, slot: u32) -> Option<u8> {
        match self.place.get(slot as usize).map(|p| p.level) {
            Some(k) if k != u8::MAX => Some(k),
            _ => None,
        }
    }

    fn cell_index(n: u32, c: [u32; 3]) -> usize {
        let n = n as usize;
        (c[2] as usize * n + c[1] as usize) * n + c[0] as usize
    }

    /// The cell at level k ≥ own holding own-level cell `c`.
    #[inline]
    fn coarse(&self, own: usize, c: [u16; 3], k: usize) -> [u32; 3] {
        if k == own {
            return c.map(u32::from);
        }
        // A level-k cell is a block of (n_own / n_k)³ own-level cells.
        let ratio = self.levels[own].n / self.levels[k].n;
        c.map(|x| x as u32 / ratio)
    }

    /// Cell coordinates of a wrapped position at a gridded level.
    fn cell_at(&self, k: usize, x: DVec3) -> [u16; 3] {
        let l = &self.levels[k];
        let f = |v: f64| {
            let c = ((v + self.half_width) / l.width).floor();
            (c.max(0.0) as u32).min(l.n - 1) as u16
        };
        [f(x.x), f(x.y), f(x.z)]
    }

    /// Start keeping level k's lists: file every finer body already present.
    fn activate(&mut self, k: usize) {
        let level = &mut self.levels[k];
        let cells = (level.n as usize).pow(3);
        level.all = Lists::with_cells(cells);
        if k > 0 {
            level.native = Lists::with_cells(cells);
        }
        level.active = true;
        for slot in 0..self.place.len() as u32 {
            let own = self.place[slot as usize].level;
            if own == u8::MAX || own as usize >= k {
                continue;
            }
            let ck = self.coarse(own as usize, self.place[slot as usize].cell, k);
            let idx = Self::cell_index(self.levels[k].n, ck);
            self.levels[k].all.push(idx, slot);
        }
    }

    fn ensure(&mut self, slot: u32) {
        let need = slot as usize + 1;
        if self.place.len() < need {
            self.place.resize(
                need,
                Place {
                    cell: [0; 3],
                    level: u8::MAX,
                },
            );
        }
    }

    /// The same levels, with no body in them (for renumbering slots).
    pub fn emptied(&self) -> Self {
        let levels = self
            .levels
            .iter()
            .map(|l| Level {
                n: l.n,
                width: l.width,
                capacity: l.capacity,
                active: false,
                all: Lists::default(),
                native: Lists::default(),
                natives: 0,
            })
            .collect();
        Self {
            half_width: self.half_width,
            levels,
            whole: Lists::with_cells(1),
            place: Vec::new(),
        }
    }

    /// A slot's level and logical cell (None if absent).
    pub fn place_of(&self, slot: u32) -> Option<(u8, [u16; 3])> {
        let p = self.place.get(slot as usize)?;
        (p.level != u8::MAX).then_some((p.level, p.cell))
    }

    /// Add a body at a known level and logical cell: renumbering keeps every body's
    /// logical cell, which crossings may have moved ahead of its position at the current
    /// time (they are processed up to the next contact).
    pub fn insert_at(&mut self, slot: u32, level: u8, cell: [u16; 3]) {
        self.ensure(slot);
        let own = level as usize;
        self.place[slot as usize] = Place { cell, level };
        if own == self.levels.len() {
            self.whole.push(0, slot);
            return;
        }
        if !self.levels[own].active {
            self.activate(own);
        }
        self.levels[own].natives += 1;
        self.link(slot, own, cell, own);
    }

    /// Add a body of radius `radius` at wrapped position `x`.
    pub fn insert(&mut self, slot: u32, radius: f64, x: DVec3) {
        self.ensure(slot);
        let own = self.level_for(radius) as usize;
        self.place[slot as usize].level = own as u8;
        if own == self.levels.len() {
            self.whole.push(0, slot);
            return;
        }
        if !self.levels[own].active {
            self.activate(own);
        }
        let c = self.cell_at(own, x);
        self.place[slot as usize].cell = c;
        self.levels[own].natives += 1;
        self.link(slot, own, c, own);
    }

    /// Link into the lists of levels `from..` (own level `own`, own-level cell `c`).
    fn link(&mut self, slot: u32, own: usize, c: [u16; 3], from: usize) {
        for k in from..self.levels.len() {
            if !self.levels[k].active {
                continue;
            }
            let ck = self.coarse(own, c, k);
            let idx = Self::cell_index(self.levels[k].n, ck);
            self.levels[k].all.push(idx, slot);
            if k == own && k > 0 {
                self.levels[k].native.push(idx, slot);
            }
        }
    }

    fn unlink(&mut self, slot: u32, own: usize, c: [u16; 3], from: usize) {
        for k in from..self.levels.len() {
            if !self.levels[k].active {
                continue;
            }
            let ck = self.coarse(own, c, k);
            let idx = Self::cell_index(self.levels[k].n, ck);
            self.levels[k].all.unlink(idx, slot);
            if k == own && k > 0 {
                self.levels[k].native.unlink(idx, slot);
            }
        }
    }

    /// Remove a body.
    pub fn remove(&mut self, slot: u32) {
        let Some(own) = self.level_of(slot) else {
            return;
        };
        let own = own as usize;
        if own == self.levels.len() {
            self.whole.unlink(0, slot);
        } else {
            let c = self.place[slot as usize].cell;
            self.unlink(slot, own, c, own);
            self.levels[own].natives -= 1;
        }
        self.place[slot as usize].level = u8::MAX;
    }

    /// Move a gridded body one cell along `axis` by `step` (±1) at its own level.
    pub fn cross(&mut self, slot: u32, axis: usize, step: i8) {
        let own = self.place[slot as usize].level as usize;
        let old = self.place[slot as usize].cell;
        let n = self.levels[own].n;
        let mut new = old;
        new[axis] = ((old[axis] as i64 + step as i64).rem_euclid(n as i64)) as u16;
        // Coarser cells change only when the coarse coordinate changes.
        let first_changed = (own..self.levels.len())
            .find(|&k| self.coarse(own, old, k) != self.coarse(own, new, k))
            .unwrap_or(self.levels.len());
        let last_changed = (own..self.levels.len())
            .rev()
            .find(|&k| self.coarse(own, old, k) != self.coarse(own, new, k));
        if let Some(last) = last_changed {
            for k in first_changed..=last {
                let (co, cn) = (self.coarse(own, old, k), self.coarse(own, new, k));
                if co == cn || !self.levels[k].active {
                    continue;
                }
                let lvl = &mut self.levels[k];
                let (io, inew) = (Self::cell_index(lvl.n, co), Self::cell_index(lvl.n, cn));
                lvl.all.unlink(io, slot);
                lvl.all.push(inew, slot);
                if k == own && k > 0 {
                    lvl.native.unlink(io, slot);
                    lvl.native.push(inew, slot);
                }
            }
        }
        self.place[slot as usize].cell = new;
    }

    /// Offset of `x` (a position, any image) from the low corner of the slot's logical
    /// cell at level `k`, each component in [−L/2, L/2) (so ≈ [0, w_k] up to rounding).
    pub fn offset_in_cell(&self, slot: u32, k: usize, x: DVec3) -> DVec3 {
        let own = self.place[slot as usize].level as usize;
        let c = self.coarse(own, self.place[slot as usize].cell, k);
        let w = self.levels[k].width;
        let side = 2.0 * self.half_width;
        let inv_side = 1.0 / side;
        let rel = |v: f64, ci: u32| {
            let d = v - (-self.half_width + ci as f64 * w);
            d - side * round_fast(d * inv_side)
        };
        DVec3::new(rel(x.x, c[0]), rel(x.y, c[1]), rel(x.z, c[2]))
    }

    /// Width of a gridded level [m].
    pub fn width(&self, k: usize) -> f64 {
        self.levels[k].width
    }

    /// Time until a gridded body at position `x` with velocity `v` leaves its own-level
    /// cell, with the axis and direction; None for whole-box bodies or v = 0.
    pub fn crossing(&self, slot: u32, x: DVec3, v: DVec3) -> Option<(f64, u8, i8)> {
        // A straight line: along each axis, the wall it moves toward at constant speed.
        self.crossing_by(slot, x, |axis, r, w| {
            let u = v[axis];
            if u > 0.0 {
                Some(((w - r) / u, 1))
            } else if u < 0.0 {
                Some((r / -u, -1))
            } else {
                None
            }
        })
    }

    /// Time until a gridded body at position `x` leaves its own-level cell along a curved
    /// path: `leave(axis, offset, width)` gives, for one axis, when the coordinate at
    /// `offset` inside a cell of `width` [m] leaves it and by which side (0: not before
    /// that time — ask again then). The earliest over the axes; None for whole-box bodies
    /// or one that never leaves.
    pub fn crossing_by(
        &self,
        slot: u32,
        x: DVec3,
        leave: impl Fn(usize, f64, f64) -> Option<(f64, i8)>,
    ) -> Option<(f64, u8, i8)> {
        let own = self.level_of(slot)? as usize;
        if own == self.levels.len() {
            return None;
        }
        let rel = self.offset_in_cell(slot, own, x);
        let w = self.levels[own].width;
        let mut best: Option<(f64, u8, i8)> = None;
        for axis in 0..3 {
            if let Some((t, step)) = leave(axis, rel[axis], w) {
                let t = t.max(0.0);
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, axis as u8, step));
                }
            }
        }
        best
    }

    /// Every body that could touch `slot` (never `slot` itself), with where it was found,
    /// appended to `out`. `alive` lists every present slot (used only for a whole-box
    /// body).
    ///
    /// Gathered first and tested after (see `EventCore::predict`): the cell heads are
    /// prefetched before the lists are walked and the partners' data before they are
    /// tested, so the cache misses of a neighbour scan overlap instead of following one
    /// another — at N ≥ 1e5 they, not the arithmetic, are the cost of an event.
    pub fn gather_candidates(
        &self,
        slot: u32,
        alive: impl Iterator<Item = u32>,
        out: &mut Vec<(u32, Partner)>,
    ) {
        let own = self.place[slot as usize].level as usize;
        if own == self.levels.len() {
            out.extend(alive.filter(|&j| j != slot).map(|j| (j, Partner::AnyImage)));
            return;
        }
        let c = self.place[slot as usize].cell;
        for k in own..self.levels.len() {
            let level = &self.levels[k];
            if k != own && level.natives == 0 {
                continue;
            }
            let lists = if k == own { &level.all } else { &level.native };
            let ck = self.coarse(own, c, k);
            let n = level.n;
            // Wrapped neighbour coordinates along each axis, for offsets −1, 0, +1.
            let around = |x: u32| {
                [
                    if x == 0 { n - 1 } else { x - 1 },
                    x,
                    if x + 1 == n { 0 } else { x + 1 },
                ]
            };
            let (ax, ay, az) = (around(ck[0]), around(ck[1]), around(ck[2]));
            let mut cells = [0usize; 27];
            for (iz, &z) in az.iter().enumerate() {
                for (iy, &y) in ay.iter().enumerate() {
                    let row = (z as usize * n as usize + y as usize) * n as usize;
                    for (ix, &x) in ax.iter().enumerate() {
                        let cell = row + x as usize;
                        cells[(iz * 3 + iy) * 3 + ix] = cell;
                        prefetch(&lists.head[cell]);
                    }
                }
            }
            // Each cell's first body, whose link is then asked for: walking the lists
            // after that misses at most on the (rare) second body of a cell.
            let firsts = cells.map(|cell| lists.head[cell]);
            for &first in &firsts {
                if first != NONE {
                    prefetch(&lists.next[first as usize]);
                }
            }
            for (i, &first) in firsts.iter().enumerate() {
                let how = Partner::Cell {
                    level: k as u8,
                    offset: [(i % 3) as i8 - 1, (i / 3 % 3) as i8 - 1, (i / 9) as i8 - 1],
                };
                lists.push_from(first, slot, how, out);
            }
        }
        out.extend(
            self.whole
                .iter(0)
                .filter(|&j| j != slot)
                .map(|j| (j, Partner::AnyImage)),
        );
    }

    /// True when no body is too large for the gridded levels (then every pair is found
    /// through cell offsets alone).
    pub fn all_gridded(&self) -> bool {
        self.whole.head[0] == NONE
    }

    /// The bodies that became possible partners of `slot` when it crossed from own-level
    /// cell `old` one cell along `axis` by `step` (±1): at every level where its cell
    /// changed, the 9 cells of the slab ahead of it, appended to `out` as
    /// `gather_candidates` would list them. The slot must be gridded and no body
    /// whole-box (`all_gridded`): every other partner was already a candidate at the
    /// prediction before.
    pub fn gather_slab(
        &self,
        slot: u32,
        old: [u16; 3],
        axis: usize,
        step: i8,
        out: &mut Vec<(u32, Partner)>,
    ) {
        let own = self.place[slot as usize].level as usize;
        let c = self.place[slot as usize].cell;
        for k in own..self.levels.len() {
            let level = &self.levels[k];
            if k != own && level.natives == 0 {
                continue;
            }
            let ck = self.coarse(own, c, k);
            if k != own && ck == self.coarse(own, old, k) {
                continue; // same coarse cell: the same neighbours at this level
            }
            let lists = if k == own { &level.all } else { &level.native };
            let n = level.n;
            let shifted = |x: u32, d: i8| (x as i64 + d as i64).rem_euclid(n as i64) as u32;
            let mut cells = [0usize; 9];
            let mut offsets = [[0i8; 3]; 9];
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut i = 0;
            for d2 in -1i8..=1 {
                for d1 in -1i8..=1 {
                    let mut offset = [0i8; 3];
                    offset[axis] = step;
                    offset[a1] = d1;
                    offset[a2] = d2;
                    let cell = [0, 1, 2].map(|a| shifted(ck[a], offset[a]));
                    cells[i] = Self::cell_index(n, cell);
                    offsets[i] = offset;
                    prefetch(&lists.head[cells[i]]);
                    i += 1;
                }
            }
            for (cell, offset) in cells.into_iter().zip(offsets) {
                let how = Partner::Cell {
                    level: k as u8,
                    offset,
                };
                lists.push_from(lists.head[cell], slot, how, out);
            }
        }
    }

    /// Ask the memory system for what `offset_in_cell` will read of `slot`.
    #[inline]
    pub fn prefetch_place(&self, slot: u32) {
        if let Some(p) = self.place.get(slot as usize) {
            prefetch(p);
        }
    }

    /// Ask for what a crossing of `slot` reads first: its place and its links in the
    /// finest level's lists (a hint: no effect on results).
    pub fn prefetch_crossing(&self, slot: u32) {
        self.prefetch_place(slot);
        if let Some(level) = self.levels.first() {
            let all = &level.all;
            if let (Some(n), Some(p)) = (all.next.get(slot as usize), all.prev.get(slot as usize)) {
                prefetch(n);
                prefetch(p);
            }
        }
    }
}

/// Ask the memory system to bring `r`'s cache line in (a hint: no effect on results).
#[inline(always)]
pub fn prefetch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint to the cache; it reads nothing into the program and
    // never faults, and `r` is a valid reference anyway.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((r as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}

/// round(x) to the nearest integer (ties away from zero) without a libm call: the
/// truncating conversion is one instruction. Exact for |x| < 2^52.
#[inline]
pub fn round_fast(x: f64) -> f64 {
    (x + 0.5f64.copysign(x)) as i64 as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_down_to_three_cells_and_big_bodies_go_whole_box() {
        let grid = CellGrid::new(1.0, 0.04, 100_000);
        // 2 / 0.08 = 25 → 24 = 3·8, then 12, 6, 3.
        assert_eq!(grid.cells_per_side(), vec![24, 12, 6, 3]);
        assert_eq!(grid.level_for(0.04), 0);
        assert_eq!(grid.level_for(0.05), 1);
        assert_eq!(grid.level_for(2.0 / 6.0 / 2.0 * 0.999), 2);
        assert_eq!(grid.level_for(0.3), 3);
        assert_eq!(grid.level_for(0.5), 4);
    }

    #[test]
    fn a_grid_of_nine_times_a_power_of_two_ends_in_thirds() {
        // N = 1e5 equal bodies at φ ≈ 0.11 (the peer clouds): at most 74 cells per side
        // by count; 72 = 9·8 is taken (64 before), and the coarse end divides by 3.
        let grid = CellGrid::new(0.01, 0.01 / 77.5, 100_000);
        assert_eq!(grid.cells_per_side(), vec![72, 36, 18, 9, 3]);
        let mut grid = grid;
        // A level-3 body (9 cells) and a level-0 body near it: the level-0 body's coarse
        // cell at level 3 is its cell / 8, at level 4 (3 cells) its cell / 24.
        grid.insert(0, 0.0001, DVec3::new(0.0005, 0.0, 0.0));
        grid.insert(1, 0.02 / 9.0 / 2.0 * 0.99, DVec3::new(0.0012, 0.0, 0.0));
        assert_eq!(grid.level_of(1), Some(3));
        let mut found = Vec::new();
        grid.gather_candidates(0, std::iter::empty(), &mut found);
        assert!(found.iter().any(|&(j, _)| j == 1));
        let ck = grid.coarse(0, grid.place[0].cell, 4);
        assert_eq!(ck, grid.place[0].cell.map(|c| c as u32 / 24));
    }

    #[test]
    fn crossing_moves_the_body_and_its_coarse_cells() {
        let mut grid = CellGrid::new(1.0, 0.04, 100_000);
        grid.insert(0, 0.04, DVec3::new(-0.01, 0.0, 0.0));
        grid.insert(1, 0.3, DVec3::new(0.2, 0.0, 0.0)); // level 3 (6 cells? no: capacity)
        let partners = |grid: &CellGrid, slot: u32| {
            let mut out = Vec::new();
            grid.gather_candidates(slot, std::iter::empty(), &mut out);
            out.into_iter().map(|(j, _)| j).collect::<Vec<_>>()
        };
        assert!(partners(&grid, 0).contains(&1));
        // Cross the box many times in +x: lists stay consistent (the body is found once).
        for _ in 0..24 * 3 {
            grid.cross(0, 0, 1);
            let count = partners(&grid, 1).iter().filter(|&&j| j == 0).count();
            assert!(count <= 1);
        }
        grid.remove(0);
        assert!(partners(&grid, 1).is_empty());
    }
}
