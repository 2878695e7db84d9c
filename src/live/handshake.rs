//! Every Foxglove client connects: a handshake shim in front of the `foxglove` crate's
//! WebSocket server that accepts the protocol's old name as well as its new one.
//!
//! The Foxglove WebSocket protocol was called `foxglove.websocket.v1` until the SDK
//! renamed it `foxglove.sdk.v1`; the JSON and binary messages agglo sends are the same
//! under both names. Foxglove Studio 1.x and Lichtblick up to 1.21 offer only the old
//! name, and the `foxglove` crate (0.30) hard-codes the new ones (`foxglove.sdk.v1`,
//! `foxglove.sdk.v1.1`, in its private `websocket::handshake`): it answers an old client
//! with HTTP 400. The crate has no hook to add a name, so rather than patch or vendor it,
//! [`Shim`] listens on the user's address and passes each connection through to the
//! crate's server on a loopback port, renaming the one token in the upgrade handshake:
//!
//! - a request that offers `foxglove.websocket.v1` and no `foxglove.sdk.*` name is
//!   forwarded with `foxglove.sdk.v1` in its place, and the server's answer
//!   `foxglove.sdk.v1` goes back to the client as `foxglove.websocket.v1` — the client
//!   hears the name it offered;
//! - any other request (`foxglove.sdk.v1`, `foxglove.sdk.v1.1`, both old and new names)
//!   is forwarded unchanged, and the server picks among the names offered as it always has.
//!
//! After the two heads every byte passes through unchanged in both directions (two
//! threads per client, each a blocking copy). A stalled client fills the socket buffers
//! and then the crate's own bounded per-client queue, which drops old messages, as
//! without the shim: the run is never held up.

use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// The protocol's name before the SDK (Foxglove Studio 1.x, Lichtblick ≤ 1.21).
pub const OLD_NAME: &str = "foxglove.websocket.v1";
/// The name the `foxglove` crate's server accepts for the same protocol.
pub const NEW_NAME: &str = "foxglove.sdk.v1";

/// The longest upgrade head read [bytes]: a browser's is well under 2 kB.
const MAX_HEAD: usize = 64 * 1024;
/// How long a connection may take to send its head, or the server to answer [s].
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);
/// How often the listener looks for a stop request while no client connects.
const POLL: Duration = Duration::from_millis(20);

/// A listener on the user's address that passes connections through to `upstream`,
/// renaming the old subprotocol name in the handshake ([module docs](self)).
pub struct Shim {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Shim {
    /// Serve `listener` (already bound: its errors were the caller's to report),
    /// forwarding each connection to `upstream`.
    pub fn start(listener: TcpListener, upstream: SocketAddr) -> io::Result<Self> {
        // Non-blocking accept, polled, so that `stop` ends the thread without a
        // connection to wake it.
        listener.set_nonblocking(true)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("live-handshake".into())
            .spawn(move || accept_loop(&listener, upstream, &flag))?;
        Ok(Self {
            stop,
            thread: Some(thread),
        })
    }

    /// Stop accepting (connections already passed through end when the server closes
    /// them) and release the address.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Shim {
    fn drop(&mut self) {
        self.halt();
    }
}

fn accept_loop(listener: &TcpListener, upstream: SocketAddr, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((client, _)) => {
                let _ = std::thread::Builder::new()
                    .name("live-client".into())
                    .spawn(move || {
                        // A client that drops mid-handshake is simply gone.
                        let _ = pass_through(client, upstream);
                    });
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::sleep(POLL),
            // A connection reset before it was accepted, or a transient lack of file
            // descriptors: the next one may succeed.
            Err(_) => std::thread::sleep(POLL),
        }
    }
}

/// One connection: the two heads (renamed as needed), then bytes both ways until either
/// side closes.
fn pass_through(mut client: TcpStream, upstream: SocketAddr) -> io::Result<()> {
    // Accepted sockets inherit non-blocking mode on some platforms.
    client.set_nonblocking(false)?;
    client.set_nodelay(true)?;
    client.set_read_timeout(Some(HEAD_TIMEOUT))?;
    let (head, rest) = read_head(&mut client)?;
    let (head, rename_back) = rename_request(&head);
    let mut server = TcpStream::connect_timeout(&upstream, HEAD_TIMEOUT)?;
    server.set_nodelay(true)?;
    server.write_all(&head)?;
    server.write_all(&rest)?;
    server.set_read_timeout(Some(HEAD_TIMEOUT))?;
    let (reply, rest) = read_head(&mut server)?;
    let reply = if rename_back {
        rename_token(&reply, NEW_NAME, OLD_NAME)
    } else {
        reply
    };
    client.write_all(&reply)?;
    client.write_all(&rest)?;
    client.set_read_timeout(None)?;
    server.set_read_timeout(None)?;

    let (mut client_in, mut server_out) = (client.try_clone()?, server.try_clone()?);
    let upward = std::thread::Builder::new()
        .name("live-client-up".into())
        .spawn(move || {
            let _ = io::copy(&mut client_in, &mut server_out);
            let _ = server_out.shutdown(Shutdown::Write);
        })?;
    let _ = io::copy(&mut server, &mut client);
    // The server closed (or the client stopped taking data): end both directions.
    let _ = client.shutdown(Shutdown::Both);
    let _ = server.shutdown(Shutdown::Both);
    let _ = upward.join();
    Ok(())
}

/// Read an HTTP head (through the blank line) and whatever bytes came after it.
fn read_head(stream: &mut TcpStream) -> io::Result<(Vec<u8>, Vec<u8>)> {
    let mut buffer = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        if let Some(end) = buffer.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buffer.split_off(end + 4);
            return Ok((buffer, rest));
        }
        if buffer.len() > MAX_HEAD {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                "handshake head too long",
            ));
        }
        let n = stream.read(&mut chunk)?;
        if n == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        buffer.extend_from_slice(&chunk[..n]);
    }
}

/// The subprotocol names a head offers (or answers), in order.
pub fn offered(head: &[u8]) -> Vec<String> {
    head.split(|&b| b == b'\n')
        .filter_map(protocol_value)
        .flat_map(|value| {
            value
                .split(',')
                .map(|t| t.trim().to_string())
                .collect::<Vec<_>>()
        })
        .filter(|t| !t.is_empty())
        .collect()
}

/// The request head to forward to the server, and whether the answer must be renamed
/// back: only a client offering the old name and none of the new ones is renamed.
pub fn rename_request(head: &[u8]) -> (Vec<u8>, bool) {
    let names = offered(head);
    let old_only = names.iter().any(|n| n == OLD_NAME)
        && !names.iter().any(|n| n.starts_with("foxglove.sdk."));
    if old_only {
        (rename_token(head, OLD_NAME, NEW_NAME), true)
    } else {
        (head.to_vec(), false)
    }
}

/// `head` with the token `from` replaced by `to` in its Sec-WebSocket-Protocol lines;
/// every other byte unchanged.
pub fn rename_token(head: &[u8], from: &str, to: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(head.len() + 8);
    for (i, line) in head.split(|&b| b == b'\n').enumerate() {
        if i > 0 {
            out.push(b'\n');
        }
        match protocol_value(line) {
            Some(value) => {
                let name_len = line.iter().position(|&b| b == b':').unwrap_or(0);
                let tokens: Vec<&str> = value
                    .split(',')
                    .map(|t| if t.trim() == from { to } else { t.trim() })
                    .collect();
                out.extend_from_slice(&line[..name_len]);
                out.extend_from_slice(b": ");
                out.extend_from_slice(tokens.join(", ").as_bytes());
                if line.ends_with(b"\r") {
                    out.push(b'\r');
                }
            }
            None => out.extend_from_slice(line),
        }
    }
    out
}

/// The value of a `Sec-WebSocket-Protocol` header line (name compared without case).
fn protocol_value(line: &[u8]) -> Option<&str> {
    let colon = line.iter().position(|&b| b == b':')?;
    let name = std::str::from_utf8(&line[..colon]).ok()?;
    if !name.trim().eq_ignore_ascii_case("sec-websocket-protocol") {
        return None;
    }
    let value = std::str::from_utf8(&line[colon + 1..]).ok()?;
    Some(value.trim_end_matches('\r').trim())
}
