//! The study's figures, each drawn once through [`Figure`] and saved as PNG + SVG with
//! [`save_png_and_svg`] (bundled font; no system fonts needed).
//!
//! - `accuracy_error`: relative error in b_f/b0 and the KS distance of the radius
//!   distribution against median wall time, log–log, one series per family, the
//!   Pareto front (cheapest setting for each error level) joined by a line, the noise
//!   level (reference over other seeds) shaded.
//! - `accuracy_growth`: b_f/b0 against wall time, the reference's seed band shaded
//!   and, when given, a published value (P04's 3.23) drawn across.
//! - `pair_map`, `pair_map_softening`: plain-iteration count and safeguarded count over
//!   speed × a0; black = the plain iteration never converges.
//! - `cooling_map`: relative error of explicit and implicit Euler over Δt × θ0, the
//!   explicit limit (and 4 × it) drawn on top, unstable cells in magenta.
//! - `tunnelling`: fraction of collisions missed against Δt and c.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::charts::{FONT, Figure, save_png_and_svg};

use super::accuracy::{AccuracyStudy, Family, Row};
use super::stability::{CoolingCell, PairCell, StabilityStudy};

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing: {e}")
}

fn family_color(f: Family) -> RGBColor {
    match f {
        Family::Reference => RGBColor(0, 0, 0),
        Family::Adaptive => RGBColor(31, 119, 180),
        Family::FixedDt => RGBColor(255, 127, 14),
        Family::Tolerance => RGBColor(44, 160, 44),
        Family::Cooling => RGBColor(148, 103, 189),
        Family::Papers => RGBColor(214, 39, 40),
    }
}

fn family_label(f: Family) -> &'static str {
    match f {
        Family::Reference => "reference (c = 1, TOL 1e-14)",
        Family::Adaptive => "adaptive, step factor c",
        Family::FixedDt => "fixed Δt",
        Family::Tolerance => "fixed-point TOL",
        Family::Cooling => "cooling explicit/implicit",
        Family::Papers => "papers' choices (NN rule, P04 bounds, plain)",
    }
}

fn text(size: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font()).color(&BLACK)
}

/// Indices of the Pareto-optimal points (no other point both as fast and as accurate).
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    idx.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

/// One line per failed run (label, then where and why it stopped), for the note under
/// a chart: a failed run is no point on it, but it is not left out silently either.
fn failed_lines(study: &AccuracyStudy) -> Vec<String> {
    study
        .rows
        .iter()
        .filter(|r| r.failed())
        .map(|r| {
            let why = r.measurement.failure.as_deref().unwrap_or("");
            // Keep a line within the figure's width.
            let why: String = if why.chars().count() > 110 {
                why.chars().take(107).chain("...".chars()).collect()
            } else {
                why.to_string()
            };
            format!("failed, not drawn: {} — {why}", r.label)
        })
        .collect()
}

/// Split `area` into the chart and, below it, a note listing the failed runs.
fn with_failure_note<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    study: &AccuracyStudy,
) -> anyhow::Result<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    let lines = failed_lines(study);
    if lines.is_empty() {
        return Ok(area.clone());
    }
    let height = area.dim_in_pixel().1 as i32;
    let note_height = 8 + 18 * lines.len() as i32;
    let (chart, note) = area.split_vertically(height - note_height);
    for (k, line) in lines.iter().enumerate() {
        note.draw_text(
            line,
            &text(13).color(&RGBColor(180, 0, 0)),
            (12, 4 + 18 * k as i32),
        )
        .map_err(err)?;
    }
    Ok(chart)
}

struct AccuracyError<'a> {
    study: &'a AccuracyStudy,
}

impl AccuracyError<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        metric: fn(&Row) -> f64,
        noise: f64,
        y_label: &str,
        title: &str,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let rows: Vec<&Row> = self.study.rows.iter().filter(|r| !r.failed()).collect();
        let positive = rows
            .iter()
            .map(|r| metric(r))
            .chain([noise])
            .filter(|&e| e > 0.0 && e.is_finite())
            .fold(f64::INFINITY, f64::min);
        // Errors of exactly 0 (the reference, settings that reproduce it bit for bit) sit on the floor.
        let floor = if positive.is_finite() {
            positive / 10.0
        } else {
            1e-6
        };
        let top = rows
            .iter()
            .map(|r| metric(r))
            .chain([noise])
            .filter(|e| e.is_finite())
            .fold(floor * 10.0, f64::max)
            * 30.0; // headroom for the legend
        let walls: Vec<f64> = rows
            .iter()
            .map(|r| r.measurement.wall_seconds.max(1e-6))
            .collect();
        let (wmin, wmax) = walls
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(a, b), &w| (a.min(w), b.max(w)));
        let (x0, x1) = (wmin / 2.0, wmax * 2.0);
        let mut chart = ChartBuilder::on(area)
            .caption(title, text(18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (floor / 2.0..top).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("median wall time [s]")
            .y_desc(y_label)
            .label_style(text(13))
            .axis_desc_style(text(14))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .draw()
            .map_err(err)?;
        if noise > 0.0 {
            chart
                .draw_series([Rectangle::new(
                    [(x0, floor / 2.0), (x1, noise)],
                    RGBColor(200, 200, 200).mix(0.4).filled(),
                )])
                .map_err(err)?
                .label(format!("noise: other seeds (mean {noise:.2e})"))
                .legend(|(x, y)| {
                    Rectangle::new(
                        [(x, y - 5), (x + 15, y + 5)],
                        RGBColor(200, 200, 200).filled(),
                    )
                });
        }
        let points: Vec<(f64, f64)> = rows
            .iter()
            .zip(&walls)
            .map(|(r, &w)| (w, metric(r).max(floor)))
            .collect();
        for family in Family::ALL.iter().rev().copied() {
            let color = family_color(family);
            let radius = if family == Family::Reference { 7 } else { 5 };
            let mut pts: Vec<(f64, f64)> = rows
                .iter()
                .zip(&points)
                .filter(|(r, _)| r.family == family)
                .map(|(_, p)| *p)
                .collect();
            if pts.is_empty() {
                continue;
            }
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let series = chart
                .draw_series(
                    pts.iter()
                        .map(|&p| Circle::new(p, radius, ShapeStyle::from(&color).filled())),
                )
                .map_err(err)?;
            series.label(family_label(family)).legend(move |(x, y)| {
                Circle::new((x + 7, y), 5, ShapeStyle::from(&color).filled())
            });
        }
        let front = pareto_front(&points);
        let front_pts: Vec<(f64, f64)> = front.iter().map(|&i| points[i]).collect();
        chart
            .draw_series(LineSeries::new(
                front_pts.clone(),
                ShapeStyle::from(&BLACK).stroke_width(1),
            ))
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], BLACK));
        chart
            .draw_series(
                front_pts
                    .iter()
                    .map(|&p| Circle::new(p, 8, ShapeStyle::from(&BLACK).stroke_width(1))),
            )
            .map_err(err)?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(text(12))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)?;
        Ok(())
    }
}

impl Figure for AccuracyError<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (title, body) = area.split_vertically(36);
        title
            .draw_text(
                &format!(
                    "{}: speed against accuracy ({} settings, same seed; zero error drawn on the floor)",
                    self.study.scenario,
                    self.study.rows.len()
                ),
                &text(20),
                (10, 8),
            )
            .map_err(err)?;
        let body = with_failure_note(&body, self.study)?;
        let panels = body.split_evenly((1, 2));
        let level = self.study.noise.level;
        self.panel(
            &panels[0],
            |r| r.errors.growth,
            level.growth,
            "relative error in b_f/b0",
            "growth b_f/b0",
        )?;
        self.panel(
            &panels[1],
            |r| r.errors.ks,
            level.ks,
            "KS distance of final radii",
            "radius distribution",
        )?;
        Ok(())
    }
}

struct AccuracyGrowth<'a> {
    study: &'a AccuracyStudy,
}

impl Figure for AccuracyGrowth<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let s = self.study;
        let area = &with_failure_note(area, s)?;
        let rows: Vec<&Row> = s.rows.iter().filter(|r| !r.failed()).collect();
        let walls: Vec<f64> = rows
            .iter()
            .map(|r| r.measurement.wall_seconds.max(1e-6))
            .collect();
        let (wmin, wmax) = walls
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(a, b), &w| (a.min(w), b.max(w)));
        let (x0, x1) = (wmin / 2.0, wmax * 2.0);
        // Ensemble rows reach mean ± 1 s.e. as well as their own seed's value.
        let ensemble_ends = rows
            .iter()
            .filter_map(|r| r.ensemble.as_ref())
            .flat_map(|e| {
                [e.growth_mean - e.growth_se, e.growth_mean + e.growth_se]
                    .into_iter()
                    .filter(|g| g.is_finite())
            });
        let (mut g0, mut g1) = rows
            .iter()
            .map(|r| r.measurement.growth_ratio)
            .chain(ensemble_ends)
            .chain(s.target_growth)
            .chain([
                s.noise.growth_mean - 2.0 * s.noise.growth_std,
                s.noise.growth_mean + 2.0 * s.noise.growth_std,
            ])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| {
                (a.min(g), b.max(g))
            });
        let pad = 0.08 * (g1 - g0).max(0.05);
        g0 -= pad;
        g1 += 6.0 * pad; // headroom for the legend
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{}: final b_f/b0 of each setting", s.scenario),
                text(20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), g0..g1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("median wall time [s]")
            .y_desc("b_f / b0")
            .label_style(text(13))
            .axis_desc_style(text(14))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .draw()
            .map_err(err)?;
        let (m, sd) = (s.noise.growth_mean, s.noise.growth_std);
        chart
            .draw_series([Rectangle::new(
                [(x0, m - sd), (x1, m + sd)],
                RGBColor(200, 200, 200).mix(0.5).filled(),
            )])
            .map_err(err)?
            .label(format!(
                "reference over {} seeds: {m:.3} ± {sd:.3}",
                s.noise.seeds.len()
            ))
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 15, y + 5)],
                    RGBColor(200, 200, 200).filled(),
                )
            });
        if let Some(t) = s.target_growth {
            chart
                .draw_series(LineSeries::new(
                    [(x0, t), (x1, t)],
                    ShapeStyle::from(&RED).stroke_width(2),
                ))
                .map_err(err)?
                .label(format!("published value {t}"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], RED));
        }
        for family in Family::ALL.iter().rev().copied() {
            let color = family_color(family);
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .zip(&walls)
                .filter(|(r, _)| r.family == family)
                .map(|(r, &w)| (w, r.measurement.growth_ratio))
                .collect();
            if pts.is_empty() {
                continue;
            }
            chart
                .draw_series(
                    pts.iter()
                        .map(|&p| Circle::new(p, 5, ShapeStyle::from(&color).filled())),
                )
                .map_err(err)?
                .label(family_label(family))
                .legend(move |(x, y)| {
                    Circle::new((x + 7, y), 5, ShapeStyle::from(&color).filled())
                });
        }
        // Settings run over several seeds: their mean ± 1 s.e. as an error bar (ticks at
        // mean − s.e., mean, mean + s.e.) at the same wall time as their own seed's dot.
        let ensembles: Vec<(f64, f64, f64)> = rows
            .iter()
            .zip(&walls)
            .filter_map(|(r, &w)| r.ensemble.as_ref().map(|e| (w, e.growth_mean, e.growth_se)))
            .filter(|(_, m, se)| m.is_finite() && se.is_finite())
            .collect();
        if !ensembles.is_empty() {
            let seeds = rows
                .iter()
                .filter_map(|r| r.ensemble.as_ref())
                .map(|e| e.seeds)
                .max()
                .unwrap_or(0);
            let style = ShapeStyle::from(&BLACK).stroke_width(2);
            chart
                .draw_series(
                    ensembles
                        .iter()
                        .map(|&(w, m, se)| ErrorBar::new_vertical(w, m - se, m, m + se, style, 10)),
                )
                .map_err(err)?
                .label(format!(
                    "unconverged settings: mean ± s.e. over {seeds} seeds"
                ))
                .legend(move |(x, y)| PathElement::new([(x + 7, y - 6), (x + 7, y + 6)], style));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(text(12))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)?;
        Ok(())
    }
}

/// Draw the accuracy charts into `dir`.
pub fn accuracy_charts(dir: &Path, study: &AccuracyStudy) -> anyhow::Result<()> {
    save_png_and_svg(dir, "accuracy_error", (1500, 650), &AccuracyError { study })?;
    save_png_and_svg(
        dir,
        "accuracy_growth",
        (1000, 650),
        &AccuracyGrowth { study },
    )?;
    Ok(())
}

/// A perceptually ordered map (viridis stops) of t ∈ [0, 1].
fn viridis(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 6] = [
        (68, 1, 84),
        (65, 68, 135),
        (42, 120, 142),
        (34, 168, 132),
        (122, 209, 81),
        (253, 231, 37),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let x = t * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f64;
    let lerp = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    RGBColor(lerp(a.0, b.0), lerp(a.1, b.1), lerp(a.2, b.2))
}

/// A heat map cell: rectangle corners (x0, y0)–(x1, y1) and its colour.
type Cell = ((f64, f64), (f64, f64), RGBColor);

/// Half-way cell edges between sorted grid values (geometric midpoints when `log`).
fn edges(values: &[f64], log: bool) -> Vec<f64> {
    let n = values.len();
    let mid = |a: f64, b: f64| if log { (a * b).sqrt() } else { 0.5 * (a + b) };
    let mut e = Vec::with_capacity(n + 1);
    if n == 1 {
        let v = values[0];
        return if log {
            vec![v / 2.0, v * 2.0]
        } else {
            vec![v - 0.5, v + 0.5]
        };
    }
    let first = if log {
        values[0] * values[0] / mid(values[0], values[1])
    } else {
        2.0 * values[0] - mid(values[0], values[1])
    };
    e.push(first);
    for k in 0..n - 1 {
        e.push(mid(values[k], values[k + 1]));
    }
    let last = if log {
        values[n - 1] * values[n - 1] / mid(values[n - 2], values[n - 1])
    } else {
        2.0 * values[n - 1] - mid(values[n - 2], values[n - 1])
    };
    e.push(last);
    e
}

fn unique_sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

fn index_of(values: &[f64], x: f64) -> usize {
    values.iter().position(|&v| v == x).unwrap_or(0)
}

/// Decades between colour-bar labels so that there are at most ~9 labels.
fn ticks_every(range: f64) -> usize {
    ((range / 8.0).ceil() as usize).max(1)
}

/// Colour bar: `lo..hi` in log10 units, labelled.
fn colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    lo: f64,
    hi: f64,
    label: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let mut chart = ChartBuilder::on(area)
        .margin_top(40)
        .margin_bottom(50)
        .margin_right(5)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .disable_x_axis()
        .y_desc(label)
        .y_labels(((hi - lo) as usize / ticks_every(hi - lo)) + 1)
        .label_style(text(12))
        .axis_desc_style(text(12))
        .y_label_formatter(&|y| format!("1e{y:.0}"))
        .draw()
        .map_err(err)?;
    let n = 100;
    chart
        .draw_series((0..n).map(|k| {
            let a = lo + (hi - lo) * k as f64 / n as f64;
            let b = lo + (hi - lo) * (k + 1) as f64 / n as f64;
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                viridis((k as f64 + 0.5) / n as f64).filled(),
            )
        }))
        .map_err(err)?;
    Ok(())
}

struct PairMap<'a> {
    cells: &'a [PairCell],
    title: &'a str,
}

impl PairMap<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        safeguarded: bool,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let xs = unique_sorted(self.cells.iter().map(|c| c.speed_ratio).collect());
        let ys = unique_sorted(self.cells.iter().map(|c| c.a0).collect());
        let (xe, ye) = (edges(&xs, false), edges(&ys, false));
        let (main, bar) = area.split_horizontally(area.dim_in_pixel().0.saturating_sub(110));
        let (lo, hi) = (0.0, 5.0); // log10 of 1 … 1e5 evaluations of G
        let title = if safeguarded {
            "safeguarded solver (100 plain its, then Illinois): G evaluations"
        } else {
            "papers' plain iteration: iterations to converge (black: never)"
        };
        let mut chart = ChartBuilder::on(&main)
            .caption(title, text(15))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(xe[0]..xe[xe.len() - 1], ye[0]..ye[ye.len() - 1])
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("approach speed / critical speed (cold)")
            .y_desc("a0")
            .label_style(text(12))
            .axis_desc_style(text(13))
            .draw()
            .map_err(err)?;
        let rects: Vec<Cell> = self
            .cells
            .iter()
            .map(|c| {
                let (i, j) = (index_of(&xs, c.speed_ratio), index_of(&ys, c.a0));
                let color = if safeguarded {
                    let n = (c.safeguarded.iterations + c.safeguarded.fallback_iterations) as f64;
                    if c.safeguarded_converged() {
                        viridis((n.max(1.0).log10() - lo) / (hi - lo))
                    } else {
                        BLACK
                    }
                } else if c.plain_converged() {
                    viridis(((c.plain.iterations as f64).max(1.0).log10() - lo) / (hi - lo))
                } else {
                    BLACK
                };
                ((xe[i], ye[j]), (xe[i + 1], ye[j + 1]), color)
            })
            .collect();
        chart
            .draw_series(
                rects
                    .into_iter()
                    .map(|(a, b, c)| Rectangle::new([a, b], c.filled())),
            )
            .map_err(err)?;
        // The critical speed (λ = af: bonding at and above it without softening).
        chart
            .draw_series(LineSeries::new(
                [(1.0, ye[0]), (1.0, ye[ye.len() - 1])],
                ShapeStyle::from(&WHITE).stroke_width(1),
            ))
            .map_err(err)?;
        colour_bar(&bar, lo, hi, "G evaluations")?;
        Ok(())
    }
}

impl Figure for PairMap<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (title, body) = area.split_vertically(34);
        title
            .draw_text(self.title, &text(18), (10, 8))
            .map_err(err)?;
        let panels = body.split_evenly((1, 2));
        self.panel(&panels[0], false)?;
        self.panel(&panels[1], true)?;
        Ok(())
    }
}

struct CoolingMap<'a> {
    cells: &'a [CoolingCell],
}

impl CoolingMap<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        explicit: bool,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let xs = unique_sorted(self.cells.iter().map(|c| c.dt).collect());
        let ys = unique_sorted(self.cells.iter().map(|c| c.theta_initial).collect());
        let (xe, ye) = (edges(&xs, true), edges(&ys, true));
        let (main, bar) = area.split_horizontally(area.dim_in_pixel().0.saturating_sub(110));
        let (lo, hi) = (-16.0, 0.0);
        let title = if explicit {
            "explicit (forward) Euler: relative error after 10 steps"
        } else {
            "implicit (backward) Euler: relative error after 10 steps"
        };
        let (x0, x1, y0, y1) = (xe[0], xe[xe.len() - 1], ye[0], ye[ye.len() - 1]);
        let mut chart = ChartBuilder::on(&main)
            .caption(title, text(15))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("Δt [s]")
            .y_desc("initial temperature θ0 [K]")
            .label_style(text(12))
            .axis_desc_style(text(13))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()
            .map_err(err)?;
        let magenta = RGBColor(230, 0, 230);
        let rects: Vec<Cell> = self
            .cells
            .iter()
            .map(|c| {
                let (i, j) = (index_of(&xs, c.dt), index_of(&ys, c.theta_initial));
                let (e, unstable) = if explicit {
                    (c.explicit_error, c.explicit_unstable)
                } else {
                    (c.implicit_error, c.implicit_unstable)
                };
                let color = if unstable {
                    magenta
                } else {
                    viridis((e.max(1e-16).log10() - lo) / (hi - lo))
                };
                ((xe[i], ye[j]), (xe[i + 1], ye[j + 1]), color)
            })
            .collect();
        chart
            .draw_series(
                rects
                    .into_iter()
                    .map(|(a, b, c)| Rectangle::new([a, b], c.filled())),
            )
            .map_err(err)?;
        // Limit lines: Δt = limit(θ) ∝ θ^{-3}; from any cell, limit(θ) = limit_c (θ_c/θ)³.
        if let Some(c) = self.cells.first() {
            for (factor, label, color) in [
                (1.0, "explicit limit 1/(4kθ³)", WHITE),
                (4.0, "4 × limit (θs = 0: first step negative)", RED),
            ] {
                let line: Vec<(f64, f64)> = (0..=200)
                    .map(|k| {
                        let theta = y0 * (y1 / y0).powf(k as f64 / 200.0);
                        (factor * c.limit * (c.theta_initial / theta).powi(3), theta)
                    })
                    .filter(|&(dt, _)| dt >= x0 && dt <= x1)
                    .collect();
                chart
                    .draw_series(LineSeries::new(
                        line,
                        ShapeStyle::from(&color).stroke_width(2),
                    ))
                    .map_err(err)?
                    .label(label)
                    .legend(move |(x, y)| {
                        PathElement::new(
                            [(x, y), (x + 15, y)],
                            ShapeStyle::from(&color).stroke_width(2),
                        )
                    });
            }
            chart
                .draw_series([Rectangle::new([(x0, y0), (x0, y0)], magenta.filled())])
                .map_err(err)?
                .label("unstable: θ ≤ 0, rises, or not finite")
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 15, y + 5)], magenta.filled())
                });
            chart
                .configure_series_labels()
                .background_style(RGBColor(120, 120, 120).mix(0.9))
                .border_style(BLACK)
                .label_font(TextStyle::from((FONT, 12).into_font()).color(&WHITE))
                .position(SeriesLabelPosition::LowerLeft)
                .draw()
                .map_err(err)?;
        }
        colour_bar(&bar, lo, hi, "relative error")?;
        Ok(())
    }
}

impl Figure for CoolingMap<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (title, body) = area.split_vertically(34);
        title
            .draw_text(
                "Radiative cooling of a 1 mm grain (P04 material, hc = 0, θs = 0) against the closed form",
                &text(18),
                (10, 8),
            )
            .map_err(err)?;
        let panels = body.split_evenly((1, 2));
        self.panel(&panels[0], true)?;
        self.panel(&panels[1], false)?;
        Ok(())
    }
}

struct Tunnelling<'a> {
    study: &'a StabilityStudy,
}

impl Tunnelling<'_> {
    fn line_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
        x_desc: &str,
        pts: &[(f64, f64)],
        band: f64,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (x0, x1) = pts.iter().fold((f64::INFINITY, 0.0_f64), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
        let (x0, x1) = if x0.is_finite() && x1 > x0 {
            (x0 / 1.5, x1 * 1.5)
        } else {
            (0.1, 10.0)
        };
        let y0 = pts.iter().map(|p| p.1).fold(-0.05, f64::min) - 0.02;
        let mut chart = ChartBuilder::on(area)
            .caption(title, text(15))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d((x0..x1).log_scale(), y0..1.02)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("fraction of collisions missed")
            .label_style(text(12))
            .axis_desc_style(text(13))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .draw()
            .map_err(err)?;
        if band > 0.0 {
            chart
                .draw_series([Rectangle::new(
                    [(x0, -band), (x1, band)],
                    RGBColor(200, 200, 200).mix(0.5).filled(),
                )])
                .map_err(err)?;
        }
        chart
            .draw_series(LineSeries::new(
                pts.to_vec(),
                ShapeStyle::from(&BLUE).stroke_width(2),
            ))
            .map_err(err)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|&p| Circle::new(p, 4, ShapeStyle::from(&BLUE).filled())),
            )
            .map_err(err)?;
        Ok(())
    }
}

impl Figure for Tunnelling<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let s = self.study;
        let (title, body) = area.split_vertically(34);
        title
            .draw_text(
                "Collisions missed by the step size (grey: seed spread of the resolved count)",
                &text(18),
                (10, 8),
            )
            .map_err(err)?;
        let panels = body.split_evenly((1, 3));
        let kin: Vec<(f64, f64)> = s
            .kinematic
            .iter()
            .filter(|k| k.colliding > 0)
            .map(|k| (k.dt / s.crossing_time, k.missed_fraction()))
            .collect();
        self.line_panel(
            &panels[0],
            "one step from the initial cloud (kinematic)",
            "Δt / (b0 / |v_rel|)",
            &kin,
            0.0,
        )?;
        let fixed: Vec<(f64, f64)> = s
            .runs
            .iter()
            .filter(|r| r.family == "fixed_dt")
            .map(|r| (r.parameter / s.crossing_time, r.missed_fraction()))
            .collect();
        self.line_panel(
            &panels[1],
            "whole runs, elastic scene: fixed Δt",
            "Δt / (b0 / |v_rel|)",
            &fixed,
            s.runs_noise,
        )?;
        let adaptive: Vec<(f64, f64)> = s
            .runs
            .iter()
            .filter(|r| r.family == "adaptive_c")
            .map(|r| (r.parameter, r.missed_fraction()))
            .collect();
        self.line_panel(
            &panels[2],
            "whole runs, elastic scene: adaptive step factor",
            "step factor c",
            &adaptive,
            s.runs_noise,
        )?;
        Ok(())
    }
}

/// Draw the stability charts into `dir`.
pub fn stability_charts(dir: &Path, study: &StabilityStudy) -> anyhow::Result<()> {
    save_png_and_svg(
        dir,
        "pair_map",
        (1500, 600),
        &PairMap {
            cells: &study.pair_cold,
            title: "Pair solve, two identical spheres head on, no softening (docs/model.md §14)",
        },
    )?;
    save_png_and_svg(
        dir,
        "pair_map_softening",
        (1500, 600),
        &PairMap {
            cells: &study.pair_soft,
            title: "Pair solve with thermal softening (α = 3e5 J/m², Q = 2e4 J/mol, θ0 = 300 K)",
        },
    )?;
    save_png_and_svg(
        dir,
        "cooling_map",
        (1500, 650),
        &CoolingMap {
            cells: &study.cooling,
        },
    )?;
    save_png_and_svg(dir, "tunnelling", (1500, 500), &Tunnelling { study })?;
    Ok(())
}
