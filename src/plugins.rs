//! Extensions in the binary: plugins a program registers beside the built-in physics,
//! each with an optional section of the scenario, `plugins.NAME` (docs/extending.md).
//!
//! A section is a type ([`PluginSection`]: serde, JSON Schema and a range check) that
//! gets what a built-in section gets: `agglo schema` documents it, parsing and
//! [`Scenario::validate`] check it (each problem named by its full path,
//! `plugins.charged_grains.q0`, with the allowed range), `--set` and the inverse
//! problem's genes address it by that path, and the recording and restart file embed
//! it with the scenario. During a build it is a resource of the world: the plugin reads
//! it in `build` (`SimBuilder::resource`) and its systems read it as `Res<S>`.
//!
//! The registry is one list per process, filled before anything is parsed (by
//! [`crate::cli::main_with`], or by [`register`] in a program that drives the library
//! itself), so every simulation the drivers build — a run, each sample of an ensemble
//! on a worker thread, a study, another MPI rank running the same binary — gets the same
//! plugins. A plugin with a section is built only into scenes that carry its section (a
//! scene runs only what it needs); one without is built into every scene. A scenario
//! naming a plugin the binary does not have is refused, naming it and listing the ones
//! the binary has.

use std::sync::{Arc, RwLock};

use bevy_ecs::prelude::*;
use schemars::JsonSchema;
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::error::{SimError, ValidationIssue};
use crate::scenario::Scenario;
use crate::schedule::{SimBuilder, SimPlugin, Simulation};

/// The section of the scenario a plugin reads, `plugins.NAME` (NAME the plugin's
/// [`SimPlugin::name`]). Give every field a serde default where one makes sense, so a
/// scene may write only what it changes; the parsed section, defaults filled in, is what
/// the scenario holds (and what genes and `--set` address).
pub trait PluginSection:
    Resource + Clone + Serialize + DeserializeOwned + JsonSchema + Send + Sync + 'static
{
    /// Every range problem of the section, each naming its field by its path inside
    /// the section (`q0`, `law.scale`) and saying the allowed range and the value
    /// given, e.g. `allowed 0 ≤ q0 ≤ 1e-6 C (got -1)`; [`issue`] formats one.
    fn validate(&self) -> Vec<ValidationIssue> {
        Vec::new()
    }
}

/// A range problem of a section field: `field` its path inside the section, `allowed`
/// the range in words with its unit, `got` the value given.
pub fn issue(field: &str, allowed: &str, got: impl std::fmt::Display) -> ValidationIssue {
    ValidationIssue {
        path: field.into(),
        message: format!("allowed {allowed} (got {got})"),
    }
}

/// What the registry knows of a section type, without naming it.
#[derive(Clone, Copy)]
struct SectionKind {
    /// Parse and check a section: its canonical value (defaults filled in), or its
    /// problems with paths inside the section.
    check: fn(&Value) -> Result<Value, Vec<ValidationIssue>>,
    /// Insert the parsed section into the world being built.
    insert: fn(&Value, &mut World),
    /// The section's JSON Schema.
    schema: fn() -> Value,
}

impl SectionKind {
    fn of<S: PluginSection>() -> Self {
        Self {
            check: |value| {
                let section: S = serde_path_to_error::deserialize(value.clone()).map_err(|e| {
                    vec![ValidationIssue {
                        path: e.path().to_string(),
                        message: e.inner().to_string(),
                    }]
                })?;
                let issues = section.validate();
                if !issues.is_empty() {
                    return Err(issues);
                }
                Ok(serde_json::to_value(&section).expect("a section serialises")) // ok: it was just parsed from a value
            },
            insert: |value, world| {
                // Checked when the scenario was parsed and validated (SimBuilder::new
                // validates it again before anything is built).
                if let Ok(section) = serde_json::from_value::<S>(value.clone()) {
                    world.insert_resource(section);
                }
            },
            schema: || serde_json::to_value(schemars::schema_for!(S)).expect("schema serialises"), // ok: plain data
        }
    }
}

/// A plugin a program adds to the command line (or to its own drivers), with its
/// section if it has one.
pub struct Extension {
    plugin: Box<dyn SimPlugin + Send + Sync>,
    section: Option<SectionKind>,
}

impl Extension {
    /// A plugin without a section: built into every scene.
    pub fn plugin(plugin: impl SimPlugin + Send + Sync + 'static) -> Self {
        Self {
            plugin: Box::new(plugin),
            section: None,
        }
    }

    /// A plugin whose parameters are the scenario section `plugins.NAME` of type `S`:
    /// built only into scenes that carry the section, where `S` is a resource.
    pub fn with_section<S: PluginSection>(plugin: impl SimPlugin + Send + Sync + 'static) -> Self {
        Self {
            plugin: Box::new(plugin),
            section: Some(SectionKind::of::<S>()),
        }
    }

    /// The plugin's name, and its section's key under `plugins`.
    pub fn name(&self) -> &'static str {
        self.plugin.name()
    }
}

impl<P: SimPlugin + Send + Sync + 'static> From<P> for Extension {
    fn from(plugin: P) -> Self {
        Extension::plugin(plugin)
    }
}

/// The process's extensions, in the order they were registered (their build order).
static REGISTRY: RwLock<Vec<Arc<Extension>>> = RwLock::new(Vec::new());

fn registered() -> Vec<Arc<Extension>> {
    REGISTRY.read().unwrap_or_else(|e| e.into_inner()).clone()
}

fn find(name: &str) -> Option<Arc<Extension>> {
    registered().into_iter().find(|e| e.name() == name)
}

/// Add `extension` to every simulation this process's drivers build from now on.
/// Register before parsing scenarios that carry its section. A second extension of a
/// name already registered, or of a built-in plugin's name, is refused.
pub fn register(extension: impl Into<Extension>) -> Result<(), String> {
    let extension = extension.into();
    let name = extension.name();
    if builtin_names().contains(&name) {
        return Err(format!(
            "plugin `{name}`: the name of a built-in plugin; give the extension its own name"
        ));
    }
    let mut list = REGISTRY.write().unwrap_or_else(|e| e.into_inner());
    if list.iter().any(|e| e.name() == name) {
        return Err(format!("plugin `{name}` is registered twice"));
    }
    list.push(Arc::new(extension));
    Ok(())
}

/// The names of the registered extensions, in build order.
pub fn names() -> Vec<&'static str> {
    registered().iter().map(|e| e.name()).collect()
}

/// The built-in plugins' names.
fn builtin_names() -> Vec<&'static str> {
    agglo_systems::default_plugins()
        .iter()
        .map(|p| p.name())
        .collect()
}

/// The problems of `scenario.plugins`, with full paths (`plugins.NAME.FIELD`).
pub(crate) fn check_sections(scenario: &Scenario) -> Vec<ValidationIssue> {
    let mut issues = Vec::new();
    for (name, value) in &scenario.plugins {
        let path = format!("plugins.{name}");
        match find(name).map(|e| e.section) {
            Some(Some(kind)) => {
                if let Err(inner) = (kind.check)(value) {
                    issues.extend(inner.into_iter().map(|i| ValidationIssue {
                        path: if i.path.is_empty() || i.path == "." {
                            path.clone()
                        } else {
                            format!("{path}.{}", i.path)
                        },
                        message: i.message,
                    }));
                }
            }
            Some(None) => issues.push(ValidationIssue {
                path,
                message: format!("plugin `{name}` has no section; remove it"),
            }),
            None => issues.push(ValidationIssue {
                path,
                message: format!("this binary has no plugin `{name}`; {}", what_it_has()),
            }),
        }
    }
    issues
}

/// The registered plugins with a section, in words, for the refusal of an unknown one.
fn what_it_has() -> String {
    let with_sections: Vec<&str> = registered()
        .iter()
        .filter(|e| e.section.is_some())
        .map(|e| e.name())
        .collect();
    if with_sections.is_empty() {
        "it has no plugin sections (the `agglo` command runs the built-in physics; a \
         program adds its own plugins with agglo::cli::main_with, docs/extending.md)"
            .into()
    } else {
        format!("it has: {}", with_sections.join(", "))
    }
}

/// Each known section of `scenario` in its canonical form (parsed, defaults filled
/// in), so that genes and `--set` find every field. Unknown or faulty sections are left
/// as given, for [`check_sections`] to report.
pub(crate) fn canonical_sections(scenario: &mut Scenario) {
    for (name, value) in scenario.plugins.iter_mut() {
        if let Some(Some(kind)) = find(name).map(|e| e.section)
            && let Ok(canonical) = (kind.check)(value)
        {
            *value = canonical;
        }
    }
}

/// Insert each section of `scenario` as its typed resource.
pub(crate) fn insert_sections(scenario: &Scenario, world: &mut World) {
    for (name, value) in &scenario.plugins {
        if let Some(Some(kind)) = find(name).map(|e| e.section) {
            (kind.insert)(value, world);
        }
    }
}

/// The `plugins` property of the scenario's JSON Schema: one property per registered
/// section, each its type's schema; their definitions go to `defs`.
pub(crate) fn sections_schema(defs: &mut serde_json::Map<String, Value>) -> Value {
    let mut properties = serde_json::Map::new();
    for extension in registered() {
        let Some(kind) = extension.section else {
            continue;
        };
        let mut schema = (kind.schema)();
        if let Some(Value::Object(own)) = schema.as_object_mut().and_then(|s| s.remove("$defs")) {
            defs.extend(own);
        }
        if let Some(s) = schema.as_object_mut() {
            s.remove("$schema");
        }
        properties.insert(extension.name().to_string(), schema);
    }
    serde_json::json!({
        "description": "Sections of the plugins this binary carries beside the built-in \
                        physics, one per plugin, named after it (docs/extending.md). A \
                        plugin with a section runs only in scenes that carry it.",
        "type": "object",
        "properties": properties,
        "additionalProperties": false,
    })
}

/// Build the registered extensions that apply to `scenario` into `builder` (after the
/// built-in physics): those with a section the scene carries, and those without one.
pub fn add_extensions(builder: &mut SimBuilder, scenario: &Scenario) {
    for extension in registered() {
        if extension.section.is_none() || scenario.plugins.contains_key(extension.name()) {
            builder.add_plugin(extension.plugin.as_ref());
        }
    }
}

/// The scenario's builder with the built-in physics and the registered extensions:
/// what every driver builds from.
pub fn builder(scenario: &Scenario) -> Result<SimBuilder, SimError> {
    use agglo_systems::AddDefaultPlugins;
    let mut builder = Simulation::builder(scenario)?;
    builder.add_default_plugins();
    add_extensions(&mut builder, scenario);
    Ok(builder)
}

/// The scenario's simulation with the built-in physics and the registered extensions.
pub fn simulation(scenario: &Scenario) -> Result<Simulation, SimError> {
    builder(scenario)?.build()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A section with one bounded field, and a plugin that reads it.
    #[derive(Resource, Clone, Serialize, serde::Deserialize, JsonSchema)]
    #[serde(deny_unknown_fields)]
    struct Knob {
        /// A dial [1].
        #[serde(default = "half")]
        level: f64,
    }
    fn half() -> f64 {
        0.5
    }
    impl PluginSection for Knob {
        fn validate(&self) -> Vec<ValidationIssue> {
            match (0.0..=1.0).contains(&self.level) {
                true => Vec::new(),
                false => vec![issue("level", "0 ≤ level ≤ 1", self.level)],
            }
        }
    }
    struct KnobPlugin(&'static str);
    impl SimPlugin for KnobPlugin {
        fn name(&self) -> &'static str {
            self.0
        }
        fn build(&self, sim: &mut SimBuilder) {
            let level = sim.resource::<Knob>().level;
            sim.leave_out(format!("knob at {level}"));
        }
    }

    fn scene(plugins: &str) -> Result<Scenario, crate::error::ScenarioError> {
        Scenario::from_json(&format!(
            r#"{{"name": "k", "seed": 1, "box": {{"half_width": 0.01}},
                "cloud": {{"count": 2, "radius": 1e-3, "v_rel": [0, 0, 0]}},
                "material": {{"rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300}},
                "time": {{"end": 1e-3}}, "plugins": {plugins}}}"#
        ))
    }

    // One test: the registry is the process's, and the unit tests share a process.
    #[test]
    fn a_registered_section_is_parsed_checked_documented_and_built() {
        // Refused: a built-in plugin's name, and a name registered twice.
        let error = register(Extension::with_section::<Knob>(KnobPlugin("impact"))).unwrap_err();
        assert!(error.contains("built-in"), "{error}");
        register(Extension::with_section::<Knob>(KnobPlugin("knob"))).unwrap();
        let error = register(Extension::with_section::<Knob>(KnobPlugin("knob"))).unwrap_err();
        assert!(error.contains("registered twice"), "{error}");
        assert_eq!(names(), ["knob"]);

        // The defaults are filled in, so a gene or --set finds the field.
        let s = scene(r#"{"knob": {}}"#).unwrap();
        assert_eq!(s.plugins["knob"], serde_json::json!({"level": 0.5}));
        // The plugin is built and reads its section as a resource.
        let p = s.pipeline().unwrap();
        assert!(p.left_out.contains(&"knob at 0.5".to_string()), "{p:?}");
        // Without the section it is not built.
        let p = scene("{}").unwrap().pipeline().unwrap();
        assert!(!p.left_out.iter().any(|l| l.starts_with("knob")), "{p:?}");
        // Every problem names its full path.
        for (plugins, words) in [
            (
                r#"{"knob": {"level": 2}}"#,
                "plugins.knob.level: allowed 0 ≤ level ≤ 1 (got 2)",
            ),
            (
                r#"{"knob": {"lvl": 1}}"#,
                "plugins.knob.lvl: unknown field `lvl`",
            ),
            (r#"{"knob": 3}"#, "plugins.knob: invalid type: integer `3`"),
            (
                r#"{"dial": {}}"#,
                "plugins.dial: this binary has no plugin `dial`; it has: knob",
            ),
        ] {
            let error = scene(plugins).unwrap_err().to_string();
            assert!(error.contains(words), "{plugins}: {error}");
        }
        // The schema documents the section's field.
        let schema = Scenario::json_schema();
        let level = &schema["properties"]["plugins"]["properties"]["knob"]["properties"]["level"];
        assert_eq!(level["description"], "A dial [1].", "{schema:#}");
    }
}
