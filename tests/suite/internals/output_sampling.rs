//! Unit tests of `output::sampling` (src/output/sampling.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::output::sampling::*;

fn times(schedule: SampleSchedule, end: f64, steps: &[f64]) -> Vec<f64> {
    let mut s = Sampler::new(schedule, end);
    let mut out = Vec::new();
    if s.due(0, 0.0) {
        s.taken(0.0);
        out.push(0.0);
    }
    for (i, &t) in steps.iter().enumerate() {
        if s.due(i as u64 + 1, t) {
            s.taken(t);
            out.push(t);
        }
    }
    out
}

#[test]
fn interval_samples_at_the_first_step_past_each_multiple() {
    let steps: Vec<f64> = (1..=10).map(|i| i as f64 * 0.3).collect();
    // Multiples of 1: reached at 1.2, 2.1, 3.0 (= 10 · 0.3 up to rounding).
    let got = times(SampleSchedule::Interval { dt: 1.0 }, 3.0, &steps);
    assert_eq!(got.len(), 4, "{got:?}");
    assert_eq!(got[0], 0.0);
    assert!((got[1] - 1.2).abs() < 1e-12 && (got[2] - 2.1).abs() < 1e-12);
    assert!((got[3] - 3.0).abs() < 1e-12);
}

#[test]
fn log_schedule_has_per_decade_samples_per_decade() {
    let steps: Vec<f64> = (1..=100_000).map(|i| i as f64 * 1e-5).collect();
    let schedule = SampleSchedule::Log {
        first: Some(1e-3),
        per_decade: 5,
    };
    let got = times(schedule, 1.0, &steps);
    // t = 0, then 1e-3 … 1 at 5 per decade: 3 decades · 5 + 1 = 16 samples.
    assert_eq!(got.len(), 17, "{got:?}");
    for w in got[1..].windows(2) {
        let ratio = w[1] / w[0];
        // Steps of 1e-5 move each sample at most 1e-5 past its time (≥ 1e-3): ≤ 1 %.
        assert!((ratio / 10f64.powf(0.2) - 1.0).abs() < 0.02, "{ratio}");
    }
}

#[test]
fn step_schedule_counts_steps_and_ends_with_the_last_step() {
    let steps: Vec<f64> = (1..=10).map(|i| i as f64).collect();
    let got = times(SampleSchedule::Steps { every: 4 }, 10.0, &steps);
    assert_eq!(got, vec![0.0, 4.0, 8.0, 10.0]);
}

#[test]
fn the_next_time_is_past_now_for_any_interval() {
    // The ordinary case: the next multiple.
    assert_eq!(next_time(1.0, 1.0, 2.5), 3.0);
    assert_eq!(next_time(3.0, 1.0, 2.5), 3.0);
    // Intervals below the clock's rounding: due at every step, never stuck, never ∞
    // (5e-324 once gave ∞: the count of intervals passed overflowed).
    for dt in [1e-20, 1e-300, 5e-324] {
        let next = next_time(1e-9, dt, 1e-3);
        assert!(next > 1e-3 && next < 1e-3 * (1.0 + 1e-12), "{dt}: {next}");
    }
}
