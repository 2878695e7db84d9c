//! Results as NumPy columns: the bodies (the `--final-state` columns, id-sorted) and the
//! tables read back, each column a `Vec` handed to NumPy as the array's own buffer (no
//! second copy), with the units of `agglo schema --outputs`.

use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use agglo::carried::CarriedColumns;
use agglo::components::BodyColumns;
use agglo::output::table::{Table, Values};

/// The `--final-state` columns (`Simulation::body_columns`, sorted by id) and the
/// carried quantities after them (NaN where a body has none), as a dict of 1-D arrays:
/// each column's vector becomes its array's buffer.
pub fn bodies_columns<'py>(
    py: Python<'py>,
    mut bodies: BodyColumns,
    carried: &CarriedColumns,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    let n = bodies.len();
    let ids = std::mem::take(&mut bodies.id);
    out.set_item("id", ids.into_pyarray(py))?;
    for (name, col) in bodies.floats() {
        out.set_item(name, col.into_pyarray(py))?;
    }
    if carried.rows.len() == n {
        for (k, name) in carried.names.iter().enumerate() {
            let values: Vec<f64> = carried
                .rows
                .iter()
                .map(|(_, row)| row[k].unwrap_or(f64::NAN))
                .collect();
            out.set_item(name, values.into_pyarray(py))?;
        }
    }
    Ok(out)
}

/// A table read back, as a dict of columns: floats and integers as arrays, text as a
/// list of str.
pub fn table_columns(py: Python<'_>, table: Table) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for (name, values) in table.names.into_iter().zip(table.columns) {
        match values {
            Values::F(v) => out.set_item(name, v.into_pyarray(py))?,
            Values::I(v) => out.set_item(name, v.into_pyarray(py))?,
            // Ids above i64::MAX (any u64 is an id): an unsigned array.
            Values::U(v) => out.set_item(name, v.into_pyarray(py))?,
            Values::S(v) => out.set_item(name, PyList::new(py, v)?)?,
        }
    }
    Ok(out)
}

/// The unit of each column of an output table (`series`, `sizes`, `snapshots`,
/// `collisions`, `final_state`), as `agglo schema --outputs` lists them.
#[pyfunction]
pub fn table_units(py: Python<'_>, table: &str) -> PyResult<Py<PyDict>> {
    let flag = format!("--{}", table.replace('_', "-"));
    let out = PyDict::new(py);
    let Some((_, _, columns)) = agglo::output::schema::tables()
        .into_iter()
        .find(|(f, _, _)| *f == flag)
    else {
        return Err(crate::errors::ScenarioError::new_err(format!(
            "table_units: no table `{table}` (series, sizes, snapshots, collisions, final_state)"
        )));
    };
    for c in columns {
        out.set_item(c.name, c.unit)?;
    }
    Ok(out.unbind())
}
