//! Scene-wide constants and run state, held as ECS resources.
//!
//! - the cooling law of a body of the scene's [`Material`] ([`CoolingLaw::for_body`]);
//!   the hardness law and its constants are re-exported from `laws/`;
//! - [`BoxGeometry`]: the periodic box (the scenario's `box` section itself);
//! - [`SimClock`], [`Counters`], [`EnergyLedger`], [`InvariantReport`]: run state;
//! - [`ContactList`], [`ImpactRecords`], [`StepEvents`]: data handed from one stage of
//!   the step to the next;
//! - [`SimRng`]: the single seeded generator of the scene.

use bevy_ecs::prelude::*;
use glam::DVec3;
use rand::SeedableRng;
use rand::rngs::StdRng;
use serde::{Deserialize, Serialize};

use crate::laws::cooling::CoolingLaw;
use crate::scene::Material;

pub use crate::laws::cooling::STEFAN_BOLTZMANN;
pub use crate::laws::hardness::{GAS_CONSTANT, HARDNESS_EXPONENT_LIMIT, hardness};
pub use crate::scene::BoxGeometry;

/// The cooling law of a body of the scene's material (docs/model.md §8).
impl CoolingLaw {
    /// The law for a sphere of mass `mass` [kg] and radius `radius` [m].
    pub fn for_body(material: &Material, mass: f64, radius: f64) -> Self {
        let area = 4.0 * std::f64::consts::PI * radius * radius;
        let mc = mass * material.C;
        Self {
            k_convection: material.hc * area / mc,
            k_radiation: STEFAN_BOLTZMANN * material.epsilon * area / mc,
            theta_gas: material.theta0,
            theta_far: material.theta_s,
        }
    }
}

/// Relative gap tolerance: g ≤ tol·(b_i + b_j) counts as touching (docs/model.md §4).
pub const CONTACT_TOLERANCE: f64 = 1e-9;

/// Simulated time and step bookkeeping.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SimClock {
    /// Simulated time t [s] at the start of the current step.
    pub time: f64,
    /// Δt [s] of the current step (set by the time-step system).
    pub dt: f64,
    /// Steps completed.
    pub step: u64,
    /// True when this step's Δt was clamped at Δt_min while a contact was due sooner.
    pub clamped_at_min: bool,
    /// True when the last step merged or fragmented bodies (which may then overlap legitimately).
    pub bodies_reshaped: bool,
    /// True when the last step pushed an overlapping bouncing pair apart (docs/model.md §5),
    /// which may push one of them into a third body.
    pub bodies_pushed: bool,
}

/// Event counters of the run (cheap, always on).
#[derive(Resource, Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Counters {
    /// Impacts resolved (bounces + bonds).
    pub impacts: u64,
    /// Impacts that bonded.
    pub bonds: u64,
    /// Impacts that bounced.
    pub bounces: u64,
    /// Bodies that fragmented.
    pub fragmentations: u64,
    /// Pieces created by fragmentation.
    pub fragments_created: u64,
    /// Fixed-point iterations summed over all impacts.
    pub fixed_point_iterations: u64,
    /// Bracketed-solver iterations summed over all impacts.
    pub fallback_iterations: u64,
    /// Impacts whose plain iteration did not converge and needed the bracketed fallback.
    pub fallbacks: u64,
    /// Impacts whose plain iteration did not converge (solver `plain` only: last iterate used).
    pub unconverged: u64,
    /// Contacts deferred to the next step because a body already had an impact.
    pub deferred_contacts: u64,
    /// Steps whose Δt was clamped at Δt_min although a contact was due sooner.
    pub clamped_steps: u64,
    /// Approaching pairs found overlapping beyond the contact tolerance (adaptive, c ≤ 1: a missed contact).
    pub overlap_violations: u64,
    /// Invariant checks that failed.
    pub invariant_violations: u64,
    /// Impacts the TC model made elastic (constant restitution law only, docs/model.md §5.4).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub collapse_elastic: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Event counts of the core (cheap, always on).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EventStats {
    /// Cell crossings processed.
    pub crossings: u64,
    /// Popped events found stale (a partner changed since the prediction).
    pub stale: u64,
    /// Body predictions made.
    pub predictions: u64,
    /// Pair contact times evaluated.
    pub pair_tests: u64,
    /// Approaching pairs found overlapping beyond rounding (missed contacts).
    pub deep_overlaps: u64,
    /// Times the slots were renumbered in Z-order.
    #[serde(default)]
    pub renumberings: u64,
}

/// Energy bookkeeping (docs/model.md §10): E = kinetic + Σ m C θ changes only by these,
/// and each of its two parts only by its own terms: Σ ½ m v² by the impact dissipation
/// and the force work, Σ m C θ by the dissipation, reaction heat, fracture energy,
/// cooling loss and external heat.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct EnergyLedger {
    /// Reaction heat added, Σ 2 α a_c over impacts [J].
    pub reaction_heat: f64,
    /// Fracture surface energy removed from heat, Σ δZ [J].
    pub fracture_energy: f64,
    /// Heat lost by cooling [J].
    pub cooling_loss: f64,
    /// Kinetic energy dissipated in impacts (turned into heat) [J].
    pub impact_dissipation: f64,
    /// Work of external forces [J]: the kinetic energy extensions changed through
    /// [`crate::bodies::Bodies`], Σ (½ m |v_after|² − ½ m |v_before|²) over
    /// every body they changed.
    #[serde(default)]
    pub force_work: f64,
    /// Σ |½ m |v_after|² − ½ m |v_before|²| over the same changes [J]: the kinetic energy
    /// forces moved in either direction, part of the kinetic ledger's scale (docs/model.md §10).
    #[serde(default)]
    pub force_work_turnover: f64,
    /// Heat added by extensions through [`crate::bodies::Bodies`],
    /// Σ m C (θ_after − θ_before) over every body they changed [J] (negative if they cool).
    #[serde(default)]
    pub external_heat: f64,
    /// Impulse of external forces [kg m/s]: the momentum extensions changed through
    /// [`crate::bodies::Bodies`], Σ m (v_after − v_before) over every body they changed.
    /// The momentum check compares P − P0 with it (docs/model.md §10).
    #[serde(default)]
    pub force_impulse: [f64; 3],
    /// Σ m |v_after − v_before| over the same changes [kg m/s]: the momentum forces moved,
    /// part of the momentum check's scale.
    #[serde(default)]
    pub force_impulse_turnover: f64,
    /// Heat the reading `impact.work_heat` adds beyond the dissipation [J]: with `twice`
    /// (P04 (6.10)) the dissipated energy counted a second time, i.e. created; with
    /// `none` minus the dissipation, which left the bodies instead of heating them.
    #[serde(default)]
    pub double_counted_heat: f64,
}

/// The first non-finite body state the checks met (stage 9), which ends the run with
/// [`crate::error::SimError::NonFinite`] at the end of the step: the step it was seen at
/// and what (the body's id, the quantity and its value). Not part of a restart
/// snapshot: a run stops at the first.
#[derive(Resource, Debug, Clone, PartialEq, Default)]
pub struct NonFiniteState {
    /// The step and the body, quantity and value of the first non-finite state seen.
    pub first: Option<(u64, String)>,
}

impl NonFiniteState {
    /// Note a body's state if any quantity is NaN or infinite (the first one only).
    pub fn check_body(&mut self, step: u64, id: u64, quantities: [(&str, f64); 9]) {
        if self.first.is_some() {
            return;
        }
        if let Some((what, x)) = quantities.iter().find(|(_, x)| !x.is_finite()) {
            self.first = Some((step, format!("body {id}: {what} = {x}")));
        }
    }
}

/// Reference totals at t = 0 and the worst invariant errors seen.
#[derive(Resource, Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct InvariantReport {
    /// Total mass at t = 0 [kg].
    pub initial_mass: f64,
    /// Total momentum at t = 0 [kg m/s].
    pub initial_momentum: [f64; 3],
    /// Kinetic plus thermal energy at t = 0 [J].
    pub initial_energy: f64,
    /// Σ m|v| at t = 0 [kg m/s]: the scale of momentum errors.
    pub momentum_scale: f64,
    /// Worst |M − M0| / M0.
    pub max_mass_error: f64,
    /// Worst |P − P0| / Σ m|v|.
    pub max_momentum_error: f64,
    /// Worst |E − E0 − ledger| / (E0 + Σ|ledger terms|), E = kinetic + thermal.
    pub max_energy_error: f64,
    /// Worst error of the kinetic ledger relative to its own scale (docs/model.md §10).
    pub max_kinetic_error: f64,
    /// Worst error of the thermal ledger relative to its own scale (docs/model.md §10).
    pub max_thermal_error: f64,
    /// First few violations, human readable.
    pub violations: Vec<String>,
}

/// One contact pair to resolve this step, found by contact detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The body with the smaller id.
    pub a: Entity,
    /// The body with the larger id.
    pub b: Entity,
    /// a's stable id (less than b's).
    pub id_a: u64,
    /// b's stable id.
    pub id_b: u64,
    /// Unit normal from a to b (towards the periodic image of b that is met).
    pub normal: DVec3,
    /// r_b − r_a for that image [m] (the minimum image unless the bodies are large).
    pub separation: DVec3,
    /// Gap at detection [m] (negative = overlap).
    pub gap: f64,
}

/// Contacts to resolve this step, in resolution order.
#[derive(Resource, Debug, Default)]
pub struct ContactList {
    /// The contacts, in resolution order.
    pub contacts: Vec<Contact>,
}

/// What one impact did to one body, for merging and fragmentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpactRecord {
    /// The first body.
    pub a: Entity,
    /// The second body.
    pub b: Entity,
    /// a's stable id.
    pub id_a: u64,
    /// b's stable id.
    pub id_b: u64,
    /// Unit normal from a to b.
    pub normal: DVec3,
    /// r_b − r_a of the image that was met [m].
    pub separation: DVec3,
    /// True when the pair bonded (to be merged).
    pub bonded: bool,
    /// Kinetic energy a lost in the pair's centre-of-mass frame [J].
    pub lost_a: f64,
    /// Kinetic energy b lost in the pair's centre-of-mass frame [J].
    pub lost_b: f64,
}

/// Impacts resolved this step.
#[derive(Resource, Debug, Default)]
pub struct ImpactRecords {
    /// One per impact, in resolution order.
    pub records: Vec<ImpactRecord>,
}

/// What happened to bodies this step, for the stages after it (the event core files
/// it; diagnostics check it). Cleared when the step closes.
#[derive(Resource, Debug, Default)]
pub struct StepEvents {
    /// Bodies changed this step, each with its contribution to the totals just before
    /// its first change (a body may appear more than once; the first entry counts).
    pub touched: Vec<(Entity, crate::totals::Totals)>,
    /// Bodies created (fragments).
    pub spawned: Vec<Entity>,
    /// Stable ids of bodies removed (merged away, fragmented).
    pub despawned: Vec<u64>,
    /// Event-core slots whose prediction was used up without the body changing.
    pub repredict: Vec<u32>,
    /// How many `touched` entries the event core has filed.
    pub filed: usize,
    /// How many `spawned` entries the event core has filed.
    pub filed_spawned: usize,
    /// How many `despawned` entries the event core has filed.
    pub filed_despawned: usize,
}

impl StepEvents {
    /// Record that `entity` is about to change; `before` is its contribution now.
    pub fn touch(&mut self, entity: Entity, before: crate::totals::Totals) {
        self.touched.push((entity, before));
    }

    /// Forget the step (when it closes).
    pub fn clear(&mut self) {
        self.touched.clear();
        self.spawned.clear();
        self.despawned.clear();
        self.repredict.clear();
        self.filed = 0;
        self.filed_spawned = 0;
        self.filed_despawned = 0;
    }
}

/// When force systems kick (`SimBuilder::add_force_systems`): every step (no interval
/// declared), or every declared interval h [s] (`SimBuilder::set_force_interval`): then
/// they run when the time since the last kick reaches h, acting over that time, and
/// steps land on the kick times, so between kicks bodies fly as the cores predict and
/// the event core re-predicts the kicked bodies once per interval, not once per event.
#[derive(Resource, Debug, Default, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ForceKicks {
    /// The declared interval h [s] (None: every step).
    pub interval: Option<f64>,
    /// Time of the last kick [s].
    pub last: f64,
    /// Kicks so far.
    pub kicks: u64,
}

impl ForceKicks {
    /// The time the next kick is due [s], if kicks follow a declared interval.
    pub fn next(&self) -> Option<f64> {
        self.interval.map(|h| self.last + h)
    }
}

/// True when bodies hold their state at their own [`crate::components::LocalTime`]
/// (the event core) rather than at the current time (the stepped core).
#[derive(Resource, Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct LazyState(pub bool);

/// Set when impacts changed velocities (or fragmentation the body set) this step, so the
/// time-step system must refresh contact detection's neighbour table before using it.
#[derive(Resource, Debug, Default, Clone, Copy)]
pub struct StateChanged(pub bool);

/// The scene's single random generator.
#[derive(Resource, Debug)]
pub struct SimRng(pub StdRng);

impl SimRng {
    /// The generator seeded with the scenario's `seed`.
    pub fn seeded(seed: u64) -> Self {
        SimRng(StdRng::seed_from_u64(seed))
    }
}

/// Stable ids for new bodies (fragments): taken in order from `next` up to `end`, a range
/// no body of the initial cloud holds. Ids are labels (any u64, docs/model.md §2): past
/// the largest given id when there is room there (0, 1, … N − 1 gives N, N + 1, …),
/// else from the widest gap between the given ids, so a fragment's id never repeats a
/// body's.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq)]
pub struct IdAllocator {
    /// The next id handed out.
    pub next: u64,
    /// One past the last id that may be handed out.
    pub end: u64,
}

impl IdAllocator {
    /// The allocator for a cloud holding `ids` (any order, distinct).
    pub fn after(ids: impl Iterator<Item = u64>) -> Self {
        let mut ids: Vec<u64> = ids.collect();
        match ids.iter().max() {
            None => Self {
                next: 0,
                end: u64::MAX,
            },
            Some(&max) if max < u64::MAX => Self {
                next: max + 1,
                end: u64::MAX,
            },
            Some(_) => {
                // The widest run of free ids: below the smallest, or between two.
                ids.sort_unstable();
                let mut best = (0, ids[0]);
                for w in ids.windows(2) {
                    if w[1] - w[0] - 1 > best.1 - best.0 {
                        best = (w[0] + 1, w[1]);
                    }
                }
                Self {
                    next: best.0,
                    end: best.1,
                }
            }
        }
    }

    /// The next free id (panics only past 2^64 / N fragments, which no run reaches).
    pub fn allocate(&mut self) -> u64 {
        // The range holds at least 2^64 / N ids: beyond any number of fragments a run
        // can make.
        assert!(self.next < self.end, "stable ids exhausted");
        let id = self.next;
        self.next += 1;
        id
    }
}
