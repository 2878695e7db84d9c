//! The genetic algorithm of docs/model.md §12 (P04 steps 1–6, P02 (22)).
//!
//! Generation 0 draws S strings uniformly in the bounds. Every later generation
//! keeps the K best strings of the previous one (costs not re-evaluated), mates
//! them in pairs (1,2), (3,4), … into two children each, λ = Φ Λ_a + (1 − Φ) Λ_b
//! with a fresh Φ ~ U[0,1] per gene and child, clamped to the bounds, and adds
//! M = S − 2K new random strings. The population is ranked by cost (lowest first,
//! ties by index, NaN last). Every `rescale_every` generations the bounds shrink
//! around the best string (half-width × shrink, clipped to the original bounds).
//!
//! All randomness of generation g comes from a generator seeded by (seed, g), so a
//! run resumed from the state after any generation continues bit-identically.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

use super::ensemble::{Evaluation, derive_seed};
use super::problem::{GaSpec, InverseError, StopOn};

/// One string: gene values and their ensemble evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Member {
    /// Gene values, in the problem's gene order.
    pub genes: Vec<f64>,
    /// Its ensemble's cost and means.
    pub eval: Evaluation,
}

/// One row of `generations.csv`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationRow {
    /// The generation (0-based).
    pub generation: usize,
    /// The best string's cost.
    pub best_cost: f64,
    /// The mean cost of the K parents.
    pub mean_top_k: f64,
    /// Strings evaluated in this generation.
    pub evaluations: usize,
    /// Strings evaluated so far.
    pub total_evaluations: usize,
    /// Simulation samples run in this generation.
    pub samples: u64,
    /// Standard error of the best cost (its own ensemble, delta method).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub best_cost_se: Option<f64>,
}

/// Everything needed to continue a run: saved as the checkpoint after each generation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaState {
    /// Generations completed.
    pub generations_done: usize,
    /// Current lower search bound of each gene.
    pub lower: Vec<f64>,
    /// Current upper search bound of each gene.
    pub upper: Vec<f64>,
    /// The K best strings of the last generation, ranked.
    pub parents: Vec<Member>,
    /// One row per generation done.
    pub history: Vec<GenerationRow>,
    /// Strings evaluated so far.
    pub total_evaluations: usize,
    /// True once G generations ran or the cost reached `tol`.
    pub finished: bool,
    /// The closing check: the best strings re-evaluated with fresh seeds, ranked by
    /// that evaluation (empty until it ran, or when the problem asks for none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub finalists: Vec<Finalist>,
}

/// One string of the closing check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Finalist {
    /// Its rank among the parents of the last generation (1 = the GA's best).
    pub ga_rank: usize,
    /// Its gene values.
    pub genes: Vec<f64>,
    /// The large ensemble of fresh seeds.
    pub eval: Evaluation,
}

impl GaState {
    /// A GA before its first generation, searching within [lower, upper] per gene.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Self {
        Self {
            generations_done: 0,
            lower,
            upper,
            parents: Vec::new(),
            history: Vec::new(),
            total_evaluations: 0,
            finished: false,
            finalists: Vec::new(),
        }
    }

    /// The best string so far (None before generation 0).
    pub fn best(&self) -> Option<&Member> {
        self.parents.first()
    }
}

/// Sort key that puts NaN last.
pub fn rank_key(c: f64) -> f64 {
    if c.is_nan() { f64::INFINITY } else { c }
}

/// Candidates of generation `g`: (population index, genes), before evaluation.
pub fn candidates(spec: &GaSpec, state: &GaState) -> Vec<(usize, Vec<f64>)> {
    let g = state.generations_done;
    let mut rng = StdRng::seed_from_u64(derive_seed(&[spec.seed, 0, g as u64]));
    let random = |rng: &mut StdRng| -> Vec<f64> {
        state
            .lower
            .iter()
            .zip(&state.upper)
            .map(|(&lo, &hi)| {
                if hi > lo {
                    rng.random_range(lo..hi)
                } else {
                    lo
                }
            })
            .collect()
    };
    if g == 0 {
        return (0..spec.strings).map(|i| (i, random(&mut rng))).collect();
    }
    let k = state.parents.len();
    let mut out = Vec::with_capacity(spec.strings - k);
    for pair in state.parents.chunks_exact(2) {
        let (a, b) = (&pair[0].genes, &pair[1].genes);
        for _child in 0..2 {
            let genes = a
                .iter()
                .zip(b)
                .zip(state.lower.iter().zip(&state.upper))
                .map(|((&x, &y), (&lo, &hi))| {
                    let phi: f64 = rng.random_range(0.0..1.0);
                    (phi * x + (1.0 - phi) * y).clamp(lo, hi)
                })
                .collect();
            out.push((k + out.len(), genes));
        }
    }
    while k + out.len() < spec.strings {
        out.push((k + out.len(), random(&mut rng)));
    }
    out
}

/// Run one generation: evaluate the candidates (`evaluate` gets the generation and
/// the (index, genes) list and returns the evaluations in that order), rank, keep
/// the top K, rescale if due, and decide whether to stop.
/// `original` = the gene ranges of the problem (rescaled bounds never leave them).
pub fn step(
    spec: &GaSpec,
    original: (&[f64], &[f64]),
    state: &mut GaState,
    evaluate: impl FnOnce(usize, &[(usize, Vec<f64>)]) -> Result<Vec<Evaluation>, InverseError>,
) -> Result<GenerationRow, InverseError> {
    let g = state.generations_done;
    let cands = candidates(spec, state);
    let evals = evaluate(g, &cands)?;
    let samples = evals.iter().map(|e| e.samples as u64).sum();
    let evaluations = evals.len();
    let mut population: Vec<Member> = state.parents.clone();
    population.extend(
        cands
            .into_iter()
            .zip(evals)
            .map(|((_, genes), eval)| Member { genes, eval }),
    );
    // Stable sort: equal costs keep population order (parents first).
    population.sort_by(|a, b| rank_key(a.eval.cost).total_cmp(&rank_key(b.eval.cost)));
    population.truncate(spec.parents);
    for m in population.iter_mut().skip(1) {
        // Only the best string's radii are charted; drop the rest to keep checkpoints small.
        m.eval.radii.clear();
    }
    state.parents = population;
    state.total_evaluations += evaluations;
    let best_cost = state.parents[0].eval.cost;
    let best_cost_se = state.parents[0].eval.cost_se;
    let mean_top_k =
        state.parents.iter().map(|m| m.eval.cost).sum::<f64>() / state.parents.len() as f64;
    let row = GenerationRow {
        generation: g,
        best_cost,
        mean_top_k,
        evaluations,
        total_evaluations: state.total_evaluations,
        samples,
        best_cost_se,
    };
    state.history.push(row.clone());
    state.generations_done += 1;

    if spec.rescale_every > 0 && state.generations_done.is_multiple_of(spec.rescale_every) {
        let best = &state.parents[0].genes;
        for (j, &x) in best.iter().enumerate() {
            let half = 0.5 * (state.upper[j] - state.lower[j]) * spec.shrink;
            state.lower[j] = (x - half).max(original.0[j]);
            state.upper[j] = (x + half).min(original.1[j]);
        }
    }
    let watched = match spec.stop_on {
        StopOn::Best => best_cost,
        StopOn::MeanTopK => mean_top_k,
    };
    state.finished = state.generations_done >= spec.generations || watched <= spec.tol;
    Ok(row)
}
