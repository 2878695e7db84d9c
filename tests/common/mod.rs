//! Helpers shared by the integration tests: scenarios built from JSON snippets.
#![allow(dead_code)]

pub mod cells;

use agglo::prelude::*;
use serde_json::{Value, json};

/// A scenario with sensible defaults; `patch` is merged over it (objects merge, other values replace).
pub fn scenario(patch: Value) -> Scenario {
    let mut base = json!({
        "name": "test",
        "seed": 1,
        "box": { "half_width": 0.01 },
        "cloud": { "count": 2, "radius": 0.001, "v_rel": [0, 0, 0] },
        "material": { "rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300 },
        "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 },
        "time": { "end": 0.002 }
    });
    merge(&mut base, patch);
    Scenario::from_value(base).expect("test scenario is valid")
}

/// Deep-merge `patch` into `base`.
pub fn merge(base: &mut Value, patch: Value) {
    match (base, patch) {
        (Value::Object(b), Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k).or_insert(Value::Null), v);
            }
        }
        (b, p) => *b = p,
    }
}

/// Two bodies on the x axis: `left` primaries at x = −gap_half − ..., moving with the given velocities.
pub fn pair(x_left: f64, v_left: f64, x_right: f64, v_right: f64) -> Value {
    json!({
        "cloud": {
            "count": 2,
            "bodies": [
                { "position": [x_left, 0, 0], "velocity": [v_left, 0, 0] },
                { "position": [x_right, 0, 0], "velocity": [v_right, 0, 0] }
            ]
        }
    })
}

/// b_f/b0 of `agglo run SCENE --seed SEED -q --summary` (the binary, as a user runs
/// it), with the summary written in `dir`; the run must succeed.
pub fn growth_of_agglo_run(scene: &std::path::Path, seed: u64, dir: &std::path::Path) -> f64 {
    let summary = dir.join(format!("summary_{seed}.json"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
        .arg("run")
        .arg(scene)
        .args(["-q", "--seed", &seed.to_string(), "--summary"])
        .arg(&summary)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    v["growth"]["growth_ratio"].as_f64().unwrap()
}

/// Mean and standard error of the mean of `xs` (n ≥ 2).
pub fn mean_and_standard_error(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Two ensembles (`a` from the event core, `b` from the stepped core) agree on `what`:
/// their means differ by at most 3 standard errors of the difference (or by rounding,
/// 1e-12 of the mean, when both spreads vanish).
pub fn assert_cores_agree(what: &str, a: &[f64], b: &[f64]) {
    let ((ma, sa), (mb, sb)) = (mean_and_standard_error(a), mean_and_standard_error(b));
    let bound = 3.0 * (sa * sa + sb * sb).sqrt();
    assert!(
        (ma - mb).abs() <= bound.max(1e-12 * ma.abs()),
        "{what}: events {ma} ± {sa}, stepped {mb} ± {sb}"
    );
}
