//! Initial conditions from data (`cloud.from_file`, explicit bodies) and the new
//! velocity options: the checks `validate` and `run` share, continuing a run from its
//! own final state, Maxwellian velocities and zero total momentum.

use std::path::Path;
use std::process::Command;

use agglo::output::table::read_table;
use agglo::prelude::*;
use serde_json::{Value, json};

use crate::common::merge;

fn agglo(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn base() -> Value {
    json!({
        "name": "t", "seed": 1,
        "box": { "half_width": 0.01 },
        "cloud": { "radius": 0.001 },
        "material": { "rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300 },
        "time": { "end": 0.001 }
    })
}

/// `validate` and `run` refuse the same bodies with the same message: overlapping, out
/// of the box, a repeated id, a mass that does not match its primaries.
#[test]
fn validate_and_run_refuse_the_same_explicit_bodies() {
    let dir = tempfile::tempdir().unwrap();
    let body = |x: f64| json!({ "position": [x, 0, 0], "velocity": [0, 0, 0] });
    let cases = [
        (
            json!([body(0.0), body(0.0015)]),
            "cloud.bodies.0: overlaps cloud.bodies.1",
        ),
        (json!([body(0.0), body(0.02)]), "cloud.bodies.1.position.0"),
        (
            json!([{ "position": [0, 0, 0], "velocity": [0, 0, 0], "id": 7 },
                   { "position": [0.005, 0, 0], "velocity": [0, 0, 0], "id": 7 }]),
            "cloud.bodies.1.id: id 7 is also cloud.bodies.0's",
        ),
        (
            json!([{ "position": [0, 0, 0], "velocity": [0, 0, 0], "mass": 1e-5 }]),
            "cloud.bodies.0.mass",
        ),
    ];
    for (bodies, expected) in cases {
        let mut v = base();
        v["cloud"]["bodies"] = bodies;
        std::fs::write(dir.path().join("s.json"), v.to_string()).unwrap();
        for command in ["validate", "run"] {
            let out = agglo(
                &[command, "s.json", "-q"][..if command == "run" { 3 } else { 2 }],
                dir.path(),
            );
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{command} accepted {v}");
            assert!(err.contains(expected), "{command}: {err}");
        }
    }
}

/// The overlap check finds the one overlapping pair among many bodies, through the
/// periodic boundary and with unequal radii (the grid search, not a pair loop).
#[test]
fn overlap_check_finds_a_pair_across_the_boundary_among_a_thousand_bodies() {
    let mut bodies = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            for k in 0..10 {
                let at = |n: i32| -0.0095 + 0.0019 * f64::from(n);
                bodies.push(json!({ "position": [at(i), at(j), at(k)], "velocity": [0, 0, 0] }));
            }
        }
    }
    let mut v = base();
    v["cloud"]["bodies"] = json!(bodies.clone());
    v["cloud"]["radius"] = json!(0.0005);
    Scenario::from_value(v.clone()).expect("a lattice 1.9 mm apart of 0.5 mm grains is valid");
    // A two-primary body (radius 0.63 mm) at x = +D touches body 0 (x = −9.5 mm) through
    // the boundary: centres 0.5 mm apart.
    bodies.push(
        json!({ "position": [0.01, -0.0095, -0.0095], "velocity": [0, 0, 0], "primaries": 2 }),
    );
    v["cloud"]["bodies"] = json!(bodies);
    let err = Scenario::from_value(v).unwrap_err().to_string();
    assert!(
        err.contains("cloud.bodies.0: overlaps cloud.bodies.1000"),
        "{err}"
    );
}

#[test]
fn v_rel_is_needed_only_when_some_velocity_is_drawn() {
    let mut v = base();
    v["cloud"]["bodies"] = json!([{ "position": [0, 0, 0], "velocity": [1, 0, 0] }]);
    Scenario::from_value(v.clone()).expect("every body has its velocity: no v_rel");
    v["cloud"]["bodies"] = json!([{ "position": [0, 0, 0] }]);
    let err = Scenario::from_value(v.clone()).unwrap_err().to_string();
    assert!(err.contains("cloud.v_rel: required"), "{err}");
    v["cloud"]["v_rel"] = json!([2, 0, 0]);
    let s = Scenario::from_value(v).unwrap();
    let vx = Simulation::new(&s).unwrap().bodies()[0].velocity.x;
    assert!(
        vx.abs() <= 2.0 && vx != 0.0,
        "drawn as v_rel λ, λ ∈ [−1, 1]: {vx}"
    );
    let mut generated = base();
    generated["cloud"]["count"] = json!(10);
    let err = Scenario::from_value(generated).unwrap_err().to_string();
    assert!(err.contains("cloud.v_rel: required"), "{err}");
}

#[test]
fn maxwell_velocities_have_the_granular_temperature_and_remove_drift_zeroes_momentum() {
    let n = 20_000;
    let tg = 4.0; // m²/s²
    let mut v = base();
    merge(
        &mut v,
        json!({ "box": { "half_width": 0.1 },
                "cloud": { "count": n, "radius": 0.0005, "velocity_distribution": "maxwell",
                           "granular_temperature": tg } }),
    );
    let bodies = Simulation::new(&Scenario::from_value(v.clone()).unwrap())
        .unwrap()
        .bodies();
    let nf = n as f64;
    for k in 0..3 {
        let c: Vec<f64> = bodies.iter().map(|b| b.velocity.to_array()[k]).collect();
        let mean = c.iter().sum::<f64>() / nf;
        let var = c.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (nf - 1.0);
        // Sampling errors: σ(mean) = √(T_g/N) = 0.014, σ(var) = T_g √(2/N) = 0.04; 5σ.
        assert!(
            mean.abs() < 5.0 * (tg / nf).sqrt(),
            "component {k}: mean {mean}"
        );
        assert!(
            (var - tg).abs() < 5.0 * tg * (2.0 / nf).sqrt(),
            "component {k}: variance {var}"
        );
        // Gaussian, not uniform: kurtosis 3 (uniform: 1.8); σ(kurtosis) ≈ √(24/N) = 0.035.
        let kurt = c.iter().map(|x| (x - mean).powi(4)).sum::<f64>() / nf / (var * var);
        assert!((kurt - 3.0).abs() < 0.2, "component {k}: kurtosis {kurt}");
    }
    v["cloud"]["remove_drift"] = json!(true);
    let bodies = Simulation::new(&Scenario::from_value(v.clone()).unwrap())
        .unwrap()
        .bodies();
    let p: glam::DVec3 = bodies.iter().map(|b| b.mass * b.velocity).sum();
    let scale: f64 = bodies.iter().map(|b| b.mass * b.velocity.length()).sum();
    // The shift is exact up to rounding of N terms: far below 1e-12 of Σ m|v|.
    assert!(p.length() < 1e-12 * scale, "{p} vs {scale}");
    v["cloud"]["v_mean"] = json!([1, 0, 0]);
    let err = Scenario::from_value(v).unwrap_err().to_string();
    assert!(err.contains("cloud.remove_drift"), "{err}");
}

/// A merging cloud on the stepped core with a fixed Δt, no fragmentation and no random
/// draws after set-up: run to T, or to T/2 and then from its own final state for T/2.
/// Δt and T are powers of two, so the clock of both halves is exact.
fn stepped_merging(end: f64) -> Value {
    json!({
        "name": "halves", "seed": 3,
        "box": { "half_width": 0.005 },
        "cloud": { "count": 300, "size_ratio": 0.6, "v_rel": [40, 40, 40] },
        "material": { "rho": 3000, "H0": 2e5, "C": 1000, "Q": 300, "alpha": 1e3,
                      "epsilon": 0.5, "theta0": 400, "theta_s": 300 },
        "impact": { "a0": 0.1, "af": 1.0, "beta": 1.0 },
        "time": { "end": end, "stepping": { "fixed": { "dt": 2f64.powi(-20) } }, "core": "stepped" }
    })
}

#[test]
fn a_run_continued_from_its_own_final_state_ends_where_the_whole_run_ends() {
    let dir = tempfile::tempdir().unwrap();
    let t_end = 2f64.powi(-11); // ≈ 4.9e-4 s: 512 steps; 300 → 77 bodies at T/2, 63 at T
    let write =
        |name: &str, v: &Value| std::fs::write(dir.path().join(name), v.to_string()).unwrap();
    write("whole.json", &stepped_merging(t_end));
    write("first.json", &stepped_merging(t_end / 2.0));
    let ok = |args: &[&str]| {
        let out = agglo(args, dir.path());
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    ok(&[
        "run",
        "whole.json",
        "-q",
        "--final-state",
        "whole.csv",
        "--summary",
        "whole_summary.json",
    ]);
    ok(&["run", "first.json", "-q", "--final-state", "half.csv"]);
    // The second half: the same scene from the file; b0 as a radius (a size ratio would
    // be taken of the file's body count).
    let first = Scenario::from_value(stepped_merging(t_end)).unwrap();
    let mut second = stepped_merging(t_end / 2.0);
    second["cloud"] = json!({ "radius": first.primary_radius(), "from_file": "half.csv" });
    write("second.json", &second);
    ok(&["run", "second.json", "-q", "--snapshots", "snap.parquet"]);

    let whole = read_table(&dir.path().join("whole.csv")).unwrap();
    let half = read_table(&dir.path().join("half.csv")).unwrap();
    // The snapshots' last sample is the continued run's end state.
    let snap = read_table(&dir.path().join("snap.parquet")).unwrap();
    let t = snap.floats("t").unwrap();
    let last: Vec<usize> = (0..t.len()).filter(|&k| t[k] == t_end / 2.0).collect();
    assert!(
        whole.len() < half.len() && half.len() < 300,
        "the cloud merges in both halves"
    );
    assert_eq!(last.len(), whole.len(), "same body count at T");
    for name in [
        "id",
        "x",
        "y",
        "z",
        "vx",
        "vy",
        "vz",
        "mass",
        "radius",
        "temperature",
        "primaries",
    ] {
        let a = whole.floats(name).unwrap();
        let b = snap.floats(name).unwrap();
        for (k, &row) in last.iter().enumerate() {
            // Same state, same steps, same order of operations: equal to the bit.
            assert_eq!(
                a[k].to_bits(),
                b[row].to_bits(),
                "{name} of body {k}: {} vs {}",
                a[k],
                b[row]
            );
        }
    }
}

#[test]
fn from_file_reads_the_last_snapshot_and_refuses_unknown_columns() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("b.csv"),
        "t,id,x,y,z,vx,vy,vz,primaries\n0,0,0,0,0,1,0,0,1\n0,1,0.005,0,0,-1,0,0,1\n\
         1e-3,4,0.001,0,0,1,0,0,2\n1e-3,9,-0.004,0,0,0,0,0,1\n",
    )
    .unwrap();
    let mut v = base();
    v["cloud"]["from_file"] = json!(dir.path().join("b.csv").to_str().unwrap());
    let s = Scenario::from_value(v.clone()).unwrap();
    assert_eq!(s.cloud.count, 2, "the rows of t = 1e-3 only");
    assert_eq!(s.cloud.from_file, None, "loaded into cloud.bodies");
    let sim = Simulation::new(&s).unwrap();
    let bodies = sim.bodies();
    assert_eq!(bodies.iter().map(|b| b.id).collect::<Vec<_>>(), vec![4, 9]);
    assert_eq!(bodies[0].primaries, 2.0);
    assert_eq!(
        bodies[0].temperature, 300.0,
        "θ0 when the file has no temperature"
    );
    std::fs::write(
        dir.path().join("c.csv"),
        "x,y,z,vx,vy,vz,colour\n0,0,0,0,0,0,1\n",
    )
    .unwrap();
    v["cloud"]["from_file"] = json!(dir.path().join("c.csv").to_str().unwrap());
    let err = Scenario::from_value(v.clone()).unwrap_err().to_string();
    assert!(err.contains("unknown column `colour`"), "{err}");
    // A row whose t is not a number belongs to no sample: refused by its row (15 of 20
    // bodies were dropped without a word).
    std::fs::write(
        dir.path().join("d.csv"),
        "t,x,y,z\n1e-3,0,0,0\nNaN,0.001,0,0\n1e-3,0.002,0,0\n",
    )
    .unwrap();
    v["cloud"]["from_file"] = json!(dir.path().join("d.csv").to_str().unwrap());
    let err = Scenario::from_value(v).unwrap_err().to_string();
    assert!(err.contains("row 2") && err.contains("t = NaN"), "{err}");
}

/// `agglo::separate::separate_overlaps` (issue 37 item 9): an end state with overlapping
/// pairs, which `cloud.bodies` refuses, becomes one it accepts, each pair pushed apart
/// along its line of centres with its centre of mass kept.
#[test]
fn overlapping_end_states_are_separated_into_a_scene_that_validates() {
    use agglo::cloud::PlacedBody;
    use agglo::separate::separate_overlaps;
    // Two bodies of 1 and 8 primaries (radii b0, 2 b0) at 0.85 of their radii sum.
    let mut v = base();
    merge(
        &mut v,
        json!({ "cloud": { "count": 2, "v_rel": [0, 0, 0] } }),
    );
    let mut s = Scenario::from_json(&v.to_string()).unwrap();
    let b0 = s.primary_radius();
    let m0 = s.primary_mass();
    let body = |x: f64, primaries: f64, id: u64| PlacedBody {
        position: [x, 0.0, 0.0],
        velocity: Some([0.0; 3]),
        primaries,
        id: Some(id),
        temperature: None,
        mass: None,
        radius: None,
    };
    s.cloud.bodies = vec![body(0.0, 1.0, 0), body(0.85 * 3.0 * b0, 8.0, 1)];
    s.cloud.count = 2;
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("overlap"), "{e}");
    let centre =
        |s: &Scenario| (s.cloud.bodies[0].position[0] + 8.0 * s.cloud.bodies[1].position[0]) / 9.0;
    let before = centre(&s);
    assert_eq!(separate_overlaps(&mut s).unwrap(), 1);
    s.validate().unwrap();
    let gap = s.cloud.bodies[1].position[0] - s.cloud.bodies[0].position[0];
    assert!(
        (gap / (3.0 * b0) - 1.0).abs() < 1e-8,
        "{gap:e} vs {:e}",
        3.0 * b0
    );
    assert!(
        (centre(&s) - before).abs() <= 1e-12 * b0,
        "the centre of mass moved"
    );
    assert!(m0 > 0.0);

    // A sticky run's own end state (ballistic aggregation's material, 5000 bodies at
    // φ = 0.097, 2 ms: 889 bodies left, one of them overlapping a neighbour after a
    // merge): as a scene it is refused, and accepted once separated, with nothing but
    // positions changed.
    let mut run = Scenario::from_json(
        &json!({
            "name": "sticky", "seed": 4, "box": { "half_width": 0.006 },
            "cloud": { "count": 5000, "radius": 2e-4, "velocity_distribution": "maxwell",
                       "granular_temperature": 1.0 },
            "material": { "rho": 1000, "H0": 1e-6, "C": 1000, "theta0": 300 },
            "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 },
            "time": { "end": 0.002 }
        })
        .to_string(),
    )
    .unwrap();
    let mut sim = agglo::kernel::simulation(&run).unwrap();
    sim.run().unwrap();
    let end: Vec<PlacedBody> = sim.bodies().iter().map(PlacedBody::from).collect();
    run.cloud.count = end.len();
    run.cloud.bodies = end.clone();
    let refused = run.validate().is_err();
    let pushes = separate_overlaps(&mut run).unwrap();
    eprintln!(
        "sticky end state of {} bodies: {pushes} pushes, refused before: {refused}",
        end.len()
    );
    assert!(
        refused && pushes > 0,
        "no overlap left by this run to test with"
    );
    run.validate().unwrap();
    for (a, b) in run.cloud.bodies.iter().zip(&end) {
        assert_eq!((a.velocity, a.mass, a.id), (b.velocity, b.mass, b.id));
    }
}
