//! What every output holds, with units: the summary's keys and the columns of every
//! table. `agglo schema --outputs` prints [`outputs_markdown`]; docs/outputs.md is the
//! same text (a test keeps them equal), and another test checks that every key of a
//! real summary is listed here.

use super::collisions::COLLISION_COLUMNS;
use super::series::SERIES_COLUMNS;
use super::sizes::SIZES_COLUMNS;
use super::snapshots::SNAPSHOT_COLUMNS;
use super::table::{Column, Kind};

/// One key of the summary JSON (nested keys joined with `.`), with its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    /// The key, nested keys joined with `.`.
    pub name: &'static str,
    /// Its unit (`-` for a pure number).
    pub unit: &'static str,
    /// What it holds, in a line.
    pub doc: &'static str,
}

const fn key(name: &'static str, unit: &'static str, doc: &'static str) -> Key {
    Key { name, unit, doc }
}

/// Every key of `--summary`, in the order it is written.
pub const SUMMARY_KEYS: &[Key] = &[
    key("scenario", "-", "the scenario's name"),
    key("seed", "-", "the seed of the run's random generator"),
    key("time", "s", "simulated time reached"),
    key("steps", "-", "steps taken (event core: event times)"),
    key("initial_bodies", "-", "bodies at t = 0"),
    key("final_bodies", "-", "bodies at the end"),
    key("growth.b_f", "m", "number-average radius b_f"),
    key(
        "growth.b_star",
        "m",
        "radius of one sphere holding all the mass, b*",
    ),
    key("growth.b0", "m", "primary radius b0"),
    key("growth.growth_ratio", "-", "b_f / b0"),
    key("growth.pi04", "-", "Π04 = 1 − b_f / b* (P04 (7.1))"),
    key("growth.n_f", "-", "n_f = (b_f / b0)³ (P04 (7.2))"),
    key("growth.pi02", "-", "Π02 = |b_f / (2 b0) − 1| (P02 (26))"),
    key("growth.radius.mean", "m", "mean radius (= b_f)"),
    key(
        "growth.radius.std_dev",
        "m",
        "standard deviation of the radii",
    ),
    key(
        "growth.radius.skewness",
        "-",
        "normalised third central moment m_3 of the radii",
    ),
    key(
        "growth.radius.kurtosis",
        "-",
        "normalised fourth central moment m_4 of the radii",
    ),
    key("mean_primaries", "-", "mean primaries per body"),
    key("kinetic_energy", "J", "Σ ½ m |v|²"),
    key("thermal_energy", "J", "Σ m C θ"),
    key("mean_temperature", "K", "number-average θ"),
    key("max_temperature", "K", "largest θ"),
    key(
        "counters.impacts",
        "-",
        "impacts resolved (bounces + bonds)",
    ),
    key("counters.bonds", "-", "impacts that bonded"),
    key("counters.bounces", "-", "impacts that bounced"),
    key("counters.fragmentations", "-", "bodies that fragmented"),
    key(
        "counters.fragments_created",
        "-",
        "pieces created by fragmentation",
    ),
    key(
        "counters.fixed_point_iterations",
        "-",
        "fixed-point iterations over all impacts",
    ),
    key(
        "counters.fallback_iterations",
        "-",
        "bracketed-solver iterations over all impacts",
    ),
    key(
        "counters.fallbacks",
        "-",
        "impacts that needed the bracketed fallback",
    ),
    key(
        "counters.unconverged",
        "-",
        "impacts whose plain iteration did not converge (solver plain)",
    ),
    key(
        "counters.deferred_contacts",
        "-",
        "contacts deferred to the next step",
    ),
    key(
        "counters.clamped_steps",
        "-",
        "steps clamped at Δt_min while a contact was due sooner",
    ),
    key(
        "counters.overlap_violations",
        "-",
        "approaching pairs found overlapping (missed contacts)",
    ),
    key(
        "counters.invariant_violations",
        "-",
        "invariant checks that failed",
    ),
    key(
        "energy.reaction_heat",
        "J",
        "reaction heat added, Σ 2 α a_c",
    ),
    key(
        "energy.fracture_energy",
        "J",
        "fracture surface energy removed from heat, Σ δZ",
    ),
    key("energy.cooling_loss", "J", "heat lost by cooling"),
    key(
        "energy.impact_dissipation",
        "J",
        "kinetic energy dissipated in impacts",
    ),
    key("energy.force_work", "J", "work of external forces"),
    key(
        "energy.force_work_turnover",
        "J",
        "Σ |kinetic energy change| by forces",
    ),
    key("energy.external_heat", "J", "heat added by extensions"),
    key(
        "energy.force_impulse",
        "kg m/s",
        "impulse of external forces [x, y, z]",
    ),
    key(
        "energy.force_impulse_turnover",
        "kg m/s",
        "Σ m |Δv| by forces",
    ),
    key(
        "energy.double_counted_heat",
        "J",
        "heat created by impact.work_heat = \"twice\"",
    ),
    key("max_mass_error", "-", "worst |M − M0| / M0"),
    key(
        "max_momentum_error",
        "-",
        "worst |P − P0 − force impulse| / momentum scale",
    ),
    key(
        "max_energy_error",
        "-",
        "worst relative error of the total energy ledger",
    ),
    key(
        "max_kinetic_energy_error",
        "-",
        "worst relative error of the kinetic ledger",
    ),
    key(
        "max_thermal_energy_error",
        "-",
        "worst relative error of the thermal ledger",
    ),
    key(
        "invariant_violations",
        "-",
        "the failed invariant checks, in words (list)",
    ),
    key(
        "plugins",
        "-",
        "plugins built into the run, in order (list)",
    ),
    key("pipeline.core", "-", "`event` or `stepped`"),
    key("pipeline.core_reason", "-", "why that core"),
    key(
        "pipeline.systems",
        "-",
        "the systems in execution order (list)",
    ),
    key("pipeline.left_out", "-", "systems left out and why (list)"),
    key("wall_seconds", "s", "wall-clock time spent stepping"),
    key(
        "events.crossings",
        "-",
        "event core only: cell crossings processed",
    ),
    key("events.stale", "-", "event core: popped events found stale"),
    key(
        "events.predictions",
        "-",
        "event core: body predictions made",
    ),
    key(
        "events.pair_tests",
        "-",
        "event core: pair contact times evaluated",
    ),
    key(
        "events.deep_overlaps",
        "-",
        "event core: approaching pairs found overlapping",
    ),
    key(
        "events.renumberings",
        "-",
        "event core: Z-order renumberings of the slots",
    ),
    key(
        "aggregates.count",
        "-",
        "rigid scenes only (physics.merge_mode): aggregates, singletons included",
    ),
    key(
        "aggregates.mean_primaries",
        "-",
        "rigid: mean primaries k per aggregate",
    ),
    key("aggregates.max_primaries", "-", "rigid: the largest k"),
    key(
        "aggregates.mean_radius_of_gyration",
        "m",
        "rigid: mass-weighted mean R_g of the primaries' centres",
    ),
    key(
        "aggregates.mean_filling_factor",
        "-",
        "rigid: mean filling factor Σ a³ / R_c³, R_c = √(5/3) R_g, over the aggregates with k ≥ 5 (null: none)",
    ),
    key(
        "aggregates.fractal.dimension",
        "-",
        "rigid: D_f of N = k_f (R_g/a)^D_f, 1 / the slope of ln(R_g/a) on ln k over the aggregates with k ≥ 5 (null: fewer than two)",
    ),
    key("aggregates.fractal.prefactor", "-", "rigid: the fit's k_f"),
    key(
        "aggregates.fractal.dimension_se",
        "-",
        "rigid: standard error of D_f from the fit's residuals",
    ),
    key(
        "aggregates.fractal.aggregates",
        "-",
        "rigid: aggregates in the fit",
    ),
    key(
        "aggregates.fractal.min_primaries",
        "-",
        "rigid: smallest k fitted",
    ),
    key(
        "aggregates.fractal.primary_radius",
        "m",
        "rigid: the primary radius a = b0 of the fit",
    ),
];

/// The tables, each with the flag that writes it and its columns.
pub fn tables() -> Vec<(&'static str, &'static str, &'static [Column])> {
    [
        (
            "--series",
            "one row per sample (output.sampling)",
            SERIES_COLUMNS,
        ),
        (
            "--sizes",
            "one row per sample and non-empty size bin; in a rigid scene (physics.merge_mode) the bins count aggregates (by k, or by the radius (Σ a³)^(1/3) of their volume), and two columns follow: `radius_of_gyration` [m], the bin's mean R_g, and `filling_factor` [-], its mean Σ a³ / R_c³ with R_c = √(5/3) R_g (1 for one primary)",
            SIZES_COLUMNS,
        ),
        (
            "--snapshots",
            "one row per body per sample, sorted by t then id; then one column per quantity an extension carries (engine/carried.rs), named by it, NaN where a body has none; in a rigid scene (physics.merge_mode) last `aggregate`, the primary's aggregate id",
            SNAPSHOT_COLUMNS,
        ),
        (
            "--collisions",
            "one row per impact, in the order the engine resolved them",
            COLLISION_COLUMNS,
        ),
    ]
    .into_iter()
    .chain(
        super::step_tables::STEP_TABLES
            .iter()
            .map(|t| (t.flag, t.rows, t.columns)),
    )
    .chain([
        (
            "--final-state",
            "one row per body at the end, sorted by id (CSV only); then one column per quantity an extension carries, named by it, empty where a body has none; in a rigid scene (physics.merge_mode) last `aggregate`, the primary's aggregate id",
            &SNAPSHOT_COLUMNS[1..],
        ),
    ])
    .collect()
}

/// The whole reference as Markdown (docs/outputs.md).
pub fn outputs_markdown() -> String {
    let mut s = String::from(
        "# Outputs\n\n\
         Every file `agglo run` writes, with its columns and units (SI). Printed by \
         `agglo schema --outputs`; this page is generated from the same table \
         (`src/output/schema.rs`). Tables are CSV (header line, floats in shortest \
         round-trip form) or, when the path ends in `.parquet`, Parquet (one required \
         DOUBLE / INT64 / UTF8 column each, zstd). Samples are taken at t = 0, on the \
         schedule of `output.sampling` (or `--sample-every`, `--sample-log`, \
         `--sample-steps`; default every T/100), and at the end; `t` is the end of the \
         first step that reaches a scheduled time.\n",
    );
    for (flag, rows, columns) in tables() {
        s += &format!(
            "\n## `{flag}`: {rows}\n\n| column | type | unit | meaning |\n|---|---|---|---|\n"
        );
        for c in columns {
            let kind = match c.kind {
                Kind::Float => "float",
                Kind::Int | Kind::Id => "integer",
                Kind::Text => "text",
            };
            s += &format!("| `{}` | {kind} | {} | {} |\n", c.name, c.unit, cell(c.doc));
        }
    }
    s += "\n## `--summary`: JSON, one object (nested keys joined with `.`)\n\n\
          | key | unit | meaning |\n|---|---|---|\n";
    for k in SUMMARY_KEYS {
        s += &format!("| `{}` | {} | {} |\n", k.name, k.unit, cell(k.doc));
    }
    s += &kernel_markdown();
    s += CONTINUING;
    s
}

/// The `agglo kernel` file: every array of [`crate::kernel::KERNEL_ARRAYS`] with its
/// shape and units, and the long table's columns.
fn kernel_markdown() -> String {
    use crate::kernel::{CONVENTION, KERNEL_ARRAYS, write::LONG_COLUMNS};
    let mut s = String::from(
        "\n## `agglo kernel --out F.npz`: measured collision kernels, one array each\n\n\
         NumPy `.npz` (`numpy.load(F)`; no pickles): Nm mass classes of `--bins`, 3 outcomes \
         (bond, bounce, fragment), R runs (seeds). Units by `--units` (SI, or cgs as DustPy \
         takes them), stored in the file as `units` and, per array, in `array_units`. \
         The convention, also stored: ",
    );
    s += CONVENTION;
    s += " `python/agglo/kernel.py` loads it into DustPy's arrays and an OpenFOAM table.\n\n\
          | array | shape | unit (SI / cgs) | meaning |\n|---|---|---|---|\n";
    for a in KERNEL_ARRAYS {
        let (si, _) = a.dim.unit(false);
        let (cgs, _) = a.dim.unit(true);
        let unit = if si == cgs {
            si.to_string()
        } else {
            format!("{si} / {cgs}")
        };
        s += &format!(
            "| `{}` | {} | {unit} | {} |\n",
            a.name,
            a.shape,
            cell(a.doc)
        );
    }
    s += "\n## `agglo kernel --parquet F`: the same arrays, one row per element with a value (NaN left out)\n\n\
          | column | type | unit | meaning |\n|---|---|---|---|\n";
    for c in LONG_COLUMNS {
        let kind = match c.kind {
            Kind::Float => "float",
            Kind::Int | Kind::Id => "integer",
            Kind::Text => "text",
        };
        s += &format!("| `{}` | {kind} | {} | {} |\n", c.name, c.unit, cell(c.doc));
    }
    s
}

/// `text` inside a Markdown table cell (a `|` would end the cell).
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// How a run continues from a table, and what is not carried.
const CONTINUING: &str = "
## Starting from a table: `cloud.from_file`

`cloud.from_file` reads the bodies of a `--final-state` or `--snapshots` file (CSV or
Parquet; with a `t` column, the rows of the last t): columns `x, y, z` required; `vx, vy,
vz`, `id`, `mass`, `radius`, `temperature`, `primaries` optional (`hardness` follows θ).
Give `cloud.radius` = b0 of the run that wrote the file (a mass that disagrees with
primaries × m_primary by more than 1e-9 is refused, naming the body). The checks
(in the box, distinct ids, no overlaps, over the neighbour grid) are the ones
`agglo validate` makes.

Carried: every body's id, position, velocity, mass, radius, temperature and primaries,
so new ids continue past the largest. Not carried: the clock (the continued run starts
at t = 0 and runs for its own `time.end`), the random generator's state (a continued
run draws from a fresh generator of its seed: fragmentation's draws differ), the
event core's calendar (rebuilt from the loaded bodies, with event times measured from
the new t = 0, which can differ from the whole run's in the last bits), the counters, the energy ledger and the
invariants' reference totals (they start again from the loaded state). On the stepped
core with a fixed Δt, a run without random draws after set-up continued from its own
final state ends bit for bit where the uninterrupted run ends when Δt and the split
time are exact in binary (`tests/interfaces/initial_data.rs`).
";
