//! Unit tests of `kernel::grid` (src/kernel/grid.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::kernel::grid::*;

#[test]
fn dustpy_default_grid_has_dustpys_length() {
    // DustPy's defaults mmin = 1e-12 g, mmax = 1e5 g, Nmbpd = 7: 17 decades → 120 points.
    let g = MassGrid::parse("dustpy:1e-12,1e5,7", 1000.0).unwrap();
    assert_eq!(g.classes(), 120);
    assert!((g.centres[0] - 1e-15).abs() < 1e-27);
    assert!((g.centres[119] / 1e2 - 1.0).abs() < 1e-12);
    // Each point lies inside its own class.
    for (k, &m) in g.centres.iter().enumerate() {
        assert_eq!(g.class_of(m), Some(k));
    }
}

#[test]
fn edges_are_half_open() {
    let g = MassGrid::parse("edges:1,2,4", 1.0).unwrap();
    assert_eq!(g.class_of(1.0), Some(0));
    assert_eq!(g.class_of(2.0), Some(1));
    assert_eq!(g.class_of(3.999), Some(1));
    assert_eq!(g.class_of(4.0), None);
    assert_eq!(g.class_of(0.5), None);
}
