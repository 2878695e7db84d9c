//! Typed errors of the library. The binary wraps them with `anyhow` context and
//! prints `{:#}`; nothing here panics on bad input.

use std::fmt;

/// One out-of-range or inconsistent field.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationIssue {
    /// Field path, e.g. `material.rho` or `cloud.v_rel.0`.
    pub path: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl fmt::Display for ValidationIssue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario `{path}`: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("scenario field `{path}`: {message}")]
    Parse { path: String, message: String },
    /// Not a scenario at all: empty, cut off, not JSON, not a JSON object, not UTF-8.
    /// The message names the file (or "the scenario") and, where there is one, the
    /// line and column.
    #[error("{0}")]
    Malformed(String),
    #[error("invalid scenario:\n  {}", .0.iter().map(|i| i.to_string()).collect::<Vec<_>>().join("\n  "))]
    Invalid(Vec<ValidationIssue>),
}

/// Why a simulation could not be set up or could not finish.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(
        "cloud placement failed: placed {placed} of {requested} particles of radius {radius:.4e} m \
         (volume fraction {volume_fraction:.3}) after {attempts} attempts; \
         lower `cloud.count` or `cloud.size_ratio`/`cloud.radius` (fractions up to ~0.30 place quickly)"
    )]
    Placement {
        placed: usize,
        requested: usize,
        radius: f64,
        volume_fraction: f64,
        attempts: u64,
    },
    #[error(
        "cloud.bodies.{i} and cloud.bodies.{j} overlap: centres {distance:e} m apart, radii sum to {contact:e} m"
    )]
    Overlap {
        i: usize,
        j: usize,
        distance: f64,
        contact: f64,
    },
    /// An explicit body that cannot start as given.
    #[error("{path}: {message}")]
    InvalidBody { path: String, message: String },
    #[error(
        "run stopped at step {step} (t = {} s of {} s): reached time.max_steps = {max_steps}", crate::readable::sci(*.time), crate::readable::sci(*.end)
    )]
    StepLimit {
        step: u64,
        time: f64,
        end: f64,
        max_steps: u64,
    },
    #[error("run interrupted at step {step} (t = {} s)", crate::readable::sci(*.time))]
    Interrupted { step: u64, time: f64 },
    #[error("the step pipeline is ill-formed: {0}")]
    Schedule(String),
    #[error("non-finite state at step {step}: {what}")]
    NonFinite { step: u64, what: String },
}
