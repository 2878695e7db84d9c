//! The peer chart: wall time against N, and time per collision against N, for agglo
//! and REBOUND on the same clouds, from the CSV `benches/peers/run.sh` writes.
//!
//! `cargo run --release --example peer_chart -- benches/peers/results.csv docs/peers`
//! writes `docs/peers.png` and `docs/peers.svg` (two log–log panels).

use std::collections::BTreeMap;
use std::path::Path;

use agglo::charts::{FONT, Figure, save_png_and_svg};
use anyhow::{Context, bail};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One CSV row: (code, variant) → points (N, wall seconds, seconds per collision).
type Series = BTreeMap<(String, String), Vec<(f64, f64, f64)>>;

fn read(csv: &Path) -> anyhow::Result<Series> {
    let text =
        std::fs::read_to_string(csv).with_context(|| format!("reading {}", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().context("empty CSV")?.split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .with_context(|| format!("column {name} missing"))
    };
    let (code, variant, n, wall, per) = (
        col("code")?,
        col("variant")?,
        col("n")?,
        col("wall_s")?,
        col("seconds_per_collision")?,
    );
    let mut series = Series::new();
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        let num = |k: usize| -> anyhow::Result<f64> { Ok(f[k].trim().parse::<f64>()?) };
        series
            .entry((f[code].to_string(), f[variant].to_string()))
            .or_default()
            .push((num(n)?, num(wall)?, num(per)?));
    }
    for points in series.values_mut() {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    if series.is_empty() {
        bail!("no rows in {}", csv.display());
    }
    Ok(series)
}

struct PeerChart(Series);

fn style(code: &str, variant: &str) -> (RGBColor, bool) {
    let colour = if code == "agglo" {
        RGBColor(0, 90, 180)
    } else {
        RGBColor(200, 70, 0)
    };
    (colour, variant == "merge")
}

impl PeerChart {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
        y_desc: &str,
        pick: impl Fn(&(f64, f64, f64)) -> f64,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("{e}");
        let all: Vec<(f64, f64)> = self.0.values().flatten().map(|p| (p.0, pick(p))).collect();
        let (x0, x1) = (500.0, 2e5);
        let y0 = all.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) / 3.0;
        let y1 = all.iter().map(|p| p.1).fold(0.0, f64::max) * 3.0;
        let mut chart = ChartBuilder::on(area)
            .caption(title, (FONT, 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("N (bodies at t = 0)")
            .y_desc(y_desc)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 13))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()
            .map_err(err)?;
        for ((code, variant), points) in &self.0 {
            let (colour, solid) = style(code, variant);
            let line: Vec<(f64, f64)> = points.iter().map(|p| (p.0, pick(p))).collect();
            let stroke = ShapeStyle::from(&colour).stroke_width(2);
            let label = format!("{code} {variant}{}", if solid { "" } else { " (dashed)" });
            if solid {
                chart
                    .draw_series(LineSeries::new(line.clone(), stroke))
                    .map_err(err)?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], stroke));
            } else {
                chart
                    .draw_series(DashedLineSeries::new(line.clone(), 6, 4, stroke))
                    .map_err(err)?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new([(x, y), (x + 6, y)], stroke));
            }
            chart
                .draw_series(line.into_iter().map(|p| Circle::new(p, 4, colour.filled())))
                .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT, 12))
            .draw()
            .map_err(err)?;
        Ok(())
    }
}

impl Figure for PeerChart {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (left, right) = area.split_horizontally(area.dim_in_pixel().0 / 2);
        self.panel(&left, "wall time, one thread", "wall time [s]", |p| p.1)?;
        self.panel(
            &right,
            "time per collision (solid: merge, dashed: bounce)",
            "seconds per collision",
            |p| p.2,
        )?;
        Ok(())
    }
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let csv = args
        .next()
        .unwrap_or_else(|| "benches/peers/results.csv".into());
    let stem = args.next().unwrap_or_else(|| "docs/peers".into());
    let series = read(Path::new(&csv))?;
    let stem = Path::new(&stem);
    let dir = stem.parent().unwrap_or(Path::new("."));
    let name = stem.file_name().context("output stem")?.to_string_lossy();
    save_png_and_svg(dir, &name, (1200, 500), &PeerChart(series))?;
    println!("wrote {}.png and {}.svg", stem.display(), stem.display());
    Ok(())
}
