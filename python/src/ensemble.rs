//! `agglo.ensemble`: one scenario over many seeds on the task farm (Rust threads), one
//! summary per seed — the same numbers for any thread count, and the same as
//! `agglo run --seed k` for each seed k — and, if asked, each run's tables.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use agglo::farm::{Workers, map};
use agglo::observables::Summary;
use agglo::output::table::read_table;
use agglo::run::{Run, RunPlan, Until};

use crate::errors::{agglo_error, guard, scenario_error};
use crate::scenario::Scenario;

/// Run `scenario` once per seed of `seeds` on `threads` threads (0: one per core), with
/// the GIL released. Returns, in the order of `seeds`, each run's summary as JSON text
/// and the tables named in `tables` (series, sizes, snapshots, collisions) as dicts of
/// columns, sampled on the scenario's `output.sampling`. The scenario's own output
/// paths are not written (each run would overwrite them), nor are its checkpoints.
#[pyfunction]
#[pyo3(signature = (scenario, seeds, threads=0, tables=Vec::new()))]
pub fn ensemble<'py>(
    py: Python<'py>,
    scenario: &Scenario,
    seeds: Vec<u64>,
    threads: usize,
    tables: Vec<String>,
) -> PyResult<Vec<(String, Bound<'py, PyDict>)>> {
    guard(|| {
        if seeds.is_empty() {
            return Err(scenario_error("ensemble: seeds: at least one seed"));
        }
        agglo::farm::check_threads(threads)
            .map_err(|e| scenario_error(format!("ensemble: threads: {e}")))?;
        let names = RunPlan::table_names();
        for name in &tables {
            if !names.contains(&name.as_str()) {
                return Err(scenario_error(format!(
                    "ensemble: tables: no table `{name}` (allowed: {})",
                    names.join(", ")
                )));
            }
        }
        let mut base = scenario.inner.clone();
        base.output = base.output.without_files();
        // Checked once here, so that a scene that cannot be built fails before any run.
        base.pipeline().map_err(scenario_error)?;
        // The scenes the threads hold at once must fit together, not only one by one.
        agglo::memory::MemoryEstimate::of_runs(&base, seeds.len(), threads)
            .check()
            .map_err(|e| scenario_error(format!("ensemble: {e}")))?;
        let dir = std::env::temp_dir().join(format!(
            "agglo-py-ensemble-{}-{:x}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos())
        ));
        let table_path =
            |index: usize, name: &str| -> PathBuf { dir.join(format!("{index}-{name}.parquet")) };
        if !tables.is_empty() {
            std::fs::create_dir_all(&dir)
                .map_err(|e| agglo_error(anyhow::anyhow!("creating {}: {e}", dir.display())))?;
        }
        let tasks: Vec<(usize, u64)> = seeds.iter().copied().enumerate().collect();
        let results = py.detach(|| {
            let work = |&(index, seed): &(usize, u64)| -> Result<Summary, String> {
                let mut s = base.clone();
                s.seed = seed;
                let mut plan = RunPlan::new(s).map_err(|e| format!("{e:#}"))?;
                // One run of many: its memory was checked above with the others held at
                // once, and a clamping warning per run would repeat the same line.
                plan.one_of_many = true;
                for name in &tables {
                    plan.set_table(name, table_path(index, name))
                        .map_err(|e| format!("{e:#}"))?;
                }
                let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
                let mut run = Run::start(plan, stop).map_err(|e| format!("{e:#}"))?;
                let outcome = run.advance(Until::End, &mut |_| std::ops::ControlFlow::Continue(()));
                let end = run.finish(&outcome);
                outcome.map_err(|e| format!("seed {seed}: {e}"))?;
                if let Some(e) = end.output_error {
                    return Err(format!("seed {seed}: {e:#}"));
                }
                Ok(end.summary)
            };
            map(&Workers::local(threads), tasks.clone(), &work)
        });
        let outcome = (|| {
            let results = results.map_err(|e| agglo_error(anyhow::anyhow!("ensemble: {e}")))?;
            let mut out = Vec::with_capacity(results.len());
            for (index, r) in results.into_iter().enumerate() {
                let summary = r.map_err(|e| agglo_error(anyhow::anyhow!("ensemble: {e}")))?;
                let json = serde_json::to_string(&summary).map_err(|e| agglo_error(e.into()))?;
                let read = PyDict::new(py);
                for name in &tables {
                    let table = read_table(&table_path(index, name)).map_err(agglo_error)?;
                    read.set_item(name, crate::columns::table_columns(py, table)?)?;
                }
                out.push((json, read));
            }
            Ok(out)
        })();
        if !tables.is_empty() {
            let _ = std::fs::remove_dir_all(&dir);
        }
        outcome
    })
}
