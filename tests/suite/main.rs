//! The integration tests, one module per theme, linked into one test binary.
//!
//! One binary instead of one per file: each integration-test binary links the whole
//! engine, and linking eighteen of them dominated a fresh `cargo test`. A theme is
//! still run on its own with `cargo test --test suite THEME::` (e.g. `record::`).
//! `tests/mpi.rs` stays apart: it is built only with `--features mpi`.

mod common;

mod carried;
mod cli;
mod closed_form;
mod conservation;
mod damaged_input;
mod determinism;
mod docs;
mod door_refusals;
mod energy_ledgers;
mod events;
mod extension;
mod extension_binary;
mod fields;
mod first_day;
mod fuzz;
mod fuzz_doors;
mod hooks;
mod initial_data;
mod internals;
mod inverse;
mod kernel;
mod kernel_harden;
mod layout;
mod live;
mod outcome;
mod outputs;
mod pipeline_from_outside;
mod properties;
mod readings;
mod record;
mod restart;
mod rigid;
mod scenario_input;
mod scenarios;
mod self_contained;
mod signals;
mod stepping;
mod study;
mod subgrid;
mod subgrid_harden;
mod subgrid_persist;
mod subgrid_structure;
mod subgrid_unbiased;
mod unfinishable_runs;
mod walls;
mod worked_examples;
mod world_memory;
mod writers;
