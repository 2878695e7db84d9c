//! The messages of the four channels, built from a run's state: shared by the MCAP
//! [`Recorder`](super::Recorder) and the live server (`crate::live`), so that a file and
//! a live connection show the same scene (topics, schemas, entity ids, colours) and the
//! same fitted layout works for both.
//!
//! Pure builders: no I/O, no channel ids. The recorder writes what they return to MCAP,
//! the live server to its WebSocket channels.

use foxglove::Encode;
use foxglove::schemas::{
    Color, LinePrimitive, Log, Point3, Pose, Quaternion, SceneEntity, SceneEntityDeletion,
    SceneUpdate, SpherePrimitive, Timestamp, Vector3, line_primitive, log, scene_entity_deletion,
};

use super::{ColourScale, FRAME_ID};
use crate::components::BodyState;
use crate::resources::Counters;
use crate::schedule::Simulation;

/// Name of the `/stats` schema (encoding `jsonschema`, bytes [`super::Stats::schema_bytes`]).
pub const STATS_SCHEMA: &str = "agglo.Stats";

/// Name used in `foxglove.Log` messages.
const LOG_NAME: &str = "agglo";

/// Invariant-violation descriptions copied into `/events` at most (the engine keeps
/// the first few itself; the counts keep coming in the aggregated warnings).
const MAX_VIOLATION_EVENTS: usize = 20;

/// The `foxglove.SceneUpdate` schema (`/particles`, `/box`).
pub fn scene_schema() -> anyhow::Result<foxglove::Schema> {
    anyhow::Context::context(SceneUpdate::get_schema(), "foxglove.SceneUpdate schema")
}

/// The `foxglove.Log` schema (`/events`).
pub fn log_schema() -> anyhow::Result<foxglove::Schema> {
    anyhow::Context::context(Log::get_schema(), "foxglove.Log schema")
}

/// A `foxglove.Timestamp` of `ns` nanoseconds of log time (saturating: timestamps hold
/// u32 seconds, 136 years of playback).
pub fn timestamp(ns: u64) -> Timestamp {
    Timestamp::new_checked(
        u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
        (ns % 1_000_000_000) as u32,
    )
    .unwrap_or(Timestamp::MAX)
}

/// A `/events` message.
pub fn log_message(stamp: Timestamp, level: log::Level, message: String) -> Log {
    Log {
        timestamp: Some(stamp),
        level: level as i32,
        message,
        name: LOG_NAME.into(),
        file: String::new(),
        line: 0,
    }
}

/// Whether a body can be drawn: a finite centre and a finite positive size (the others
/// are left out of `/particles`, and a `NonFinite` error reports them).
pub fn drawable(b: &BodyState) -> bool {
    b.position.is_finite() && b.radius.is_finite() && b.radius > 0.0
}

/// The `/particles` entity of body `b`: a sphere of diameter 2b at its centre, coloured
/// by temperature, with the body's stable id as the entity id ([`sphere_entity`]).
pub fn body_entity(b: &BodyState, colours: &ColourScale, stamp: Timestamp) -> SceneEntity {
    sphere_entity(b, colours.rgb(b.temperature), stamp)
}

/// The grey of a primary that is an aggregate of one (rigid scenes).
pub const SINGLE_PRIMARY_RGB: [f64; 3] = [0.6, 0.6, 0.6];

/// The colour of the primaries of aggregate `id` of `primaries` primaries (rigid scenes,
/// docs/model.md §6.1): grey for a primary alone; otherwise a hue of its own, the
/// fractional part of id × the golden ratio's 0.618…, so that aggregates of nearby ids
/// get well-separated hues and an aggregate keeps its colour while it grows (its id
/// is its smallest primary's).
pub fn aggregate_rgb(id: u64, primaries: usize) -> [f64; 3] {
    if primaries < 2 {
        return SINGLE_PRIMARY_RGB;
    }
    let hue = (id as f64 * 0.618_033_988_749_894_9).fract() * 6.0;
    // HSV with saturation 0.8 and value 0.95 to RGB.
    let (s, v) = (0.8, 0.95);
    let sector = (hue.floor() as usize).min(5);
    let f = hue - sector as f64;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match sector {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// The `/particles` entity of body `b` coloured `rgb` (components in [0, 1]).
pub fn sphere_entity(b: &BodyState, [r, g, bl]: [f64; 3], stamp: Timestamp) -> SceneEntity {
    let diameter = 2.0 * b.radius;
    SceneEntity {
        timestamp: Some(stamp),
        frame_id: FRAME_ID.into(),
        id: b.id.to_string(),
        spheres: vec![SpherePrimitive {
            pose: Some(identity_pose(b.position.x, b.position.y, b.position.z)),
            size: Some(Vector3 {
                x: diameter,
                y: diameter,
                z: diameter,
            }),
            color: Some(Color {
                r,
                g,
                b: bl,
                a: 1.0,
            }),
        }],
        ..Default::default()
    }
}

/// Deletion of the entity of body `id`.
pub fn deletion_of(id: u64, stamp: Timestamp) -> SceneEntityDeletion {
    SceneEntityDeletion {
        timestamp: Some(stamp),
        r#type: scene_entity_deletion::Type::MatchingId as i32,
        id: id.to_string(),
    }
}

/// Deletion of every entity on the topic (applied before the message's own entities).
pub fn deletion_of_all(stamp: Timestamp) -> SceneEntityDeletion {
    SceneEntityDeletion {
        timestamp: Some(stamp),
        r#type: scene_entity_deletion::Type::All as i32,
        id: String::new(),
    }
}

/// The periodic box [−D, D]³ as a line list of its 12 edges (`/box`).
pub fn box_update(half_width: f64, stamp: Timestamp) -> SceneUpdate {
    let d = half_width;
    let corner = |i: usize| Point3 {
        x: if i & 1 == 0 { -d } else { d },
        y: if i & 2 == 0 { -d } else { d },
        z: if i & 4 == 0 { -d } else { d },
    };
    // Edges join corners differing in one bit.
    let mut points = Vec::with_capacity(24);
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            if i & bit == 0 {
                points.push(corner(i));
                points.push(corner(i | bit));
            }
        }
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![SceneEntity {
            timestamp: Some(stamp),
            frame_id: FRAME_ID.into(),
            id: "box".into(),
            lines: vec![LinePrimitive {
                r#type: line_primitive::Type::LineList as i32,
                pose: Some(identity_pose(0.0, 0.0, 0.0)),
                // Thickness in pixels (scale invariant): visible at any zoom.
                thickness: 2.0,
                scale_invariant: true,
                points,
                color: Some(Color {
                    r: 0.8,
                    g: 0.8,
                    b: 0.8,
                    a: 1.0,
                }),
                colors: Vec::new(),
                indices: Vec::new(),
            }],
            ..Default::default()
        }],
    }
}

/// The `/events` error naming bodies left out of `/particles` (non-finite centre or size).
pub fn skipped_bodies_message(skipped: &[&BodyState]) -> String {
    let list: Vec<String> = skipped.iter().take(10).map(|b| b.id.to_string()).collect();
    format!(
        "{} bodies with a non-finite position or size left out of /particles (ids {}{})",
        skipped.len(),
        list.join(", "),
        if skipped.len() > 10 { ", …" } else { "" }
    )
}

/// The message of the run's outcome on `/events`, with its status word and level.
pub fn outcome_message(
    sim: &Simulation,
    outcome: &Result<(), crate::error::SimError>,
) -> (&'static str, log::Level, String) {
    let clock = sim.clock();
    match outcome {
        Ok(()) => (
            "finished",
            log::Level::Info,
            format!(
                "run finished: t = {:e} s in {} steps",
                clock.time, clock.step
            ),
        ),
        Err(e @ crate::error::SimError::Interrupted { .. }) => {
            ("interrupted", log::Level::Error, e.to_string())
        }
        Err(e) => ("failed", log::Level::Error, e.to_string()),
    }
}

/// The `/events` message at the start of a run.
pub fn start_message(scenario: &crate::scenario::Scenario) -> String {
    format!(
        "run started: scenario {} (seed {}), T = {:e} s, {} bodies; agglo {}",
        scenario.name,
        scenario.seed,
        scenario.time.end,
        scenario.cloud.count,
        env!("CARGO_PKG_VERSION")
    )
}

/// Counter increments since the last snapshot, reported there as one warning each.
#[derive(Debug, Clone, Copy, Default)]
struct Pending {
    since: f64,
    fallbacks: u64,
    unconverged: u64,
    clamped_steps: u64,
    overlap_violations: u64,
    invariant_violations: u64,
}

/// The warnings of `/events`: new invariant-violation descriptions as they come, and per
/// snapshot one aggregated line per kind of counter that grew since the last one.
#[derive(Debug, Clone)]
pub struct Warnings {
    counters: Counters,
    pending: Pending,
    violations_reported: usize,
}

impl Warnings {
    /// Start counting from `sim`'s counters now.
    pub fn new(sim: &Simulation) -> Self {
        Self {
            counters: sim.counters(),
            pending: Pending {
                since: sim.clock().time,
                ..Default::default()
            },
            violations_reported: 0,
        }
    }

    /// Count new warnings; returns the new invariant-violation descriptions, to be
    /// reported at once (at most [`MAX_VIOLATION_EVENTS`] over the run).
    pub fn note(&mut self, sim: &Simulation) -> Vec<String> {
        let now = sim.counters();
        let before = self.counters;
        if now == before {
            return Vec::new();
        }
        let p = &mut self.pending;
        p.fallbacks += now.fallbacks.saturating_sub(before.fallbacks);
        p.unconverged += now.unconverged.saturating_sub(before.unconverged);
        p.clamped_steps += now.clamped_steps.saturating_sub(before.clamped_steps);
        p.overlap_violations += now
            .overlap_violations
            .saturating_sub(before.overlap_violations);
        p.invariant_violations += now
            .invariant_violations
            .saturating_sub(before.invariant_violations);
        self.counters = now;
        if now.invariant_violations > before.invariant_violations
            && self.violations_reported < MAX_VIOLATION_EVENTS
        {
            let report = sim.invariants();
            let new: Vec<String> = report
                .violations
                .iter()
                .skip(self.violations_reported)
                .take(MAX_VIOLATION_EVENTS - self.violations_reported)
                .map(|v| format!("invariant violation: {v}"))
                .collect();
            self.violations_reported += new.len();
            return new;
        }
        Vec::new()
    }

    /// One aggregated warning per kind of counter that grew since the last call (or the
    /// start), at simulated time `t`; starts the next interval at `t`.
    pub fn flush(&mut self, t: f64) -> Vec<String> {
        let p = self.pending;
        let c = self.counters;
        let since = p.since;
        let lines = [
            (
                p.fallbacks,
                "impacts needed the bracketed fallback solver",
                c.fallbacks,
            ),
            (
                p.unconverged,
                "impacts did not converge (plain solver, last iterate used)",
                c.unconverged,
            ),
            (
                p.clamped_steps,
                "steps clamped at dt_min although a contact was due sooner",
                c.clamped_steps,
            ),
            (
                p.overlap_violations,
                "approaching pairs found overlapping (missed contacts)",
                c.overlap_violations,
            ),
            (
                p.invariant_violations,
                "invariant checks failed",
                c.invariant_violations,
            ),
        ];
        self.pending = Pending {
            since: t,
            ..Default::default()
        };
        lines
            .into_iter()
            .filter(|(n, _, _)| *n > 0)
            .map(|(n, what, total)| format!("{n} {what} since t = {since:e} s ({total} in total)"))
            .collect()
    }
}

fn identity_pose(x: f64, y: f64, z: f64) -> Pose {
    Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    }
}
