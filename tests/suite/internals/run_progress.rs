//! Unit tests of `run::progress` (src/run/progress.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::run::progress::*;

#[test]
fn eta_is_wall_time_scaled_by_the_simulated_time_left() {
    // A quarter of T in 10 s: 30 s to go.
    let text = line(0.25, 1.0, 1.5e5, "events", 42, 10.0);
    assert_eq!(
        text,
        "t = 2.500e-1 of 1e0 s · 1.500e5 events/s · 42 bodies · ETA 30.0s"
    );
    assert_eq!(format_duration(3725.0), "1h02m05s");
    assert_eq!(format_duration(125.0), "2m05s");
    assert_eq!(
        line(0.0, 1.0, 0.0, "steps", 1, 0.0).rsplit(' ').next(),
        Some("?")
    );
}
