//! Scenario files: the JSON description of one run, its validation, and the
//! JSON Schema printed by `agglo schema`.
//!
//! A scenario fully describes a run (box, cloud, material, impact model, time
//! control, physics toggles, seed, output). Parsing reports the field path of a
//! type error or unknown field (via `serde_path_to_error`); [`Scenario::validate`]
//! then checks every range and names the field and the allowed range. Symbols
//! follow docs/model.md §1: all values SI.

use std::path::Path;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{ScenarioError, ValidationIssue};

/// One complete run description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, used in summaries and recordings.
    pub name: String,
    /// Free text: what the scene is for.
    #[serde(default)]
    pub description: String,
    /// Seed of the scene's single random generator (cloud placement and velocities).
    pub seed: u64,
    /// The periodic control volume.
    #[serde(rename = "box")]
    pub domain: Domain,
    pub cloud: Cloud,
    pub material: Material,
    #[serde(default)]
    pub impact: ImpactModel,
    pub time: TimeControl,
    #[serde(default)]
    pub physics: Physics,
    #[serde(default)]
    pub diagnostics: Diagnostics,
    #[serde(default)]
    pub output: Output,
}

/// The periodic cube [−D, D]³.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Domain {
    /// Half-width D [m] of the periodic cube [−D, D]³.
    pub half_width: f64,
}

/// The initial cloud of N equal primary spheres (docs/model.md §2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Cloud {
    /// Number of primary particles N.
    pub count: usize,
    /// Primary size: give exactly one of `radius` [m] or `size_ratio`
    /// s = d / (V/N)^(1/3) (volume fraction (π/6) s³).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Size ratio s = 2b / (V/N)^(1/3), 0 < s < 0.9 (P04's L and P02's s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size_ratio: Option<f64>,
    /// Mean velocity v̄ [m/s].
    #[serde(default)]
    pub v_mean: [f64; 3],
    /// Relative velocity amplitudes v_rel [m/s] per component.
    pub v_rel: [f64; 3],
    /// Distribution of λ_i per component: `symmetric` = U[−1, 1] (P04), `positive` = U[0, 1] (P02).
    #[serde(default)]
    pub velocity_distribution: VelocityDistribution,
    /// Explicit bodies instead of a random cloud (for set-ups such as a head-on pair):
    /// when given, its length must equal `count`, and `v_mean`/`v_rel` are ignored.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<PlacedBody>,
}

/// One explicitly placed body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlacedBody {
    /// Centre [m], inside [−D, D]³.
    pub position: [f64; 3],
    /// Velocity [m/s].
    pub velocity: [f64; 3],
    /// Primary grains in the body (mass = primaries · m_primary), ≥ 1.
    #[serde(default = "one")]
    pub primaries: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum VelocityDistribution {
    /// λ ~ U[−1, 1] per component (P04).
    #[default]
    Symmetric,
    /// λ ~ U[0, 1] per component (P02).
    Positive,
}

/// One material per scene (docs/model.md §1). Symbols as in docs/model.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(non_snake_case)]
pub struct Material {
    /// Density ρ [kg/m³].
    pub rho: f64,
    /// Base hardness H0 [Pa].
    pub H0: f64,
    /// Heat capacity C [J/(kg K)].
    pub C: f64,
    /// Activation energy Q [J/mol] (P02's U); 0 disables thermal softening.
    #[serde(default)]
    pub Q: f64,
    /// Reaction constant α [J/m²] (P02's ϑ): heat released per unit contact area per impact.
    #[serde(default)]
    pub alpha: f64,
    /// Surface energy γ [J/m²] for fragmentation; `null` (or absent) = ∞ = no fragmentation.
    #[serde(default)]
    pub gamma: Option<f64>,
    /// Friction coefficient μ0.
    #[serde(default)]
    pub mu0: f64,
    /// Emissivity ε, 0 ≤ ε ≤ 1.
    #[serde(default)]
    pub epsilon: f64,
    /// Convection coefficient hc [W/(m² K)].
    #[serde(default)]
    pub hc: f64,
    /// Gas temperature θ0 [K], also the initial particle temperature.
    pub theta0: f64,
    /// Far-field radiation temperature θs [K].
    #[serde(default)]
    pub theta_s: f64,
}

/// The impact/heat solve (docs/model.md §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImpactModel {
    /// Contact-area fraction at full rebound (e = 1), 0 ≤ a0 ≤ af.
    pub a0: f64,
    /// Contact-area fraction at adhesion (e = 0), a0 ≤ af ≤ 1.
    pub af: f64,
    /// Impact-duration scale β (P02's k), > 0.
    pub beta: f64,
    /// Impact-duration law: `p04` (P04 (4.10)) or `p02` (P02 (12)).
    #[serde(default)]
    pub duration: DurationLaw,
    /// μ = μ0 (1 − e) when true (P02), μ = μ0 otherwise (P04).
    #[serde(default)]
    pub friction_scales_with_adhesion: bool,
    /// Relative tolerance TOL of the fixed point: |e_{K+1} − e_K| ≤ TOL·e_K (+ an absolute floor).
    #[serde(default = "default_solver_tol")]
    pub tol: f64,
    /// Plain fixed-point iterations before the bracketed fallback takes over.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: u32,
    /// Solver: `safeguarded` (papers' iteration, then bracketed fallback; default) or
    /// `plain` (the papers' iteration only; non-convergence is counted, the last iterate used).
    #[serde(default)]
    pub solver: SolverKind,
    /// Reading: which hardness a pair bonds against in G(e) (docs/model.md §5.1 step 7):
    /// `min` (the softer body governs, P04's footnote to (3.1); default), `harmonic`,
    /// `arithmetic` (means of the two) or `max` (both surfaces must yield).
    #[serde(default, skip_serializing_if = "is_default")]
    pub pair_hardness: PairHardness,
    /// Reading: `sticking` caps the friction impulse where sliding stops (default), `none`
    /// applies the papers' full Coulomb impulse, which can reverse sliding and create
    /// kinetic energy (docs/model.md §5.1 step 5).
    #[serde(default, skip_serializing_if = "is_default")]
    pub friction_cap: FrictionCap,
    /// Reading: `fixed_point` bonds only when e* = 0 (default); `any_iterate` is P02 (20),
    /// which bonds as soon as one iterate of the papers' iteration from e0 = 0 presses at
    /// ≥ 2H (docs/model.md §5.3).
    #[serde(default, skip_serializing_if = "is_default")]
    pub bond_test: BondTest,
    /// Reading: how a bouncing pair that overlaps is separated: `normal` (along n̂,
    /// mass-weighted, centre of mass fixed; default) or `velocities` (P02 (8): each body
    /// moves b(1 − δ) along its own outgoing velocity, δ = |r_ij|/(b_i + b_j)).
    #[serde(default, skip_serializing_if = "is_default")]
    pub separation: Separation,
    /// Reading: `once` heats the pair by its kinetic-energy loss W (P02 (14)–(17); default);
    /// `twice` is P04 (6.10), which adds the deformation work δW — the same dissipated
    /// energy — on top, so the pair is heated by W more (docs/model.md §5.1 step 6).
    #[serde(default, skip_serializing_if = "is_default")]
    pub work_heat: WorkHeat,
}

/// How often the dissipated energy heats the pair (docs/model.md §5.1 step 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum WorkHeat {
    /// W once, split equally (P02 (14)–(17)).
    #[default]
    Once,
    /// W twice: δK plus the deformation work δW of P04 (4.7)–(4.9), (6.10).
    Twice,
}

fn is_default<T: Default + PartialEq>(x: &T) -> bool {
    *x == T::default()
}

/// Which hardness a pair bonds against (docs/model.md §5.1 step 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PairHardness {
    /// min(H_i, H_j): the softer body governs (P04, footnote to (3.1) and §6(b)).
    #[default]
    Min,
    /// 2 H_i H_j / (H_i + H_j).
    Harmonic,
    /// (H_i + H_j) / 2.
    Arithmetic,
    /// max(H_i, H_j): both surfaces must yield.
    Max,
}

/// Whether the tangential (friction) impulse is capped (docs/model.md §5.1 step 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FrictionCap {
    /// Capped at the impulse m_red |v_ti − v_tj| that stops the sliding.
    #[default]
    Sticking,
    /// The papers' uncapped impulse μ Ī δτ (P04 (4.17), P02 (7)); may create energy.
    None,
}

/// When a pair bonds (docs/model.md §5.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BondTest {
    /// Only when the fixed point itself is e* = 0.
    #[default]
    FixedPoint,
    /// P02 (20): when any iterate of the papers' iteration from e0 = 0 reaches P ≥ 2H.
    AnyIterate,
}

/// How an overlapping bouncing pair is separated (docs/model.md §5.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Separation {
    /// Along n̂ to touching, each body in inverse proportion to its mass.
    #[default]
    Normal,
    /// P02 (8): r_i += b_i (1 − δ) v_i/|v_i|, and the same for j.
    Velocities,
}

fn default_solver_tol() -> f64 {
    1e-12
}
fn default_max_iterations() -> u32 {
    100
}

impl Default for ImpactModel {
    fn default() -> Self {
        Self {
            a0: 0.0,
            af: 1.0,
            beta: 1.0,
            duration: DurationLaw::P04,
            friction_scales_with_adhesion: false,
            tol: default_solver_tol(),
            max_iterations: default_max_iterations(),
            solver: SolverKind::Safeguarded,
            pair_hardness: PairHardness::Min,
            friction_cap: FrictionCap::Sticking,
            bond_test: BondTest::FixedPoint,
            separation: Separation::Normal,
            work_heat: WorkHeat::Once,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DurationLaw {
    /// δτ = (1 + e) β min(b) / ((v_in − v_jn)/2)  (P04 (4.10)).
    #[default]
    P04,
    /// δτ = 2 β min(b) / ((1 + e)|v_in − v_jn|)  (P02 (12)).
    P02,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// The papers' fixed-point iteration, with a bracketed fallback that cannot fail.
    #[default]
    Safeguarded,
    /// The papers' fixed-point iteration alone (for stability studies).
    Plain,
    /// Reading: the closed form's smaller root as the answer, no iteration — the
    /// quadratic of docs/model.md §5.2 with the pre-impact hardness (exact without
    /// softening).
    ClosedForm,
    /// Reading: the same with P04 (4.14)'s coefficient c1 as printed, which carries a
    /// spurious λ (docs/model.md §14); `p04` duration law only.
    ClosedFormPrinted,
}

/// End time and step control (docs/model.md §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeControl {
    /// End time T [s].
    pub end: f64,
    /// Step-size control.
    #[serde(default)]
    pub stepping: Stepping,
    /// Hard cap on the number of steps (a run that reaches it stops with an error).
    #[serde(default = "default_max_steps")]
    pub max_steps: u64,
    /// Which core advances the scene (docs/model.md §4): `auto` picks the event core
    /// whenever the scene allows it.
    #[serde(default, skip_serializing_if = "Core::is_auto")]
    pub core: Core,
}

/// The two ways of advancing a scene (docs/model.md §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Core {
    /// The event core for adaptive stepping with c = 1, the `all` contact rule and
    /// non-explicit cooling; the stepped core otherwise.
    #[default]
    Auto,
    /// Event-driven: every step lands on the next contact, costing O(k log N).
    Events,
    /// The event core predicting every pair through every image: O(N²) per event.
    /// A reference for tests, not for production runs.
    EventsBruteForce,
    /// Every stage visits every body each step (fixed Δt, c ≠ 1, the papers' rules).
    Stepped,
}

impl Core {
    fn is_auto(&self) -> bool {
        *self == Core::Auto
    }
}

fn default_max_steps() -> u64 {
    50_000_000
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Stepping {
    /// Adaptive Δt = clamp(c·t_c, Δt_min, min(Δt_max, skin / (2 v_max))).
    Adaptive {
        /// Step factor c: 1 lands exactly on the next contact; > 1 trades accuracy for speed.
        #[serde(default = "one")]
        step_factor: f64,
        /// Lower bound Δt_min [s].
        #[serde(default = "default_dt_min")]
        dt_min: f64,
        /// Upper bound Δt_max [s].
        #[serde(default = "default_dt_max")]
        dt_max: f64,
        /// Neighbour-search margin, as a multiple of the primary radius b0.
        #[serde(default = "default_skin")]
        skin: f64,
    },
    /// Fixed Δt [s]; contacts are found only as overlaps at step ends (pairs may tunnel).
    Fixed { dt: f64 },
}

fn one() -> f64 {
    1.0
}
fn default_dt_min() -> f64 {
    1e-8
}
fn default_dt_max() -> f64 {
    1e-3
}
fn default_skin() -> f64 {
    // Measured on paper2004_best: 0.25 b0 → 2090 steps, 0.5 → 1712, 1.0 → 1586, but the
    // cell search grows as (2 + skin)³: 0.5 b0 is the fastest (identical results for all).
    0.5
}

impl Default for Stepping {
    fn default() -> Self {
        Stepping::Adaptive {
            step_factor: 1.0,
            dt_min: default_dt_min(),
            dt_max: default_dt_max(),
            skin: default_skin(),
        }
    }
}

/// Which physics systems the scene runs (docs/model.md §3: a scene runs only what it needs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Physics {
    /// Bonded pairs merge into one body (§6).
    #[serde(default = "yes")]
    pub merging: bool,
    /// Bodies that absorbed enough energy fragment (§7); also off when γ is `null`.
    #[serde(default = "yes")]
    pub fragmentation: bool,
    /// Cooling integrator (§8); also off when ε = 0 and hc = 0.
    #[serde(default)]
    pub cooling: CoolingMethod,
    /// Contact rule: `all` contacts (deepest first, one per body per step), or the papers'
    /// `nearest_neighbour` rule (each body may only meet its nearest neighbour).
    #[serde(default)]
    pub contact_rule: ContactRule,
    /// Reading: how many impacts a body takes in one step of the stepped core —
    /// `one_per_body` (the engine: its deepest contact; the rest wait a step) or
    /// `every_contact` (every contact found, in order; the papers do not say).
    #[serde(default, skip_serializing_if = "is_default")]
    pub impacts_per_step: ImpactsPerStep,
}

/// How many impacts one body takes in one step (`physics.impacts_per_step`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImpactsPerStep {
    /// One impact per body per step, deepest contact first (docs/model.md §4.2).
    #[default]
    OnePerBody,
    /// Every contact found in the step, in the same order, each with the velocities the
    /// earlier ones left (stepped core only: on the event core contacts are events).
    EveryContact,
}

fn yes() -> bool {
    true
}

impl Default for Physics {
    fn default() -> Self {
        Self {
            merging: true,
            fragmentation: true,
            cooling: CoolingMethod::Implicit,
            contact_rule: ContactRule::All,
            impacts_per_step: ImpactsPerStep::OnePerBody,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CoolingMethod {
    /// No cooling system.
    Off,
    /// Forward Euler (the papers' choice, P04 (6.21)); conditionally stable.
    Explicit,
    /// Reading: forward Euler kept from blowing up — a step that would cross the
    /// equilibrium temperature stops at it (stepped core only, like `explicit`).
    ExplicitClamped,
    /// Backward Euler by safeguarded Newton; unconditionally stable and monotone. The
    /// event core integrates cooling accurately instead (as `exact`).
    #[default]
    Implicit,
    /// Accurate integration over each interval (≤ 1e-9 relative to the closed forms).
    Exact,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ContactRule {
    /// Every touching, approaching pair is a contact (deepest first, one per body per step).
    #[default]
    All,
    /// The papers' staggering rule: a pair is a contact only if each is the other's nearest neighbour.
    NearestNeighbour,
}

/// Invariant checks (docs/model.md §10).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Diagnostics {
    /// Check the invariants every `every` steps (and at the end); false = never.
    #[serde(default = "yes")]
    pub invariants: bool,
    /// Check period in steps.
    #[serde(default = "default_check_every")]
    pub every: u64,
    /// Relative tolerance for mass, momentum and energy checks.
    #[serde(default = "default_check_tol")]
    pub tolerance: f64,
}

fn default_check_every() -> u64 {
    1
}
fn default_check_tol() -> f64 {
    1e-9
}

impl Default for Diagnostics {
    fn default() -> Self {
        Self {
            invariants: true,
            every: default_check_every(),
            tolerance: default_check_tol(),
        }
    }
}

/// Output options. Recording options live here too.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Write the summary JSON here (same as `--summary`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub summary: Option<String>,
    /// Write the final state CSV here (same as `--final-state`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_state: Option<String>,
    /// Record the run to this MCAP file (same as `--out`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mcap: Option<String>,
    /// Recording options.
    #[serde(default)]
    pub recording: Recording,
}

/// How often and how a recording samples the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Recording {
    /// Record every k-th step (0 = use `interval` only).
    #[serde(default)]
    pub every_steps: u64,
    /// Record whenever this much simulated time [s] has passed; `null` = T / 300.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval: Option<f64>,
    /// Playback duration [s] of the whole run at 1×: log time = simulated time × (this / T).
    #[serde(default = "default_playback")]
    pub playback_seconds: f64,
}

fn default_playback() -> f64 {
    30.0
}

impl Default for Recording {
    fn default() -> Self {
        Self {
            every_steps: 0,
            interval: None,
            playback_seconds: default_playback(),
        }
    }
}

impl Scenario {
    /// Parse a scenario from JSON text, reporting the path of the offending field.
    pub fn from_json(text: &str) -> Result<Self, ScenarioError> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let scenario: Scenario =
            serde_path_to_error::deserialize(de).map_err(|e| ScenarioError::Parse {
                path: e.path().to_string(),
                message: e.inner().to_string(),
            })?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Parse a scenario held as a JSON value (used by the inverse problem).
    pub fn from_value(value: serde_json::Value) -> Result<Self, ScenarioError> {
        let scenario: Scenario =
            serde_path_to_error::deserialize(value).map_err(|e| ScenarioError::Parse {
                path: e.path().to_string(),
                message: e.inner().to_string(),
            })?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Read and parse a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Pretty JSON of this scenario (round-trips through [`Scenario::from_json`]).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("scenario serialises") // ok: plain data
    }

    /// The JSON Schema of the scenario format.
    pub fn json_schema() -> serde_json::Value {
        serde_json::to_value(schemars::schema_for!(Scenario)).expect("schema serialises") // ok: plain data
    }

    /// Primary radius b0 [m], from `radius` or `size_ratio`.
    pub fn primary_radius(&self) -> f64 {
        match (self.cloud.radius, self.cloud.size_ratio) {
            (Some(b), _) => b,
            (None, Some(s)) => {
                let side = 2.0 * self.domain.half_width;
                let spacing = (side.powi(3) / self.cloud.count as f64).cbrt();
                0.5 * s * spacing
            }
            (None, None) => f64::NAN, // rejected by validate()
        }
    }

    /// Volume fraction of the initial cloud.
    pub fn volume_fraction(&self) -> f64 {
        let b = self.primary_radius();
        let side = 2.0 * self.domain.half_width;
        self.cloud.count as f64 * 4.0 / 3.0 * std::f64::consts::PI * b.powi(3) / side.powi(3)
    }

    /// Why this scene cannot run on the event core, if it cannot.
    fn event_core_obstacle(&self) -> Option<&'static str> {
        let exact_steps = matches!(
            self.time.stepping,
            Stepping::Adaptive { step_factor, .. } if step_factor == 1.0
        );
        if !exact_steps {
            return Some("adaptive stepping with step_factor = 1 (time.stepping)");
        }
        if self.physics.contact_rule != ContactRule::All {
            return Some("physics.contact_rule = \"all\"");
        }
        if self.physics.impacts_per_step != ImpactsPerStep::OnePerBody {
            return Some("physics.impacts_per_step = \"one_per_body\"");
        }
        if matches!(
            self.physics.cooling,
            CoolingMethod::Explicit | CoolingMethod::ExplicitClamped
        ) {
            return Some("physics.cooling other than \"explicit\" or \"explicit_clamped\"");
        }
        None
    }

    /// True when this scene runs on the event core (docs/model.md §4).
    pub fn uses_event_core(&self) -> bool {
        match self.time.core {
            Core::Auto => self.event_core_obstacle().is_none(),
            Core::Events | Core::EventsBruteForce => true,
            Core::Stepped => false,
        }
    }

    /// Check every range; all problems are reported together, each with its field path.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let mut v = Validator::default();
        v.positive("box.half_width", self.domain.half_width);

        let c = &self.cloud;
        if c.count == 0 || c.count > 10_000_000 {
            v.push("cloud.count", "1 ≤ N ≤ 10 000 000", c.count as f64);
        }
        match (c.radius, c.size_ratio) {
            (Some(_), Some(_)) | (None, None) => v.issues.push(ValidationIssue {
                path: "cloud".into(),
                message: "give exactly one of `radius` [m] or `size_ratio`".into(),
            }),
            (Some(b), None) => {
                v.positive("cloud.radius", b);
                if b.is_finite() && b > 0.0 && self.domain.half_width > 0.0 {
                    let s = self.size_ratio_of_radius(b);
                    if s >= 0.9 {
                        v.issues.push(ValidationIssue {
                            path: "cloud.radius".into(),
                            message: format!(
                                "radius {b:e} m gives size ratio s = {s:.4}; allowed s < 0.9 (volume fraction < 0.38)"
                            ),
                        });
                    }
                }
            }
            (None, Some(s)) => v.range_open("cloud.size_ratio", s, 0.0, 0.9, "0 < s < 0.9"),
        }
        for k in 0..3 {
            v.finite(&format!("cloud.v_mean.{k}"), c.v_mean[k]);
            v.non_negative(&format!("cloud.v_rel.{k}"), c.v_rel[k]);
            v.below_speed_limit(&format!("cloud.v_rel.{k}"), c.v_rel[k]);
        }
        v.below_speed_limit("cloud.v_mean", norm(c.v_mean));
        if !c.bodies.is_empty() {
            if c.bodies.len() != c.count {
                v.issues.push(ValidationIssue {
                    path: "cloud.bodies".into(),
                    message: format!(
                        "lists {} bodies but cloud.count = {}; they must agree",
                        c.bodies.len(),
                        c.count
                    ),
                });
            }
            let d = self.domain.half_width;
            for (i, body) in c.bodies.iter().enumerate() {
                for k in 0..3 {
                    let x = body.position[k];
                    if !(x >= -d && x <= d) {
                        v.push(
                            &format!("cloud.bodies.{i}.position.{k}"),
                            &format!("−D ≤ x ≤ D = {d:e}"),
                            x,
                        );
                    }
                    v.finite(&format!("cloud.bodies.{i}.velocity.{k}"), body.velocity[k]);
                }
                v.below_speed_limit(&format!("cloud.bodies.{i}.velocity"), norm(body.velocity));
                if !(body.primaries >= 1.0 && body.primaries.is_finite()) {
                    v.push(
                        &format!("cloud.bodies.{i}.primaries"),
                        "a finite number ≥ 1",
                        body.primaries,
                    );
                }
            }
        }

        let m = &self.material;
        v.positive("material.rho", m.rho);
        v.positive("material.H0", m.H0);
        v.positive("material.C", m.C);
        v.non_negative("material.Q", m.Q);
        v.non_negative("material.alpha", m.alpha);
        if let Some(g) = m.gamma {
            v.positive("material.gamma", g);
        }
        v.non_negative("material.mu0", m.mu0);
        v.range_closed("material.epsilon", m.epsilon, 0.0, 1.0, "0 ≤ ε ≤ 1");
        v.non_negative("material.hc", m.hc);
        v.positive("material.theta0", m.theta0);
        v.non_negative("material.theta_s", m.theta_s);

        let i = &self.impact;
        v.range_closed("impact.af", i.af, 0.0, 1.0, "0 < af ≤ 1");
        if i.af == 0.0 {
            v.push("impact.af", "0 < af ≤ 1", i.af);
        }
        v.range_closed("impact.a0", i.a0, 0.0, 1.0, "0 ≤ a0 ≤ af");
        if i.a0.is_finite() && i.af.is_finite() && i.a0 > i.af {
            v.issues.push(ValidationIssue {
                path: "impact.a0".into(),
                message: format!("must satisfy a0 ≤ af (got a0 = {}, af = {})", i.a0, i.af),
            });
        }
        v.positive("impact.beta", i.beta);
        v.range_open("impact.tol", i.tol, 0.0, 1.0, "0 < tol < 1");
        if i.max_iterations == 0 {
            v.push("impact.max_iterations", "≥ 1", 0.0);
        }
        if i.solver == SolverKind::ClosedFormPrinted && i.duration != DurationLaw::P04 {
            v.issues.push(ValidationIssue {
                path: "impact.solver".into(),
                message: "closed_form_printed is P04 (4.14), derived for P04's duration law: \
                          it needs impact.duration = \"p04\""
                    .into(),
            });
        }

        let t = &self.time;
        v.positive("time.end", t.end);
        if t.max_steps == 0 {
            v.push("time.max_steps", "≥ 1", 0.0);
        }
        match &t.stepping {
            Stepping::Adaptive {
                step_factor,
                dt_min,
                dt_max,
                skin,
            } => {
                v.positive("time.stepping.adaptive.step_factor", *step_factor);
                v.positive("time.stepping.adaptive.dt_min", *dt_min);
                v.positive("time.stepping.adaptive.dt_max", *dt_max);
                if dt_min.is_finite() && dt_max.is_finite() && dt_min > dt_max {
                    v.issues.push(ValidationIssue {
                        path: "time.stepping.adaptive.dt_min".into(),
                        message: format!(
                            "must satisfy dt_min ≤ dt_max (got {dt_min:e} > {dt_max:e})"
                        ),
                    });
                }
                v.positive("time.stepping.adaptive.skin", *skin);
                // Every step is at most Δt_max long: at least T/Δt_max steps.
                v.step_count_fits(
                    "time.stepping.adaptive.dt_max",
                    "at least T/Δt_max",
                    t.end,
                    *dt_max,
                    t.max_steps,
                );
            }
            Stepping::Fixed { dt } => {
                v.positive("time.stepping.fixed.dt", *dt);
                v.step_count_fits("time.stepping.fixed.dt", "T/Δt", t.end, *dt, t.max_steps);
            }
        }
        if matches!(t.core, Core::Events | Core::EventsBruteForce)
            && let Some(why) = self.event_core_obstacle()
        {
            v.issues.push(ValidationIssue {
                path: "time.core".into(),
                message: format!("the event core needs {why}"),
            });
        }
        if self.diagnostics.every == 0 {
            v.push("diagnostics.every", "≥ 1", 0.0);
        }
        v.positive("diagnostics.tolerance", self.diagnostics.tolerance);
        let r = &self.output.recording;
        if let Some(dt) = r.interval {
            v.positive("output.recording.interval", dt);
        }
        v.positive("output.recording.playback_seconds", r.playback_seconds);

        if v.issues.is_empty() {
            Ok(())
        } else {
            Err(ScenarioError::Invalid(v.issues))
        }
    }

    fn size_ratio_of_radius(&self, b: f64) -> f64 {
        let side = 2.0 * self.domain.half_width;
        let spacing = (side.powi(3) / self.cloud.count as f64).cbrt();
        2.0 * b / spacing
    }
}

/// The largest speed a scenario may give [m/s]: any |v_mean|, any v_rel component, any
/// explicit body's |velocity|.
///
/// 1e5 m/s (100 km/s) is above the fastest natural impacts (meteoroids meet the Earth at
/// up to ~72 km/s) and hundreds of times the speeds of granular flows and of the papers'
/// scenes (P04: ~200 m/s; P02: ~4 m/s), so no physical scene is refused. Below it every
/// energy stays far from overflow (½ v² ~ 1e10 J/kg) and runs of the
/// shipped size finish: with v̄ = (1e5, 0, 0) m/s and v_rel = 1e5 m/s per component
/// (release build) P04's best case takes 0.01 s, quick_demo 0.25 s (38 635 impacts).
/// Above it lie only mistakes: with v_rel = 1e300 m/s the kinetic energies overflow to ∞
/// and P04's scene was still running after 200 s.
pub const MAX_SPEED: f64 = 1e5;

/// Length of a 3-vector [same unit as its components].
fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// Steps a run of length `end` [s] needs at steps of at most `dt` [s]: ⌈T/Δt⌉, less a
/// relative 1e-12 (the clock lands on T when a step ends that close to it).
fn planned_steps(end: f64, dt: f64) -> f64 {
    (end / dt * (1.0 - 1e-12)).ceil()
}

/// Collects range violations with their field paths.
#[derive(Default)]
struct Validator {
    issues: Vec<ValidationIssue>,
}

impl Validator {
    fn push(&mut self, path: &str, allowed: &str, got: f64) {
        self.issues.push(ValidationIssue {
            path: path.into(),
            message: format!("allowed {allowed} (got {got})"),
        });
    }
    fn finite(&mut self, path: &str, x: f64) {
        if !x.is_finite() {
            self.push(path, "a finite number", x);
        }
    }
    fn positive(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x > 0.0) {
            self.push(path, "a finite number > 0", x);
        }
    }
    fn non_negative(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x >= 0.0) {
            self.push(path, "a finite number ≥ 0", x);
        }
    }
    fn range_open(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x > lo && x < hi) {
            self.push(path, allowed, x);
        }
    }
    fn range_closed(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x >= lo && x <= hi) {
            self.push(path, allowed, x);
        }
    }
    /// A speed [m/s] above [`MAX_SPEED`] (NaN and ∞ are reported by the finiteness checks).
    fn below_speed_limit(&mut self, path: &str, speed: f64) {
        if speed.is_finite() && speed > MAX_SPEED {
            self.issues.push(ValidationIssue {
                path: path.into(),
                message: format!(
                    "speed {speed:.4e} m/s is not physical; allowed ≤ {MAX_SPEED:e} m/s \
                     (100 km/s, above the fastest natural impacts)"
                ),
            });
        }
    }
    /// A run of `end` [s] in steps of at most `dt` [s] that needs more than `max_steps`
    /// steps can never finish. Non-positive or non-finite values are reported elsewhere.
    fn step_count_fits(&mut self, path: &str, count: &str, end: f64, dt: f64, max_steps: u64) {
        if !(end.is_finite() && end > 0.0 && dt.is_finite() && dt > 0.0) {
            return;
        }
        let planned = planned_steps(end, dt);
        if planned > max_steps as f64 {
            self.issues.push(ValidationIssue {
                path: path.into(),
                message: format!(
                    "{count} = {end:e} s / {dt:e} s = {planned:.3e} planned steps exceed \
                     time.max_steps = {max_steps}; allowed Δt ≥ time.end / time.max_steps \
                     = {:e} s (or raise time.max_steps)",
                    end / max_steps as f64
                ),
            });
        }
    }
}
