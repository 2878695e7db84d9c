//! Inverse-problem files: the base scenario, the genes and their ranges, the cost,
//! the ensemble rule and the genetic-algorithm settings (docs/model.md §12), with
//! validation that names the field path of every problem, like scenario files.
//!
//! ```json
//! { "name": "…", "base": "paper2004_best.json",
//!   "genes": [ { "name": "v0", "path": "cloud.v_rel.0", "min": 20, "max": 200,
//!                "tied": [ { "path": "cloud.v_rel.1", "scale": 0.1 } ] } ],
//!   "end_time": "scenario",
//!   "cost": "pi04",
//!   "ensemble": { "tol": 0.0005, "min_samples": 2, "max_samples": 40, "track": ["cost"] },
//!   "ga": { "strings": 20, "parents": 6, "generations": 25, "rescale_every": 4,
//!           "shrink": 0.5, "tol": 0, "seed": 2004 },
//!   "on_failure": "error" }
//! ```
//! `base` is a path relative to the inverse file's directory, or an inline scenario.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::{ScenarioError, ValidationIssue};
use crate::scenario::{Scenario, Stepping};

use super::genes::{get_path, set_path};

/// Why one simulation sample failed, as text: samples can run on another MPI rank.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{0}")]
pub struct SampleFailure(pub String);

/// An inverse-problem file as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InverseSpec {
    /// The problem's name (in outputs and the live view).
    pub name: String,
    #[serde(default)]
    /// Free text: what the problem is for.
    pub description: String,
    /// Base scenario: a path relative to this file's directory, or an inline scenario object.
    pub base: BaseScenario,
    /// The parameters searched, each a numeric scenario field with a range.
    pub genes: Vec<GeneSpec>,
    /// How the end time T follows from the genes.
    #[serde(default)]
    pub end_time: EndTimeRule,
    /// The cost minimised.
    pub cost: CostSpec,
    /// How many samples each string's ensemble takes.
    pub ensemble: EnsembleSpec,
    /// The genetic algorithm's settings.
    pub ga: GaSpec,
    /// What a failed simulation sample does.
    #[serde(default)]
    pub on_failure: FailurePolicy,
    /// After the last generation, re-evaluate the best strings with large ensembles
    /// of fresh seeds and re-rank them by that (the GA's own costs carry the noise
    /// it selected for).
    #[serde(default)]
    pub reevaluate: Reevaluate,
}

/// The closing check of the best strings (`"reevaluate"`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reevaluate {
    /// How many of the best strings (at most K, the parents kept); 0 = no check.
    #[serde(default = "four")]
    pub strings: usize,
    /// Samples per string (fixed, ≥ 2 so that a standard error exists).
    #[serde(default = "hundred")]
    pub samples: u32,
}

fn four() -> usize {
    4
}
fn hundred() -> u32 {
    100
}

impl Default for Reevaluate {
    fn default() -> Self {
        Self {
            strings: four(),
            samples: hundred(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
/// Where the base scenario comes from: a file or the scenario inline.
pub enum BaseScenario {
    /// Path to a scenario file, relative to the inverse file's directory.
    Path(String),
    /// The scenario itself.
    Inline(Box<Value>),
}

/// One gene: a scenario field (dotted path) searched in [min, max], with optional
/// fields tied to it (set to `scale` × gene).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneSpec {
    /// Short label used in outputs (defaults to the path).
    #[serde(default)]
    pub name: String,
    /// Dotted scenario path, e.g. `material.H0` or `cloud.v_rel.0`.
    pub path: String,
    /// The gene's lower bound, in the field's unit.
    pub min: f64,
    /// The gene's upper bound, in the field's unit.
    pub max: f64,
    /// Other fields that follow this gene: field = scale × gene (P04: v_rel = (v0, 0.1 v0, 0.1 v0)).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tied: Vec<Tie>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
/// A field that follows a gene: field = `scale` × gene.
pub struct Tie {
    /// The field's dotted scenario path.
    pub path: String,
    #[serde(default = "one")]
    /// The factor (default 1).
    pub scale: f64,
}

fn one() -> f64 {
    1.0
}

/// How T is set for each parameter set.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum EndTimeRule {
    /// Use the base scenario's `time` as is.
    #[default]
    Scenario,
    /// P02 (13): T = (S_gap / v_crit) · ln(0.01)/ln(0.9), S_gap = (V/N)^(1/3) − 2 b0,
    /// v_crit = √(6 af H0 β / ρ) (docs/model.md §13), with `steps` fixed steps of T / steps.
    P02 {
        /// Fixed steps over T.
        steps: u64,
    },
}

/// The cost of one parameter set, computed from ensemble-mean observables.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum CostSpec {
    /// Π04 = 1 − b̄_f / b* (P04 (7.1)); lower = more agglomeration.
    Pi04,
    /// Π02 = |b̄_f / (r_t b0) − 1| (P02 (26)).
    Pi02 {
        /// The target growth r_t = b̄_f / b0.
        target_ratio: f64,
    },
    /// |m̄ − target| / |target| (|m̄| if target = 0) for one radius moment.
    Moment {
        /// Which moment.
        moment: Moment,
        /// Its target value.
        target: f64,
    },
}

/// Radius-distribution moments (docs/model.md §11); lengths in units of b0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Moment {
    /// b_f / b0.
    Mean,
    /// σ / b0.
    StdDev,
    /// m_3.
    Skewness,
    /// m_4.
    Kurtosis,
}

/// Quantities whose running ensemble mean must stabilise (P04 (8.1), P02 (25), (27)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tracked {
    /// The cost of the running means.
    Cost,
    /// b_f / b0.
    Mean,
    /// σ / b0.
    StdDev,
    /// m_3.
    Skewness,
    /// m_4.
    Kurtosis,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
/// How many simulation samples a string's ensemble takes (the problem's `ensemble`).
pub struct EnsembleSpec {
    /// `running_mean` (the papers): stop when |Q̄_{E+1} − Q̄_E| ≤ tol |Q̄_{E+1}|;
    /// `standard_error`: stop when the standard error of Q̄ ≤ tol |Q̄| — for every tracked Q.
    pub tol: f64,
    /// Which stopping rule `tol` applies to.
    #[serde(default)]
    pub rule: EnsembleRule,
    #[serde(default = "two")]
    /// Samples run before the rule may stop (default 2).
    pub min_samples: u32,
    /// Samples after which the ensemble stops regardless.
    pub max_samples: u32,
    #[serde(default = "default_track")]
    /// The quantities the rule watches (default: the cost).
    pub track: Vec<Tracked>,
}

fn two() -> u32 {
    2
}
fn default_track() -> Vec<Tracked> {
    vec![Tracked::Cost]
}

/// When an ensemble has enough samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnsembleRule {
    /// P04 (8.1) / P02 (25): the running mean moved by at most TOL relative. Two
    /// samples that happen to agree stop it, so a cost carries sampling noise.
    #[default]
    RunningMean,
    /// The standard error of the running mean is at most TOL relative (≥ 2 samples;
    /// the cost's by the delta method).
    StandardError,
}

/// Genetic-algorithm settings (docs/model.md §12).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaSpec {
    /// Population size S.
    pub strings: usize,
    /// Parents kept K (even); M = S − 2K new random strings per generation.
    pub parents: usize,
    /// Maximum number of generations G.
    pub generations: usize,
    /// Shrink the bounds around the best every this many generations (0 = never).
    #[serde(default)]
    pub rescale_every: usize,
    /// New half-width = old half-width × shrink, 0 < shrink ≤ 1.
    #[serde(default = "half")]
    pub shrink: f64,
    /// Stop when the watched cost ≤ tol.
    #[serde(default)]
    pub tol: f64,
    /// Which cost `tol` watches.
    #[serde(default)]
    pub stop_on: StopOn,
    /// Run seed: every random draw derives from it.
    pub seed: u64,
}

fn half() -> f64 {
    0.5
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
/// Which cost the GA's `tol` watches.
pub enum StopOn {
    #[default]
    /// The best string's cost (default).
    Best,
    /// The mean cost of the K parents.
    MeanTopK,
}

/// What a failed sample (placement impossible, step limit, non-finite state) does.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum FailurePolicy {
    /// Stop the whole run with an error naming the genes and the seed (default).
    #[default]
    Error,
    /// The string's cost becomes this value and its ensemble stops.
    Penalty(f64),
}

/// Everything that can go wrong in the inverse problem.
#[derive(Debug, thiserror::Error)]
pub enum InverseError {
    /// A file could not be read.
    #[error("cannot read `{path}`: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why reading failed.
        #[source]
        source: std::io::Error,
    },
    /// A field of the inverse file does not parse.
    #[error("inverse file field `{path}`: {message}")]
    Parse {
        /// The field's path.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// Parsed, but values out of their ranges: every problem, with its path.
    #[error("invalid inverse problem:\n  {}", .0.iter().map(|i| i.to_string()).collect::<Vec<_>>().join("\n  "))]
    Invalid(Vec<ValidationIssue>),
    /// The base scenario could not be loaded.
    #[error("base scenario: {0}")]
    Base(#[source] ScenarioError),
    /// A sample failed and the failure policy is `error`.
    #[error(
        "generation {generation}, string {string}, sample {sample} (seed {seed}) failed with genes {genes}: {source}\n  \
         (set \"on_failure\": {{\"penalty\": <cost>}} in the inverse file to score such strings instead)"
    )]
    Sample {
        /// The generation (0-based).
        generation: usize,
        /// The string's index in it.
        string: usize,
        /// The sample's index in its ensemble.
        sample: u32,
        /// The sample's seed (`agglo run --seed` repeats it).
        seed: u64,
        /// The string's genes, `name = value, …`.
        genes: String,
        /// Why the sample failed.
        #[source]
        source: SampleFailure,
    },
    /// The checkpoint could not be read, written or matched to the problem.
    #[error("{0}")]
    Checkpoint(String),
    /// Stopped by the user (Ctrl-C); the last generation is checkpointed.
    #[error("interrupted; the last completed generation is checkpointed: continue with --resume")]
    Interrupted,
    /// Anything else (the message says what).
    #[error("{0}")]
    Other(String),
}

/// A loaded, validated inverse problem with its base scenario resolved.
#[derive(Debug, Clone)]
pub struct InverseProblem {
    /// The file as written.
    pub spec: InverseSpec,
    /// The base scenario (defaults filled in).
    pub base: Scenario,
    base_value: Value,
}

impl InverseProblem {
    /// Read an inverse file; a relative `base` path is resolved against the file's directory.
    pub fn load(path: &Path) -> Result<Self, InverseError> {
        let text = std::fs::read_to_string(path).map_err(|source| InverseError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_json(&text, &dir)
    }

    /// Parse inverse-file text; `dir` resolves a relative `base` path.
    pub fn from_json(text: &str, dir: &Path) -> Result<Self, InverseError> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let spec: InverseSpec =
            serde_path_to_error::deserialize(de).map_err(|e| InverseError::Parse {
                path: e.path().to_string(),
                message: e.inner().to_string(),
            })?;
        Self::new(spec, dir)
    }

    /// Validate `spec` and resolve its base scenario.
    pub fn new(spec: InverseSpec, dir: &Path) -> Result<Self, InverseError> {
        let base = match &spec.base {
            BaseScenario::Path(p) => {
                let full: PathBuf = dir.join(p);
                Scenario::load(&full).map_err(InverseError::Base)?
            }
            BaseScenario::Inline(v) => {
                Scenario::from_value((**v).clone()).map_err(InverseError::Base)?
            }
        };
        let base_value = serde_json::to_value(&base)
            .map_err(|e| InverseError::Other(format!("serialising the base scenario: {e}")))?;
        let problem = Self {
            spec,
            base,
            base_value,
        };
        problem.validate()?;
        Ok(problem)
    }

    /// Number of genes.
    pub fn dimension(&self) -> usize {
        self.spec.genes.len()
    }

    /// Gene labels (name, or path when unnamed).
    pub fn gene_names(&self) -> Vec<String> {
        self.spec
            .genes
            .iter()
            .map(|g| {
                if g.name.is_empty() {
                    g.path.clone()
                } else {
                    g.name.clone()
                }
            })
            .collect()
    }

    /// Original search bounds (lower, upper).
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        (
            self.spec.genes.iter().map(|g| g.min).collect(),
            self.spec.genes.iter().map(|g| g.max).collect(),
        )
    }

    /// The base scenario as a JSON value with every default filled in.
    pub fn base_value(&self) -> &Value {
        &self.base_value
    }

    /// The scenario for gene values `genes` and scene seed `seed` (genes applied,
    /// tied fields set, end-time rule applied, validated).
    pub fn scenario_for(&self, genes: &[f64], seed: u64) -> Result<Scenario, ScenarioError> {
        let mut value = self.base_value.clone();
        for (g, &x) in self.spec.genes.iter().zip(genes) {
            set_gene(&mut value, &g.path, x)?;
            for tie in &g.tied {
                set_gene(&mut value, &tie.path, tie.scale * x)?;
            }
        }
        self.finish(value, seed)
    }

    /// The base scenario with one field overridden (for one-gene scans).
    pub fn scenario_with(&self, path: &str, x: f64, seed: u64) -> Result<Scenario, ScenarioError> {
        let mut value = self.base_value.clone();
        set_gene(&mut value, path, x)?;
        self.finish(value, seed)
    }

    fn finish(&self, mut value: Value, seed: u64) -> Result<Scenario, ScenarioError> {
        if let Value::Object(map) = &mut value {
            map.insert("seed".into(), Value::from(seed));
        }
        let mut scenario = Scenario::from_value(value)?;
        if let EndTimeRule::P02 { steps } = self.spec.end_time {
            let end = p02_end_time(&scenario);
            scenario.time.end = end;
            scenario.time.stepping = Stepping::Fixed {
                dt: end / steps as f64,
            };
            scenario.validate()?;
        }
        Ok(scenario)
    }

    fn validate(&self) -> Result<(), InverseError> {
        let mut issues = Vec::new();
        let mut push =
            |path: String, message: String| issues.push(ValidationIssue { path, message });
        let s = &self.spec;
        if s.genes.is_empty() {
            push("genes".into(), "at least one gene is needed".into());
        }
        for (i, g) in s.genes.iter().enumerate() {
            if !(g.min.is_finite() && g.max.is_finite() && g.min <= g.max) {
                push(
                    format!("genes.{i}.max"),
                    format!(
                        "need finite min ≤ max (got min = {}, max = {})",
                        g.min, g.max
                    ),
                );
            }
            match get_path(&self.base_value, &g.path) {
                Some(Value::Number(_)) | Some(Value::Null) => {}
                _ => push(
                    format!("genes.{i}.path"),
                    format!("`{}` is not a numeric field of the base scenario", g.path),
                ),
            }
            for (j, t) in g.tied.iter().enumerate() {
                if !matches!(
                    get_path(&self.base_value, &t.path),
                    Some(Value::Number(_)) | Some(Value::Null)
                ) {
                    push(
                        format!("genes.{i}.tied.{j}.path"),
                        format!("`{}` is not a numeric field of the base scenario", t.path),
                    );
                }
                if !t.scale.is_finite() {
                    push(
                        format!("genes.{i}.tied.{j}.scale"),
                        "a finite number".into(),
                    );
                }
            }
        }
        if let EndTimeRule::P02 { steps } = s.end_time
            && steps == 0
        {
            push("end_time.p02.steps".into(), "allowed ≥ 1 (got 0)".into());
        }
        // A field a gene or a tie sets must be one nothing else sets afterwards, or
        // best.json would report values never applied: the scene seed is each sample's,
        // the P02 end-time rule sets time.end and the fixed step, and a path set twice
        // keeps only the last value.
        let mut seen: Vec<(&str, String)> = Vec::new();
        for (i, g) in s.genes.iter().enumerate() {
            let own = std::iter::once((g.path.as_str(), format!("genes.{i}.path")));
            let ties = g
                .tied
                .iter()
                .enumerate()
                .map(|(j, t)| (t.path.as_str(), format!("genes.{i}.tied.{j}.path")));
            for (path, field) in own.chain(ties) {
                if path == "seed" {
                    push(
                        field.clone(),
                        "`seed` is set for each sample from ga.seed; a gene on it would be \
                         overwritten (allowed: a numeric field of the scene other than seed)"
                            .into(),
                    );
                }
                if matches!(s.end_time, EndTimeRule::P02 { .. })
                    && (path == "time.end" || path.starts_with("time.stepping"))
                {
                    push(
                        field.clone(),
                        format!(
                            "`{path}` is set by the P02 end-time rule (end_time.p02), which would \
                             overwrite the gene; remove the rule or the gene"
                        ),
                    );
                }
                if let Some((_, first)) = seen.iter().find(|(p, _)| *p == path) {
                    push(
                        field.clone(),
                        format!("`{path}` is already set by {first}; each field may be set once"),
                    );
                }
                seen.push((path, field));
            }
        }
        match s.cost {
            CostSpec::Pi04 => {}
            CostSpec::Pi02 { target_ratio } => {
                if !(target_ratio.is_finite() && target_ratio > 0.0) {
                    push(
                        "cost.pi02.target_ratio".into(),
                        format!("allowed a finite number > 0 (got {target_ratio})"),
                    );
                }
            }
            CostSpec::Moment { target, .. } => {
                if !target.is_finite() {
                    push(
                        "cost.moment.target".into(),
                        format!("allowed a finite number (got {target})"),
                    );
                }
            }
        }
        let e = &s.ensemble;
        if !(e.tol.is_finite() && e.tol >= 0.0) {
            push(
                "ensemble.tol".into(),
                format!("allowed a finite number ≥ 0 (got {})", e.tol),
            );
        }
        if e.min_samples == 0 {
            push("ensemble.min_samples".into(), "allowed ≥ 1 (got 0)".into());
        }
        if e.max_samples < e.min_samples.max(1) {
            push(
                "ensemble.max_samples".into(),
                format!(
                    "allowed ≥ min_samples = {} (got {})",
                    e.min_samples, e.max_samples
                ),
            );
        }
        if e.rule == EnsembleRule::StandardError && e.min_samples < 2 {
            push(
                "ensemble.min_samples".into(),
                format!(
                    "allowed ≥ 2 with the standard_error rule (got {})",
                    e.min_samples
                ),
            );
        }
        let r = &s.reevaluate;
        if r.strings > 0 && r.samples < 2 {
            push(
                "reevaluate.samples".into(),
                format!("allowed ≥ 2 (got {}), or set strings to 0", r.samples),
            );
        }
        if e.track.is_empty() {
            push("ensemble.track".into(), "list at least one quantity".into());
        }
        let ga = &s.ga;
        if ga.strings < 2 {
            push(
                "ga.strings".into(),
                format!("allowed S ≥ 2 (got {})", ga.strings),
            );
        }
        if ga.parents < 2 || !ga.parents.is_multiple_of(2) || 2 * ga.parents > ga.strings {
            push(
                "ga.parents".into(),
                format!(
                    "allowed an even K with 2 ≤ K and 2K ≤ S = {} (got {})",
                    ga.strings, ga.parents
                ),
            );
        }
        if ga.generations == 0 {
            push("ga.generations".into(), "allowed ≥ 1 (got 0)".into());
        }
        if !(ga.shrink > 0.0 && ga.shrink <= 1.0) {
            push(
                "ga.shrink".into(),
                format!("allowed 0 < shrink ≤ 1 (got {})", ga.shrink),
            );
        }
        if !ga.tol.is_finite() {
            push(
                "ga.tol".into(),
                format!("allowed a finite number (got {})", ga.tol),
            );
        }
        if let FailurePolicy::Penalty(p) = s.on_failure
            && !(p.is_finite() && p > 0.0)
        {
            // Costs are ≥ 0 and minimised: a penalty ≤ 0 would let failed strings win.
            push(
                "on_failure.penalty".into(),
                format!("allowed a finite number > 0 (got {p})"),
            );
        }
        if let Err(message) = population_fits(ga.strings, s.genes.len()) {
            push("ga.strings".into(), message);
        }
        // The check `agglo run` applies to a scene, for the scene every sample runs.
        if let Err(message) = crate::memory::MemoryEstimate::of(&self.base).check() {
            let message = message.strip_prefix("cloud.count: ").unwrap_or(&message);
            push("base.cloud.count".into(), message.to_string());
        }
        if !issues.is_empty() {
            return Err(InverseError::Invalid(issues));
        }
        // Every corner of the box must give a valid scenario (e.g. s < 0.9, a0 ≤ af),
        // so no gene combination can fail validation mid-run: all 2^k corners for up to
        // MAX_CORNER_GENES genes (a0 at its upper bound with af at its lower one
        // crossed, and only the all-lower and all-upper corners were tried), else those two.
        let (lo, hi) = self.bounds();
        let k = lo.len();
        let corners: Vec<u64> = if k <= MAX_CORNER_GENES {
            (0..1u64 << k).collect()
        } else {
            vec![0, u64::MAX]
        };
        for corner in corners {
            let genes: Vec<f64> = (0..k)
                .map(|i| if corner >> i & 1 == 1 { hi[i] } else { lo[i] })
                .collect();
            if let Err(e) = self.scenario_for(&genes, self.base.seed) {
                let label: Vec<String> = self
                    .gene_names()
                    .iter()
                    .zip(&genes)
                    .map(|(n, x)| format!("{n} = {x}"))
                    .collect();
                issues.push(ValidationIssue {
                    path: "genes".into(),
                    message: format!(
                        "the genes at a corner of their bounds ({}) give an invalid scenario: {e}",
                        label.join(", ")
                    ),
                });
                break;
            }
        }
        if issues.is_empty() {
            Ok(())
        } else {
            Err(InverseError::Invalid(issues))
        }
    }
}

/// Genes up to which every corner of the bounds is validated (2^10 scenarios, checked
/// in well under a second for a generated cloud).
const MAX_CORNER_GENES: usize = 10;

/// Memory a GA population of `strings` strings of `genes` genes holds [B] per string:
/// the genes, bounds and costs of a member and its evaluation record, measured loosely
/// and rounded up (the populations that fit are small; this refuses the ones that
/// cannot, e.g. 1e12 strings, before any allocation).
const BYTES_PER_STRING: usize = 512;

/// An error naming the memory a population needs when it exceeds what is available.
pub fn population_fits(strings: usize, genes: usize) -> Result<(), String> {
    let bytes = strings as f64 * (BYTES_PER_STRING + 16 * genes) as f64;
    crate::memory::fits("strings", strings, bytes)
}

fn set_gene(value: &mut Value, path: &str, x: f64) -> Result<(), ScenarioError> {
    set_path(value, path, x).map_err(|message| {
        ScenarioError::Invalid(vec![ValidationIssue {
            path: path.into(),
            message,
        }])
    })
}

/// P02 (13) end time for a scenario (docs/model.md §13): T = (S_gap / v_crit) · ln(0.01)/ln(0.9).
pub fn p02_end_time(s: &Scenario) -> f64 {
    let side = 2.0 * s.domain.half_width;
    let spacing = (side.powi(3) / s.cloud.count as f64).cbrt();
    let gap = spacing - 2.0 * s.primary_radius();
    let v_crit = (6.0 * s.impact.af * s.material.H0 * s.impact.beta / s.material.rho).sqrt();
    gap / v_crit * (0.01f64.ln() / 0.9f64.ln())
}
