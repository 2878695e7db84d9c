//! Advancing cells: one ([`advance_cell`]) or a macro step's batch on the task farm
//! ([`advance_cells`]: threads here, and every MPI rank under `mpirun`; [`serve`] on
//! the ranks other than 0). Each (cell, replica) box is one task — borrowed from the
//! caller's cells on this process's threads (`farm::map_local`), an owned copy sent as
//! bytes under MPI (`farm::map`), run by the same function; the results are put
//! together in cell and replica order, so they are the same bytes for any number of
//! threads or ranks and any order of the cells in the batch.

use serde::{Deserialize, Serialize};

use crate::farm::{Workers, thread_count};
use crate::kernel::Accumulator;
use crate::memory::available_bytes;

use super::adjust::apply_rates;
use super::cell::{CellState, KeptBox, ReplicaRun, STATE_VERSION, run_replica};
use super::config::Coupling;
use super::error::SubgridError;
use super::exchange::{CellInput, CellOutput};
use super::lift::{box_volume, check_box, check_input, is_trace};
use super::memory::check_memory;
use super::profile::{self, Part, timed};
use super::restrict::combine;

/// What a cell's step starts from, once its input and state are checked.
struct Prepared {
    volume: f64,
    /// The classes lifting skips as traces (none for kept boxes).
    ignored: Vec<bool>,
    time: f64,
    steps: u64,
}

/// Check `input` and `state` for `cell` and fix the box volume (a kept box's own).
/// `at_once` of the cell's boxes may run together and `available` bytes of memory are
/// free (memory.rs).
fn prepare(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    state: Option<&CellState>,
    at_once: usize,
    available: Option<f64>,
) -> Result<Prepared, SubgridError> {
    check_input(c, cell, input)?;
    if let Some(s) = state {
        s.check(c, cell)?;
    }
    let kept = state.filter(|s| (c.keep_bodies || c.persist) && s.keeps_bodies());
    let volume = match kept {
        Some(s) => s.volume,
        None => box_volume(c, cell, input)?,
    };
    check_step(cell, input.dt, volume, kept.map(|s| s.time))?;
    let ignored = match kept {
        Some(_) if !c.persist => vec![false; input.classes.len()],
        _ => {
            match kept.and_then(|s| s.expected.as_ref()) {
                // A kept box is only checked for what transport inserts into it: the
                // bodies it made itself (an aggregate grown beyond a quarter of the
                // side) are the closed cell's and stay.
                Some(expected) => check_box(c, cell, &inserted(input, expected), volume)?,
                None => check_box(c, cell, input, volume)?,
            };
            input
                .classes
                .iter()
                .map(|k| is_trace(k.number_density, volume))
                .collect()
        }
    };
    if kept.is_none() || c.persist {
        // A box lifted (or adjusted) to the input: its expected bodies and a Poisson
        // margin of 5 σ. A kept box continued as it is was checked when it was lifted.
        let lambda: f64 = input
            .classes
            .iter()
            .zip(&ignored)
            .filter(|&(_, &trace)| !trace)
            .map(|(k, _)| k.number_density * volume)
            .sum();
        let bodies = lambda + 5.0 * lambda.sqrt();
        let keeps = if c.keep_bodies || c.persist {
            c.replicas as usize
        } else {
            0
        };
        check_memory(cell, bodies, at_once, keeps, available)?;
    }
    Ok(Prepared {
        volume,
        ignored,
        time: state.map_or(0.0, |s| s.time),
        steps: state.map_or(0, |s| s.macro_steps),
    })
}

/// What an adjusted box receives: `input`'s classes that transport grew since
/// `expected` (the rest at density 0), the bodies lifting places among the kept ones.
fn inserted(input: &CellInput, expected: &CellInput) -> CellInput {
    let mut grown = input.clone();
    for (a, e) in grown.classes.iter_mut().zip(&expected.classes) {
        if *a == *e || a.number_density <= e.number_density {
            a.number_density = 0.0;
        } else {
            a.number_density -= e.number_density;
        }
    }
    grown
}

/// The range of V·Δt [m³ s] a step may have: every rate is a box sum times 1/(V·Δt)
/// (counts up to 1e7, masses, momenta, energies), so 1/(V·Δt) must stay far from
/// overflow (V·Δt = 5e-324 gave NaN rates) and from underflow to 0.
pub const VOLUME_TIME_RANGE: (f64, f64) = (1e-290, 1e290);

/// Refuse a Δt that no rate can be divided by in a box of `volume` [m³], or that is
/// lost against a kept box's clock `kept_time` [s] (time + Δt = time: the box would not
/// move; a box lifted afresh starts at 0).
fn check_step(cell: u64, dt: f64, volume: f64, kept_time: Option<f64>) -> Result<(), SubgridError> {
    let (lo, hi) = VOLUME_TIME_RANGE;
    let vdt = volume * dt;
    if !(lo..=hi).contains(&vdt) {
        return Err(SubgridError::input(
            cell,
            "dt",
            format!("{dt:e}"),
            format!(
                "with the box of {volume:e} m³, dt must lie in [{:e}, {:e}] s (V·dt in \
                 [{lo:e}, {hi:e}] m³ s: every rate is divided by it)",
                lo / volume,
                hi / volume
            ),
        ));
    }
    if let Some(time) = kept_time
        && time + dt == time
    {
        return Err(SubgridError::input(
            cell,
            "dt",
            format!("{dt:e}"),
            format!(
                "must be above about {:e} s: smaller steps are lost against the cell's time {time:e} \
                 s (time + dt = time)",
                time * f64::EPSILON
            ),
        ));
    }
    Ok(())
}

/// The cell's output and new state from its replicas' runs (in replica order).
fn finish(
    c: &Coupling,
    cell: u64,
    macro_step: u64,
    input: &CellInput,
    prepared: &Prepared,
    runs: Vec<ReplicaRun>,
) -> Result<(CellOutput, CellState), SubgridError> {
    let measured: Vec<_> = runs.iter().map(|r| r.measured.clone()).collect();
    let mut output = timed(Part::Restrict, || {
        combine(
            c,
            cell,
            macro_step,
            input,
            prepared.volume,
            &prepared.ignored,
            &measured,
        )
    });
    if c.kernel {
        let mut pooled: Option<Accumulator> = None;
        for run in &runs {
            let Some(acc) = &run.kernel else { continue };
            match &mut pooled {
                None => pooled = Some(acc.clone()),
                Some(p) => p.merge(acc).map_err(|e| SubgridError::Run {
                    cell,
                    replica: 0,
                    reason: format!("pooling the kernel: {e}"),
                })?,
            }
        }
        output.kernel = pooled;
    }
    let boxes: Vec<KeptBox> = runs.into_iter().filter_map(|r| r.kept).collect();
    let state = CellState {
        version: STATE_VERSION,
        cell,
        macro_steps: prepared.steps + 1,
        time: prepared.time + input.dt,
        volume: prepared.volume,
        boxes,
        expected: c.persist.then(|| apply_rates(c, input, &output)),
    };
    Ok((output, state))
}

/// Advance one cell over `input.dt`: K replica boxes, lifted from `input` (or, with
/// `keep_bodies` and a state, continued), run one after the other on this thread.
/// `macro_step` (any number the caller counts steps by) and `cell` seed the boxes with
/// the base seed ([`super::replica_seed`]). The same bytes as the cell's entry of
/// [`advance_cells`].
pub fn advance_cell(
    c: &Coupling,
    cell: u64,
    macro_step: u64,
    input: &CellInput,
    state: Option<&CellState>,
) -> Result<(CellOutput, CellState), SubgridError> {
    c.check()?;
    let prepared = timed(Part::Coupling, || {
        prepare(c, cell, input, state, 1, available_bytes())
    })?;
    let runs = (0..c.replicas)
        .map(|r| {
            let kept = kept_box(c, state, r);
            let expected = state.and_then(|s| s.expected.as_ref());
            run_replica(
                c,
                cell,
                macro_step,
                r,
                input,
                prepared.volume,
                kept,
                expected,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    timed(Part::Coupling, || {
        finish(c, cell, macro_step, input, &prepared, runs)
    })
}

fn kept_box<'a>(c: &Coupling, state: Option<&'a CellState>, replica: u32) -> Option<&'a KeptBox> {
    state
        .filter(|_| c.keep_bodies || c.persist)
        .and_then(|s| s.boxes.get(replica as usize))
}

/// One box of a batch as another MPI rank receives it: what it needs to run the box.
/// (On this process's threads a box runs from the caller's cells, without a copy.)
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReplicaTask {
    /// The cell's id (the flow solver's).
    pub cell: u64,
    /// The macro step's number as the caller counts them (with the cell and the
    /// replica it seeds the box).
    pub macro_step: u64,
    /// Which of the cell's K boxes, 0-based (it sets the box's seed).
    pub replica: u32,
    /// The cell's macro state for this step.
    pub input: CellInput,
    /// The box's volume [m³].
    pub volume: f64,
    /// The box as the last step left it (persistent or kept boxes), to resume.
    pub kept: Option<KeptBox>,
    /// With `persist`: the cell's remembered state the input is measured against.
    pub expected: Option<CellInput>,
}

/// The work of one task (the same function on every thread and rank).
pub fn run_task(c: &Coupling, t: &ReplicaTask) -> Result<ReplicaRun, SubgridError> {
    run_replica(
        c,
        t.cell,
        t.macro_step,
        t.replica,
        &t.input,
        t.volume,
        t.kept.as_ref(),
        t.expected.as_ref(),
    )
}

/// One box of a batch borrowed from the caller's cells: what [`ReplicaTask`] holds,
/// without copying the cell's input, kept box or remembered state.
struct BoxOfCell<'a> {
    cell: u64,
    replica: u32,
    input: &'a CellInput,
    volume: f64,
    kept: Option<&'a KeptBox>,
    expected: Option<&'a CellInput>,
}

impl BoxOfCell<'_> {
    /// Run the box ([`run_task`] on [`Self::task`] gives the same bytes).
    fn run(&self, c: &Coupling, macro_step: u64) -> Result<ReplicaRun, SubgridError> {
        run_replica(
            c,
            self.cell,
            macro_step,
            self.replica,
            self.input,
            self.volume,
            self.kept,
            self.expected,
        )
    }

    /// The box as an owned task, to send to another rank.
    fn task(&self, macro_step: u64) -> ReplicaTask {
        ReplicaTask {
            cell: self.cell,
            macro_step,
            replica: self.replica,
            input: self.input.clone(),
            volume: self.volume,
            kept: self.kept.cloned(),
            expected: self.expected.cloned(),
        }
    }
}

/// Advance a macro step's cells — (cell id, input, state or `None`) each — as
/// independent tasks on `workers`, one per (cell, replica). Results in the order of
/// `cells`, each as [`advance_cell`] would give it: a cell's bad input is that cell's
/// error and does not stop the others. A failure of the farm itself (a worker that
/// panicked, MPI) is every cell's error.
pub fn advance_cells(
    c: &Coupling,
    macro_step: u64,
    cells: &[(u64, CellInput, Option<CellState>)],
    workers: &Workers,
) -> Vec<Result<(CellOutput, CellState), SubgridError>> {
    if let Err(e) = c.check() {
        return cells.iter().map(|_| Err(e.clone())).collect();
    }
    let begun = profile::start();
    // Every thread may be running a box of the largest cell (an estimate per cell
    // against the memory free now, read once).
    let at_once = thread_count(workers.threads).min(cells.len() * c.replicas as usize);
    let available = available_bytes();
    let prepared: Vec<Result<Prepared, SubgridError>> = cells
        .iter()
        .map(|(cell, input, state)| prepare(c, *cell, input, state.as_ref(), at_once, available))
        .collect();
    let mut boxes = Vec::new();
    for ((cell, input, state), p) in cells.iter().zip(&prepared) {
        let Ok(p) = p else { continue };
        let expected = state.as_ref().and_then(|s| s.expected.as_ref());
        for replica in 0..c.replicas {
            boxes.push(BoxOfCell {
                cell: *cell,
                replica,
                input,
                volume: p.volume,
                kept: kept_box(c, state.as_ref(), replica),
                expected,
            });
        }
    }
    profile::add(Part::Coupling, begun);
    let results = match workers.cluster {
        // On this process's threads the boxes are run where they lie: no copy of a kept
        // box, no hand-over per box (farm/local.rs).
        None => crate::farm::map_local(workers.threads, &boxes, &|b: &BoxOfCell| {
            b.run(c, macro_step)
        }),
        // Other ranks need the tasks as bytes: owned copies.
        Some(_) => {
            let begun = profile::start();
            let tasks: Vec<ReplicaTask> = boxes.iter().map(|b| b.task(macro_step)).collect();
            profile::add(Part::Coupling, begun);
            let work = |t: &ReplicaTask| run_task(c, t);
            crate::farm::map(workers, tasks, &work)
        }
    };
    let results = match results {
        Ok(r) => r,
        Err(e) => {
            return cells
                .iter()
                .map(|(cell, ..)| {
                    Err(SubgridError::Farm {
                        cell: *cell,
                        reason: e.to_string(),
                    })
                })
                .collect();
        }
    };
    let begun = profile::start();
    let mut results = results.into_iter();
    let outputs = cells
        .iter()
        .zip(prepared)
        .map(|((cell, input, _), p)| {
            let p = p?;
            let runs: Vec<_> = results.by_ref().take(c.replicas as usize).collect();
            let runs = runs.into_iter().collect::<Result<Vec<_>, _>>()?;
            finish(c, *cell, macro_step, input, &p, runs)
        })
        .collect();
    profile::add(Part::Coupling, begun);
    outputs
}

/// On MPI ranks other than 0: run the boxes rank 0's [`advance_cells`] hands out, until
/// it stops the cluster; returns the exit code. Every rank must hold the same coupling.
#[cfg(feature = "mpi")]
pub fn serve(c: &Coupling, cluster: &crate::farm::Cluster, threads: usize) -> i32 {
    // `farm::map` sends each task with its index in the list.
    cluster.serve(threads, &|t: &crate::farm::Indexed<ReplicaTask>| {
        run_task(c, &t.task)
    })
}
