//! Ensemble cost of one parameter set (docs/model.md §12, P04 (8.1), P02 (25), (27)).
//!
//! Samples i = 1, 2, … run with independent clouds whose seeds derive from
//! (run seed, generation, string, sample) by splitmix64, so any sample can be
//! re-run on its own (`agglo run --seed`) and no random state is ever saved.
//! After each sample the running means of the observables are updated; the
//! ensemble stops once every tracked running mean Q̄ satisfies
//! |Q̄_{E+1} − Q̄_E| ≤ TOL |Q̄_{E+1}| (and E+1 ≥ min_samples), or at max_samples.
//! The cost is computed from the ensemble means (so Π02 = |mean(b_f/b0)/r_t − 1|
//! can approach zero, as P02 reports).
//!
//! That rule (the papers') stops as soon as two running means agree, which they
//! can do by chance; the `standard_error` rule stops once the standard error of
//! every tracked mean is within TOL instead. Every evaluation reports the standard
//! error of its cost (delta method on the per-sample observables) and of b̄_f/b0.
//!
//! Samples are fed to an [`Accumulator`] strictly in sample order, wherever and in
//! whatever order they were computed (see `batch`), so the result is the same
//! for any number of threads or ranks.

use serde::{Deserialize, Serialize};

use crate::observables::Growth;
use crate::scenario::Scenario;

use super::problem::{
    CostSpec, EnsembleRule, EnsembleSpec, FailurePolicy, Moment, SampleFailure, Tracked,
};

// Their home is crate::seeds (the live view and the kernel use them too, and importing
// them from here tied the door to a run into a circle); kept here for the subgrid's
// imports.
pub use crate::seeds::{derive_seed, splitmix64};

/// Scene seed of `sample` of `string` in `generation` of the run with `seed`.
pub fn sample_seed(seed: u64, generation: usize, string: usize, sample: u32) -> u64 {
    derive_seed(&[seed, 1, generation as u64, string as u64, sample as u64])
}

/// The per-sample observables the ensemble averages (lengths in units of b0).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Observables {
    /// b_f / b0.
    pub mean: f64,
    /// σ / b0.
    pub std_dev: f64,
    /// Skewness of the final radii (dimensionless).
    pub skewness: f64,
    /// Kurtosis of the final radii (dimensionless).
    pub kurtosis: f64,
    /// b* / b0.
    pub b_star: f64,
}

impl Observables {
    /// The observables of one run's growth.
    pub fn of(g: &Growth) -> Self {
        Self {
            mean: g.growth_ratio,
            std_dev: g.radius.std_dev / g.b0,
            skewness: g.radius.skewness,
            kurtosis: g.radius.kurtosis,
            b_star: g.b_star / g.b0,
        }
    }
    /// The observables as an array, in field order.
    fn to_array(self) -> [f64; 5] {
        [
            self.mean,
            self.std_dev,
            self.skewness,
            self.kurtosis,
            self.b_star,
        ]
    }
    fn add(&mut self, o: &Self) {
        self.mean += o.mean;
        self.std_dev += o.std_dev;
        self.skewness += o.skewness;
        self.kurtosis += o.kurtosis;
        self.b_star += o.b_star;
    }
    fn scaled(&self, k: f64) -> Self {
        Self {
            mean: self.mean * k,
            std_dev: self.std_dev * k,
            skewness: self.skewness * k,
            kurtosis: self.kurtosis * k,
            b_star: self.b_star * k,
        }
    }
}

/// The cost of ensemble-mean observables.
pub fn cost_of(spec: &CostSpec, m: &Observables) -> f64 {
    match *spec {
        CostSpec::Pi04 => 1.0 - m.mean / m.b_star,
        CostSpec::Pi02 { target_ratio } => (m.mean / target_ratio - 1.0).abs(),
        CostSpec::Moment { moment, target } => {
            let x = match moment {
                Moment::Mean => m.mean,
                Moment::StdDev => m.std_dev,
                Moment::Skewness => m.skewness,
                Moment::Kurtosis => m.kurtosis,
            };
            if target == 0.0 {
                x.abs()
            } else {
                ((x - target) / target).abs()
            }
        }
    }
}

/// ∂cost/∂(ensemble means), in [`Observables::to_array`] order, at the means `m`.
fn cost_gradient(spec: &CostSpec, m: &Observables) -> [f64; 5] {
    match *spec {
        CostSpec::Pi04 => [
            -1.0 / m.b_star,
            0.0,
            0.0,
            0.0,
            m.mean / (m.b_star * m.b_star),
        ],
        CostSpec::Pi02 { target_ratio } => {
            let s = (m.mean / target_ratio - 1.0).signum();
            [s / target_ratio, 0.0, 0.0, 0.0, 0.0]
        }
        CostSpec::Moment { moment, target } => {
            let k = match moment {
                Moment::Mean => 0,
                Moment::StdDev => 1,
                Moment::Skewness => 2,
                Moment::Kurtosis => 3,
            };
            let x = m.to_array()[k];
            let mut g = [0.0; 5];
            g[k] = if target == 0.0 {
                x.signum()
            } else {
                ((x - target) / target).signum() / target
            };
            g
        }
    }
}

/// Standard error of the mean of `values` (None below two samples).
pub fn standard_error(values: impl ExactSizeIterator<Item = f64> + Clone) -> Option<f64> {
    let n = values.len();
    if n < 2 {
        return None;
    }
    let mean = values.clone().sum::<f64>() / n as f64;
    let ss: f64 = values.map(|x| (x - mean) * (x - mean)).sum();
    Some((ss / (n as f64 * (n - 1) as f64)).sqrt())
}

/// Standard error of the cost of the ensemble means, by the delta method: the cost
/// linearised about the means, applied to each sample's deviation from them.
pub fn cost_standard_error(spec: &CostSpec, samples: &[Observables]) -> Option<f64> {
    let n = samples.len();
    if n < 2 {
        return None;
    }
    let mut m = Observables::default();
    for o in samples {
        m.add(o);
    }
    let m = m.scaled(1.0 / n as f64);
    let g = cost_gradient(spec, &m);
    let mean = m.to_array();
    let linear = samples.iter().map(|o| {
        o.to_array()
            .iter()
            .zip(&mean)
            .zip(&g)
            .map(|((x, xm), gi)| if *gi == 0.0 { 0.0 } else { gi * (x - xm) })
            .sum::<f64>()
    });
    standard_error(linear)
}

/// The stopping rule on a stream of tracked values (one vector per sample).
#[derive(Debug, Clone)]
pub struct StoppingRule {
    /// Which quantity the rule tracks.
    pub kind: EnsembleRule,
    /// The rule's tolerance, relative to the tracked values ([`EnsembleRule`] says of
    /// what: their change or their standard error).
    pub tol: f64,
    /// Samples run before the rule may stop.
    pub min_samples: u32,
    /// Samples after which it stops regardless.
    pub max_samples: u32,
    previous: Option<Vec<f64>>,
    count: u32,
}

impl StoppingRule {
    /// The papers' running-mean rule.
    pub fn new(tol: f64, min_samples: u32, max_samples: u32) -> Self {
        Self::of_kind(EnsembleRule::RunningMean, tol, min_samples, max_samples)
    }

    /// The rule `kind` with these bounds.
    pub fn of_kind(kind: EnsembleRule, tol: f64, min_samples: u32, max_samples: u32) -> Self {
        Self {
            kind,
            tol,
            min_samples,
            max_samples,
            previous: None,
            count: 0,
        }
    }

    /// Feed the running means after one more sample; true = stop now (running-mean rule).
    pub fn push(&mut self, running: &[f64]) -> bool {
        self.push_with_errors(running, &vec![None; running.len()])
    }

    /// Feed the running means and their standard errors after one more sample.
    pub fn push_with_errors(&mut self, running: &[f64], errors: &[Option<f64>]) -> bool {
        self.count += 1;
        let settled = match self.kind {
            EnsembleRule::RunningMean => match &self.previous {
                Some(prev) => prev
                    .iter()
                    .zip(running)
                    .all(|(p, q)| (q - p).abs() <= self.tol * q.abs()),
                None => false,
            },
            EnsembleRule::StandardError => running
                .iter()
                .zip(errors)
                .all(|(q, se)| se.is_some_and(|se| se <= self.tol * q.abs())),
        };
        self.previous = Some(running.to_vec());
        self.count >= self.max_samples || (settled && self.count >= self.min_samples)
    }

    /// Samples seen so far.
    pub fn count(&self) -> u32 {
        self.count
    }
}

/// Number of samples the rule takes on a stream of per-sample values of one quantity
/// (running mean tracked), or None if the stream ends first. For tests and studies.
pub fn samples_needed(values: &[f64], tol: f64, min_samples: u32, max_samples: u32) -> Option<u32> {
    let mut rule = StoppingRule::new(tol, min_samples, max_samples);
    let mut sum = 0.0;
    for (i, v) in values.iter().enumerate() {
        sum += v;
        if rule.push(&[sum / (i + 1) as f64]) {
            return Some(rule.count());
        }
    }
    None
}

/// The result of one parameter set's ensemble.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Evaluation {
    /// Ensemble cost (lower is better).
    pub cost: f64,
    /// Standard error of the cost (delta method; None below two samples or on failure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost_se: Option<f64>,
    /// Standard error of the ensemble mean b̄_f/b0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub growth_se: Option<f64>,
    /// Samples run.
    pub samples: u32,
    /// Failed samples (only with an `on_failure` penalty; then cost = penalty).
    #[serde(default)]
    pub failures: u32,
    /// Ensemble means of the observables.
    #[serde(default)]
    pub means: Observables,
    /// Generation the string was evaluated at (seed coordinates).
    #[serde(default)]
    pub generation: usize,
    #[serde(default)]
    /// Its index in the generation (seed coordinates).
    pub index: usize,
    /// Final radii / b0 of every body of every sample, in sample order (for the histogram).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub radii: Vec<f64>,
}

/// What one simulation sample contributes to its ensemble.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleResult {
    /// The sample's observables.
    pub observables: Observables,
    /// Final radii / b0 (only when the ensemble keeps them).
    pub radii: Vec<f64>,
}

/// A sample's result, or why it failed.
pub type SampleOutcome = Result<SampleResult, SampleFailure>;

/// Run one sample: build its scene, run it, measure it (through [`crate::run::Run`],
/// writing no file).
pub fn run_sample(
    scenario: Result<Scenario, crate::error::ScenarioError>,
    keep_radii: bool,
) -> SampleOutcome {
    let scenario =
        scenario.map_err(|e| SampleFailure(crate::error::SimError::from(e).to_string()))?;
    let (end, outcome) =
        crate::run::Run::complete(crate::run::RunPlan::unwritten(scenario), Vec::new())
            .map_err(|e| SampleFailure(crate::run::failure_text(&e)))?;
    outcome.map_err(|e| SampleFailure(e.to_string()))?;
    let sim = end.sim;
    let bodies = sim.bodies();
    let material = sim.material();
    let growth = Growth::of(&bodies, material.rho, sim.primary().radius);
    Ok(SampleResult {
        observables: Observables::of(&growth),
        radii: if keep_radii {
            bodies
                .iter()
                .map(|b| b.radius / sim.primary().radius)
                .collect()
        } else {
            Vec::new()
        },
    })
}

/// Where an ensemble stands after one more sample.
#[derive(Debug)]
pub enum Progress {
    /// The rule wants another sample.
    More,
    /// The ensemble is complete.
    Done(Evaluation),
    /// Sample `sample` failed and the failure policy is to stop the run.
    Failed {
        /// The sample's index.
        sample: u32,
        /// Why it failed.
        failure: SampleFailure,
    },
}

/// One ensemble being filled, sample by sample, in sample order.
#[derive(Debug, Clone)]
pub struct Accumulator {
    ensemble: EnsembleSpec,
    cost: CostSpec,
    on_failure: FailurePolicy,
    rule: StoppingRule,
    samples: Vec<Observables>,
    sums: Observables,
    radii: Vec<f64>,
    generation: usize,
    index: usize,
}

impl Accumulator {
    /// An empty ensemble of `ensemble`'s rule, costed by `cost`, failing by `on_failure`.
    pub fn new(
        ensemble: &EnsembleSpec,
        cost: &CostSpec,
        on_failure: FailurePolicy,
        (generation, index): (usize, usize),
    ) -> Self {
        Self {
            rule: StoppingRule::of_kind(
                ensemble.rule,
                ensemble.tol,
                ensemble.min_samples,
                ensemble.max_samples,
            ),
            ensemble: ensemble.clone(),
            cost: *cost,
            on_failure,
            samples: Vec::new(),
            sums: Observables::default(),
            radii: Vec::new(),
            generation,
            index,
        }
    }

    /// Samples taken so far.
    pub fn count(&self) -> u32 {
        self.samples.len() as u32
    }

    /// The rule's least number of samples.
    pub fn min_samples(&self) -> u32 {
        self.ensemble.min_samples
    }

    /// The rule's cap.
    pub fn max_samples(&self) -> u32 {
        self.ensemble.max_samples
    }

    /// Add the next sample's outcome (samples must come in order).
    pub fn push(&mut self, outcome: SampleOutcome) -> Progress {
        let sample = self.count();
        let result = match outcome {
            Ok(r) => r,
            Err(failure) => {
                return match self.on_failure {
                    FailurePolicy::Error => Progress::Failed { sample, failure },
                    FailurePolicy::Penalty(p) => {
                        let n = sample.max(1) as f64;
                        Progress::Done(Evaluation {
                            cost: p,
                            samples: sample + 1,
                            failures: 1,
                            means: self.sums.scaled(1.0 / n),
                            generation: self.generation,
                            index: self.index,
                            radii: std::mem::take(&mut self.radii),
                            ..Default::default()
                        })
                    }
                };
            }
        };
        self.sums.add(&result.observables);
        self.samples.push(result.observables);
        self.radii.extend(result.radii);
        let n = self.samples.len();
        let means = self.sums.scaled(1.0 / n as f64);
        let c = cost_of(&self.cost, &means);
        let cost_se = cost_standard_error(&self.cost, &self.samples);
        let se_of = |f: fn(&Observables) -> f64| standard_error(self.samples.iter().map(f));
        let growth_se = se_of(|o| o.mean);
        let (tracked, errors): (Vec<f64>, Vec<Option<f64>>) = self
            .ensemble
            .track
            .iter()
            .map(|t| match t {
                Tracked::Cost => (c, cost_se),
                Tracked::Mean => (means.mean, growth_se),
                Tracked::StdDev => (means.std_dev, se_of(|o| o.std_dev)),
                Tracked::Skewness => (means.skewness, se_of(|o| o.skewness)),
                Tracked::Kurtosis => (means.kurtosis, se_of(|o| o.kurtosis)),
            })
            .unzip();
        if self.rule.push_with_errors(&tracked, &errors) {
            Progress::Done(Evaluation {
                cost: c,
                cost_se,
                growth_se,
                samples: n as u32,
                failures: 0,
                means,
                generation: self.generation,
                index: self.index,
                radii: std::mem::take(&mut self.radii),
            })
        } else {
            Progress::More
        }
    }
}

/// "name = value, …" for messages.
pub fn format_genes(names: &[String], genes: &[f64]) -> String {
    names
        .iter()
        .zip(genes)
        .map(|(n, x)| format!("{n} = {x:e}"))
        .collect::<Vec<_>>()
        .join(", ")
}
