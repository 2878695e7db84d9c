//! `agglo._agglo`: the compiled half of the Python package `agglo` (python/agglo/ is
//! the other half). A thin layer over the library: scenarios are `agglo::scenario`'s,
//! runs are `agglo::run`'s — the same code `agglo run` calls, so a run started here
//! writes the same bytes — and results leave as NumPy arrays built once in Rust.
//!
//! No Rust panic crosses into Python: every entry point runs under
//! [`errors::guard`], which turns a panic into `agglo.AggloError`.

mod carry;
mod columns;
mod ensemble;
mod errors;
mod hooks;
mod kernel;
mod scenario;
mod simulation;
mod subgrid;

use pyo3::prelude::*;

/// The allocator of the `agglo` binary (large blocks on transparent huge pages): the
/// engine's scattered reads of large clouds then miss the TLB as rarely as they do in
/// `agglo run`. It serves the Rust side only; Python keeps its own.
#[global_allocator]
static ALLOCATOR: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;

#[pymodule]
fn _agglo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("ScenarioError", py.get_type::<errors::ScenarioError>())?;
    m.add("AggloError", py.get_type::<errors::AggloError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<scenario::Scenario>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_function(wrap_pyfunction!(ensemble::ensemble, m)?)?;
    m.add_function(wrap_pyfunction!(columns::table_units, m)?)?;
    m.add_function(wrap_pyfunction!(kernel::measure_kernel, m)?)?;
    m.add_class::<subgrid::Coupling>()?;
    m.add_class::<subgrid::CellState>()?;
    Ok(())
}
