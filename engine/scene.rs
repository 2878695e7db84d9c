//! The sections of a scene the engine itself owns because every stage shares them —
//! `box` ([`BoxGeometry`]), `material` ([`Material`]), `time` ([`TimeControl`]) and
//! `physics` ([`Physics`]); the cloud is [`crate::cloud::Cloud`], and a whole run
//! description is a [`crate::setup::Scene`]. Each section is one type, deserialised from the scenario
//! file and inserted into the world as it is: a system reads the section, never a copy.
//! The sections of the other concerns live with them (`impact` in the impact plugin,
//! `diagnostics` in the diagnostics plugin, `output` with the drivers) and reach the
//! world through [`crate::setup::Scene::insert_settings`]. Symbols follow docs/model.md §1; all
//! values SI.

use bevy_ecs::prelude::*;
use glam::DVec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::ValidationIssue;
use crate::issues::Issues;
pub use crate::laws::cooling::CoolingMethod;
use crate::laws::hardness::hardness;

/// Why a scene with these time and physics sections cannot run on the event core, if
/// it cannot (docs/model.md §4): the event core needs exact contact times and lazy
/// cooling, which the rules below exclude.
pub fn event_core_obstacle(time: &TimeControl, physics: &Physics) -> Option<&'static str> {
    let exact_steps = matches!(
        time.stepping,
        Stepping::Adaptive { step_factor, .. } if step_factor == 1.0
    );
    if !exact_steps {
        return Some("adaptive stepping with step_factor = 1 (time.stepping)");
    }
    if physics.contact_rule != ContactRule::All {
        return Some("physics.contact_rule = \"all\"");
    }
    if physics.impacts_per_step != ImpactsPerStep::OnePerBody {
        return Some("physics.impacts_per_step = \"one_per_body\"");
    }
    if matches!(
        physics.cooling,
        CoolingMethod::Explicit | CoolingMethod::ExplicitClamped
    ) {
        return Some("physics.cooling other than \"explicit\" or \"explicit_clamped\"");
    }
    None
}

/// What keeps a scene asking for the event core off it, as `validate` and the pipeline
/// say it: "the event core needs …".
pub fn event_core_needs(time: &TimeControl, physics: &Physics) -> Option<String> {
    event_core_obstacle(time, physics).map(|why| format!("the event core needs {why}"))
}

/// True when a scene with these sections runs on the event core (docs/model.md §4).
pub fn uses_event_core(time: &TimeControl, physics: &Physics) -> bool {
    match time.core {
        Core::Auto => event_core_obstacle(time, physics).is_none(),
        Core::Events | Core::EventsBruteForce => true,
        Core::Stepped => false,
    }
}

/// `serde(skip_serializing_if)` for options at their default: a scenario written back
/// out names only what it changed.
pub fn is_default<T: Default + PartialEq>(x: &T) -> bool {
    x == &T::default()
}

/// `serde(default)` for switches that are on unless turned off.
pub fn yes() -> bool {
    true
}

/// `serde(default)` for factors that are 1 unless given.
pub fn one() -> f64 {
    1.0
}

/// One material per scene (docs/model.md §1). Symbols as in docs/model.md.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(non_snake_case)]
pub struct Material {
    /// Density ρ [kg/m³].
    pub rho: f64,
    /// Base hardness H0 [Pa].
    pub H0: f64,
    /// Heat capacity C [J/(kg K)], 0 < C ≤ 1e100.
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

/// The scene's material (the scenario's `material` section, read as it is) and what it
/// implies: the hardness law with its overflow rule, the radius of a mass, whether it
/// cools, its surface energy with `null` read as ∞.
/// The largest specific heat capacity C accepted [J/(kg·K)]: far above any material
/// (≈ 1.4e4 for hydrogen), far below where m C or the cooling constants σεA/(m C) leave
/// f64's range.
pub const MAX_HEAT_CAPACITY: f64 = 1e100;

impl Material {
    /// Range problems of the `material` section, by full path.
    pub fn issues(&self) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        let m = self;
        v.positive("material.rho", m.rho);
        v.positive("material.H0", m.H0);
        // Real heat capacities lie within 1e2…2e4 J/(kg·K); 1e200 validated, then every
        // temperature went NaN at step 1 (issue 39), so a bound well above any material.
        v.range_open_closed(
            "material.C",
            m.C,
            0.0,
            MAX_HEAT_CAPACITY,
            "0 < C ≤ 1e100 J/(kg·K)",
        );
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
        v.issues
    }

    /// Hardness H = H0 · exp(Q / (R θ)) [Pa]; +∞ when the exponent exceeds 700
    /// (docs/model.md §1, "hardness overflow"). Never NaN for θ > 0.
    pub fn hardness(&self, theta: f64) -> f64 {
        hardness(self.H0, self.Q, theta)
    }

    /// Radius of a body of mass `m` [kg]: (3 m / (4 π ρ))^(1/3).
    pub fn radius_of_mass(&self, m: f64) -> f64 {
        (3.0 * m / (4.0 * std::f64::consts::PI * self.rho)).cbrt()
    }

    /// True when cooling would change anything (ε > 0 or hc > 0).
    pub fn cools(&self) -> bool {
        self.epsilon > 0.0 || self.hc > 0.0
    }

    /// Surface energy γ [J/m²]; +∞ (no fragmentation) when the scenario gives `null`.
    pub fn surface_energy(&self) -> f64 {
        self.gamma.unwrap_or(f64::INFINITY)
    }
}

/// The periodic cube [−D, D]³.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
// The `box` section of a scenario, read by every stage as it is; named `Domain` in the
// schema and in parse errors.
#[serde(deny_unknown_fields, rename = "Domain")]
pub struct BoxGeometry {
    /// Half-width D [m] of the periodic cube [−D, D]³.
    pub half_width: f64,
}

impl BoxGeometry {
    /// Range problems of the `box` section, by full path.
    pub fn issues(&self) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        v.positive("box.half_width", self.half_width);
        v.issues
    }

    /// Side length 2D [m].
    pub fn side(&self) -> f64 {
        2.0 * self.half_width
    }
    /// Minimum-image displacement of `d` (each component in [−D, D]).
    #[inline]
    pub fn min_image(&self, d: DVec3) -> DVec3 {
        let l = self.side();
        d - l * (d / l).round()
    }
    /// Map a position back into [−D, D) (periodic re-entry).
    #[inline]
    pub fn wrap(&self, r: DVec3) -> DVec3 {
        let l = self.side();
        let mut w = r - l * ((r + DVec3::splat(self.half_width)) / l).floor();
        // Guard the rounding edge where r + D is a hair below a multiple of L.
        for k in 0..3 {
            if w[k] >= self.half_width {
                w[k] -= l;
            }
            if w[k] < -self.half_width {
                w[k] = -self.half_width;
            }
        }
        w
    }
}

/// End time and step control (docs/model.md §4).
#[derive(Resource, Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
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

impl TimeControl {
    /// Range problems of the `time` section, by full path; the core asked for is checked against `physics` (docs/model.md §4).
    pub fn issues(&self, physics: &Physics) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        let t = self;
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
            && let Some(message) = event_core_needs(self, physics)
        {
            v.issues.push(ValidationIssue {
                path: "time.core".into(),
                message,
            });
        }
        v.issues
    }
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
/// How the stepped core chooses Δt (`time.stepping`, docs/model.md §4).
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
    Fixed {
        /// Δt [s], > 0.
        dt: f64,
    },
}

impl Stepping {
    /// Neighbour-search margin beyond touching [m] for primaries of radius `b0` [m]:
    /// skin · b0 when adaptive, 0 for fixed steps.
    pub fn search_skin(&self, b0: f64) -> f64 {
        match *self {
            Stepping::Adaptive { skin, .. } => skin * b0,
            Stepping::Fixed { .. } => 0.0,
        }
    }

    /// The longest step [s]: Δt_max when adaptive, the fixed Δt otherwise.
    pub fn dt_max(&self) -> f64 {
        match *self {
            Stepping::Adaptive { dt_max, .. } => dt_max,
            Stepping::Fixed { dt } => dt,
        }
    }
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
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
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
    /// What a bond makes (docs/model.md §6.1): `coalesce` (one sphere at the centre of
    /// mass, the papers' model) or `rigid` (an aggregate of the primaries as they touched,
    /// flying without rotation).
    #[serde(default, skip_serializing_if = "is_default")]
    pub merge_mode: MergeMode,
}

/// What a bond makes (`physics.merge_mode`, docs/model.md §6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MergeMode {
    /// The bonded pair becomes one sphere at its centre of mass (P04's model).
    #[default]
    Coalesce,
    /// The bonded pair's aggregates join rigidly: every primary keeps its place relative
    /// to the others and flies with the aggregate's velocity (no rotation).
    Rigid,
}

impl Physics {
    /// What a `rigid` scene asks for that `rigid` does not support yet, each named by its
    /// field (docs/model.md §6.1); empty for `coalesce`. `has_field`: the scene has a
    /// `field` section (gravity or drag).
    pub fn rigid_issues(&self, time: &TimeControl, has_field: bool) -> Vec<ValidationIssue> {
        let mut issues = Vec::new();
        if self.merge_mode != MergeMode::Rigid {
            return issues;
        }
        let mut refuse = |path: &str, why: &str| {
            issues.push(ValidationIssue {
                path: path.into(),
                message: format!("physics.merge_mode = \"rigid\" {why}"),
            })
        };
        if !uses_event_core(time, self) {
            let why = event_core_obstacle(time, self).unwrap_or("time.core = \"events\"");
            refuse(
                "time.core",
                &format!("runs on the event core only, which needs {why}"),
            );
        } else if time.core == Core::EventsBruteForce {
            refuse(
                "time.core",
                "runs on the event core with cells only (\"events\" or \"auto\")",
            );
        }
        if !self.merging {
            refuse(
                "physics.merging",
                "needs physics.merging = true (a bond joins two aggregates)",
            );
        }
        if has_field {
            refuse(
                "field",
                "flies aggregates ballistically only: remove the field section (gravity, drag)",
            );
        }
        issues
    }
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

impl Default for Physics {
    fn default() -> Self {
        Self {
            merging: true,
            fragmentation: true,
            cooling: CoolingMethod::Implicit,
            contact_rule: ContactRule::All,
            impacts_per_step: ImpactsPerStep::OnePerBody,
            merge_mode: MergeMode::Coalesce,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
/// Which touching pairs of a step are resolved (`physics.contact_rule`).
pub enum ContactRule {
    /// Every touching, approaching pair is a contact (deepest first, one per body per step).
    #[default]
    All,
    /// The papers' staggering rule: a pair is a contact only if each is the other's nearest neighbour.
    NearestNeighbour,
}

/// The largest speed a scenario may give [m/s] (defined with the range checks).
pub use crate::issues::MAX_SPEED;
