//! Unit tests of `live::run` (src/live/run.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::live::run::*;

#[test]
fn the_subset_fits_and_is_nested() {
    assert_eq!(subset_shift(10_000, 10_000), 0);
    assert_eq!(subset_shift(10_001, 10_000), 1);
    assert_eq!(subset_shift(100_000, 10_000), 4);
    assert_eq!(subset_shift(1_000_000, 10_000), 7);
    let ids = 0..100_000u64;
    let shown = |k| ids.clone().filter(|&id| in_subset(id, k)).count();
    // 1 in 16 of 100 000 ids: 6250 expected; the hash is uniform, so the count is
    // within a few standard deviations (√(N p (1 − p)) ≈ 77) of it.
    let n4 = shown(4);
    assert!((n4 as f64 - 6250.0).abs() < 5.0 * 77.0, "{n4}");
    assert_eq!(shown(0), 100_000);
    for id in 0..10_000u64 {
        if in_subset(id, 5) {
            assert!(in_subset(id, 4), "{id} in 1/32 but not in 1/16");
        }
    }
}
