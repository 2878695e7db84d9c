//! Reading recordings back: `agglo inspect` ([`inspect`]) and the scenario embedded
//! for `agglo run --from` ([`scenario_from_recording`]).
//!
//! The reader scans the file record by record, so it also reads a file whose writer
//! was killed (no summary section, possibly a torn last chunk): it reports what the
//! complete chunks hold and says where the file ends.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use mcap::read::{LinearReader, Options};
use mcap::records::Record;
use serde::Serialize;

use super::{
    BOX_HALF_WIDTH_KEY, PIPELINE_KEY, RESULT_METADATA, RUN_METADATA, SCENARIO_ATTACHMENT,
    STATS_TOPIC,
};
use crate::scenario::Scenario;
use crate::schedule::Pipeline;

/// One channel of a recording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelInfo {
    /// The channel's topic, e.g. `/bodies`.
    pub topic: String,
    /// Its schema's name.
    pub schema: String,
    /// Its messages' encoding (`protobuf`, `json`).
    pub message_encoding: String,
    /// Messages on it.
    pub messages: u64,
}

/// What `agglo inspect` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Inspection {
    /// The file inspected.
    pub file: String,
    /// Its size [B].
    pub bytes: u64,
    /// True when the summary section and footer are present (the writer finished).
    pub finalised: bool,
    /// Why the scan stopped early, for a damaged or truncated file.
    pub damage: Option<String>,
    /// Chunks read.
    pub chunks: u64,
    /// Every channel, in the file's order.
    pub channels: Vec<ChannelInfo>,
    /// Messages in all.
    pub messages: u64,
    /// Log-time span of the messages [s] (simulated time × playback scale).
    pub log_seconds: f64,
    /// Simulated time of the first `/stats` message [s].
    pub first_time: Option<f64>,
    /// Simulated time of the last `/stats` message [s].
    pub last_time: Option<f64>,
    /// The embedded scenario (JSON), if the file has it.
    pub scenario: Option<String>,
    /// The run's seed, from the metadata.
    pub seed: Option<u64>,
    /// The agglo version that wrote it.
    pub engine_version: Option<String>,
    /// The command line that made it.
    pub command_line: Option<String>,
    /// The outcome metadata (status, message, steps, time), absent if the writer was killed.
    pub result: Option<BTreeMap<String, String>>,
    /// The last `/stats` message.
    pub final_stats: Option<serde_json::Value>,
    /// Whether the scenario attachment is present.
    pub has_scenario: bool,
    /// Box half-width D [m]: from the metadata, else from the scenario attachment
    /// (recordings made before D went into the metadata).
    pub box_half_width: Option<f64>,
    /// The pipeline the run ran (absent in recordings made before it was recorded).
    pub pipeline: Option<Pipeline>,
}

/// Scan the recording at `path`.
pub fn inspect(path: &Path) -> anyhow::Result<Inspection> {
    let buf = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if !buf.starts_with(mcap::MAGIC) {
        anyhow::bail!("{} is not an MCAP file (no MCAP magic)", path.display());
    }
    let mut scan = Scan::default();
    scan.run(&buf);
    let finalised = matches!(mcap::Summary::read(&buf), Ok(Some(_)));

    let mut meta = scan.metadata.remove(RUN_METADATA).unwrap_or_default();
    let scenario_value: Option<serde_json::Value> = scan
        .scenario_json
        .as_deref()
        .and_then(|s| serde_json::from_slice(s).ok());
    let box_half_width = meta
        .remove(BOX_HALF_WIDTH_KEY)
        .and_then(|d| d.parse::<f64>().ok())
        .or_else(|| {
            scenario_value
                .as_ref()
                .and_then(|v| v.get("box")?.get("half_width")?.as_f64())
        });
    let pipeline = meta
        .remove(PIPELINE_KEY)
        .and_then(|p| serde_json::from_str::<Pipeline>(&p).ok());
    let channels: Vec<ChannelInfo> = scan.channels.into_values().collect();
    let stats_time = |v: &Option<serde_json::Value>| {
        v.as_ref()
            .and_then(|v| v.get("time"))
            .and_then(|t| t.as_f64())
    };
    Ok(Inspection {
        file: path.display().to_string(),
        bytes: buf.len() as u64,
        finalised,
        damage: scan.damage,
        chunks: scan.chunks,
        messages: channels.iter().map(|c| c.messages).sum(),
        channels,
        log_seconds: match scan.log_span {
            Some((a, b)) => (b - a) as f64 * 1e-9,
            None => 0.0,
        },
        first_time: stats_time(&scan.first_stats),
        last_time: stats_time(&scan.last_stats),
        scenario: meta.remove("scenario").or_else(|| {
            scenario_value
                .as_ref()
                .and_then(|v| v.get("name")?.as_str().map(String::from))
        }),
        seed: meta
            .remove("seed")
            .and_then(|s| s.parse().ok())
            .or_else(|| {
                scenario_value
                    .as_ref()
                    .and_then(|v| v.get("seed")?.as_u64())
            }),
        engine_version: meta.remove("engine_version"),
        command_line: meta.remove("command_line"),
        result: scan.metadata.remove(RESULT_METADATA),
        final_stats: scan.last_stats,
        has_scenario: scan.scenario_json.is_some(),
        box_half_width,
        pipeline,
    })
}

/// The scenario embedded in the recording at `path` (as run: seed applied).
pub fn scenario_from_recording(path: &Path) -> anyhow::Result<Scenario> {
    let buf = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if !buf.starts_with(mcap::MAGIC) {
        anyhow::bail!("{} is not an MCAP file (no MCAP magic)", path.display());
    }
    let reader = LinearReader::new_with_options(&buf, Options::IgnoreEndMagic.into())
        .with_context(|| format!("{} is not an MCAP file", path.display()))?;
    for record in reader {
        let record = record.with_context(|| format!("reading {}", path.display()))?;
        match record {
            Record::Attachment { header, data, .. } if header.name == SCENARIO_ATTACHMENT => {
                let text = std::str::from_utf8(&data).with_context(|| {
                    format!("attachment {SCENARIO_ATTACHMENT} is not UTF-8 text")
                })?;
                return Scenario::from_json(text).with_context(|| {
                    format!(
                        "parsing the scenario embedded in {} (attachment {SCENARIO_ATTACHMENT})",
                        path.display()
                    )
                });
            }
            // The writer puts the attachment before any chunk: stop at the first.
            Record::Chunk { .. } | Record::DataEnd(_) => break,
            _ => {}
        }
    }
    anyhow::bail!(
        "{} holds no `{SCENARIO_ATTACHMENT}` attachment: not an agglo recording",
        path.display()
    )
}

/// Where the readable part ends, in words: a writer killed mid-record leaves a record
/// whose length field is unwritten (zeros or all ones) or cut off, which the mcap reader
/// reports as "record with opcode 06 length exceeds limit: 18446744073709551615".
#[doc(hidden)]
pub fn ends_early(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::RecordTooLarge { opcode, .. } => format!(
            "a record (opcode {opcode:#04x}) whose length was never written: the file was cut \
             off while it was being written"
        ),
        mcap::McapError::UnexpectedEof => {
            "the last record is incomplete: the file was cut off while it was being written".into()
        }
        e => format!("a record that does not read ({e})"),
    }
}

#[derive(Default)]
struct Scan {
    /// Channel id → schema name (resolved when the channel is seen).
    schemas: BTreeMap<u16, String>,
    channels: BTreeMap<u16, ChannelInfo>,
    stats_channel: Option<u16>,
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    scenario_json: Option<Vec<u8>>,
    chunks: u64,
    log_span: Option<(u64, u64)>,
    first_stats: Option<serde_json::Value>,
    last_stats: Option<serde_json::Value>,
    damage: Option<String>,
}

impl Scan {
    fn run(&mut self, buf: &[u8]) {
        let reader = match LinearReader::new_with_options(buf, Options::IgnoreEndMagic.into()) {
            Ok(r) => r,
            Err(e) => {
                self.damage = Some(format!("not an MCAP file: {e}"));
                return;
            }
        };
        for record in reader {
            match record {
                Ok(Record::DataEnd(_)) => return,
                Ok(Record::Chunk { header, data }) => {
                    // Read the whole chunk first: a torn chunk must not count half.
                    match super::chunk::records(&header, &data) {
                        Ok(records) => {
                            self.chunks += 1;
                            for r in records {
                                self.record(r);
                            }
                        }
                        Err(e) => {
                            self.damage = Some(format!("unreadable chunk: {e}"));
                            return;
                        }
                    }
                }
                Ok(r) => self.record(r),
                Err(e) => {
                    self.damage = Some(ends_early(&e));
                    return;
                }
            }
        }
        // No DataEnd record: the writer never finished.
        self.damage = Some("no data-end record: the writer did not finish".into());
    }

    fn record(&mut self, record: Record<'_>) {
        match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                if c.topic == STATS_TOPIC {
                    self.stats_channel = Some(c.id);
                }
                let schema = self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                self.channels.entry(c.id).or_insert(ChannelInfo {
                    topic: c.topic,
                    schema,
                    message_encoding: c.message_encoding,
                    messages: 0,
                });
            }
            Record::Message { header, data } => {
                if let Some(c) = self.channels.get_mut(&header.channel_id) {
                    c.messages += 1;
                }
                let t = header.log_time;
                self.log_span = Some(match self.log_span {
                    None => (t, t),
                    Some((a, b)) => (a.min(t), b.max(t)),
                });
                if Some(header.channel_id) == self.stats_channel
                    && let Ok(v) = serde_json::from_slice::<serde_json::Value>(&data)
                {
                    if self.first_stats.is_none() {
                        self.first_stats = Some(v.clone());
                    }
                    self.last_stats = Some(v);
                }
            }
            Record::Metadata(m) => {
                self.metadata.insert(m.name, m.metadata);
            }
            Record::Attachment { header, data, .. } if header.name == SCENARIO_ATTACHMENT => {
                self.scenario_json = Some(data.into_owned());
            }
            _ => {}
        }
    }
}

impl Inspection {
    /// Human-readable report.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "{} ({} bytes)", self.file, self.bytes);
        let _ = writeln!(
            s,
            "  scenario {} (seed {}), agglo {}",
            self.scenario.as_deref().unwrap_or("?"),
            self.seed
                .map(|x| x.to_string())
                .unwrap_or_else(|| "?".into()),
            self.engine_version.as_deref().unwrap_or("?")
        );
        if let Some(cmd) = &self.command_line {
            let _ = writeln!(s, "  command line: {cmd}");
        }
        match (self.finalised, &self.damage) {
            (true, None) => {
                let _ = writeln!(
                    s,
                    "  finalised (summary present); {} chunks, {} messages",
                    self.chunks, self.messages
                );
            }
            // The summary survived but the data did not read whole: say so in the text
            // too ("finalised; 0 chunks" read as a healthy empty recording).
            (true, Some(d)) => {
                let _ = writeln!(
                    s,
                    "  DAMAGED: finalised (summary present), but only {} chunks, {} messages \
                     read before the damage — {d}",
                    self.chunks, self.messages
                );
            }
            (false, damage) => {
                let _ = writeln!(
                    s,
                    "  NOT finalised: the writer stopped before finishing (killed, or the disk \
                     filled); {} complete chunks, {} messages are readable{}",
                    self.chunks,
                    self.messages,
                    match (self.first_time, self.last_time) {
                        (Some(a), Some(b)) => format!(", simulated time {a:e} s → {b:e} s"),
                        _ => String::new(),
                    }
                );
                if let Some(d) = damage {
                    let _ = writeln!(s, "  where the readable part ends: {d}");
                }
                let restart = Path::new(&self.file).with_extension("restart");
                let _ = if restart.exists() {
                    writeln!(
                        s,
                        "  continue the run from its last checkpoint: agglo run --resume {}",
                        restart.display()
                    )
                } else {
                    writeln!(
                        s,
                        "  a run with output.restart continues from its last checkpoint with \
                         agglo run --resume RUN.restart (none beside this file)"
                    )
                };
            }
        }
        match (self.first_time, self.last_time) {
            (Some(a), Some(b)) => {
                let _ = writeln!(
                    s,
                    "  simulated time {a:e} s → {b:e} s ({:e} s), replayed in {:.3} s of log time",
                    b - a,
                    self.log_seconds
                );
            }
            _ => {
                let _ = writeln!(s, "  no /stats messages");
            }
        }
        if let Some(r) = &self.result {
            let _ = writeln!(
                s,
                "  outcome: {} — {}",
                r.get("status").map(String::as_str).unwrap_or("?"),
                r.get("message").map(String::as_str).unwrap_or("")
            );
        } else {
            let _ = writeln!(s, "  outcome: unknown (no result metadata)");
        }
        if let Some(d) = self.box_half_width {
            let _ = writeln!(s, "  box half-width D = {d:e} m");
        }
        if let Some(p) = &self.pipeline {
            let _ = writeln!(s, "  {} core: {}", p.core, p.systems.join(" → "));
            for line in &p.left_out {
                let _ = writeln!(s, "    {line}");
            }
        }
        let _ = writeln!(s, "  channels:");
        for c in &self.channels {
            let _ = writeln!(
                s,
                "    {:<11} {:>7} messages  {} ({})",
                c.topic, c.messages, c.schema, c.message_encoding
            );
        }
        if let Some(serde_json::Value::Object(m)) = &self.final_stats {
            let _ = writeln!(s, "  final statistics:");
            for (k, v) in m {
                let _ = writeln!(s, "    {k:<24} {v}");
            }
        }
        s
    }
}
