//! `agglo.subgrid`'s compiled half: [`agglo::subgrid`] (a box per flow-solver cell per
//! macro step, docs/coupling.md) with NumPy arrays in and out, the GIL released while
//! the boxes run. The pure-Python half (python/agglo/subgrid.py) shapes the arrays and
//! wraps the outputs, and offers preCICE's Micro Manager interface.

use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use agglo::farm::Workers;
use agglo::scenario::Relaxation;
use agglo::subgrid::{self, BoxSize, CellInput, CellOutput, GasState, SubgridError};

use crate::errors::{AggloError, ScenarioError, guard};
use crate::scenario::Scenario;

/// A subgrid error as a Python exception: bad input or settings are a `ScenarioError`
/// (a `ValueError`, naming the cell and the field), a failed box an `AggloError`.
fn subgrid_error(e: &SubgridError) -> PyErr {
    match e {
        SubgridError::Config { .. } | SubgridError::Input { .. } | SubgridError::State { .. } => {
            ScenarioError::new_err(e.to_string())
        }
        SubgridError::Run { .. } | SubgridError::Farm { .. } => AggloError::new_err(e.to_string()),
    }
}

/// The coupling's settings (`agglo::subgrid::Coupling`), shared by every cell.
#[pyclass(module = "agglo._agglo", frozen)]
pub struct Coupling {
    inner: subgrid::Coupling,
}

/// A cell's state between macro steps (opaque; `to_bytes`/`from_bytes`, picklable).
#[pyclass(module = "agglo._agglo", frozen)]
pub struct CellState {
    inner: subgrid::CellState,
}

#[pymethods]
impl CellState {
    /// The state's bytes (preCICE's `get_state`).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.inner.to_bytes())
    }

    /// A state from [`CellState::to_bytes`] (`set_state`); other bytes are refused.
    #[staticmethod]
    fn from_bytes(bytes: &[u8]) -> PyResult<Self> {
        guard(|| {
            let inner = subgrid::CellState::from_bytes(bytes)
                .map_err(|e| ScenarioError::new_err(format!("state: {e}")))?;
            Ok(Self { inner })
        })
    }

    /// The cell the state belongs to.
    #[getter]
    fn cell(&self) -> u64 {
        self.inner.cell()
    }

    /// Macro steps the cell has advanced.
    #[getter]
    fn macro_steps(&self) -> u64 {
        self.inner.macro_steps()
    }

    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let from_bytes = py.get_type::<CellState>().getattr("from_bytes")?;
        Ok((from_bytes, (self.to_bytes(py),)))
    }
}

/// Per-cell arrays of a batch, checked for shape: `n` cells of `k` classes.
struct Batch<'a> {
    number_density: &'a [f64],
    mass: &'a [f64],
    velocity: &'a [f64],
    temperature: &'a [f64],
    granular_temperature: &'a [f64],
    /// (n, k, 3), or None: isotropic.
    granular_anisotropy: Option<&'a [f64]>,
    dt: &'a [f64],
    gas_velocity: &'a [f64],
    gas_temperature: &'a [f64],
}

/// `array` as a contiguous slice of `want` values (`name` names it in the error).
fn flat<'a>(
    array: &'a PyReadonlyArrayDyn<'_, f64>,
    name: &str,
    want: usize,
) -> PyResult<&'a [f64]> {
    let values = array
        .as_slice()
        .map_err(|_| ScenarioError::new_err(format!("{name}: not a contiguous float64 array")))?;
    if values.len() != want {
        return Err(ScenarioError::new_err(format!(
            "{name}: {} values, shape {:?} (must hold {want})",
            values.len(),
            array.as_array().shape()
        )));
    }
    Ok(values)
}

/// The drag from its JSON form (the scenario's `field.drag.relaxation`: `{"stokes":
/// {"viscosity": μ}}`, `{"epstein": {"gas_density": ρ_g, "thermal_speed": v_th}}`,
/// `{"constant": {"tau": τ}}`), or no drag.
fn drag_of(json: Option<&str>) -> PyResult<Option<Relaxation>> {
    json.map(|text| {
        serde_json::from_str(text).map_err(|e| {
            ScenarioError::new_err(format!(
                "gas drag: {e} (give {{\"stokes\": {{\"viscosity\": mu}}}}, {{\"epstein\": \
                 {{\"gas_density\": rho_g, \"thermal_speed\": v_th}}}} or {{\"constant\": \
                 {{\"tau\": tau}}}})"
            ))
        })
    })
    .transpose()
}

/// An output as a dict: `mean`, `se` and `units` by figure name (arrays shaped per
/// class, per class × 3, 3 or scalar), and the cell's `cell`, `macro_step`, `dt`,
/// `replicas`, `box_volume`.
fn output_dict<'py>(py: Python<'py>, out: &CellOutput) -> PyResult<Bound<'py, PyDict>> {
    let (mean, se, units) = (PyDict::new(py), PyDict::new(py), PyDict::new(py));
    for column in out.columns() {
        // A figure of one value is a scalar (shape ()); the others keep their shape.
        let shape: Vec<usize> = if column.shape == [1] {
            vec![]
        } else {
            column.shape.clone()
        };
        let m: Bound<'py, PyArrayDyn<f64>> = column.mean.to_pyarray(py).reshape(shape.clone())?;
        let s: Bound<'py, PyArrayDyn<f64>> = column.se.to_pyarray(py).reshape(shape)?;
        mean.set_item(column.name, m)?;
        se.set_item(column.name, s)?;
        units.set_item(column.name, column.unit)?;
    }
    let d = PyDict::new(py);
    d.set_item("mean", mean)?;
    d.set_item("se", se)?;
    d.set_item("units", units)?;
    d.set_item("cell", out.cell)?;
    d.set_item("macro_step", out.macro_step)?;
    d.set_item("dt", out.dt)?;
    d.set_item("replicas", out.replicas)?;
    d.set_item("box_volume", out.box_volume)?;
    Ok(d)
}

#[pymethods]
impl Coupling {
    /// A coupling of `scenario` on the class `edges` [kg]: N = `bodies` per box (or,
    /// with `bodies=None`, bodies enough for a relative standard error `target_se` of
    /// the cell's impact rate, within [`min_bodies`, `max_bodies`]), K = `replicas`;
    /// `keep_bodies` (a closed cell) or `persist` (kept boxes adjusted to transport;
    /// the default unless `keep_bodies`).
    #[new]
    #[pyo3(signature = (scenario, edges, bodies=Some(1000), replicas=4, keep_bodies=false, kernel=false, target_se=0.05, min_bodies=100, max_bodies=100_000, persist=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scenario: &Scenario,
        edges: Vec<f64>,
        bodies: Option<u32>,
        replicas: u32,
        keep_bodies: bool,
        kernel: bool,
        target_se: f64,
        min_bodies: u32,
        max_bodies: u32,
        persist: Option<bool>,
    ) -> PyResult<Self> {
        guard(|| {
            let mut c = subgrid::Coupling::new(scenario.inner.clone(), edges)
                .map_err(|e| subgrid_error(&e))?;
            c.bodies = match bodies {
                Some(n) => BoxSize::Bodies(n),
                None => BoxSize::TargetSe {
                    relative: target_se,
                    min_bodies,
                    max_bodies,
                },
            };
            c.replicas = replicas;
            c.keep_bodies = keep_bodies;
            c.kernel = kernel;
            c.persist = persist.unwrap_or(!keep_bodies);
            c.check().map_err(|e| subgrid_error(&e))?;
            Ok(Self { inner: c })
        })
    }

    /// The number of size classes.
    #[getter]
    fn classes(&self) -> usize {
        self.inner.classes()
    }

    /// Whether cells keep their boxes and adjust them to transport.
    #[getter]
    fn persist(&self) -> bool {
        self.inner.persist
    }

    /// The class edges [kg].
    #[getter]
    fn edges(&self) -> Vec<f64> {
        self.inner.edges.clone()
    }

    /// The primary grain's radius [m] and mass [kg].
    #[getter]
    fn primary(&self) -> (f64, f64) {
        self.inner.primary()
    }

    /// Replica boxes K per cell and step.
    #[getter]
    fn replicas(&self) -> u32 {
        self.inner.replicas
    }

    /// Advance a macro step's cells (arrays with one row per cell: `number_density`,
    /// `mass`, `temperature`, `granular_temperature` of shape (n, k), `velocity` (n, k,
    /// 3), `dt` and `gas_temperature` (n,), `gas_velocity` (n, 3), optionally
    /// `granular_anisotropy` (n, k, 3)) on `threads` threads (0: one per core). Returns
    /// the outputs (dicts) and the new states; raises, naming every failed cell, when any
    /// cell fails.
    #[pyo3(signature = (macro_step, cells, number_density, mass, velocity, temperature, granular_temperature, dt, gas_velocity, gas_temperature, drag=None, states=None, threads=0, granular_anisotropy=None))]
    #[allow(clippy::too_many_arguments)]
    fn advance_cells<'py>(
        &self,
        py: Python<'py>,
        macro_step: u64,
        cells: Vec<u64>,
        number_density: PyReadonlyArrayDyn<'py, f64>,
        mass: PyReadonlyArrayDyn<'py, f64>,
        velocity: PyReadonlyArrayDyn<'py, f64>,
        temperature: PyReadonlyArrayDyn<'py, f64>,
        granular_temperature: PyReadonlyArrayDyn<'py, f64>,
        dt: PyReadonlyArrayDyn<'py, f64>,
        gas_velocity: PyReadonlyArrayDyn<'py, f64>,
        gas_temperature: PyReadonlyArrayDyn<'py, f64>,
        drag: Option<&str>,
        states: Option<Vec<Option<PyRef<'py, CellState>>>>,
        threads: usize,
        granular_anisotropy: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<(Vec<Bound<'py, PyDict>>, Vec<CellState>)> {
        guard(|| {
            let (n, k) = (cells.len(), self.inner.classes());
            let b = Batch {
                number_density: flat(&number_density, "number_density", n * k)?,
                mass: flat(&mass, "mass", n * k)?,
                velocity: flat(&velocity, "velocity", n * k * 3)?,
                temperature: flat(&temperature, "temperature", n * k)?,
                granular_temperature: flat(&granular_temperature, "granular_temperature", n * k)?,
                granular_anisotropy: match &granular_anisotropy {
                    Some(a) => Some(flat(a, "granular_anisotropy", n * k * 3)?),
                    None => None,
                },
                dt: flat(&dt, "dt", n)?,
                gas_velocity: flat(&gas_velocity, "gas_velocity", n * 3)?,
                gas_temperature: flat(&gas_temperature, "gas_temperature", n)?,
            };
            let drag = drag_of(drag)?;
            let states = states.unwrap_or_default();
            if !states.is_empty() && states.len() != n {
                return Err(ScenarioError::new_err(format!(
                    "states: {} for {n} cells (give one per cell, or None)",
                    states.len()
                )));
            }
            let mut batch = Vec::with_capacity(n);
            for (i, &cell) in cells.iter().enumerate() {
                let row = |v: &[f64], w: usize| v[i * w..(i + 1) * w].to_vec();
                let gas = GasState {
                    velocity: [
                        b.gas_velocity[3 * i],
                        b.gas_velocity[3 * i + 1],
                        b.gas_velocity[3 * i + 2],
                    ],
                    temperature: b.gas_temperature[i],
                    drag,
                };
                let input = CellInput::from_columns(
                    cell,
                    &row(b.number_density, k),
                    &row(b.mass, k),
                    &row(b.velocity, 3 * k),
                    &row(b.temperature, k),
                    &row(b.granular_temperature, k),
                    b.granular_anisotropy.map(|a| row(a, 3 * k)).as_deref(),
                    gas,
                    b.dt[i],
                )
                .map_err(|e| subgrid_error(&e))?;
                let state = states
                    .get(i)
                    .and_then(|s| s.as_ref())
                    .map(|s| s.inner.clone());
                batch.push((cell, input, state));
            }
            let coupling = &self.inner;
            let results = py.detach(|| {
                subgrid::advance_cells(coupling, macro_step, &batch, &Workers::local(threads))
            });
            let failed: Vec<&SubgridError> =
                results.iter().filter_map(|r| r.as_ref().err()).collect();
            if let Some(first) = failed.first() {
                let message = failed
                    .iter()
                    .map(|e| e.to_string())
                    .collect::<Vec<_>>()
                    .join("\n");
                return Err(match first {
                    SubgridError::Run { .. } | SubgridError::Farm { .. } => {
                        AggloError::new_err(message)
                    }
                    _ => ScenarioError::new_err(message),
                });
            }
            let mut outputs = Vec::with_capacity(n);
            let mut new_states = Vec::with_capacity(n);
            for (output, state) in results.into_iter().flatten() {
                outputs.push(output_dict(py, &output)?);
                new_states.push(CellState { inner: state });
            }
            Ok((outputs, new_states))
        })
    }
}
