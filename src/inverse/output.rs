//! Outputs of an inverse run, all written from the GA state alone (so a resumed run
//! writes the same files): `generations.csv`, `best.json` (top K in real units, the
//! layout of P04 Tables 1–3 / P02 Table 1, each cost with its standard error, then
//! the closing check's re-ranking), `best_scenario.json` (the winner — of the
//! closing check when there is one — ready for `agglo run`, seeded with its first
//! sample), and the charts `convergence.{png,svg}` (P04 Fig. 4 / P02 Fig. 4, with
//! ± 1 standard error bars and the closing check) and `best_radii.{png,svg}`
//! (histogram of final radii over the best string's ensemble, P02 Fig. 5).
//!
//! Which figures compare with the papers' tables: `top` is ranked by the GA's own
//! ensembles, stopped by the papers' rule — the way P04 Table 3 and P02 Table 1 were
//! made. `check` re-runs the best strings on fresh seeds: its costs are the ones to
//! believe.

use std::fmt::Write as _;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;

use crate::charts::{FONT, Figure, save_png_and_svg};

use super::check_seed;
use super::ensemble::sample_seed;
use super::ga::{Finalist, GaState, GenerationRow};
use super::problem::{CostSpec, InverseError, InverseProblem};

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> InverseError + '_ {
    move |source| InverseError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// `generations.csv`: one row per generation (floats in shortest round-trip form).
pub fn generations_csv(history: &[GenerationRow]) -> String {
    let mut s = String::from(
        "generation,best_cost,mean_top_k,evaluations,total_evaluations,samples,samples_per_string,best_cost_se\n",
    );
    for r in history {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{}",
            r.generation,
            r.best_cost,
            r.mean_top_k,
            r.evaluations,
            r.total_evaluations,
            r.samples,
            r.samples as f64 / r.evaluations.max(1) as f64,
            r.best_cost_se.map(|x| x.to_string()).unwrap_or_default()
        );
    }
    s
}

#[derive(Debug, Serialize)]
/// One gene of a string in `best.json`: its name, the scenario field it sets, its value.
pub struct GeneValue {
    /// The gene's name.
    pub name: String,
    /// The scenario field it sets (dotted path).
    pub path: String,
    /// Its value, in the field's unit.
    pub value: f64,
}

/// One ranked string of `best.json`.
#[derive(Debug, Serialize)]
pub struct Ranked {
    /// Rank by the GA's ensemble (1 = the best).
    pub rank: usize,
    /// Its genes.
    pub genes: Vec<GeneValue>,
    /// Its cost (the problem's `cost`).
    pub cost: f64,
    /// Standard error of the cost (delta method over the ensemble's samples).
    pub cost_se: Option<f64>,
    /// Ensemble mean b_f / b0.
    pub growth_ratio: f64,
    /// Standard error of `growth_ratio` (None with one sample).
    pub growth_se: Option<f64>,
    /// n_f = (b̄_f / b0)³.
    pub n_f: f64,
    /// Ensemble mean σ/b0 of the final radii.
    pub std_dev_ratio: f64,
    /// Ensemble mean skewness m_3 of the final radii.
    pub skewness: f64,
    /// Ensemble mean kurtosis m_4 of the final radii.
    pub kurtosis: f64,
    /// Samples in its ensemble.
    pub samples: u32,
    /// Failed samples (with an `on_failure` penalty).
    pub failures: u32,
    /// The generation it was evaluated in; sample i ran with seed `seeds[i]` (`agglo
    /// run --seed`).
    pub generation: usize,
    /// Its index in that generation.
    pub index: usize,
    /// The samples' seeds, in sample order.
    pub seeds: Vec<u64>,
}

/// One string of the closing check in `best.json`.
#[derive(Debug, Serialize)]
pub struct Checked {
    /// Rank by the check's cost (1 = the winner).
    pub rank: usize,
    /// Rank by the GA's own ensemble.
    pub ga_rank: usize,
    /// Its genes.
    pub genes: Vec<GeneValue>,
    /// Its cost over the check's ensemble.
    pub cost: f64,
    /// Standard error of that cost (delta method).
    pub cost_se: Option<f64>,
    /// Ensemble mean b_f / b0.
    pub growth_ratio: f64,
    /// Its standard error.
    pub growth_se: Option<f64>,
    /// n_f = (b̄_f / b0)³.
    pub n_f: f64,
    /// Samples in the check's ensemble.
    pub samples: u32,
    /// Failed samples.
    pub failures: u32,
    /// The GA's own cost for the same string.
    pub ga_cost: f64,
    /// The GA's standard error of that cost.
    pub ga_cost_se: Option<f64>,
    /// Samples in the GA's ensemble.
    pub ga_samples: u32,
    /// Sample i of the check ran with seed `seeds[i]`.
    pub seeds: Vec<u64>,
}

#[derive(Debug, Serialize)]
/// The closing check in `best.json`.
pub struct CheckFile {
    /// Strings re-evaluated.
    pub strings: usize,
    /// Samples of fresh seeds per string.
    pub samples_per_string: u32,
    /// The strings, ranked by the check's cost.
    pub ranked: Vec<Checked>,
}

#[derive(Debug, Serialize)]
/// What `best.json` holds.
pub struct BestFile<'a> {
    /// The problem's name.
    pub problem: &'a str,
    /// The cost the strings are ranked by.
    pub cost: &'a CostSpec,
    /// Generations done.
    pub generations: usize,
    /// Strings evaluated in all.
    pub total_evaluations: usize,
    /// True once the GA stopped by its own rule.
    pub finished: bool,
    /// Ranked by the GA's own ensembles (comparable with the papers' tables).
    pub top: Vec<Ranked>,
    /// The closing check: the best strings re-run on fresh seeds and re-ranked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub check: Option<CheckFile>,
}

fn gene_values(problem: &InverseProblem, genes: &[f64]) -> Vec<GeneValue> {
    problem
        .gene_names()
        .iter()
        .zip(&problem.spec.genes)
        .zip(genes)
        .map(|((n, g), &v)| GeneValue {
            name: n.clone(),
            path: g.path.clone(),
            value: v,
        })
        .collect()
}

fn check_file(problem: &InverseProblem, state: &GaState) -> Option<CheckFile> {
    if state.finalists.is_empty() {
        return None;
    }
    let seed = problem.spec.ga.seed;
    let ranked = state
        .finalists
        .iter()
        .enumerate()
        .map(|(r, f): (usize, &Finalist)| {
            let ga = &state.parents[f.ga_rank - 1].eval;
            Checked {
                rank: r + 1,
                ga_rank: f.ga_rank,
                genes: gene_values(problem, &f.genes),
                cost: f.eval.cost,
                cost_se: f.eval.cost_se,
                growth_ratio: f.eval.means.mean,
                growth_se: f.eval.growth_se,
                n_f: f.eval.means.mean.powi(3),
                samples: f.eval.samples,
                failures: f.eval.failures,
                ga_cost: ga.cost,
                ga_cost_se: ga.cost_se,
                ga_samples: ga.samples,
                seeds: (0..f.eval.samples)
                    .map(|i| check_seed(seed, f.ga_rank, i))
                    .collect(),
            }
        })
        .collect();
    Some(CheckFile {
        strings: state.finalists.len(),
        samples_per_string: problem.spec.reevaluate.samples,
        ranked,
    })
}

/// `best.json` of `problem` at `state`: its parents ranked, and the closing check when it ran.
pub fn best_file<'a>(problem: &'a InverseProblem, state: &GaState) -> BestFile<'a> {
    let seed = problem.spec.ga.seed;
    let top = state
        .parents
        .iter()
        .enumerate()
        .map(|(r, m)| Ranked {
            rank: r + 1,
            genes: gene_values(problem, &m.genes),
            cost: m.eval.cost,
            cost_se: m.eval.cost_se,
            growth_ratio: m.eval.means.mean,
            growth_se: m.eval.growth_se,
            n_f: m.eval.means.mean.powi(3),
            std_dev_ratio: m.eval.means.std_dev,
            skewness: m.eval.means.skewness,
            kurtosis: m.eval.means.kurtosis,
            samples: m.eval.samples,
            failures: m.eval.failures,
            generation: m.eval.generation,
            index: m.eval.index,
            seeds: (0..m.eval.samples)
                .map(|i| sample_seed(seed, m.eval.generation, m.eval.index, i))
                .collect(),
        })
        .collect();
    BestFile {
        problem: &problem.spec.name,
        cost: &problem.spec.cost,
        generations: state.generations_done,
        total_evaluations: state.total_evaluations,
        finished: state.finished,
        top,
        check: check_file(problem, state),
    }
}

/// Write the text outputs (cheap; done after every generation).
pub fn write_tables(
    dir: &Path,
    problem: &InverseProblem,
    state: &GaState,
) -> Result<(), InverseError> {
    let p = dir.join("generations.csv");
    std::fs::write(&p, generations_csv(&state.history)).map_err(io(&p))?;
    let best = best_file(problem, state);
    let p = dir.join("best.json");
    let text =
        serde_json::to_string_pretty(&best).map_err(|e| InverseError::Other(e.to_string()))?;
    std::fs::write(&p, text + "\n").map_err(io(&p))?;
    let seed = problem.spec.ga.seed;
    // The winner of the closing check when it ran, else the GA's best.
    let winner = match (state.finalists.first(), state.best()) {
        (Some(f), _) => Some((
            &f.genes,
            check_seed(seed, f.ga_rank, 0),
            format!(
                "Winner of the closing check of inverse problem `{}` after {} generations: \
                 cost {} ± {} (1 s.e.) over {} fresh samples (GA rank {}; seeds in best.json, \
                 this file uses the first).",
                problem.spec.name,
                state.generations_done,
                f.eval.cost,
                f.eval.cost_se.unwrap_or(f64::NAN),
                f.eval.samples,
                f.ga_rank
            ),
        )),
        (None, Some(m)) => Some((
            &m.genes,
            sample_seed(seed, m.eval.generation, m.eval.index, 0),
            format!(
                "Best string of inverse problem `{}` after {} generations: ensemble cost {} over {} samples \
                 (seeds in best.json; this file uses the first).",
                problem.spec.name, state.generations_done, m.eval.cost, m.eval.samples
            ),
        )),
        (None, None) => None,
    };
    if let Some((genes, seed, description)) = winner {
        let mut scenario = problem
            .scenario_for(genes, seed)
            .map_err(|e| InverseError::Other(format!("best scenario: {e}")))?;
        scenario.name = format!("{}_best", problem.spec.name);
        scenario.description = description;
        let p = dir.join("best_scenario.json");
        std::fs::write(&p, scenario.to_json() + "\n").map_err(io(&p))?;
    }
    Ok(())
}

/// Write the charts (at the end of a run).
pub fn write_charts(
    dir: &Path,
    problem: &InverseProblem,
    state: &GaState,
) -> Result<(), InverseError> {
    let chart = |e: anyhow::Error| InverseError::Other(format!("chart: {e:#}"));
    save_png_and_svg(
        dir,
        "convergence",
        (900, 600),
        &Convergence {
            title: format!("{}: cost per generation", problem.spec.name),
            history: &state.history,
            finalists: &state.finalists,
        },
    )
    .map_err(chart)?;
    if let Some(m) = state.best()
        && !m.eval.radii.is_empty()
    {
        save_png_and_svg(
            dir,
            "best_radii",
            (900, 600),
            &Histogram {
                title: format!(
                    "Final radii of the best string ({} samples)",
                    m.eval.samples
                ),
                x_label: "b / b0".into(),
                values: &m.eval.radii,
                bins: 30,
            },
        )
        .map_err(chart)?;
    }
    Ok(())
}

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

struct Convergence<'a> {
    title: String,
    history: &'a [GenerationRow],
    /// Drawn one generation to the right of the last, as "check".
    finalists: &'a [Finalist],
}

impl Figure for Convergence<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let h = self.history;
        let n = h.len().max(1) as f64 + if self.finalists.is_empty() { 0.0 } else { 1.0 };
        let se = |c: f64, e: Option<f64>| (c - e.unwrap_or(0.0), c + e.unwrap_or(0.0));
        // (x, cost, low, high) of the best per generation and of the checked strings.
        let bars: Vec<(f64, f64, f64, f64)> = h
            .iter()
            .map(|r| {
                let (a, b) = se(r.best_cost, r.best_cost_se);
                (r.generation as f64, r.best_cost, a, b)
            })
            .collect();
        let checked: Vec<(f64, f64, f64, f64)> = self
            .finalists
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let (a, b) = se(f.eval.cost, f.eval.cost_se);
                // Side by side across the check's column, the winner first.
                let spread = (self.finalists.len().max(2) - 1) as f64;
                let x = h.len() as f64 - 0.35 + 0.7 * k as f64 / spread;
                (x, f.eval.cost, a, b)
            })
            .collect();
        let values: Vec<f64> = h
            .iter()
            .flat_map(|r| [r.best_cost, r.mean_top_k])
            .chain(bars.iter().chain(&checked).flat_map(|b| [b.2, b.3]))
            .collect();
        let hi = values
            .iter()
            .cloned()
            .filter(|v| v.is_finite())
            .fold(f64::MIN, f64::max);
        let lo = values
            .iter()
            .cloned()
            .filter(|v| v.is_finite())
            .fold(f64::MAX, f64::min);
        let log = lo > 0.0 && hi / lo > 20.0;
        let best: Vec<(f64, f64)> = h
            .iter()
            .map(|r| (r.generation as f64, r.best_cost))
            .collect();
        let mean: Vec<(f64, f64)> = h
            .iter()
            .map(|r| (r.generation as f64, r.mean_top_k))
            .collect();
        let (lo, hi) = if hi >= lo { (lo, hi) } else { (0.0, 1.0) };
        // Error bars clipped to the drawn range (a log axis has no room below 0).
        let floor = if log { lo * 0.8 } else { f64::MIN };
        let clip = |b: &(f64, f64, f64, f64)| (b.0, b.1, b.2.max(floor), b.3);
        let pad = if hi > lo {
            0.05 * (hi - lo)
        } else {
            0.1 * hi.abs().max(1e-12)
        };
        let mut builder = ChartBuilder::on(area);
        builder
            .caption(&self.title, (FONT, 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80);
        macro_rules! finish {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc("generation")
                    .y_desc("cost")
                    .label_style((FONT, 14))
                    .draw()
                    .map_err(err)?;
                chart
                    .draw_series(LineSeries::new(best.clone(), BLUE.stroke_width(2)))
                    .map_err(err)?
                    .label("best")
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2))
                    });
                chart
                    .draw_series(best.iter().map(|&p| Circle::new(p, 3, BLUE.filled())))
                    .map_err(err)?;
                chart
                    .draw_series(bars.iter().map(clip).map(|(x, y, a, b)| {
                        ErrorBar::new_vertical(x, a, y, b, BLUE.stroke_width(1), 6)
                    }))
                    .map_err(err)?
                    .label("best ± 1 s.e. (its own ensemble)")
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x + 10, y - 6), (x + 10, y + 6)], BLUE)
                    });
                if !checked.is_empty() {
                    let green = RGBColor(0, 140, 60);
                    chart
                        .draw_series(
                            checked
                                .iter()
                                .map(|&(x, y, _, _)| Circle::new((x, y), 4, green.filled())),
                        )
                        .map_err(err)?;
                    chart
                        .draw_series(checked.iter().map(clip).map(|(x, y, a, b)| {
                            ErrorBar::new_vertical(x, a, y, b, green.stroke_width(2), 6)
                        }))
                        .map_err(err)?
                        .label("closing check: best strings on fresh seeds, ± 1 s.e.")
                        .legend(move |(x, y)| {
                            PathElement::new(
                                vec![(x + 10, y - 6), (x + 10, y + 6)],
                                green.stroke_width(2),
                            )
                        });
                }
                chart
                    .draw_series(LineSeries::new(mean.clone(), RED.stroke_width(2)))
                    .map_err(err)?
                    .label("mean of top K")
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2))
                    });
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .label_font((FONT, 14))
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(err)?;
            }};
        }
        // The legend (four lines, upper right) gets the top ~40 % of the plot to itself:
        // the costs fall with the generations, so without this headroom it covered the
        // last generations and the closing check.
        if log {
            let headroom = (hi / lo).powf(0.7).max(1.25);
            finish!(
                builder
                    .build_cartesian_2d(-0.5..n - 0.5, (lo * 0.8..hi * headroom).log_scale())
                    .map_err(err)?
            );
        } else {
            let headroom = 0.7 * (hi - lo) + pad;
            finish!(
                builder
                    .build_cartesian_2d(-0.5..n - 0.5, (lo - pad)..(hi + headroom))
                    .map_err(err)?
            );
        }
        Ok(())
    }
}

/// A histogram of `values` with `bins` equal bins.
pub struct Histogram<'a> {
    /// The chart's title.
    pub title: String,
    /// The x axis's label.
    pub x_label: String,
    /// The values binned.
    pub values: &'a [f64],
    /// Equal bins over the values' range.
    pub bins: usize,
}

impl Figure for Histogram<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let lo = self.values.iter().cloned().fold(f64::MAX, f64::min);
        let mut hi = self.values.iter().cloned().fold(f64::MIN, f64::max);
        if hi <= lo {
            hi = lo + 1.0;
        }
        let width = (hi - lo) / self.bins as f64;
        let mut counts = vec![0usize; self.bins];
        for &v in self.values {
            let i = (((v - lo) / width) as usize).min(self.bins - 1);
            counts[i] += 1;
        }
        let top = *counts.iter().max().unwrap_or(&1) as f64;
        let mut chart = ChartBuilder::on(area)
            .caption(&self.title, (FONT, 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(lo..hi, 0.0..top * 1.1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc("bodies")
            .label_style((FONT, 14))
            .draw()
            .map_err(err)?;
        chart
            .draw_series(counts.iter().enumerate().map(|(i, &c)| {
                let x0 = lo + i as f64 * width;
                Rectangle::new([(x0, 0.0), (x0 + width, c as f64)], BLUE.mix(0.6).filled())
            }))
            .map_err(err)?;
        Ok(())
    }
}

/// A line chart of y against x, optionally with a horizontal reference line.
pub struct LineChart<'a> {
    /// The chart's title.
    pub title: String,
    /// The x axis's label.
    pub x_label: String,
    /// The y axis's label.
    pub y_label: String,
    /// The (x, y) points, joined in order.
    pub points: &'a [(f64, f64)],
    /// A logarithmic x axis.
    pub log_x: bool,
    /// A horizontal line at this y, with its label.
    pub reference: Option<(f64, String)>,
}

impl Figure for LineChart<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let xs = self.points.iter().map(|p| p.0);
        let x0 = xs.clone().fold(f64::MAX, f64::min);
        let x1 = xs.fold(f64::MIN, f64::max).max(x0 * 1.0001 + 1e-300);
        let mut ys: Vec<f64> = self
            .points
            .iter()
            .map(|p| p.1)
            .filter(|y| y.is_finite())
            .collect();
        if let Some((r, _)) = &self.reference {
            ys.push(*r);
        }
        let y0 = ys.iter().cloned().fold(f64::MAX, f64::min);
        let y1 = ys.iter().cloned().fold(f64::MIN, f64::max);
        let pad = ((y1 - y0) * 0.08).max(1e-9);
        let mut builder = ChartBuilder::on(area);
        builder
            .caption(&self.title, (FONT, 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70);
        macro_rules! finish {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(self.x_label.as_str())
                    .y_desc(self.y_label.as_str())
                    .label_style((FONT, 14))
                    .draw()
                    .map_err(err)?;
                chart
                    .draw_series(LineSeries::new(self.points.to_vec(), BLUE.stroke_width(2)))
                    .map_err(err)?;
                chart
                    .draw_series(
                        self.points
                            .iter()
                            .map(|&p| Circle::new(p, 4, BLUE.filled())),
                    )
                    .map_err(err)?;
                if let Some((r, label)) = &self.reference {
                    chart
                        .draw_series(LineSeries::new(
                            vec![(x0, *r), (x1, *r)],
                            RED.stroke_width(1),
                        ))
                        .map_err(err)?
                        .label(label.as_str())
                        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
                    chart
                        .configure_series_labels()
                        .label_font((FONT, 14))
                        .background_style(WHITE.mix(0.8))
                        .border_style(BLACK)
                        .draw()
                        .map_err(err)?;
                }
            }};
        }
        if self.log_x && x0 > 0.0 {
            finish!(
                builder
                    .build_cartesian_2d((x0..x1).log_scale(), (y0 - pad)..(y1 + pad))
                    .map_err(err)?
            );
        } else {
            finish!(
                builder
                    .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
                    .map_err(err)?
            );
        }
        Ok(())
    }
}
