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

use std::sync::atomic::{AtomicBool, Ordering};

use serde::{Deserialize, Serialize};

use crate::observables::Growth;
use crate::schedule::Simulation;

use super::problem::{
    CostSpec, EnsembleSpec, FailurePolicy, InverseError, InverseProblem, Moment, Tracked,
};

/// splitmix64 finaliser: a bijective 64-bit mixer.
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash a sequence of words into one seed (each word mixed into the running state).
pub fn derive_seed(words: &[u64]) -> u64 {
    words
        .iter()
        .fold(0x6A09_E667_F3BC_C908, |h, &w| splitmix64(h ^ splitmix64(w)))
}

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
    pub skewness: f64,
    pub kurtosis: f64,
    /// b* / b0.
    pub b_star: f64,
}

impl Observables {
    pub fn of(g: &Growth) -> Self {
        Self {
            mean: g.growth_ratio,
            std_dev: g.radius.std_dev / g.b0,
            skewness: g.radius.skewness,
            kurtosis: g.radius.kurtosis,
            b_star: g.b_star / g.b0,
        }
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

/// The stopping rule on a stream of tracked values (one vector per sample).
#[derive(Debug, Clone)]
pub struct StoppingRule {
    pub tol: f64,
    pub min_samples: u32,
    pub max_samples: u32,
    previous: Option<Vec<f64>>,
    count: u32,
}

impl StoppingRule {
    pub fn new(tol: f64, min_samples: u32, max_samples: u32) -> Self {
        Self {
            tol,
            min_samples,
            max_samples,
            previous: None,
            count: 0,
        }
    }

    /// Feed the running means after one more sample; true = stop now.
    pub fn push(&mut self, running: &[f64]) -> bool {
        self.count += 1;
        let settled = match &self.previous {
            Some(prev) => prev
                .iter()
                .zip(running)
                .all(|(p, q)| (q - p).abs() <= self.tol * q.abs()),
            None => false,
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
    /// Samples run.
    pub samples: u32,
    /// Failed samples (only with an `on_failure` penalty; then cost = penalty).
    #[serde(default)]
    pub failures: u32,
    /// Ensemble means of the observables.
    #[serde(default)]
    pub means: Observables,
    /// Generation and population index the string was evaluated at (seed coordinates).
    #[serde(default)]
    pub generation: usize,
    #[serde(default)]
    pub index: usize,
    /// Final radii / b0 of every body of every sample, in sample order (for the histogram).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub radii: Vec<f64>,
}

/// Run the ensemble of `genes` with seeds from (`seed`, `generation`, `index`, sample).
/// `cancel` aborts between samples.
pub fn evaluate(
    problem: &InverseProblem,
    genes: &[f64],
    seed: u64,
    generation: usize,
    index: usize,
    keep_radii: bool,
    cancel: Option<&AtomicBool>,
) -> Result<Evaluation, InverseError> {
    let spec = &problem.spec;
    evaluate_with(
        &spec.ensemble,
        &spec.cost,
        spec.on_failure,
        |sample| problem.scenario_for(genes, sample_seed(seed, generation, index, sample)),
        |sample| sample_seed(seed, generation, index, sample),
        &format_genes(&problem.gene_names(), genes),
        (generation, index),
        keep_radii,
        cancel,
    )
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

/// The ensemble loop, given a scenario factory per sample.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_with(
    ensemble: &EnsembleSpec,
    cost: &CostSpec,
    on_failure: FailurePolicy,
    scenario: impl Fn(u32) -> Result<crate::scenario::Scenario, crate::error::ScenarioError>,
    seed_of: impl Fn(u32) -> u64,
    genes_text: &str,
    (generation, index): (usize, usize),
    keep_radii: bool,
    cancel: Option<&AtomicBool>,
) -> Result<Evaluation, InverseError> {
    let mut rule = StoppingRule::new(ensemble.tol, ensemble.min_samples, ensemble.max_samples);
    let mut sums = Observables::default();
    let mut radii = Vec::new();
    let mut sample = 0u32;
    loop {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(InverseError::Interrupted);
        }
        let result = scenario(sample)
            .map_err(crate::error::SimError::from)
            .and_then(|s| {
                let mut sim = Simulation::new(&s)?;
                sim.run()?;
                Ok(sim)
            });
        let sim = match result {
            Ok(sim) => sim,
            Err(source) => match on_failure {
                FailurePolicy::Error => {
                    return Err(InverseError::Sample {
                        generation,
                        string: index,
                        sample,
                        seed: seed_of(sample),
                        genes: genes_text.to_string(),
                        source,
                    });
                }
                FailurePolicy::Penalty(p) => {
                    let n = sample.max(1) as f64;
                    return Ok(Evaluation {
                        cost: p,
                        samples: sample + 1,
                        failures: 1,
                        means: sums.scaled(1.0 / n),
                        generation,
                        index,
                        radii,
                    });
                }
            },
        };
        let bodies = sim.bodies();
        let material = sim.material();
        let growth = Growth::of(&bodies, material.rho, material.primary_radius);
        sums.add(&Observables::of(&growth));
        if keep_radii {
            radii.extend(bodies.iter().map(|b| b.radius / material.primary_radius));
        }
        sample += 1;
        let means = sums.scaled(1.0 / sample as f64);
        let c = cost_of(cost, &means);
        let tracked: Vec<f64> = ensemble
            .track
            .iter()
            .map(|t| match t {
                Tracked::Cost => c,
                Tracked::Mean => means.mean,
                Tracked::StdDev => means.std_dev,
                Tracked::Skewness => means.skewness,
                Tracked::Kurtosis => means.kurtosis,
            })
            .collect();
        if rule.push(&tracked) {
            return Ok(Evaluation {
                cost: c,
                samples: sample,
                failures: 0,
                means,
                generation,
                index,
                radii,
            });
        }
    }
}
