//! Issue 39's `agglo kernel` findings: sizes that aborted or hung (seeds, speed samples,
//! speed pairs) refused with the estimate or the range before anything is allocated; an
//! output directory that is missing refused before the first seed runs; converted grids
//! whose masses underflow refused naming the grid.

use std::process::{Command, Output};

use agglo::kernel::{self, MAX_SPEED_PAIRS, MAX_SPEED_SAMPLES, MassGrid, Sampling};

/// `agglo kernel scenarios/quick_demo.json` with `args` (one class around its grains
/// unless `args` give --bins), in the repository.
fn agglo_kernel(args: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_agglo"));
    command.args(["kernel", "scenarios/quick_demo.json"]);
    if !args.contains(&"--bins") {
        command.args(["--bins", "edges:1e-9,1"]);
    }
    command
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

fn refused(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    stderr
}

#[test]
fn an_ensemble_that_cannot_fit_is_refused_with_its_estimate_before_the_seeds_are_listed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("k.npz");
    let out = out.to_str().unwrap();
    // 4294967295 seeds aborted allocating their 34 GB list; each run's accumulator on one
    // class is 720 B, 3.1 TB in all.
    let stderr = refused(&agglo_kernel(&["--seeds", "4294967295", "--out", out]));
    assert!(
        stderr.contains("--seeds 4294967295: 4294967295 seeds need about 3092.4 GB")
            && stderr.contains("(720 B per run on 1 classes)"),
        "{stderr}"
    );
    assert!(!std::path::Path::new(out).exists());
    // The library refuses the same for Python's kernel.measure(seeds=2**32 - 1).
    let grid = MassGrid::parse("edges:1e-9,1", 1000.0).unwrap();
    assert_eq!(kernel::run_bytes(1), 720.0);
    assert!(kernel::check_seeds(u32::MAX, &grid).is_err());
    assert!(kernel::check_seeds(1000, &grid).is_ok());
}

#[test]
fn speed_samples_and_pairs_beyond_their_range_are_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("k.npz");
    let out = out.to_str().unwrap();
    // 4e9 sample times aborted allocating 32 GB; 4e9 pairs hung drawing them.
    let stderr = refused(&agglo_kernel(&[
        "--speed-samples",
        "4000000000",
        "--out",
        out,
    ]));
    assert!(
        stderr.contains("--speed-samples 4000000000: allowed 1 to 1000000"),
        "{stderr}"
    );
    let stderr = refused(&agglo_kernel(&[
        "--speed-pairs",
        "4000000000",
        "--out",
        out,
    ]));
    assert!(
        stderr.contains("--speed-pairs 4000000000: allowed 1 to 4096"),
        "{stderr}"
    );
    // The limits themselves are accepted.
    let at_limit = Sampling {
        times: MAX_SPEED_SAMPLES,
        pairs: MAX_SPEED_PAIRS,
    };
    assert_eq!(at_limit.check(), Ok(()));
    let e = Sampling {
        pairs: MAX_SPEED_PAIRS + 1,
        ..at_limit
    }
    .check()
    .unwrap_err();
    assert!(e.contains("every pair of the 64 bodies"), "{e}");
}

#[test]
fn an_output_in_a_missing_directory_is_refused_before_any_seed_runs() {
    for args in [
        ["--out", "/missing/k.npz", "--seeds", "3"],
        ["--out", "k_unused.npz", "--parquet", "/missing/k.parquet"],
    ] {
        let stderr = refused(&agglo_kernel(&args));
        assert!(
            stderr.contains(" /missing/k.")
                && stderr.contains("the directory /missing does not exist"),
            "{stderr}"
        );
        // No run started (each run prints a line `run i/S …` to stderr).
        assert!(!stderr.contains("run 1/"), "{stderr}");
    }
    assert!(
        !std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("k_unused.npz")
            .exists()
    );
}

#[test]
fn converted_grids_whose_masses_underflow_are_refused_naming_the_grid() {
    let parse_error = |spec: &str| MassGrid::parse(spec, 1000.0).unwrap_err().to_string();
    // ρπd³/6 of d = 1e-200 m is 0: the edges were NaN.
    let e = parse_error("openfoam:1e-200,2e-200,3e-200");
    assert!(
        e.starts_with("--bins openfoam: point 0 is 0e0 kg after conversion"),
        "{e}"
    );
    // Two diameters whose masses round to the same number.
    let e = parse_error("openfoam:1e-3,1.0000000000000001e-3");
    assert!(e.starts_with("--bins openfoam:"), "{e}");
    // DustPy's mmin in grams, 5e-324 g, is 0 kg.
    let e = parse_error("dustpy:5e-324,1e-300,1");
    assert!(e.starts_with("--bins dustpy: point 0 is 0e0 kg"), "{e}");
    // An mmax whose log10 is mmin's: one point, which panicked indexing the second.
    let e = parse_error("dustpy:1e300,1.0000000000000002e300,7");
    assert!(
        e.starts_with("--bins dustpy: mmax: allowed a decade's fraction"),
        "{e}"
    );
    // Sound grids still parse, with every edge finite and increasing (at 1e-303 kg the
    // midpoints √(m_k m_k+1) underflowed to 0 before: refused as a converted grid).
    for spec in ["openfoam:1e-6,2e-6,4e-6", "dustpy:1e-300,1e-290,1"] {
        let grid = MassGrid::parse(spec, 1000.0).unwrap();
        assert!(
            grid.edges
                .windows(2)
                .all(|w| w[0].is_finite() && w[0] > 0.0 && w[1] > w[0]),
            "{spec}: {:?}",
            grid.edges
        );
    }
    // From the command line: named, exit 1, before any run.
    let stderr = refused(&agglo_kernel(&[
        "--bins",
        "openfoam:1e-200,2e-200",
        "--out",
        "/missing/k.npz",
    ]));
    assert!(stderr.contains("--bins openfoam: point 0"), "{stderr}");
}
