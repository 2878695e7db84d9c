//! The figure names a cell's output hands back, listed for readers in two places — the
//! C header's comment on `AggloOutput` and docs/coupling.md's "Figure names" table —
//! checked against their one source, `agglo::subgrid::CellOutput::columns()` of a real
//! output with every figure (the coupling's `kernel` on): the same names, in the same
//! order, with the same units and shapes. A figure added, renamed or reshaped in the
//! library fails this test until both lists say so.

use agglo::prelude::*;
use agglo::subgrid::{CellInput, Column, Coupling, GasState, advance_cell};

/// How a figure's values are laid out, in the words of both lists.
fn shape_words(shape: &[usize], classes: usize) -> String {
    let word = |n: usize| match n == classes {
        true => "classes".to_string(),
        false => n.to_string(),
    };
    shape
        .iter()
        .map(|&n| word(n))
        .collect::<Vec<_>>()
        .join(" × ")
}

/// Every figure of a one-step output on 2 classes (so that "classes" is told from 1 and
/// 3), with the kernel's sums: (name, unit, shape words).
fn figures() -> Vec<(String, String, String)> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/ballistic_aggregation.json"
    );
    let base = Scenario::load(std::path::Path::new(path)).unwrap();
    let m0 = base.primary_mass();
    let mut coupling = Coupling::new(base, vec![0.5 * m0, 1.5 * m0, 1e9 * m0]).unwrap();
    coupling.bodies = agglo::subgrid::BoxSize::Bodies(100);
    coupling.replicas = 2;
    coupling.kernel = true;
    let gas = GasState {
        velocity: [0.0; 3],
        temperature: 300.0,
        drag: None,
    };
    let n0 = 0.02 / (4.0 / 3.0 * std::f64::consts::PI * coupling.base.primary_radius().powi(3));
    let input = CellInput::from_columns(
        1,
        &[n0, 0.0],
        &[m0, 2.0 * m0],
        &[0.0; 6],
        &[300.0; 2],
        &[1.0; 2],
        None,
        gas,
        1e-5,
    )
    .unwrap();
    let (out, _) = advance_cell(&coupling, 1, 0, &input, None).unwrap();
    out.columns()
        .iter()
        .map(|c: &Column| {
            (
                c.name.to_string(),
                c.unit.to_string(),
                shape_words(&c.shape, 2),
            )
        })
        .collect()
}

#[test]
fn the_headers_figure_list_is_the_librarys() {
    let header =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/include/agglo.h")).unwrap();
    // The lines after "Its figures" in AggloOutput's comment: `//   NAME [UNIT], SHAPE`.
    let listed: Vec<(String, String, String)> = header
        .lines()
        .skip_while(|l| !l.contains("Its figures"))
        .skip_while(|l| !l.starts_with("//   "))
        .map_while(|l| l.strip_prefix("//   "))
        .map(|l| {
            let (name, rest) = l.split_once(" [").unwrap_or_else(|| panic!("{l}"));
            let (unit, shape) = rest.split_once("], ").unwrap_or_else(|| panic!("{l}"));
            (name.to_string(), unit.to_string(), shape.to_string())
        })
        .collect();
    assert_eq!(
        listed,
        figures(),
        "capi/src/output.rs's AggloOutput comment"
    );
}

#[test]
fn the_docs_figure_table_is_the_librarys() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/coupling.md"))
        .unwrap();
    // The rows of the table under "## Figure names": | `NAME` | UNIT | SHAPE |.
    let listed: Vec<(String, String, String)> = doc
        .lines()
        .skip_while(|l| *l != "## Figure names")
        .skip_while(|l| !l.starts_with("| ---"))
        .skip(1)
        .map_while(|l| l.strip_prefix("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split(" | ").collect();
            assert_eq!(cells.len(), 3, "{l}");
            (
                cells[0].trim_end_matches('`').to_string(),
                cells[1].to_string(),
                cells[2].trim_end_matches(" |").to_string(),
            )
        })
        .collect();
    assert_eq!(listed, figures(), "docs/coupling.md's Figure names table");
}
