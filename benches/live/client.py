#!/usr/bin/env python3
"""A Foxglove WebSocket client that subscribes to every channel of `agglo run --live` and
reads (and drops) everything until the server closes: the subscribed client of the live
overhead timing (README, "Watch it live"). Standard library only.

usage: client.py PORT [HOST]      (retries for 60 s while the server starts)
"""
import base64, json, os, socket, struct, sys, time

port = int(sys.argv[1])
host = sys.argv[2] if len(sys.argv) > 2 else "127.0.0.1"

deadline = time.time() + 60
while True:
    try:
        s = socket.create_connection((host, port))
        break
    except OSError:
        if time.time() > deadline:
            sys.exit(f"no server on {host}:{port}")
        time.sleep(0.05)

key = base64.b64encode(os.urandom(16)).decode()
s.sendall(
    (
        f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
        "Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
    ).encode()
)
buf = b""
while b"\r\n\r\n" not in buf:
    buf += s.recv(4096)
head, buf = buf.split(b"\r\n\r\n", 1)
if b" 101 " not in head.split(b"\r\n")[0]:
    sys.exit(head.decode(errors="replace"))


def read_exact(n):
    global buf
    while len(buf) < n:
        chunk = s.recv(1 << 20)
        if not chunk:
            raise EOFError
        buf += chunk
    out, buf = buf[:n], buf[n:]
    return out


def frame():
    b0, b1 = read_exact(2)
    n = b1 & 0x7F
    if n == 126:
        n = struct.unpack(">H", read_exact(2))[0]
    elif n == 127:
        n = struct.unpack(">Q", read_exact(8))[0]
    return b0 & 0x0F, read_exact(n)


def send_text(text):
    data = text.encode()
    mask = os.urandom(4)
    n = len(data)
    header = bytes([0x81]) + (
        bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n)
    )
    s.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))


subscribed, received, size, per = set(), 0, 0, {}
try:
    while True:
        op, data = frame()
        if op == 8:
            break
        if op == 1:
            msg = json.loads(data)
            if msg.get("op") == "advertise":
                subs = [
                    {"id": c["id"], "channelId": c["id"]}
                    for c in msg["channels"]
                    if c["id"] not in subscribed
                ]
                subscribed.update(c["id"] for c in msg["channels"])
                send_text(json.dumps({"op": "subscribe", "subscriptions": subs}))
        elif op == 2:
            received += 1
            size += len(data)
            sub = struct.unpack("<I", data[1:5])[0]
            per[sub] = per.get(sub, 0) + len(data)
except (EOFError, ConnectionError):
    pass
print(f"client: {received} messages, {size / 1e6:.1f} MB; bytes per channel id {per}", file=sys.stderr)
