//! Typed errors of the displacement analysis and the alert state machine.

use thiserror::Error;

/// What can go wrong in the pure analysis. None of these is a panic: bad input comes back as one of them.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AnalysisError {
    /// A number in the input is NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found (point and field).
        what: String,
    },
    /// Too few points common to both epochs to define the datum.
    #[error("too few datum points: {found} common points, at least {needed} needed")]
    TooFewDatumPoints {
        /// Points available.
        found: usize,
        /// Points needed by the transformation.
        needed: usize,
    },
    /// The datum points do not determine the transformation (e.g. collinear) or their covariance is singular.
    #[error("singular system: {what}")]
    Singular {
        /// Which matrix was singular.
        what: String,
    },
    /// A joint covariance does not match its point list (wrong length).
    #[error("joint covariance has {len} elements, expected {expected}")]
    BadJointCovariance {
        /// Elements given.
        len: usize,
        /// (3n)² elements expected.
        expected: usize,
    },
    /// A configuration value is out of range (confidence outside (0, 1), zero window, …).
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// No open alert has that id.
    #[error("unknown alert {0}")]
    UnknownAlert(String),
    /// The alert was acknowledged already and has not been escalated since: an acknowledgement
    /// stands, and only a higher level asks for a new one.
    #[error("alert '{id}' was acknowledged already by {by}")]
    AlreadyAcknowledged {
        /// Alert id.
        id: String,
        /// Who acknowledged it.
        by: String,
    },
    /// A series the filter cannot take (non-finite value, times not increasing, a covariance that
    /// is not positive definite): the message names the measurement.
    #[error("invalid input: {0}")]
    InvalidInput(String),
}
