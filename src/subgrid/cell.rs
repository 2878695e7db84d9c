//! One cell: its state between macro steps ([`CellState`], the `get_state`/`set_state`
//! of a per-cell coupling library) and one replica box advanced over a macro step
//! ([`run_replica`]).

use serde::{Deserialize, Serialize};

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::Arc;

use crate::kernel::{Accumulator, KernelObserver, Sampling, Window};
use crate::observer::Observer;
use crate::run::{BareResume, Resume, Run, RunPlan, Until, failure_text};
use agglo_systems::diagnostics::InitialEnergies;
use agglo_systems::impact::CollapseGuard;
use bevy_ecs::world::FromWorld;

use crate::cloud::PlacedBody;
use crate::scenario::Scenario;
use crate::schedule::Simulation;
use agglo_engine::restart::RestartSnapshot;

use super::adjust::adjusted_box;
use super::config::Coupling;
use super::error::SubgridError;
use super::exchange::CellInput;
use super::lift::{box_scene, lift, replica_seed};
use super::profile::{Lap, Part};
use super::restrict::{ClassSums, Replica};
use crate::resources::{Counters, EnergyLedger};

/// Layout version of [`CellState::to_bytes`]; bumped when it changes (3: the CRC-32
/// after the postcard bytes, issue 39; 4: each remembered class's granular
/// anisotropy, issue 37; 5: a kept box holds its scene's seed instead of the scene,
/// issue 37).
pub const STATE_VERSION: u32 = 5;

/// A kept box between macro steps: the restart snapshot at the end of the last step
/// (engine/restart.rs), from which the next step continues bit for bit, and the seed of
/// the scene it was lifted (or adjusted) as. The rest of that scene follows from the
/// coupling, the cell's box volume and the step's gas (`lift::box_scene`), so it is
/// not stored: a resumed box is built from its settings and the snapshot's bodies
/// alone, not from the bodies it was lifted with (issue 37: re-reading a 1000-body
/// lifted scene to resume 22 bodies cost 7 × their run). With `persist`, a box whose
/// Poisson draw held no body is kept as empty (no snapshot) and lifted afresh at the
/// next step: it remembers nothing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeptBox {
    /// The seed of the box's scene (its random generator's, `Scenario::seed`).
    pub seed: u64,
    /// What the box's run read of its first bodies when it was built.
    pub start: BoxStart,
    /// [`RestartSnapshot::encode`]'s bytes.
    pub snapshot: Vec<u8>,
}

/// What a box's run reads of its initial bodies while its simulation is built, kept so
/// that a resumed box, built without them (`SimBuilder::resuming`), runs as the box
/// continuing would: the body count (the invariant checks' full recount cadence), the
/// initial kinetic and thermal energy (the references of the energy ledgers' checks)
/// and the collapse time of the TC model (drawn from the initial velocities when the
/// scene has a restitution and gives none; 0 when off).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BoxStart {
    /// Bodies at the start of the box's run.
    pub bodies: u64,
    /// Σ ½ m v² at the start [J].
    pub kinetic: f64,
    /// Σ m C θ at the start [J].
    pub thermal: f64,
    /// t_c of the TC model [s] (0: off).
    pub collapse_time: f64,
}

impl BoxStart {
    /// Read from a box's simulation built from its scene, before it runs.
    fn of(sim: &mut Simulation) -> Self {
        let bodies = sim.info().initial_bodies as u64;
        let world = sim.world_mut();
        // The value each check system's `Local` was filled with when the pipeline was
        // built: the same bodies in the same order, not yet moved.
        let energies = InitialEnergies::from_world(world);
        let collapse_time = world.get_resource::<CollapseGuard>().map_or(0.0, |g| g.t_c);
        Self {
            bodies,
            kinetic: energies.kinetic,
            thermal: energies.thermal,
            collapse_time,
        }
    }

    /// Each field in range (a state read back is checked before a box is built).
    fn check(&self) -> Result<(), String> {
        // A scene's cloud holds 1 to 2³² − 2 bodies (`cloud.count`).
        if !(1..u32::MAX as u64).contains(&self.bodies) {
            return Err(format!(
                "start.bodies = {} (must be ≥ 1 and < {})",
                self.bodies,
                u32::MAX
            ));
        }
        for (name, x) in [
            ("kinetic", self.kinetic),
            ("thermal", self.thermal),
            ("collapse_time", self.collapse_time),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(format!("start.{name} = {x:e} (must be ≥ 0 and finite)"));
            }
        }
        Ok(())
    }
}

impl KeptBox {
    /// The kept form of a box that holds no body (persist only).
    fn empty() -> Self {
        Self {
            seed: 0,
            start: BoxStart::default(),
            snapshot: Vec::new(),
        }
    }
    /// True for a box kept with no body: lifted afresh at the next step.
    pub fn is_empty(&self) -> bool {
        self.snapshot.is_empty()
    }
}

/// What a cell carries from one macro step to the next. Opaque to the flow solver:
/// store it with [`CellState::to_bytes`] and give it back (decoded with
/// [`CellState::from_bytes`]) with the cell's next step — or give `None` to start the
/// cell afresh. Without `keep_bodies` it holds only the cell's clock; with it, every
/// replica's bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellState {
    pub(crate) version: u32,
    pub(crate) cell: u64,
    pub(crate) macro_steps: u64,
    pub(crate) time: f64,
    pub(crate) volume: f64,
    pub(crate) boxes: Vec<KeptBox>,
    /// With `persist`: what the flow solver holds after applying the last step's rates
    /// ([`super::apply_rates`]), against which the next input's transport is measured.
    pub(crate) expected: Option<CellInput>,
}

impl CellState {
    /// The cell this state belongs to.
    pub fn cell(&self) -> u64 {
        self.cell
    }
    /// Macro steps the cell has taken.
    pub fn macro_steps(&self) -> u64 {
        self.macro_steps
    }
    /// The cell's simulated time [s] (the sum of its steps' Δt).
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Volume of each of its boxes [m³] (kept boxes keep theirs).
    pub fn box_volume(&self) -> f64 {
        self.volume
    }
    /// The kept boxes, one per replica (empty without `keep_bodies`).
    pub fn boxes(&self) -> &[KeptBox] {
        &self.boxes
    }
    /// True when the state holds bodies (a closed cell).
    pub fn keeps_bodies(&self) -> bool {
        !self.boxes.is_empty()
    }

    /// The state as bytes: postcard (every f64 as its 8 bytes; the layout version
    /// first, as a varint) followed by the CRC-32 of those bytes (u32, little-endian),
    /// so that damaged bytes are refused rather than read as another state.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = postcard::to_allocvec(self).expect("a cell state always encodes");
        let crc = crc32fast::hash(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        bytes
    }

    /// A state from [`Self::to_bytes`]'s bytes; refuses another layout version, bytes
    /// whose checksum does not match, and a state whose fields are out of range.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        // The version first, so that an older layout is named as such.
        let (version, _) = postcard::take_from_bytes::<u32>(bytes)
            .map_err(|e| format!("the cell state does not decode ({e})"))?;
        if version != STATE_VERSION {
            return Err(format!(
                "the cell state has layout version {version}, this build reads version \
                 {STATE_VERSION}"
            ));
        }
        let Some((payload, crc)) = bytes.split_last_chunk::<4>() else {
            return Err(format!(
                "the cell state is {} bytes, too short to hold its checksum",
                bytes.len()
            ));
        };
        let stored = u32::from_le_bytes(*crc);
        if crc32fast::hash(payload) != stored {
            return Err(format!(
                "the cell state's checksum does not match its {} bytes (damaged bytes)",
                bytes.len()
            ));
        }
        let (s, rest): (Self, _) = postcard::take_from_bytes(payload)
            .map_err(|e| format!("the cell state does not decode ({e})"))?;
        if !rest.is_empty() {
            return Err(format!(
                "the cell state has {} bytes after its end",
                rest.len()
            ));
        }
        s.check_fields()?;
        Ok(s)
    }

    /// The checks that need no coupling: every number in range (a state made in
    /// memory by a caller, or read back, never reaches a box with a NaN volume).
    fn check_fields(&self) -> Result<(), String> {
        if !(self.time.is_finite() && self.time >= 0.0) {
            return Err(format!(
                "time = {:e} (must be ≥ 0 and finite [s])",
                self.time
            ));
        }
        // A normal number: 1/V and V^(1/3) stay finite and exact enough.
        if !(self.volume.is_finite() && self.volume >= f64::MIN_POSITIVE) {
            return Err(format!(
                "box_volume = {:e} (must be finite and ≥ {:e} [m³])",
                self.volume,
                f64::MIN_POSITIVE
            ));
        }
        for (r, kept) in self.boxes.iter().enumerate() {
            if !kept.is_empty() {
                kept.start.check().map_err(|e| format!("boxes[{r}].{e}"))?;
            }
        }
        if let Some(e) = &self.expected {
            for (k, class) in e.classes.iter().enumerate() {
                let n = class.number_density;
                if !(n.is_finite() && n >= 0.0) {
                    return Err(format!(
                        "expected.classes[{k}].number_density = {n:e} (must be ≥ 0 and finite \
                         [1/m³])"
                    ));
                }
                let m = class.mass;
                if !(m.is_finite() && m > 0.0) {
                    return Err(format!(
                        "expected.classes[{k}].mass = {m:e} (must be > 0 and finite [kg])"
                    ));
                }
                let a = class.granular_anisotropy;
                if !a.iter().all(|x| x.is_finite() && *x >= 0.0) {
                    return Err(format!(
                        "expected.classes[{k}].granular_anisotropy = {a:?} (each must be ≥ 0 \
                         and finite)"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Check that this state can continue `cell` under `c`.
    pub(crate) fn check(&self, c: &Coupling, cell: u64) -> Result<(), SubgridError> {
        let bad = |reason: String| Err(SubgridError::State { cell, reason });
        if self.version != STATE_VERSION {
            return bad(format!(
                "layout version {}, this build makes version {STATE_VERSION}",
                self.version
            ));
        }
        if self.cell != cell {
            return bad(format!("it is cell {}'s state", self.cell));
        }
        let keeps = c.keep_bodies || c.persist;
        if keeps && self.boxes.len() != c.replicas as usize {
            return bad(format!(
                "it holds {} boxes; the coupling keeps {} replicas' bodies",
                self.boxes.len(),
                c.replicas
            ));
        }
        if !keeps && !self.boxes.is_empty() {
            // Its bodies would be dropped without a word.
            return bad(format!(
                "it holds {} boxes of bodies (a closed or persistent cell's state); this \
                 coupling keeps none (keep_bodies and persist are false)",
                self.boxes.len()
            ));
        }
        if c.persist != self.expected.is_some() {
            return bad(if c.persist {
                "it remembers no cell state; a persistent coupling's state does (it was made \
                 without persist)"
                    .into()
            } else {
                "it remembers a cell state (made with persist); this coupling has persist = \
                 false"
                    .into()
            });
        }
        if let Some(e) = &self.expected
            && e.classes.len() != c.classes()
        {
            return bad(format!(
                "expected.classes = {} classes (must be {}, one per class of the edges)",
                e.classes.len(),
                c.classes()
            ));
        }
        self.check_fields().or_else(bad)
    }
}

/// One replica's result: what it measured, its kernel sums, its kept box.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReplicaRun {
    /// The class sums and ledgers the box measured over the step.
    pub measured: Replica,
    /// Its kernel sums, with `Coupling::kernel`.
    pub kernel: Option<Accumulator>,
    /// The box at the end of the step, when the cell keeps its boxes.
    pub kept: Option<KeptBox>,
}

/// A box whose Poisson draw held no body (probability e^−N): it saw nothing, and
/// counts as such (every sum and event 0), since dropping it would bias every rate up.
/// A closed cell cannot keep an empty box (it would stay empty): refused, asking for a
/// larger N. A persistent cell keeps it as empty, to be lifted afresh next step.
fn empty_box(
    c: &Coupling,
    cell: u64,
    replica: u32,
    volume: f64,
) -> Result<ReplicaRun, SubgridError> {
    if c.keep_bodies {
        return Err(SubgridError::input(
            cell,
            "bodies",
            format!("replica {replica}'s box of {volume:e} m³ drew no body"),
            "a closed cell keeps its boxes: raise N",
        ));
    }
    let nothing = ClassSums::of(c, &[]);
    let zero = (EnergyLedger::default(), Counters::default());
    Ok(ReplicaRun {
        measured: Replica::new(nothing.clone(), nothing, &zero.0, &zero.0, &zero.1, &zero.1),
        kernel: None,
        kept: c.persist.then(KeptBox::empty),
    })
}

/// Advance replica `replica` of `cell` over `input.dt`: lift a new box of `volume`
/// [m³] (seeded by [`replica_seed`]), or continue `kept` — as it was, or, with
/// `persist` and an `expected` state the input differs from, adjusted (adjust.rs).
#[allow(clippy::too_many_arguments)] // the task's fields, as ReplicaTask holds them
pub fn run_replica(
    c: &Coupling,
    cell: u64,
    macro_step: u64,
    replica: u32,
    input: &CellInput,
    volume: f64,
    kept: Option<&KeptBox>,
    expected: Option<&CellInput>,
) -> Result<ReplicaRun, SubgridError> {
    let fail = |reason: String| SubgridError::Run {
        cell,
        replica,
        reason,
    };
    // Each part of the box's step is a lap of one stopwatch (profile.rs).
    let mut lap = Lap::start();
    // A persistent box that held nothing has nothing to continue: lifted afresh.
    let kept = kept.filter(|k| !k.is_empty());
    let scenario = match kept {
        None => {
            let seed = replica_seed(c.base.seed, cell, macro_step, replica);
            let s = lift(c, cell, input, volume, seed).map_err(|e| match e {
                SubgridError::Run { reason, .. } => fail(reason),
                other => other,
            })?;
            lap.to(Part::Lift);
            if s.cloud.bodies.is_empty() {
                return empty_box(c, cell, replica, volume);
            }
            s
        }
        Some(kept) => {
            let snapshot =
                RestartSnapshot::decode(&kept.snapshot).map_err(|e| SubgridError::State {
                    cell,
                    reason: format!("replica {replica}: {e}"),
                })?;
            lap.to(Part::Restore);
            if let Some(e) = expected.filter(|e| e.classes != input.classes) {
                // Transport changed the cell: the box adjusted to it (adjust.rs).
                let seed = replica_seed(c.base.seed, cell, macro_step, replica);
                let s = adjusted_box(c, cell, input, e, volume, seed, &snapshot.bodies).map_err(
                    |e| match e {
                        SubgridError::Run { reason, .. } => fail(reason),
                        other => other,
                    },
                )?;
                lap.to(Part::Adjust);
                if s.cloud.bodies.is_empty() {
                    return empty_box(c, cell, replica, volume);
                }
                return run_scene(c, cell, replica, s, None, lap);
            }
            // The box's settings in the gas of this step; its clock runs on from the
            // snapshot's time, and its bodies are the snapshot's.
            let mut s = box_scene(c, input, volume.cbrt(), kept.seed, vec![placeholder(input)]);
            s.time.end = snapshot.time() + input.dt;
            if s.impact.restitution.is_some() && s.impact.collapse_time.is_none() {
                s.impact.collapse_time = Some(kept.start.collapse_time);
            }
            lap.to(Part::Restore);
            return run_scene(c, cell, replica, s, Some((snapshot, kept.start)), lap);
        }
    };
    run_scene(c, cell, replica, scenario, None, lap)
}

/// The one body of a resumed box's scene: a primary grain at rest at the origin, in the
/// step's gas. It is never spawned (`SimBuilder::resuming`); it is there because a
/// scene's cloud holds at least one body, and one body is checked in no time.
fn placeholder(input: &CellInput) -> PlacedBody {
    PlacedBody {
        position: [0.0; 3],
        velocity: Some([0.0; 3]),
        primaries: 1.0,
        id: Some(0),
        temperature: Some(input.gas.temperature),
        mass: None,
        radius: None,
    }
}

/// Run `scenario` over its end time through the door every run takes ([`Run`]: the
/// built-in physics and the registered extensions; resumed from a kept box's snapshot
/// and start, when given, without the scene's cloud) and measure it, timing its parts as
/// laps of `lap`.
fn run_scene(
    c: &Coupling,
    cell: u64,
    replica: u32,
    scenario: Scenario,
    resume: Option<(RestartSnapshot, BoxStart)>,
    mut lap: Lap,
) -> Result<ReplicaRun, SubgridError> {
    let fail = |reason: String| SubgridError::Run {
        cell,
        replica,
        reason,
    };
    let keeps = c.keep_bodies || c.persist;
    let seed = scenario.seed;
    let mut plan = RunPlan::unwritten(scenario);
    let resumed = resume.map(|(snapshot, start)| {
        // A resumed box is built without its scene's cloud (`placeholder`): the
        // snapshot brings the bodies, `start` what the run read of its first ones.
        plan.resume = Some(Resume {
            file: PathBuf::from(format!("cell {cell}'s kept box {replica}")),
            snapshot,
        });
        plan.resume_bare = Some(BareResume {
            initial_bodies: start.bodies as usize,
            energies: InitialEnergies {
                kinetic: start.kinetic,
                thermal: start.thermal,
            },
        });
        start
    });
    // Only a box that measures the kernel collects the impact, merge and fragment
    // messages its accumulator reads (the observer subscribes them).
    let mut observers: Vec<Box<dyn Observer>> = Vec::new();
    let kernel = c.kernel.then(|| {
        let acc = Accumulator::new(c.kernel_grid(), Window::default(), Sampling::default());
        let (observer, handback) = KernelObserver::new(acc);
        observers.push(Box::new(observer));
        handback
    });
    // Assembling the box ends with the last word on its builder; building it (the
    // event core's first prediction of every body, the schedule's initialisation) and
    // resuming it are the calendar: what a direct run of the box does first.
    let mut run = Run::start_observed_with(plan, Arc::default(), observers, |_| {
        lap.to(Part::Build);
        Ok(())
    })
    .map_err(|e| fail(failure_text(&e)))?;
    let box_start = match resumed {
        Some(start) => start,
        None if keeps => BoxStart::of(run.sim_mut()),
        None => BoxStart::default(),
    };
    lap.to(Part::Calendar);
    let start = ClassSums::of(c, &run.sim().bodies());
    lap.to(Part::Restrict);
    let (ledger0, counters0) = (run.sim().ledger(), run.sim().counters());
    let outcome = run.advance(Until::End, &mut |_| ControlFlow::Continue(()));
    let mut end = run.finish(&outcome);
    // The accumulator's refusal first: it stopped the run.
    if let Some(e) = end.output_error.take() {
        return Err(fail(format!("kernel: {e}")));
    }
    outcome.map_err(|e| fail(e.to_string()))?;
    let kernel = match kernel {
        Some(handback) => Some(
            handback
                .take()
                .ok_or_else(|| fail("the run ended without its kernel".into()))?,
        ),
        None => None,
    };
    lap.to(Part::Run);
    let sim = &mut end.sim;
    let end_sums = ClassSums::of(c, &sim.bodies());
    let measured = Replica::new(
        start,
        end_sums,
        &ledger0,
        &sim.ledger(),
        &counters0,
        &sim.counters(),
    );
    lap.to(Part::Restrict);
    let kept = keeps.then(|| {
        // The run is complete: every body is at the end time (Simulation::run_until).
        let snapshot = agglo_engine::restart::capture(sim.world_mut());
        let kept = KeptBox {
            seed,
            start: box_start,
            snapshot: snapshot.encode(),
        };
        lap.to(Part::Keep);
        kept
    });
    // Freeing the box's world is part of every run's cost, timed apart from the
    // coupling's bookkeeping.
    drop(end);
    lap.to(Part::Teardown);
    Ok(ReplicaRun {
        measured,
        kernel,
        kept,
    })
}
