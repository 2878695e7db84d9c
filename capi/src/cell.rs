//! Advancing cells: one (`agglo_cell_advance`) or a macro step's batch on threads
//! (`agglo_cells_advance`), each from its per-class arrays, gas state and Δt.

use agglo::farm::Workers;
use agglo::subgrid::{self, CellInput, GasState};
use agglo_engine::field::Relaxation;

use crate::coupling::AggloCoupling;
use crate::error::{AggloStatus, Failure, guard, handle, out_pointer, slice};
use crate::output::AggloOutput;
use crate::state::AggloCellState;

/// `AggloGas::drag`: no drag (the bodies do not feel the gas velocity).
pub const AGGLO_DRAG_NONE: u32 = 0;
/// `AggloGas::drag`: the same relaxation time for every body, `drag_a` = τ [s].
pub const AGGLO_DRAG_CONSTANT: u32 = 1;
/// `AggloGas::drag`: Stokes drag, `drag_a` = the gas's dynamic viscosity μ [Pa s].
pub const AGGLO_DRAG_STOKES: u32 = 2;
/// `AggloGas::drag`: Epstein drag, `drag_a` = gas density ρ_g [kg/m³], `drag_b` = mean
/// thermal speed v_th [m/s].
pub const AGGLO_DRAG_EPSTEIN: u32 = 3;

/// The cell's gas over the macro step.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AggloGas {
    /// Gas velocity [m/s].
    pub velocity: [f64; 3],
    /// Gas temperature [K] (the ambient temperature of cooling), > 0.
    pub temperature: f64,
    /// One of the `AGGLO_DRAG_*` values (a plain integer, so that any value C passes is
    /// checked rather than trusted).
    pub drag: u32,
    /// The drag law's first parameter (see `AGGLO_DRAG_*`: τ [s], μ [Pa s] or ρ_g
    /// [kg/m³]); unused without drag.
    pub drag_a: f64,
    /// The drag law's second parameter (Epstein's thermal speed v_th [m/s]); unused
    /// otherwise.
    pub drag_b: f64,
}

/// One cell's macro state (macro → micro). Each per-class pointer holds one value per
/// class (`agglo_coupling_classes`), `velocity` three per class (x, y, z), row-major.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AggloCellInput {
    /// Bodies per unit volume n_k [1/m³], ≥ 0.
    pub number_density: *const f64,
    /// Representative body mass m_k [kg], inside class k's edges.
    pub mass: *const f64,
    /// Mean velocity of each class [m/s], 3 per class.
    pub velocity: *const f64,
    /// Temperature of each class's bodies [K], > 0.
    pub temperature: *const f64,
    /// Granular temperature of each class [m²/s²], ≥ 0: the mean over the axes of a
    /// velocity component's variance.
    pub granular_temperature: *const f64,
    /// How each class's granular temperature splits over x, y, z, 3 per class (a_i ≥ 0,
    /// not all 0): component i's variance is T·3a_i/(a_x + a_y + a_z). NULL: isotropic.
    pub granular_anisotropy: *const f64,
    /// The cell's gas over the step.
    pub gas: AggloGas,
    /// The macro time step Δt [s], > 0.
    pub dt: f64,
}

/// Advance one cell over its macro step. `*state` is NULL (lift the cell's bodies from
/// the input) or the cell's state from its previous step; on success it is replaced by
/// the new state (the old one is freed) and `*out` holds the output (free it with
/// `agglo_output_free`; whatever `*out` held before is overwritten, not freed). On
/// failure neither is touched.
///
/// # Safety
/// `coupling` a live coupling; `input` points to an input whose arrays hold the
/// coupling's class count; `state` and `out` point to writable handle storage, `*state`
/// NULL or a live state.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_cell_advance(
    coupling: *const AggloCoupling,
    cell: u64,
    macro_step: u64,
    input: *const AggloCellInput,
    state: *mut *mut AggloCellState,
    out: *mut *mut AggloOutput,
) -> AggloStatus {
    guard(|| {
        out_pointer(state, "state")?;
        out_pointer(out, "out")?;
        // SAFETY: the caller's contract.
        let c = &unsafe { handle(coupling, "coupling") }?.0;
        // SAFETY: as above.
        let input = unsafe { read_input(c, cell, handle(input, "input")?) }?;
        // SAFETY: `state` checked non-NULL; `*state` NULL or live.
        let old = unsafe { (*state).as_ref() }.map(|s| &s.0);
        let (output, new) = subgrid::advance_cell(c, cell, macro_step, &input, old)?;
        // SAFETY: both checked non-NULL; the old state is ours to free.
        unsafe {
            crate::state::agglo_state_free(*state);
            *state = AggloCellState::into_raw(new);
            *out = AggloOutput::into_raw(output);
        }
        Ok(())
    })
}

/// Advance a macro step's `n_cells` cells as independent tasks on `threads` worker
/// threads (0: one per core; at most 1024). Cell i has id `cells[i]`, input `inputs[i]` and state
/// `states[i]` (NULL: lift from the input), replaced on success as in
/// `agglo_cell_advance`; `outs[i]` gets its output, or NULL when it failed (what it held
/// before is overwritten, not freed), and
/// `statuses[i]` (NULL: not wanted) its status, written for every entry once the
/// arguments themselves are usable. A cell's own fault fails that cell alone: its input
/// (out of range, an unknown `gas.drag`, a NULL array), its state (another cell's, or a
/// closed cell's given to an open coupling), or a state given to two entries
/// (`AGGLO_STATUS_ARGUMENT` for each, naming the other index: advancing both would free
/// it twice). Returns `AGGLO_STATUS_OK` when every
/// cell advanced, else the first failed cell's status, with every failed cell's message
/// (one per line) in `agglo_last_error()`. A cell's output is the same bytes for any
/// thread count and any order of the cells.
///
/// # Safety
/// `coupling` a live coupling; `cells` and `inputs` point to `n_cells` entries; `states`
/// and `outs` to `n_cells` writable handles (`states[i]` NULL or a live state of cell
/// `cells[i]`); `statuses` NULL or `n_cells` writable statuses.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn agglo_cells_advance(
    coupling: *const AggloCoupling,
    macro_step: u64,
    n_cells: usize,
    cells: *const u64,
    inputs: *const AggloCellInput,
    states: *mut *mut AggloCellState,
    outs: *mut *mut AggloOutput,
    statuses: *mut AggloStatus,
    threads: usize,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let c = &unsafe { handle(coupling, "coupling") }?.0;
        // SAFETY: as above.
        let ids = unsafe { slice(cells, n_cells, "cells") }?;
        // SAFETY: as above.
        let inputs = unsafe { slice(inputs, n_cells, "inputs") }?;
        if n_cells > 0 {
            out_pointer(states, "states")?;
            out_pointer(outs, "outs")?;
        }
        // One OS thread each: 100000 started that many (issue 39).
        agglo::farm::check_threads(threads)
            .map_err(|e| Failure::argument(format!("threads: {e}")))?;
        // SAFETY: states holds n_cells handles, each NULL or live.
        let handles = unsafe { slice(states.cast_const(), n_cells, "states") }?;
        // Each cell's own refusal (an unknown drag, a wrong length, a state shared with
        // another entry) fails that cell alone; the others go to the farm.
        let mut shared = shared_states(handles);
        let mut own: Vec<Option<Failure>> = Vec::with_capacity(n_cells);
        let mut batch = Vec::with_capacity(n_cells);
        for (i, (&cell, input)) in ids.iter().zip(inputs).enumerate() {
            // SAFETY: the caller's contract: the input's arrays hold the class count.
            let read = unsafe { read_input(c, cell, input) }.and_then(|input| {
                if let Some(f) = shared[i].take() {
                    return Err(f);
                }
                // SAFETY: states[i] is NULL or live.
                let state = unsafe { handles[i].as_ref() }.map(|s| s.0.clone());
                Ok((cell, input, state))
            });
            match read {
                Ok(entry) => {
                    batch.push(entry);
                    own.push(None);
                }
                Err(failure) => own.push(Some(failure)),
            }
        }
        let mut results =
            subgrid::advance_cells(c, macro_step, &batch, &Workers::local(threads)).into_iter();
        let mut messages = Vec::new();
        let mut first_failure = AggloStatus::Ok;
        for (i, failure) in own.into_iter().enumerate() {
            let result = match failure {
                Some(f) => Err(f),
                None => results
                    .next()
                    .expect("one result per cell sent")
                    .map_err(Failure::from),
            };
            let cell_status = match result {
                Ok((output, new)) => {
                    // SAFETY: i < n_cells; the old state is ours to free (no other entry
                    // holds it: shared_states).
                    unsafe {
                        crate::state::agglo_state_free(*states.add(i));
                        *states.add(i) = AggloCellState::into_raw(new);
                        *outs.add(i) = AggloOutput::into_raw(output);
                    }
                    AggloStatus::Ok
                }
                Err(f) => {
                    // SAFETY: i < n_cells.
                    unsafe { *outs.add(i) = std::ptr::null_mut() };
                    messages.push(f.message);
                    f.status
                }
            };
            if !statuses.is_null() {
                // SAFETY: statuses holds n_cells entries when not NULL.
                unsafe { *statuses.add(i) = cell_status };
            }
            if first_failure == AggloStatus::Ok {
                first_failure = cell_status;
            }
        }
        if messages.is_empty() {
            Ok(())
        } else {
            Err(Failure {
                status: first_failure,
                message: messages.join("\n"),
            })
        }
    })
}

/// Per entry, the other entries that hold the same state (pointer equality), when any:
/// advancing both would replace (and free) the one state twice, so every entry sharing
/// a state is refused and none is left pointing to a freed state. O(n) with a map.
fn shared_states(states: &[*mut AggloCellState]) -> Vec<Option<Failure>> {
    let mut holders: std::collections::HashMap<*mut AggloCellState, Vec<usize>> =
        std::collections::HashMap::new();
    for (i, &s) in states.iter().enumerate() {
        if !s.is_null() {
            holders.entry(s).or_default().push(i);
        }
    }
    (0..states.len())
        .map(|i| {
            let all = holders.get(&states[i])?;
            let others: Vec<String> = all
                .iter()
                .filter(|&&j| j != i)
                .map(|j| format!("states[{j}]"))
                .collect();
            (!others.is_empty()).then(|| {
                Failure::argument(format!(
                    "states[{i}] is the same state as {} (each cell needs its own state)",
                    others.join(", ")
                ))
            })
        })
        .collect()
}

/// The input at `input` as the library's, checked for lengths (values are checked
/// when the cell advances, naming the cell and the field).
///
/// # Safety
/// The input's pointers hold the coupling's class count of values (3 for velocity).
unsafe fn read_input(
    c: &agglo::subgrid::Coupling,
    cell: u64,
    input: &AggloCellInput,
) -> Result<CellInput, Failure> {
    let k = c.classes();
    let field = |name: &str| format!("cell {cell}: {name}");
    // SAFETY: the caller's contract.
    let (n, m, v, t, g) = unsafe {
        (
            slice(input.number_density, k, &field("number_density"))?,
            slice(input.mass, k, &field("mass"))?,
            slice(input.velocity, 3 * k, &field("velocity"))?,
            slice(input.temperature, k, &field("temperature"))?,
            slice(
                input.granular_temperature,
                k,
                &field("granular_temperature"),
            )?,
        )
    };
    let gas = GasState {
        velocity: input.gas.velocity,
        temperature: input.gas.temperature,
        drag: match input.gas.drag {
            AGGLO_DRAG_NONE => None,
            AGGLO_DRAG_CONSTANT => Some(Relaxation::Constant {
                tau: input.gas.drag_a,
            }),
            AGGLO_DRAG_STOKES => Some(Relaxation::Stokes {
                viscosity: input.gas.drag_a,
            }),
            AGGLO_DRAG_EPSTEIN => Some(Relaxation::Epstein {
                gas_density: input.gas.drag_a,
                thermal_speed: input.gas.drag_b,
            }),
            other => {
                return Err(Failure {
                    status: AggloStatus::Input,
                    message: format!(
                        "cell {cell}: gas.drag = {other} (must be AGGLO_DRAG_NONE (0), \
                         _CONSTANT (1), _STOKES (2) or _EPSTEIN (3))"
                    ),
                });
            }
        },
    };
    // SAFETY: the caller's contract (NULL or 3 per class).
    let a = if input.granular_anisotropy.is_null() {
        None
    } else {
        Some(unsafe {
            slice(
                input.granular_anisotropy,
                3 * k,
                &field("granular_anisotropy"),
            )
        }?)
    };
    Ok(CellInput::from_columns(
        cell, n, m, v, t, g, a, gas, input.dt,
    )?)
}
