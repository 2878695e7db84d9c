//! `agglo.kernel.measure`: the collision kernel of `agglo kernel` from Python — the same
//! library calls (`agglo::kernel::measure`, `write_files`), with the GIL released.

use std::path::PathBuf;

use pyo3::prelude::*;

use agglo::kernel::{self, MassGrid, Sampling, Window};

use crate::errors::{agglo_error, guard, scenario_error};
use crate::scenario::Scenario;

/// Run `scenario` over `seeds` seeds (its own, then the next ones) on `threads` threads
/// and write the kernel file `out` (.npz; and the long table `parquet`), exactly as
/// `agglo kernel SCENARIO --bins BINS --seeds SEEDS` does.
#[pyfunction]
#[pyo3(signature = (scenario, bins, out, seeds=8, threads=0, window=(0.0, f64::INFINITY), cgs=false, parquet=None))]
#[allow(clippy::too_many_arguments)]
pub fn measure_kernel(
    py: Python<'_>,
    scenario: &Scenario,
    bins: &str,
    out: PathBuf,
    seeds: u32,
    threads: usize,
    window: (f64, f64),
    cgs: bool,
    parquet: Option<PathBuf>,
) -> PyResult<()> {
    guard(|| {
        let s = &scenario.inner;
        if seeds == 0 {
            return Err(scenario_error("kernel: seeds: at least 1"));
        }
        let grid = MassGrid::for_scenario(bins, s)
            .map_err(|e| scenario_error(format!("kernel: bins: {e}")))?;
        let window = Window::new(window.0, window.1)
            .map_err(|e| scenario_error(format!("kernel: window: {e}")))?;
        // Refused before the seeds are listed or any run starts (issue 39: 2**32 − 1
        // seeds killed the interpreter; a missing directory lost the measurement).
        kernel::check_seeds(seeds, &grid)
            .map_err(|e| scenario_error(format!("kernel: seeds: {e}")))?;
        kernel::write::check_writable(&out, "out").map_err(agglo_error)?;
        if let Some(path) = &parquet {
            kernel::write::check_writable(path, "parquet").map_err(agglo_error)?;
        }
        let seed_list = kernel::seeds(s, seeds);
        py.detach(|| {
            let workers = agglo::farm::Workers::local(threads);
            let acc = kernel::measure(
                s,
                &grid,
                window,
                Sampling::default(),
                &seed_list,
                &workers,
                |_| {},
            )?;
            kernel::write_files(&acc, s, cgs, &out, parquet.as_deref())
        })
        .map_err(agglo_error)
    })
}
