//! The repository is self-contained: nothing in it points outside it, and the physics
//! specification it cites is its own `docs/model.md`.
//!
//! The tests walk README.md, docs/**/*.md, docs/**/*.json, src/**, engine/**, systems/**,
//! tests/**, benches/**, examples/**, scenarios/**, .ci/run and Cargo.toml, skipping
//! binary files (images, fonts, recordings, anything containing a NUL byte) and every
//! `target/` directory, and check that:
//!
//! 1. no file refers to the shared directory beside the checkout or to an absolute
//!    path of the build machine;
//! 2. the specification is only ever named by its in-tree path (no upper-case file
//!    name of the old out-of-tree copy);
//! 3. `docs/model.md` exists and has the numbered headings `## 1.` to `## 14.`, once
//!    each and in order;
//! 4. every section citation of `docs/model.md` (the path followed by a section sign
//!    and a number) names a section from 1 to 14 that exists as a heading.
//!
//! Every needle is assembled at run time, so this file never matches itself. Failures
//! list every offending file and line.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// The numbered sections the model document must have.
const SECTIONS: std::ops::RangeInclusive<u32> = 1..=15;

/// The model document, relative to the repository root.
const MODEL_DOC: &str = "docs/model.md";

/// Extensions of files that are never text.
const BINARY_EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "gif", "bmp", "ico", "webp", "svg", "ttf", "otf", "woff", "woff2",
    "mcap", "pdf", "zip", "gz", "xz", "zst", "tar", "bin", "so", "rlib", "a",
];

struct TextFile {
    /// Path relative to the repository root, with `/` separators.
    rel: String,
    text: String,
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| extensions.iter().any(|x| x.eq_ignore_ascii_case(e)))
}

/// Every regular file under `dir` (recursively, in sorted order) that `keep` accepts;
/// `target/` and `.git/` directories and symbolic links are not followed.
fn walk(dir: &Path, keep: &dyn Fn(&Path) -> bool, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(Result::ok).map(|e| e.path()).collect();
    paths.sort();
    for path in paths {
        let Ok(meta) = fs::symlink_metadata(&path) else {
            continue;
        };
        if meta.is_dir() {
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name != "target" && name != ".git" {
                walk(&path, keep, out);
            }
        } else if meta.is_file() && keep(&path) {
            out.push(path);
        }
    }
}

/// The text files the checks cover.
fn text_files() -> Vec<TextFile> {
    let root = root();
    let mut paths = Vec::new();
    for single in ["README.md", "Cargo.toml", ".ci/run"] {
        let path = root.join(single);
        if path.is_file() {
            paths.push(path);
        }
    }
    walk(
        &root.join("docs"),
        &|p| has_extension(p, &["md", "json"]),
        &mut paths,
    );
    for dir in [
        "src",
        "engine",
        "systems",
        "tests",
        "benches",
        "examples",
        "scenarios",
    ] {
        walk(
            &root.join(dir),
            &|p| !has_extension(p, BINARY_EXTENSIONS),
            &mut paths,
        );
    }
    paths
        .into_iter()
        .filter_map(|path| {
            let bytes =
                fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
            if bytes.contains(&0) {
                return None; // binary content under a text-like name
            }
            let rel = path
                .strip_prefix(root)
                .unwrap_or(&path)
                .to_string_lossy()
                .replace('\\', "/");
            Some(TextFile {
                rel,
                text: String::from_utf8_lossy(&bytes).into_owned(),
            })
        })
        .collect()
}

/// 1-based line number of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset].matches('\n').count() + 1
}

/// The line holding byte `offset`, trimmed and shortened for a message.
fn line_excerpt(text: &str, offset: usize) -> String {
    let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let line = text[start..end].trim();
    const MAX: usize = 160;
    if line.chars().count() > MAX {
        let cut: String = line.chars().take(MAX).collect();
        format!("{cut}…")
    } else {
        line.to_string()
    }
}

/// "file:line: what — the line" for each occurrence of `needle` in the covered files.
fn occurrences(files: &[TextFile], needle: &str, what: &str) -> Vec<String> {
    let mut found = Vec::new();
    for file in files {
        for (offset, _) in file.text.match_indices(needle) {
            found.push(format!(
                "{}:{}: {what} — {}",
                file.rel,
                line_of(&file.text, offset),
                line_excerpt(&file.text, offset)
            ));
        }
    }
    found
}

/// Section numbers of the `## N.` headings of the model document, in file order, with
/// their line numbers; `None` if the document does not exist.
fn model_headings() -> Option<Vec<(u32, usize)>> {
    let text = fs::read_to_string(root().join(MODEL_DOC)).ok()?;
    let mut headings = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let Some(rest) = line.strip_prefix("## ") else {
            continue;
        };
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        if digits.is_empty() || !rest[digits.len()..].starts_with('.') {
            continue;
        }
        if let Ok(number) = digits.parse() {
            headings.push((number, index + 1));
        }
    }
    Some(headings)
}

/// Skips spaces, tabs, no-break spaces, line breaks and the comment leaders a wrapped
/// comment line starts with (`//!`, `///`, `//`, `*`, `#`); returns the rest.
fn skip_gap(mut rest: &str) -> &str {
    loop {
        let trimmed = rest.trim_start_matches([' ', '\t', '\r', '\n', '\u{a0}', '\u{202f}']);
        let had_newline =
            trimmed.len() < rest.len() && rest[..rest.len() - trimmed.len()].contains('\n');
        rest = trimmed;
        if !had_newline {
            return rest;
        }
        let before = rest.len();
        for leader in ["//!", "///", "//", "*", "#"] {
            if let Some(r) = rest.strip_prefix(leader) {
                rest = r;
                break;
            }
        }
        if rest.len() == before {
            return rest;
        }
    }
}

/// Leading ASCII digits of `s` as a number, and the rest.
fn leading_number(s: &str) -> Option<(u32, &str)> {
    let digits = s.bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 {
        return None;
    }
    Some((s[..digits].parse().ok()?, &s[digits..]))
}

/// The section numbers a citation starting right after the section sign names:
/// `4`, `4.2` (section 4), `§4–6`, `4-6` (both ends), and lists continued by
/// `, §5`, `; §5`, ` and §5` or ` & §5`. `Err` if no number follows the sign.
fn cited_sections(after_sign: &str) -> Result<Vec<u32>, ()> {
    let rest = after_sign.strip_prefix('§').unwrap_or(after_sign); // "§§4–5"
    let rest = rest.trim_start_matches([' ', '\u{a0}', '\u{202f}']);
    let (first, mut rest) = leading_number(rest).ok_or(())?;
    let mut sections = vec![first];
    loop {
        // A sub-section number (".2") belongs to the section before it.
        if let Some((_, r)) = rest.strip_prefix('.').and_then(leading_number) {
            rest = r;
            continue;
        }
        // A range end: "–6", "-6", "–§6".
        let range = rest
            .strip_prefix('–')
            .or_else(|| rest.strip_prefix('-'))
            .map(|r| r.strip_prefix('§').unwrap_or(r));
        if let Some((n, r)) = range.and_then(leading_number) {
            sections.push(n);
            rest = r;
            continue;
        }
        // A list continuation that repeats the sign: ", §5", "; §5", " and §5", " & §5".
        let mut continued = None;
        for separator in [",", ";", " and", " &"] {
            if let Some(r) = rest.strip_prefix(separator) {
                let r = r.trim_start_matches([' ', '\u{a0}', '\u{202f}']);
                if let Some(r) = r.strip_prefix('§') {
                    let r = r.trim_start_matches([' ', '\u{a0}', '\u{202f}']);
                    if let Some((n, r)) = leading_number(r) {
                        continued = Some((n, r));
                    }
                }
                break;
            }
        }
        match continued {
            Some((n, r)) => {
                sections.push(n);
                rest = r;
            }
            None => return Ok(sections),
        }
    }
}

#[test]
fn the_walk_covers_the_repository() {
    let files = text_files();
    let names: BTreeSet<&str> = files.iter().map(|f| f.rel.as_str()).collect();
    for expected in [
        "README.md",
        "Cargo.toml",
        "src/lib.rs",
        "engine/lib.rs",
        "systems/lib.rs",
        "tests/interfaces/self_contained.rs",
    ] {
        assert!(
            names.contains(expected),
            "the walk of {} did not see {expected}; it saw {} files",
            root().display(),
            files.len()
        );
    }
    assert!(
        !names
            .iter()
            .any(|n| n.starts_with("target/") || n.contains("/target/")),
        "the walk entered a target/ directory"
    );
}

#[test]
fn nothing_points_outside_the_repository() {
    let files = text_files();
    let shared = concat!("..", "/shared");
    let machine = concat!("/wo", "rk/");
    let mut found = occurrences(
        &files,
        shared,
        "refers to the shared directory outside the repository",
    );
    found.extend(occurrences(
        &files,
        machine,
        "contains an absolute path of the build machine",
    ));
    assert!(
        found.is_empty(),
        "{} reference(s) to paths outside the repository (cite {MODEL_DOC} or an in-tree file instead):\n{}",
        found.len(),
        found.join("\n")
    );
}

#[test]
fn the_specification_is_named_by_its_in_tree_path() {
    let files = text_files();
    let old_name = concat!("MODEL", ".md");
    let found = occurrences(
        &files,
        old_name,
        &format!("names the out-of-tree specification; write `{MODEL_DOC}`"),
    );
    assert!(
        found.is_empty(),
        "{} mention(s) of the old specification file name:\n{}",
        found.len(),
        found.join("\n")
    );
}

#[test]
fn the_model_document_has_sections_1_to_15() {
    let headings = model_headings().unwrap_or_else(|| {
        panic!(
            "{MODEL_DOC} is missing (expected at {})",
            root().join(MODEL_DOC).display()
        )
    });
    let mut problems = Vec::new();
    for section in SECTIONS {
        let lines: Vec<usize> = headings
            .iter()
            .filter(|(n, _)| *n == section)
            .map(|(_, line)| *line)
            .collect();
        match lines.len() {
            0 => problems.push(format!("{MODEL_DOC}: no heading `## {section}.`")),
            1 => {}
            _ => problems.push(format!(
                "{MODEL_DOC}: heading `## {section}.` appears {} times, at lines {lines:?}",
                lines.len()
            )),
        }
    }
    for (number, line) in &headings {
        if !SECTIONS.contains(number) {
            problems.push(format!(
                "{MODEL_DOC}:{line}: heading `## {number}.` is outside {}–{}",
                SECTIONS.start(),
                SECTIONS.end()
            ));
        }
    }
    let order: Vec<u32> = headings.iter().map(|(n, _)| *n).collect();
    if order.windows(2).any(|w| w[0] >= w[1]) {
        problems.push(format!(
            "{MODEL_DOC}: numbered headings out of order: {order:?}"
        ));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_section_citation_exists() {
    let existing: BTreeSet<u32> = model_headings()
        .unwrap_or_default()
        .into_iter()
        .map(|(n, _)| n)
        .filter(|n| SECTIONS.contains(n))
        .collect();
    let doc_path = concat!("docs/model", ".md");
    let mut problems = Vec::new();
    let mut citations = 0usize;
    for file in text_files() {
        for (offset, _) in file.text.match_indices(doc_path) {
            let after = skip_gap(&file.text[offset + doc_path.len()..]);
            let Some(after_sign) = after.strip_prefix('§') else {
                continue; // the file is named, no section cited
            };
            citations += 1;
            let at = format!(
                "{}:{}: {}",
                file.rel,
                line_of(&file.text, offset),
                line_excerpt(&file.text, offset)
            );
            match cited_sections(after_sign) {
                Err(()) => problems.push(format!(
                    "{at}\n    no section number after the section sign"
                )),
                Ok(sections) => {
                    for n in sections {
                        if !SECTIONS.contains(&n) {
                            problems.push(format!(
                                "{at}\n    cites §{n}, outside {}–{}",
                                SECTIONS.start(),
                                SECTIONS.end()
                            ));
                        } else if !existing.contains(&n) {
                            problems.push(format!(
                                "{at}\n    cites §{n}, which has no heading in {MODEL_DOC}"
                            ));
                        }
                    }
                }
            }
        }
    }
    assert!(
        problems.is_empty(),
        "{} bad citation(s) among {citations}:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn citation_parser() {
    assert_eq!(cited_sections("4 and more"), Ok(vec![4]));
    assert_eq!(cited_sections("4.2: the exact time"), Ok(vec![4]));
    assert_eq!(cited_sections("14)."), Ok(vec![14]));
    assert_eq!(cited_sections("4, §5, §8)"), Ok(vec![4, 5, 8]));
    assert_eq!(cited_sections("7, P04 §5"), Ok(vec![7]));
    assert_eq!(cited_sections("§4–6"), Ok(vec![4, 6]));
    assert_eq!(cited_sections("4-§6"), Ok(vec![4, 6]));
    assert_eq!(cited_sections("5 and §14"), Ok(vec![5, 14]));
    assert_eq!(cited_sections("n"), Err(()));
    assert_eq!(skip_gap("  \n   //! §4"), "§4");
    assert_eq!(skip_gap(" §4"), "§4");
    assert_eq!(skip_gap("\n    /// §4"), "§4");
    assert_eq!(skip_gap(" and"), "and");
}
