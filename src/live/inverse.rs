//! [`LiveInverse`]: the inverse problem served live, one message per generation as it
//! ends, so that Foxglove plots show the search converge.
//!
//! | topic          | schema                             | encoding | what |
//! |----------------|------------------------------------|----------|------|
//! | `/generations` | `agglo.Generation` (JSON Schema)   | json     | best and mean-of-top-K ensemble cost with their standard errors, the best string's genes normalised to their ranges (0 = min, 1 = max of the inverse file), samples per string |
//! | `/events`      | `foxglove.Log`                     | protobuf | one line per generation, the closing check |
//!
//! Log time is the generation number in seconds (generation g at g + 1 s); the layout's
//! plots take the `generation` field as their x axis. The JSON Schema lists the genes of the problem by name,
//! so every gene is a plottable field (`/generations.best_genes.v0`); the layout
//! ([`layout`]) plots them all.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use foxglove::RawChannel;
use foxglove::schemas::log::Level;
use serde::Serialize;
use serde_json::{Value, json};

use super::{Server, publish};
use crate::inverse::{Event, GaState, InverseProblem};
use crate::record::EVENTS_TOPIC;
use crate::record::messages;

/// Topic of the per-generation message.
pub const GENERATIONS_TOPIC: &str = "/generations";
/// Name of its JSON Schema.
pub const GENERATION_SCHEMA: &str = "agglo.Generation";

/// One `/generations` message.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Generation {
    /// Generation number (0 first).
    pub generation: u64,
    /// Ensemble cost of the best string.
    pub best_cost: f64,
    /// Its standard error (delta method; null below two samples).
    pub best_cost_se: Option<f64>,
    /// Mean ensemble cost of the K best strings (the parents).
    pub mean_top_k: f64,
    /// Its standard error, √(Σ se²) / K over the parents that have one (null if none).
    pub mean_top_k_se: Option<f64>,
    /// Strings evaluated in this generation.
    pub evaluations: u64,
    /// Simulation samples run in this generation.
    pub samples: u64,
    /// Samples per string evaluated in this generation.
    pub samples_per_string: f64,
    /// Samples of the best string's ensemble.
    pub best_samples: u64,
    /// Mean b_f/b0 of the best string's ensemble.
    pub best_growth: f64,
    /// The best string's genes, (x − min) / (max − min) with the inverse file's ranges.
    pub best_genes: BTreeMap<String, f64>,
    /// The same genes in their units.
    pub best_genes_value: BTreeMap<String, f64>,
}

impl Generation {
    /// The message of the state after a generation (`None` before the first).
    pub fn of(problem: &InverseProblem, state: &GaState) -> Option<Self> {
        let row = state.history.last()?;
        let best = state.parents.first()?;
        let (lower, upper) = problem.bounds();
        let keys = gene_keys(problem);
        let ses: Vec<f64> = state
            .parents
            .iter()
            .filter_map(|m| m.eval.cost_se)
            .collect();
        let k = state.parents.len() as f64;
        Some(Self {
            generation: row.generation as u64,
            best_cost: row.best_cost,
            best_cost_se: row.best_cost_se,
            mean_top_k: row.mean_top_k,
            mean_top_k_se: (ses.len() == state.parents.len())
                .then(|| ses.iter().map(|s| s * s).sum::<f64>().sqrt() / k),
            evaluations: row.evaluations as u64,
            samples: row.samples,
            samples_per_string: row.samples as f64 / row.evaluations.max(1) as f64,
            best_samples: best.eval.samples as u64,
            best_growth: best.eval.means.mean,
            best_genes: keys
                .iter()
                .zip(&best.genes)
                .zip(lower.iter().zip(&upper))
                .map(|((key, x), (lo, hi))| (key.clone(), (x - lo) / (hi - lo)))
                .collect(),
            best_genes_value: keys
                .iter()
                .cloned()
                .zip(best.genes.iter().copied())
                .collect(),
        })
    }
}

/// Field names of the genes: the gene names with every character that a Foxglove
/// message path would read as syntax (`.`, `[`, …) replaced by `_`.
pub fn gene_keys(problem: &InverseProblem) -> Vec<String> {
    problem
        .gene_names()
        .iter()
        .map(|n| {
            n.chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '_' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect()
        })
        .collect()
}

/// The JSON Schema of `/generations` for this problem's genes.
pub fn schema(problem: &InverseProblem) -> Value {
    let genes: serde_json::Map<String, Value> = gene_keys(problem)
        .into_iter()
        .map(|k| (k, json!({ "type": "number" })))
        .collect();
    let number = json!({ "type": "number" });
    // A standard error is null below two samples; Foxglove's schema reader takes one type
    // per field (a list such as ["number", "null"] makes it drop the channel).
    let nullable = number.clone();
    let integer = json!({ "type": "integer" });
    json!({
        "title": GENERATION_SCHEMA,
        "type": "object",
        "properties": {
            "generation": integer,
            "best_cost": number,
            "best_cost_se": nullable,
            "mean_top_k": number,
            "mean_top_k_se": nullable,
            "evaluations": integer,
            "samples": integer,
            "samples_per_string": number,
            "best_samples": integer,
            "best_growth": number,
            "best_genes": { "type": "object", "properties": genes.clone() },
            "best_genes_value": { "type": "object", "properties": genes }
        }
    })
}

/// The Foxglove layout of a live inverse problem: costs, genes, samples per string, the
/// log and the raw message.
pub fn layout(problem: &InverseProblem) -> Value {
    let path = |value: String, label: &str| json!({ "value": value, "enabled": true, "timestampMethod": "receiveTime", "label": label });
    let plot = |title: &str, paths: Vec<Value>| {
        json!({
            "title": title,
            "paths": paths,
            "showXAxisLabels": true,
            "showYAxisLabels": true,
            "showLegend": true,
            "legendDisplay": "floating",
            "showPlotValuesInLegend": true,
            "isSynced": false,
            // x = the generation number (a live connection stamps messages with the
            // time they arrive).
            "xAxisVal": "custom",
            "xAxisPath": { "value": format!("{GENERATIONS_TOPIC}.generation"), "enabled": true },
            "sidebarDimension": 240
        })
    };
    let t = GENERATIONS_TOPIC;
    let genes = gene_keys(problem)
        .into_iter()
        .map(|k| path(format!("{t}.best_genes.{k}"), &k))
        .collect();
    json!({
        "configById": {
            "Plot!cost": plot("ensemble cost (x: generation)", vec![
                path(format!("{t}.best_cost"), "best"),
                path(format!("{t}.mean_top_k"), "mean of the K best"),
            ]),
            "Plot!cost_se": plot("standard errors of the costs", vec![
                path(format!("{t}.best_cost_se"), "best"),
                path(format!("{t}.mean_top_k_se"), "mean of the K best"),
            ]),
            "Plot!genes": plot("best string's genes (0 = min, 1 = max)", genes),
            "Plot!samples": plot("samples per string", vec![
                path(format!("{t}.samples_per_string"), "this generation"),
                path(format!("{t}.best_samples"), "best string"),
            ]),
            "RosOut!events": { "searchTerms": [], "minLogLevel": 1, "topicToRender": EVENTS_TOPIC },
            "RawMessages!generation": { "topicPath": t, "diffEnabled": false, "expansion": "all" }
        },
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": { "speed": 1 },
        "layout": {
            "direction": "row",
            "first": {
                "direction": "column",
                "first": { "direction": "column", "first": "Plot!cost", "second": "Plot!cost_se", "splitPercentage": 60 },
                "second": "Plot!genes",
                "splitPercentage": 62
            },
            "second": {
                "direction": "column",
                "first": { "direction": "column", "first": "Plot!samples", "second": "RosOut!events" },
                "second": "RawMessages!generation",
                "splitPercentage": 55
            },
            "splitPercentage": 55
        }
    })
}

/// The channels of a live inverse problem, for [`Server::bind`].
pub fn topics(problem: &InverseProblem) -> anyhow::Result<Vec<super::Topic>> {
    let schema = serde_json::to_vec(&schema(problem))?;
    Ok(vec![
        (
            GENERATIONS_TOPIC,
            "json",
            foxglove::Schema::new(GENERATION_SCHEMA, "jsonschema", schema),
        ),
        (EVENTS_TOPIC, "protobuf", messages::log_schema()?),
    ])
}

/// Log time [ns] of generation g: g + 1 seconds.
fn log_time(generation: usize) -> u64 {
    (generation as u64 + 1).saturating_mul(1_000_000_000)
}

/// An inverse problem served live. Feed it the driver's events ([`LiveInverse::on_event`]).
pub struct LiveInverse {
    server: Mutex<Option<Server>>,
    generations: Arc<RawChannel>,
    events: Arc<RawChannel>,
    problem: InverseProblem,
    /// Log time of the last generation published [ns].
    last: AtomicU64,
}

impl LiveInverse {
    /// Create the channels on `server`; with `wait`, block until a client subscribes (or
    /// `stop` is set).
    pub fn start(
        server: Server,
        problem: &InverseProblem,
        wait: bool,
        stop: &std::sync::atomic::AtomicBool,
    ) -> anyhow::Result<Self> {
        let generations = server.channel(GENERATIONS_TOPIC)?;
        let events = server.channel(EVENTS_TOPIC)?;
        if wait {
            eprintln!(
                "live: waiting for a client to subscribe on {} (Ctrl-C to stop)",
                server.url()
            );
            server.wait_for_subscriber(&[&generations, &events], stop);
        }
        Ok(Self {
            server: Mutex::new(Some(server)),
            generations,
            events,
            problem: problem.clone(),
            last: AtomicU64::new(0),
        })
    }

    /// Publish what the event says: a generation's message, the closing check's start.
    pub fn on_event(&self, e: &Event) {
        match e {
            Event::GenerationState(state) => {
                let Some(g) = Generation::of(&self.problem, state) else {
                    return;
                };
                let ns = log_time(g.generation as usize);
                self.last.store(ns, Ordering::Relaxed);
                if let Ok(bytes) = serde_json::to_vec(&g) {
                    publish(&self.generations, ns, &bytes);
                }
                self.log(
                    ns,
                    Level::Info,
                    format!(
                        "generation {}: best {:.6e} (± {:.1e}), mean of the K best {:.6e}, {} strings, {:.1} samples/string",
                        g.generation,
                        g.best_cost,
                        g.best_cost_se.unwrap_or(f64::NAN),
                        g.mean_top_k,
                        g.evaluations,
                        g.samples_per_string
                    ),
                );
            }
            Event::CheckStarted { strings, samples } => {
                // Half a generation after the last one.
                self.log(
                    self.last.load(Ordering::Relaxed) + 500_000_000,
                    Level::Info,
                    format!(
                        "closing check: the best {strings} strings, {samples} fresh samples each"
                    ),
                );
            }
            _ => {}
        }
    }

    fn log(&self, ns: u64, level: Level, message: String) {
        use foxglove::Encode;
        let msg = messages::log_message(messages::timestamp(ns), level, message);
        let mut buf = Vec::new();
        if msg.encode(&mut buf).is_ok() {
            publish(&self.events, ns, &buf);
        }
    }

    /// Let clients receive the last messages, then close the server.
    pub fn finish(&self) {
        let server = self.server.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(server) = server {
            server.close();
        }
    }
}
