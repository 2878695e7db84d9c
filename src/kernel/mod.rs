//! Measured collision kernels for coagulation codes (`agglo kernel`; issue 30,
//! docs/outputs.md "agglo kernel", docs/model.md §14 for the ballistic check).
//!
//! Codes that integrate the Smoluchowski equation — DustPy, the population-balance
//! modules of CFD codes — read a collision kernel K_ij and outcome probabilities per
//! pair of mass classes. This module measures them from simulated collisions on the
//! consumer's grid ([`MassGrid`]): an [`Accumulator`] gathers, during a run, the impact
//! counts per outcome and the exposure of every pair of classes (exact on the event
//! core, O(classes) per merge or fragmentation, nothing per step otherwise); runs,
//! seeds and windows pool by adding; [`Estimate`] turns the pooled sums into the
//! kernel, its errors and the rest, and [`write`] stores them as `.npz` and as a long
//! table. [`measure`] runs an ensemble of seeds on the task farm, pooled in seed order,
//! so the file is the same for any number of threads.
//!
//! ```no_run
//! use agglo::kernel::{self, Accumulator, Estimate, MassGrid, Sampling, Window};
//! use agglo::prelude::*;
//! let scenario = Scenario::load(std::path::Path::new("scenarios/ballistic_aggregation.json"))?;
//! let grid = MassGrid::parse("dustpy:1e-5,1,7", scenario.material.rho)?;
//! let acc = kernel::measure(&scenario, &grid, Window::default(), Sampling::default(),
//!     &kernel::seeds(&scenario, 4), &agglo::farm::Workers::local(0), |_| {})?;
//! let k = Estimate::of(&acc);
//! println!("K_00 = {:e} m³/s", k.floats("kernel")[0]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod accumulator;
#[doc(hidden)]
pub mod estimate;
#[doc(hidden)]
pub mod grid;
mod observer;
pub mod write;

pub use accumulator::{
    Accumulator, KernelError, MAX_SPEED_PAIRS, MAX_SPEED_SAMPLES, MEMBERS_PER_CLASS, OUTCOMES,
    RESAMPLE_FRACTION, RunMoments, Sampling, Tally, Window, subscribe,
};
pub use estimate::{
    Array, ArraySpec, CONVENTION, Data, Dim, Estimate, KERNEL_ARRAYS, ZERO_COUNT_UPPER_95, wilson,
};
pub use grid::{GridError, GridKind, MAX_CLASSES, MassGrid, dustpy_mass_grid};
pub use observer::KernelObserver;

use crate::farm::Workers;
use crate::run::{Run, RunPlan};
use crate::scenario::Scenario;
use crate::schedule::Simulation;

/// Bytes one run's accumulator holds until the ensemble is pooled, on `classes`
/// classes [B]: per pair of classes its tally (3 counts, exposure, 4 speed sums,
/// fragment mass, 3 relative-speed sums, draws: 104 B) and moments (9 sums: 72 B); the
/// grid (16 B per class); 512 B for the seed, the task and the result's slot.
pub fn run_bytes(classes: usize) -> f64 {
    let pairs = (classes * classes) as f64;
    176.0 * pairs + 16.0 * (classes as f64 + 1.0) + 512.0
}

/// Refuse an ensemble of `count` runs on `grid` whose accumulators, held until they are
/// pooled in seed order, do not fit the memory available now — before the seeds are
/// listed (4294967295 seeds aborted allocating 34 GB).
pub fn check_seeds(count: u32, grid: &MassGrid) -> Result<(), String> {
    let per_run = run_bytes(grid.classes());
    crate::memory::fits("seeds", count as usize, count as f64 * per_run)
        .map_err(|e| format!("{e} ({per_run:.0} B per run on {} classes)", grid.classes()))
}

/// The seeds of an ensemble of `count` runs: the scenario's seed, then the next ones
/// (each run can be repeated alone with `agglo run --seed`).
pub fn seeds(scenario: &Scenario, count: u32) -> Vec<u64> {
    (0..count as u64)
        .map(|s| scenario.seed.wrapping_add(s))
        .collect()
}

/// The scenario's simulation with the built-in physics and the registered extensions,
/// collecting what an [`Accumulator`] reads, for a program that steps it itself (runs
/// of `agglo kernel` and subgrid boxes go through [`crate::run::Run`] with a
/// [`KernelObserver`]).
pub fn simulation(scenario: &Scenario) -> Result<Simulation, crate::error::SimError> {
    let mut builder = crate::plugins::builder(scenario)?;
    subscribe(&mut builder);
    builder.build()
}

/// Run `scenario` with `seed` to its end, accumulating on `grid`.
pub fn measure_one(
    scenario: &Scenario,
    grid: &MassGrid,
    window: Window,
    sampling: Sampling,
    seed: u64,
) -> anyhow::Result<Accumulator> {
    let mut scenario = scenario.clone();
    scenario.seed = seed;
    sampling.check().map_err(anyhow::Error::msg)?;
    let (observer, result) = KernelObserver::new(Accumulator::new(grid.clone(), window, sampling));
    let (end, outcome) = Run::complete(RunPlan::unwritten(scenario), vec![Box::new(observer)])?;
    // The accumulator's refusal first: it stopped the run.
    if let Some(e) = end.output_error {
        return Err(e);
    }
    outcome.map_err(|e| anyhow::Error::new(e).context(format!("running seed {seed}")))?;
    result
        .take()
        .ok_or_else(|| anyhow::anyhow!("seed {seed}: the run ended without its kernel"))
}

/// Run `scenario` once per seed on `workers` and pool the runs in seed order (so the
/// result does not depend on the number of workers). `progress` gets a line per run.
pub fn measure(
    scenario: &Scenario,
    grid: &MassGrid,
    window: Window,
    sampling: Sampling,
    seeds: &[u64],
    workers: &Workers,
    mut progress: impl FnMut(&str),
) -> anyhow::Result<Accumulator> {
    sampling.check().map_err(anyhow::Error::msg)?;
    let count = u32::try_from(seeds.len()).unwrap_or(u32::MAX);
    check_seeds(count, grid).map_err(anyhow::Error::msg)?;
    // The scenes the workers hold at once (unchecked, 3e8 bodies aborted where `agglo
    // run` refuses them).
    if let Some(warning) =
        crate::memory::MemoryEstimate::of_runs(scenario, seeds.len(), workers.threads)
            .check()
            .map_err(anyhow::Error::msg)?
    {
        progress(&warning);
    }
    let work = |seed: &u64| -> Result<Accumulator, String> {
        measure_one(scenario, grid, window, sampling, *seed).map_err(|e| format!("{e:#}"))
    };
    let total = seeds.len();
    let mut done = 0;
    let results = crate::farm::map_with_progress(workers, seeds.to_vec(), &work, |_, r| {
        done += 1;
        match r {
            Ok(acc) => progress(&format!(
                "run {done}/{total} (seed {}): {} impacts in the window",
                acc.seeds.first().copied().unwrap_or(0),
                (0..acc.classes() * acc.classes())
                    .map(|p| acc.pooled.total(p))
                    .sum::<u64>()
            )),
            Err(e) => progress(&format!("run {done}/{total} failed: {e}")),
        }
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut pooled = Accumulator::new(grid.clone(), window, sampling);
    for (seed, result) in seeds.iter().zip(results) {
        let acc = result.map_err(|e| anyhow::anyhow!("seed {seed}: {e}"))?;
        pooled.merge(&acc)?;
    }
    Ok(pooled)
}

/// Write the estimate of `acc` to `npz` (and the long table to `long`, if given), in
/// SI or cgs, with `scenario` as provenance.
pub fn write_files(
    acc: &Accumulator,
    scenario: &Scenario,
    cgs: bool,
    npz: &std::path::Path,
    long: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    let arrays = Estimate::of(acc).into_arrays(cgs, &scenario.to_json(), &acc.grid.spec);
    write::write_npz(npz, &arrays)?;
    if let Some(path) = long {
        write::write_long(path, &arrays)?;
    }
    Ok(())
}
