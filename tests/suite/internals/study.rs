//! Unit tests of `study` (src/study/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::study::*;

#[test]
fn ks_distance_of_identical_and_disjoint_samples() {
    assert_eq!(ks_distance(&[1.0, 2.0, 2.0], &[2.0, 1.0, 2.0]), 0.0);
    assert_eq!(ks_distance(&[1.0, 2.0], &[3.0, 4.0]), 1.0);
    // Half the mass of `b` lies below every sample of `a`'s upper half.
    assert!((ks_distance(&[1.0, 2.0], &[1.0, 1.0]) - 0.5).abs() < 1e-15);
}

#[test]
fn median_and_spread() {
    assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
    assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
    let (m, s) = mean_std(&[1.0, 3.0]);
    assert_eq!(m, 2.0);
    assert!((s - 2f64.sqrt()).abs() < 1e-15);
}
