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
    /// The file could not be read.
    #[error("cannot read scenario `{path}`: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why reading failed.
        #[source]
        source: std::io::Error,
    },
    /// A field does not parse (wrong type, unknown key, bad value).
    #[error("scenario field `{path}`: {message}")]
    Parse {
        /// The field's path, e.g. `material.rho`.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// Not a scenario at all: empty, cut off, not JSON, not a JSON object, not UTF-8.
    /// The message names the file (or "the scenario") and, where there is one, the
    /// line and column.
    #[error("{0}")]
    Malformed(String),
    /// Parsed, but values out of their ranges: every problem, each with its path.
    #[error("invalid scenario:\n  {}", .0.iter().map(|i| i.to_string()).collect::<Vec<_>>().join("\n  "))]
    Invalid(Vec<ValidationIssue>),
}

/// Why a simulation could not be set up or could not finish.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scenario could not be loaded.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(
        "cloud placement failed: placed {placed} of {requested} particles of radius {radius:.4e} m \
         (volume fraction {volume_fraction:.3}) after {attempts} attempts; \
         lower `cloud.count` or `cloud.size_ratio`/`cloud.radius` (fractions up to ~0.30 place quickly)"
    )]
    /// The random cloud could not be placed without overlaps.
    Placement {
        /// Bodies placed before giving up.
        placed: usize,
        /// Bodies asked for (`cloud.count`).
        requested: usize,
        /// Their radius [m].
        radius: f64,
        /// The volume fraction asked for.
        volume_fraction: f64,
        /// Placement attempts made.
        attempts: u64,
    },
    #[error(
        "cloud.bodies.{i} and cloud.bodies.{j} overlap: centres {distance:e} m apart, radii sum to {contact:e} m"
    )]
    /// Two explicit bodies (`cloud.bodies`) overlap.
    Overlap {
        /// The first body's index in `cloud.bodies`.
        i: usize,
        /// The second body's index.
        j: usize,
        /// Their centres' distance [m].
        distance: f64,
        /// Their radii's sum [m].
        contact: f64,
    },
    /// An explicit body that cannot start as given.
    #[error("{path}: {message}")]
    InvalidBody {
        /// The body's path, e.g. `cloud.bodies.3.radius`.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    #[error(
        "run stopped at step {step} (t = {} s of {} s): reached time.max_steps = {max_steps}", crate::readable::sci(*.time), crate::readable::sci(*.end)
    )]
    /// The run reached `time.max_steps` before the end time.
    StepLimit {
        /// The step reached.
        step: u64,
        /// The simulated time reached [s].
        time: f64,
        /// The end time T [s].
        end: f64,
        /// `time.max_steps`.
        max_steps: u64,
    },
    /// The run was stopped by its caller (a signal, an observer, a stop flag); it can
    /// be continued.
    #[error("run interrupted at step {step} (t = {} s)", crate::readable::sci(*.time))]
    Interrupted {
        /// The last step completed.
        step: u64,
        /// The simulated time then [s].
        time: f64,
    },
    /// The plugins' systems do not make a valid step (an access conflict, a missing stage).
    #[error("the step pipeline is ill-formed: {0}")]
    Schedule(String),
    /// A body's state became NaN or infinite.
    #[error("non-finite state at step {step}: {what}")]
    NonFinite {
        /// The step it was seen at.
        step: u64,
        /// The body, the quantity and its value.
        what: String,
    },
}
