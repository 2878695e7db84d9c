//! Unit tests of `record::inspect` (src/record/inspect.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::record::inspect::ends_early;

/// A killed writer's unwritten length and a cut record read as what happened, not
/// as the parser's "length exceeds limit: 18446744073709551615".
#[test]
fn a_cut_recording_is_described_in_words() {
    let unwritten = ends_early(&mcap::McapError::RecordTooLarge {
        opcode: 6,
        len: u64::MAX,
    });
    assert!(unwritten.contains("cut off"), "{unwritten}");
    assert!(!unwritten.contains(&u64::MAX.to_string()), "{unwritten}");
    let cut = ends_early(&mcap::McapError::UnexpectedEof);
    assert!(cut.contains("cut off"), "{cut}");
}
