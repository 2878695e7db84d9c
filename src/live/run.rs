//! [`LiveRun`]: a simulation served live, with the recording's channels and messages
//! (see the [module docs](super) for the threads and the subset of large clouds).
//!
//! Life cycle, mirroring the [`Recorder`](crate::record::Recorder): [`LiveRun::start`]
//! (before the first step: creates the channels, waits for a subscriber with
//! `--live-wait`, publishes the box, the start event and the t = 0 frame),
//! [`LiveRun::observe`] after every step, [`LiveRun::finish`] whatever the outcome
//! (the last frame and the outcome, then the server closes).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use foxglove::schemas::log::Level;
use foxglove::schemas::{
    Color, Pose, Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Vector3,
};
use foxglove::{Encode, RawChannel};

use super::{LiveOptions, Server, publish};
use crate::components::BodyState;
use crate::error::SimError;
use crate::observables::Summary;
use crate::observer::{Ending, Observer, Written};
use crate::record::messages::{self, Warnings};
use crate::record::{
    BOX_TOPIC, ColourScale, EVENTS_TOPIC, FRAME_ID, PARTICLES_TOPIC, STATS_TOPIC, Sampling, Stats,
};
use crate::scenario::Scenario;
use crate::schedule::Simulation;
use crate::seeds::splitmix64;

/// Id of the text entity that says when `/particles` shows a subset.
pub const SUBSET_NOTE_ID: &str = "live_subset";

/// Share of wall time the frames may take, at most: the next frame is due no sooner than
/// (time to capture the last one on the simulation thread + time to publish it) / this
/// after it. With a 2 % budget the live view stays within the 10 % whatever N,
/// also on a machine whose cores are all busy (then the publisher's work competes with
/// the run too); `--live-rate` only ever lowers the rate further.
pub const TIME_BUDGET: f64 = 0.02;

/// While a finished run lingers, its final frame goes out again this often.
pub const REPUBLISH: Duration = Duration::from_secs(1);

/// The channels of a run, for [`Server::bind`]: the recording's topics and schemas.
pub fn topics() -> anyhow::Result<Vec<super::Topic>> {
    let scene = messages::scene_schema()?;
    Ok(vec![
        (PARTICLES_TOPIC, "protobuf", scene.clone()),
        (BOX_TOPIC, "protobuf", scene),
        (
            STATS_TOPIC,
            "json",
            foxglove::Schema::new(messages::STATS_SCHEMA, "jsonschema", Stats::schema_bytes()),
        ),
        (EVENTS_TOPIC, "protobuf", messages::log_schema()?),
    ])
}

/// The four channels of a run.
struct Channels {
    particles: Arc<RawChannel>,
    bbox: Arc<RawChannel>,
    stats: Arc<RawChannel>,
    events: Arc<RawChannel>,
}

impl Channels {
    fn all(&self) -> [&Arc<RawChannel>; 4] {
        [&self.particles, &self.bbox, &self.stats, &self.events]
    }

    fn subscribed(&self) -> bool {
        self.all().iter().any(|c| c.has_sinks())
    }
}

/// One frame, captured on the simulation thread, published on the publisher thread.
struct Frame {
    /// Simulated time [s].
    t: f64,
    /// Every body, sorted by id.
    bodies: Vec<BodyState>,
    stats: Stats,
    /// Events before the frame (new invariant violations) and after it (aggregated
    /// warnings, the outcome), as the recording orders them.
    before: Vec<(Level, String)>,
    after: Vec<(Level, String)>,
}

/// What the simulation thread hands over.
#[derive(Default)]
struct Slot {
    frame: Option<Frame>,
    /// Events of frames that were replaced before they went out.
    events: Vec<(f64, Level, String)>,
    done: bool,
}

/// The slot, the flag the publisher raises when a frame is due, and the wake-up.
struct Shared {
    slot: Mutex<Slot>,
    wake: Condvar,
    due: AtomicBool,
    /// Nanoseconds the simulation thread spent capturing the last frame.
    capture_ns: AtomicU64,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Slot> {
        // A panic on the other thread cannot leave the slot half-written: take it as is.
        self.slot.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// A run served live. See the module docs.
pub struct LiveRun {
    server: Option<Server>,
    channels: Arc<Channels>,
    shared: Arc<Shared>,
    publisher: Option<JoinHandle<()>>,
    warnings: Warnings,
    /// Kinetic energy at t = 0 [J], as the recording's first snapshot has it.
    initial_kinetic_energy: f64,
    /// Frames the publisher had not sent when the next one came (replaced).
    dropped: u64,
    /// How long the final state stays served to a connected client (`--live-linger`).
    linger: Duration,
    /// `--live-pace`: simulated seconds per wall second at most, with the simulated time
    /// and the instant the paced clock started from.
    pace: Option<(f64, f64, Instant)>,
    /// The run's stop flag (Ctrl-C), polled while pacing or lingering.
    stop: Arc<AtomicBool>,
}

impl LiveRun {
    /// Create the channels on `server`, wait for a subscriber if asked (returns early
    /// if `stop` is set meanwhile), and publish the box, the start event and the frame
    /// of `sim`'s current state (t = 0: call before the first step).
    pub fn start(
        server: Server,
        options: &LiveOptions,
        sim: &Simulation,
        stop: &Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let scenario = sim.world().get_resource::<Scenario>().ok_or_else(|| {
            anyhow::anyhow!("a live run needs a simulation built from a Scenario")
        })?;
        let channels = Arc::new(Channels {
            particles: server.channel(PARTICLES_TOPIC)?,
            bbox: server.channel(BOX_TOPIC)?,
            stats: server.channel(STATS_TOPIC)?,
            events: server.channel(EVENTS_TOPIC)?,
        });
        if options.wait {
            eprintln!(
                "live: waiting for a client to subscribe on {} (Ctrl-C to stop)",
                server.url()
            );
            server.wait_for_subscriber(&channels.all(), stop);
        }
        let shared = Arc::new(Shared {
            slot: Mutex::new(Slot::default()),
            wake: Condvar::new(),
            due: AtomicBool::new(false),
            capture_ns: AtomicU64::new(0),
        });
        let publisher = Publisher {
            channels: channels.clone(),
            shared: shared.clone(),
            sampling: Sampling::from_scenario(scenario),
            colours: ColourScale::from_scenario(scenario),
            half_width: scenario.domain.half_width,
            max_bodies: options.max_bodies,
            period: Duration::from_secs_f64(1.0 / options.rate_hz),
            buf: Vec::new(),
        };
        let start_event = messages::start_message(scenario);
        let handle = std::thread::Builder::new()
            .name("agglo-live".into())
            .spawn(move || publisher.run())?;
        let bodies = sim.bodies();
        let initial_kinetic_energy = Summary::new(sim, &bodies).kinetic_energy;
        let mut live = Self {
            server: Some(server),
            channels,
            shared,
            publisher: Some(handle),
            warnings: Warnings::new(sim),
            initial_kinetic_energy,
            dropped: 0,
            linger: Duration::from_secs_f64(options.linger_seconds),
            pace: options
                .pace
                .map(|rate| (rate, sim.clock().time, Instant::now())),
            stop: stop.clone(),
        };
        if live.channels.subscribed() {
            live.hand_over(sim, bodies, vec![(Level::Info, start_event)], Vec::new());
        }
        Ok(live)
    }

    /// Call after every step: one atomic load unless a frame is due and a client listens
    /// (and, with `--live-pace`, a wait while the run is ahead of its pace).
    pub fn observe(&mut self, sim: &Simulation) {
        if let Some((rate, t0, started)) = self.pace {
            self.keep_pace(sim.clock().time - t0, rate, started);
        }
        if !self.shared.due.load(Ordering::Relaxed) {
            return;
        }
        self.shared.due.store(false, Ordering::Relaxed);
        if self.channels.subscribed() {
            self.capture(sim, Vec::new());
        }
    }

    /// Publish the last state and the outcome, let the clients receive them, and close
    /// the server. Call on success, error and interruption alike, after every other
    /// output is written: with a client connected, the final state stays served (see
    /// [`LiveRun::linger`]). Returns the frames dropped because the publisher was still
    /// busy with the one before.
    pub fn finish(mut self, sim: &Simulation, outcome: &Result<(), SimError>) -> u64 {
        let (_, level, message) = messages::outcome_message(sim, outcome);
        if self.channels.subscribed() {
            self.capture(sim, vec![(level, message.clone())]);
        }
        self.linger(sim, &message);
        self.shared.lock().done = true;
        self.shared.wake.notify_all();
        if let Some(handle) = self.publisher.take() {
            let _ = handle.join();
        }
        if let Some(server) = self.server.take() {
            server.close();
        }
        self.dropped
    }

    /// Wait until `elapsed` simulated seconds are due at `rate` simulated seconds per
    /// second after `started`, in short sleeps so that Ctrl-C still stops at once. The
    /// publisher keeps its frame clock meanwhile, so frames go out during the wait.
    fn keep_pace(&self, elapsed: f64, rate: f64, started: Instant) {
        // Capped at a day: a simulated time far ahead of any useful pace is not a
        // reason to sleep for ever (Duration::from_secs_f64 refuses huge values).
        let due = Duration::from_secs_f64((elapsed / rate).clamp(0.0, 86_400.0));
        loop {
            let now = started.elapsed();
            if now >= due || self.stop.load(Ordering::SeqCst) {
                return;
            }
            std::thread::sleep((due - now).min(Duration::from_millis(50)));
        }
    }

    /// With a client connected, tell it by a status (not an error) that the run finished,
    /// and keep the final state served until it disconnects, the linger time passes or
    /// a stop is asked for. The final frame goes out again every [`REPUBLISH`]: a panel
    /// that subscribes after the run ended (a short run is over before the 3D panel has
    /// asked for `/particles`) still gets the cloud.
    fn linger(&mut self, sim: &Simulation, outcome: &str) {
        let Some(server) = self.server.as_ref() else {
            return;
        };
        if self.linger.is_zero() || server.clients() == 0 {
            return;
        }
        server.publish_status(format!(
            "agglo: the run has ended ({outcome}). Its final state stays served until you \
             disconnect (at most {:.0} s).",
            self.linger.as_secs_f64()
        ));
        eprintln!(
            "live: the run has ended; serving its final state until the client disconnects \
             (at most {:.0} s; --live-linger sets it, Ctrl-C ends it)",
            self.linger.as_secs_f64()
        );
        let until = Instant::now() + self.linger;
        let mut next_frame = Instant::now() + REPUBLISH;
        while let Some(server) = self.server.as_ref() {
            let now = Instant::now();
            if server.clients() == 0 || now >= until || self.stop.load(Ordering::SeqCst) {
                return;
            }
            if now >= next_frame {
                if self.channels.subscribed() {
                    self.capture(sim, Vec::new());
                }
                next_frame = now + REPUBLISH;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn capture(&mut self, sim: &Simulation, closing: Vec<(Level, String)>) {
        let start = Instant::now();
        let bodies = sim.bodies();
        let before = self
            .warnings
            .note(sim)
            .into_iter()
            .map(|l| (Level::Warning, l))
            .collect();
        self.hand_over(sim, bodies, before, closing);
        let ns = start.elapsed().as_nanos().min(u64::MAX as u128) as u64;
        self.shared.capture_ns.store(ns, Ordering::Relaxed);
    }

    /// Build the frame's statistics (over every body) and hand it to the publisher.
    fn hand_over(
        &mut self,
        sim: &Simulation,
        bodies: Vec<BodyState>,
        before: Vec<(Level, String)>,
        closing: Vec<(Level, String)>,
    ) {
        let clock = sim.clock();
        let summary = Summary::new(sim, &bodies);
        let stats = Stats::new(&summary, clock.dt, self.initial_kinetic_energy);
        let mut after: Vec<(Level, String)> = self
            .warnings
            .flush(clock.time)
            .into_iter()
            .map(|l| (Level::Warning, l))
            .collect();
        after.extend(closing);
        let frame = Frame {
            t: clock.time,
            bodies,
            stats,
            before,
            after,
        };
        let mut slot = self.shared.lock();
        if let Some(old) = slot.frame.replace(frame) {
            // Its bodies and statistics are superseded; its events are not.
            self.dropped += 1;
            let t = old.t;
            slot.events.extend(
                old.before
                    .into_iter()
                    .chain(old.after)
                    .map(|(l, m)| (t, l, m)),
            );
        }
        drop(slot);
        self.shared.wake.notify_all();
    }
}

impl Drop for LiveRun {
    /// An early return (an error before `finish`) still stops the publisher thread.
    fn drop(&mut self) {
        self.shared.lock().done = true;
        self.shared.wake.notify_all();
        if let Some(handle) = self.publisher.take() {
            let _ = handle.join();
        }
    }
}

/// The publisher thread: raises `due` on the frame clock while idle, publishes frames.
struct Publisher {
    channels: Arc<Channels>,
    shared: Arc<Shared>,
    sampling: Sampling,
    colours: ColourScale,
    half_width: f64,
    max_bodies: usize,
    period: Duration,
    buf: Vec<u8>,
}

impl Publisher {
    fn run(mut self) {
        let mut next = Instant::now() + self.period;
        loop {
            let (frame, events, done) = {
                let mut slot = self.shared.lock();
                while slot.frame.is_none() && slot.events.is_empty() && !slot.done {
                    let now = Instant::now();
                    if now >= next {
                        self.shared.due.store(true, Ordering::Relaxed);
                        next = now + self.period;
                    }
                    slot = self
                        .shared
                        .wake
                        .wait_timeout(slot, next.saturating_duration_since(now))
                        .unwrap_or_else(|p| p.into_inner())
                        .0;
                }
                (
                    slot.frame.take(),
                    std::mem::take(&mut slot.events),
                    slot.done,
                )
            };
            for (t, level, message) in events {
                self.event(t, level, message);
            }
            if let Some(frame) = frame {
                let start = Instant::now();
                self.publish_frame(frame);
                // Hold the next frame back until this one's cost is within the budget.
                let capture = Duration::from_nanos(self.shared.capture_ns.load(Ordering::Relaxed));
                let cost = capture + start.elapsed();
                next = next.max(Instant::now() + cost.div_f64(TIME_BUDGET));
            }
            if done {
                let slot = self.shared.lock();
                if slot.frame.is_none() && slot.events.is_empty() {
                    return;
                }
            }
        }
    }

    fn encode<M: Encode>(&mut self, msg: &M) -> bool {
        self.buf.clear();
        msg.encode(&mut self.buf).is_ok()
    }

    fn event(&mut self, t: f64, level: Level, message: String) {
        let ns = self.sampling.log_time(t);
        let msg = messages::log_message(messages::timestamp(ns), level, message);
        if self.encode(&msg) {
            publish(&self.channels.events, ns, &self.buf);
        }
    }

    /// The recording's snapshot, live: events, `/particles` (every entity replaced: a
    /// client that joined late or lost a message is right again at the next frame),
    /// `/box` (again, for clients that joined late), `/stats`, the non-drawable bodies
    /// and the aggregated warnings.
    fn publish_frame(&mut self, frame: Frame) {
        let t = frame.t;
        let ns = self.sampling.log_time(t);
        let stamp = messages::timestamp(ns);
        for (level, message) in frame.before {
            self.event(t, level, message);
        }
        let (drawable, skipped): (Vec<&BodyState>, Vec<&BodyState>) =
            frame.bodies.iter().partition(|b| messages::drawable(b));
        if self.channels.particles.has_sinks() {
            let k = subset_shift(drawable.len(), self.max_bodies);
            let mut entities: Vec<SceneEntity> = drawable
                .iter()
                .filter(|b| in_subset(b.id, k))
                .map(|b| messages::body_entity(b, &self.colours, stamp))
                .collect();
            if k > 0 {
                let text = format!(
                    "live view: {} of {} bodies shown (1 in {}, by id); /stats covers all",
                    entities.len(),
                    drawable.len(),
                    1u64 << k
                );
                entities.push(self.note(text, stamp));
            }
            let update = SceneUpdate {
                deletions: vec![messages::deletion_of_all(stamp)],
                entities,
            };
            if self.encode(&update) {
                publish(&self.channels.particles, ns, &self.buf);
            }
        }
        if self.channels.bbox.has_sinks() {
            let update = messages::box_update(self.half_width, stamp);
            if self.encode(&update) {
                publish(&self.channels.bbox, ns, &self.buf);
            }
        }
        self.buf.clear();
        if serde_json::to_writer(&mut self.buf, &frame.stats).is_ok() {
            publish(&self.channels.stats, ns, &self.buf);
        }
        if !skipped.is_empty() {
            self.event(t, Level::Error, messages::skipped_bodies_message(&skipped));
        }
        for (level, message) in frame.after {
            self.event(t, level, message);
        }
    }

    /// A text above the box, facing the camera.
    fn note(&self, text: String, stamp: foxglove::schemas::Timestamp) -> SceneEntity {
        let d = self.half_width;
        SceneEntity {
            timestamp: Some(stamp),
            frame_id: FRAME_ID.into(),
            id: SUBSET_NOTE_ID.into(),
            texts: vec![TextPrimitive {
                pose: Some(Pose {
                    position: Some(Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: 1.25 * d,
                    }),
                    orientation: Some(Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                        w: 1.0,
                    }),
                }),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color: Some(Color {
                    r: 1.0,
                    g: 1.0,
                    b: 1.0,
                    a: 1.0,
                }),
                text,
            }],
            ..Default::default()
        }
    }
}

impl Observer for LiveRun {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        LiveRun::observe(self, sim);
        Ok(())
    }

    fn finish(self: Box<Self>, end: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        LiveRun::finish(*self, end.sim, end.outcome);
        Ok(())
    }
}

/// The smallest k with n / 2ᵏ ≤ max: `/particles` shows 1 body in 2ᵏ.
pub fn subset_shift(n: usize, max: usize) -> u32 {
    let mut k = 0;
    while k < 63 && (n >> k) > max {
        k += 1;
    }
    k
}

/// Whether body `id` is in the subset of 1 in 2ᵏ: the top k bits of its hash are zero.
/// Nested: the subset for k contains the subset for k + 1.
pub fn in_subset(id: u64, k: u32) -> bool {
    k == 0 || splitmix64(id) >> (64 - k) == 0
}
