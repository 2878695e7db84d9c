//! The [`Recorder`]: writes a run to MCAP through the `mcap` crate, with Foxglove's
//! protobuf schemas from the `foxglove` crate (not its logging machinery, so log
//! times are simulated time × the playback scale rather than wall-clock time).
//!
//! Life cycle: [`Recorder::create`] writes the metadata, the scenario attachment, the
//! schemas and channels, the box and the first snapshot; [`Recorder::observe`] runs
//! after every step (cheap unless a snapshot is due); [`Recorder::finish`] records the
//! last state, the outcome and writes the summary section — call it whatever the
//! run's outcome. Chunks are zstd-compressed, bounded by [`CHUNK_SIZE`] and every one
//! holds messages (so every chunk gets message indexes): a killed process leaves the
//! chunks written so far readable.
//!
//! **Threads.** The simulation thread only captures: it reads the bodies (an owned
//! copy, which on the event core brings each to the current time), computes `/stats`
//! and numbers every message. A writer thread ([`crate::output::offload`]) builds the
//! `/particles` scene from that copy, encodes it, compresses the chunks and writes the
//! file, in the order the messages were numbered, so the file is byte for byte what
//! one thread writes. Measured (perf, release) on `peer_bounce_100000` with T = 1e-4 s
//! and 300 snapshots: the writer thread takes 69 % of the CPU, the simulation thread
//! 31 %; at 1e6 bodies (11 snapshots) 52 % and 48 %. A run with a free core takes about
//! as long as its writer. On a machine with no idle core, the threads cost about 5 % more
//! CPU than `AGGLO_WRITERS=inline` (which keeps everything on the simulation thread).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::Context;
use foxglove::Encode;
use foxglove::schemas::{SceneEntity, SceneEntityDeletion, SceneUpdate, Timestamp, log};
use mcap::records::{MessageHeader, Metadata};

use super::messages::{self, Warnings};
use super::{
    BOX_HALF_WIDTH_KEY, BOX_TOPIC, ColourScale, EVENTS_TOPIC, PARTICLES_TOPIC, PIPELINE_KEY,
    RESULT_METADATA, RUN_METADATA, SCENARIO_ATTACHMENT, STATS_TOPIC, Sampling, Stats,
};
use crate::components::BodyState;
use crate::error::SimError;
use crate::observables::Summary;
use crate::output::offload::{Offload, Sink, Threading};
use crate::resources::BoxGeometry;
use crate::scenario::Scenario;
use crate::schedule::Simulation;

/// Target uncompressed chunk size [bytes]: about 8 snapshots of 1000 bodies, so a
/// killed run loses at most a few snapshots.
pub const CHUNK_SIZE: u64 = 1 << 20;

/// Channel ids.
#[derive(Debug, Clone, Copy)]
struct Channels {
    particles: u16,
    bbox: u16,
    stats: u16,
    events: u16,
}

/// What a recording holds, returned by [`Recorder::finish`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RecordingReport {
    /// `/particles` snapshots written.
    pub snapshots: u64,
    /// Entity deletions issued.
    pub deletions: u64,
    /// `/events` messages written.
    pub events: u64,
    /// File size [bytes].
    pub bytes: u64,
}

/// `/particles` snapshots (and smaller messages) that may wait for the writer thread:
/// each holds a copy of the bodies (96 bytes a body: 9.6 MB at 1e5 bodies), so this
/// bounds the memory a slow disk can take, and how far the file may lag the run.
pub const QUEUED_JOBS: usize = 1;

/// Records one run. See the module docs.
pub struct Recorder {
    out: Offload<McapSink>,
    channels: Channels,
    sequence: u32,
    sampling: Sampling,
    /// Simulated time and step of the last snapshot.
    last_time: f64,
    last_step: u64,
    /// Kinetic energy of the first snapshot [J] (`/stats.kinetic_energy_over_initial`).
    initial_kinetic_energy: Option<f64>,
    warnings: Warnings,
    report: RecordingReport,
}

/// What the simulation thread hands the writer thread, in file order.
enum Job {
    /// A message already encoded (the small ones: `/box`, `/stats`, `/events`).
    Message {
        header: MessageHeader,
        data: Vec<u8>,
    },
    /// A `/particles` snapshot of `bodies` (sorted by id, drawable or not) at `stamp`:
    /// built into a `SceneUpdate` and encoded on the writer thread.
    Particles {
        header: MessageHeader,
        stamp: Timestamp,
        bodies: Vec<BodyState>,
        /// In a rigid scene, each body's aggregate id (the same order): the primaries
        /// are coloured by aggregate instead of by temperature.
        aggregates: Option<Vec<u64>>,
    },
    /// A metadata record (the outcome, written last).
    Metadata(Metadata),
}

/// The MCAP file and the state the `/particles` messages need, on the writer thread.
struct McapSink {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    colours: ColourScale,
    /// Ids shown by the last snapshot, sorted.
    shown: Vec<u64>,
    /// Entity deletions issued.
    deletions: u64,
    buf: Vec<u8>,
}

impl Sink for McapSink {
    type Job = Job;
    /// Deletions issued and the file's size [bytes].
    type Output = (u64, u64);

    fn take(&mut self, job: Job) -> anyhow::Result<()> {
        match job {
            Job::Message { header, data } => {
                self.writer.write_to_known_channel(&header, &data)?;
            }
            Job::Particles {
                header,
                stamp,
                bodies,
                aggregates,
            } => {
                // Bodies with a non-finite centre or size cannot be drawn: left out (the
                // simulation thread reports them on /events).
                let drawable: Vec<&BodyState> =
                    bodies.iter().filter(|b| messages::drawable(b)).collect();
                let ids: Vec<u64> = drawable.iter().map(|b| b.id).collect();
                let deletions: Vec<SceneEntityDeletion> = sorted_difference(&self.shown, &ids)
                    .map(|id| messages::deletion_of(id, stamp))
                    .collect();
                let entities: Vec<SceneEntity> = match aggregates {
                    None => drawable
                        .iter()
                        .map(|b| messages::body_entity(b, &self.colours, stamp))
                        .collect(),
                    Some(of) => aggregate_entities(&bodies, &of, stamp),
                };
                self.deletions += deletions.len() as u64;
                let update = SceneUpdate {
                    deletions,
                    entities,
                };
                self.buf.clear();
                update.encode(&mut self.buf)?;
                self.writer.write_to_known_channel(&header, &self.buf)?;
                self.shown = ids;
            }
            Job::Metadata(meta) => self.writer.write_metadata(&meta)?,
        }
        Ok(())
    }

    fn finish(mut self) -> anyhow::Result<(u64, u64)> {
        self.writer
            .finish()
            .with_context(|| format!("finalising recording {}", self.path.display()))?;
        let file = self
            .writer
            .into_inner()
            .into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("flushing recording {}", self.path.display()))?;
        Ok((
            self.deletions,
            file.metadata().map(|m| m.len()).unwrap_or(0),
        ))
    }
}

/// The drawable primaries of a rigid scene, each coloured by its aggregate
/// ([`messages::aggregate_rgb`]); `of[i]` is `bodies[i]`'s aggregate id.
fn aggregate_entities(bodies: &[BodyState], of: &[u64], stamp: Timestamp) -> Vec<SceneEntity> {
    let mut sizes: BTreeMap<u64, usize> = BTreeMap::new();
    for &id in of {
        *sizes.entry(id).or_default() += 1;
    }
    bodies
        .iter()
        .zip(of)
        .filter(|(b, _)| messages::drawable(b))
        .map(|(b, id)| messages::sphere_entity(b, messages::aggregate_rgb(*id, sizes[id]), stamp))
        .collect()
}

impl Recorder {
    /// Create `path` and record the initial state of `sim` (which must not have stepped yet
    /// for the recording to start at t = 0). `command_line` goes into the metadata.
    pub fn create(path: &Path, sim: &Simulation, command_line: &str) -> anyhow::Result<Self> {
        // The description the run was built from (a Scenario puts itself in the world).
        let scenario = sim
            .world()
            .get_resource::<Scenario>()
            .context("recording needs a simulation built from a Scenario")?;
        let file =
            File::create(path).with_context(|| format!("creating recording {}", path.display()))?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("")
            .library(format!("agglo {}", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_SIZE))
            // One compressing thread, the writer's (zstd's own workers would change
            // the bytes and take the cores other runs use).
            .compression_threads(0)
            .create(BufWriter::new(file))
            .with_context(|| format!("starting recording {}", path.display()))?;
        let sampling = Sampling::from_scenario(scenario);
        let colours = ColourScale::from_scenario(scenario);

        // Metadata and the attachment first, outside chunks, so the first chunk holds
        // the schemas, channels and messages together.
        let mut meta = BTreeMap::new();
        meta.insert(
            "engine_version".into(),
            env!("CARGO_PKG_VERSION").to_string(),
        );
        meta.insert("scenario".into(), scenario.name.clone());
        meta.insert("seed".into(), scenario.seed.to_string());
        meta.insert("command_line".into(), command_line.to_string());
        meta.insert("time_end_s".into(), format!("{:?}", scenario.time.end));
        meta.insert(
            BOX_HALF_WIDTH_KEY.into(),
            format!("{:?}", scenario.domain.half_width),
        );
        meta.insert(
            PIPELINE_KEY.into(),
            serde_json::to_string(sim.pipeline()).context("the pipeline as JSON")?,
        );
        meta.insert(
            "log_seconds_per_sim_second".into(),
            format!("{:?}", sampling.log_seconds_per_sim_second),
        );
        meta.insert(
            "snapshot_interval_s".into(),
            sampling
                .interval
                .map(|dt| format!("{dt:?}"))
                .unwrap_or_else(|| "none".into()),
        );
        meta.insert(
            "snapshot_every_steps".into(),
            sampling.every_steps.to_string(),
        );
        meta.insert(
            "colour_scale".into(),
            format!(
                "log temperature: blue at {:?} K to red at {:?} K and above",
                colours.theta_lo, colours.theta_hi
            ),
        );
        writer.write_metadata(&Metadata {
            name: RUN_METADATA.into(),
            metadata: meta,
        })?;
        writer.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: SCENARIO_ATTACHMENT.into(),
            media_type: "application/json".into(),
            data: Cow::Owned(scenario.to_json().into_bytes()),
        })?;

        let no_meta = BTreeMap::new();
        let scene = messages::scene_schema()?;
        let scene_id = writer.add_schema(&scene.name, &scene.encoding, &scene.data)?;
        let log_schema = messages::log_schema()?;
        let log_id = writer.add_schema(&log_schema.name, &log_schema.encoding, &log_schema.data)?;
        let stats_id =
            writer.add_schema(messages::STATS_SCHEMA, "jsonschema", &Stats::schema_bytes())?;
        let channels = Channels {
            particles: writer.add_channel(scene_id, PARTICLES_TOPIC, "protobuf", &no_meta)?,
            bbox: writer.add_channel(scene_id, BOX_TOPIC, "protobuf", &no_meta)?,
            stats: writer.add_channel(stats_id, STATS_TOPIC, "json", &no_meta)?,
            events: writer.add_channel(log_id, EVENTS_TOPIC, "protobuf", &no_meta)?,
        };

        let clock = sim.clock();
        let sink = McapSink {
            writer,
            path: path.to_path_buf(),
            colours,
            shown: Vec::new(),
            deletions: 0,
            buf: Vec::new(),
        };
        let out = Offload::new(sink, path, Threading::from_env(QUEUED_JOBS))?;
        let mut recorder = Self {
            out,
            channels,
            sequence: 0,
            sampling,
            last_time: clock.time,
            last_step: clock.step,
            initial_kinetic_energy: None,
            warnings: Warnings::new(sim),
            report: RecordingReport::default(),
        };
        recorder.write_box(sim)?;
        recorder.event(
            clock.time,
            log::Level::Info,
            messages::start_message(scenario),
        )?;
        recorder.snapshot(sim)?;
        Ok(recorder)
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        self.out.path()
    }

    /// Call after every step: notes warnings and records a snapshot when one is due.
    pub fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        self.note_counters(sim)?;
        let clock = sim.clock();
        if self.sampling.due(clock.step, clock.time, self.last_time) {
            self.snapshot(sim)?;
        }
        Ok(())
    }

    /// Record the last state (unless just recorded) and the outcome, write the summary
    /// section and close the file. Call on success, error and interruption alike.
    pub fn finish(
        mut self,
        sim: &Simulation,
        outcome: &Result<(), SimError>,
    ) -> anyhow::Result<RecordingReport> {
        self.note_counters(sim)?;
        let clock = sim.clock();
        if clock.step != self.last_step || self.report.snapshots == 0 {
            self.snapshot(sim)?;
        } else {
            self.flush_pending(clock.time)?;
        }
        let (status, level, message) = messages::outcome_message(sim, outcome);
        self.event(clock.time, level, message.clone())?;
        let mut meta = BTreeMap::new();
        meta.insert("status".into(), status.to_string());
        meta.insert("message".into(), message);
        meta.insert("steps".into(), clock.step.to_string());
        meta.insert("time_s".into(), format!("{:?}", clock.time));
        meta.insert("snapshots".into(), self.report.snapshots.to_string());
        self.out.send(Job::Metadata(Metadata {
            name: RESULT_METADATA.into(),
            metadata: meta,
        }))?;
        // Waits for the writer thread to write everything queued and close the file.
        let (deletions, bytes) = self.out.finish()?;
        self.report.deletions = deletions;
        self.report.bytes = bytes;
        Ok(self.report)
    }

    fn header(&mut self, channel: u16, log_time: u64) -> MessageHeader {
        self.sequence = self.sequence.wrapping_add(1);
        MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        }
    }

    /// Encode `msg` and write it on `channel` at simulated time `t`.
    fn write_proto<M: Encode>(&mut self, channel: u16, t: f64, msg: &M) -> anyhow::Result<()>
    where
        M::Error: Send + Sync + 'static,
    {
        let mut data = Vec::with_capacity(msg.encoded_len().unwrap_or(0));
        msg.encode(&mut data)?;
        let header = self.header(channel, self.sampling.log_time(t));
        self.out.send(Job::Message { header, data })
    }

    fn stamp(&self, t: f64) -> Timestamp {
        messages::timestamp(self.sampling.log_time(t))
    }

    fn event(&mut self, t: f64, level: log::Level, message: String) -> anyhow::Result<()> {
        let msg = messages::log_message(self.stamp(t), level, message);
        self.report.events += 1;
        self.write_proto(self.channels.events, t, &msg)
    }

    /// The periodic box [−D, D]³ as a line list of its 12 edges.
    fn write_box(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let d = sim.world().resource::<BoxGeometry>().half_width;
        let t = sim.clock().time;
        let update = messages::box_update(d, self.stamp(t));
        self.write_proto(self.channels.bbox, t, &update)
    }

    /// Count new warnings; copy new invariant-violation descriptions to `/events` at once.
    fn note_counters(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let t = sim.clock().time;
        for line in self.warnings.note(sim) {
            self.event(t, log::Level::Warning, line)?;
        }
        Ok(())
    }

    /// One aggregated warning per kind of counter that grew since the last snapshot.
    fn flush_pending(&mut self, t: f64) -> anyhow::Result<()> {
        for line in self.warnings.flush(t) {
            self.event(t, log::Level::Warning, line)?;
        }
        Ok(())
    }

    /// Write `/particles` (with deletions of bodies gone since the last one) and `/stats`.
    fn snapshot(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let clock = sim.clock();
        let t = clock.time;
        let bodies = sim.bodies();
        let stamp = self.stamp(t);

        // What needs the world is computed here; the bodies then go to the writer
        // thread, which builds the scene from them.
        let summary = Summary::new(sim, &bodies);
        let skipped = (!bodies.iter().all(messages::drawable)).then(|| {
            let skipped: Vec<&BodyState> =
                bodies.iter().filter(|b| !messages::drawable(b)).collect();
            messages::skipped_bodies_message(&skipped)
        });
        let header = self.header(self.channels.particles, self.sampling.log_time(t));
        let aggregates = crate::aggregates::aggregate_ids(sim.world());
        self.out.send(Job::Particles {
            header,
            stamp,
            bodies,
            aggregates,
        })?;

        let initial = *self
            .initial_kinetic_energy
            .get_or_insert(summary.kinetic_energy);
        let mut stats = Stats::new(&summary, clock.dt, initial);
        stats.carried = sim.carried_totals().into_iter().collect();
        let data = serde_json::to_vec(&stats)?;
        let header = self.header(self.channels.stats, self.sampling.log_time(t));
        self.out.send(Job::Message { header, data })?;

        if let Some(message) = skipped {
            self.event(t, log::Level::Error, message)?;
        }
        self.flush_pending(t)?;
        self.last_time = t;
        self.last_step = clock.step;
        self.report.snapshots += 1;
        Ok(())
    }
}

/// Elements of sorted `a` missing from sorted `b`, in order.
#[doc(hidden)]
pub fn sorted_difference<'a>(a: &'a [u64], b: &'a [u64]) -> impl Iterator<Item = u64> + 'a {
    let mut j = 0;
    a.iter().copied().filter(move |&x| {
        while j < b.len() && b[j] < x {
            j += 1;
        }
        !(j < b.len() && b[j] == x)
    })
}
