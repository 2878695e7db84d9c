//! The documentation a newcomer reads stays true: every relative link in README.md and
//! docs/*.md resolves (the file, and the `#anchor` among the target's headings), every
//! `agglo …` command line in their ```sh / ```bash blocks parses with the real parser
//! (`agglo::cli_args::Cli`), and the minimal scenario the scenario guide tells people
//! to copy runs.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use agglo::prelude::*;
use clap::Parser;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// README.md and every docs/*.md (the guides and reference pages; not the generated
/// pages under docs/study/ and docs/results/).
fn pages() -> Vec<PathBuf> {
    let mut pages = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    assert!(docs.len() >= 10, "the guides are in docs/: {docs:?}");
    pages.extend(docs);
    pages
}

/// A page's lines outside fenced code blocks, and its fenced blocks as (info, lines).
fn split(text: &str) -> (Vec<&str>, Vec<(String, Vec<&str>)>) {
    let mut prose = Vec::new();
    let mut blocks = Vec::new();
    let mut open: Option<(String, Vec<&str>)> = None;
    for line in text.lines() {
        let fence = line.trim_start().starts_with("```");
        match (&mut open, fence) {
            (None, true) => {
                let info = line.trim_start().trim_start_matches('`').trim().to_string();
                open = Some((info, Vec::new()));
            }
            (Some(_), true) => blocks.push(open.take().unwrap()),
            (Some((_, lines)), false) => lines.push(line),
            (None, false) => prose.push(line),
        }
    }
    assert!(open.is_none(), "an unclosed code block");
    (prose, blocks)
}

/// GitHub's anchor of a heading: lower case, letters, digits, `-` and `_` kept, spaces
/// to `-`, everything else dropped; a repeated anchor gets `-1`, `-2`, ….
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    for line in split(text).0 {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&hashes) || !line[hashes..].starts_with(' ') {
            continue;
        }
        let slug: String = line[hashes..]
            .trim()
            .to_lowercase()
            .chars()
            .filter_map(|c| match c {
                ' ' => Some('-'),
                c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
                _ => None,
            })
            .collect();
        let mut unique = slug.clone();
        let mut n = 0;
        while seen.contains(&unique) {
            n += 1;
            unique = format!("{slug}-{n}");
        }
        seen.insert(unique);
    }
    seen
}

/// The targets of the Markdown links and images in `lines`, outside inline code.
fn link_targets(lines: &[&str]) -> Vec<String> {
    let mut targets = Vec::new();
    for line in lines {
        // Drop inline code spans: `[x](y)` inside backticks is not a link.
        let mut text = String::new();
        for (i, part) in line.split('`').enumerate() {
            if i % 2 == 0 {
                text.push_str(part);
            }
        }
        let mut rest = text.as_str();
        while let Some(start) = rest.find("](") {
            let after = &rest[start + 2..];
            let Some(end) = after.find(')') else { break };
            targets.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    targets
}

#[test]
fn every_relative_link_resolves() {
    let mut checked = 0;
    let mut broken = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let (prose, _) = split(&text);
        for target in link_targets(&prose) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(path)
            };
            let name = page.strip_prefix(root()).unwrap().display().to_string();
            checked += 1;
            if !file.exists() {
                broken.push(format!("{name}: {target} (no such file)"));
                continue;
            }
            if let Some(anchor) = anchor
                && file.extension().is_some_and(|e| e == "md")
            {
                let known = anchors(&std::fs::read_to_string(&file).unwrap());
                if !known.contains(anchor) {
                    broken.push(format!("{name}: {target} (no heading with that anchor)"));
                }
            }
        }
    }
    assert!(
        checked >= 40,
        "only {checked} links found: is the scan right?"
    );
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn anchors_are_githubs() {
    let text = "# agglo\n## 1. Hooks: impacts, merges, fragments\n## 2. Changing an impact's outcome\n```sh\n# not a heading\n```\n## Stopped runs: checkpoints and `--resume`\n## agglo\n";
    let got = anchors(text);
    for a in [
        "agglo",
        "1-hooks-impacts-merges-fragments",
        "2-changing-an-impacts-outcome",
        "stopped-runs-checkpoints-and---resume",
        "agglo-1",
    ] {
        assert!(got.contains(a), "{a} not in {got:?}");
    }
    assert!(!got.contains("not-a-heading"));
}

/// Words of a shell command line as the shell splits them: single and double quotes,
/// backslash escapes; an unquoted `$VAR` (which may expand to nothing) is left out.
/// Stops at a pipe, a redirection, `;`, `&&` or a comment.
fn shell_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut quoted_var = false;
    let mut chars = line.chars().peekable();
    let mut push = |word: &mut String, in_word: &mut bool, quoted_var: bool| {
        if *in_word && (quoted_var || !word.starts_with('$')) {
            words.push(std::mem::take(word));
        }
        word.clear();
        *in_word = false;
    };
    while let Some(c) = chars.next() {
        match c {
            ' ' | '\t' => {
                push(&mut word, &mut in_word, quoted_var);
                quoted_var = false;
            }
            '\'' => {
                in_word = true;
                for q in chars.by_ref() {
                    if q == '\'' {
                        break;
                    }
                    word.push(q);
                }
            }
            '"' => {
                in_word = true;
                quoted_var = true;
                while let Some(q) = chars.next() {
                    match q {
                        '"' => break,
                        '\\' => word.extend(chars.next()),
                        q => word.push(q),
                    }
                }
            }
            '\\' => {
                in_word = true;
                word.extend(chars.next());
            }
            '|' | '>' | '<' | ';' | '&' => break,
            '#' if !in_word => break,
            c => {
                in_word = true;
                word.push(c);
            }
        }
    }
    push(&mut word, &mut in_word, quoted_var);
    words
}

/// The `agglo` arguments of a shell line that runs agglo (directly, as
/// `target/release/agglo`, through `cargo run --release --`, `mpirun -n K` or `srun`),
/// starting with the program name; None for any other line.
fn agglo_arguments(line: &str) -> Option<Vec<String>> {
    let line = line.trim().trim_start_matches("$ ");
    let words = shell_words(line);
    let start = words.iter().position(|w| {
        w == "agglo" || w.ends_with("/agglo") || w == "--" && line.starts_with("cargo run")
    })?;
    // A program other than these in front (e.g. `man ./agglo.1`, `cargo install`) is not agglo.
    let launcher = &words[..start];
    let launched = launcher.is_empty()
        || launcher[0] == "mpirun"
        || launcher[0] == "srun"
        || launcher.starts_with(&["cargo".into(), "run".into()]);
    if !launched {
        return None;
    }
    let mut args = vec!["agglo".to_string()];
    args.extend(words[start + 1..].iter().cloned());
    Some(args)
}

#[test]
fn shell_lines_split_as_the_shell_splits_them() {
    assert_eq!(
        shell_words(
            r#"agglo run s.json --set 'output.restart={"every": 1e-3}' --out "$OUT" $RESUME -q # note"#
        ),
        [
            "agglo",
            "run",
            "s.json",
            "--set",
            r#"output.restart={"every": 1e-3}"#,
            "--out",
            "$OUT",
            "-q"
        ]
    );
    assert_eq!(
        agglo_arguments("cargo run --release -- run a.json | head").unwrap(),
        ["agglo", "run", "a.json"]
    );
    assert_eq!(
        agglo_arguments("mpirun -n 64 target/release/agglo scan p.json").unwrap(),
        ["agglo", "scan", "p.json"]
    );
    assert!(agglo_arguments("cargo run --release --example peer_chart").is_none());
    assert!(agglo_arguments("man ./agglo.1").is_none());
}

/// Every shell code block of README.md and docs/*.md: (the page's path, its lines).
fn shell_blocks() -> Vec<(String, Vec<String>)> {
    let mut blocks = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let name = page.strip_prefix(root()).unwrap().display().to_string();
        for (info, lines) in split(&text).1 {
            if matches!(info.as_str(), "sh" | "bash" | "shell" | "console") {
                blocks.push((name.clone(), lines.into_iter().map(String::from).collect()));
            }
        }
    }
    blocks
}

#[test]
fn every_agglo_command_in_the_docs_parses() {
    let mut parsed = 0;
    let mut refused = Vec::new();
    for (name, lines) in shell_blocks() {
        // Continuation lines (a trailing backslash) joined first.
        let mut joined = Vec::new();
        let mut current = String::new();
        for line in &lines {
            match line.trim_end().strip_suffix('\\') {
                Some(head) => current.push_str(head),
                None => {
                    current.push_str(line);
                    joined.push(std::mem::take(&mut current));
                }
            }
        }
        for line in joined {
            let Some(args) = agglo_arguments(&line) else {
                continue;
            };
            parsed += 1;
            if let Err(e) = agglo::cli_args::Cli::try_parse_from(&args) {
                use clap::error::ErrorKind::{DisplayHelp, DisplayVersion};
                if !matches!(e.kind(), DisplayHelp | DisplayVersion) {
                    refused.push(format!("{name}: `{}`\n{e}", line.trim()));
                }
            }
        }
    }
    assert!(parsed >= 30, "only {parsed} agglo command lines found");
    assert!(refused.is_empty(), "{}", refused.join("\n"));
}

/// scenarios/minimal.json, the scenario guide's copyable start, runs, and is minimal:
/// each of its top-level fields is needed.
#[test]
fn the_minimal_scenario_runs_and_needs_each_of_its_sections() {
    let path = root().join("scenarios/minimal.json");
    let scenario = Scenario::load(&path).unwrap();
    let mut sim = Simulation::new(&scenario).unwrap();
    sim.run().unwrap();
    let summary = sim.summary();
    assert_eq!(summary.initial_bodies, 200);
    // Something happens in it: impacts, and bonds that merge grains.
    assert!(summary.counters.bonds > 0 && summary.counters.bounces > 0);
    assert!(summary.final_bodies < summary.initial_bodies);

    let text = std::fs::read_to_string(&path).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    for section in ["name", "seed", "box", "cloud", "material", "time"] {
        let mut without = value.clone();
        without.as_object_mut().unwrap().remove(section);
        assert!(
            Scenario::from_value(without).is_err(),
            "minimal.json needs no `{section}`"
        );
    }
    // The scenario guide shows it whole.
    let guide = std::fs::read_to_string(root().join("docs/scenarios.md")).unwrap();
    assert!(
        guide.contains(text.trim()),
        "docs/scenarios.md shows minimal.json as it is"
    );
}

/// docs/extending.md opens with the first force as examples/first_force.rs has it (the
/// program tests/interfaces/extension_binary.rs runs), and no page or crate marks a code
/// example `ignore`: each one compiles, runs, or is plain text.
#[test]
fn the_first_force_on_the_page_is_the_example_that_runs() {
    let page = std::fs::read_to_string(root().join("docs/extending.md")).unwrap();
    let (_, blocks) = split(&page);
    let (info, lines) = &blocks[0];
    assert_eq!(info, "rust", "the page opens with the first force's code");
    let code = std::fs::read_to_string(root().join("examples/first_force.rs")).unwrap();
    let shown = lines.join("\n");
    assert!(
        shown.contains("add_force_systems") && code.contains(&shown),
        "docs/extending.md's first code block is not a part of examples/first_force.rs:\n{shown}"
    );
    let mut marked = Vec::new();
    for dir in ["docs", "src", "engine", "systems", "examples", "python/src"] {
        for path in files_under(&root().join(dir)) {
            let Ok(text) = std::fs::read_to_string(&path) else {
                continue;
            };
            if text.contains(&format!("{}ignore", "```")) {
                marked.push(path.display().to_string());
            }
        }
    }
    assert!(marked.is_empty(), "`ignore`d code examples in {marked:?}");
}

/// Every file under `dir`, recursively (.rs and .md).
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return files;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files.extend(files_under(&path));
        } else if path.extension().is_some_and(|e| e == "rs" || e == "md") {
            files.push(path);
        }
    }
    files
}

/// A shell line in the docs that writes into a directory under `~` comes after a
/// `mkdir -p` of that directory in the same block: on a fresh home the directory is not
/// there (`agglo completions bash > ~/.local/share/bash-completion/completions/agglo`
/// failed so).
#[test]
fn files_written_under_home_have_their_directory_made_first() {
    let mut checked = 0;
    let mut missing = Vec::new();
    for (name, lines) in shell_blocks() {
        let mut made: Vec<String> = Vec::new();
        for line in lines {
            let line = line.split(" #").next().unwrap_or("").trim();
            if let Some(dirs) = line.strip_prefix("mkdir -p ") {
                made.extend(dirs.split_whitespace().map(String::from));
            }
            let Some(target) = line.split("> ").nth(1).map(str::trim) else {
                continue;
            };
            let Some(dir) = target.rsplit_once('/').map(|(d, _)| d) else {
                continue;
            };
            if !dir.starts_with('~') {
                continue;
            }
            checked += 1;
            if !made.iter().any(|m| m == dir) {
                missing.push(format!("{name}: `{line}`: no `mkdir -p {dir}` before it"));
            }
        }
    }
    assert!(checked >= 3, "only {checked} writes under ~ found");
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

/// The README's install block holds the two commands CI runs first, as written
/// (`.ci/readme_commands` reads them): the main job on a shipped scenario, then the
/// tests. The second must be the test command `.ci/run` relies on.
#[test]
fn the_readme_install_block_holds_the_two_commands_ci_runs() {
    let out = std::process::Command::new("bash")
        .arg(root().join(".ci/readme_commands"))
        .arg(root().join("README.md"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let commands: Vec<&str> = text.lines().collect();
    assert_eq!(commands.len(), 2, "{commands:?}");
    let main_job = agglo_arguments(commands[0]).expect("the first command runs agglo");
    assert_eq!(main_job[1], "run");
    assert!(
        root().join(&main_job[2]).is_file(),
        "a shipped scenario: {}",
        main_job[2]
    );
    agglo::cli_args::Cli::try_parse_from(&main_job).unwrap();
    assert_eq!(commands[1], "cargo test && python/test.sh");
}
