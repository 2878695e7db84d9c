//! Scenario files: the JSON description of one run, its validation, and the
//! JSON Schema printed by `agglo schema`.
//!
//! A scenario fully describes a run (box, cloud, material, impact model, time
//! control, physics toggles, diagnostics, seed, output). Each section is a type that
//! lives with the concern that reads it and is inserted into the world as it is
//! (docs/architecture.md, "settings"): `box`, `cloud`, `material`, `time` and `physics`
//! in the engine, `impact` and `diagnostics` in their plugins, `output` with the
//! drivers; this file puts them together, loads and checks them. Parsing reports the field path of a
//! type error or unknown field (via `serde_path_to_error`); then each section checks
//! its own ranges (an `issues()` beside its type, naming the field by its path and the
//! allowed range, as an extension's `PluginSection` does), and [`Scenario::validate`]
//! is the loop over them plus the checks that need the whole scene (derived constants,
//! explicit bodies, extension sections). Symbols follow docs/model.md §1: all values SI.

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
use agglo_engine::issues::Issues;
pub use agglo_engine::resources::BoxGeometry as Domain;
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
    /// The bodies at t = 0: a random cloud or explicit bodies.
    pub cloud: Cloud,
    /// The grains' material: density, hardness, heat, cooling.
    pub material: Material,
    #[serde(default)]
    /// The impact/heat solve (docs/model.md §5).
    pub impact: ImpactModel,
    /// The end time and how the steps are chosen.
    pub time: TimeControl,
    #[serde(default)]
    /// Which physics runs: merging, fragmentation, the cooling integrator, the contact
    /// rule, impacts per step.
    pub physics: Physics,
    /// Forces every body feels between events: uniform g, linear gas drag
    /// (docs/model.md §4.7). None when absent.
    #[serde(default, skip_serializing_if = "Field::is_none")]
    pub field: Field,
    #[serde(default)]
    /// The invariant checks during the run.
    pub diagnostics: Diagnostics,
    #[serde(default)]
    /// What the run writes and where.
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
        scenario.take_old_names()?;
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
        scenario.take_old_names()?;
        scenario.load_cloud_file()?;
        crate::plugins::registry::canonical_sections(&mut scenario.plugins);
        scenario.validate()?;
        Ok(scenario)
    }

    /// Move fields given by a deprecated name to their current one: `output.mcap` is
    /// `output.recording.path` (issue 40: the recording has one name, as `--recording`
    /// and Python's `recording=`). Both at once is refused, naming both.
    pub fn take_old_names(&mut self) -> Result<(), ScenarioError> {
        if let Some(path) = self.output.mcap.take() {
            if self.output.recording.path.is_some() {
                return Err(ScenarioError::Invalid(vec![ValidationIssue {
                    path: "output.mcap".into(),
                    message: "output.mcap is the old name of output.recording.path: give \
                              only output.recording.path"
                        .into(),
                }]));
            }
            self.output.recording.path = Some(path);
        }
        Ok(())
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
        // Each section checks itself (paths and ranges in its own words), then the
        // checks that need the whole scene.
        let mut v = Issues {
            issues: [
                self.domain.issues(),
                self.cloud.issues(&self.domain),
                self.material.issues(),
                self.impact.issues(),
                self.time.issues(&self.physics),
                self.diagnostics.issues(),
                self.output.issues(&self.time),
                self.field.issues(),
                self.physics.rigid_issues(&self.time, !self.field.is_none()),
            ]
            .concat(),
        };
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

impl Scenario {
    /// The derived constants of the scene are finite and, where they divide, not zero:
    /// the box volume (2D)³, the primary grain's mass m0 = (4/3)π b0³ ρ with m0² normal
    /// and (N m0)² finite (reduced masses and energies multiply two masses; the whole
    /// cloud can merge into one body), its heat capacity m0 C, and the radiation law's
    /// θ⁴ at the hottest given temperature.
    fn check_derived(&self, v: &mut Issues) {
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
