//! `--live`: `agglo run` and `agglo optimize` served over the Foxglove WebSocket protocol
//! on a loopback port, read by a WebSocket client as Foxglove reads it (advertise →
//! subscribe → binary message data). The live view changes nothing: the summary, the
//! final state and the recording are the bytes of a run without it. A bad address is
//! refused before the run, and a client that stops reading never holds the run up.
//!
//! Every wait is bounded (a minute at most); everything is on 127.0.0.1.

use std::collections::BTreeMap;
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use foxglove::Decode;
use foxglove::schemas::SceneUpdate;
use serde_json::{Value, json};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

const BIN: &str = env!("CARGO_BIN_EXE_agglo");

/// The subprotocol of the `foxglove` crate's server (0.30).
const SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The same protocol's name before the SDK, the only one Foxglove Studio 1.x and
/// Lichtblick up to 1.21 offer.
const OLD_SUBPROTOCOL: &str = "foxglove.websocket.v1";

/// Longest wait for anything (start-up, a message, the end of a run).
const PATIENCE: Duration = Duration::from_secs(60);

fn scenario(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
}

/// A port free now (the kernel's choice; released at once, so a later bind can race,
/// which only a busy machine would lose).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

type Ws = WebSocket<TcpStream>;

/// Connect as Foxglove does, retrying while the server starts.
fn connect(port: u16, child: &mut Child) -> Ws {
    let (ws, answered) = connect_offering(port, child, SUBPROTOCOL);
    assert_eq!(
        answered, SUBPROTOCOL,
        "the server negotiates Foxglove's subprotocol"
    );
    ws
}

/// Connect offering the subprotocol names `offered` (comma-separated), retrying while
/// the server starts; the socket and the name the server answered.
fn connect_offering(port: u16, child: &mut Child, offered: &str) -> (Ws, String) {
    let start = Instant::now();
    loop {
        if let Ok(stream) = TcpStream::connect(("127.0.0.1", port)) {
            let mut request = format!("ws://127.0.0.1:{port}")
                .into_client_request()
                .unwrap();
            request
                .headers_mut()
                .insert("Sec-WebSocket-Protocol", offered.parse().unwrap());
            let (ws, response) = tungstenite::client(request, stream)
                .unwrap_or_else(|e| panic!("handshake offering {offered}: {e}"));
            let answered = response.headers()["sec-websocket-protocol"]
                .to_str()
                .unwrap()
                .to_string();
            ws.get_ref()
                .set_read_timeout(Some(Duration::from_millis(500)))
                .unwrap();
            return (ws, answered);
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("agglo exited ({status}) before serving");
        }
        assert!(start.elapsed() < PATIENCE, "no server on port {port}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// An advertised channel: topic → (id, encoding, schema name, schema encoding).
type Channels = BTreeMap<String, (u64, String, String, String)>;

/// Read text messages until the channels in `want` are advertised.
fn advertised(ws: &mut Ws, want: &[&str]) -> Channels {
    let start = Instant::now();
    let mut channels = Channels::new();
    while !want.iter().all(|t| channels.contains_key(*t)) {
        assert!(start.elapsed() < PATIENCE, "advertised only {channels:?}");
        let Some(Message::Text(text)) = read(ws) else {
            continue;
        };
        let v: Value = serde_json::from_str(text.as_str()).unwrap();
        if v["op"] == "advertise" {
            for c in v["channels"].as_array().unwrap() {
                channels.insert(
                    c["topic"].as_str().unwrap().to_string(),
                    (
                        c["id"].as_u64().unwrap(),
                        c["encoding"].as_str().unwrap().to_string(),
                        c["schemaName"].as_str().unwrap().to_string(),
                        c["schemaEncoding"].as_str().unwrap_or("").to_string(),
                    ),
                );
            }
        }
    }
    channels
}

/// Subscribe to `topics`; subscription i is topic i.
fn subscribe(ws: &mut Ws, channels: &Channels, topics: &[&str]) {
    let subscriptions: Vec<Value> = topics
        .iter()
        .enumerate()
        .map(|(i, t)| json!({ "id": i, "channelId": channels[*t].0 }))
        .collect();
    ws.send(Message::text(
        json!({ "op": "subscribe", "subscriptions": subscriptions }).to_string(),
    ))
    .unwrap();
}

/// One message, or None on a read timeout; panics on other errors except a closed
/// connection (None too).
fn read(ws: &mut Ws) -> Option<Message> {
    match ws.read() {
        Ok(m) => Some(m),
        Err(tungstenite::Error::Io(e))
            if matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ) =>
        {
            None
        }
        Err(_) => None,
    }
}

/// Message data received until the server closes or `child` exits: (subscription, log
/// time, payload).
fn collect(ws: &mut Ws, child: &mut Child) -> Vec<(u32, u64, Vec<u8>)> {
    let start = Instant::now();
    let mut got = Vec::new();
    loop {
        assert!(start.elapsed() < PATIENCE, "the run did not end");
        match ws.read() {
            Ok(Message::Binary(b)) => {
                assert_eq!(b[0], 1, "binary opcode 1 = message data");
                let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
                let t = u64::from_le_bytes(b[5..13].try_into().unwrap());
                got.push((sub, t, b[13..].to_vec()));
            }
            Ok(Message::Close(_)) => break,
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
            }
            Err(_) => break,
        }
    }
    got
}

fn wait(child: Child) -> std::process::Output {
    let start = Instant::now();
    let mut child = child;
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > PATIENCE {
            let _ = child.kill();
            panic!("agglo did not finish");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// `agglo run quick_demo` in `dir` with relative output paths (so that two runs record
/// the same command line), plus `extra` flags. A live run closes as soon as it ends
/// (`--live-linger 0`) unless `extra` sets the linger: these tests read until the server
/// closes.
fn run_in(dir: &Path, extra: &[&str]) -> Child {
    let mut extra = extra.to_vec();
    if extra.contains(&"--live") && !extra.contains(&"--live-linger") {
        extra.extend(["--live-linger", "0"]);
    }
    Command::new(BIN)
        .current_dir(dir)
        .arg("run")
        .arg(scenario("quick_demo.json"))
        .args([
            "--seed",
            "11",
            "--out",
            "run.mcap",
            "--summary",
            "summary.json",
        ])
        .args(["--final-state", "final.csv", "-q"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// The summary without its wall time (the one field two identical runs differ in).
fn summary(dir: &Path) -> Value {
    let mut v: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("wall_seconds");
    v
}

/// The last `/stats` message of a recording.
fn last_recorded_stats(mcap: &Path) -> Value {
    let buf = std::fs::read(mcap).unwrap();
    let last = mcap::MessageStream::new(&buf)
        .unwrap()
        .map(|m| m.unwrap())
        .filter(|m| m.channel.topic == "/stats")
        .last()
        .expect("a /stats message");
    serde_json::from_slice(&last.data).unwrap()
}

#[test]
fn a_live_run_serves_the_recordings_channels_and_changes_nothing() {
    let live_dir = tempfile::tempdir().unwrap();
    let plain_dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut child = run_in(live_dir.path(), &["--live", &addr, "--live-wait"]);
    let mut ws = connect(port, &mut child);
    let channels = advertised(&mut ws, &["/particles", "/box", "/stats", "/events"]);
    // The recording's channels and schemas (src/record/mod.rs).
    let scene = |t: &str| channels[t].1 == "protobuf" && channels[t].2 == "foxglove.SceneUpdate";
    assert!(scene("/particles") && scene("/box"), "{channels:?}");
    assert_eq!(
        (channels["/stats"].1.as_str(), channels["/stats"].2.as_str()),
        ("json", "agglo.Stats")
    );
    assert_eq!(channels["/stats"].3, "jsonschema");
    assert_eq!(channels["/events"].2, "foxglove.Log");
    subscribe(&mut ws, &channels, &["/particles", "/stats"]);
    let got = collect(&mut ws, &mut child);
    let out = wait(child);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("ws://{addr}")),
        "the address is printed: {stderr}"
    );

    let particles: Vec<SceneUpdate> = got
        .iter()
        .filter(|m| m.0 == 0)
        .map(|m| SceneUpdate::decode(m.2.as_slice()).expect("a foxglove.SceneUpdate"))
        .collect();
    let stats: Vec<Value> = got
        .iter()
        .filter(|m| m.0 == 1)
        .map(|m| serde_json::from_slice(&m.2).expect("JSON /stats"))
        .collect();
    assert!(
        !particles.is_empty() && !stats.is_empty(),
        "{} messages",
        got.len()
    );
    // Frame 0 (the run waited for us): 300 bodies, every one a sphere with its id.
    let first = &particles[0];
    assert_eq!(first.entities.len(), 300);
    assert!(
        first
            .entities
            .iter()
            .all(|e| e.spheres.len() == 1 && e.id.parse::<u64>().is_ok())
    );
    assert_eq!(stats[0]["step"], 0);
    assert_eq!(stats[0]["bodies"], 300);

    // The same run without --live: the same summary, final state and recording bytes.
    let plain = wait(run_in(plain_dir.path(), &[]));
    assert!(plain.status.success());
    let (a, b) = (live_dir.path(), plain_dir.path());
    assert_eq!(summary(a), summary(b));
    for file in ["final.csv", "run.mcap"] {
        assert!(
            std::fs::read(a.join(file)).unwrap() == std::fs::read(b.join(file)).unwrap(),
            "{file} differs with --live"
        );
    }
    // The last frame is the final state, and its statistics are the recording's last
    // (every body, whatever /particles shows).
    let last = stats.last().unwrap();
    assert_eq!(last["step"], summary(b)["steps"]);
    assert_eq!(*last, last_recorded_stats(&b.join("run.mcap")));
    assert_eq!(
        particles.last().unwrap().entities.len() as u64,
        last["bodies"].as_u64().unwrap()
    );
}

/// Every Foxglove client connects: one offering the protocol's old name
/// (`foxglove.websocket.v1`, Studio 1.x, Lichtblick ≤ 1.21), one offering the new, and one
/// offering both; each hears a name it offered and receives the run's frames.
#[test]
fn clients_offering_either_name_of_the_protocol_connect() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut child = run_in(dir.path(), &["--live", &addr, "--live-wait"]);
    let both = format!("{OLD_SUBPROTOCOL}, {SUBPROTOCOL}");
    let mut clients = Vec::new();
    for (offered, expected) in [
        (OLD_SUBPROTOCOL, OLD_SUBPROTOCOL),
        (SUBPROTOCOL, SUBPROTOCOL),
        // The crate's server picks among the offered names; the new one here.
        (both.as_str(), SUBPROTOCOL),
    ] {
        let (mut ws, answered) = connect_offering(port, &mut child, offered);
        assert_eq!(answered, expected, "offering {offered}");
        let channels = advertised(&mut ws, &["/stats"]);
        clients.push((offered, ws, channels));
    }
    // Only once all three are subscribed does the run (held by --live-wait) matter:
    // the first subscription starts it, so every client gets at least the last frame.
    for (_, ws, channels) in &mut clients {
        subscribe(ws, channels, &["/stats"]);
    }
    for (offered, ws, _) in &mut clients {
        let got = collect(ws, &mut child);
        let last: Value = serde_json::from_slice(&got.last().expect("frames").2)
            .unwrap_or_else(|e| panic!("offering {offered}: /stats is JSON: {e}"));
        assert!(last["bodies"].as_u64().unwrap() >= 1, "offering {offered}");
    }
    let out = wait(child);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A client offering no name of the protocol is still refused (HTTP 400), as the
/// crate's server refuses it.
#[test]
fn a_client_offering_another_protocol_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut child = run_in(dir.path(), &["--live", &addr, "--live-wait"]);
    let start = Instant::now();
    let refused = loop {
        if let Ok(stream) = TcpStream::connect(("127.0.0.1", port)) {
            let mut request = format!("ws://127.0.0.1:{port}")
                .into_client_request()
                .unwrap();
            request
                .headers_mut()
                .insert("Sec-WebSocket-Protocol", "chat.v1".parse().unwrap());
            break tungstenite::client(request, stream).unwrap_err();
        }
        assert!(start.elapsed() < PATIENCE, "no server on port {port}");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(
        matches!(&refused, tungstenite::HandshakeError::Failure(tungstenite::Error::Http(r)) if r.status() == 400),
        "{refused:?}"
    );
    let _ = child.kill();
    let _ = child.wait();
}

/// A run that ends with a client connected tells it so by a status (info, not an error)
/// and keeps its final state served: a panel that subscribes only after the end still
/// gets the last frame; when the client disconnects the process exits at once.
#[test]
fn a_finished_run_keeps_its_final_state_served_until_the_client_leaves() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut child = run_in(
        dir.path(),
        &["--live", &addr, "--live-wait", "--live-linger", "50"],
    );
    let mut ws = connect(port, &mut child);
    let channels = advertised(&mut ws, &["/particles", "/stats"]);
    subscribe(&mut ws, &channels, &["/stats"]);
    // Read until the status that the run has ended.
    let start = Instant::now();
    let status = loop {
        assert!(start.elapsed() < PATIENCE, "no status that the run ended");
        if let Some(Message::Text(text)) = read(&mut ws) {
            let v: Value = serde_json::from_str(text.as_str()).unwrap();
            if v["op"] == "status" {
                break v;
            }
        }
    };
    assert_eq!(
        status["level"], 0,
        "info, not a warning or an error: {status}"
    );
    let message = status["message"].as_str().unwrap();
    assert!(
        message.contains("run has ended") && message.contains("run finished"),
        "{message}"
    );
    // Every file is written before the wait.
    assert!(dir.path().join("summary.json").is_file());
    assert!(dir.path().join("final.csv").is_file());
    let bodies = summary(dir.path())["final_bodies"].as_u64().unwrap();
    // A late subscriber to /particles still receives the final cloud.
    ws.send(Message::text(
        json!({ "op": "subscribe", "subscriptions": [{ "id": 7, "channelId": channels["/particles"].0 }] })
            .to_string(),
    ))
    .unwrap();
    let start = Instant::now();
    let update = loop {
        assert!(start.elapsed() < PATIENCE, "no final frame after the end");
        if let Some(Message::Binary(b)) = read(&mut ws)
            && u32::from_le_bytes(b[1..5].try_into().unwrap()) == 7
        {
            break SceneUpdate::decode(&b[13..]).unwrap();
        }
    };
    assert_eq!(update.entities.len() as u64, bodies);
    assert!(child.try_wait().unwrap().is_none(), "still serving");
    // Leaving ends the wait: well before the 50 s linger.
    let left = Instant::now();
    ws.close(None).unwrap();
    while ws.read().is_ok() {}
    let out = wait(child);
    assert!(out.status.success());
    assert!(
        left.elapsed() < Duration::from_secs(20),
        "exited {:?} after the client left",
        left.elapsed()
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("serving its final state"), "{stderr}");
}

/// `--live-pace` only waits: T / rate of wall time at least, the same outputs.
#[test]
fn a_paced_run_takes_its_time_and_changes_nothing() {
    let paced_dir = tempfile::tempdir().unwrap();
    let plain_dir = tempfile::tempdir().unwrap();
    let end: f64 = 0.002; // [s]; quick_demo runs this in milliseconds unpaced
    let rate = end / 1.5; // simulated seconds per second: at least 1.5 s of wall time
    let port = free_port();
    let start = Instant::now();
    let paced = wait(run_in(
        paced_dir.path(),
        &[
            "--set",
            &format!("time.end={end}"),
            "--live",
            &format!("127.0.0.1:{port}"),
            "--live-pace",
            &rate.to_string(),
        ],
    ));
    let wall = start.elapsed();
    assert!(
        paced.status.success(),
        "{}",
        String::from_utf8_lossy(&paced.stderr)
    );
    assert!(
        wall >= Duration::from_secs_f64(1.5),
        "paced run took {wall:?}"
    );
    let plain = wait(run_in(
        plain_dir.path(),
        &["--set", &format!("time.end={end}")],
    ));
    assert!(plain.status.success());
    assert_eq!(summary(paced_dir.path()), summary(plain_dir.path()));
    for file in ["final.csv", "run.mcap"] {
        assert!(
            std::fs::read(paced_dir.path().join(file)).unwrap()
                == std::fs::read(plain_dir.path().join(file)).unwrap(),
            "{file} differs with --live-pace"
        );
    }
}

#[test]
fn a_large_cloud_shows_a_subset_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let mut child = run_in(
        dir.path(),
        &[
            "--live",
            &format!("127.0.0.1:{port}"),
            "--live-wait",
            "--live-bodies",
            "100",
        ],
    );
    let mut ws = connect(port, &mut child);
    let channels = advertised(&mut ws, &["/particles", "/stats"]);
    subscribe(&mut ws, &channels, &["/particles", "/stats"]);
    let got = collect(&mut ws, &mut child);
    assert!(wait(child).status.success());
    let first = got.iter().find(|m| m.0 == 0).expect("a /particles message");
    let update = SceneUpdate::decode(first.2.as_slice()).unwrap();
    // 300 bodies, at most 100 drawn: 1 in 4 by id hash (≈ 75; the note is one more).
    let spheres = update
        .entities
        .iter()
        .filter(|e| !e.spheres.is_empty())
        .count();
    assert!((30..=120).contains(&spheres), "{spheres} spheres");
    let note = update
        .entities
        .iter()
        .find(|e| e.id == "live_subset")
        .expect("the scene says it shows a subset");
    assert!(
        note.texts[0].text.contains("of 300 bodies"),
        "{}",
        note.texts[0].text
    );
    // The statistics still count every body.
    let stats: Value = serde_json::from_slice(&got.iter().find(|m| m.0 == 1).unwrap().2).unwrap();
    assert_eq!(stats["bodies"], 300);
}

#[test]
fn a_client_that_stops_reading_never_holds_the_run_up() {
    let dir = tempfile::tempdir().unwrap();
    // 10 000 bodies that bounce and never merge: every frame draws all of them (≈ 1.3 MB),
    // and the run lasts seconds, so the unread frames (as many as the time budget lets
    // through, about one a second) exceed what the two sockets buffer (≈ 4 MB on Linux's
    // defaults) and pile up in the server's queue for the client.
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/scenes/peer_bounce_10000.json"),
    )
    .unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    v["time"]["end"] = json!(0.003);
    let scene = dir.path().join("bounce.json");
    std::fs::write(&scene, v.to_string()).unwrap();
    let port = free_port();
    let mut child = Command::new(BIN)
        .current_dir(dir.path())
        .args([
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--summary",
            "summary.json",
        ])
        .args(["--live", &format!("127.0.0.1:{port}"), "--live-wait"])
        .args(["--live-rate", "1000", "--live-bodies", "10000"])
        .args(["--live-linger", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut ws = connect(port, &mut child);
    let channels = advertised(&mut ws, &["/particles", "/stats"]);
    subscribe(&mut ws, &channels, &["/particles", "/stats"]);
    // Never read again; the run must end by itself with every output.
    let out = wait(child);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.path().join("summary.json").exists());
    drop(ws);
}

#[test]
fn an_address_that_cannot_be_bound_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    for (bad, says) in [
        (addr.as_str(), "already in use"),
        ("nonsense", "not an address"),
        ("127.0.0.1:99999", "not an address"),
    ] {
        let out = wait(run_in(dir.path(), &["--live", bad]));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{bad}: accepted");
        assert!(
            stderr.contains(bad) && stderr.contains(says),
            "{bad}: {stderr}"
        );
        assert!(
            !dir.path().join("summary.json").exists(),
            "{bad}: the run started"
        );
    }
}

#[test]
fn a_live_inverse_problem_publishes_every_generation() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let port = free_port();
    let mut child = Command::new(BIN)
        .args(["optimize", scenario("inverse_demo.json").to_str().unwrap()])
        .args(["--out", out_dir.to_str().unwrap(), "--threads", "1", "-q"])
        .args(["--live", &format!("127.0.0.1:{port}"), "--live-wait"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut ws = connect(port, &mut child);
    let channels = advertised(&mut ws, &["/generations", "/events"]);
    assert_eq!(channels["/generations"].2, "agglo.Generation");
    subscribe(&mut ws, &channels, &["/generations"]);
    let got = collect(&mut ws, &mut child);
    let out = wait(child);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let generations: Vec<Value> = got
        .iter()
        .map(|m| serde_json::from_slice(&m.2).unwrap())
        .collect();
    // inverse_demo runs 5 generations; each is published as it ends, with the costs of
    // generations.csv (same f64, printed by the same formatter).
    let csv = std::fs::read_to_string(out_dir.join("generations.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(generations.len(), 5);
    assert_eq!(rows.len(), 5);
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for (g, (msg, row)) in generations.iter().zip(&rows).enumerate() {
        assert_eq!(msg["generation"], g);
        let best: f64 = row[col("best_cost")].parse().unwrap();
        assert_eq!(msg["best_cost"].as_f64().unwrap(), best, "generation {g}");
        for gene in ["v0", "s"] {
            let x = msg["best_genes"][gene].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&x), "{gene} = {x} not normalised");
        }
        assert!(
            msg["samples_per_string"].as_f64().unwrap() >= 3.0,
            "min_samples is 3"
        );
    }
    assert!(out_dir.join("live.layout.json").exists());
}
