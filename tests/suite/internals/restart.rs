//! Unit tests of `restart` (src/restart.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::restart::*;
use agglo::scenario::Scenario;
use std::path::Path;

fn snapshot() -> (Scenario, RestartSnapshot) {
    let scenario = Scenario::from_json(
        r#"{"name": "t", "seed": 3, "box": {"half_width": 0.01},
            "cloud": {"count": 20, "radius": 1e-4, "v_rel": [1, 1, 1]},
            "material": {"rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300},
            "impact": {"a0": 0.5, "af": 1.0, "beta": 1.0}, "time": {"end": 1e-3},
            "output": {"restart": {"every": 1e-4}}}"#,
    )
    .unwrap();
    let mut sim = agglo_engine::schedule::Simulation::builder(&scenario).unwrap();
    agglo_systems::AddDefaultPlugins::add_default_plugins(&mut sim);
    let mut sim = sim.build().unwrap();
    let snapshot = agglo_engine::restart::capture(sim.world_mut());
    (scenario, snapshot)
}

#[test]
fn a_file_reads_back_exactly() {
    let (scenario, snapshot) = snapshot();
    let bytes = encode(&scenario, &snapshot);
    let (s, back) = decode(Path::new("x.restart"), &bytes).unwrap();
    assert_eq!(back, snapshot);
    assert_eq!(s.to_json(), scenario.to_json());
}

#[test]
fn other_files_and_versions_are_refused_naming_the_file() {
    let (scenario, snapshot) = snapshot();
    let path = Path::new("x.restart");
    let error = decode(path, b"{\"name\": 1}").unwrap_err().to_string();
    assert!(
        error.contains("x.restart is not an agglo restart file"),
        "{error}"
    );
    let mut bytes = encode(&scenario, &snapshot);
    bytes[MAGIC.len()] = 9;
    let error = decode(path, &bytes).unwrap_err().to_string();
    assert!(
        error.contains("x.restart: restart format version 9"),
        "{error}"
    );
    let bytes = &encode(&scenario, &snapshot)[..MAGIC.len() + 3];
    let error = decode(path, bytes).unwrap_err().to_string();
    assert!(error.contains("x.restart ends early"), "{error}");
}
