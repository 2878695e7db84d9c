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

pub(crate) mod registry;

pub use registry::{Extension, PluginSection, Sections, add_extensions, issue, names, register};

use crate::error::SimError;
use crate::scenario::Scenario;
use crate::schedule::{SimBuilder, Simulation};

/// The scenario's builder with the built-in physics and the registered extensions:
/// what every driver builds from.
pub fn builder(scenario: &Scenario) -> Result<SimBuilder, SimError> {
    registry::build(scenario, &scenario.plugins)
}

/// [`builder`] for a simulation to be resumed from `snapshot` next, whose run started
/// with `initial_bodies` bodies (`SimBuilder::resuming`: the scene's initial cloud is
/// neither placed nor spawned; what else must be given is listed there).
pub fn resuming_builder(
    scenario: &Scenario,
    snapshot: &agglo_engine::restart::RestartSnapshot,
    initial_bodies: usize,
) -> Result<SimBuilder, SimError> {
    let builder = SimBuilder::resuming(scenario, snapshot, initial_bodies)?;
    Ok(registry::with_plugins(builder, &scenario.plugins))
}

/// The scenario's simulation with the built-in physics and the registered extensions.
pub fn simulation(scenario: &Scenario) -> Result<Simulation, SimError> {
    builder(scenario)?.build()
}

/// `Simulation::new(&scenario)` from `agglo::prelude`: the scene with the built-in
/// physics and every registered extension, as every driver builds it ([`simulation`]).
/// (`agglo_systems::NewBuiltinSimulation::new` builds the built-ins alone, for programs that
/// use the engine without this package.)
pub trait NewSimulation {
    /// The scenario's simulation with the built-in physics and the registered extensions.
    fn new(scenario: &Scenario) -> Result<Self, SimError>
    where
        Self: Sized;
}

impl NewSimulation for Simulation {
    fn new(scenario: &Scenario) -> Result<Self, SimError> {
        simulation(scenario)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ValidationIssue;
    use crate::schedule::SimPlugin;
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
