//! Foxglove layouts: the generic one shipped in `docs/`, the one `agglo run --out`
//! writes beside its recording and the one `agglo layout` writes for an existing file.
//! Each must name only panel types Foxglove knows and only topics a recording has,
//! and a fitted layout's camera must see the whole box of its recording.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_agglo");

/// Panel types of Foxglove Studio 1.48 (the version `foxglove-shot` runs): the `type`
/// of every entry of `getBuiltin` in `@foxglove/studio-base@1.48.0`,
/// `src/panels/index.js` (npm). A panel type outside this list shows "Unknown panel
/// type: X" instead of the panel — as `Log` did before it became `RosOut`.
const FOXGLOVE_PANEL_TYPES: &[&str] = &[
    "3D",
    "DiagnosticStatusPanel",
    "DiagnosticSummary",
    "ImageViewPanel",
    "Indicator",
    "Gauge",
    "Teleop",
    "map",
    "Parameters",
    "Plot",
    "Publish",
    "RawMessages",
    "RosOut",
    "StateTransitions",
    "Table",
    "TopicGraph",
    "SourceInfo",
    "GlobalVariableSliderPanel",
    "NodePlayground",
    "Tab",
];

/// The topics every agglo recording has (src/record/mod.rs), all of which the layout shows.
const TOPICS: [&str; 4] = ["/particles", "/box", "/stats", "/events"];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn agglo(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("agglo runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Record a shipped scenario to `dir/NAME.mcap` (the run writes `NAME.layout.json` too).
fn record(dir: &Path, scenario: &str) -> PathBuf {
    let mcap = dir.join(scenario.replace(".json", ".mcap"));
    let path = root().join("scenarios").join(scenario);
    assert_ok(&agglo(&["run", s(&path), "--out", s(&mcap), "-q"]));
    mcap
}

/// What a recording offers a layout: its topics, the fields of its `/stats`
/// messages, and its box half-width.
struct Recording {
    topics: BTreeSet<String>,
    stats_fields: BTreeSet<String>,
    half_width: f64,
}

fn read_recording(path: &Path) -> Recording {
    let buf = std::fs::read(path).unwrap();
    let mut topics = BTreeSet::new();
    let mut stats_fields = BTreeSet::new();
    let mut half_width = None;
    for m in mcap::MessageStream::new(&buf).unwrap() {
        let m = m.unwrap();
        topics.insert(m.channel.topic.clone());
        if m.channel.topic == "/stats" {
            let v: Value = serde_json::from_slice(&m.data).unwrap();
            stats_fields.extend(v.as_object().unwrap().keys().cloned());
        }
        if m.channel.topic == "/box" {
            half_width = Some(box_half_width_drawn(&m.data));
        }
    }
    Recording {
        topics,
        stats_fields,
        half_width: half_width.expect("a /box message"),
    }
}

/// D as drawn: the largest corner coordinate of the `/box` line list.
fn box_half_width_drawn(data: &[u8]) -> f64 {
    use foxglove::Decode;
    let update = foxglove::schemas::SceneUpdate::decode(data).unwrap();
    update.entities[0].lines[0]
        .points
        .iter()
        .flat_map(|p| [p.x.abs(), p.y.abs(), p.z.abs()])
        .fold(0.0, f64::max)
}

fn read_layout(path: &Path) -> Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("reading layout {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}

/// Panel ids placed in the layout tree (its leaves).
fn placed_panels(tree: &Value, out: &mut BTreeSet<String>) {
    match tree {
        Value::String(id) => {
            out.insert(id.clone());
        }
        Value::Object(split) => {
            for key in ["first", "second"] {
                placed_panels(&split[key], out);
            }
        }
        other => panic!("unexpected layout node {other}"),
    }
}

/// Every message path a panel config names: strings and object keys starting with `/`
/// (`/stats.bodies`, `/events`, the 3D panel's `topics` keys), with the panel id.
fn message_paths(panel: &str, config: &Value, out: &mut Vec<(String, String)>) {
    match config {
        Value::String(x) if x.starts_with('/') => out.push((panel.into(), x.clone())),
        Value::Array(items) => items.iter().for_each(|v| message_paths(panel, v, out)),
        Value::Object(map) => {
            for (key, value) in map {
                if key.starts_with('/') {
                    out.push((panel.into(), key.clone()));
                }
                message_paths(panel, value, out);
            }
        }
        _ => {}
    }
}

/// `/stats.bodies` → (`/stats`, Some(`bodies`)); `/events` → (`/events`, None).
fn split_path(path: &str) -> (&str, Option<&str>) {
    match path.split_once('.') {
        Some((topic, field)) => (topic, Some(field)),
        None => (path, None),
    }
}

/// The checks every layout must pass against `recording`.
fn check_layout(name: &str, layout: &Value, recording: &Recording) {
    let configs = layout["configById"]
        .as_object()
        .unwrap_or_else(|| panic!("{name}: no configById"));
    let mut placed = BTreeSet::new();
    placed_panels(&layout["layout"], &mut placed);
    let configured: BTreeSet<String> = configs.keys().cloned().collect();
    assert_eq!(placed, configured, "{name}: panels placed vs configured");

    for id in &placed {
        let kind = id.split_once('!').map_or(id.as_str(), |(k, _)| k);
        assert!(
            FOXGLOVE_PANEL_TYPES.contains(&kind),
            "{name}: panel {id} has type {kind}, which Foxglove 1.48 does not know"
        );
    }

    let mut paths = Vec::new();
    for (id, config) in configs {
        message_paths(id, config, &mut paths);
    }
    let mut named = BTreeSet::new();
    for (panel, path) in &paths {
        let (topic, field) = split_path(path);
        assert!(
            recording.topics.contains(topic),
            "{name}: panel {panel} names topic {topic}, absent from the recording ({:?})",
            recording.topics
        );
        if let (Some(field), "/stats") = (field, topic) {
            assert!(
                recording.stats_fields.contains(field),
                "{name}: panel {panel} plots /stats.{field}, which /stats does not have"
            );
        }
        named.insert(topic.to_string());
    }
    let all: BTreeSet<String> = TOPICS.iter().map(|t| t.to_string()).collect();
    assert_eq!(named, all, "{name}: the layout should show every topic");
}

/// The 3D panels' cameras, by panel id.
fn cameras(layout: &Value) -> BTreeMap<String, Value> {
    layout["configById"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(id, _)| id.starts_with("3D!"))
        .map(|(id, c)| (id.clone(), c["cameraState"].clone()))
        .collect()
}

/// A fitted camera sees the whole box [−D, D]³ (bounding sphere √3 D around the target
/// at the origin): between its near and far planes and inside the vertical field of view.
fn check_camera_fits(name: &str, layout: &Value, d: f64) {
    let cams = cameras(layout);
    assert!(!cams.is_empty(), "{name}: no 3D panel");
    for (id, cam) in cams {
        let get = |k: &str| {
            cam[k]
                .as_f64()
                .unwrap_or_else(|| panic!("{name} {id}: {k}"))
        };
        let (distance, near, far, fovy) = (get("distance"), get("near"), get("far"), get("fovy"));
        let r = 3f64.sqrt() * d;
        assert!(
            near < distance - r,
            "{name} {id}: near plane {near} clips the box"
        );
        assert!(
            far > distance + r,
            "{name} {id}: far plane {far} clips the box"
        );
        let half_angle = (0.5 * fovy).to_radians();
        assert!(
            distance * half_angle.sin() >= r,
            "{name} {id}: distance {distance} too close to see the box (D = {d})"
        );
        // ... and not so far that the box is a speck: it fills at least a third of the view.
        assert!(
            distance * half_angle.sin() <= 3.0 * r,
            "{name} {id}: distance {distance} too far for D = {d}"
        );
    }
}

#[test]
fn every_layout_names_known_panels_and_recorded_topics() {
    let dir = tempfile::tempdir().unwrap();
    let p04_like = record(dir.path(), "quick_demo.json");
    let p02 = record(dir.path(), "paper2002_best.json");
    let rebuilt = dir.path().join("rebuilt.json");
    assert_ok(&agglo(&["layout", s(&p02), "--out", s(&rebuilt)]));

    let layouts = [
        (
            "docs/foxglove_layout.json",
            root().join("docs/foxglove_layout.json"),
            &p04_like,
        ),
        (
            "quick_demo.layout.json",
            p04_like.with_extension("layout.json"),
            &p04_like,
        ),
        (
            "paper2002_best.layout.json",
            p02.with_extension("layout.json"),
            &p02,
        ),
        ("agglo layout paper2002_best.mcap", rebuilt, &p02),
    ];
    for (name, path, recording) in layouts {
        let recording = read_recording(recording);
        check_layout(name, &read_layout(&path), &recording);
    }
}

#[test]
fn fitted_layouts_frame_their_recordings_box() {
    let dir = tempfile::tempdir().unwrap();
    for scenario in ["quick_demo.json", "paper2002_best.json"] {
        let mcap = record(dir.path(), scenario);
        let d = read_recording(&mcap).half_width;
        let written = read_layout(&mcap.with_extension("layout.json"));
        check_camera_fits(scenario, &written, d);
        // `agglo layout` reads D back from the file and writes the same layout.
        let again = dir.path().join("again.json");
        assert_ok(&agglo(&["layout", s(&mcap), "--out", s(&again)]));
        assert_eq!(read_layout(&again), written, "{scenario}");
    }
    // The generic layout is fitted to P04's box (D = 1 cm).
    let generic = read_layout(&root().join("docs/foxglove_layout.json"));
    check_camera_fits("docs/foxglove_layout.json", &generic, 1e-2);
}

#[test]
fn layout_defaults_to_a_file_beside_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = record(dir.path(), "paper2002_best.json");
    let beside = mcap.with_extension("layout.json");
    std::fs::remove_file(&beside).unwrap();
    let out = agglo(&["layout", s(&mcap)]);
    assert_ok(&out);
    assert!(beside.exists(), "{}", String::from_utf8_lossy(&out.stdout));
}

#[test]
fn layout_of_something_that_is_not_a_recording_fails_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.mcap");
    std::fs::write(&text, "not a recording").unwrap();
    let foreign = dir.path().join("foreign.mcap");
    write_foreign_mcap(&foreign);
    let cases = [
        (dir.path().join("missing.mcap"), "No such file"),
        (text, "not an MCAP file"),
        (foreign, "box.half_width"),
    ];
    for (path, expect) in cases {
        let out = agglo(&["layout", s(&path)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{}: {err}", path.display());
        assert!(err.contains(expect), "{}: {err}", path.display());
        assert!(!err.contains("panicked"), "{err}");
        assert!(!path.with_extension("layout.json").exists());
    }
}

/// A valid MCAP file from some other program: one channel, no agglo metadata.
fn write_foreign_mcap(path: &Path) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let channel = w
        .add_channel(0, "/chatter", "json", &BTreeMap::new())
        .unwrap();
    let header = mcap::records::MessageHeader {
        channel_id: channel,
        sequence: 0,
        log_time: 0,
        publish_time: 0,
    };
    w.write_to_known_channel(&header, b"{}").unwrap();
    w.finish().unwrap();
}
