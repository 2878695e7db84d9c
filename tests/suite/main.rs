//! The integration tests of the model, one module per theme, linked into one test binary:
//! physics against closed forms and conservation laws, the event and stepped cores, fields,
//! extensions, kernels, the subgrid coupling, rigid aggregates, the inverse problem, and
//! the library's inner pieces (`internals`). Their twin, `tests/interfaces/`, tests the
//! program's doors (CLI, files, recordings, live view, signals, restart, the docs).
//!
//! Two binaries rather than one per file or one in all: each integration-test binary links
//! the whole engine, so eighteen of them made linking dominate a fresh `cargo test`; but one
//! binary is compiled by one rustc, mostly on one core, at the end of the build. Two halves
//! compile side by side on a two-core machine. A theme still runs on its own with
//! `cargo test --test suite THEME::` (e.g. `subgrid::`). `tests/mpi.rs` stays apart: it is
//! built only with `--features mpi`.

#[path = "../common/mod.rs"]
mod common;

mod carried;
mod closed_form;
mod conservation;
mod determinism;
mod energy_ledgers;
mod events;
mod extension;
mod fields;
mod hooks;
mod internals;
mod inverse;
mod kernel;
mod kernel_harden;
mod outcome;
mod pipeline_from_outside;
mod properties;
mod readings;
mod rigid;
mod stepping;
mod study;
mod subgrid;
mod subgrid_harden;
mod subgrid_persist;
mod subgrid_structure;
mod subgrid_unbiased;
mod walls;
mod worked_examples;
