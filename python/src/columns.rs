//! Results as NumPy columns: the bodies (the `--final-state` columns, id-sorted) and the
//! tables read back, each column a `Vec` handed to NumPy as the array's own buffer (no
//! second copy), with the units of `agglo schema --outputs`.

use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use agglo::carried::CarriedColumns;
use agglo::components::BodyState;
use agglo::output::table::{Table, Values};

/// The `--final-state` columns of `bodies` (sorted by id) and the carried quantities
/// after them (NaN where a body has none), as a dict of 1-D arrays.
pub fn bodies_columns<'py>(
    py: Python<'py>,
    bodies: &[BodyState],
    carried: &CarriedColumns,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    // One pass over the bodies, filling every column (a pass per column read the 96-byte
    // rows twelve times: 2.6× the engine's own read at N = 10⁶).
    let n = bodies.len();
    let mut id = Vec::with_capacity(n);
    let mut cols: [Vec<f64>; 11] = std::array::from_fn(|_| Vec::with_capacity(n));
    for b in bodies {
        id.push(b.id);
        let row = [
            b.position.x,
            b.position.y,
            b.position.z,
            b.velocity.x,
            b.velocity.y,
            b.velocity.z,
            b.mass,
            b.radius,
            b.temperature,
            b.hardness,
            b.primaries,
        ];
        for (col, v) in cols.iter_mut().zip(row) {
            col.push(v);
        }
    }
    out.set_item("id", id.into_pyarray(py))?;
    let names = [
        "x",
        "y",
        "z",
        "vx",
        "vy",
        "vz",
        "mass",
        "radius",
        "temperature",
        "hardness",
        "primaries",
    ];
    for (name, col) in names.into_iter().zip(cols) {
        out.set_item(name, col.into_pyarray(py))?;
    }
    if carried.rows.len() == bodies.len() {
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
