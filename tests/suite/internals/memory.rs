//! Unit tests of `memory` (src/memory.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::memory::*;
use agglo::scenario::Scenario;

fn estimate(bodies: usize, available: f64) -> MemoryEstimate {
    MemoryEstimate {
        bodies,
        bytes: BASE_BYTES + BYTES_PER_BODY * bodies as f64,
        available: Some(available),
        runs_at_once: 1,
    }
}

#[test]
fn a_scene_that_fits_passes_and_one_that_does_not_names_the_field_and_the_limit() {
    assert_eq!(estimate(1000, 1e9).check(), Ok(None));
    let half = estimate(1_000_000, 1.2e9).check().unwrap();
    assert!(half.unwrap().starts_with("warning"));
    let e = estimate(100_000_000, 1e9).check().unwrap_err();
    assert!(e.starts_with("cloud.count"), "{e}");
    // (1e9 − 16e6) / 650 bodies fit.
    assert!(e.contains("N ≤ 1.514e6"), "{e}");
}

#[test]
fn a_recorded_run_is_estimated_with_the_recording_s_bytes_per_body() {
    let mut scenario = Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json"),
    )
    .unwrap();
    scenario.cloud.count = 1_000_000;
    let (plain, recorded) = (
        MemoryEstimate::of_run(&scenario, false),
        MemoryEstimate::of_run(&scenario, true),
    );
    assert_eq!(plain.bytes, BASE_BYTES + 650.0 * 1e6);
    assert_eq!(recorded.bytes, BASE_BYTES + 1450.0 * 1e6);
    let limited = MemoryEstimate {
        available: Some(1e9),
        ..recorded
    };
    // (1e9 − 16e6) / 1450 bodies fit when recorded.
    let e = limited.check().unwrap_err();
    assert!(
        e.contains("1450 B per body") && e.contains("N ≤ 6.786e5"),
        "{e}"
    );
}

#[test]
fn runs_held_at_once_multiply_the_estimate_and_the_refusal_says_how_many_fit() {
    let mut scenario = Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick_demo.json"),
    )
    .unwrap();
    scenario.cloud.count = 1_000_000;
    // 3 runs on 8 threads: 3 at once; 20 runs on 4 threads: 4.
    let three = MemoryEstimate::of_runs(&scenario, 3, 8);
    assert_eq!(
        (three.runs_at_once, three.bytes),
        (3, BASE_BYTES + 3.0 * 650e6)
    );
    let four = MemoryEstimate::of_runs(&scenario, 20, 4);
    assert_eq!(four.runs_at_once, 4);
    // (1.5e9 − 16e6) / 650e6 = 2.28: two runs fit, not four.
    let e = MemoryEstimate {
        available: Some(1.5e9),
        ..four
    }
    .check()
    .unwrap_err();
    assert!(
        e.contains("4 runs at once") && e.contains("at most 2 runs") && e.contains("650 B"),
        "{e}"
    );
}

#[test]
fn this_machine_reports_its_available_memory() {
    let a = available_bytes().expect("Linux has MemAvailable");
    assert!(a > 1e6, "{a}");
}
