//! The exceptions of the module, and the guard that keeps panics on the Rust side.
//!
//! `ScenarioError` (a `ValueError`): a scenario that cannot be read or is out of range;
//! its message names the field path and the allowed range, as `agglo validate` does.
//! `AggloError` (a `RuntimeError`): anything else that went wrong in a run (an output
//! that cannot be written, a run that failed), with its causes.

use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(agglo, ScenarioError, PyValueError);
pyo3::create_exception!(agglo, AggloError, PyRuntimeError);

/// A scenario error, with its causes (`{:#}`, as the command line prints them).
pub fn scenario_error(e: impl std::fmt::Display) -> PyErr {
    ScenarioError::new_err(format!("{e:#}"))
}

/// Any other error of the library, with its causes.
pub fn agglo_error(e: anyhow::Error) -> PyErr {
    AggloError::new_err(format!("{e:#}"))
}

/// Run `f`, turning a Rust panic into `AggloError` (the panic's message included):
/// a bug in agglo must not take the interpreter down or surface as a bare
/// `PanicException`.
pub fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => {
            let message = agglo::farm::panic_message(payload.as_ref());
            Err(AggloError::new_err(format!(
                "internal error (a bug in agglo, please report it): {message}"
            )))
        }
    }
}
