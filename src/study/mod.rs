//! `agglo study`: what each numerical choice costs and what it buys (docs/model.md §4, §5,
//! §8, §14).
//!
//! - [`accuracy`]: one scene, one seed, a ladder of numerical settings (adaptive step
//!   factor, fixed Δt, fixed-point tolerance, cooling integrator, the papers' contact
//!   rule), each timed and compared with a resolved reference; the reference's spread
//!   over a few seeds is the noise band. Writes `accuracy.csv` and charts.
//! - [`stability`]: where methods fail — the pair solve's plain iteration against the
//!   safeguarded solver over speed × a0 (with and without thermal softening), explicit
//!   against implicit cooling over Δt × θ, and the collisions a step size misses.
//! - [`readings`]: the scene under each alternative reading of the papers (the model's
//!   decisions made the other way), over an ensemble of seeds, against the baseline and
//!   the published value. Writes `readings.csv`, `runs.csv`, `readings.md` and a chart.
//! - [`charts`]: the figures, drawn through [`crate::charts::save_png_and_svg`].
//! - [`write`]: a study's tables and charts, written into its output folder.
//!
//! Everything here is deterministic except the measured wall times.

pub mod accuracy;
pub mod charts;
pub mod readings;
pub mod stability;
pub mod write;

use std::io::Write;

/// The shipped study scene (`scenarios/study_accuracy.json`), built in so that
/// `agglo study stability` runs without arguments.
pub const STUDY_SCENARIO: &str = include_str!("../../scenarios/study_accuracy.json");

use std::path::Path;

/// Median of `values` (NaN-free; 0 for an empty slice).
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Mean and sample standard deviation of `values` (std 0 for fewer than two values).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, 0.0);
    }
    let var = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (mean, var.sqrt())
}

/// Two-sample Kolmogorov–Smirnov distance: the largest gap between the empirical CDFs
/// of `a` and `b` (0 for identical samples, 1 for disjoint ones; 1 if either is empty
/// and the other is not).
pub fn ks_distance(a: &[f64], b: &[f64]) -> f64 {
    match (a.is_empty(), b.is_empty()) {
        (true, true) => return 0.0,
        (true, false) | (false, true) => return 1.0,
        _ => {}
    }
    let mut a = a.to_vec();
    let mut b = b.to_vec();
    a.sort_by(f64::total_cmp);
    b.sort_by(f64::total_cmp);
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j) = (0usize, 0usize);
    let mut worst = 0.0_f64;
    while i < a.len() && j < b.len() {
        // Step past every sample equal to the smaller current value in both, so ties
        // (e.g. many unmerged primaries of the same radius) are handled exactly.
        let x = a[i].min(b[j]);
        while i < a.len() && a[i] <= x {
            i += 1;
        }
        while j < b.len() && b[j] <= x {
            j += 1;
        }
        worst = worst.max((i as f64 / na - j as f64 / nb).abs());
    }
    worst
}

/// Relative error |x − reference| / |reference| (absolute when the reference is 0).
pub fn relative_error(x: f64, reference: f64) -> f64 {
    if reference == 0.0 {
        x.abs()
    } else {
        (x - reference).abs() / reference.abs()
    }
}

/// Write `rows` under `header` as CSV to `path` (values must not contain commas).
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<String>]) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(path)
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", path.display()))?,
    );
    writeln!(out, "{}", header.join(","))?;
    for row in rows {
        writeln!(out, "{}", row.join(","))?;
    }
    out.flush()?;
    Ok(())
}

/// Format a float for CSV: shortest round-trip representation.
pub fn num(x: f64) -> String {
    format!("{x:?}")
}
