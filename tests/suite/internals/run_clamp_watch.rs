//! Unit tests of `run::clamp_watch` (src/run/clamp_watch.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::run::clamp_watch::*;
use std::time::Instant;

/// Steps `from..to`, each clamped if `clamped(step)`; the windows reported.
fn feed(
    watch: &mut ClampWatch,
    total: &mut u64,
    steps: std::ops::Range<u64>,
    clamped: impl Fn(u64) -> bool,
    now: Instant,
) -> Vec<ClampedWindow> {
    let mut reported = Vec::new();
    for step in steps {
        if clamped(step) {
            *total += 1;
        }
        reported.extend(watch.observe(step + 1, *total, now));
    }
    reported
}

#[test]
fn a_mostly_clamped_window_is_reported_once() {
    let t0 = Instant::now();
    let mut watch = ClampWatch::new(0, 0);
    let mut total = 0;
    // 3 of every 4 steps clamped: 750 of the first 1000.
    let got = feed(&mut watch, &mut total, 0..1000, |s| s % 4 != 0, t0);
    assert_eq!(
        got,
        vec![ClampedWindow {
            clamped: 750,
            steps: 1000
        }]
    );
}

#[test]
fn half_or_fewer_clamped_is_not_reported() {
    let t0 = Instant::now();
    let mut watch = ClampWatch::new(0, 0);
    let mut total = 0;
    let got = feed(&mut watch, &mut total, 0..5000, |s| s % 2 == 0, t0);
    assert!(got.is_empty(), "{got:?}");
}

#[test]
fn warnings_wait_for_the_interval() {
    let t0 = Instant::now();
    let mut watch = ClampWatch::new(0, 0);
    let mut total = 0;
    // Three bad windows within the interval: one warning.
    let got = feed(&mut watch, &mut total, 0..3000, |_| true, t0);
    assert_eq!(got.len(), 1);
    // After the interval, the next bad window is reported again.
    let later = t0 + MIN_INTERVAL;
    let got = feed(&mut watch, &mut total, 3000..4000, |_| true, later);
    assert_eq!(got.len(), 1);
}
