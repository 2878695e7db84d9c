//! The integration tests of the program's doors, one module per theme, linked into one
//! test binary: the CLI and its refusals, scenario input and damaged files, the output
//! tables and recordings, the live view, signals and restart, first-day use, and the docs'
//! claims checked against the program. The model's own tests are in `tests/suite/`; the
//! two binaries compile side by side (see `tests/suite/main.rs`). One theme:
//! `cargo test --test interfaces THEME::` (e.g. `record::`).

#[path = "../common/mod.rs"]
mod common;

mod cli;
mod damaged_input;
mod docs;
mod door_refusals;
mod extension_binary;
mod first_day;
mod fuzz;
mod fuzz_doors;
mod initial_data;
mod layout;
mod live;
mod outputs;
mod record;
mod restart;
mod scenario_input;
mod scenarios;
mod self_contained;
mod signals;
mod unfinishable_runs;
mod world_memory;
mod writers;
