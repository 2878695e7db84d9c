//! The sufficient statistics of a measured kernel, gathered while runs run
//! ([`Accumulator`]): per outcome the impact counts C_ij and the exposure
//! E_ij = (1/V)∫N_i N_j dt (½N_i(N_i − 1) on the diagonal) of each pair of mass classes,
//! plus what a fragmenting pair's mass becomes, impact speeds, and the relative speed
//! of all pairs sampled at a few times. Runs, seeds and time windows pool by adding
//! (K = ΣC/ΣE), so [`Accumulator::merge`] is exact.
//!
//! **Cost.** Class counts change only at merges and fragmentations, so the exposure is
//! exact on the event core and kept incrementally: each class remembers when its count
//! last changed, and a change of class k adds N_k N_j × (time since the later of the two
//! changes) to E_kj for every class j before N_k changes — O(classes) per merge or
//! fragmentation, nothing per step otherwise. A step without impacts costs a look at
//! three empty message buffers and the clock. The bodies are read only at the start of
//! a run and at the relative-speed samples (a fixed number per run); nothing is kept
//! per body (a class change is read from the masses in the step's messages).
//!
//! **Sampled speeds describe the epoch of K.** K is a ratio of sums over exposure, so a
//! whole-run K is weighted by where the pairs were: in a coarsening system, early. The
//! relative speeds and geometric kernel are sampled at the window's start, whenever the
//! merges and fragmentations since the last sample reach 1/[`RESAMPLE_FRACTION`] of the
//! bodies then, and at [`Sampling::times`] evenly spread times; each interval between
//! two samples contributes the mean of its two ends (the trapezoid rule) weighted by the
//! exposure E_ij it accrued, so the averages are exposure-weighted like K.
//!
//! It reads the engine's hooks (engine/hooks.rs): impacts, merges and fragmentations,
//! which exist only when the simulation subscribed to them ([`subscribe`]).

use std::collections::{BTreeMap, BinaryHeap};

use bevy_ecs::prelude::{Entity, With};

use serde::{Deserialize, Serialize};

use crate::bodies::{Clockwork, state_at};
use crate::components::{BodyState, Mass, Particle, ParticleId, StoredBody};
use crate::hooks::{FragmentMessage, ImpactMessage, ImpactOutcome, MergeMessage, Messages};
use crate::resources::LazyState;
use crate::scene::{BoxGeometry, Material, Physics, TimeControl};
use crate::schedule::{SimBuilder, Simulation};
use crate::seeds::{derive_seed, splitmix64};
use agglo_engine::field::Field;

use super::grid::{GridError, MassGrid};

/// The outcomes counted, in the order of the outcome axis of every array.
pub const OUTCOMES: [&str; 3] = ["bond", "bounce", "fragment"];
const BOND: usize = 0;
const BOUNCE: usize = 1;
const FRAGMENT: usize = 2;

/// A new relative-speed sample is taken when merges and fragmentations since the last
/// one reach 1/`RESAMPLE_FRACTION` of the bodies then (ballistic aggregation from 1e4 to
/// 12 bodies: about 25 samples). 1/8 halved the remaining bias of the monomer geometric
/// kernel on the shipped scene (1.6 % against 3.2 % below K/χ) for twice the samples, +1 %
/// of the run's instructions at N = 1e5.
pub const RESAMPLE_FRACTION: u64 = 4;

/// Bodies of each class a relative-speed sample draws its pairs from: a uniform random
/// subset (all of them in a class that has fewer).
pub const MEMBERS_PER_CLASS: usize = 64;

/// Have `builder` collect what an [`Accumulator`] reads: impacts, merges, fragmentations.
pub fn subscribe(builder: &mut SimBuilder) {
    builder.subscribe::<ImpactMessage>();
    builder.subscribe::<MergeMessage>();
    builder.subscribe::<FragmentMessage>();
}

/// Why an accumulator could not observe or pool.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelError {
    /// The mass grid is unusable.
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error(
        "the simulation does not collect {0}: build it with agglo::kernel::subscribe(&mut builder)"
    )]
    /// The simulation does not collect the messages named (impacts, merges, fragments).
    NotSubscribed(&'static str),
    #[error(
        "Accumulator::observe before Accumulator::begin: call begin(&sim) before the first step"
    )]
    /// Observed before `begin`.
    NotBegun,
    /// Begun again before `end_run`.
    #[error("Accumulator::begin while a run is open: call end_run first")]
    RunOpen,
    /// Pooled with an accumulator on another grid (the two grids' specs).
    #[error("cannot pool accumulators on different grids (`{0}` and `{1}`)")]
    GridMismatch(String, String),
    /// Pooled with an accumulator whose run is still open.
    #[error("cannot pool an accumulator whose run is still open: call end_run first")]
    OtherOpen,
    /// A merge whose bond the accumulator did not see.
    #[error(
        "at t = {time:e} s body {id} merged, but no impact of its step names it: the accumulator reads merges through their bonds"
    )]
    UnknownParent {
        /// The merged body's stable id.
        id: u64,
        /// When [s].
        time: f64,
    },
    /// A body left a class without a merge or fragmentation message.
    #[error(
        "at t = {time:e} s body {id} left a class the accumulator counted empty: bodies were added or removed without a merge or fragmentation message"
    )]
    Untracked {
        /// The body's stable id.
        id: u64,
        /// When [s].
        time: f64,
    },
    /// A window outside 0 ≤ T0 < T1.
    #[error("--window: allowed 0 ≤ T0 < T1, finite T0 (got {start:e}:{end:e})")]
    Window {
        /// T0 asked for [s].
        start: f64,
        /// T1 asked for [s].
        end: f64,
    },
}

/// The time window impacts and exposure are counted in: start ≤ t < end [s].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Window {
    /// Start T0 [s], ≥ 0 and finite.
    pub start: f64,
    /// `f64::INFINITY` for "to the end of the run".
    pub end: f64,
}

impl Default for Window {
    fn default() -> Self {
        Self {
            start: 0.0,
            end: f64::INFINITY,
        }
    }
}

impl Window {
    /// The window [start, end) [s]; refused unless 0 ≤ start < end, start finite.
    pub fn new(start: f64, end: f64) -> Result<Self, KernelError> {
        if start.is_finite() && start >= 0.0 && end > start {
            Ok(Self { start, end })
        } else {
            Err(KernelError::Window { start, end })
        }
    }
    #[inline]
    fn contains(&self, t: f64) -> bool {
        self.start <= t && t < self.end
    }
    /// Length of [a, b] inside the window.
    #[inline]
    fn overlap(&self, a: f64, b: f64) -> f64 {
        (b.min(self.end) - a.max(self.start)).max(0.0)
    }
}

/// Sums that pool by adding, over one run or many. Pair arrays are `classes²` long,
/// row-major, filled only for i ≤ j (the kernel is symmetric).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tally {
    /// Mass classes on the grid.
    pub classes: usize,
    /// Impacts per outcome ([`OUTCOMES`]), `3 × classes²`.
    pub counts: Vec<u64>,
    /// Exposure E_ij = (1/V)∫ pairs(i, j) dt [s/m³].
    pub exposure: Vec<f64>,
    /// Over every impact of the pair: Σ w, Σ w², Σ |Δv|, Σ |Δv|² with w the normal
    /// approach speed [m/s] and |Δv| = √(w² + tangential²).
    pub speeds: Vec<[f64; 4]>,
    /// Σ (m_a + m_b) over the pair's fragmenting impacts [kg].
    pub fragment_pair_mass: Vec<f64>,
    /// (i, j, k) → mass [kg] the pair's fragmenting impacts left in class k (the pieces,
    /// and a partner that did not break). Sparse: few triples ever occur.
    pub fragment_products: BTreeMap<(u32, u32, u32), f64>,
    /// Relative speed over all pairs, sampled: Σ ΔE, Σ ΔE ⟨|Δv|⟩, Σ ΔE ⟨π(b_a + b_b)²|Δv|⟩,
    /// ΔE [s/m³] the exposure of the pair accrued between two samples and ⟨·⟩ the mean
    /// of the two samples' averages (one, where the pair was present at only one).
    pub relative: Vec<[f64; 3]>,
    /// Pairs drawn for the relative-speed samples.
    pub relative_draws: Vec<u64>,
}

impl Tally {
    /// Zero sums on `classes` classes.
    pub fn new(classes: usize) -> Self {
        let pairs = classes * classes;
        Self {
            classes,
            counts: vec![0; 3 * pairs],
            exposure: vec![0.0; pairs],
            speeds: vec![[0.0; 4]; pairs],
            fragment_pair_mass: vec![0.0; pairs],
            fragment_products: BTreeMap::new(),
            relative: vec![[0.0; 3]; pairs],
            relative_draws: vec![0; pairs],
        }
    }

    /// Add `other` (same classes) to this.
    pub fn add(&mut self, other: &Tally) {
        let add = |a: &mut [f64], b: &[f64]| a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        self.counts
            .iter_mut()
            .zip(&other.counts)
            .for_each(|(x, y)| *x += y);
        add(&mut self.exposure, &other.exposure);
        for (x, y) in self.speeds.iter_mut().zip(&other.speeds) {
            add(x, y);
        }
        add(&mut self.fragment_pair_mass, &other.fragment_pair_mass);
        for (key, mass) in &other.fragment_products {
            *self.fragment_products.entry(*key).or_insert(0.0) += mass;
        }
        for (x, y) in self.relative.iter_mut().zip(&other.relative) {
            add(x, y);
        }
        self.relative_draws
            .iter_mut()
            .zip(&other.relative_draws)
            .for_each(|(x, y)| *x += y);
    }

    /// Impacts of all outcomes of pair index `p`.
    pub fn total(&self, p: usize) -> u64 {
        let pairs = self.classes * self.classes;
        self.counts[p] + self.counts[pairs + p] + self.counts[2 * pairs + p]
    }
}

/// Per-run second moments, for the across-run (across-seed) standard error of the
/// pooled ratio K = ΣC/ΣE: Σ_r C_r², Σ_r C_r E_r per outcome and for all outcomes
/// (index 3), and Σ_r E_r².
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunMoments {
    /// Σ_r C_r² per pair, per outcome and for all (4 × classes²).
    pub cc: Vec<f64>,
    /// Σ_r C_r E_r per pair, per outcome and for all (4 × classes²) [s/m³].
    pub ce: Vec<f64>,
    /// Σ_r E_r² per pair (classes²) [s²/m⁶].
    pub ee: Vec<f64>,
}

impl RunMoments {
    fn new(classes: usize) -> Self {
        let pairs = classes * classes;
        Self {
            cc: vec![0.0; 4 * pairs],
            ce: vec![0.0; 4 * pairs],
            ee: vec![0.0; pairs],
        }
    }
    fn add_run(&mut self, run: &Tally) {
        let pairs = run.classes * run.classes;
        for p in 0..pairs {
            let e = run.exposure[p];
            self.ee[p] += e * e;
            for o in 0..4 {
                let c = if o < 3 {
                    run.counts[o * pairs + p]
                } else {
                    run.total(p)
                } as f64;
                self.cc[o * pairs + p] += c * c;
                self.ce[o * pairs + p] += c * e;
            }
        }
    }
    fn add(&mut self, other: &RunMoments) {
        for (a, b) in [
            (&mut self.cc, &other.cc),
            (&mut self.ce, &other.ce),
            (&mut self.ee, &other.ee),
        ] {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
    }
}

/// How the relative speed of all pairs is sampled: at the window's start, every
/// 1/[`RESAMPLE_FRACTION`] of the bodies merged or fragmented, and at `times` evenly
/// spread times (for scenes whose population does not change).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sampling {
    /// Sample times per run, evenly spread over the window (cut at the run's end), beside
    /// the samples the merges and fragmentations call for.
    pub times: u32,
    /// Pairs drawn per pair of classes at each sample (uniformly, with replacement).
    pub pairs: u32,
}

/// The most sample times per run: the times are listed when a run begins and each is a
/// pass over the bodies (4e9 aborted allocating 32 GB).
pub const MAX_SPEED_SAMPLES: u32 = 1_000_000;

/// The most pairs drawn per pair of classes and sample: at [`MEMBERS_PER_CLASS`]² = 4096
/// every pair of the chosen subsets is taken once, so more draws give the same numbers
/// (4e9 hung drawing them one by one).
pub const MAX_SPEED_PAIRS: u32 = (MEMBERS_PER_CLASS * MEMBERS_PER_CLASS) as u32;

impl Sampling {
    /// Refuse more samples or pairs than a run can use, naming the flag and the range.
    pub fn check(&self) -> Result<(), String> {
        if self.times > MAX_SPEED_SAMPLES {
            return Err(format!(
                "--speed-samples {}: allowed 1 to {MAX_SPEED_SAMPLES} (each sample is a pass \
                 over the bodies; the times are listed, 8 B each, when a run begins)",
                self.times
            ));
        }
        if self.pairs > MAX_SPEED_PAIRS {
            return Err(format!(
                "--speed-pairs {}: allowed 1 to {MAX_SPEED_PAIRS} (at {MAX_SPEED_PAIRS} = \
                 {MEMBERS_PER_CLASS}² every pair of the {MEMBERS_PER_CLASS} bodies drawn per \
                 class is taken once: more draws change nothing)",
                self.pairs
            ));
        }
        Ok(())
    }
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            times: 16,
            pairs: 256,
        }
    }
}

/// Counts and exposure on a mass grid, over any number of runs (docs/outputs.md,
/// "agglo kernel"). Per run: [`Accumulator::begin`] before the first step,
/// [`Accumulator::observe`] after every step, [`Accumulator::end_run`] at the end.
/// Pool with [`Accumulator::merge`]; estimate with [`super::Estimate::of`].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Accumulator {
    /// The mass classes counted on.
    pub grid: MassGrid,
    /// The time window counted in [s].
    pub window: Window,
    /// How relative speeds over all pairs are sampled.
    pub sampling: Sampling,
    /// Everything pooled so far.
    pub pooled: Tally,
    /// Per-run second moments, for the across-run standard errors.
    pub moments: RunMoments,
    /// Runs pooled.
    pub runs: u64,
    /// The runs' seeds, in pooling order.
    pub seeds: Vec<u64>,
    #[serde(skip)]
    live: Option<Box<Live>>,
}

/// The state of the run being observed.
#[derive(Debug, Clone)]
struct Live {
    tally: Tally,
    /// Bodies per class now, and when each count last changed [s].
    count: Vec<u64>,
    /// The classes with at least one body, ascending.
    occupied: Vec<usize>,
    since: Vec<f64>,
    /// The bodies merges made in the step being read, and their masses [kg].
    merged: Vec<(u64, f64)>,
    /// 1/V [1/m³].
    per_volume: f64,
    seed: u64,
    sample_times: Vec<f64>,
    next_sample: usize,
    /// Bodies now, at the last relative-speed sample, and the merges and fragmentations
    /// since it.
    bodies: u64,
    bodies_at_sample: u64,
    events_since_sample: u64,
    /// Samples taken (each draws from a generator of its own).
    samples_taken: u64,
    /// The last sample, waiting for the exposure of the interval it opens.
    pending: Option<SpeedSample>,
}

/// One relative-speed sample: per pair of classes present, the mean |Δv| and geometric
/// kernel of the draws, and the exposure at the sample (to weigh the interval after it).
#[derive(Debug, Clone)]
struct SpeedSample {
    /// (pair index, ⟨|Δv|⟩ [m/s], ⟨π(b_a + b_b)²|Δv|⟩ [m³/s]).
    means: Vec<(usize, f64, f64)>,
    exposure_at: Vec<f64>,
}

impl Accumulator {
    /// An empty accumulator on `grid`, counting in `window`.
    pub fn new(grid: MassGrid, window: Window, sampling: Sampling) -> Self {
        let classes = grid.classes();
        Self {
            grid,
            window,
            sampling,
            pooled: Tally::new(classes),
            moments: RunMoments::new(classes),
            runs: 0,
            seeds: Vec::new(),
            live: None,
        }
    }

    /// Mass classes on the grid.
    pub fn classes(&self) -> usize {
        self.grid.classes()
    }

    /// Start observing a run, before its first step: reads the bodies once.
    pub fn begin(&mut self, sim: &Simulation) -> Result<(), KernelError> {
        if self.live.is_some() {
            return Err(KernelError::RunOpen);
        }
        let world = sim.world();
        for (name, present) in [
            (
                "impacts",
                world.contains_resource::<Messages<ImpactMessage>>(),
            ),
            (
                "merges",
                world.contains_resource::<Messages<MergeMessage>>(),
            ),
            (
                "fragmentations",
                world.contains_resource::<Messages<FragmentMessage>>(),
            ),
        ] {
            if !present {
                return Err(KernelError::NotSubscribed(name));
            }
        }
        let now = sim.clock().time;
        let bodies = sim.bodies();
        let masses: Vec<f64> = bodies.iter().map(|b| b.mass).collect();
        self.grid.check_covers(&masses, now)?;
        let classes = self.classes();
        let mut count = vec![0u64; classes];
        for b in &bodies {
            // Covered: checked just above.
            let k = self.grid.class_of(b.mass).unwrap_or(0);
            count[k] += 1;
        }
        let side = world.resource::<BoxGeometry>().side();
        let end = world.resource::<TimeControl>().end.min(self.window.end);
        let span = (end - self.window.start).max(0.0);
        let n = self.sampling.times as usize;
        let sample_times = (0..n)
            .map(|s| self.window.start + span * (s as f64 + 0.5) / n as f64)
            .filter(|&t| t >= now)
            .collect();
        self.live = Some(Box::new(Live {
            tally: Tally::new(classes),
            occupied: (0..classes).filter(|&k| count[k] > 0).collect(),
            count,
            since: vec![now; classes],
            merged: Vec::new(),
            per_volume: 1.0 / (side * side * side),
            seed: sim.info().seed,
            sample_times,
            next_sample: 0,
            bodies: bodies.len() as u64,
            bodies_at_sample: bodies.len() as u64,
            events_since_sample: 0,
            samples_taken: 0,
            pending: None,
        }));
        if self.window.contains(now)
            && let Some(live) = self.live.as_deref_mut()
        {
            // The first relative-speed sample: the state the window opens on.
            live.sample(&self.grid, self.window, self.sampling, sim, now);
        }
        Ok(())
    }

    /// After a step: bin the step's impacts, move the class counts of its merges and
    /// fragmentations (adding the exposure up to each), and sample relative speeds when
    /// a sample time has passed.
    pub fn observe(&mut self, sim: &Simulation) -> Result<(), KernelError> {
        let window = self.window;
        let sampling = self.sampling;
        let grid = &self.grid;
        let live = self.live.as_deref_mut().ok_or(KernelError::NotBegun)?;
        let mut impacts = sim.step_messages::<ImpactMessage>().peekable();
        let mut merges = sim.step_messages::<MergeMessage>().peekable();
        let mut fragments = sim.step_messages::<FragmentMessage>().peekable();
        if impacts.peek().is_some() {
            live.impacts(grid, window, impacts, sim)?;
        }
        if merges.peek().is_some() || fragments.peek().is_some() {
            // Merges first: a body a bond made can fragment in the same step.
            // A merge names its parents, not their masses: those are in the bond's
            // impact message of this step, or — a chain of bonds in one step — the
            // mass of the merge that made the parent. No per-body table is kept.
            live.merged.clear();
            for m in merges {
                for parent in m.parents {
                    let mass = live
                        .merged
                        .iter()
                        .rev()
                        .find(|(id, _)| *id == parent)
                        .map(|&(_, mass)| mass)
                        .or_else(|| {
                            sim.step_messages::<ImpactMessage>().find_map(|i| {
                                (i.id_a == parent)
                                    .then_some(i.mass_a)
                                    .or((i.id_b == parent).then_some(i.mass_b))
                            })
                        })
                        .ok_or(KernelError::UnknownParent {
                            id: parent,
                            time: m.time,
                        })?;
                    live.remove(grid, window, parent, mass, m.time)?;
                }
                live.add(grid, window, m.child, m.mass, m.time)?;
                live.merged.push((m.child, m.mass));
                live.events_since_sample += 1;
            }
            for f in fragments {
                live.remove(grid, window, f.parent, f.parent_mass, f.time)?;
                // As the engine splits it (Split::ByMass): the same bits.
                let piece = f.parent_mass / f.children.len() as f64;
                for &child in &f.children {
                    live.add(grid, window, child, piece, f.time)?;
                }
                live.events_since_sample += 1;
            }
        }
        let now = sim.clock().time;
        let timed = live.next_sample < live.sample_times.len()
            && now >= live.sample_times[live.next_sample];
        if timed || live.resample_due(window, now) {
            while live.next_sample < live.sample_times.len()
                && now >= live.sample_times[live.next_sample]
            {
                live.next_sample += 1;
            }
            live.sample(grid, window, sampling, sim, now);
        }
        Ok(())
    }

    /// Bodies per class now, in the run being observed (`None` between runs).
    pub fn live_counts(&self) -> Option<&[u64]> {
        self.live.as_deref().map(|l| &l.count[..])
    }

    /// End the run: add the exposure up to the current time and pool the run.
    pub fn end_run(&mut self, sim: &Simulation) -> Result<(), KernelError> {
        let mut live = self.live.take().ok_or(KernelError::NotBegun)?;
        let now = sim.clock().time;
        if live.pending.is_some() && now <= self.window.end {
            // A last sample closes the last interval at the run's end.
            live.sample(&self.grid, self.window, self.sampling, sim, now);
        }
        live.close_interval(self.window, now, &[]);
        self.moments.add_run(&live.tally);
        self.pooled.add(&live.tally);
        self.runs += 1;
        self.seeds.push(live.seed);
        Ok(())
    }

    /// Pool `other` (closed, same grid) into this: sums add, so the result is that of
    /// one accumulator that saw both's runs. The windows may differ (pooling windows of
    /// one run is how a window is split).
    pub fn merge(&mut self, other: &Accumulator) -> Result<(), KernelError> {
        if other.grid.edges != self.grid.edges {
            return Err(KernelError::GridMismatch(
                self.grid.spec.clone(),
                other.grid.spec.clone(),
            ));
        }
        if other.live.is_some() {
            return Err(KernelError::OtherOpen);
        }
        self.pooled.add(&other.pooled);
        self.moments.add(&other.moments);
        self.runs += other.runs;
        self.seeds.extend_from_slice(&other.seeds);
        Ok(())
    }
}

/// Row-major index of the unordered pair (i, j).
#[inline]
fn pair(classes: usize, i: usize, j: usize) -> usize {
    let (lo, hi) = if i <= j { (i, j) } else { (j, i) };
    lo * classes + hi
}

impl Live {
    /// Add the exposure of pair (i, j), i ≤ j, from the later of their last changes to `now`.
    #[inline]
    fn flush_pair(&mut self, window: Window, i: usize, j: usize, now: f64) {
        let from = self.since[i].max(self.since[j]);
        let dt = window.overlap(from, now);
        if dt > 0.0 {
            let (ni, nj) = (self.count[i] as f64, self.count[j] as f64);
            let pairs = if i == j {
                0.5 * ni * (ni - 1.0)
            } else {
                ni * nj
            };
            let classes = self.count.len();
            self.tally.exposure[i * classes + j] += pairs * dt * self.per_volume;
        }
    }

    /// Class `k`'s count is about to change at `now`: bring every pair with it up to now.
    /// A pair with an empty class has no pairs, so it is skipped (exactly: it adds 0):
    /// on a DustPy grid most classes are empty at any time (merge 1e6 on 106 classes:
    /// this cut the accumulator's CPU by about half), and only the occupied classes are
    /// visited (each pair is its own sum, so the order changes no bit).
    fn touch(&mut self, window: Window, k: usize, now: f64) {
        if self.count[k] > 0 {
            for x in 0..self.occupied.len() {
                let j = self.occupied[x];
                if j == k && self.count[k] < 2 {
                    continue;
                }
                let (lo, hi) = if k <= j { (k, j) } else { (j, k) };
                self.flush_pair(window, lo, hi, now);
            }
        }
        self.since[k] = now;
    }

    /// Body `id` of mass `mass` leaves its class at `now`.
    fn remove(
        &mut self,
        grid: &MassGrid,
        window: Window,
        id: u64,
        mass: f64,
        now: f64,
    ) -> Result<(), KernelError> {
        let k = class_at(grid, id, mass, now)?;
        if self.count[k] == 0 {
            // Only bodies made or removed without a message (an extension's) lead here.
            return Err(KernelError::Untracked { id, time: now });
        }
        self.touch(window, k, now);
        self.count[k] -= 1;
        if self.count[k] == 0
            && let Ok(x) = self.occupied.binary_search(&k)
        {
            self.occupied.remove(x);
        }
        self.bodies -= 1;
        Ok(())
    }

    /// Body `id` of mass `mass` joins its class at `now`.
    fn add(
        &mut self,
        grid: &MassGrid,
        window: Window,
        id: u64,
        mass: f64,
        now: f64,
    ) -> Result<(), KernelError> {
        let k = class_at(grid, id, mass, now)?;
        self.touch(window, k, now);
        self.count[k] += 1;
        if self.count[k] == 1
            && let Err(x) = self.occupied.binary_search(&k)
        {
            self.occupied.insert(x, k);
        }
        self.bodies += 1;
        Ok(())
    }

    /// Bin the step's impacts (and, for fragmenting ones, where their mass went).
    fn impacts<'a>(
        &mut self,
        grid: &MassGrid,
        window: Window,
        impacts: impl Iterator<Item = &'a ImpactMessage>,
        sim: &Simulation,
    ) -> Result<(), KernelError> {
        let classes = grid.classes();
        let pairs = classes * classes;
        let any_fragments = sim.step_messages::<FragmentMessage>().next().is_some();
        for m in impacts {
            if !window.contains(m.time) {
                continue;
            }
            let i = class_at(grid, m.id_a, m.mass_a, m.time)?;
            let j = class_at(grid, m.id_b, m.mass_b, m.time)?;
            let p = pair(classes, i, j);
            // At most one impact per body per step, so a fragmentation of either body
            // this step is this impact's doing (as the collision log reads it).
            let broken = |id: u64| {
                any_fragments
                    .then(|| {
                        sim.step_messages::<FragmentMessage>()
                            .find(|f| f.parent == id)
                    })
                    .flatten()
            };
            let (frag_a, frag_b) = (broken(m.id_a), broken(m.id_b));
            let outcome = if frag_a.is_some() || frag_b.is_some() {
                FRAGMENT
            } else {
                match m.outcome {
                    ImpactOutcome::Bond => BOND,
                    ImpactOutcome::Bounce => BOUNCE,
                }
            };
            self.tally.counts[outcome * pairs + p] += 1;
            let w = m.normal_speed;
            let dv2 = w * w + m.tangential_speed * m.tangential_speed;
            let s = &mut self.tally.speeds[p];
            s[0] += w;
            s[1] += w * w;
            s[2] += dv2.sqrt();
            s[3] += dv2;
            if outcome == FRAGMENT {
                let (lo, hi) = (i.min(j) as u32, i.max(j) as u32);
                self.tally.fragment_pair_mass[p] += m.mass_a + m.mass_b;
                // A bonded pair merged into the body of the smaller id, id_a.
                let merged = sim
                    .step_messages::<MergeMessage>()
                    .any(|g| g.parents == [m.id_a, m.id_b]);
                let mut put = |mass: f64, k: usize| {
                    *self
                        .tally
                        .fragment_products
                        .entry((lo, hi, k as u32))
                        .or_insert(0.0) += mass;
                };
                for f in [frag_a, frag_b].into_iter().flatten() {
                    let piece = f.parent_mass / f.children.len() as f64;
                    let k = class_at(grid, f.parent, piece, f.time)?;
                    put(f.parent_mass, k);
                }
                if frag_a.is_none() {
                    put(m.mass_a, i);
                }
                if frag_b.is_none() && !merged {
                    put(m.mass_b, j);
                }
            }
        }
        Ok(())
    }

    /// Whether the population changed enough since the last sample for another (or, in
    /// the window with none taken yet, whether this is the first).
    fn resample_due(&self, window: Window, now: f64) -> bool {
        if !window.contains(now) {
            return false;
        }
        if self.pending.is_none() {
            return true;
        }
        self.events_since_sample > 0
            && self.events_since_sample * RESAMPLE_FRACTION >= self.bodies_at_sample
    }

    /// Take a relative-speed sample now: close the interval since the last one and open
    /// the next.
    fn sample(
        &mut self,
        grid: &MassGrid,
        window: Window,
        sampling: Sampling,
        sim: &Simulation,
        now: f64,
    ) {
        let means = self.draw_relative_speeds(grid, sampling, sim);
        self.close_interval(window, now, &means);
        self.pending = Some(SpeedSample {
            means,
            exposure_at: self.tally.exposure.clone(),
        });
        self.bodies_at_sample = self.bodies;
        self.events_since_sample = 0;
        self.samples_taken += 1;
    }

    /// Bring every pair's exposure up to `now`, and add the pending sample's interval to
    /// the relative-speed sums: each pair's exposure accrued since that sample times the
    /// mean of its average there and in `next` (the sample now; empty at the run's end).
    fn close_interval(&mut self, window: Window, now: f64, next: &[(usize, f64, f64)]) {
        let classes = self.count.len();
        for i in 0..classes {
            for j in i..classes {
                if self.count[i] > 0 && self.count[j] > 0 {
                    self.flush_pair(window, i, j, now);
                }
            }
        }
        self.since.fill(now);
        let Some(pending) = self.pending.take() else {
            return;
        };
        let exposure = &self.tally.exposure;
        let accrued = |p: usize| exposure[p] - pending.exposure_at[p];
        let mut at_next = vec![None; classes * classes];
        for &(p, speed, geometric) in next {
            at_next[p] = Some((speed, geometric));
        }
        let add = |p: usize, speed: f64, geometric: f64, relative: &mut Vec<[f64; 3]>| {
            let de = accrued(p);
            if de > 0.0 {
                let r = &mut relative[p];
                r[0] += de;
                r[1] += de * speed;
                r[2] += de * geometric;
            }
        };
        let mut relative = std::mem::take(&mut self.tally.relative);
        let mut in_pending = vec![false; classes * classes];
        for &(p, speed, geometric) in &pending.means {
            in_pending[p] = true;
            match at_next[p] {
                Some((s, g)) => add(p, 0.5 * (speed + s), 0.5 * (geometric + g), &mut relative),
                None => add(p, speed, geometric, &mut relative),
            }
        }
        for &(p, speed, geometric) in next {
            if !in_pending[p] {
                add(p, speed, geometric, &mut relative);
            }
        }
        self.tally.relative = relative;
    }

    /// Draw pairs of bodies of every pair of classes present and average |Δv| and the
    /// geometric kernel π(b_a + b_b)²|Δv| over them: (pair index, means) per pair.
    ///
    /// The pairs are drawn from a uniform random subset of each class: the
    /// [`MEMBERS_PER_CLASS`] bodies of smallest hash(seed, sample, id). That subset does
    /// not depend on the order the bodies are stored in (so the draws are the same on any
    /// thread count), and finding it is one pass over the bodies' ids and masses, without
    /// copying and sorting all bodies at every sample (which cost more than the rest of
    /// the accumulator at N = 1e5); only the chosen bodies are brought to the current time.
    fn draw_relative_speeds(
        &mut self,
        grid: &MassGrid,
        sampling: Sampling,
        sim: &Simulation,
    ) -> Vec<(usize, f64, f64)> {
        let classes = grid.classes();
        let members = self.chosen_members(grid, sim);
        // A generator of its own per run and sample (splitmix64 over a counter): the
        // draws depend on nothing but the seed, the sample and the bodies.
        let mut state = derive_seed(&[self.seed, 0x6B65_726E, self.samples_taken]);
        let mut draw = |n: usize| {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            // Multiply-shift: uniform enough for n ≪ 2^32.
            (((splitmix64(state) >> 32) * n as u64) >> 32) as usize
        };
        let nonempty: Vec<usize> = (0..classes).filter(|&k| !members[k].is_empty()).collect();
        let mut means = Vec::new();
        for (x, &i) in nonempty.iter().enumerate() {
            for &j in &nonempty[x..] {
                let (a, b) = (&members[i], &members[j]);
                if i == j && a.len() < 2 {
                    continue;
                }
                let (mut speed, mut geometric) = (0.0, 0.0);
                let mut add = |u: &BodyState, v: &BodyState| {
                    let dv = (u.velocity - v.velocity).length();
                    let sigma = u.radius + v.radius;
                    speed += dv;
                    geometric += std::f64::consts::PI * sigma * sigma * dv;
                };
                let distinct = if i == j {
                    a.len() * (a.len() - 1) / 2
                } else {
                    a.len() * b.len()
                };
                let drawn = if distinct <= sampling.pairs as usize {
                    // Few bodies (most classes late in a coarsening run): every pair once,
                    // the exact mean over the subset, for fewer operations than the draws.
                    for (x, u) in a.iter().enumerate() {
                        let partners = if i == j { &a[x + 1..] } else { &b[..] };
                        for v in partners {
                            add(u, v);
                        }
                    }
                    distinct
                } else {
                    for _ in 0..sampling.pairs {
                        let u = &a[draw(a.len())];
                        let v = if i == j {
                            // Another body of the same class.
                            let k = draw(a.len() - 1);
                            let v = &a[k];
                            if v.id == u.id { &a[a.len() - 1] } else { v }
                        } else {
                            &b[draw(b.len())]
                        };
                        add(u, v);
                    }
                    sampling.pairs as usize
                };
                if drawn == 0 {
                    continue;
                }
                let n = drawn as f64;
                let p = i * classes + j;
                means.push((p, speed / n, geometric / n));
                self.tally.relative_draws[p] += drawn as u64;
            }
        }
        means
    }

    /// Per class, up to [`MEMBERS_PER_CLASS`] bodies: those of smallest
    /// splitmix64(salt + id), in that order, brought to the current time.
    fn chosen_members(&self, grid: &MassGrid, sim: &Simulation) -> Vec<Vec<BodyState>> {
        let classes = grid.classes();
        let mut members = vec![Vec::new(); classes];
        let world = sim.world();
        let Some(mut light) =
            world.try_query_filtered::<(Entity, &ParticleId, &Mass), With<Particle>>()
        else {
            return members; // components never registered: no particles
        };
        let salt = derive_seed(&[self.seed, 0x6D65_6D62, self.samples_taken]);
        // Max-heaps of (key, id, entity): the largest kept key on top, to be displaced.
        let mut kept: Vec<BinaryHeap<(u64, u64, Entity)>> = vec![BinaryHeap::new(); classes];
        for (entity, id, mass) in light.iter(world) {
            let Some(k) = grid.class_of(mass.0) else {
                continue;
            };
            let key = splitmix64(salt.wrapping_add(id.0.wrapping_mul(0x9E37_79B9_7F4A_7C15)));
            let heap = &mut kept[k];
            if heap.len() < MEMBERS_PER_CLASS {
                heap.push((key, id.0, entity));
            } else if heap.peek().is_some_and(|top| (key, id.0) < (top.0, top.1)) {
                heap.pop();
                heap.push((key, id.0, entity));
            }
        }
        let Some(mut full) = world.try_query_filtered::<StoredBody, With<Particle>>() else {
            return members;
        };
        let lazy = world.resource::<LazyState>().0;
        let now = sim.clock().time;
        let clockwork = Clockwork::new(
            world.resource::<BoxGeometry>(),
            world.resource::<Material>(),
            world.resource::<Physics>(),
        )
        .with_field(world.get_resource::<Field>());
        for (k, heap) in kept.into_iter().enumerate() {
            for (_, _, entity) in heap.into_sorted_vec() {
                let Ok(body) = full.get(world, entity) else {
                    continue;
                };
                let state = body.state();
                members[k].push(if lazy {
                    state_at(&state, body.local_time.0, now, &clockwork)
                } else {
                    state
                });
            }
        }
        members
    }
}

/// The class of body `id` of mass `mass` at `time`, or the error naming it outside the grid.
fn class_at(grid: &MassGrid, id: u64, mass: f64, time: f64) -> Result<usize, KernelError> {
    grid.class_of(mass)
        .ok_or_else(|| outside(grid, time, id, mass))
}

fn outside(grid: &MassGrid, time: f64, id: u64, mass: f64) -> KernelError {
    KernelError::Grid(GridError::Outside {
        time,
        id,
        mass: grid.show(mass),
        range: grid.show_range(),
    })
}
