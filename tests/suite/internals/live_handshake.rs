//! Unit tests of `live::handshake` (src/live/handshake.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::live::handshake::*;

const REQUEST: &str =
    "GET / HTTP/1.1\r\nHost: x\r\nSec-WebSocket-Protocol: NAMES\r\nUpgrade: websocket\r\n\r\n";

fn request(names: &str) -> Vec<u8> {
    REQUEST.replace("NAMES", names).into_bytes()
}

#[test]
fn only_an_old_only_client_is_renamed() {
    let (head, back) = rename_request(&request(OLD_NAME));
    assert!(back);
    assert_eq!(head, request(NEW_NAME));
    for names in [
        NEW_NAME.to_string(),
        "foxglove.sdk.v1.1".into(),
        format!("{OLD_NAME}, {NEW_NAME}"),
        "something.else".into(),
    ] {
        let (head, back) = rename_request(&request(&names));
        assert!(!back, "{names}");
        assert_eq!(head, request(&names), "{names}");
    }
}

#[test]
fn the_answer_is_renamed_back_and_nothing_else_changes() {
    let reply = format!(
        "HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: {NEW_NAME}\r\nX-Note: {NEW_NAME}\r\n\r\n"
    );
    let renamed = rename_token(reply.as_bytes(), NEW_NAME, OLD_NAME);
    assert_eq!(
        String::from_utf8(renamed).unwrap(),
        format!(
            "HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: {OLD_NAME}\r\nX-Note: {NEW_NAME}\r\n\r\n"
        )
    );
    // `foxglove.sdk.v1.1` is not `foxglove.sdk.v1`: tokens match whole.
    assert_eq!(
        offered(&rename_token(
            &request("foxglove.sdk.v1.1"),
            NEW_NAME,
            OLD_NAME
        )),
        ["foxglove.sdk.v1.1"]
    );
}
