//! Unit tests of `subgrid::structure` (src/subgrid/structure.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::subgrid::stream::Stream;
use agglo::subgrid::structure::*;

/// The minimum image through `nearest_whole` is round's, its square bit for bit: on
/// the halves, the zeros, just inside and outside ±0.5 and ±1.5, far out, NaN, and
/// 10⁵ random differences of positions in a box.
#[test]
fn the_minimum_image_is_rounds_bit_for_bit() {
    let side = 0.0123;
    let image = |d: f64, r: f64| d - side * r;
    let mut xs = vec![
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.5,
        -1.5,
        1.0,
        -1.0,
        7.3,
        -7.3,
        f64::NAN,
    ];
    for edge in [0.5f64, 1.5] {
        for x in [edge.next_down(), edge.next_up()] {
            xs.extend([x, -x]);
        }
    }
    let mut rng = Stream(3);
    xs.extend((0..100_000).map(|_| 2.0 * (rng.uniform() - rng.uniform())));
    for x in xs {
        let d = x * side;
        let (ours, rounds) = (
            image(d, nearest_whole(d / side)),
            image(d, (d / side).round()),
        );
        // Equal as numbers (−0 and +0 for d = −0), the square bit for bit.
        assert!(
            ours == rounds || (ours.is_nan() && rounds.is_nan()),
            "x = {x}: {ours} against {rounds}"
        );
        assert_eq!(
            (ours * ours).to_bits(),
            (rounds * rounds).to_bits(),
            "x = {x}"
        );
    }
}
