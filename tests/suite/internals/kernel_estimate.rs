//! Unit tests of `kernel::estimate` (src/kernel/estimate.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::kernel::estimate::*;

#[test]
fn wilson_brackets_the_estimate_and_stays_in_unit_interval() {
    // 0 of 10: the interval starts at 0 and its top is ≈ 0.278 (z²/(n + z²)).
    let (lo, hi) = wilson(0, 10);
    assert_eq!(lo, 0.0);
    assert!((hi - 0.2775).abs() < 1e-3, "{hi}");
    let (lo, hi) = wilson(5, 10);
    assert!(lo < 0.5 && hi > 0.5 && (0.5 - lo - (hi - 0.5)).abs() < 1e-12);
}
