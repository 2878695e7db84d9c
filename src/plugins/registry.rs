//! The registry of extensions a program adds beside the built-in physics, and what it
//! does with their sections, `plugins.NAME` of a scenario: parse and check them, fill
//! in their defaults, document them, insert them into a world, and build the plugins
//! that apply. It works on the sections alone (a scenario's `plugins` map), so the
//! scenario can use it without the two depending on each other; [`super`] is the
//! face the drivers call with a whole scenario.

use std::collections::BTreeMap;
use std::sync::{Arc, RwLock};

use bevy_ecs::prelude::*;
use schemars::JsonSchema;
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::error::{SimError, ValidationIssue};
use crate::schedule::{SimBuilder, SimPlugin};
use agglo_engine::setup::Scene;

/// A scenario's plugin sections: each plugin's name and its section as given.
pub type Sections = BTreeMap<String, Value>;

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

/// The problems of a scenario's `plugins`, with full paths (`plugins.NAME.FIELD`).
pub(crate) fn check_sections(sections: &Sections) -> Vec<ValidationIssue> {
    let mut issues = Vec::new();
    for (name, value) in sections {
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

/// Each known section in its canonical form (parsed, defaults filled
/// in), so that genes and `--set` find every field. Unknown or faulty sections are left
/// as given, for [`check_sections`] to report.
pub(crate) fn canonical_sections(sections: &mut Sections) {
    for (name, value) in sections.iter_mut() {
        if let Some(Some(kind)) = find(name).map(|e| e.section)
            && let Ok(canonical) = (kind.check)(value)
        {
            *value = canonical;
        }
    }
}

/// Insert each section as its typed resource.
pub(crate) fn insert_sections(sections: &Sections, world: &mut World) {
    for (name, value) in sections {
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

/// Build the registered extensions that apply to a scene with `sections` into
/// `builder` (after the built-in physics): those with a section the scene carries, and
/// those without one.
pub fn add_extensions(builder: &mut SimBuilder, sections: &Sections) {
    for extension in registered() {
        if extension.section.is_none() || sections.contains_key(extension.name()) {
            builder.add_plugin(extension.plugin.as_ref());
        }
    }
}

/// The builder of `scene` (whose plugin sections are `sections`) with the built-in
/// physics and the registered extensions.
pub(crate) fn build(scene: &dyn Scene, sections: &Sections) -> Result<SimBuilder, SimError> {
    Ok(with_plugins(
        crate::schedule::Simulation::builder(scene)?,
        sections,
    ))
}

/// `builder` with the built-in physics and the registered extensions (`sections`: the
/// scene's plugin sections).
pub(crate) fn with_plugins(mut builder: SimBuilder, sections: &Sections) -> SimBuilder {
    use agglo_systems::AddDefaultPlugins;
    builder.add_default_plugins();
    add_extensions(&mut builder, sections);
    builder
}
