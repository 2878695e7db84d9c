//! The study's outputs: `readings.csv`, `runs.csv`, `readings.md` and the chart.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::*;
use crate::charts::{FONT, Figure, save_png_and_svg};

/// Write `readings.csv` (one row per reading), `runs.csv` (one row per run),
/// `readings.md` (the table for the docs) and the chart `readings.png`/`.svg` to `dir`.
pub fn write_readings(dir: &Path, study: &ReadingsStudy) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let header = [
        "reading",
        "what",
        "source",
        "runs",
        "failures",
        "growth_mean",
        "growth_std",
        "growth_se",
        "delta",
        "z",
        "z_target",
        "mass_mean_ratio",
        "pi04",
        "pi02",
        "n_f",
        "final_bodies",
        "impacts",
        "bonds",
        "unconverged",
        "reaction_over_dissipation",
        "wall_seconds",
        "failure",
    ];
    let clean = |s: &str| s.replace([',', '\n'], ";");
    let rows: Vec<Vec<String>> = study
        .readings
        .iter()
        .zip(&study.summaries)
        .map(|(r, s)| {
            vec![
                r.key.clone(),
                clean(&r.what),
                clean(&r.source),
                s.runs.to_string(),
                s.failures.to_string(),
                num(s.growth_mean),
                num(s.growth_std),
                num(s.growth_se),
                num(s.delta),
                num(s.z),
                num(s.z_target),
                num(s.mass_mean_ratio),
                num(s.pi04),
                num(s.pi02),
                num(s.n_f),
                num(s.final_bodies),
                num(s.impacts),
                num(s.bonds),
                num(s.unconverged),
                num(s.reaction_over_dissipation),
                num(s.wall_seconds),
                clean(&s.failure),
            ]
        })
        .collect();
    write_csv(&dir.join("readings.csv"), &header, &rows)?;

    let run_header = [
        "reading",
        "seed",
        "growth_ratio",
        "mass_mean_ratio",
        "pi04",
        "n_f",
        "final_bodies",
        "impacts",
        "bonds",
        "bounces",
        "fallbacks",
        "unconverged",
        "reaction_over_dissipation",
        "max_temperature",
        "invariant_violations",
        "wall_seconds",
        "error",
    ];
    let run_rows: Vec<Vec<String>> = study
        .runs
        .iter()
        .map(|run| {
            let key = study.readings[run.reading].key.clone();
            match &run.result {
                Ok(m) => vec![
                    key,
                    run.seed.to_string(),
                    num(m.growth_ratio),
                    num(m.mass_mean_ratio),
                    num(m.pi04),
                    num(m.n_f),
                    m.final_bodies.to_string(),
                    m.impacts.to_string(),
                    m.bonds.to_string(),
                    m.bounces.to_string(),
                    m.fallbacks.to_string(),
                    m.unconverged.to_string(),
                    num(m.reaction_over_dissipation),
                    num(m.max_temperature),
                    m.invariant_violations.to_string(),
                    num(m.wall_seconds),
                    String::new(),
                ],
                Err(e) => {
                    let mut row = vec![key, run.seed.to_string()];
                    row.extend(std::iter::repeat_n(String::new(), run_header.len() - 3));
                    row.push(clean(e));
                    row
                }
            }
        })
        .collect();
    write_csv(&dir.join("runs.csv"), &run_header, &run_rows)?;
    std::fs::write(dir.join("readings.md"), markdown(study))?;
    // One row per reading: beyond MAX_CHART_ROWS (combination runs) the table is the result.
    if study.readings.len() <= MAX_CHART_ROWS {
        let height = 160 + 34 * study.readings.len() as u32;
        save_png_and_svg(dir, "readings", (1000, height), &Chart(study))?;
    }
    Ok(())
}

/// The summary table in Markdown.
pub fn markdown(study: &ReadingsStudy) -> String {
    let mut s = format!(
        "{} — {} seeds ({}…{}){}{}\n\n",
        study.scenario,
        study.seeds.len(),
        study.seeds.first().copied().unwrap_or(0),
        study.seeds.last().copied().unwrap_or(0),
        match study.p02_steps {
            Some(n) => format!(", T from P02 (13) with {n} fixed steps"),
            None => String::new(),
        },
        match study.max_steps {
            Some(n) => format!(", at most {n} steps per run"),
            None => String::new(),
        }
    );
    if let Some(t) = study.target_growth {
        s += &format!("Published b_f/b0: {t}.\n\n");
    }
    s += "| reading | what | b_f/b0 (± s.e.) | Δ vs baseline | z | z vs published | (N0/N_f)^(1/3) | Π04 | Π02 | bonds | failed |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (r, m) in study.readings.iter().zip(&study.summaries) {
        let ok = m.runs - m.failures;
        let (growth, delta, z) = if ok == 0 {
            ("–".to_string(), "–".to_string(), "–".to_string())
        } else {
            (
                format!("{:.3} ± {:.3}", m.growth_mean, m.growth_se),
                if r.key == BASELINE {
                    "–".into()
                } else {
                    format!("{:+.3}", m.delta)
                },
                if r.key == BASELINE {
                    "–".into()
                } else {
                    format!("{:+.1}", m.z)
                },
            )
        };
        let val = |x: f64, p: usize| {
            if ok == 0 {
                "–".to_string()
            } else {
                format!("{x:.p$}")
            }
        };
        let z_target = if ok == 0 || m.z_target.is_nan() {
            "–".to_string()
        } else {
            format!("{:+.1}", m.z_target)
        };
        s += &format!(
            "| `{}` | {} ({}) | {} | {} | {} | {} | {} | {} | {} | {} | {}/{} |\n",
            r.key,
            r.what,
            r.source,
            growth,
            delta,
            z,
            z_target,
            val(m.mass_mean_ratio, 3),
            val(m.pi04, 3),
            val(m.pi02, 4),
            val(m.bonds, 0),
            m.failures,
            m.runs
        );
    }
    if let Some(t) = study.target_growth {
        let close: Vec<_> = study
            .readings
            .iter()
            .zip(&study.summaries)
            .filter(|(_, m)| m.runs > m.failures && m.z_target.abs() <= 2.0)
            .collect();
        if close.is_empty() {
            s += &format!("\nNo reading lands within 2 s.e. of the published {t}.\n");
        } else {
            s += &format!("\nWithin 2 s.e. of the published {t}:\n\n");
            for (r, m) in close {
                s += &format!(
                    "- `{}`: {:.3} ± {:.3} (z = {:+.1}{})\n",
                    r.key,
                    m.growth_mean,
                    m.growth_se,
                    m.z_target,
                    if m.failures > 0 {
                        format!(", {} of {} runs failed", m.failures, m.runs)
                    } else {
                        String::new()
                    }
                );
            }
        }
    }
    let failures: Vec<_> = study
        .readings
        .iter()
        .zip(&study.summaries)
        .filter(|(_, m)| m.failures > 0)
        .collect();
    if !failures.is_empty() {
        s += "\nFailures (first message):\n\n";
        for (r, m) in failures {
            s += &format!("- `{}`: {}\n", r.key, m.failure);
        }
    }
    s
}

fn text(size: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font())
}

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing: {e}")
}

/// Most readings drawn on the chart.
const MAX_CHART_ROWS: usize = 40;

/// Most runs drawn as dots on the chart.
const MAX_DOTS: usize = 1000;

/// b_f/b0 of each reading (mean ± 2 s.e., every run as a dot up to [`MAX_DOTS`]), the baseline's
/// ± 2 s.e. band shaded and the published value drawn across.
struct Chart<'a>(&'a ReadingsStudy);

impl Figure for Chart<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let s = self.0;
        let n = s.readings.len();
        let values = s
            .runs
            .iter()
            .filter_map(|r| r.result.as_ref().ok().map(|m| m.growth_ratio))
            .chain(s.target_growth);
        let (mut g0, mut g1) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| {
            (a.min(g), b.max(g))
        });
        if !g0.is_finite() {
            (g0, g1) = (0.0, 1.0);
        }
        let pad = 0.05 * (g1 - g0).max(0.05);
        let (g0, g1) = (g0 - pad, g1 + pad);
        let labels: Vec<String> = s.readings.iter().map(|r| r.key.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "{}: b_f/b0 under each reading ({} seeds; mean ± 2 s.e.)",
                    s.scenario,
                    s.seeds.len()
                ),
                text(18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(230)
            .build_cartesian_2d(g0..g1, -0.5..(n as f64 - 0.5))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("b_f / b0")
            .y_labels(n)
            .y_label_formatter(&|y| {
                let k = y.round();
                if (y - k).abs() < 1e-6 && k >= 0.0 && (k as usize) < labels.len() {
                    labels[n - 1 - k as usize].clone()
                } else {
                    String::new()
                }
            })
            .label_style(text(13))
            .axis_desc_style(text(14))
            .draw()
            .map_err(err)?;
        let row = |k: usize| (n - 1 - k) as f64;
        let base = &s.summaries[0];
        if base.growth_mean.is_finite() {
            let (m, e) = (base.growth_mean, 2.0 * base.growth_se);
            chart
                .draw_series([Rectangle::new(
                    [(m - e, -0.5), (m + e, n as f64 - 0.5)],
                    RGBColor(200, 200, 200).mix(0.6).filled(),
                )])
                .map_err(err)?;
        }
        if let Some(t) = s.target_growth {
            chart
                .draw_series(LineSeries::new(
                    [(t, -0.5), (t, n as f64 - 0.5)],
                    ShapeStyle::from(&RED).stroke_width(2),
                ))
                .map_err(err)?
                .label(format!("published {t}"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], RED));
        }
        // Every run as a dot, unless there are so many that the SVG would run to megabytes.
        let dots = RGBColor(120, 120, 120);
        let shown = if s.runs.len() <= MAX_DOTS {
            &s.runs[..]
        } else {
            &[]
        };
        chart
            .draw_series(shown.iter().filter_map(|r| {
                r.result
                    .as_ref()
                    .ok()
                    .map(|m| Circle::new((m.growth_ratio, row(r.reading)), 2, dots.filled()))
            }))
            .map_err(err)?;
        let blue = RGBColor(31, 119, 180);
        for (k, m) in s.summaries.iter().enumerate() {
            if !m.growth_mean.is_finite() {
                continue;
            }
            let y = row(k);
            let e = 2.0 * m.growth_se;
            chart
                .draw_series([PathElement::new(
                    [(m.growth_mean - e, y), (m.growth_mean + e, y)],
                    ShapeStyle::from(&blue).stroke_width(3),
                )])
                .map_err(err)?;
            chart
                .draw_series([Circle::new((m.growth_mean, y), 5, blue.filled())])
                .map_err(err)?;
        }
        if s.target_growth.is_some() {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(text(12))
                .position(SeriesLabelPosition::LowerRight)
                .draw()
                .map_err(err)?;
        }
        Ok(())
    }
}
