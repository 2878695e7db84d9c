//! `agglo.Scenario`'s compiled core: a scenario is the library's `Scenario`, loaded,
//! overridden (`--set`'s paths, checks and messages) and validated by the same code as
//! the command line's. The attribute view that mirrors the JSON is pure Python
//! (python/agglo/scenario.py) over [`Scenario::to_json`].

use std::path::PathBuf;

use numpy::ndarray::ArrayView1;
use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use agglo::scenario::{PlacedBody, Scenario as Inner};

use crate::errors::{agglo_error, guard, scenario_error};

/// A scenario: the JSON description of one run, checked.
#[pyclass(module = "agglo._agglo", name = "Scenario", frozen, from_py_object)]
#[derive(Clone)]
pub struct Scenario {
    pub inner: Inner,
}

#[pymethods]
impl Scenario {
    /// Read and check a scenario file (JSON).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        guard(|| {
            let inner = Inner::load(&path)
                .map_err(|e| scenario_error(format!("loading scenario {}: {e}", path.display())))?;
            Ok(Self { inner })
        })
    }

    /// Parse and check a scenario from its JSON text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        guard(|| {
            let inner = Inner::from_json(text).map_err(scenario_error)?;
            Ok(Self { inner })
        })
    }

    /// The scenario as pretty JSON (round-trips through `from_json`).
    fn to_json(&self) -> String {
        self.inner.to_json()
    }

    /// This scenario with `PATH=VALUE` settings applied, exactly as `agglo run --set`
    /// does (VALUE is JSON); checked as a file is.
    fn with_settings(&self, settings: Vec<String>) -> PyResult<Self> {
        guard(|| {
            let inner = self
                .inner
                .with_settings(&settings)
                .map_err(scenario_error)?;
            Ok(Self { inner })
        })
    }

    /// This scenario with another seed (as `agglo run --seed`: the name is unchanged).
    fn with_seed(&self, seed: u64) -> Self {
        let mut inner = self.inner.clone();
        inner.seed = seed;
        Self { inner }
    }

    /// The report `agglo validate` prints: (text, memory warning or None). Raises
    /// `ScenarioError` when the scene cannot be built or cannot fit in memory.
    fn validation_report(&self) -> PyResult<(String, Option<String>)> {
        guard(|| {
            let report = agglo::validate::report(&self.inner).map_err(scenario_error)?;
            Ok((report.text, report.warning))
        })
    }

    /// This scenario with explicit bodies from arrays (N rows each): `position` (N, 3)
    /// [m] and, optionally, `velocity` (N, 3) [m/s], `primaries`, `radius` [m], `mass`
    /// [kg], `temperature` [K], `id`. Checked by the placed-bodies check of
    /// `cloud.bodies` (inside the box, no overlaps, consistent mass and radius); with
    /// `separate`, overlapping pairs (a run's end state can hold some) are first pushed
    /// apart (`agglo::separate::separate_overlaps`).
    #[pyo3(signature = (position, velocity=None, primaries=None, radius=None, mass=None, temperature=None, id=None, separate=false))]
    #[allow(clippy::too_many_arguments)]
    fn with_bodies(
        &self,
        position: PyReadonlyArray2<'_, f64>,
        velocity: Option<PyReadonlyArray2<'_, f64>>,
        primaries: Option<PyReadonlyArray1<'_, f64>>,
        radius: Option<PyReadonlyArray1<'_, f64>>,
        mass: Option<PyReadonlyArray1<'_, f64>>,
        temperature: Option<PyReadonlyArray1<'_, f64>>,
        id: Option<PyReadonlyArray1<'_, u64>>,
        separate: bool,
    ) -> PyResult<Self> {
        guard(|| {
            let position = position.as_array();
            let n = position.nrows();
            if position.ncols() != 3 {
                return Err(scenario_error(format!(
                    "with_bodies: position: shape ({n}, {}), expected (N, 3)",
                    position.ncols()
                )));
            }
            let velocity = velocity.as_ref().map(|v| v.as_array());
            if let Some(v) = &velocity
                && v.shape() != [n, 3]
            {
                return Err(scenario_error(format!(
                    "with_bodies: velocity: shape {:?}, expected ({n}, 3) like position",
                    v.shape()
                )));
            }
            let primaries = column("primaries", &primaries, n)?;
            let radius = column("radius", &radius, n)?;
            let mass = column("mass", &mass, n)?;
            let temperature = column("temperature", &temperature, n)?;
            let id = id.as_ref().map(|a| a.as_array());
            if let Some(ids) = &id
                && ids.len() != n
            {
                return Err(scenario_error(format!(
                    "with_bodies: id: {} values for {n} bodies",
                    ids.len()
                )));
            }
            let bodies: Vec<PlacedBody> = (0..n)
                .map(|i| PlacedBody {
                    position: [position[[i, 0]], position[[i, 1]], position[[i, 2]]],
                    velocity: velocity.as_ref().map(|v| [v[[i, 0]], v[[i, 1]], v[[i, 2]]]),
                    primaries: primaries.as_ref().map_or(1.0, |a| a[i]),
                    id: id.as_ref().map(|a| a[i]),
                    temperature: temperature.as_ref().map(|a| a[i]),
                    mass: mass.as_ref().map(|a| a[i]),
                    radius: radius.as_ref().map(|a| a[i]),
                })
                .collect();
            let mut inner = self.inner.clone();
            inner.cloud.from_file = None;
            inner.cloud.bodies = bodies;
            inner.cloud.count = n;
            if separate {
                agglo::separate::separate_overlaps(&mut inner).map_err(scenario_error)?;
            }
            inner.validate().map_err(scenario_error)?;
            Ok(Self { inner })
        })
    }

    /// The JSON Schema of the scenario format (what `agglo schema` prints), as text.
    #[staticmethod]
    fn json_schema() -> PyResult<String> {
        serde_json::to_string_pretty(&Inner::json_schema()).map_err(|e| agglo_error(e.into()))
    }

    /// Derived figures: the primary radius b0 [m] and mass [kg] and the volume fraction.
    fn derived<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("primary_radius", self.inner.primary_radius())?;
        d.set_item("primary_mass", self.inner.primary_mass())?;
        d.set_item("volume_fraction", self.inner.volume_fraction())?;
        d.set_item("event_core", self.inner.uses_event_core())?;
        Ok(d)
    }

    /// Pickled as its JSON text.
    fn __reduce__(&self, py: Python<'_>) -> PyResult<(Py<PyAny>, (String,))> {
        let from_json = py.get_type::<Scenario>().getattr("from_json")?.unbind();
        Ok((from_json, (self.inner.to_json(),)))
    }
}

/// A per-body column of `with_bodies`, checked to hold one value per body.
fn column<'a>(
    name: &str,
    a: &'a Option<PyReadonlyArray1<'_, f64>>,
    n: usize,
) -> PyResult<Option<ArrayView1<'a, f64>>> {
    let Some(a) = a else { return Ok(None) };
    let a = a.as_array();
    if a.len() == n {
        Ok(Some(a))
    } else {
        Err(scenario_error(format!(
            "with_bodies: {name}: {} values for {n} bodies",
            a.len()
        )))
    }
}
