//! The tables a run writes while it runs — `--series`, `--sizes`, `--snapshots` on the
//! schedule of `output.sampling` (or the flags), `--collisions` after every step —
//! an observer ([`crate::observer::Observer`]) of a [`crate::run::Run`].
//!
//! Between samples the observer costs O(1) per step (a look at the clock). At a sample
//! the bodies are read once through `Simulation::bodies()`, which on the event core
//! brings each to the current time without changing the world: the event core does no
//! per-event work for the outputs.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::components::{Mass, Particle, ParticleId, Temperature};
use crate::observer::{Ending, Observer, Written};
use crate::resources::LazyState;
use crate::scenario::Scenario;
use crate::schedule::Simulation;

use super::collisions::{self, CollisionLog};
use super::sampling::{SampleSchedule, Sampler};
use super::series::{Pending, SERIES_COLUMNS, series_row};
use super::sizes::{self, RIGID_SIZES_COLUMNS, SIZES_COLUMNS, SizeBins};
use super::snapshots::SNAPSHOT_COLUMNS;
use super::table::{Cell, Column, TableWriter, float};

/// Where the tables go and when they are sampled, from the flags over the `output`
/// section.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TablePaths {
    /// The series table (`--series`, `output.series`): one row per sample.
    pub series: Option<PathBuf>,
    /// The size-distribution table (`--sizes`, `output.sizes`): one row per bin per sample.
    pub sizes: Option<PathBuf>,
    /// The snapshots table (`--snapshots`, `output.snapshots`): every body at each sample.
    pub snapshots: Option<PathBuf>,
    /// The collision log (`--collisions`, `output.collisions`): one row per impact.
    pub collisions: Option<PathBuf>,
    /// When the sampled tables are sampled (None: the `output.sampling` default).
    pub sampling: Option<SampleSchedule>,
}

impl TablePaths {
    /// True when no table is asked for.
    pub fn is_empty(&self) -> bool {
        self.series.is_none()
            && self.sizes.is_none()
            && self.snapshots.is_none()
            && self.collisions.is_none()
    }

    /// Subscribe what these tables read (the impacts, for `collisions`) on a scene's
    /// builder; [`crate::run::Run`] does it for the tables of its plan.
    pub fn subscribe(&self, builder: &mut crate::schedule::SimBuilder) {
        if self.collisions.is_some() {
            collisions::subscribe(builder);
        }
    }
}

/// The tables of one run, open.
pub struct RunTables {
    sampler: Sampler,
    series: Option<TableWriter>,
    /// The size table, its bins, and whether it counts rigid aggregates.
    sizes: Option<(TableWriter, SizeBins, bool)>,
    snapshots: Option<TableWriter>,
    collisions: Option<CollisionLog>,
    samples: u64,
}

/// What the tables hold when a run ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TablesReport {
    /// Samples taken.
    pub samples: u64,
    /// Rows of the collision log (impacts).
    pub collisions: u64,
}

impl RunTables {
    /// Open the tables `paths` asks for (none: `None`) and take the sample at t = 0.
    pub fn open(
        paths: &TablePaths,
        scenario: &Scenario,
        sim: &Simulation,
    ) -> anyhow::Result<Option<Self>> {
        if paths.is_empty() {
            return Ok(None);
        }
        let create = |path: &Option<PathBuf>, name: &str, columns: &[Column]| {
            path.as_deref()
                .map(|p: &Path| TableWriter::create(p, name, columns))
                .transpose()
        };
        let series = create(&paths.series, "series", SERIES_COLUMNS)?;
        // Snapshots carry the quantities extensions registered (engine/carried.rs) as
        // columns after the built-in ones, as --final-state does.
        let carried = sim.carried().names;
        let snapshot_columns: Vec<Column> = SNAPSHOT_COLUMNS
            .iter()
            .copied()
            .chain(carried.iter().map(|name| carried_column(name)))
            .collect();
        let snapshots = create(&paths.snapshots, "snapshots", &snapshot_columns)?;
        // A rigid scene's size table counts aggregates and adds their shape; a coalesce
        // scene's keeps its columns (and bytes).
        let rigid = sim
            .world()
            .get_resource::<crate::aggregates::RigidAggregates>()
            .is_some();
        let size_columns: Vec<Column> = SIZES_COLUMNS
            .iter()
            .chain(if rigid { RIGID_SIZES_COLUMNS } else { &[] })
            .copied()
            .collect();
        let sizes = match create(&paths.sizes, "sizes", &size_columns)? {
            Some(table) => {
                // A rigid aggregate breaks into whole primaries: k stays a whole number.
                let can_fragment = !rigid
                    && agglo_systems::fragment::scene_fragments(
                        &sim.material(),
                        sim.world().resource::<crate::scene::Physics>(),
                    );
                let bins = scenario
                    .output
                    .size_bins
                    .resolve(&sim.bodies(), can_fragment);
                Some((table, bins, rigid))
            }
            None => None,
        };
        if paths.collisions.is_some()
            && sim
                .world()
                .get_resource::<crate::hooks::Messages<crate::hooks::ImpactMessage>>()
                .is_none()
        {
            anyhow::bail!(
                "--collisions needs the impacts: run through agglo::run::Run (or subscribe them with \
                 TablePaths::subscribe)"
            );
        }
        let collisions = paths
            .collisions
            .as_deref()
            .map(CollisionLog::create)
            .transpose()?;
        let schedule = paths
            .sampling
            .unwrap_or_else(|| SampleSchedule::default_for(scenario.time.end));
        let mut tables = Self {
            sampler: Sampler::new(schedule, scenario.time.end),
            series,
            sizes,
            snapshots,
            collisions,
            samples: 0,
        };
        tables.observe(sim)?;
        Ok(Some(tables))
    }

    /// After a step: log its impacts, and take a sample if one is due.
    pub fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        if let Some(log) = &mut self.collisions {
            log.observe(sim)?;
        }
        let c = sim.clock();
        if self.sampler.due(c.step, c.time) {
            self.sample(sim)?;
        }
        Ok(())
    }

    /// Take the last sample (unless one was taken at this time) and close the files.
    pub fn finish(mut self, sim: &Simulation) -> anyhow::Result<TablesReport> {
        if self.sampler.last().is_none_or(|t| t < sim.clock().time) {
            self.sample(sim)?;
        }
        for table in [self.series, self.sizes.map(|s| s.0), self.snapshots]
            .into_iter()
            .flatten()
        {
            table.finish()?;
        }
        let collisions = self.collisions.as_ref().map_or(0, CollisionLog::rows);
        if let Some(log) = self.collisions {
            log.finish()?;
        }
        Ok(TablesReport {
            samples: self.samples,
            collisions,
        })
    }

    fn sample(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let t = sim.clock().time;
        let bodies = sim.bodies();
        if let Some(series) = &mut self.series {
            let pending = pending_account(sim, &bodies);
            series
                .row(&series_row(sim, &bodies, pending))
                .context("writing the time series")?;
        }
        if let Some((table, bins, rigid)) = &mut self.sizes {
            let by = sizes::label(*bins);
            let b0 = sim.primary().radius;
            if *rigid {
                let shapes = crate::aggregates::aggregate_shapes(sim.world());
                for row in sizes::aggregate_size_rows(*bins, &shapes, b0) {
                    table
                        .row(&sizes::aggregate_cells(t, by, row))
                        .context("writing the size distribution")?;
                }
            } else {
                for row in sizes::size_rows(*bins, &bodies, b0) {
                    table
                        .row(&sizes::cells(t, by, row))
                        .context("writing the size distribution")?;
                }
            }
        }
        if let Some(table) = &mut self.snapshots {
            let carried = sim.carried();
            let mut cells = Vec::new();
            for (i, b) in bodies.iter().enumerate() {
                cells.clear();
                cells.extend_from_slice(&[
                    Cell::F(t),
                    Cell::U(b.id),
                    Cell::F(b.position.x),
                    Cell::F(b.position.y),
                    Cell::F(b.position.z),
                    Cell::F(b.velocity.x),
                    Cell::F(b.velocity.y),
                    Cell::F(b.velocity.z),
                    Cell::F(b.mass),
                    Cell::F(b.radius),
                    Cell::F(b.temperature),
                    Cell::F(b.hardness),
                    Cell::F(b.primaries),
                ]);
                // The carried values, in the bodies' id order (NaN where a body has none).
                if let Some((id, values)) = carried.rows.get(i) {
                    anyhow::ensure!(
                        *id == b.id,
                        "carried quantities out of step with the bodies"
                    );
                    cells.extend(values.iter().map(|v| Cell::F(v.unwrap_or(f64::NAN))));
                }
                table.row(&cells).context("writing the snapshots")?;
            }
        }
        self.sampler.taken(t);
        self.samples += 1;
        Ok(())
    }
}

impl Observer for RunTables {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        RunTables::observe(self, sim)
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        RunTables::finish(*self, end.sim).map(|_| ())
    }
}

/// The column of a quantity an extension carries (its unit is the extension's own).
fn carried_column(name: &str) -> Column {
    // Column names are 'static (the built-in ones are constants); a run registers a few
    // carried quantities once, so their names are kept for the life of the process.
    let name: &'static str = Box::leak(name.to_owned().into_boxed_str());
    float(
        name,
        "-",
        "a quantity an extension carries through merges and fragments (NaN: the body has none)",
    )
}

/// What the event core's bodies have moved since they were last brought up to date and
/// the ledger has not booked yet (it is booked when each body is next touched, and at
/// the end of the run): the heat lost by cooling, Σ m C (θ_stored − θ_now), and in a
/// field its work and impulse, Σ ½ m (|v_now|² − |v_stored|²) and Σ m (v_now − v_stored).
/// Zero on the stepped core. `bodies` are the bodies at now, sorted by id.
fn pending_account(sim: &Simulation, bodies: &[crate::components::BodyState]) -> Pending {
    let world = sim.world();
    if !world.resource::<LazyState>().0 {
        return Pending::default();
    }
    let Some(mut query) = world.try_query_filtered::<(
        &ParticleId,
        &Mass,
        &Temperature,
        &crate::components::Velocity,
    ), bevy_ecs::prelude::With<Particle>>() else {
        return Pending::default();
    };
    let mut stored: Vec<(u64, f64, f64, glam::DVec3)> = query
        .iter(world)
        .map(|(id, m, t, v)| (id.0, m.0, t.0, v.0))
        .collect();
    stored.sort_by_key(|s| s.0);
    let c = sim.material().C;
    // Summed in id order: the same on any thread count.
    let mut pending = Pending::default();
    for (&(_, m, theta, v), now) in stored.iter().zip(bodies) {
        pending.cooling += m * c * (theta - now.temperature);
        let work = 0.5 * m * (now.velocity.length_squared() - v.length_squared());
        let impulse = m * (now.velocity - v);
        pending.work += work;
        pending.work_turnover += work.abs();
        pending.impulse += impulse;
        pending.impulse_turnover += impulse.length();
    }
    pending
}
