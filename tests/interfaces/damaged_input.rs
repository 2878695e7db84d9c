//! Issue 33: inputs a user or a damaged disk gives, each once a panic, an abort, a hang
//! or a silent NaN, now refused with an error naming the field or read as labels. Each
//! test is named after what it guards; the ones that crashed the process run the binary
//! with a time limit, so a regression fails the test instead of killing the suite.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use agglo::components::Velocity;
use agglo::prelude::*;
use serde_json::{Value, json};

use crate::common::merge;

/// What a bounded run of the binary gave: None for the status when it was killed at the
/// time limit.
struct Outcome {
    status: Option<std::process::ExitStatus>,
    stdout: String,
    stderr: String,
}

impl Outcome {
    fn ok(&self) -> bool {
        self.status.is_some_and(|s| s.success())
    }
    /// Refused: a non-zero exit that is not a crash (a panic exits 101, an abort is a
    /// signal).
    fn refused(&self) -> bool {
        self.status.is_some_and(|s| s.code() == Some(1))
    }
}

/// `agglo ARGS` in `dir`, killed after `limit` (a hang is a failure, not a stuck suite).
fn agglo_within(args: &[&str], dir: &Path, limit: Duration) -> Outcome {
    let mut child = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let read = |r: Option<&mut dyn std::io::Read>| {
        let mut s = String::new();
        if let Some(r) = r {
            let _ = r.read_to_string(&mut s);
        }
        s
    };
    let stdout = read(child.stdout.as_mut().map(|r| r as &mut dyn std::io::Read));
    let stderr = read(child.stderr.as_mut().map(|r| r as &mut dyn std::io::Read));
    Outcome {
        status,
        stdout,
        stderr,
    }
}

/// 60 s: every run here takes well under a second in a debug build when it works; the
/// limit only has to tell a hang from a run.
const LIMIT: Duration = Duration::from_secs(60);

fn base() -> Value {
    json!({
        "name": "t", "seed": 1,
        "box": { "half_width": 0.01 },
        "cloud": { "count": 2, "radius": 0.001, "v_rel": [0, 0, 0] },
        "material": { "rho": 2000, "H0": 1e4, "C": 1000, "theta0": 300 },
        "impact": { "a0": 0.5, "af": 1.0, "beta": 1.0 },
        "time": { "end": 0.001 }
    })
}

fn write_scene(dir: &Path, patch: Value) -> PathBuf {
    let mut v = base();
    merge(&mut v, patch);
    let path = dir.join("scene.json");
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    path
}

fn load_error(patch: Value) -> String {
    let mut v = base();
    merge(&mut v, patch);
    match Scenario::from_value(v) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

/// Body ids are labels: u64::MAX, i64::MAX, 1e12 and 4e9 run as 0 and 1 do (a dense
/// table indexed by id once asked for 4 TB, wrapped `id + 1`, or took 15 GB), and the
/// final state gives them back exactly.
#[test]
fn any_u64_body_id_is_a_label() {
    for ids in [
        [u64::MAX, 3],
        [i64::MAX as u64, 1_000_000_000_000],
        [4_000_000_000, u64::MAX - 1],
    ] {
        for core in ["events", "stepped"] {
            let dir = tempfile::tempdir().unwrap();
            let scene = write_scene(
                dir.path(),
                json!({
                    "time": { "end": 0.002, "core": core },
                    "cloud": { "bodies": [
                        { "position": [-0.003, 0, 0], "velocity": [3, 0, 0], "id": ids[0] },
                        { "position": [0.003, 0, 0], "velocity": [-3, 0, 0], "id": ids[1] }
                    ] }
                }),
            );
            let out = agglo_within(
                &[
                    "run",
                    scene.to_str().unwrap(),
                    "-q",
                    "--final-state",
                    "end.csv",
                ],
                dir.path(),
                LIMIT,
            );
            assert!(out.ok(), "ids {ids:?} on {core}: {}", out.stderr);
            let text = std::fs::read_to_string(dir.path().join("end.csv")).unwrap();
            // The two grains bond and merge (two_body.json): the survivor keeps one id.
            let id = text.lines().nth(1).unwrap().split(',').next().unwrap();
            let id: u64 = id.parse().expect("the id column is an unsigned integer");
            assert!(ids.contains(&id), "{ids:?} on {core}: survivor {id}");
        }
    }
}

/// The id column of `cloud.from_file` is read as an exact u64, not through f64 (ids
/// above i64::MAX were "not an integer", and 2^53 + 1 would become 2^53).
#[test]
fn from_file_reads_u64_ids_exactly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("b.csv"),
        "id,x,y,z\n18446744073709551615,-0.003,0,0\n9007199254740993,0.003,0,0\n",
    )
    .unwrap();
    let mut v = base();
    v["cloud"] = json!({ "radius": 0.001, "v_rel": [0, 0, 0],
        "from_file": dir.path().join("b.csv").to_str().unwrap() });
    let s = Scenario::from_value(v).unwrap();
    let ids: Vec<_> = s.cloud.bodies.iter().map(|b| b.id).collect();
    assert_eq!(ids, [Some(u64::MAX), Some(9_007_199_254_740_993)]);
}

/// Values each inside its field's range whose derived constants overflow or vanish are
/// refused up front, naming the field (the cooling solve once panicked on a clamp with
/// NaN bounds, the cloud generator on an infinite box).
#[test]
fn derived_constants_that_overflow_or_vanish_are_refused() {
    for (patch, field) in [
        (
            json!({ "material": { "theta_s": 1e150 } }),
            "material.theta_s",
        ),
        (
            json!({ "cloud": { "radius": null, "size_ratio": 1e-150 } }),
            "cloud.size_ratio",
        ),
        (json!({ "cloud": { "radius": 1e-120 } }), "cloud.radius"),
        (
            json!({ "box": { "half_width": 1.797e308 } }),
            "box.half_width",
        ),
        (json!({ "material": { "rho": 1e200 } }), "material.rho"),
    ] {
        let message = load_error(patch.clone());
        assert!(
            message.contains(field) && message.contains("allowed"),
            "{patch}: {message}"
        );
    }
}

/// `--live-rate 1e-300` passed the range check and panicked making a Duration.
#[test]
fn a_live_rate_below_a_frame_per_thousand_seconds_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), json!({}));
    let out = agglo_within(
        &[
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--live",
            "127.0.0.1:0",
            "--live-rate",
            "1e-300",
        ],
        dir.path(),
        LIMIT,
    );
    assert!(out.refused(), "{:?} {}", out.status, out.stderr);
    assert!(out.stderr.contains("--live-rate"), "{}", out.stderr);
}

/// `--live-rate` / `--live-bodies` without `--live` did nothing, silently.
#[test]
fn live_flags_without_live_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), json!({}));
    for flag in [["--live-rate", "5"], ["--live-bodies", "10"]] {
        let out = agglo_within(
            &["run", scene.to_str().unwrap(), "-q", flag[0], flag[1]],
            dir.path(),
            LIMIT,
        );
        assert!(!out.ok(), "{flag:?} accepted without --live");
        assert!(out.stderr.contains("--live"), "{}", out.stderr);
    }
}

/// A sample interval of 1e-300 s made the sampler count 1e297 sample times inside one
/// step: the run spun and no signal stopped it. Now the schedule skips to the step's
/// time at once.
#[test]
fn a_tiny_sample_interval_does_not_spin() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), json!({ "time": { "core": "stepped" } }));
    let out = agglo_within(
        &[
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--series",
            "s.csv",
            "--sample-every",
            "1e-300",
        ],
        dir.path(),
        LIMIT,
    );
    assert!(
        out.status.is_some(),
        "still running after {LIMIT:?}: {}",
        out.stderr
    );
    assert!(out.ok(), "{}", out.stderr);
}

/// A checkpoint interval that would land more than once per allowed step is refused
/// (the event core took a synced checkpoint every step; validate said
/// "18446744073709551614 before T").
#[test]
fn a_checkpoint_interval_finer_than_the_step_budget_is_refused() {
    let message = load_error(json!({ "output": { "restart": { "every": 1e-300 } } }));
    assert!(
        message.contains("output.restart.every") && message.contains("allowed"),
        "{message}"
    );
}

/// Explicit bodies larger than the box were accepted.
#[test]
fn a_body_larger_than_the_box_is_refused() {
    // 1e6 primaries of b0 = 1 mm: radius 0.1 m in a box of half-width 0.01 m.
    let message = load_error(json!({ "cloud": { "count": 1, "bodies": [
        { "position": [0, 0, 0], "velocity": [0, 0, 0], "primaries": 1e6 }
    ] } }));
    assert!(
        message.contains("cloud.bodies.0.radius") && message.contains("larger than the box"),
        "{message}"
    );
}

/// Duplicate columns in a body table were accepted (the first silently won).
#[test]
fn a_body_table_with_a_repeated_column_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("b.csv"),
        "x,y,z,x\n-0.003,0,0,0.5\n0.003,0,0,0.5\n",
    )
    .unwrap();
    let mut v = base();
    v["cloud"] = json!({ "radius": 0.001, "v_rel": [0, 0, 0],
        "from_file": dir.path().join("b.csv").to_str().unwrap() });
    let message = Scenario::from_value(v).unwrap_err().to_string();
    assert!(
        message.contains("`x`") && message.contains("twice"),
        "{message}"
    );
}

/// `cloud.from_file` reads CSV as CSV: a quoted field holding a comma, an unnamed
/// leading index column (`df.to_csv(path)`), and `cloud.count` taken from the file.
#[test]
fn from_file_reads_quoted_fields_and_a_pandas_index() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("b.csv"),
        ",\"x\",y,z,temperature\n0,\"-0.003\",0,0,300\n1,0.003,\"0\",0,\"3.1e2\"\n",
    )
    .unwrap();
    let mut v = base();
    v["cloud"] = json!({ "radius": 0.001, "v_rel": [0, 0, 0],
        "from_file": dir.path().join("b.csv").to_str().unwrap() });
    v["cloud"].as_object_mut().unwrap().remove("count");
    let s = Scenario::from_value(v).unwrap();
    assert_eq!(s.cloud.count, 2);
    assert_eq!(s.cloud.bodies[0].position, [-0.003, 0.0, 0.0]);
    assert_eq!(s.cloud.bodies[1].temperature, Some(310.0));

    // A quoted field holding a comma is one field (then refused as no number, by name).
    std::fs::write(
        dir.path().join("c.csv"),
        "x,y,z,temperature\n-0.003,0,0,\"3,5\"\n0.003,0,0,300\n",
    )
    .unwrap();
    let mut v = base();
    v["cloud"] = json!({ "radius": 0.001, "v_rel": [0, 0, 0],
        "from_file": dir.path().join("c.csv").to_str().unwrap() });
    let message = Scenario::from_value(v).unwrap_err().to_string();
    assert!(message.contains("temperature"), "{message}");
    assert!(!message.contains("fields, but the header"), "{message}");
}

/// One flipped bit inside a compressed chunk of a recording made `agglo inspect` and
/// `agglo layout` abort on a 2.8e18-byte allocation or panic on "capacity overflow"
/// (36 of 800 runs over 400 mutated copies of tests/fuzz_corpus/rec.mcap). These four
/// flips each crashed main; now the file reads as damaged, in the text report too.
#[test]
fn a_flipped_bit_in_a_recording_chunk_is_damage_not_an_abort() {
    let bytes =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus/rec.mcap"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut finalised = 0;
    for (at, bit) in [(6748, 7), (5405, 5), (3929, 6), (4162, 0)] {
        let mut b = bytes.clone();
        b[at] ^= 1 << bit;
        let path = dir.path().join(format!("flip_{at}_{bit}.mcap"));
        std::fs::write(&path, &b).unwrap();
        for args in [
            vec!["inspect", path.to_str().unwrap()],
            vec!["layout", path.to_str().unwrap(), "--out", "l.json"],
        ] {
            let out = agglo_within(&args, dir.path(), LIMIT);
            assert!(
                out.ok() || out.refused(),
                "{args:?}: {:?} {}",
                out.status,
                out.stderr
            );
        }
        let report = agglo::record::inspect(&path).unwrap();
        assert!(report.damage.is_some(), "flip at {at}: no damage reported");
        // The summary at the end survived: the text said "finalised; 0 chunks".
        if report.finalised {
            finalised += 1;
            assert!(
                report.to_text().contains("DAMAGED"),
                "flip at {at}: {}",
                report.to_text()
            );
        }
    }
    assert!(
        finalised > 0,
        "no flip left the summary whole: the text check ran on none"
    );
}

/// `agglo inspect` on a recording cut by a kill says it is not finalised, how much is
/// readable, and how to continue (`--resume`), instead of only the parser's words.
#[test]
fn inspect_of_a_killed_recording_says_what_is_readable_and_how_to_resume() {
    let bytes =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus/rec.mcap"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.mcap");
    std::fs::write(dir.path().join("cut.restart"), b"").unwrap();
    // Cut anywhere, and cut just after a record's opcode whose length the writer had not
    // filled in (all ones: the mcap reader's "length exceeds limit: 18446744073709551615").
    let cut = &bytes[..bytes.len() * 2 / 3];
    let mut unwritten_length = bytes[..bytes.len() / 2].to_vec();
    unwritten_length.push(0x06);
    unwritten_length.extend([0xff; 8]);
    for file in [cut.to_vec(), unwritten_length] {
        std::fs::write(&path, &file).unwrap();
        let out = agglo_within(&["inspect", "cut.mcap"], dir.path(), LIMIT);
        assert!(out.ok(), "{}", out.stderr);
        for words in ["NOT finalised", "are readable", "--resume", "cut.restart"] {
            assert!(
                out.stdout.contains(words),
                "no `{words}` in:\n{}",
                out.stdout
            );
        }
        // In words, not the parser's.
        for raw in ["exceeds limit", "18446744073709551615"] {
            assert!(!out.stdout.contains(raw), "`{raw}` in:\n{}", out.stdout);
        }
    }
}

/// Parquet written with Snappy, pandas' and pyarrow's default codec, was refused
/// ("Disabled feature at compile time: snap").
#[test]
fn from_file_reads_snappy_parquet() {
    use parquet::basic::{Compression, GzipLevel};
    use parquet::data_type::{DoubleType, Int32Type, Int64Type};
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use std::sync::Arc;

    let dir = tempfile::tempdir().unwrap();
    // Snappy (pandas' default), gzip and lz4 (pandas' other choices, refused as a
    // "disabled feature" before); ids as int8 (refused by its internal type name) and
    // pandas' stored index `__index_level_0__` (refused as an unknown column).
    for compression in [
        Compression::SNAPPY,
        Compression::GZIP(GzipLevel::default()),
        Compression::LZ4_RAW,
        Compression::LZ4,
    ] {
        let path = dir.path().join("b.parquet");
        let schema = Arc::new(
            parquet::schema::parser::parse_message_type(
                "message b { REQUIRED DOUBLE x; REQUIRED DOUBLE y; REQUIRED DOUBLE z; \
                 REQUIRED INT32 id (INTEGER(8, true)); REQUIRED INT64 __index_level_0__; }",
            )
            .unwrap(),
        );
        let props = WriterProperties::builder()
            .set_compression(compression)
            .build();
        let mut writer = SerializedFileWriter::new(
            std::fs::File::create(&path).unwrap(),
            schema,
            Arc::new(props),
        )
        .unwrap();
        let mut group = writer.next_row_group().unwrap();
        for values in [[-0.003, 0.003], [0.0, 0.0], [0.0, 0.0]] {
            let mut column = group.next_column().unwrap().unwrap();
            column
                .typed::<DoubleType>()
                .write_batch(&values, None, None)
                .unwrap();
            column.close().unwrap();
        }
        let mut column = group.next_column().unwrap().unwrap();
        column
            .typed::<Int32Type>()
            .write_batch(&[7, 9], None, None)
            .unwrap();
        column.close().unwrap();
        let mut column = group.next_column().unwrap().unwrap();
        column
            .typed::<Int64Type>()
            .write_batch(&[10, 11], None, None)
            .unwrap();
        column.close().unwrap();
        group.close().unwrap();
        writer.close().unwrap();
        let bodies = agglo::cloud_file::load_bodies(&path)
            .unwrap_or_else(|e| panic!("{compression:?}: {e:#}"));
        assert_eq!(bodies.len(), 2);
        assert_eq!(bodies[1].position, [0.003, 0.0, 0.0]);
        assert_eq!(
            bodies.iter().map(|b| b.id).collect::<Vec<_>>(),
            [Some(7), Some(9)]
        );
    }
}

/// A CSV table whose writer was killed mid-row ends in a torn line: it is left out on
/// read (the rows before it are whole), instead of failing the whole file.
#[test]
fn a_torn_last_csv_line_is_left_out() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("b.csv"),
        "x,y,z,temperature\n-0.003,0,0,300\n0.003,0,0,300\n0.0,0.00",
    )
    .unwrap();
    let bodies = agglo::cloud_file::load_bodies(&dir.path().join("b.csv")).unwrap();
    assert_eq!(bodies.len(), 2);
    // A file written by hand without a last newline keeps its last (whole) row.
    std::fs::write(dir.path().join("c.csv"), "x,y,z\n-0.003,0,0\n0.003,0,0").unwrap();
    assert_eq!(
        agglo::cloud_file::load_bodies(&dir.path().join("c.csv"))
            .unwrap()
            .len(),
        2
    );
}

/// A restart file altered by hand and its checksum recomputed: a snapshot that does not
/// describe a run of its scene (a NaN position, an infinite clock, a repeated id, a
/// checkpoint interval of 1e-300 s) is refused on resume, naming what is wrong, instead
/// of hanging or panicking.
#[test]
fn a_restart_snapshot_altered_with_its_checksum_recomputed_is_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus/run.restart");
    let (scenario, snapshot) = agglo::restart::read(&path).unwrap();
    type Alter = fn(&mut agglo::restart::RestartSnapshot);
    let cases: [(Alter, &str); 4] = [
        (|s| s.bodies[1].position[0] = f64::NAN, "position"),
        (|s| s.clock.time = f64::INFINITY, "clock.time"),
        (|s| s.bodies[1].id = s.bodies[0].id, "two bodies"),
        (|s| s.checkpoints.every = 1e-300, "checkpoints"),
    ];
    for (alter, words) in cases {
        let mut altered = snapshot.clone();
        alter(&mut altered);
        let bytes = agglo::restart::encode(&scenario, &altered);
        let (scenario, altered) = agglo::restart::decode(&path, &bytes).unwrap();
        let mut sim = Simulation::new(&scenario).unwrap();
        let err = sim.resume(&altered).unwrap_err().to_string();
        assert!(err.contains(words), "{words}: {err}");
    }
    // The file as written resumes.
    let mut sim = Simulation::new(&scenario).unwrap();
    sim.resume(&snapshot).unwrap();
}

fn inverse_error(patch: Value) -> String {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut v: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("inverse_demo.json")).unwrap())
            .unwrap();
    merge(&mut v, patch);
    match agglo::inverse::InverseProblem::from_json(&v.to_string(), &dir) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

/// Genes whose values the run overwrites (the scene seed, a path set twice, time.end
/// under the P02 end-time rule) are refused: best.json reported values never applied.
#[test]
fn inverse_genes_the_run_would_overwrite_are_refused() {
    let gene = |path: &str| json!({ "name": "g", "path": path, "min": 1, "max": 2 });
    for (genes, words) in [
        (json!([gene("seed")]), "`seed`"),
        (
            json!([gene("cloud.v_rel.0"), gene("cloud.v_rel.0")]),
            "already set by genes.0.path",
        ),
        (
            json!([{ "name": "T", "path": "time.end", "min": 1e-4, "max": 2e-4 }]),
            "P02 end-time rule",
        ),
    ] {
        let message = inverse_error(json!({ "genes": genes }));
        assert!(message.contains(words), "{genes}: {message}");
    }
}

/// a0 and af gene ranges that can cross (a0 at its upper bound above af at its lower)
/// are refused by validation; `optimize` failed in generation 0.
#[test]
fn crossing_a0_and_af_gene_ranges_are_refused() {
    let message = inverse_error(json!({ "genes": [
        { "name": "a0", "path": "impact.a0", "min": 0.1, "max": 0.6 },
        { "name": "af", "path": "impact.af", "min": 0.5, "max": 1.0 }
    ] }));
    assert!(
        message.contains("a0 = 0.6") && message.contains("af = 0.5"),
        "{message}"
    );
}

/// A penalty ≤ 0 let failed strings win (costs are ≥ 0 and minimised).
#[test]
fn a_failure_penalty_of_zero_or_less_is_refused() {
    for p in [0.0, -1.0] {
        let message = inverse_error(json!({ "on_failure": { "penalty": p } }));
        assert!(
            message.contains("on_failure.penalty") && message.contains("> 0"),
            "{message}"
        );
    }
}

/// `ga.strings = 1e12` and `scan --points 1e11` aborted on an allocation; `validate`
/// called the problem valid. Now both get the memory check `run` applies.
#[test]
fn populations_and_scans_larger_than_memory_are_refused() {
    let message = inverse_error(json!({ "ga": { "strings": 1_000_000_000_000u64, "parents": 4 } }));
    assert!(
        message.contains("ga.strings") && message.contains("memory"),
        "{message}"
    );
    let dir = tempfile::tempdir().unwrap();
    let problem = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/inverse_demo.json");
    let out = agglo_within(&["validate", problem.to_str().unwrap()], dir.path(), LIMIT);
    assert!(out.ok(), "{}", out.stderr);
    let out = agglo_within(
        &[
            "scan",
            problem.to_str().unwrap(),
            "--gene",
            "cloud.v_rel.0",
            "--from",
            "1",
            "--to",
            "2",
            "--points",
            "100000000000",
            "--out",
            "scan.csv",
            "-q",
        ],
        dir.path(),
        LIMIT,
    );
    assert!(out.refused(), "{:?} {}", out.status, out.stderr);
    assert!(
        out.stderr.contains("--points") && out.stderr.contains("memory"),
        "{}",
        out.stderr
    );
}

/// An Epstein gas so thin that a primary's relaxation time is infinite turned every
/// position into NaN, and the run exited 0 with 0 violations; the derived τ is now
/// checked at load, naming the field.
#[test]
fn a_drag_whose_relaxation_time_is_infinite_is_refused() {
    let message = load_error(json!({ "field": { "drag": { "relaxation":
        { "epstein": { "gas_density": 1e-320, "thermal_speed": 400.0 } } } } }));
    assert!(
        message.contains("field.drag.relaxation.epstein.gas_density")
            && message.contains("allowed"),
        "{message}"
    );
}

/// A NaN in a body's state — whatever put it there — ends the run with
/// `SimError::NonFinite` naming the body, the quantity and the step, on both cores
/// (the checks only counted it, and the run went on to T, exit 0).
#[test]
fn a_non_finite_body_state_ends_the_run_naming_body_quantity_and_step() {
    for core in ["stepped", "events"] {
        let mut v = base();
        merge(
            &mut v,
            json!({ "time": { "core": core }, "cloud": { "bodies": [
                { "position": [-0.003, 0, 0], "velocity": [3, 0, 0], "id": 5 },
                { "position": [0.003, 0, 0], "velocity": [-3, 0, 0], "id": 9 }
            ] } }),
        );
        let s = Scenario::from_value(v).unwrap();
        let mut sim = Simulation::new(&s).unwrap();
        sim.step().unwrap();
        let world = sim.world_mut();
        let mut q = world.query::<(&ParticleId, &mut Velocity)>();
        for (id, mut velocity) in q.iter_mut(world) {
            if id.0 == 9 {
                velocity.0.y = f64::NAN;
            }
        }
        let err = loop {
            match sim.step() {
                Ok(()) if sim.is_finished() => panic!("{core}: ran to T with a NaN velocity"),
                Ok(()) => {}
                Err(e) => break e,
            }
        };
        let SimError::NonFinite { step, what } = &err else {
            panic!("{core}: {err}");
        };
        assert!(
            // The drift of the step carries the NaN into y first, or it is seen as is; on
            // the event core the NaN's contact reaches body 5 in the same step.
            (what.contains("body 9") || what.contains("body 5"))
                && (what.contains("velocity y") || what.contains("position y")),
            "{core}: {what}"
        );
        assert!(*step >= 1, "{core}: step {step}");
    }
}

/// Placing the pieces of a fragmenting body was quadratic in their count (a body of 3e4
/// primaries took 23 s, 1e5 over two minutes): now O(n log n). 1e5 pieces are placed in
/// well under the 10 s allowed here (a debug build; the quadratic loop's 5e9 distances
/// take minutes), and no two overlap.
#[test]
fn a_body_of_1e5_primaries_fragments_in_seconds() {
    let start = Instant::now();
    let offsets = agglo::systems::fragment::piece_offsets(100_000, 1e-6);
    let elapsed = start.elapsed();
    assert!(elapsed < Duration::from_secs(10), "{elapsed:?}");
    assert_eq!(offsets.len(), 100_000);
    // No overlap: the closest pair of centres is at least two piece radii apart.
    let closest = agglo::systems::fragment::closest_distance(&offsets);
    assert!(closest >= 2e-6, "{closest:e}");
}

/// `--recording run.restart` with `output.restart`: the restart file (beside the
/// recording, RUN.restart) was the recording itself, overwritten at the first
/// checkpoint, exit 0.
#[test]
fn a_recording_on_the_restart_files_path_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        json!({ "output": { "restart": { "every": 0.0004 } } }),
    );
    let out = agglo_within(
        &[
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--recording",
            "run.restart",
        ],
        dir.path(),
        LIMIT,
    );
    assert!(out.refused(), "{:?} {}", out.status, out.stderr);
    assert!(
        out.stderr.contains("--recording") && out.stderr.contains("restart file"),
        "{}",
        out.stderr
    );
}

/// A long scenario name failed at the first checkpoint ("File name too long", labelled
/// "recording the run"); a "/" in the name (or a `--set` value, which the name carries)
/// stopped `--live` from starting. The files named after the scene now get a plain,
/// short name.
#[test]
fn long_names_and_slashes_in_names_make_plain_file_names() {
    let dir = tempfile::tempdir().unwrap();
    let long = "n".repeat(300);
    let scene = write_scene(
        dir.path(),
        json!({ "name": long, "output": { "restart": { "every": 0.0004 } } }),
    );
    let out = agglo_within(&["run", scene.to_str().unwrap(), "-q"], dir.path(), LIMIT);
    assert!(out.ok(), "{}", out.stderr);
    let restart: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".restart"))
        .collect();
    assert_eq!(restart.len(), 1, "{restart:?}");
    assert!(restart[0].len() < 120, "{}", restart[0]);

    let scene = write_scene(dir.path(), json!({ "name": "a/b" }));
    let out = agglo_within(
        &[
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--set",
            "description=x/y",
            "--live",
            "127.0.0.1:0",
        ],
        dir.path(),
        LIMIT,
    );
    assert!(out.ok(), "{}", out.stderr);
}

/// Send `signal` to a child (by its own pid) and wait at most `limit` for it to end.
fn signal_and_wait(child: &mut std::process::Child, signal: i32, limit: Duration) -> Option<i32> {
    // SAFETY: kill has no preconditions; the pid is our own child's.
    unsafe { libc::kill(child.id() as i32, signal) };
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status.code().unwrap_or(-1));
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A stop signal always stops: a run inside a step that never ends (a test hook holds
/// step 3) exits within about a second of SIGTERM, with 128 + 15, naming the signal.
/// Main's run went on until a second signal (`timeout` sends one: 22 minutes).
#[test]
fn sigterm_stops_a_run_stuck_inside_a_step_within_a_second() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        json!({ "time": { "end": 1.0, "core": "stepped" } }),
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args(["run", scene.to_str().unwrap(), "-q", "--out", "r.mcap"])
        .env("AGGLO_TEST_STUCK_AT_STEP", "3")
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let start = Instant::now();
    let code = signal_and_wait(&mut child, libc::SIGTERM, Duration::from_secs(20));
    let took = start.elapsed();
    let mut stderr = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert_eq!(code, Some(128 + 15), "{stderr}");
    // One second of grace, plus the watchdog's 20 ms polls and the exit.
    assert!(took < Duration::from_secs(3), "{took:?}");
    assert!(stderr.contains("SIGTERM"), "{stderr}");
    // The recording reads up to its last complete chunk.
    assert!(agglo::record::inspect(&dir.path().join("r.mcap")).is_ok());
}

/// The case from the issue: `--sample-every 1e-300` spun inside one step and SIGTERM did
/// nothing. The run now steps normally and stops at the next step end.
#[test]
fn sigterm_stops_a_run_with_a_tiny_sample_interval() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        json!({ "time": { "end": 1000.0, "core": "stepped" } }),
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args([
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--series",
            "s.csv",
            "--sample-every",
            "1e-300",
        ])
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let code = signal_and_wait(&mut child, libc::SIGTERM, Duration::from_secs(10));
    // Stopped by the signal (non-zero), or already finished: either way not spinning.
    assert!(code.is_some(), "still running 10 s after SIGTERM");
}

/// Found by the fuzz harness: one byte changed in a restart file's snapshot (checksum
/// recomputed) gave a body a speed of 7e38 m/s, a local time of −7e222 s, or the event
/// core's grid a frame velocity of ~1e300 m/s, and the resumed event core crossed cells
/// without end inside one step. A snapshot's speeds (bodies' and frame's) are held to
/// the scenario's limit (1e5 m/s), its local times to [0, t].
#[test]
fn a_restart_snapshot_with_an_absurd_speed_or_local_time_is_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus/run.restart");
    let bytes = std::fs::read(&path).unwrap();
    // Bytes of the body (after the 22-byte header): 1690 is in body 1's v_y (bit 3
    // flipped), 1843 in body 2's local time (set to 238).
    for (at, edit, words) in [
        (
            1690,
            Box::new(|b: u8| b ^ (1 << 3)) as Box<dyn Fn(u8) -> u8>,
            "body 1 (id 1): speed",
        ),
        (1843, Box::new(|_| 238), "body 2 (id 2): local time"),
        // The event core's saved frame velocity (z, its exponent's byte), bit 6.
        (2753, Box::new(|b: u8| b ^ (1 << 6)), "frame velocity"),
    ] {
        let mut body = bytes[22..].to_vec();
        body[at] = edit(body[at]);
        let mut file = bytes[..22].to_vec();
        file[18..22].copy_from_slice(&crc32fast::hash(&body).to_le_bytes());
        file.extend_from_slice(&body);
        let (scenario, snapshot) = agglo::restart::decode(&path, &file).unwrap();
        let mut sim = Simulation::new(&scenario).unwrap();
        let err = sim.resume(&snapshot).unwrap_err().to_string();
        assert!(err.contains(words), "{words}: {err}");
    }
}

/// Found by the fuzz harness: one flipped bit in a Parquet body table's footer made the
/// parquet crate panic ("column start and length should not be negative", "Decoder for
/// dict should have been set"). Now each is an error naming the file.
#[test]
fn a_flipped_bit_in_a_parquet_footer_is_an_error_not_a_panic() {
    let bytes = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus/bodies.parquet"),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (at, bit) in [(3631, 0), (3630, 7), (3626, 0)] {
        let mut b = bytes.clone();
        b[at] ^= 1 << bit;
        let path = dir.path().join(format!("flip_{at}_{bit}.parquet"));
        std::fs::write(&path, &b).unwrap();
        let err = agglo::cloud_file::load_bodies(&path).unwrap_err();
        assert!(
            format!("{err:#}").contains("damaged"),
            "flip at {at}: {err:#}"
        );
    }
}

/// A run killed outright (SIGKILL, no chance to close its files) leaves tables a reader
/// opens: each Parquet table ends in a footer listing the row groups written (it was 0
/// bytes: the footer, and the writer's buffer, came only at the end), and each CSV table
/// ends in a whole row.
#[test]
fn tables_of_a_killed_run_are_readable() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let scene = write_scene(
        dir,
        json!({ "cloud": { "count": 64, "v_rel": [0.5, 0.5, 0.5] }, "time": { "end": 1.0 } }),
    );
    let out = Command::new(env!("CARGO_BIN_EXE_agglo"))
        .current_dir(dir)
        .args(["run", scene.to_str().unwrap(), "-q"])
        .args(["--series", "s.parquet", "--sizes", "z.parquet"])
        .args(["--collisions", "c.parquet", "--snapshots", "b.csv"])
        .args(["--sample-every", "1e-4"])
        .env("AGGLO_TEST_SIGKILL_AFTER_STEP", "40")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert_eq!(out.signal(), Some(libc::SIGKILL), "the run was not killed");
    for name in ["s.parquet", "z.parquet", "c.parquet", "b.csv"] {
        let table = agglo::output::table::read_table(&dir.join(name))
            .unwrap_or_else(|e| panic!("{name} after SIGKILL: {e:#}"));
        assert!(!table.names.is_empty(), "{name}: no columns");
    }
    let csv = std::fs::read_to_string(dir.join("b.csv")).unwrap();
    assert!(csv.ends_with('\n'), "b.csv ends in a torn row");
}

/// A full disk behind standard output (`> /dev/full`) is an error naming standard
/// output and a failing exit, not a panic (exit 101), in every command that prints.
#[test]
fn a_full_standard_output_is_an_error_not_a_panic() {
    let full = Path::new("/dev/full");
    if !full.exists() {
        return; // not Linux: no such device to test with
    }
    let quick = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two_body.json");
    let quick = quick.to_str().unwrap();
    for args in [vec!["schema"], vec!["validate", quick], vec!["run", quick]] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
            .args(&args)
            .stdout(std::fs::File::create(full).unwrap())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("cannot write to standard output"),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// Two outputs on one file are refused before the run, naming both (they exited 0 with
/// one of them lost), and so is a final state under a Parquet name (written as CSV).
#[test]
fn outputs_that_share_a_file_are_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let quick = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two_body.json");
    for (args, words) in [
        (
            vec!["--recording", "x.mcap", "--summary", "x.mcap"],
            vec!["--recording and --summary", "x.mcap"],
        ),
        (
            vec!["--final-state", "y.csv", "--series", "y.csv"],
            vec!["--final-state", "--series", "y.csv"],
        ),
        (
            vec!["--out", "r.mcap", "--summary", "r.layout.json"],
            vec!["layout", "--summary"],
        ),
        (
            // `--out`, the recording's old name, is still accepted.
            vec!["--out", "run.restart", "--set", "output.restart.every=1e-4"],
            vec!["--recording and the restart file", "run.restart"],
        ),
        (
            vec!["--final-state", "f.parquet"],
            vec!["--final-state f.parquet", "CSV"],
        ),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
            .current_dir(dir.path())
            .arg("run")
            .arg(&quick)
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        for w in words {
            assert!(stderr.contains(w), "{args:?}: no `{w}` in {stderr}");
        }
        // Refused before anything was written.
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "{args:?}"
        );
    }
}

/// A thread count beyond any machine is refused with the range before any thread starts
/// (`--threads 100000` started tens of thousands of OS threads).
#[test]
fn a_thread_count_beyond_any_machine_is_refused() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let demo = root.join("scenarios/inverse_demo.json");
    let quick = root.join("scenarios/quick_demo.json");
    let (demo, quick) = (demo.to_str().unwrap(), quick.to_str().unwrap());
    for args in [
        vec![
            "scan",
            demo,
            "--gene",
            "cloud.v_rel.0",
            "--from",
            "1",
            "--to",
            "2",
            "--out",
            "x",
        ],
        vec!["optimize", demo, "--out", "x"],
        vec!["kernel", quick, "--bins", "primaries:1,4", "--out", "k.npz"],
        vec!["study", "readings", quick, "--out", "x"],
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
            .args(&args)
            .args(["--threads", "100000"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains("threads ≤ 1024"), "{args:?}: {stderr}");
    }
}
