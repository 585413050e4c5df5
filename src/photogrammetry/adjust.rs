//! The least-squares engine (placeholder until the engine lands).

use super::epoch::{EpochInput, EpochProblem};
use super::error::AdjustError;
use super::result::{AdjustOptions, Adjustment};

/// Validates and adjusts an epoch of the upload form.
pub fn adjust(input: &EpochInput, options: &AdjustOptions) -> Result<Adjustment, AdjustError> {
    let problem = input.validate()?;
    adjust_problem(&problem, options)
}

/// Adjusts a validated epoch.
pub fn adjust_problem(
    _problem: &EpochProblem,
    _options: &AdjustOptions,
) -> Result<Adjustment, AdjustError> {
    Err(AdjustError::Singular("engine not yet implemented".into()))
}
