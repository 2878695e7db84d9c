//! Watching a run while it runs: `agglo run --live` and `agglo optimize --live` serve
//! their progress over the Foxglove WebSocket protocol (the `foxglove` crate's
//! `live_visualization` server), so the Foxglove app can connect to
//! `ws://ADDR` as a data source.
//!
//! - [`Server`]: the address is checked and bound before any work starts
//!   ([`Server::bind`]); an address that cannot be bound (in use, not an address, no
//!   permission) is an error naming it. Clients offering the protocol's old name
//!   (`foxglove.websocket.v1`) connect as well as those offering the new one
//!   ([`handshake`]).
//! - [`run::LiveRun`]: a simulation, with the recording's channels, schemas and entity
//!   layout (`/particles`, `/box`, `/stats`, `/events`; messages built by
//!   [`crate::record::messages`]), so the fitted layout of a recording works live.
//! - [`inverse::LiveInverse`]: the inverse problem, one `/generations` message per
//!   generation (costs with their standard errors, the best string's genes normalised to
//!   their ranges, samples per string).
//!
//! **Never in the way.** Frames are published on a wall-clock rate
//! ([`LiveOptions::rate_hz`]), not per step: a publisher thread raises a flag when a
//! frame is due and it is idle; the simulation thread, after a step, reads that flag
//! (one relaxed atomic load), and only when it is set and a client is subscribed copies
//! the bodies and the statistics. Selecting, encoding and sending happen on the publisher
//! thread. The frames also keep to a time budget ([`run::TIME_BUDGET`], 2 % of wall
//! time): after each, the next waits at least its cost (capture + publishing) / 2 %, so
//! a cloud of 1e6 bodies gets fewer frames per second rather than a slower run. Each client has a small queue ([`CLIENT_BACKLOG`] messages) whose oldest
//! messages are dropped when it fills, so a stalled client costs memory bounded by a few
//! frames, and a client that disconnects is simply gone. Nothing the live view does
//! changes the run: outputs and recordings are the same bytes as without it.
//!
//! **Large clouds.** `/particles` shows a deterministic subset of at most about
//! [`LiveOptions::max_bodies`] bodies: those whose id hashes (splitmix64) below 2⁶⁴/2ᵏ,
//! with the smallest k that fits. The subsets are nested, so as bodies merge and k falls
//! the shown bodies stay shown. The scene says so (a text entity in `/particles`), and
//! `/stats` is always computed over every body.

pub mod handshake;
pub mod inverse;
pub mod run;

use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context as _;
use foxglove::{Context, FoxgloveError, PartialMetadata, RawChannel, Schema, WebSocketServer};

/// Where `--live` serves when no address is given.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Messages queued per client before the oldest are dropped: a few frames (a frame is a
/// `/particles`, a `/box`, a `/stats` message and its events), so that a stalled client
/// holds at most a few frames of memory (≈ 1 MB each at 10 000 bodies).
pub const CLIENT_BACKLOG: usize = 32;

/// How long the server stays up after the last frame for clients to receive it [s].
const LINGER: Duration = Duration::from_millis(500);

/// How long a finished run keeps serving its final state to a connected client, at most
/// [s] (`--live-linger`): long enough to look at the last frame, short enough that a
/// forgotten client does not hold a terminal for long.
pub const DEFAULT_LINGER_SECONDS: f64 = 60.0;

/// The longest `--live-linger` accepted [s] (a day).
pub const MAX_LINGER_SECONDS: f64 = 86_400.0;

/// How to serve a run live.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveOptions {
    /// The address to serve on.
    pub addr: SocketAddr,
    /// Hold the start until a client subscribes to a channel.
    pub wait: bool,
    /// Frames per second of wall-clock time, at most (> 0).
    pub rate_hz: f64,
    /// Bodies drawn in `/particles` at most, about (≥ 1); statistics cover all.
    pub max_bodies: usize,
    /// When the run ends with a client connected, keep serving the final state until the
    /// client disconnects or this many seconds pass [s] (0 ≤ linger ≤ a day; 0 closes at
    /// once). The client is told by a status message that the run finished.
    pub linger_seconds: f64,
    /// Simulated seconds per wall-clock second, at most (> 0): the run waits after a
    /// step that got ahead of it, so that a short run can be watched. `None`: full speed.
    pub pace: Option<f64>,
}

/// Parse `--live ADDR`: `IP:PORT` or `HOST:PORT` (resolved now). The error names the text.
pub fn parse_addr(text: &str) -> anyhow::Result<SocketAddr> {
    if let Ok(addr) = text.parse::<SocketAddr>() {
        return Ok(addr);
    }
    let hint = "give HOST:PORT, e.g. --live 127.0.0.1:8765 (put --live after the scenario \
                file, or give the address)";
    let mut found = text
        .to_socket_addrs()
        .map_err(|e| anyhow::anyhow!("--live {text:?}: not an address ({e}); {hint}"))?;
    found
        .next()
        .with_context(|| format!("--live {text:?}: the name resolves to no address; {hint}"))
}

/// Check the live options (the rate and the body count, with their allowed ranges).
pub fn check_options(o: &LiveOptions) -> anyhow::Result<()> {
    anyhow::ensure!(
        // Below one frame per 1000 s the frame period no longer fits a Duration for
        // tiny rates (1e-300 panicked), and no one watches a frame a quarter of an hour.
        o.rate_hz.is_finite() && (1e-3..=1000.0).contains(&o.rate_hz),
        "--live-rate: allowed 0.001 ≤ rate ≤ 1000 frames per second (got {})",
        o.rate_hz
    );
    anyhow::ensure!(
        o.linger_seconds.is_finite() && (0.0..=MAX_LINGER_SECONDS).contains(&o.linger_seconds),
        "--live-linger: allowed 0 ≤ seconds ≤ {MAX_LINGER_SECONDS} (got {})",
        o.linger_seconds
    );
    if let Some(pace) = o.pace {
        anyhow::ensure!(
            pace.is_finite() && pace > 0.0,
            "--live-pace: allowed 0 < rate < ∞ simulated seconds per second (got {pace})"
        );
    }
    anyhow::ensure!(
        o.max_bodies >= 1,
        "--live-bodies: allowed ≥ 1 (got {})",
        o.max_bodies
    );
    Ok(())
}

/// A bound WebSocket server with its own Foxglove context (its channels reach only it).
pub struct Server {
    /// Kept alive with the server: dropping the context would close the channels.
    _context: Arc<Context>,
    channels: Vec<Arc<RawChannel>>,
    handle: Option<foxglove::WebSocketServerHandle>,
    /// Listens on `addr` and passes connections through to the crate's server.
    shim: Option<handshake::Shim>,
    addr: SocketAddr,
}

/// A channel to create: topic, message encoding, schema.
pub type Topic = (&'static str, &'static str, Schema);

impl Server {
    /// Create the channels of `topics`, then bind `addr` and start serving them. Errors
    /// name the address and say why: in use, not an address of this machine, no
    /// permission.
    ///
    /// The channels exist before the first client can connect: a channel created while a
    /// client is connected is advertised to it before the server can route its
    /// subscription ("Unknown channel ID" from foxglove 0.30), and that client would
    /// never receive it.
    pub fn bind(addr: SocketAddr, name: &str, topics: Vec<Topic>) -> anyhow::Result<Self> {
        let context = Context::new();
        let channels = topics
            .into_iter()
            .map(|(topic, encoding, schema)| {
                context
                    .channel_builder(topic)
                    .message_encoding(encoding)
                    .schema(schema)
                    .build_raw()
                    .with_context(|| format!("creating live channel {topic}"))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        // The user's address is the shim's; the crate's server listens on a loopback
        // port behind it (module `handshake`: it accepts both names of the protocol).
        let listener = std::net::TcpListener::bind(addr).map_err(|e| bind_error(addr, &e))?;
        let bound = listener.local_addr().map_err(|e| bind_error(addr, &e))?;
        let handle = WebSocketServer::new()
            .name(name)
            .bind("127.0.0.1", 0)
            .context(&context)
            .message_backlog_size(CLIENT_BACKLOG)
            .start_blocking()
            .map_err(|e| match e {
                FoxgloveError::Bind(io) => bind_error(addr, &io),
                e => anyhow::anyhow!("--live {addr}: cannot start the server: {e}"),
            })?;
        let upstream = SocketAddr::from(([127, 0, 0, 1], handle.port()));
        let shim = handshake::Shim::start(listener, upstream)
            .with_context(|| format!("--live {addr}: cannot start the server"))?;
        Ok(Self {
            _context: context,
            channels,
            handle: Some(handle),
            shim: Some(shim),
            addr: bound,
        })
    }

    /// The address served (with the port chosen when 0 was asked for).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The WebSocket URL of the server.
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// The link that opens the server in the Foxglove web app.
    pub fn app_link(&self) -> String {
        format!(
            "https://app.foxglove.dev/?ds=foxglove-websocket&ds.url={}",
            self.url()
        )
    }

    /// The channel of `topic` (created by [`Server::bind`]).
    pub fn channel(&self, topic: &str) -> anyhow::Result<Arc<RawChannel>> {
        self.channels
            .iter()
            .find(|c| c.topic() == topic)
            .cloned()
            .with_context(|| format!("the live server has no channel {topic}"))
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.handle.as_ref().map_or(0, |h| h.client_count())
    }

    /// Tell every connected client `message` as a status (Foxglove shows it in its
    /// problems list, at info level: not an error).
    pub fn publish_status(&self, message: impl Into<String>) {
        if let Some(handle) = &self.handle {
            handle.publish_status(foxglove::websocket::Status::info(message));
        }
    }

    /// Block until one of `channels` has a subscriber, polling `stop` (Ctrl-C): returns
    /// false if a stop was asked for first.
    pub fn wait_for_subscriber(&self, channels: &[&Arc<RawChannel>], stop: &AtomicBool) -> bool {
        while !channels.iter().any(|c| c.has_sinks()) {
            if stop.load(Ordering::SeqCst) {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        true
    }

    /// Give connected clients [`LINGER`] to receive the last messages, then stop.
    pub fn close(mut self) {
        if self.clients() > 0 {
            std::thread::sleep(LINGER);
        }
        if let Some(shim) = self.shim.take() {
            shim.stop();
        }
        if let Some(handle) = self.handle.take() {
            // Closing frames go out in the background (dropping the shutdown handle
            // instead would abort the client tasks at once); the process exit ends them.
            handle.stop().detach_all();
        }
    }
}

/// The error of an address that cannot be bound, naming it and saying what to do.
fn bind_error(addr: SocketAddr, io: &std::io::Error) -> anyhow::Error {
    let why = match io.kind() {
        std::io::ErrorKind::AddrInUse => {
            "the address is already in use (another `agglo --live`? pick another port)"
        }
        std::io::ErrorKind::AddrNotAvailable => {
            "not an address of this machine (use 127.0.0.1, or 0.0.0.0 for every interface)"
        }
        std::io::ErrorKind::PermissionDenied => {
            "permission denied (ports below 1024 need privileges: use a port ≥ 1024)"
        }
        _ => "cannot bind",
    };
    anyhow::anyhow!("--live {addr}: {why} ({io})")
}

/// Log `data` on `channel` at log time `ns` [ns] (a no-op without subscribers).
fn publish(channel: &RawChannel, ns: u64, data: &[u8]) {
    channel.log_with_meta(data, PartialMetadata { log_time: Some(ns) });
}
