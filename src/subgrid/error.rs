//! Why a cell could not be advanced ([`SubgridError`]): every message names the cell
//! and the field, with the value and the allowed range, e.g.
//! `cell 17: classes[2].number_density = -1 (must be ≥ 0)`.

use serde::{Deserialize, Serialize};

/// An error of the coupling. Bad input never panics: it comes back as one of these,
/// and the other cells of a batch are not affected.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum SubgridError {
    /// The [`super::Coupling`] itself is unusable (before any cell is looked at).
    #[error("coupling: {field} = {value} ({allowed})")]
    Config {
        /// The coupling's field, by its path.
        field: String,
        /// The value given.
        value: String,
        /// What is allowed.
        allowed: String,
    },
    /// A cell's input is out of range.
    #[error("cell {cell}: {field} = {value} ({allowed})")]
    Input {
        /// The cell's id.
        cell: u64,
        /// The input's field, by its path.
        field: String,
        /// The value given.
        value: String,
        /// What is allowed.
        allowed: String,
    },
    /// A cell's state does not decode, or belongs to another cell or coupling.
    #[error("cell {cell}: state: {reason}")]
    State {
        /// The cell's id.
        cell: u64,
        /// Why the state is refused.
        reason: String,
    },
    /// The box could not be set up or run (the engine's own message).
    #[error("cell {cell}, replica {replica}: {reason}")]
    Run {
        /// The cell's id.
        cell: u64,
        /// Which of its boxes.
        replica: u32,
        /// The engine's message.
        reason: String,
    },
    /// The task farm failed (a worker panicked, an MPI failure): every cell of the
    /// batch gets this error.
    #[error("cell {cell}: task farm: {reason}")]
    Farm {
        /// The cell's id.
        cell: u64,
        /// What failed.
        reason: String,
    },
}

impl SubgridError {
    /// An input error of `cell`: `field` is `value`, which is not `allowed`.
    pub fn input(
        cell: u64,
        field: impl Into<String>,
        value: impl std::fmt::Display,
        allowed: impl Into<String>,
    ) -> Self {
        Self::Input {
            cell,
            field: field.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    /// A configuration error: `field` is `value`, which is not `allowed`.
    pub fn config(
        field: impl Into<String>,
        value: impl std::fmt::Display,
        allowed: impl Into<String>,
    ) -> Self {
        Self::Config {
            field: field.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    /// The cell the error is about (`None` for a configuration error).
    pub fn cell(&self) -> Option<u64> {
        match self {
            Self::Config { .. } => None,
            Self::Input { cell, .. }
            | Self::State { cell, .. }
            | Self::Run { cell, .. }
            | Self::Farm { cell, .. } => Some(*cell),
        }
    }
}
