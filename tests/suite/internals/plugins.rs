//! Unit tests of `plugins` (src/plugins/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::error::ValidationIssue;
use agglo::plugins::*;
use agglo::scenario::Scenario;
use agglo::schedule::SimBuilder;
use agglo::schedule::SimPlugin;
use bevy_ecs::prelude::*;
use schemars::JsonSchema;
use serde::Serialize;

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

fn scene(plugins: &str) -> Result<Scenario, agglo::error::ScenarioError> {
    Scenario::from_json(&format!(
        r#"{{"name": "k", "seed": 1, "box": {{"half_width": 0.01}},
            "cloud": {{"count": 2, "radius": 1e-3, "v_rel": [0, 0, 0]}},
            "material": {{"rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300}},
            "time": {{"end": 1e-3}}, "plugins": {plugins}}}"#
    ))
}

// One test: the registry is the process's, and the whole suite shares one process
// (no other test registers an extension; one that does must join this test).
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
