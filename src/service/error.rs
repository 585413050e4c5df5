//! Why a use case did not happen. Each variant names the item at fault; the API maps them to
//! statuses (`http::error`), the watched directory writes them to the folder's `error.txt`.

use thiserror::Error;

use cliffwatch_core::contract::truncate_for_message as cut;

use crate::store::StoreError;
use cliffwatch_core::photogrammetry::input::epoch_csv::CsvError;
use cliffwatch_core::photogrammetry::{AdjustError, EpochError};

/// Why a use case failed; nothing of it was stored.
#[derive(Debug, Error)]
pub enum ServiceError {
    /// The site does not exist (uploads do not create sites).
    #[error("unknown site '{}'", cut(.0))]
    UnknownSite(String),
    /// The site has no epoch with that id.
    #[error("site '{site}' has no epoch {epoch}")]
    UnknownEpoch {
        /// Site id.
        site: String,
        /// The epoch id asked for.
        epoch: i64,
    },
    /// No alert has that id.
    #[error("unknown alert '{}'", cut(.0))]
    UnknownAlert(String),
    /// The site has no open incident with that id (`block:B1`, `point:T203`, `site`).
    #[error("no open incident '{}' on this site", cut(.0))]
    UnknownIncident(String),
    /// The site has no group of that name.
    #[error("unknown group '{}'", cut(.0))]
    UnknownGroup(String),
    /// The site is defined in the configuration file, which is applied at every start: an edit
    /// through the API would be undone at the next one.
    #[error("site '{}' is defined in the configuration file ([[sites]]), which is applied at every start: change it there, or remove it from the file to manage it through the API", cut(.0))]
    ConfiguredSite(String),
    /// The site is retired: it takes no upload and no change of its settings any more.
    #[error("site '{}' was retired on {at} ({}): it takes no more uploads or changes", cut(.site), cut(.reason))]
    RetiredSite {
        /// Site id.
        site: String,
        /// When it was retired (RFC 3339).
        at: String,
        /// Why.
        reason: String,
    },
    /// The site cannot be deleted yet (not retired, or its data not exported since); the
    /// message says which step is missing.
    #[error("{0}")]
    NotDeletable(String),
    /// No webhook endpoint has that id.
    #[error("unknown webhook '{}'", cut(.0))]
    UnknownWebhook(String),
    /// A point setting for a point the site has never measured, on a site with epochs, without
    /// `"planned": true`: most likely a misspelt name.
    #[error(
        "point '{}': site '{site}' has never measured it (no epoch observed it); check the \
         name, or send \"planned\": true to set up a point before its first measurement",
        cut(.point)
    )]
    UnmeasuredPoint {
        /// Site id.
        site: String,
        /// The point named.
        point: String,
    },
    /// A site definition that cannot be stored (the message names the field).
    #[error("{0}")]
    InvalidSite(String),
    /// A site with that id exists already.
    #[error("site '{}' exists", cut(.0))]
    SiteExists(String),
    /// A webhook endpoint that cannot be used (the message names the field).
    #[error("{0}")]
    InvalidWebhook(String),
    /// An acknowledgement without a name, or with a name or comment too long.
    #[error("{0}")]
    BadAcknowledgement(String),
    /// The alert was acknowledged already and has not been raised again since (escalated alerts
    /// open again and can be acknowledged anew).
    #[error("alert '{id}' was acknowledged already by {by}")]
    AlreadyAcknowledged {
        /// Alert id.
        id: String,
        /// Who acknowledged it.
        by: String,
    },
    /// The upload is not a valid epoch (names the field, image or point).
    #[error(transparent)]
    Invalid(#[from] EpochError),
    /// An upload whose body is of another media type than the upload's forms (`None`: the
    /// request said none).
    #[error(
        "an epoch is uploaded as application/json or text/csv, not {}",
        .0.as_deref().unwrap_or("a body without Content-Type")
    )]
    UnsupportedMedia(Option<String>),
    /// An upload whose body cannot be read as its form says (not JSON, a CSV not UTF-8).
    #[error("{0}")]
    BadBody(String),
    /// An upload of the wrong shape: JSON not of the upload form (names the field), a CSV
    /// without its observation time.
    #[error("{0}")]
    InvalidUpload(String),
    /// A CSV upload that cannot be read, or whose camera the site cannot tell.
    #[error(transparent)]
    Csv(#[from] CsvError),
    /// The epoch cannot be adjusted (names the image or point).
    #[error(transparent)]
    Adjust(#[from] AdjustError),
    /// The epoch is larger than the node takes (configuration `setting`).
    #[error(
        "the epoch has {count} {what}; this server takes at most {limit} per epoch ({setting})"
    )]
    TooLarge {
        /// What was counted, e.g. `points`.
        what: &'static str,
        /// How many the epoch has.
        count: usize,
        /// The limit.
        limit: usize,
        /// The configuration setting of the limit.
        setting: &'static str,
    },
    /// Another body was stored for this `observed_at`.
    #[error("epoch {epoch} of site '{site}' has observed_at {observed_at} with another body")]
    Conflict {
        /// Site id.
        site: String,
        /// Observation time.
        observed_at: String,
        /// The stored epoch's id.
        epoch: i64,
    },
    /// A plan that cannot be analysed (the message names the item).
    #[error(transparent)]
    Plan(#[from] cliffwatch_core::plan::PlanError),
    /// A site whose network cannot be rebuilt for a pre-analysis (no epoch, observations
    /// deleted).
    #[error("{0}")]
    NoNetwork(String),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// Every upload slot of the node stayed busy for the whole wait.
    #[error(transparent)]
    Overloaded(#[from] super::admission::Overloaded),
    /// A computation task panicked or was cancelled.
    #[error("computation task failed: {0}")]
    Task(String),
}

impl From<tokio::task::JoinError> for ServiceError {
    fn from(e: tokio::task::JoinError) -> Self {
        ServiceError::Task(e.to_string())
    }
}
