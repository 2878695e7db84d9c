//! The fuzz harness that stays (issue 33): every reader of user or disk input, given
//! random mutations of the seed inputs in `tests/fuzz_corpus/` (a scenario, a body table
//! as CSV and as Parquet, a recording, a restart file) and of the shipped inverse
//! problem, returns a value or an error — never a panic, an abort or a hang. `cargo fuzz`
//! needs a nightly toolchain, so these are proptests: each runs a bounded number of
//! cases (a few seconds in the debug build) from a fixed seed (see [`fuzz_config`]),
//! and proptest keeps any failure it finds in `fuzz.proptest-regressions` to replay
//! first. A crash found here becomes a named regression test in `damaged_input.rs`.
//!
//! An abort (an allocation the input asked for) kills the test binary: the suite fails
//! loudly, which is the point.

use std::path::{Path, PathBuf};

use agglo::prelude::*;
use proptest::prelude::*;
use serde_json::{Value, json};

fn corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_corpus")
        .join(name)
}

fn corpus_bytes(name: &str) -> Vec<u8> {
    std::fs::read(corpus(name)).unwrap()
}

/// One edit of a file: flip a bit, replace a byte, delete a span, insert bytes, or cut
/// the file short (positions taken modulo the length).
#[derive(Debug, Clone)]
pub(crate) enum Edit {
    Flip { at: usize, bit: u8 },
    Replace { at: usize, byte: u8 },
    Delete { at: usize, len: usize },
    Insert { at: usize, bytes: Vec<u8> },
    Truncate { at: usize },
}

pub(crate) fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Edit::Flip { at, bit }),
        2 => (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Edit::Replace { at, byte }),
        1 => (any::<usize>(), 1usize..64).prop_map(|(at, len)| Edit::Delete { at, len }),
        1 => (any::<usize>(), proptest::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| Edit::Insert { at, bytes }),
        1 => any::<usize>().prop_map(|at| Edit::Truncate { at }),
    ]
}

pub(crate) fn apply(bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for e in edits {
        let n = b.len().max(1);
        match e {
            Edit::Flip { at, bit } => {
                if !b.is_empty() {
                    b[at % n] ^= 1 << bit;
                }
            }
            Edit::Replace { at, byte } => {
                if !b.is_empty() {
                    b[at % n] = *byte;
                }
            }
            Edit::Delete { at, len } => {
                let at = at % n;
                let end = (at + len).min(b.len());
                b.drain(at.min(end)..end);
            }
            Edit::Insert { at, bytes } => {
                let at = at % (b.len() + 1);
                b.splice(at..at, bytes.iter().copied());
            }
            Edit::Truncate { at } => b.truncate(at % n),
        }
    }
    b
}

pub(crate) fn edits() -> impl Strategy<Value = Vec<Edit>> {
    proptest::collection::vec(edit(), 1..4)
}

fn write_temp(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Extreme numbers a field may be given: signed zeros, the ends of f64, the smallest
/// normal and subnormal, the largest integers, values that overflow when cubed or
/// squared, and ordinary ones.
pub(crate) fn extreme() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(json!(0.0)),
        Just(json!(-0.0)),
        Just(json!(f64::MAX)),
        Just(json!(-f64::MAX)),
        Just(json!(f64::MIN_POSITIVE)),
        Just(json!(5e-324)),
        Just(json!(1e-150)),
        Just(json!(1e150)),
        Just(json!(1e200)),
        Just(json!(1e-300)),
        Just(json!(u64::MAX)),
        Just(json!(i64::MAX)),
        Just(json!(4e9)),
        Just(json!(-1)),
        (-1e3f64..1e3).prop_map(|x| json!(x)),
        (1u32..300).prop_map(|e| json!(10f64.powi(e as i32))),
        (1u32..300).prop_map(|e| json!(10f64.powi(-(e as i32)))),
    ]
}

/// Every numeric leaf of `v`, as a dotted path.
pub(crate) fn numeric_paths(v: &Value, prefix: &str, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                numeric_paths(x, &p, out);
            }
        }
        Value::Array(a) => {
            for (k, x) in a.iter().enumerate() {
                numeric_paths(x, &format!("{prefix}.{k}"), out);
            }
        }
        Value::Number(_) => out.push(prefix.to_string()),
        _ => {}
    }
}

pub(crate) fn set(v: &mut Value, path: &str, x: Value) {
    let mut slot = v;
    for key in path.split('.') {
        slot = match slot {
            Value::Array(a) => &mut a[key.parse::<usize>().unwrap()],
            other => &mut other[key],
        };
    }
    *slot = x;
}

/// Run `work` on its own thread and fail (naming `case`) if it has not finished within
/// 20 s — a hang fails the test instead of holding up the suite (the thread is left
/// behind; the test binary ends with the failure).
pub(crate) fn within_time(case: String, work: impl FnOnce() + Send + 'static) {
    let (done, wait) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        work();
        let _ = done.send(());
    });
    match wait.recv_timeout(std::time::Duration::from_secs(20)) {
        Ok(()) => {}
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => panic!("hung over 20 s: {case}"),
        // The work panicked: its own message is on stderr.
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => panic!("panicked: {case}"),
    }
}

/// A scenario that loads is built and stepped a little: the derived constants of any
/// accepted scene must not panic, spin or turn to NaN silently. At most 50 steps and
/// 2000 bodies (a larger count is the memory check's business, tested elsewhere).
fn build_and_step(s: &Scenario) {
    if s.cloud.count > 2000 {
        return;
    }
    let Ok(mut sim) = Simulation::new(s) else {
        return;
    };
    for _ in 0..50 {
        if sim.is_finished() || sim.step().is_err() {
            return;
        }
    }
}

/// 256 cases a target (about a second each in the debug build), from a fixed seed so that
/// CI runs the same inputs every time; `PROPTEST_RNG_SEED=N PROPTEST_CASES=K` explores
/// others (how the cases behind the named regression tests in `damaged_input.rs` were
/// found).
pub(crate) fn fuzz_config() -> ProptestConfig {
    let mut config = ProptestConfig::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        config.cases = 256;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        config.rng_seed = proptest::test_runner::RngSeed::Fixed(33);
    }
    config
}

proptest! {
    #![proptest_config(fuzz_config())]

    /// The scenario loader and its derived constants: one or two numeric fields of the
    /// seed scenario set to extreme values; what loads is built and stepped.
    #[test]
    fn scenarios_with_extreme_numbers_load_or_are_refused(
        picks in proptest::collection::vec((any::<usize>(), extreme()), 1..3),
    ) {
        let mut v: Value = serde_json::from_slice(&corpus_bytes("scenario.json")).unwrap();
        let mut paths = Vec::new();
        numeric_paths(&v, "", &mut paths);
        for (k, x) in picks {
            set(&mut v, &paths[k % paths.len()], x);
        }
        if let Ok(s) = Scenario::from_value(v.clone()) {
            within_time(v.to_string(), move || build_and_step(&s));
        }
    }

    /// `--set PATH=VALUE`: any path (known, unknown, into arrays) and any value text.
    #[test]
    fn set_settings_never_panic(
        path in prop_oneof![
            Just("cloud.count".to_string()), Just("cloud.bodies".to_string()),
            Just("box.half_width".to_string()), Just("cloud.v_rel.7".to_string()),
            Just("time".to_string()), Just("material.theta_s".to_string()),
            Just("output.restart.every".to_string()), Just("".to_string()),
            Just("a..b".to_string()), "[a-z_.0-9]{0,24}",
        ],
        value in prop_oneof![
            Just("1e400".to_string()), Just("-0".to_string()), Just("[]".to_string()),
            Just("{}".to_string()), Just("null".to_string()), Just("\"x/y\"".to_string()),
            Just("18446744073709551616".to_string()), ".{0,12}",
        ],
    ) {
        let base = Scenario::load(&corpus("scenario.json")).unwrap();
        if let Ok(s) = agglo::scenario::with_settings(&base, &[format!("{path}={value}")]) {
            build_and_step(&s);
        }
    }

    /// The CSV body reader (`cloud.from_file`): mutated seed tables.
    #[test]
    fn mutated_csv_body_tables_read_or_are_refused(e in edits()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_temp(dir.path(), "b.csv", &apply(&corpus_bytes("bodies.csv"), &e));
        let _ = agglo::cloud_file::load_bodies(&path);
    }

    /// The Parquet body reader: mutated seed tables.
    #[test]
    fn mutated_parquet_body_tables_read_or_are_refused(e in edits()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_temp(dir.path(), "b.parquet", &apply(&corpus_bytes("bodies.parquet"), &e));
        let _ = agglo::cloud_file::load_bodies(&path);
    }

    /// The MCAP reader behind `inspect`, `layout` and `--from`: mutated recordings.
    #[test]
    fn mutated_recordings_inspect_or_are_refused(e in edits()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_temp(dir.path(), "r.mcap", &apply(&corpus_bytes("rec.mcap"), &e));
        if let Ok(report) = agglo::record::inspect(&path) {
            let _ = report.to_text();
        }
        let _ = agglo::record::layout::box_half_width(&path);
        let _ = agglo::record::scenario_from_recording(&path);
    }

    /// The restart decoder and resume: mutated restart files, their checksum recomputed
    /// (as a hand edit would), decoded, and what decodes resumed and stepped.
    #[test]
    fn mutated_restart_files_resume_or_are_refused(e in edits()) {
        let bytes = corpus_bytes("run.restart");
        let header = b"agglo-restart\n".len() + 8;
        let mut body = apply(&bytes[header..], &e);
        let mut file = bytes[..header].to_vec();
        let crc = crc32fast::hash(&body);
        file[header - 4..].copy_from_slice(&crc.to_le_bytes());
        file.append(&mut body);
        if let Ok((scenario, snapshot)) = agglo::restart::decode(Path::new("r.restart"), &file) {
            within_time(format!("{e:?}"), move || {
                if let Ok(mut sim) = Simulation::new(&scenario)
                    && sim.resume(&snapshot).is_ok()
                {
                    for _ in 0..50 {
                        if sim.is_finished() || sim.step().is_err() {
                            break;
                        }
                    }
                }
            });
        }
    }

    /// The inverse-problem loader: mutated shipped inverse problems.
    #[test]
    fn mutated_inverse_problems_load_or_are_refused(which in any::<bool>(), e in edits()) {
        let name = if which { "inverse_demo.json" } else { "paper2002_inverse.json" };
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        let text = std::fs::read(dir.join(name)).unwrap();
        let text = String::from_utf8_lossy(&apply(&text, &e)).into_owned();
        let _ = agglo::inverse::InverseProblem::from_json(&text, &dir);
    }
}
