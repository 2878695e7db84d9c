//! Scenario files: the JSON description of one run, its validation, and the
//! JSON Schema printed by `agglo schema`.
//!
//! A scenario fully describes a run (box, cloud, material, impact model, time
//! control, physics toggles, diagnostics, seed, output). Each section is a type that
//! lives with the concern that reads it and is inserted into the world as it is
//! (docs/architecture.md, "settings"): `box`, `cloud`, `material`, `time` and `physics`
//! in the engine, `impact` and `diagnostics` in their plugins, `output` with the
//! drivers; this file puts them together, loads and checks them. Parsing reports the field path of a
//! type error or unknown field (via `serde_path_to_error`); [`Scenario::validate`]
//! then checks every range and names the field and the allowed range. Symbols
//! follow docs/model.md §1: all values SI.

use std::collections::BTreeMap;
use std::path::Path;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use bevy_ecs::prelude::*;

use crate::error::{ScenarioError, SimError, ValidationIssue};
pub use crate::output::Output;
pub use crate::record::Recording;
use crate::schedule::Pipeline;
pub use agglo_engine::cloud::{Cloud, PlacedBody, PrimaryGrain, VelocityDistribution};
pub use agglo_engine::field::{Drag, Field, Relaxation};
pub use agglo_engine::resources::BoxGeometry as Domain;
use agglo_engine::scene::event_core_needs;
pub use agglo_engine::scene::{
    ContactRule, CoolingMethod, Core, ImpactsPerStep, Material, Physics, Stepping, TimeControl,
};
use agglo_engine::setup::Scene;
pub use agglo_systems::diagnostics::Diagnostics;
pub use agglo_systems::impact::{
    BondTest, DurationLaw, FrictionCap, ImpactModel, PairHardness, RestitutionLaw, Separation,
    SolverKind, WorkHeat,
};

/// One complete run description.
// It is also a resource of the world it builds, for the drivers (the recording embeds
// it); physics reads only its own section.
#[derive(Resource, Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
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
    /// Forces every body feels between events: uniform g, linear gas drag
    /// (docs/model.md §4.7). None when absent.
    #[serde(default, skip_serializing_if = "Field::is_none")]
    pub field: Field,
    #[serde(default)]
    pub diagnostics: Diagnostics,
    #[serde(default)]
    pub output: Output,
    /// The sections of the extensions this binary carries, one per plugin, named after
    /// it: `"plugins": {"charged_grains": {"q0": 1e-8}}` (src/plugins/). Left out of
    /// the JSON when empty, so a scene without extensions reads and writes as before.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub plugins: BTreeMap<String, serde_json::Value>,
}

impl Scenario {
    /// Parse a scenario from JSON text, reporting the path of the offending field.
    pub fn from_json(text: &str) -> Result<Self, ScenarioError> {
        Self::parse(text, "the scenario")
    }

    /// Parse `text`, called `what` in messages (a file name, or "the scenario"): a text
    /// that is not a scenario at all says so in a person's words (empty, cut off at line
    /// L column C, not JSON, not an object); a field of the wrong type or out of range
    /// is named by its path.
    fn parse(text: &str, what: &str) -> Result<Self, ScenarioError> {
        let malformed = |message: String| ScenarioError::Malformed(message);
        let Some(first) = text.trim_start().chars().next() else {
            return Err(malformed(format!("{what} is empty")));
        };
        if first != '{'
            && let Some(kind) = json_kind(first)
        {
            return Err(malformed(format!(
                "{what}: the top level must be a JSON object ({{ \"name\": …, … }}), not {kind}"
            )));
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let parsed: Result<Scenario, _> = serde_path_to_error::deserialize(&mut *de);
        let scenario = match parsed {
            Ok(scenario) => scenario,
            Err(e) => {
                let (path, inner) = (e.path().to_string(), e.into_inner());
                return Err(match inner.classify() {
                    serde_json::error::Category::Eof => malformed(format!(
                        "{what} ends early at line {} column {} (cut off?)",
                        inner.line(),
                        inner.column()
                    )),
                    // A field's own path says where, when there is one.
                    _ if path == "." || path == "?" => match inner.classify() {
                        serde_json::error::Category::Syntax => {
                            malformed(format!("{what} is not valid JSON: {inner}"))
                        }
                        _ => malformed(format!("{what}: {inner}")),
                    },
                    _ => ScenarioError::Parse {
                        path,
                        message: inner.to_string(),
                    },
                });
            }
        };
        de.end()
            .map_err(|e| malformed(format!("{what} has more after the scenario's object: {e}")))?;
        let mut scenario = scenario;
        scenario.load_cloud_file()?;
        crate::plugins::registry::canonical_sections(&mut scenario.plugins);
        scenario.validate()?;
        Ok(scenario)
    }

    /// Parse a scenario held as a JSON value (used by the inverse problem).
    pub fn from_value(value: serde_json::Value) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario =
            serde_path_to_error::deserialize(value).map_err(|e| ScenarioError::Parse {
                path: e.path().to_string(),
                message: e.inner().to_string(),
            })?;
        scenario.load_cloud_file()?;
        crate::plugins::registry::canonical_sections(&mut scenario.plugins);
        scenario.validate()?;
        Ok(scenario)
    }

    /// Read `cloud.from_file` into `cloud.bodies` (then the field is cleared: the
    /// scenario, as recordings embed it, holds the bodies it starts from), and take
    /// `cloud.count` from the bodies when it is left out.
    pub fn load_cloud_file(&mut self) -> Result<(), ScenarioError> {
        if let Some(file) = self.cloud.from_file.take() {
            if !self.cloud.bodies.is_empty() {
                return Err(ScenarioError::Invalid(vec![ValidationIssue {
                    path: "cloud.from_file".into(),
                    message: "give either cloud.bodies or cloud.from_file, not both".into(),
                }]));
            }
            self.cloud.bodies = crate::cloud_file::load_bodies(Path::new(&file))
                .map_err(|e| ScenarioError::Malformed(format!("cloud.from_file: {e:#}")))?;
        }
        if self.cloud.count == 0 {
            self.cloud.count = self.cloud.bodies.len();
        }
        Ok(())
    }

    /// Read and parse a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let bytes = std::fs::read(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            ScenarioError::Malformed(format!(
                "{} is not UTF-8 text (invalid byte at offset {})",
                path.display(),
                e.utf8_error().valid_up_to()
            ))
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Pretty JSON of this scenario (round-trips through [`Scenario::from_json`]).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("scenario serialises") // ok: plain data
    }

    /// The JSON Schema of the scenario format.
    /// The `plugins` property lists the sections of the extensions this binary carries.
    pub fn json_schema() -> serde_json::Value {
        let mut schema =
            serde_json::to_value(schemars::schema_for!(Scenario)).expect("schema serialises"); // ok: plain data
        let mut defs = serde_json::Map::new();
        let plugins = crate::plugins::registry::sections_schema(&mut defs);
        if let Some(root) = schema.as_object_mut() {
            if let Some(serde_json::Value::Object(properties)) = root.get_mut("properties") {
                properties.insert("plugins".into(), plugins);
            }
            if let Some(serde_json::Value::Object(own)) = root.get_mut("$defs") {
                for (name, def) in defs {
                    own.entry(name).or_insert(def);
                }
            }
        }
        schema
    }

    /// Primary radius b0 [m], from `radius` or `size_ratio`.
    pub fn primary_radius(&self) -> f64 {
        self.cloud.primary_radius(&self.domain)
    }

    /// Mass of the primary grain [kg]: (4/3)π b0³ ρ, b0 [`Self::primary_radius`] and ρ
    /// `material.rho` (the mass unit of a flow solver's size classes, docs/coupling.md).
    pub fn primary_mass(&self) -> f64 {
        4.0 / 3.0 * std::f64::consts::PI * self.primary_radius().powi(3) * self.material.rho
    }

    /// Volume fraction of the initial cloud.
    pub fn volume_fraction(&self) -> f64 {
        self.cloud.volume_fraction(&self.domain)
    }

    /// The pipeline `Simulation::new` would build for this scene, without generating its
    /// cloud: the plugins decide from the scene's sections, never from the bodies, so a
    /// one-body copy of the scene gets the same systems at no cost for any N.
    pub fn pipeline(&self) -> Result<Pipeline, SimError> {
        self.validate()?;
        let copy = self.one_body_copy();
        let sim = crate::plugins::registry::build(&copy, &copy.plugins)?.build()?;
        Ok(sim.pipeline().clone())
    }

    /// This scene with a single body of the same primary radius (the first placed body,
    /// if the scene places its bodies): what it needs to build its pipeline.
    fn one_body_copy(&self) -> Scenario {
        let mut one = self.clone();
        one.cloud.radius = Some(self.primary_radius());
        one.cloud.size_ratio = None;
        one.cloud.count = 1;
        one.cloud.bodies.truncate(1);
        one
    }

    /// True when this scene runs on the event core (docs/model.md §4).
    pub fn uses_event_core(&self) -> bool {
        agglo_engine::scene::uses_event_core(&self.time, &self.physics)
    }

    /// Check every range; all problems are reported together, each with its field path.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let mut v = Validator::default();
        v.positive("box.half_width", self.domain.half_width);

        let c = &self.cloud;
        // The upper limit is the machine's memory (crate::memory, checked by `run` and
        // `validate` before anything is allocated), and the event core's 32-bit slots.
        if c.count == 0 || c.count >= u32::MAX as usize {
            v.push(
                "cloud.count",
                "1 ≤ N < 2^32 and within the machine's memory (left out only with \
                 cloud.bodies or cloud.from_file)",
                c.count as f64,
            );
        }
        match (c.radius, c.size_ratio) {
            (Some(_), Some(_)) => v.issues.push(ValidationIssue {
                path: "cloud".into(),
                message: "give exactly one of `radius` [m] or `size_ratio`, not both (over a \
                          scenario that gives the other: --set cloud.radius=R --set \
                          cloud.size_ratio=null, or --set cloud.size_ratio=S --set \
                          cloud.radius=null)"
                    .into(),
            }),
            (None, None) => v.issues.push(ValidationIssue {
                path: "cloud".into(),
                message: "give exactly one of `radius` [m] or `size_ratio`".into(),
            }),
            (Some(b), None) => {
                v.positive("cloud.radius", b);
                if b.is_finite() && b > 0.0 && self.domain.half_width > 0.0 {
                    let s = self.cloud.size_ratio_of_radius(b, &self.domain);
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
        }
        v.below_speed_limit("cloud.v_mean", norm(c.v_mean));
        let maxwell = c.velocity_distribution == VelocityDistribution::Maxwell;
        match c.v_rel {
            Some(v_rel) if maxwell => {
                let _ = v_rel;
                v.issues.push(ValidationIssue {
                    path: "cloud.v_rel".into(),
                    message: "not used by velocity_distribution = \"maxwell\" (give granular_temperature)".into(),
                });
            }
            Some(v_rel) => {
                for (k, &x) in v_rel.iter().enumerate() {
                    v.non_negative(&format!("cloud.v_rel.{k}"), x);
                    v.below_speed_limit(&format!("cloud.v_rel.{k}"), x);
                }
            }
            None if c.draws_uniform_velocities() => v.issues.push(ValidationIssue {
                path: "cloud.v_rel".into(),
                message: "required: velocities are drawn as v̄ + v_rel ∘ λ (a generated cloud, or \
                          explicit bodies without a velocity); give [vx, vy, vz] amplitudes [m/s], \
                          or every body its velocity"
                    .into(),
            }),
            None => {}
        }
        match (maxwell, c.granular_temperature) {
            (true, Some(tg)) => {
                v.non_negative("cloud.granular_temperature", tg);
                v.below_speed_limit("cloud.granular_temperature (as √T_g)", tg.max(0.0).sqrt());
            }
            (true, None) => v.issues.push(ValidationIssue {
                path: "cloud.granular_temperature".into(),
                message: "required by velocity_distribution = \"maxwell\": T_g [m²/s²], the variance of each velocity component".into(),
            }),
            (false, Some(_)) => v.issues.push(ValidationIssue {
                path: "cloud.granular_temperature".into(),
                message: "used only by velocity_distribution = \"maxwell\"".into(),
            }),
            (false, None) => {}
        }
        if c.remove_drift && c.v_mean != [0.0; 3] {
            v.issues.push(ValidationIssue {
                path: "cloud.remove_drift".into(),
                message: format!(
                    "sets the total momentum to zero, which contradicts v_mean = {:?}; give v_mean = [0, 0, 0]",
                    c.v_mean
                ),
            });
        }
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
            for (i, body) in c.bodies.iter().enumerate() {
                // Paths are formatted only for a body with a problem: 10⁶ bodies are
                // checked in milliseconds, not in the seconds 10⁷ `format!`s take.
                if body_is_plausible(body) {
                    continue;
                }
                for k in 0..3 {
                    v.finite(&format!("cloud.bodies.{i}.position.{k}"), body.position[k]);
                }
                if let Some(velocity) = body.velocity {
                    for (k, &x) in velocity.iter().enumerate() {
                        v.finite(&format!("cloud.bodies.{i}.velocity.{k}"), x);
                    }
                    v.below_speed_limit(&format!("cloud.bodies.{i}.velocity"), norm(velocity));
                }
                if !(body.primaries >= 1.0 && body.primaries.is_finite()) {
                    v.push(
                        &format!("cloud.bodies.{i}.primaries"),
                        "a finite number ≥ 1",
                        body.primaries,
                    );
                }
                if let Some(theta) = body.temperature {
                    v.positive(&format!("cloud.bodies.{i}.temperature"), theta);
                }
                if let Some(m) = body.mass {
                    v.positive(&format!("cloud.bodies.{i}.mass"), m);
                }
                if let Some(b) = body.radius {
                    v.positive(&format!("cloud.bodies.{i}.radius"), b);
                }
            }
        }

        let m = &self.material;
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

        if let Some(RestitutionLaw::Constant(e)) = i.restitution {
            v.range_closed("impact.restitution.constant", e, 0.0, 1.0, "0 ≤ e ≤ 1");
        }
        if let Some(tc) = i.collapse_time {
            v.non_negative("impact.collapse_time", tc);
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
            && let Some(message) = event_core_needs(&self.time, &self.physics)
        {
            v.issues.push(ValidationIssue {
                path: "time.core".into(),
                message,
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
        if let Some(restart) = &self.output.restart {
            v.positive("output.restart.every", restart.every);
            // A checkpoint is taken at a step end, at most one per step (the event core
            // cuts a step to land on each): more checkpoints than the run may take steps
            // would never finish (1e-300 s once wrote a synced file every step).
            v.step_count_fits(
                "output.restart.every",
                "checkpoints T/every",
                t.end,
                restart.every,
                t.max_steps,
            );
        }
        v.issues.extend(self.field.issues());
        if let Some(schedule) = &self.output.sampling {
            for (field, allowed, got) in schedule.problems() {
                v.push(&format!("output.sampling.{field}"), allowed, got);
            }
        }
        // On fields known to be in range: the constants derived from them must neither
        // overflow nor vanish (each field in range can still give an infinite box volume,
        // a primary mass of 0, or θ⁴ = ∞ in the radiation law).
        if v.issues.is_empty() {
            self.check_derived(&mut v);
        }
        // Last, on fields known to be in range: the explicit bodies as a run places them
        // (in the box, distinct ids, consistent masses and radii, no overlaps; O(N)) —
        // the very function the run calls, so `agglo validate` and `agglo run` agree.
        if v.issues.is_empty() && !self.cloud.bodies.is_empty() {
            let primary = PrimaryGrain::of(&self.cloud, &self.domain, &self.material);
            if let Err(e) = agglo_engine::cloud::placed_bodies(
                &self.cloud,
                &self.domain,
                &self.material,
                &primary,
            ) {
                let (path, message) = match e {
                    SimError::InvalidBody { path, message } => (path, message),
                    SimError::Overlap {
                        i,
                        j,
                        distance,
                        contact,
                    } => (
                        format!("cloud.bodies.{i}"),
                        format!(
                            "overlaps cloud.bodies.{j}: centres {distance:e} m apart, radii sum to {contact:e} m"
                        ),
                    ),
                    other => ("cloud.bodies".to_string(), other.to_string()),
                };
                v.issues.push(ValidationIssue { path, message });
            }
        }

        v.issues
            .extend(crate::plugins::registry::check_sections(&self.plugins));
        if v.issues.is_empty() {
            Ok(())
        } else {
            Err(ScenarioError::Invalid(v.issues))
        }
    }
}

impl Scenario {
    /// The scenario's name as a plain file name for the files named after it (the
    /// restart file `NAME.restart`, the live layout): characters other than letters,
    /// digits, `-`, `_` and `.` become `_` (a name carries `--set` settings, whose
    /// values may hold "/"), and a name longer than 100 bytes is cut to 80 characters
    /// followed by a hash of the whole name (a long name failed with "File name too
    /// long" at the first checkpoint). Short plain names are unchanged.
    pub fn file_stem(&self) -> String {
        let plain: String = self
            .name
            .chars()
            .map(|c| {
                if c.is_alphanumeric() || "-_.".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if plain.len() <= 100 {
            return plain;
        }
        // FNV-1a, 64 bits: stable across builds and platforms.
        let hash = self.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        });
        let head: String = plain.chars().take(80).collect();
        format!("{head}-{hash:016x}")
    }
}

/// Temperatures [K] whose fourth power (the radiation law, θ⁴) stays finite with room
/// for the Stefan–Boltzmann factor: θ ≤ 1e70 K.
pub const MAX_TEMPERATURE: f64 = 1e70;

/// The largest specific heat capacity C accepted [J/(kg·K)]: far above any material
/// (≈ 1.4e4 for hydrogen), far below where m C or the cooling constants σεA/(m C) leave
/// f64's range.
const MAX_HEAT_CAPACITY: f64 = 1e100;

impl Scenario {
    /// The derived constants of the scene are finite and, where they divide, not zero:
    /// the box volume (2D)³, the primary grain's mass m0 = (4/3)π b0³ ρ with m0² normal
    /// and (N m0)² finite (reduced masses and energies multiply two masses; the whole
    /// cloud can merge into one body), its heat capacity m0 C, and the radiation law's
    /// θ⁴ at the hottest given temperature.
    fn check_derived(&self, v: &mut Validator) {
        let d = self.domain.half_width;
        if !(1e-100..=1e100).contains(&d) {
            v.issues.push(ValidationIssue {
                path: "box.half_width".into(),
                message: format!(
                    "the box volume (2D)³ = {:e} m³ overflows or vanishes; allowed 1e-100 m ≤ D ≤ 1e100 m (got {})",
                    self.domain.side().powi(3),
                    agglo_engine::readable::exact(d),
                ),
            });
            return;
        }
        let b0 = self.primary_radius();
        let m0 = 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) * self.material.rho;
        let total = m0 * self.cloud.count.max(self.cloud.bodies.len()) as f64;
        let radius_field = if self.cloud.radius.is_some() {
            "cloud.radius"
        } else {
            "cloud.size_ratio"
        };
        if !(b0.powi(2).is_normal() && (m0 * m0).is_normal() && (m0 * self.material.C).is_normal())
        {
            v.issues.push(ValidationIssue {
                path: radius_field.into(),
                message: format!(
                    "the primary radius b0 = {b0:e} m gives a primary mass m0 = {m0:e} kg (ρ = {:e}) \
                     whose square underflows; allowed b0 and ρ with m0 > 1e-150 kg",
                    self.material.rho
                ),
            });
        }
        if !(total * total).is_finite() {
            v.issues.push(ValidationIssue {
                path: "material.rho".into(),
                message: format!(
                    "the cloud's mass N m0 = {total:e} kg overflows when squared (reduced masses, \
                     energies); allowed ρ and b0 with N m0 < 1e150 kg (got ρ = {:e})",
                    self.material.rho
                ),
            });
        }
        // Under drag, every body from a primary to the whole cloud merged into one needs
        // a relaxation time τ that is positive and finite, with a finite terminal
        // velocity u + g τ: an Epstein gas of density 1e-320 gave τ = ∞ and every
        // position NaN.
        if let Some(drag) = self.field.drag
            && v.issues.is_empty()
        {
            let field = match drag.relaxation {
                Relaxation::Constant { .. } => "field.drag.relaxation.constant.tau",
                Relaxation::Stokes { .. } => "field.drag.relaxation.stokes.viscosity",
                Relaxation::Epstein { .. } => "field.drag.relaxation.epstein.gas_density",
            };
            let radius_of = |mass: f64| b0 * (mass / m0).cbrt();
            for mass in [m0, total] {
                let tau = self.field.relaxation_time(mass, radius_of(mass));
                let terminal = glam::DVec3::from_array(drag.gas_velocity) + self.field.g() * tau;
                if !(tau.is_finite() && tau.is_normal() && terminal.is_finite()) {
                    v.issues.push(ValidationIssue {
                        path: field.into(),
                        message: format!(
                            "gives a body of {mass:e} kg the relaxation time τ = {tau:e} s \
                             (terminal velocity {terminal}); allowed values giving a finite \
                             τ > 0 and a finite terminal velocity for every body from a \
                             primary to the whole cloud"
                        ),
                    });
                    break;
                }
            }
        }
        let m = &self.material;
        for (path, theta) in [
            ("material.theta0", m.theta0),
            ("material.theta_s", m.theta_s),
        ] {
            if theta > MAX_TEMPERATURE {
                v.push(path, "0 ≤ θ ≤ 1e70 K (the radiation law takes θ⁴)", theta);
            } else if v.issues.is_empty() {
                // The cooling rate of a primary at θ: k_c θ + k_r θ⁴ [K/s] must be finite.
                let law = agglo_engine::laws::cooling::CoolingLaw::for_body(m, m0, b0);
                let rate = law.k_convection * theta + law.k_radiation * theta.powi(4);
                if !rate.is_finite() {
                    v.issues.push(ValidationIssue {
                        path: path.into(),
                        message: format!(
                            "a primary grain (b0 = {b0:e} m) at θ = {theta:e} K cools at an \
                             infinite rate k_c θ + k_r θ⁴; allowed θ with a finite rate (got {})",
                            agglo_engine::readable::exact(theta)
                        ),
                    });
                }
            }
        }
        for (i, body) in self.cloud.bodies.iter().enumerate() {
            if let Some(theta) = body.temperature
                && theta > MAX_TEMPERATURE
            {
                v.push(
                    &format!("cloud.bodies.{i}.temperature"),
                    "0 < θ ≤ 1e70 K (the radiation law takes θ⁴)",
                    theta,
                );
            }
        }
    }
}

/// `base` with each `PATH=VALUE` applied (VALUE parsed as JSON, else taken as a string),
/// then parsed and checked as a file is; the name gains the settings so the outputs say
/// what ran. `agglo run --set` and `agglo study readings --set`.
pub fn with_settings(base: &Scenario, settings: &[String]) -> anyhow::Result<Scenario> {
    use serde_json::Value;
    let mut value = serde_json::to_value(base)?;
    for setting in settings {
        let (path, raw) = setting
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--set {setting}: expected PATH=VALUE"))?;
        let new: Value = serde_json::from_str(raw).unwrap_or_else(|_| Value::from(raw));
        let mut slot = &mut value;
        let keys: Vec<&str> = path.split('.').collect();
        for (i, key) in keys.iter().enumerate() {
            let above = keys[..i].join(".");
            // A section the scenario leaves out (`output.restart`) is null here: setting
            // a field inside it creates it. A key that is no field of its section is
            // added too, and the scenario's own parsing names it with the fields there
            // are (`scenario field `nosuch`: unknown field ...`): the first segment that
            // does not exist is the one named.
            if slot.is_null() {
                *slot = Value::Object(Default::default());
            }
            slot = match slot {
                Value::Object(map) => map.entry(*key).or_insert(Value::Null),
                Value::Array(items) => {
                    let len = items.len();
                    key.parse::<usize>()
                        .ok()
                        .and_then(|k| items.get_mut(k))
                        .ok_or_else(|| {
                            anyhow::anyhow!(
                                "--set {setting}: `{above}` is a list of {len}; no element `{key}`"
                            )
                        })?
                }
                other => anyhow::bail!(
                    "--set {setting}: `{above}` is a value ({other}), not a section: it has \
                     no field `{key}`"
                ),
            };
        }
        *slot = new;
    }
    let mut scenario = Scenario::from_value(value)
        .map_err(|e| anyhow::anyhow!("--set {}: {e}", settings.join(" ")))?;
    // The name records what changes the run; where its outputs go (`output.*`) does not,
    // and a name carrying it would name the outputs after themselves (a restart file
    // `quick_demo__output.restart.every_1e-3_.restart`).
    let physics: Vec<&str> = settings
        .iter()
        .map(String::as_str)
        .filter(|s| {
            let path = s.split('=').next().unwrap_or("").trim();
            path != "output" && !path.starts_with("output.")
        })
        .collect();
    if !physics.is_empty() {
        scenario.name = format!("{} ({})", base.name, physics.join(", "));
    }
    Ok(scenario)
}

impl Scenario {
    /// This scenario with `--set PATH=VALUE` settings applied: [`with_settings`].
    pub fn with_settings(&self, settings: &[String]) -> anyhow::Result<Scenario> {
        with_settings(self, settings)
    }
}

/// What a JSON text starting with `first` holds at its top level, if `first` can start
/// one: used to say what a scenario file holds instead of an object.
fn json_kind(first: char) -> Option<&'static str> {
    match first {
        '[' => Some("an array"),
        '"' => Some("a string"),
        't' | 'f' => Some("a boolean"),
        'n' => Some("null"),
        '-' | '0'..='9' => Some("a number"),
        _ => None,
    }
}

/// The largest speed a scenario may give [m/s] (defined with the engine's scene types).
pub use agglo_engine::scene::MAX_SPEED;

/// True when none of the per-body checks of [`Scenario::validate`] would complain.
fn body_is_plausible(b: &PlacedBody) -> bool {
    let positive = |x: Option<f64>| x.is_none_or(|x| x.is_finite() && x > 0.0);
    b.position.iter().all(|x| x.is_finite())
        && b.velocity
            .is_none_or(|v| v.iter().all(|x| x.is_finite()) && norm(v) <= MAX_SPEED)
        && b.primaries >= 1.0
        && b.primaries.is_finite()
        && positive(b.temperature)
        && positive(b.mass)
        && positive(b.radius)
}

/// Length of a 3-vector [same unit as its components].
/// |x|, without overflowing for components up to f64::MAX / √3 (the sum of squares of
/// components ≳ 1.34e154 is ∞; hypot scales first).
fn norm(x: [f64; 3]) -> f64 {
    x[0].hypot(x[1]).hypot(x[2])
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
            message: format!(
                "allowed {allowed} (got {})",
                agglo_engine::readable::exact(got)
            ),
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
    fn range_open_closed(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x > lo && x <= hi) {
            self.push(path, allowed, x);
        }
    }
    fn range_closed(&mut self, path: &str, x: f64, lo: f64, hi: f64, allowed: &str) {
        if !(x >= lo && x <= hi) {
            self.push(path, allowed, x);
        }
    }
    /// A speed [m/s] above [`MAX_SPEED`]. ∞ counts (finite components whose norm
    /// overflows, e.g. v̄ = (1e200, 0, 0), validated and then hung the run); NaN is
    /// reported by the finiteness checks.
    fn below_speed_limit(&mut self, path: &str, speed: f64) {
        if speed > MAX_SPEED {
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

impl Scene for Scenario {
    fn name(&self) -> &str {
        &self.name
    }
    fn seed(&self) -> u64 {
        self.seed
    }
    fn domain(&self) -> &Domain {
        &self.domain
    }
    fn cloud(&self) -> &Cloud {
        &self.cloud
    }
    fn material(&self) -> &Material {
        &self.material
    }
    fn time(&self) -> &TimeControl {
        &self.time
    }
    fn physics(&self) -> &Physics {
        &self.physics
    }
    fn validate(&self) -> Result<(), ScenarioError> {
        Scenario::validate(self)
    }
    /// The plugins' sections as they are, and the whole description for the drivers.
    fn insert_settings(&self, world: &mut World) {
        world.insert_resource(self.impact);
        world.insert_resource(self.diagnostics.clone());
        if !self.field.is_none() {
            world.insert_resource(self.field);
        }
        if let Some(restart) = &self.output.restart {
            // The checkpoints are part of the run (engine/restart.rs): every simulation
            // of this scenario takes them, whatever writes them out.
            world.insert_resource(agglo_engine::restart::Checkpoints::every(restart.every));
        }
        crate::plugins::registry::insert_sections(&self.plugins, world);
        world.insert_resource(self.clone());
    }
}
