//! Checkpoints: after every generation the GA state is written to
//! `DIR/checkpoint.json` (atomically: temp file, then rename). Since all randomness
//! derives from (seed, generation[, string, sample]), the state holds no random
//! generator; a resumed run repeats exactly what the uninterrupted run would do.
//! Floats are written with round-trip precision, so the restored state is bit-identical.
//! The file carries a CRC-32 of its content: a flipped digit, a lost line or any other
//! change is refused on `--resume` instead of resuming with altered state.

use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::ga::GaState;
use super::problem::{InverseError, InverseProblem};

/// The checkpoint's file name in the run's output directory.
pub const FILE: &str = "checkpoint.json";
const FORMAT: &str = "agglo-inverse-checkpoint-1";

#[derive(Debug, Clone, Serialize, Deserialize)]
/// The GA's checkpoint (`checkpoint.json`): the problem it belongs to and the state
/// to continue from.
pub struct Checkpoint {
    /// The layout's name and version, `agglo-inverse-checkpoint-1`.
    pub format: String,
    /// `crc32:` and the CRC-32 (hex) of this checkpoint's JSON without this field.
    /// Absent only in checkpoints written before checksums; those still load.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checksum: Option<String>,
    /// The inverse file as parsed (a resume must match it).
    pub spec: Value,
    /// The resolved base scenario (a resume must match it).
    pub base: Value,
    /// Where the GA stands.
    pub state: GaState,
}

impl Checkpoint {
    /// The checkpoint of `problem` at `state` (its checksum filled in).
    pub fn new(problem: &InverseProblem, state: &GaState) -> Self {
        Self {
            format: FORMAT.into(),
            checksum: None,
            spec: serde_json::to_value(&problem.spec).unwrap_or(Value::Null),
            base: problem.base_value().clone(),
            state: state.clone(),
        }
    }

    /// `crc32:` and the CRC-32 of the JSON of this checkpoint without its checksum.
    fn content_checksum(&self) -> Result<String, InverseError> {
        let body = Checkpoint {
            checksum: None,
            ..self.clone()
        };
        let text = serde_json::to_string(&body)
            .map_err(|e| InverseError::Checkpoint(format!("serialising the checkpoint: {e}")))?;
        Ok(format!("crc32:{:08x}", crc32fast::hash(text.as_bytes())))
    }

    /// Write it to `dir`/checkpoint.json, replacing the last one atomically.
    pub fn save(&self, dir: &Path) -> Result<(), InverseError> {
        let sealed = Checkpoint {
            checksum: Some(self.content_checksum()?),
            ..self.clone()
        };
        let text = serde_json::to_string(&sealed)
            .map_err(|e| InverseError::Checkpoint(format!("serialising the checkpoint: {e}")))?;
        let tmp = dir.join(format!("{FILE}.tmp"));
        let io = |source, path: &Path| InverseError::Io {
            path: path.display().to_string(),
            source,
        };
        std::fs::write(&tmp, text).map_err(|e| io(e, &tmp))?;
        std::fs::rename(&tmp, dir.join(FILE)).map_err(|e| io(e, &dir.join(FILE)))
    }

    /// Load `DIR/checkpoint.json` and check it belongs to `problem`.
    pub fn load(dir: &Path, problem: &InverseProblem) -> Result<GaState, InverseError> {
        let path = dir.join(FILE);
        let text = std::fs::read_to_string(&path).map_err(|source| InverseError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let cp: Checkpoint = serde_json::from_str(&text).map_err(|e| {
            InverseError::Checkpoint(format!("{}: not a valid checkpoint: {e}", path.display()))
        })?;
        if let Some(written) = &cp.checksum {
            let now = cp.content_checksum()?;
            if *written != now {
                return Err(InverseError::Checkpoint(format!(
                    "{}: the content does not match its checksum ({written} written, {now} now): \
                     the file was changed or damaged after it was written; resume from an intact \
                     copy or start again without --resume",
                    path.display()
                )));
            }
        }
        if cp.format != FORMAT {
            return Err(InverseError::Checkpoint(format!(
                "{}: format `{}`, expected `{FORMAT}`",
                path.display(),
                cp.format
            )));
        }
        let fresh = Checkpoint::new(problem, &cp.state);
        if cp.spec != fresh.spec || cp.base != fresh.base {
            return Err(InverseError::Checkpoint(format!(
                "{} was written for a different inverse problem or base scenario; \
                 use another --out directory or drop --resume",
                path.display()
            )));
        }
        let n = problem.dimension();
        if cp.state.lower.len() != n
            || cp.state.upper.len() != n
            || cp.state.parents.iter().any(|m| m.genes.len() != n)
        {
            return Err(InverseError::Checkpoint(format!(
                "{}: gene count does not match the problem",
                path.display()
            )));
        }
        check_state(problem, &cp.state).map_err(|e| {
            InverseError::Checkpoint(format!(
                "{}: the state does not describe a run of this problem: {e}",
                path.display()
            ))
        })?;
        Ok(cp.state)
    }
}

/// The GA state is one a run of `problem` can be in, checked as its scenarios are (a
/// checkpoint altered and its checksum recomputed by hand must not resume): the bounds
/// finite and inside the genes' own, lower ≤ upper; at most K parents, each inside the
/// genes' bounds and giving a valid scenario; no more generations done than allowed.
fn check_state(problem: &InverseProblem, state: &GaState) -> Result<(), String> {
    let genes = &problem.spec.genes;
    for (i, g) in genes.iter().enumerate() {
        let (lo, hi) = (state.lower[i], state.upper[i]);
        if !(lo.is_finite() && hi.is_finite() && g.min <= lo && lo <= hi && hi <= g.max) {
            return Err(format!(
                "gene {i} searched in [{lo}, {hi}]; allowed a range inside [{}, {}]",
                g.min, g.max
            ));
        }
    }
    let ga = &problem.spec.ga;
    if state.generations_done > ga.generations {
        return Err(format!(
            "{} generations done; ga.generations = {}",
            state.generations_done, ga.generations
        ));
    }
    if state.parents.len() > ga.parents {
        return Err(format!(
            "{} parents kept; ga.parents = {}",
            state.parents.len(),
            ga.parents
        ));
    }
    for (k, m) in state.parents.iter().enumerate() {
        for (i, (&x, g)) in m.genes.iter().zip(genes).enumerate() {
            if !(x.is_finite() && g.min <= x && x <= g.max) {
                return Err(format!(
                    "parent {k}, gene {i} = {x}; allowed [{}, {}]",
                    g.min, g.max
                ));
            }
        }
        problem
            .scenario_for(&m.genes, problem.base.seed)
            .map_err(|e| format!("parent {k} gives an invalid scenario: {e}"))?;
    }
    Ok(())
}
