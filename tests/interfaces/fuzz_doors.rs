//! Fuzzing of the doors added since issue 33 (issue 39): `agglo kernel`'s grid, window
//! and sampling, and a subgrid cell's input and kept state. Like `fuzz.rs`, proptests
//! from a fixed seed over a seed corpus (`tests/fuzz_corpus/kernel_bins.txt`,
//! `cell_inputs.json`: the findings, replayed first), each case bounded in time
//! by `within_time`, and a few seconds a target in the debug build.
//!
//! The contract checked: an input is refused with an error naming it, or it runs — and
//! what runs never fails later naming the lifted box's internals (`cloud.bodies.59`,
//! `material.theta0`) instead of the cell's own field.

use std::path::{Path, PathBuf};

use agglo::kernel::{self, MAX_CLASSES, MassGrid, Sampling, Window};
use agglo::prelude::*;
use agglo::subgrid::*;
use proptest::prelude::*;
use serde_json::Value;

use crate::common::cells::{coupling, monomers};
use crate::fuzz::{apply, edits, extreme, fuzz_config, numeric_paths, set, within_time};

fn corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_corpus")
        .join(name)
}

fn seed_scenario() -> Scenario {
    Scenario::load(&corpus("scenario.json")).unwrap()
}

fn seed_bins() -> Vec<String> {
    std::fs::read_to_string(corpus("kernel_bins.txt"))
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

/// A grid that parsed is usable: at most MAX_CLASSES classes, finite increasing edges.
fn assert_usable(grid: &MassGrid, bins: &str) {
    assert!(
        grid.classes() >= 1 && grid.classes() <= MAX_CLASSES,
        "{bins}"
    );
    assert!(
        grid.edges.windows(2).all(|w| w[0] < w[1]) && grid.edges.iter().all(|e| e.is_finite()),
        "{bins}: {:?}",
        grid.edges
    );
}

/// One seed of the corpus scene (12 bodies, 0.4 ms) measured on `grid`: a result or an
/// error, in bounded time.
fn measure(grid: MassGrid, window: Window, sampling: Sampling, case: String) {
    within_time(case.clone(), move || {
        let s = seed_scenario();
        if let Ok(acc) = kernel::measure_one(&s, &grid, window, sampling, 3) {
            assert_eq!(acc.classes(), grid.classes(), "{case}");
        }
    });
}

/// The box internals a cell's error must not name (they are the lifted scene's paths).
const INTERNALS: [&str; 3] = ["cloud.bodies.", "material.theta0", "cloud.count"];

/// `input` advanced as cell 5 of `c` in bounded time: refused naming the cell, or run.
fn advance_or_refuse(c: Coupling, input: CellInput, state: Option<CellState>, case: String) {
    within_time(case.clone(), move || {
        match advance_cell(&c, 5, 1, &input, state.as_ref()) {
            Ok((out, _)) => assert!(out.box_volume.is_finite() && out.box_volume > 0.0, "{case}"),
            // A damaged state's bodies are the state's own: naming them is naming it.
            Err(e @ SubgridError::State { .. }) => {
                assert!(e.to_string().starts_with("cell 5: state: "), "{case}: {e}");
            }
            Err(e) => {
                let text = e.to_string();
                assert!(text.starts_with("cell 5"), "{case}: {text}");
                assert!(
                    INTERNALS.iter().all(|inside| !text.contains(inside)),
                    "{case}: the error names the box's internals, not the cell's field: {text}"
                );
            }
        }
    });
}

/// The seed cell: monomers at φ = 0.02 over 10 µs in boxes of 24 bodies, one replica.
fn seed_cell() -> (Coupling, Value) {
    let c = coupling(24, 1);
    let input = serde_json::to_value(monomers(&c, 0.02, 1e-5)).unwrap();
    (c, input)
}

/// The corpus's cell inputs (the findings), each refused by name or run.
#[test]
fn the_seed_cell_inputs_are_refused_by_name_or_run() {
    let patches: Vec<serde_json::Map<String, Value>> =
        serde_json::from_str(&std::fs::read_to_string(corpus("cell_inputs.json")).unwrap())
            .unwrap();
    let (c, good) = seed_cell();
    for patch in patches {
        let mut v = good.clone();
        for (path, value) in &patch {
            set(&mut v, path, value.clone());
        }
        let input: CellInput = serde_json::from_value(v).unwrap();
        advance_or_refuse(c.clone(), input, None, format!("{patch:?}"));
    }
    // And the corpus's grids all parse for the corpus scene.
    let s = seed_scenario();
    for bins in seed_bins() {
        let grid = MassGrid::for_scenario(&bins, &s).unwrap_or_else(|e| panic!("{bins}: {e}"));
        assert_usable(&grid, &bins);
    }
}

proptest! {
    #![proptest_config(fuzz_config())]

    /// `--bins`: the corpus grids mutated byte by byte, and grids built from extreme
    /// numbers; what parses is usable, and one seed of the corpus scene is measured on
    /// it with an extreme window and sampling.
    #[test]
    fn kernel_grids_windows_and_sampling_parse_or_are_refused(
        pick in any::<usize>(),
        e in edits(),
        numbers in proptest::collection::vec(extreme(), 1..5),
        kind in 0usize..4,
        window in (extreme(), extreme()),
        sampling in ((0u32..64), (0u32..300)),
    ) {
        let s = seed_scenario();
        let corpus = seed_bins();
        let mutated = String::from_utf8_lossy(
            &apply(corpus[pick % corpus.len()].as_bytes(), &e),
        ).into_owned();
        let listed: Vec<String> = numbers.iter().map(|x| x.to_string()).collect();
        let built = match kind {
            0 => format!("edges:{}", listed.join(",")),
            1 => format!("dustpy:{}", listed.join(",")),
            2 => format!("dustpy:primary,{}", listed.join(",")),
            _ => format!("openfoam:{}", listed.join(",")),
        };
        let (t0, t1) = (window.0.as_f64().unwrap_or(0.0), window.1.as_f64().unwrap_or(1.0));
        let sampling = Sampling { times: sampling.0, pairs: sampling.1 };
        for bins in [mutated, built] {
            let Ok(grid) = MassGrid::for_scenario(&bins, &s) else { continue };
            assert_usable(&grid, &bins);
            let Ok(window) = Window::new(t0.abs(), t1.abs()) else { continue };
            if sampling.check().is_ok() && sampling.times > 0 && sampling.pairs > 0 {
                measure(grid, window, sampling, format!("{bins} [{t0}, {t1}] {sampling:?}"));
            }
        }
    }
}

proptest! {
    #![proptest_config(fuzz_config())]

    /// A cell's input: one to three of the seed cell's numbers set to extreme values
    /// (signs, zeros, subnormals, 1e300, the ends of f64).
    #[test]
    fn cell_inputs_with_extreme_numbers_are_refused_by_name_or_run(
        picks in proptest::collection::vec((any::<usize>(), extreme()), 1..4),
    ) {
        let (c, mut v) = seed_cell();
        let mut paths = Vec::new();
        numeric_paths(&v, "", &mut paths);
        for (k, x) in &picks {
            set(&mut v, &paths[k % paths.len()], x.clone());
        }
        // JSON cannot hold NaN or ∞: those are the C and Python harnesses' to try.
        if let Ok(input) = serde_json::from_value::<CellInput>(v.clone()) {
            advance_or_refuse(c, input, None, v.to_string());
        }
    }

    /// A closed cell's kept state, edited and sealed again with its checksum (as a hand
    /// that edits a state would): refused on restore, or continued.
    #[test]
    fn edited_and_resealed_cell_states_are_refused_or_continue(e in edits()) {
        let (mut c, v) = seed_cell();
        c.keep_bodies = true;
        let input: CellInput = serde_json::from_value(v).unwrap();
        let (_, state) = advance_cell(&c, 5, 0, &input, None).unwrap();
        let bytes = state.to_bytes();
        let mut payload = apply(&bytes[..bytes.len() - 4], &e);
        let crc = crc32fast::hash(&payload);
        payload.extend_from_slice(&crc.to_le_bytes());
        if let Ok(edited) = CellState::from_bytes(&payload) {
            advance_or_refuse(c, input, Some(edited), format!("{e:?}"));
        }
        // Unsealed, any change is refused.
        let unsealed = apply(&bytes, &e);
        if unsealed != bytes {
            prop_assert!(CellState::from_bytes(&unsealed).is_err());
        }
    }
}
