//! How much memory a scene needs, against what the machine has: the limit on the number
//! of bodies comes from here, not from a fixed cap.
//!
//! The estimate is the measured peak resident memory per body of a run (release build,
//! no recording, `cargo bench --bench memory` on the merging peer clouds,
//! `benches/peers/scenes/`: 568 B per body at N = 1e5 and 482 B at 1e6; 1231 B at 1e4,
//! where the process's own 5.7 MB is about half of it; the 1e6 bounce cloud peaks at 552 B
//! when its final state is read), rounded up to [`BYTES_PER_BODY`] for the field's
//! relaxation time and the sampled tables, plus [`BASE_BYTES`] for the process itself
//! and the recording's buffers, plus [`RECORDING_BYTES_PER_BODY`] when the run records
//! (a frame's scene is built, encoded and compressed on the writer thread from a copy of
//! the bodies). It is compared with the memory the kernel says is available
//! (`MemAvailable` in /proc/meminfo) before anything is allocated: `agglo run` refuses a
//! scene that cannot fit and warns when it would take more than half; `agglo validate`
//! prints the estimate and runs the same check.

use crate::scenario::Scenario;

/// Peak resident bytes per body of a run (measured; see the module docs) [B].
pub const BYTES_PER_BODY: f64 = 650.0;

/// Peak resident bytes per body that recording adds [B]: a recorded 1e6-body peer
/// bounce run peaked at 1302 MiB against 564 MB unrecorded, +802 B per body (it was
/// 1366 MiB against 659 MB before the world's memory fixes).
pub const RECORDING_BYTES_PER_BODY: f64 = 800.0;

/// Peak resident bytes per primary that a rigid scene (`physics.merge_mode = "rigid"`,
/// docs/model.md §6.1) adds [B]: an aggregate entity per primary at t = 0 (its id, mass,
/// velocity and member list) and each primary's aggregate and offset, which move every
/// body to a new archetype (the old table keeps its capacity). Measured on the
/// scenarios/bcca.json cloud (`/usr/bin/time` peak RSS, rigid less coalesce): +590 B per
/// body at N = 5e4 and 2e5 just after t = 0, +700 B over a run to t = 0.3 s at 5e4 (the
/// coalesce run's merged bodies leave); rounded up.
pub const RIGID_BYTES_PER_BODY: f64 = 750.0;

/// Resident bytes of the process without bodies (5.7 MB measured for two bodies) plus
/// the recording's chunk buffers (1 MiB uncompressed, compressed copy) [B].
pub const BASE_BYTES: f64 = 16e6;

/// What a scene is expected to need and what the machine has.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    /// Bodies at t = 0.
    pub bodies: usize,
    /// Expected peak resident memory [B].
    pub bytes: f64,
    /// Memory available now [B] (None where the kernel does not say).
    pub available: Option<f64>,
    /// Runs of the scene held in memory at once (an ensemble's threads); `bytes`
    /// counts them all.
    pub runs_at_once: usize,
}

impl MemoryEstimate {
    /// The estimate for `scenario` on this machine, without a recording.
    pub fn of(scenario: &Scenario) -> Self {
        Self::of_run(scenario, false)
    }

    /// The estimate for `scenario` on this machine, recorded to MCAP or not.
    pub fn of_run(scenario: &Scenario, recording: bool) -> Self {
        let bodies = scenario.cloud.count.max(scenario.cloud.bodies.len());
        let rigid = scenario.physics.merge_mode == crate::scene::MergeMode::Rigid;
        let per_body = BYTES_PER_BODY
            + if recording {
                RECORDING_BYTES_PER_BODY
            } else {
                0.0
            }
            + if rigid { RIGID_BYTES_PER_BODY } else { 0.0 };
        Self {
            bodies,
            bytes: BASE_BYTES + per_body * bodies as f64,
            available: available_bytes(),
            runs_at_once: 1,
        }
    }

    /// The estimate for an ensemble of `runs` unrecorded runs of `scenario` on `threads`
    /// worker threads (0 = one per core): min(runs, threads) scenes are held at once.
    /// Each run alone passed `run`'s check, so `agglo kernel`, `ensemble()` and the
    /// studies aborted on a scene that `agglo run` refuses, or on threads × a scene.
    pub fn of_runs(scenario: &Scenario, runs: usize, threads: usize) -> Self {
        let one = Self::of_run(scenario, false);
        let at_once = runs.min(crate::farm::thread_count(threads)).max(1);
        Self {
            bytes: BASE_BYTES + (one.bytes - BASE_BYTES) * at_once as f64,
            runs_at_once: at_once,
            ..one
        }
    }

    /// Bytes per body of one run [B].
    fn per_body(&self) -> f64 {
        (self.bytes - BASE_BYTES) / (self.bodies.max(1) * self.runs_at_once.max(1)) as f64
    }

    /// One line for `agglo validate`.
    pub fn describe(&self) -> String {
        // Say the fixed part: at small N it is most of the figure, and "16 MB for 300
        // bodies (650 B per body)" does not add up without it.
        let parts = format!(
            "memory: about {:.0} MB for {} bodies ({:.0} MB fixed + {:.0} B per body)",
            self.bytes / 1e6,
            self.bodies,
            BASE_BYTES / 1e6,
            self.per_body(),
        );
        match self.available {
            Some(a) => format!("{parts}, {:.0} MB available", a / 1e6),
            None => format!("{parts}; available memory unknown"),
        }
    }

    /// An error naming `cloud.count` when the scene cannot fit; a warning when it would
    /// take more than half of what is available.
    pub fn check(&self) -> Result<Option<String>, String> {
        let Some(available) = self.available else {
            return Ok(None);
        };
        if self.bytes > available && self.runs_at_once > 1 {
            let fit = ((available - BASE_BYTES) / (self.bytes - BASE_BYTES)
                * self.runs_at_once as f64)
                .floor();
            return Err(format!(
                "cloud.count: {} runs at once of {} bodies each need about {:.1} GB ({:.0} B \
                 per body), but only {:.1} GB of memory is available; allowed at most {fit:.0} \
                 runs at once on this machine now (fewer threads), or fewer bodies",
                self.runs_at_once,
                self.bodies,
                self.bytes / 1e9,
                self.per_body(),
                available / 1e9,
            ));
        }
        if self.bytes > available {
            return Err(format!(
                "cloud.count: {} bodies need about {:.1} GB ({:.0} B per body), but only {:.1} GB \
                 of memory is available; allowed N ≤ {:.3e} on this machine now",
                self.bodies,
                self.bytes / 1e9,
                self.per_body(),
                available / 1e9,
                ((available - BASE_BYTES) / self.per_body())
                    .max(0.0)
                    .floor()
            ));
        }
        Ok((self.bytes > 0.5 * available).then(|| {
            format!(
                "warning: {} bodies need about {:.1} GB, more than half of the {:.1} GB available",
                self.bodies,
                self.bytes / 1e9,
                available / 1e9
            )
        }))
    }
}

/// An error when `count` items (strings, scan points) needing `bytes` [B] in all exceed
/// the memory available now (`run`'s check for bodies, applied to the inverse problem
/// and scans, which once aborted on an allocation of 1e12 strings).
pub fn fits(what: &str, count: usize, bytes: f64) -> Result<(), String> {
    let available = available_bytes().unwrap_or(f64::INFINITY);
    if bytes + BASE_BYTES > available {
        return Err(format!(
            "{count} {what} need about {:.1} GB, but only {:.1} GB of memory is available; \
             allowed at most {:.3e} {what} on this machine now",
            bytes / 1e9,
            available / 1e9,
            ((available - BASE_BYTES) / (bytes / count.max(1) as f64))
                .max(0.0)
                .floor()
        ));
    }
    Ok(())
}

/// Bytes one copy of `scenario` holds [B]: its fixed part and its listed bodies. A
/// study that lists a scene per run (readings × seeds) holds this many per run.
pub fn scenario_bytes(scenario: &Scenario) -> f64 {
    (std::mem::size_of::<Scenario>()
        + scenario.cloud.bodies.len() * std::mem::size_of::<crate::cloud::PlacedBody>()) as f64
}

/// Memory available to a new process [B], from /proc/meminfo (Linux).
pub fn available_bytes() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}
