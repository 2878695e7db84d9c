//! Ballistic particle–cluster aggregation (BPCA, `agglo::particle_cluster`): grow one
//! aggregate by firing monomers at it one at a time, then print its fractal dimension
//! fitted over the growth (R_g against k, decade by decade) and its filling factors
//! (docs/aggregates.md).
//!
//! ```text
//! cargo run --release --example bpca -- [primaries = 10000] [seed = 1] [--plot DIR]
//! ```
//!
//! With `--plot DIR` it also runs scenarios/bcca.json (cluster–cluster aggregation on
//! the event core, seconds) and draws `DIR/aggregates_df.png` (and `.svg`): R_g/a
//! against k for the cluster–cluster population and for the particle–cluster growth,
//! with their fitted power laws — the figure of docs/aggregates.md.

use std::path::{Path, PathBuf};

use agglo::aggregates::{AggregateShape, FIT_MIN_PRIMARIES, aggregate_shapes, fractal_fit};
use agglo::charts::{FONT, Figure, save_png_and_svg};
use agglo::particle_cluster::{ParticleClusterGrowth, grow};
use agglo::prelude::*;
use plotters::coord::Shift;
use plotters::prelude::*;

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let plot: Option<PathBuf> = match args.iter().position(|a| a == "--plot") {
        Some(i) => {
            let dir = args.get(i + 1).cloned().expect("--plot DIR");
            args.drain(i..i + 2);
            Some(dir.into())
        }
        None => None,
    };
    let n: usize = args
        .first()
        .map_or(10_000, |s| s.parse().expect("primaries"));
    let seed: u64 = args.get(1).map_or(1, |s| s.parse().expect("seed"));
    let a = 1.0; // lengths in primary radii
    let start = std::time::Instant::now();
    let g = grow(n, a, seed);
    let took = start.elapsed().as_secs_f64();
    println!(
        "{n} primaries (seed {seed}) in {took:.2} s: {} monomers fired, {} missed",
        g.fired, g.missed
    );
    let mut from = 10;
    while from < n {
        let to = (from * 10).min(n);
        let fit = fractal_fit(&g.history(from, to), a, from).expect("a fit");
        println!(
            "  D_f over k = {from}..{to}: {:.3} (k_f {:.3})",
            fit.dimension, fit.prefactor
        );
        from *= 10;
    }
    let shape = g.shape();
    println!(
        "  R_g = {:.3} a; filling factor Σa³/R_c³ (R_c = √(5/3) R_g): {:.4}; inside 0.5 R_g: {:.4}",
        shape.radius_of_gyration / a,
        shape.filling_factor,
        g.filling_factor_within(0.5 * shape.radius_of_gyration)
    );
    if let Some(dir) = plot {
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/bcca.json");
        let mut sim = Simulation::new(&Scenario::load(&scene)?)?;
        sim.run()?;
        let b0 = sim.primary().radius;
        let population = aggregate_shapes(sim.world());
        save_png_and_svg(
            &dir,
            "aggregates_df",
            (900, 600),
            &Growth {
                population: &population,
                primary_radius: b0,
                particle_cluster: &g,
            },
        )?;
        println!("  drew {}", dir.join("aggregates_df.png").display());
    }
    Ok(())
}

/// R_g/a against k, log–log: the cluster–cluster population and the particle–cluster
/// growth, each with its fitted N = k_f (R_g/a)^D_f.
struct Growth<'a> {
    population: &'a [AggregateShape],
    primary_radius: f64,
    particle_cluster: &'a ParticleClusterGrowth,
}

impl Figure for Growth<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("{e}");
        let pc = self.particle_cluster;
        let a_pc = pc.primary_radius;
        let k_max = pc.centres.len().max(2) as f64;
        let mut chart = ChartBuilder::on(area)
            .caption(
                "Rigid aggregates: radius of gyration against primaries",
                (FONT, 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d((1.5..k_max * 1.5).log_scale(), (0.8..200.0).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("primaries k")
            .y_desc("R_g / a")
            .label_style((FONT, 15))
            .draw()
            .map_err(e)?;
        let bcca = fractal_fit(self.population, self.primary_radius, FIT_MIN_PRIMARIES);
        let bpca = fractal_fit(&pc.history(1000, pc.centres.len()), a_pc, 1000);
        let line = |k: f64, d_f: f64, k_f: f64| (k / k_f).powf(1.0 / d_f);
        chart
            .draw_series(
                self.population
                    .iter()
                    .filter(|s| s.primaries >= 2)
                    .map(|s| {
                        let y = s.radius_of_gyration / self.primary_radius;
                        Circle::new((s.primaries as f64, y), 3, BLUE.filled())
                    }),
            )
            .map_err(e)?
            .label(match bcca {
                Some(f) => format!(
                    "cluster–cluster (scenarios/bcca.json): D_f = {:.2}, k_f = {:.2}",
                    f.dimension, f.prefactor
                ),
                None => "cluster–cluster (scenarios/bcca.json)".into(),
            })
            .legend(|(x, y)| Circle::new((x + 10, y), 3, BLUE.filled()));
        if let Some(f) = bcca {
            chart
                .draw_series(LineSeries::new(
                    [5.0, 2000.0].map(|k| (k, line(k, f.dimension, f.prefactor))),
                    BLUE.stroke_width(1),
                ))
                .map_err(e)?;
        }
        chart
            .draw_series(LineSeries::new(
                pc.radius_of_gyration
                    .iter()
                    .enumerate()
                    .skip(1)
                    .map(|(i, r)| ((i + 1) as f64, r / a_pc)),
                RED.stroke_width(2),
            ))
            .map_err(e)?
            .label(match bpca {
                Some(f) => format!(
                    "particle–cluster growth (k ≥ 10³): D_f = {:.2}, k_f = {:.2}",
                    f.dimension, f.prefactor
                ),
                None => "particle–cluster growth".into(),
            })
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        Ok(())
    }
}
