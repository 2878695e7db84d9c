//! `--live` on `agglo run` and `agglo optimize`: the flags, and thin glue over
//! [`agglo::live`] and [`agglo::run`] (the run's live server is started by the library).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use anyhow::Context;

use agglo::live::inverse::LiveInverse;
use agglo::live::{LiveOptions, Server, check_options, parse_addr};

pub use agglo::cli_args::{LiveArgs, LiveInverseArgs};

/// Flags of this module and whether each takes a value (the recording's command line
/// leaves them out: they do not change the run, so a run with and without them records
/// the same bytes).
const LIVE_FLAGS: [(&str, bool); 6] = [
    ("--live", false),
    ("--live-wait", false),
    ("--live-rate", true),
    ("--live-bodies", true),
    ("--live-linger", true),
    ("--live-pace", true),
];

/// The command line as a recording keeps it: `args` without the live flags.
pub fn recorded_command_line(args: impl IntoIterator<Item = String>) -> String {
    let mut kept = Vec::new();
    let mut args = args.into_iter().peekable();
    while let Some(arg) = args.next() {
        let name = arg.split('=').next().unwrap_or("");
        let Some(&(flag, takes_value)) = LIVE_FLAGS.iter().find(|(f, _)| *f == name) else {
            kept.push(arg);
            continue;
        };
        if arg.contains('=') {
            continue;
        }
        // `--live` takes an optional value: clap gives it the next word unless that
        // word is a flag.
        let optional = flag == "--live";
        if takes_value || (optional && args.peek().is_some_and(|a| !a.starts_with('-'))) {
            args.next();
        }
    }
    kept.join(" ")
}

/// The live options of `agglo run`, if asked (checked before the scene is built).
pub fn options(args: &LiveArgs) -> anyhow::Result<Option<LiveOptions>> {
    let Some(text) = &args.live else {
        return Ok(None);
    };
    let options = LiveOptions {
        addr: parse_addr(text)?,
        wait: args.live_wait,
        rate_hz: args.live_rate,
        max_bodies: args.live_bodies,
        linger_seconds: args.live_linger,
        pace: args.live_pace,
    };
    check_options(&options)?;
    Ok(Some(options))
}

/// Bind and start the live server of `agglo optimize`, if asked; the layout goes to
/// `out/live.layout.json`.
pub fn start_inverse(
    args: &LiveInverseArgs,
    problem: &agglo::inverse::InverseProblem,
    out: &Path,
    stop: &AtomicBool,
) -> anyhow::Result<Option<LiveInverse>> {
    let Some(text) = &args.live else {
        return Ok(None);
    };
    let topics = agglo::live::inverse::topics(problem)?;
    let server = Server::bind(parse_addr(text)?, "agglo optimize", topics)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let layout: PathBuf = out.join("live.layout.json");
    let text = serde_json::to_string_pretty(&agglo::live::inverse::layout(problem))?;
    std::fs::write(&layout, text + "\n")
        .with_context(|| format!("writing Foxglove layout {}", layout.display()))?;
    agglo::run::announce_live(&server, &layout);
    Ok(Some(LiveInverse::start(
        server,
        problem,
        args.live_wait,
        stop,
    )?))
}
