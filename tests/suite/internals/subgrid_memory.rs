//! Unit tests of `subgrid::memory` (src/subgrid/memory.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::subgrid::memory::*;

#[test]
fn a_box_that_does_not_fit_is_refused_with_the_estimate() {
    // 1e7 bodies in one box: 16 MB + 1e7 × 1000 B = 10.0 GB, against 4 GB.
    let e = check_memory(3, 1e7, 1, 0, Some(4e9))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("cell 3: bodies = 1.000e7 per box (1 boxes running at once"),
        "{e}"
    );
    assert!(
        e.contains("about 10.0 GB") && e.contains("1000 B per body"),
        "{e}"
    );
    // (4e9 − 16e6) / 1000 bodies fit.
    assert!(e.contains("at most 3.984e6 bodies"), "{e}");
    // Two threads and four kept boxes: 2 × 1000 + 4 × 120 B per body, 2.5 GB for
    // 1e6 bodies, against 2 GB; without the kept boxes 2.0 GB fits in 4 GB.
    let e = check_memory(3, 1e6, 2, 4, Some(2e9))
        .unwrap_err()
        .to_string();
    assert!(e.contains("2480 B per body"), "{e}");
    assert!(check_memory(3, 1e6, 2, 0, Some(4e9)).is_ok());
    assert!(check_memory(3, 1e12, 1, 0, None).is_ok());
}
