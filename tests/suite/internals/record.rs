//! Unit tests of `record` (src/record/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::record::*;

#[test]
fn colour_scale_ends_and_clamps() {
    let c = ColourScale {
        theta_lo: 300.0,
        theta_hi: 3e5,
    };
    assert_eq!(c.fraction(300.0), 0.0);
    assert_eq!(c.fraction(3e5), 1.0);
    assert_eq!(c.fraction(1e9), 1.0);
    assert_eq!(c.fraction(1.0), 0.0);
    // One decade of three: a third of the way (ln ratio, exact up to rounding).
    assert!((c.fraction(3000.0) - 1.0 / 3.0).abs() < 1e-12);
    assert_eq!(c.rgb(300.0), [0.10, 0.25, 1.00]);
    assert_eq!(c.rgb(1e7), [1.00, 0.10, 0.05]);
}

#[test]
fn time_sampling_fires_on_crossing_multiples() {
    let s = Sampling {
        every_steps: 0,
        interval: Some(1.0),
        log_seconds_per_sim_second: 1.0,
    };
    assert!(!s.due(1, 0.5, 0.0));
    assert!(s.due(2, 1.2, 0.5));
    assert!(!s.due(3, 1.9, 1.2));
    // A long step that skips several multiples records once.
    assert!(s.due(4, 4.5, 1.9));
    let k = Sampling {
        every_steps: 3,
        interval: None,
        log_seconds_per_sim_second: 1.0,
    };
    assert!(k.due(3, 0.1, 0.0) && !k.due(4, 0.2, 0.1) && k.due(6, 0.3, 0.2));
}

#[test]
fn log_time_scales_and_saturates() {
    let s = Sampling {
        every_steps: 0,
        interval: None,
        log_seconds_per_sim_second: 3000.0,
    };
    assert_eq!(s.log_time(0.01), 30_000_000_000);
    assert_eq!(s.log_time(-1.0), 0);
    assert_eq!(s.log_time(f64::NAN), 0);
    assert_eq!(s.log_time(f64::INFINITY), 0);
}
