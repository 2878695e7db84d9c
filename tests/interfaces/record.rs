//! Recording to MCAP (`agglo run --out`), reading it back with the `mcap` crate,
//! `agglo inspect`, `agglo run --from`, and finalisation on errors, Ctrl-C and SIGKILL.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use foxglove::Decode;
use foxglove::schemas::{Log, SceneUpdate};

const BIN: &str = env!("CARGO_BIN_EXE_agglo");

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

/// quick_demo (300 grains, merging and fragmentation) with `edit` applied, written to `dir`.
fn scenario_file(dir: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let text = std::fs::read_to_string(scenarios_dir().join("quick_demo.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut v);
    let path = dir.join(format!("{name}.json"));
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    path
}

fn agglo(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("agglo runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// One body row of `--final-state`: id and the fields the recording carries.
struct Row {
    id: u64,
    position: [f64; 3],
    radius: f64,
}

fn final_state(path: &Path) -> Vec<Row> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Row {
                id: f[0].parse().unwrap(),
                position: [
                    f[1].parse().unwrap(),
                    f[2].parse().unwrap(),
                    f[3].parse().unwrap(),
                ],
                radius: f[8].parse().unwrap(),
            }
        })
        .collect()
}

/// Messages of a finished recording, in file order: (topic, log time, data).
fn messages(buf: &[u8]) -> Vec<(String, u64, Vec<u8>)> {
    mcap::MessageStream::new(buf)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), m.log_time, m.data.into_owned())
        })
        .collect()
}

fn result_metadata(buf: &[u8], summary: &mcap::Summary) -> BTreeMap<String, String> {
    let index = summary
        .metadata_indexes
        .iter()
        .find(|i| i.name == "agglo.result")
        .expect("result metadata indexed");
    mcap::read::metadata(buf, index).unwrap().metadata
}

#[test]
fn recording_reads_back_and_matches_the_final_state() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = scenarios_dir().join("quick_demo.json");
    let mcap_path = dir.path().join("run.mcap");
    let csv = dir.path().join("final.csv");
    let out = agglo(&[
        "run",
        s(&scenario),
        "--seed",
        "11",
        "--out",
        s(&mcap_path),
        "--final-state",
        s(&csv),
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let buf = std::fs::read(&mcap_path).unwrap();

    // Summary: channels, schemas, counts, a message index for every chunk.
    let summary = mcap::Summary::read(&buf).unwrap().expect("summary section");
    let topics: BTreeMap<String, (String, String)> = summary
        .channels
        .values()
        .map(|c| {
            let schema = c.schema.as_ref().expect("every channel has a schema");
            (
                c.topic.clone(),
                (schema.name.clone(), schema.encoding.clone()),
            )
        })
        .collect();
    let expect = |t: &str, name: &str, enc: &str| {
        assert_eq!(topics[t], (name.to_string(), enc.to_string()), "{t}");
    };
    expect("/particles", "foxglove.SceneUpdate", "protobuf");
    expect("/box", "foxglove.SceneUpdate", "protobuf");
    expect("/events", "foxglove.Log", "protobuf");
    expect("/stats", "agglo.Stats", "jsonschema");
    assert_eq!(topics.len(), 4);
    assert!(!summary.chunk_indexes.is_empty());
    for (i, c) in summary.chunk_indexes.iter().enumerate() {
        assert!(
            !c.message_index_offsets.is_empty(),
            "chunk {i} has no message index"
        );
        assert_eq!(c.compression, "zstd");
    }
    let stats = summary.stats.as_ref().expect("statistics record");
    let count_of = |topic: &str| {
        let id = summary
            .channels
            .values()
            .find(|c| c.topic == topic)
            .unwrap()
            .id;
        stats.channel_message_counts.get(&id).copied().unwrap_or(0)
    };

    // The scenario attachment re-parses to the scenario run (seed applied); metadata names it.
    let attachment = mcap::read::attachment(&buf, &summary.attachment_indexes[0]).unwrap();
    assert_eq!(attachment.name, "scenario.json");
    let embedded =
        agglo::scenario::Scenario::from_json(std::str::from_utf8(&attachment.data).unwrap())
            .unwrap();
    let mut original = agglo::scenario::Scenario::load(&scenario).unwrap();
    original.seed = 11;
    assert_eq!(embedded, original);
    let run_meta = summary
        .metadata_indexes
        .iter()
        .find(|i| i.name == "agglo")
        .map(|i| mcap::read::metadata(&buf, i).unwrap().metadata)
        .expect("run metadata");
    assert_eq!(run_meta["seed"], "11");
    assert_eq!(run_meta["engine_version"], env!("CARGO_PKG_VERSION"));
    assert!(run_meta["command_line"].contains("--out"));
    assert_eq!(result_metadata(&buf, &summary)["status"], "finished");

    // Every message: log times non-decreasing in file order.
    let msgs = messages(&buf);
    assert_eq!(msgs.len() as u64, stats.message_count);
    assert!(
        msgs.windows(2).all(|w| w[0].1 <= w[1].1),
        "log times decrease"
    );

    // Replay /particles like Foxglove: deletions, then add/replace by id.
    let end = embedded.time.end;
    let half_width = embedded.domain.half_width;
    let scale = embedded.output.recording.playback_seconds / end;
    let mut scene: BTreeMap<String, ([f64; 3], f64)> = BTreeMap::new();
    let mut snapshots = 0u64;
    let mut deletions = 0u64;
    let mut stats_seen = Vec::new();
    for (topic, log_time, data) in &msgs {
        match topic.as_str() {
            "/particles" => {
                let update = SceneUpdate::decode(&data[..]).expect("decodes as SceneUpdate");
                for d in &update.deletions {
                    assert!(
                        scene.remove(&d.id).is_some(),
                        "deletion of {} which is not shown",
                        d.id
                    );
                    deletions += 1;
                }
                for e in &update.entities {
                    assert_eq!(e.frame_id, "world");
                    assert_eq!(e.spheres.len(), 1);
                    let sphere = &e.spheres[0];
                    let p = sphere.pose.unwrap().position.unwrap();
                    let size = sphere.size.unwrap();
                    assert!(p.x.is_finite() && p.y.is_finite() && p.z.is_finite());
                    // Positions are wrapped into [−D, D).
                    for x in [p.x, p.y, p.z] {
                        assert!(
                            (-half_width..half_width).contains(&x),
                            "{x} outside the box"
                        );
                    }
                    assert!(size.x > 0.0 && size.x == size.y && size.y == size.z);
                    let c = sphere.color.unwrap();
                    assert!([c.r, c.g, c.b].iter().all(|v| (0.0..=1.0).contains(v)));
                    scene.insert(e.id.clone(), ([p.x, p.y, p.z], size.x));
                }
                snapshots += 1;
            }
            "/stats" => {
                let v: serde_json::Value = serde_json::from_slice(data).unwrap();
                let t = v["time"].as_f64().unwrap();
                // Log time = simulated time × playback scale, rounded to the nanosecond.
                assert_eq!(*log_time, (t * scale * 1e9).round() as u64);
                // After each snapshot the replayed scene holds exactly the live bodies:
                // every merged-away or fragmented body was deleted.
                assert_eq!(scene.len() as u64, v["bodies"].as_u64().unwrap(), "t = {t}");
                stats_seen.push(v);
            }
            "/events" => {
                Log::decode(&data[..]).expect("decodes as Log");
            }
            "/box" => {
                let b = SceneUpdate::decode(&data[..]).unwrap();
                assert_eq!(b.entities[0].lines[0].points.len(), 24);
            }
            other => panic!("unexpected topic {other}"),
        }
    }
    assert_eq!(snapshots, count_of("/particles"));
    assert_eq!(snapshots, count_of("/stats"));
    assert_eq!(count_of("/box"), 1);
    // Default rate: Δt_rec = T/300, plus the first state; long steps skip some multiples.
    assert!((50..=302).contains(&snapshots), "{snapshots} snapshots");
    let first = &stats_seen[0];
    let last = stats_seen.last().unwrap();
    assert_eq!(first["time"].as_f64(), Some(0.0));
    assert_eq!(last["time"].as_f64(), Some(end));
    let times: Vec<f64> = stats_seen
        .iter()
        .map(|v| v["time"].as_f64().unwrap())
        .collect();
    assert!(
        times.windows(2).all(|w| w[0] < w[1]),
        "one snapshot per time"
    );

    // The final scene is the final state: same ids, same positions, diameter 2b (exact:
    // protobuf doubles and the CSV's round-trip formatting are both lossless).
    let rows = final_state(&csv);
    assert!(rows.len() < 300, "the run merged bodies");
    assert!(deletions >= 300 - rows.len() as u64);
    assert_eq!(scene.len(), rows.len());
    for r in &rows {
        let (p, d) = scene
            .get(&r.id.to_string())
            .unwrap_or_else(|| panic!("body {} missing from the last snapshot", r.id));
        assert_eq!(*p, r.position, "body {}", r.id);
        assert_eq!(*d, 2.0 * r.radius, "body {}", r.id);
    }
    assert_eq!(last["bodies"].as_u64(), Some(rows.len() as u64));

    // `agglo inspect --json` agrees.
    let out = agglo(&["inspect", s(&mcap_path), "--json"]);
    assert!(out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["finalised"], true);
    assert_eq!(report["scenario"], "quick_demo");
    assert_eq!(report["seed"], 11);
    assert_eq!(report["last_time"].as_f64(), Some(end));
    assert_eq!(
        report["final_stats"]["bodies"].as_u64(),
        Some(rows.len() as u64)
    );
    assert_eq!(report["messages"].as_u64(), Some(stats.message_count));
    // Text form names the channels.
    let out = agglo(&["inspect", s(&mcap_path)]);
    let text = String::from_utf8(out.stdout).unwrap();
    for t in [
        "/particles",
        "/box",
        "/stats",
        "/events",
        "quick_demo",
        "seed 11",
    ] {
        assert!(text.contains(t), "inspect output lacks {t}:\n{text}");
    }
}

#[test]
fn from_recording_reproduces_the_final_state_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    // A scenario naming its own outputs: `--from` must not overwrite them.
    let scenario = scenario_file(dir.path(), "own_outputs", |v| {
        v["output"] = serde_json::json!({
            "final_state": dir.path().join("a.csv").to_str().unwrap(),
            "recording": { "path": dir.path().join("a.mcap").to_str().unwrap(), "every_steps": 5 }
        });
    });
    let out = agglo(&["run", s(&scenario), "--seed", "5", "-q"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let a_mcap = dir.path().join("a.mcap");
    let a_csv = dir.path().join("a.csv");
    let recording = std::fs::read(&a_mcap).unwrap();
    let b_csv = dir.path().join("b.csv");
    let b_mcap = dir.path().join("b.mcap");
    let out = agglo(&[
        "run",
        "--from",
        s(&a_mcap),
        "--final-state",
        s(&b_csv),
        "--out",
        s(&b_mcap),
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(&a_csv).unwrap(),
        std::fs::read(&b_csv).unwrap(),
        "--from did not reproduce the final state"
    );
    assert_eq!(
        std::fs::read(&a_mcap).unwrap(),
        recording,
        "--from overwrote the recording"
    );
    // The re-run recorded the same messages (only the command line differs).
    let a = messages(&recording);
    let b = messages(&std::fs::read(&b_mcap).unwrap());
    assert_eq!(a, b);
    // every_steps = 5 and no interval: every 5th step plus the first and last state.
    let steps = a
        .iter()
        .filter(|m| m.0 == "/stats")
        .map(|m| {
            serde_json::from_slice::<serde_json::Value>(&m.2).unwrap()["step"]
                .as_u64()
                .unwrap()
        })
        .collect::<Vec<_>>();
    let last = *steps.last().unwrap();
    assert!(
        steps[..steps.len() - 1]
            .iter()
            .enumerate()
            .all(|(i, &k)| k == 5 * i as u64)
    );
    assert!(last > 5 * (steps.len() as u64 - 2));

    // Not a recording: a clear error, no panic.
    let out = agglo(&["run", "--from", s(&scenario)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not an MCAP file"), "{err}");
    let out = agglo(&["inspect", s(&scenario)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not an MCAP file"), "{err}");
}

#[test]
fn a_step_limit_error_leaves_a_finalised_recording() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = scenario_file(dir.path(), "limited", |v| {
        v["time"]["max_steps"] = serde_json::json!(40);
    });
    let mcap_path = dir.path().join("limited.mcap");
    let out = agglo(&["run", s(&scenario), "--out", s(&mcap_path), "-q"]);
    assert!(!out.status.success(), "the run must fail at the step limit");
    assert!(String::from_utf8_lossy(&out.stderr).contains("max_steps"));
    let buf = std::fs::read(&mcap_path).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().expect("summary section");
    let result = result_metadata(&buf, &summary);
    assert_eq!(result["status"], "failed");
    assert_eq!(result["steps"], "40");
    // The last state (step 40) is recorded.
    let last = messages(&buf)
        .into_iter()
        .rev()
        .find(|m| m.0 == "/stats")
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&last.2).unwrap();
    assert_eq!(v["step"].as_u64(), Some(40));
}

/// A run long enough to be interrupted: quick_demo for 100× its time, recording every step.
fn long_run(dir: &Path, name: &str) -> (std::process::Child, PathBuf) {
    let scenario = scenario_file(dir, name, |v| {
        v["time"]["end"] = serde_json::json!(0.4);
        v["output"] = serde_json::json!({ "recording": { "every_steps": 1 } });
    });
    let mcap_path = dir.join(format!("{name}.mcap"));
    let child = Command::new(BIN)
        .args(["run", s(&scenario), "--out", s(&mcap_path), "-q"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (child, mcap_path)
}

/// Wait until `path` holds more than `bytes` bytes (the writer has written chunks).
fn wait_for_size(path: &Path, bytes: u64) {
    let start = Instant::now();
    while std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) <= bytes {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "recording did not grow"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn ctrl_c_leaves_a_finalised_recording() {
    let dir = tempfile::tempdir().unwrap();
    let (child, mcap_path) = long_run(dir.path(), "interrupted");
    // The file exists only once the Ctrl-C handler is installed; wait for a chunk too.
    wait_for_size(&mcap_path, 50_000);
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success(), "an interrupted run exits non-zero");
    assert!(String::from_utf8_lossy(&out.stderr).contains("interrupted"));
    let buf = std::fs::read(&mcap_path).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().expect("summary section");
    assert_eq!(result_metadata(&buf, &summary)["status"], "interrupted");
    let msgs = messages(&buf);
    let stats = msgs.iter().filter(|m| m.0 == "/stats").count();
    assert!(stats > 1);
    assert_eq!(summary.stats.unwrap().message_count, msgs.len() as u64);
}

#[test]
fn sigkill_leaves_recoverable_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let (mut child, mcap_path) = long_run(dir.path(), "killed");
    // Wait until a complete chunk is on disk (chunks go to the file as they close,
    // not at the end), then kill the writer mid-run.
    let start = Instant::now();
    while recovered_snapshots(&std::fs::read(&mcap_path).unwrap_or_default()) == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no chunk written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let buf = std::fs::read(&mcap_path).unwrap();
    assert!(
        mcap::Summary::read(&buf)
            .map(|s| s.is_none())
            .unwrap_or(true)
    );
    // A lenient reader recovers the complete chunks.
    assert!(recovered_snapshots(&buf) > 0, "no snapshot recovered");
    // `agglo inspect` says so and still reports the scenario.
    let out = agglo(&["inspect", s(&mcap_path), "--json"]);
    assert!(out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["finalised"], false);
    assert_eq!(report["scenario"], "quick_demo");
    assert!(report["channels"][0]["messages"].as_u64().unwrap() > 0);
}

/// `/particles` snapshots a lenient reader recovers from a possibly unfinished file;
/// each must decode and hold bodies.
fn recovered_snapshots(buf: &[u8]) -> usize {
    let Ok(stream) =
        mcap::MessageStream::new_with_options(buf, mcap::read::Options::IgnoreEndMagic.into())
    else {
        return 0;
    };
    let mut recovered = 0;
    for m in stream {
        let Ok(m) = m else { break };
        if m.channel.topic == "/particles" {
            let u = SceneUpdate::decode(&m.data[..]).unwrap();
            assert!(!u.entities.is_empty());
            recovered += 1;
        }
    }
    recovered
}

#[test]
fn recording_metadata_carries_the_pipeline_and_the_box() {
    let dir = tempfile::tempdir().unwrap();
    // The stepped core without fragmentation: a pipeline that differs from the default.
    let scenario = scenario_file(dir.path(), "stepped", |v| {
        v["time"]["core"] = "stepped".into();
        v["material"]["gamma"] = serde_json::Value::Null;
    });
    let mcap_path = dir.path().join("run.mcap");
    let summary_path = dir.path().join("summary.json");
    let out = agglo(&[
        "run",
        s(&scenario),
        "--out",
        s(&mcap_path),
        "--summary",
        s(&summary_path),
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let buf = std::fs::read(&mcap_path).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().expect("summary section");
    let run_meta = summary
        .metadata_indexes
        .iter()
        .find(|i| i.name == "agglo")
        .map(|i| mcap::read::metadata(&buf, i).unwrap().metadata)
        .expect("run metadata");
    let recorded: serde_json::Value = serde_json::from_str(&run_meta["pipeline"]).unwrap();
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
    assert_eq!(recorded, written["pipeline"]);
    assert_eq!(recorded["core"], "stepped");
    assert_eq!(
        recorded["left_out"][0],
        "fragmentation off: γ = ∞ (material.gamma = null)"
    );
    assert!(
        recorded["systems"]
            .as_array()
            .unwrap()
            .contains(&"drift::drift".into())
    );
    assert_eq!(run_meta["box_half_width_m"].parse::<f64>().unwrap(), 5e-3);

    // `agglo inspect` shows both.
    let text = String::from_utf8(agglo(&["inspect", s(&mcap_path)]).stdout).unwrap();
    assert!(text.contains("box half-width D = 5e-3 m"), "{text}");
    assert!(
        text.contains("stepped core: contact::detect_contacts →"),
        "{text}"
    );
    assert!(text.contains("fragmentation off: γ = ∞"), "{text}");
}

/// Snapshots at the default rate fall at the first step end past each multiple of T/300:
/// never two in one interval, and fewer than 301 when steps grow long. The count for
/// `paper2004_best` is the one docs/foxglove.md quotes.
#[test]
fn default_snapshots_follow_the_crossings_and_the_docs_count_them() {
    let dir = tempfile::tempdir().unwrap();
    let mcap_path = dir.path().join("p04.mcap");
    let out = agglo(&[
        "run",
        s(&scenarios_dir().join("paper2004_best.json")),
        "--out",
        s(&mcap_path),
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let buf = std::fs::read(&mcap_path).unwrap();
    let times: Vec<f64> = messages(&buf)
        .into_iter()
        .filter(|(topic, _, _)| topic == "/stats")
        .map(|(_, _, data)| {
            let v: serde_json::Value = serde_json::from_slice(&data).unwrap();
            v["time"].as_f64().unwrap()
        })
        .collect();
    let interval = 0.01 / 300.0; // T / 300 [s]
    let cells: Vec<f64> = times.iter().map(|t| (t / interval).floor()).collect();
    // Every snapshot but the last (the final state, always recorded) opens a new interval.
    for pair in cells[..cells.len() - 1].windows(2) {
        assert!(pair[1] > pair[0], "two snapshots in one interval: {pair:?}");
    }
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/foxglove.md"))
            .unwrap();
    let quoted: usize = doc
        .split("`paper2004_best` records ")
        .nth(1)
        .and_then(|t| t.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .expect("docs/foxglove.md quotes the snapshot count of paper2004_best");
    assert_eq!(
        times.len(),
        quoted,
        "docs/foxglove.md says `paper2004_best` records {quoted} snapshots: update it"
    );
    assert!(times.len() < 301);
}

/// `output.mcap`, the recording's old name in a scenario, still records (issue 40: one
/// name for the recording, `output.recording.path` as `--recording` and `recording=`):
/// it is read into `output.recording.path`, so the scenario the recording embeds holds
/// only the new name; giving both is refused, naming the old one.
#[test]
fn the_old_output_mcap_is_read_as_the_recording_path() {
    let dir = tempfile::tempdir().unwrap();
    let old = dir.path().join("old.mcap");
    let scenario = scenario_file(dir.path(), "old_name", |v| {
        v["output"] = serde_json::json!({ "mcap": old.to_str().unwrap() });
    });
    let out = agglo(&["run", s(&scenario), "-q"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let embedded = agglo::record::scenario_from_recording(&old).unwrap();
    assert_eq!(embedded.output.recording.path.as_deref(), old.to_str());
    assert_eq!(embedded.output.mcap, None);
    assert!(!embedded.to_json().contains("\"mcap\""));

    let text = std::fs::read_to_string(&scenario).unwrap();
    let mut both: serde_json::Value = serde_json::from_str(&text).unwrap();
    both["output"]["recording"] = serde_json::json!({ "path": "new.mcap" });
    let error = agglo::scenario::Scenario::from_json(&both.to_string())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("output.mcap") && error.contains("output.recording.path"),
        "{error}"
    );
}
