//! What a user who hands `agglo` something that is not a scenario reads: an empty file,
//! a cut-off file, JSON that is not an object, bytes that are not UTF-8, trailing text —
//! each in a person's words, naming the file and the position; and, over random bytes
//! and random mutations of the shipped scenarios, the loader never panics and every error
//! names a field or a position.

use std::path::{Path, PathBuf};

use agglo::prelude::*;
use proptest::prelude::*;

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn load_error(bytes: &[u8]) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "scene.json", bytes);
    let err = Scenario::load(&path).expect_err("not a scenario");
    (err.to_string(), path.display().to_string())
}

#[test]
fn an_empty_file_is_called_empty() {
    for text in ["", "  \n\t "] {
        let (message, path) = load_error(text.as_bytes());
        assert_eq!(message, format!("{path} is empty"));
    }
}

#[test]
fn a_cut_off_file_says_where_it_ends() {
    let (message, path) = load_error(br#"{"name": "x", "seed": 1, "box": {"half_width": 0.01}"#);
    assert_eq!(
        message,
        format!("{path} ends early at line 1 column 52 (cut off?)")
    );
}

#[test]
fn json_that_is_not_an_object_says_what_it_is() {
    for (text, kind) in [
        ("[1, 2]", "an array"),
        ("\"quick_demo\"", "a string"),
        ("42", "a number"),
        ("null", "null"),
        ("true", "a boolean"),
    ] {
        let (message, _) = load_error(text.as_bytes());
        assert!(
            message.contains("the top level must be a JSON object") && message.ends_with(kind),
            "{text}: {message}"
        );
    }
}

#[test]
fn bytes_that_are_not_utf8_give_the_offset() {
    let (message, path) = load_error(b"{\"name\": \"\xff\"}");
    assert_eq!(
        message,
        format!("{path} is not UTF-8 text (invalid byte at offset 10)")
    );
}

#[test]
fn text_after_the_object_is_refused() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two_body.json"),
    )
    .unwrap();
    assert!(Scenario::from_json(&text).is_ok());
    let err = Scenario::from_json(&format!("{text}\n{{}}"))
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with(
            "the scenario has more after the scenario's object: trailing characters at line"
        ),
        "{err}"
    );
}

#[test]
fn a_missing_top_level_field_is_named_with_its_position() {
    let err = Scenario::from_json("{}").unwrap_err().to_string();
    assert_eq!(err, "the scenario: missing field `name` at line 1 column 2");
}

/// An error names a field (a dotted path, or a missing/unknown field) or a position
/// (line and column, or a byte offset), or says the text is empty.
fn names_a_field_or_a_position(message: &str) -> bool {
    message.contains("scenario field `")
        || message.starts_with("invalid scenario:\n  ")
        || message.contains(" at line ")
        || message.contains("is empty")
        || message.contains("the top level must be a JSON object")
}

/// The shipped scenarios' texts.
fn shipped() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut texts: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| std::fs::read_to_string(p).unwrap())
        .filter(|t| Scenario::from_json(t).is_ok()) // inverse-problem files are not scenarios
        .collect();
    texts.sort();
    texts
}

/// One edit of a text: delete a span, insert a byte, or replace a byte.
#[derive(Debug, Clone)]
enum Mutation {
    Delete { at: usize, len: usize },
    Insert { at: usize, byte: u8 },
    Replace { at: usize, byte: u8 },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1usize..40).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Insert { at, byte }),
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Replace { at, byte }),
    ]
}

fn apply(text: &str, edits: &[Mutation]) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for edit in edits {
        let n = bytes.len().max(1);
        match *edit {
            Mutation::Delete { at, len } => {
                let at = at % n;
                let end = (at + len).min(bytes.len());
                bytes.drain(at.min(end)..end);
            }
            Mutation::Insert { at, byte } => bytes.insert(at % (bytes.len() + 1), byte),
            Mutation::Replace { at, byte } => {
                if !bytes.is_empty() {
                    bytes[at % n] = byte;
                }
            }
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic_and_errors_say_where(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Err(e) = Scenario::from_json(&text) {
            let message = e.to_string();
            prop_assert!(names_a_field_or_a_position(&message), "{message}");
        }
    }

    #[test]
    fn mutated_shipped_scenarios_never_panic_and_errors_say_where(
        which in any::<usize>(),
        edits in proptest::collection::vec(mutation(), 1..4),
    ) {
        let texts = shipped();
        let text = apply(&texts[which % texts.len()], &edits);
        if let Err(e) = Scenario::from_json(&text) {
            let message = e.to_string();
            prop_assert!(names_a_field_or_a_position(&message), "{message}");
        }
    }
}
