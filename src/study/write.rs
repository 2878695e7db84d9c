//! A study's outputs: its tables, then its charts.
//!
//! Apart from [`super::accuracy`] and [`super::stability`] so that the imports run one
//! way: the studies compute, [`super::charts`] draws what they computed, and this
//! writes both.

use std::path::Path;

use super::accuracy::{AccuracyStudy, write_accuracy_tables};
use super::charts::{accuracy_charts, stability_charts};
use super::stability::{StabilityStudy, write_stability_tables};

/// Write `accuracy.csv`, `noise.csv` and the charts into `dir`.
pub fn write_accuracy(dir: &Path, study: &AccuracyStudy) -> anyhow::Result<()> {
    write_accuracy_tables(dir, study)?;
    accuracy_charts(dir, study)
}

/// Write the CSVs and charts of `study` into `dir`.
pub fn write_stability(dir: &Path, study: &StabilityStudy) -> anyhow::Result<()> {
    write_stability_tables(dir, study)?;
    stability_charts(dir, study)
}
