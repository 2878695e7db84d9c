//! Unit tests of `subgrid::lift` (src/subgrid/lift.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::subgrid::lift::*;
use agglo::subgrid::stream::Stream;
use std::f64::consts::PI;

/// Whether a body of radius `b` at `p` overlaps none of `placed` in the periodic
/// cube of side `side`, by every pair and minimum images (the grid's reference).
fn free_by_every_pair(placed: &[[f64; 4]], side: f64, p: [f64; 3], b: f64) -> bool {
    placed.iter().all(|q| {
        let d2: f64 = (0..3)
            .map(|x| {
                let d = p[x] - q[x];
                let d = d - side * (d / side).round();
                d * d
            })
            .sum();
        d2 >= (b + q[3]) * (b + q[3])
    })
}

/// The grid's answer for every probe is the pair-by-pair answer, in a box of mixed
/// sizes filled to volume fraction ≈ 0.2 (cells off and on the periodic boundary,
/// every octant) and in one of fewer than three cells per side. The looking order
/// only changes how soon an overlap is found, never whether: this is what keeps
/// lifted boxes the same bit for bit whatever order the cells are looked at in.
#[test]
fn the_grid_finds_exactly_the_overlaps_every_pair_finds() {
    let side = 0.02;
    let b = (0.2 * side * side * side / (1000.0 * 4.0 / 3.0 * PI)).cbrt();
    for (min_cell, radii) in [
        // Largest 2b: 6b-wide cells, about 6 per side.
        (4.0 * b, [2.0 * b, 1.3 * b, 0.8 * b]),
        // Two cells per side: every cell looked at, minimum images by rounding.
        (0.45 * side, [1.5 * b, b, 0.5 * b]),
    ] {
        let mut grid = PlacementGrid::new(side, min_cell, 1000);
        let mut rng = Stream(7);
        let mut placed = Vec::new();
        for (i, &r) in radii.iter().enumerate() {
            for _ in 0..[20, 200, 700][i] {
                let p = grid.place(r, &mut rng).expect("room at φ ≈ 0.2");
                placed.push([p[0], p[1], p[2], r]);
            }
        }
        let (mut free, mut taken) = (0, 0);
        for _ in 0..20_000 {
            let p = [0, 1, 2].map(|_| side * (rng.uniform() - 0.5));
            let r = radii[(3.0 * rng.uniform()) as usize];
            let (c, within) = grid.locate(p);
            let by_grid = grid.free(p, c, within, r);
            assert_eq!(by_grid, free_by_every_pair(&placed, side, p, r), "{p:?}");
            if by_grid { free += 1 } else { taken += 1 }
        }
        // Both answers occur often enough to have been compared (at φ ≈ 0.2
        // most probes overlap; a few hundred are free).
        assert!(free > 100 && taken > 100, "free {free}, taken {taken}");
    }
}
