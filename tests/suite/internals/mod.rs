//! Unit tests of the library's inner pieces (helpers, parsers, small state machines),
//! one file per source module. They live here rather than in `#[cfg(test)]` modules so
//! that `cargo test` compiles the library once: a unit-test harness compiles the whole
//! library again, and on two cores that was ~45 s of a fresh `cargo test` (docs/speed.md).

mod cli_live;
mod farm;
mod huge_pages;
mod inverse_genes;
mod kernel_estimate;
mod kernel_grid;
mod live;
mod live_handshake;
mod live_run;
mod memory;
mod output_offload;
mod output_parquet_sink;
mod output_sampling;
mod output_step_tables_impact_speeds;
mod plugins;
mod record;
mod record_chunk;
mod record_inspect;
mod record_layout;
mod record_writer;
mod restart;
mod run_clamp_watch;
mod run_progress;
mod study;
mod study_readings;
mod subgrid_lift;
mod subgrid_memory;
mod subgrid_structure;

/// The library is built without a unit-test harness (Cargo.toml, `[lib] test = false`),
/// so a `#[test]` written under src/ would compile and never run. Every Rust file of the
/// library is read here and none may hold one; the tests of its inner pieces belong in
/// this directory.
#[test]
fn the_library_holds_no_unit_tests_that_would_never_run() {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = vec![src];
    let mut read = 0;
    let mut offenders = Vec::new();
    while let Some(path) = files.pop() {
        if path.is_dir() {
            files.extend(std::fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()));
        } else if path.extension().is_some_and(|e| e == "rs") {
            read += 1;
            let text = std::fs::read_to_string(&path).unwrap();
            if text.lines().any(|l| {
                let l = l.trim();
                l == "#[test]" || l.starts_with("#[cfg(") && l.contains("test")
            }) {
                offenders.push(path.display().to_string());
            }
        }
    }
    // The library has about ninety files: the walk saw them, not an empty tree.
    assert!(read > 50, "read only {read} files under src/");
    assert!(
        offenders.is_empty(),
        "unit tests under src/ never run (the library has no test harness); move them to \
         tests/suite/internals/: {offenders:?}"
    );
}
