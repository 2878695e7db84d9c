//! A cell's output (micro → macro) read by name: every figure of
//! [`agglo::subgrid::CellOutput::columns`] as a mean and a standard error per value.
//! The figures are listed once for C readers, on [`AggloOutput`] (so in the header), and
//! in docs/coupling.md's "Figure names"; tests/figure_names.rs checks both against the
//! library's columns.

use std::ffi::{CString, c_char};

use agglo::subgrid::{CellOutput, Column};

use crate::error::{AggloStatus, Failure, guard, handle, out_pointer, text};

/// A cell's output (opaque): made by the advance calls, freed by `agglo_output_free`.
/// Each figure is the mean over the K replica boxes and its standard error, read by
/// name with `agglo_output_get` (docs/coupling.md says what each means). Per class: one
/// value per class; `classes × 3`: x, y, z per class, row-major; the `kernel_*` figures
/// (only with the coupling's `kernel` option) are sums over the replicas, (classes ×
/// classes) row-major, whose standard errors are NaN. Its figures (name [unit], values;
/// checked against the library by capi/tests/figure_names.rs):
///   number_rate [1/(m^3 s)], classes
///   mass_rate [kg/(m^3 s)], classes
///   momentum_rate [N/m^3], classes × 3
///   number_density [1/m^3], classes
///   mass_density [kg/m^3], classes
///   velocity [m/s], classes × 3
///   temperature [K], classes
///   class_granular_temperature [m^2/s^2], classes
///   class_granular_temperature_axes [m^2/s^2], classes × 3
///   present [replicas], classes
///   granular_replicas [replicas], classes
///   fluctuation_energy_rate [W/m^3], classes
///   thermal_energy_rate [W/m^3], classes
///   ignored [0 or 1], classes
///   total_number_rate [1/(m^3 s)], 1
///   granular_temperature [m^2/s^2], 1
///   gas_momentum_rate [N/m^3], 3
///   force_work_rate [W/m^3], 1
///   heat_loss_rate [W/m^3], 1
///   reaction_heat_rate [W/m^3], 1
///   dissipation_rate [W/m^3], 1
///   fracture_energy_rate [W/m^3], 1
///   impact_rate [1/(m^3 s)], 1
///   bond_rate [1/(m^3 s)], 1
///   bounce_rate [1/(m^3 s)], 1
///   fragment_rate [1/(m^3 s)], 1
///   bodies [bodies per box], 1
///   kernel_exposure [s/m^3], classes × classes
///   kernel_bonds [impacts], classes × classes
///   kernel_bounces [impacts], classes × classes
///   kernel_fragments [impacts], classes × classes
pub struct AggloOutput {
    output: CellOutput,
    columns: Vec<(CString, Column)>,
}

impl AggloOutput {
    pub(crate) fn into_raw(output: CellOutput) -> *mut Self {
        let columns = output
            .columns()
            .into_iter()
            .map(|c| (CString::new(c.name).expect("names hold no NUL"), c))
            .collect();
        Box::into_raw(Box::new(Self { output, columns }))
    }

    fn column(&self, name: &str) -> Result<&Column, Failure> {
        self.columns
            .iter()
            .map(|(_, c)| c)
            .find(|c| c.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> = self.columns.iter().map(|(_, c)| c.name).collect();
                Failure::argument(format!(
                    "no output figure is called {name:?} (there are: {})",
                    names.join(", ")
                ))
            })
    }
}

/// The number of named figures in an output (0 for NULL).
///
/// # Safety
/// `output` is NULL or a live output.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_figures(output: *const AggloOutput) -> usize {
    // SAFETY: the caller's contract.
    unsafe { output.as_ref() }.map_or(0, |o| o.columns.len())
}

/// The name of figure `index` (< `agglo_output_figures`), or NULL. The text lives as
/// long as the output.
///
/// # Safety
/// `output` is NULL or a live output.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_figure_name(
    output: *const AggloOutput,
    index: usize,
) -> *const c_char {
    // SAFETY: the caller's contract.
    unsafe { output.as_ref() }
        .and_then(|o| o.columns.get(index))
        .map_or(std::ptr::null(), |(name, _)| name.as_ptr())
}

/// How many values figure `name` holds (classes, 3 × classes, 3 or 1) into `*len`.
///
/// # Safety
/// `output` a live output; `name` a NUL-terminated string; `len` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_len(
    output: *const AggloOutput,
    name: *const c_char,
    len: *mut usize,
) -> AggloStatus {
    guard(|| {
        out_pointer(len, "len")?;
        // SAFETY: the caller's contract.
        let o = unsafe { handle(output, "output") }?;
        // SAFETY: as above.
        let column = o.column(unsafe { text(name, "name") }?)?;
        // SAFETY: checked non-NULL.
        unsafe { *len = column.mean.len() };
        Ok(())
    })
}

/// Copy figure `name` into the caller's arrays: `mean` and `se` (the standard error
/// over the replicas; NULL: not wanted) of `len` values each, which must be the
/// figure's length (`agglo_output_len`). Per-class vectors are row-major (class, axis).
///
/// # Safety
/// `output` a live output; `name` a NUL-terminated string; `mean` and `se` NULL or
/// `len` writable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_get(
    output: *const AggloOutput,
    name: *const c_char,
    mean: *mut f64,
    se: *mut f64,
    len: usize,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let o = unsafe { handle(output, "output") }?;
        // SAFETY: as above.
        let column = o.column(unsafe { text(name, "name") }?)?;
        if len != column.mean.len() {
            return Err(Failure::argument(format!(
                "len = {len} for figure {:?}, which holds {} values",
                column.name,
                column.mean.len()
            )));
        }
        // SAFETY: each NULL (skipped) or `len` writable doubles.
        unsafe {
            if !mean.is_null() {
                std::slice::from_raw_parts_mut(mean, len).copy_from_slice(&column.mean);
            }
            if !se.is_null() {
                std::slice::from_raw_parts_mut(se, len).copy_from_slice(&column.se);
            }
        }
        Ok(())
    })
}

/// The output's cell id, macro step and box volume [m³] (each pointer NULL: not wanted).
///
/// # Safety
/// `output` a live output; the other pointers NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_info(
    output: *const AggloOutput,
    cell: *mut u64,
    macro_step: *mut u64,
    box_volume: *mut f64,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let o = &unsafe { handle(output, "output") }?.output;
        // SAFETY: each NULL (skipped) or writable.
        unsafe {
            if let Some(c) = cell.as_mut() {
                *c = o.cell;
            }
            if let Some(s) = macro_step.as_mut() {
                *s = o.macro_step;
            }
            if let Some(v) = box_volume.as_mut() {
                *v = o.box_volume;
            }
        }
        Ok(())
    })
}

/// Free an output (NULL is ignored).
///
/// # Safety
/// `output` is NULL or an output from this library not freed before.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_output_free(output: *mut AggloOutput) {
    if !output.is_null() {
        // SAFETY: made by Box::into_raw in this module, freed once (the caller's word).
        drop(unsafe { Box::from_raw(output) });
    }
}
