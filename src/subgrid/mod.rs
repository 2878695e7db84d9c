//! `agglo::subgrid`: agglo inside a flow solver — a box advanced over each cell's
//! macro time step, homogenized results back (P04 §9; issue 32; the exchange is
//! docs/model.md §15, the user's guide docs/coupling.md).
//!
//! Shaped like the per-cell interface of coupling libraries (preCICE's Micro Manager
//! calls `solve(macro_data, dt) -> dict` with `get_state`/`set_state` per cell):
//!
//! - [`Coupling`] — the settings, the same for every cell: the base scenario
//!   (material, impact, physics, core), the class edges, N or a target standard error,
//!   the replicas K, whether cells keep their bodies;
//! - [`CellInput`] (macro → micro) — per class the number density, representative
//!   mass, mean velocity, temperature and granular temperature; the gas (velocity,
//!   temperature, drag); Δt;
//! - [`CellOutput`] (micro → macro) — per class the source rates of number, mass and
//!   momentum and the class state at the end; what the gas received; heat rates;
//!   impact, bond, bounce and fragment rates; each a [`Stat`] (mean and standard error
//!   over the K replicas); optionally the pooled kernel sums;
//! - [`advance_cell`] — one cell; [`advance_cells`] — a batch on the task farm;
//! - [`CellState`] — opaque, to bytes and back (`get_state`/`set_state`);
//! - [`SubgridError`] — names the cell and the field.
//!
//! ```no_run
//! use agglo::subgrid::*;
//! use agglo::prelude::*;
//! let base = Scenario::load(std::path::Path::new("scenarios/ballistic_aggregation.json"))?;
//! let m0 = base.primary_mass();
//! let coupling = Coupling::new(base, vec![0.5 * m0, 1.5 * m0, 2.5 * m0, 1e6 * m0])?;
//! let class = |n: f64, m: f64| ClassInput {
//!     number_density: n, mass: m, velocity: [0.0; 3], temperature: 300.0,
//!     granular_temperature: 1.0, granular_anisotropy: ISOTROPIC,
//! };
//! let input = CellInput {
//!     classes: vec![class(1e9, m0), class(0.0, 2.0 * m0), class(0.0, 3.0 * m0)],
//!     gas: GasState { velocity: [0.0; 3], temperature: 300.0, drag: None },
//!     dt: 1e-4,
//! };
//! let (out, state) = advance_cell(&coupling, 17, 0, &input, None)?;
//! println!("dn_0/dt = {:e} ± {:e} 1/(m³ s)", out.classes[0].number_rate.mean,
//!     out.classes[0].number_rate.se);
//! let bytes = state.to_bytes(); // get_state; CellState::from_bytes is set_state
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! **Determinism.** Replica r of cell c at macro step s is seeded by
//! [`replica_seed`]`(base.seed, c, s, r)` (a splitmix64 hash) and runs alone, so a
//! cell's output is the same bytes for any thread or rank count and any order of
//! submission.

mod adjust;
mod batch;
mod cell;
mod config;
mod error;
mod exchange;
#[doc(hidden)]
pub mod lift;
#[doc(hidden)]
pub mod memory;
pub mod profile;
mod restrict;
#[doc(hidden)]
pub mod stream;
#[doc(hidden)]
pub mod structure;

pub use adjust::apply_rates;
#[cfg(feature = "mpi")]
pub use batch::serve;
pub use batch::{ReplicaTask, VOLUME_TIME_RANGE, advance_cell, advance_cells, run_task};
pub use cell::{BoxStart, CellState, KeptBox, ReplicaRun, STATE_VERSION};
pub use config::{BoxSize, Coupling, MAX_BODIES, MAX_REPLICAS};
pub use error::SubgridError;
pub use exchange::{
    CellInput, CellOutput, ClassInput, ClassOutput, Column, GasState, ISOTROPIC, Stat,
};
pub use lift::{
    MAX_DIAMETER_PER_SIDE, MAX_VOLUME_FRACTION, SWEEPS_BELOW_IMPACTS, TRACE_BODIES, box_volume,
    check_box, check_input, draw_counts, expected_impact_density, is_trace, lift, lift_with_sweeps,
    radius_of, replica_seed,
};
pub use memory::{KEPT_BYTES_PER_BODY, LIFT_BYTES_PER_BODY, cell_bytes, check_memory};
pub use restrict::{ClassSums, Replica};
pub use structure::{EQUILIBRATE_FROM, STEP, SWEEPS};
