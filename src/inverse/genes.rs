//! Genes: numeric scenario fields addressed by dotted path (docs/model.md §12).
//!
//! A path walks the JSON value of a fully serialised scenario: object keys by
//! name, array elements by index (`cloud.v_rel.0`). Setting a gene writes a
//! number there; the scenario is then re-parsed and validated with
//! [`Scenario::from_value`](crate::scenario::Scenario::from_value), so a gene can
//! never produce a scenario the engine would not accept from a file.

use serde_json::Value;

/// The value at `path`, if the path exists.
pub fn get_path<'a>(value: &'a Value, path: &str) -> Option<&'a Value> {
    let mut node = value;
    for segment in path.split('.') {
        node = match node {
            Value::Object(map) => map.get(segment)?,
            Value::Array(items) => items.get(segment.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(node)
}

/// Write the number `x` at `path`. The path must already exist and hold a number
/// (or `null`, for optional numbers such as `material.gamma`).
pub fn set_path(value: &mut Value, path: &str, x: f64) -> Result<(), String> {
    let mut node = value;
    for segment in path.split('.') {
        node = match node {
            Value::Object(map) => map
                .get_mut(segment)
                .ok_or_else(|| format!("`{path}`: no field `{segment}` in the base scenario"))?,
            Value::Array(items) => {
                let len = items.len();
                let i = segment.parse::<usize>().map_err(|_| {
                    format!("`{path}`: `{segment}` indexes an array and must be a number")
                })?;
                items
                    .get_mut(i)
                    .ok_or_else(|| format!("`{path}`: index {i} out of range (length {len})"))?
            }
            _ => {
                return Err(format!(
                    "`{path}`: `{segment}` is below a number, not a field"
                ));
            }
        };
    }
    match node {
        Value::Number(_) | Value::Null => {
            let n = serde_json::Number::from_f64(x)
                .ok_or_else(|| format!("`{path}`: {x} is not a finite number"))?;
            *node = Value::Number(n);
            Ok(())
        }
        other => Err(format!(
            "`{path}` holds {}, not a number",
            match other {
                Value::Bool(_) => "a boolean",
                Value::String(_) => "a string",
                Value::Array(_) => "an array",
                Value::Object(_) => "an object",
                _ => "something else",
            }
        )),
    }
}
