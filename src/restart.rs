//! Restart files: the `output.restart` section and the file `agglo run --resume` reads.
//!
//! A scene with `output.restart.every = h` takes a checkpoint at each multiple of h
//! (engine/restart.rs: what a snapshot holds, and why a run with checkpoints and its
//! resumed continuations are bit-identical). `agglo run` writes each snapshot to the
//! restart file, replacing the previous one atomically (a temporary file, synced, then
//! renamed, the directory synced), so a kill at any moment — SIGKILL and power loss
//! included — leaves the last complete checkpoint in place.
//!
//! The file: the magic line `agglo-restart\n`, the format version (u32, little-endian),
//! the CRC-32 of everything after it (u32), then two length-prefixed (u64) blocks: the
//! scenario as it ran (JSON, after `--set` and `--seed`), and the snapshot (postcard).
//! A file whose content does not match its checksum is refused, naming the file.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use agglo_engine::restart::{Checkpoints, RestartSnapshot};

use crate::scenario::Scenario;

/// The `output.restart` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RestartSettings {
    /// Take a checkpoint every this much simulated time [s] (at the first step end
    /// reaching each multiple, before the end time). The checkpoints are part of the
    /// run: on the event core steps land on them and the calendar is rebuilt there.
    pub every: f64,
    /// The restart file [default: beside the recording, `RUN.restart`, else
    /// `NAME.restart` in the working directory, NAME the scenario's name]; `--restart`
    /// overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
}

#[doc(hidden)]
pub const MAGIC: &[u8] = b"agglo-restart\n";
const FORMAT_VERSION: u32 = 1;

/// Where the restart file of `scenario` goes: `explicit` (`--restart`), else the
/// section's path, else beside the recording, else `NAME.restart`.
pub fn restart_path(
    scenario: &Scenario,
    explicit: Option<&Path>,
    recording: Option<&Path>,
) -> Option<PathBuf> {
    let settings = scenario.output.restart.as_ref()?;
    Some(if let Some(path) = explicit {
        path.to_path_buf()
    } else if let Some(path) = &settings.path {
        PathBuf::from(path)
    } else if let Some(mcap) = recording {
        mcap.with_extension("restart")
    } else {
        // The name may carry `--set` settings: keep it a plain, short file name.
        PathBuf::from(format!("{}.restart", scenario.file_stem()))
    })
}

/// The file's bytes: header, checksum, scenario and snapshot.
pub fn encode(scenario: &Scenario, snapshot: &RestartSnapshot) -> Vec<u8> {
    let json = scenario.to_json().into_bytes();
    let snap = snapshot.encode();
    let mut body = Vec::with_capacity(16 + json.len() + snap.len());
    for block in [&json, &snap] {
        body.extend_from_slice(&(block.len() as u64).to_le_bytes());
        body.extend_from_slice(block);
    }
    let mut bytes = Vec::with_capacity(MAGIC.len() + 8 + body.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
    bytes.extend_from_slice(&body);
    bytes
}

/// Write a snapshot to `path`, replacing what is there only once the new file is
/// complete and on disk. Returns the bytes written.
pub fn write(path: &Path, scenario: &Scenario, snapshot: &RestartSnapshot) -> anyhow::Result<u64> {
    let bytes = encode(scenario, snapshot);
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let mut file =
        std::fs::File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    file.write_all(&bytes)
        .and_then(|()| file.sync_all())
        .with_context(|| format!("writing {}", tmp.display()))?;
    drop(file);
    std::fs::rename(&tmp, path)
        .with_context(|| format!("replacing {} by {}", path.display(), tmp.display()))?;
    // The rename itself reaches the disk with its directory (a power cut after it would
    // otherwise leave the old file, which is still complete: hence no error if the
    // platform cannot sync a directory).
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(dir) = std::fs::File::open(dir) {
        let _ = dir.sync_all();
    }
    Ok(bytes.len() as u64)
}

/// The scenario and snapshot of a restart file's bytes; `path` names the file in errors.
pub fn decode(path: &Path, bytes: &[u8]) -> anyhow::Result<(Scenario, RestartSnapshot)> {
    let name = path.display();
    let Some(rest) = bytes.strip_prefix(MAGIC) else {
        bail!("{name} is not an agglo restart file (it does not start with `agglo-restart`)");
    };
    if rest.len() < 8 {
        bail!(
            "{name} ends early: {} bytes, not even its header",
            bytes.len()
        );
    }
    let version = u32::from_le_bytes(rest[0..4].try_into().expect("4 bytes"));
    if version != FORMAT_VERSION {
        bail!("{name}: restart format version {version}, this build reads {FORMAT_VERSION}");
    }
    let written = u32::from_le_bytes(rest[4..8].try_into().expect("4 bytes"));
    let body = &rest[8..];
    let computed = crc32fast::hash(body);
    if written != computed {
        bail!(
            "{name}: the content does not match its checksum (crc32 {written:08x} written, \
             {computed:08x} now): the file was changed or damaged after it was written; \
             refusing to resume from it"
        );
    }
    let mut blocks = Vec::with_capacity(2);
    let mut at = 0usize;
    for what in ["scenario", "snapshot"] {
        let len = body
            .get(at..at + 8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize)
            .with_context(|| format!("{name} ends early, before its {what}"))?;
        let block = body
            .get(at + 8..at + 8 + len)
            .with_context(|| format!("{name} ends early, inside its {what}"))?;
        blocks.push(block);
        at += 8 + len;
    }
    let text = std::str::from_utf8(blocks[0])
        .with_context(|| format!("{name}: the embedded scenario is not UTF-8"))?;
    let scenario = Scenario::from_json(text)
        .with_context(|| format!("parsing the scenario embedded in {name}"))?;
    let snapshot = RestartSnapshot::decode(blocks[1])
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("reading the snapshot in {name}"))?;
    Ok((scenario, snapshot))
}

/// The restart file `--resume PATH` means: PATH itself, or, when PATH is a recording
/// (an MCAP file), the restart file a run writes beside it by default, `RUN.restart`.
pub fn restart_file_of(path: &Path) -> PathBuf {
    let mut head = [0u8; 8];
    let is_recording = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok()
        && head == mcap::MAGIC;
    if is_recording {
        path.with_extension("restart")
    } else {
        path.to_path_buf()
    }
}

/// Read the restart file `--resume PATH` means ([`restart_file_of`]).
pub fn read(path: &Path) -> anyhow::Result<(Scenario, RestartSnapshot)> {
    let file = restart_file_of(path);
    if file != path && !file.exists() {
        bail!(
            "{} is a recording; the restart file a run with `output.restart` writes beside \
             it, {}, does not exist (give the restart file itself)",
            path.display(),
            file.display()
        );
    }
    let bytes = std::fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
    decode(&file, &bytes)
}
