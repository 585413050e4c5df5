//! Why a watched folder failed.

use crate::detect::first_epoch::FirstEpochError;
use crate::detect::identify::IdentifyError;
use crate::detect::DetectError;
use crate::service::ServiceError;

/// Why a watched folder failed (written to its `error.txt`).
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// Reading or moving files failed.
    #[error("file system: {0}")]
    Io(#[from] std::io::Error),
    /// `epoch.json` is not the upload form.
    #[error("epoch.json: {0}")]
    Json(#[from] serde_json::Error),
    /// An image of `epoch.json` has no file.
    #[error("no image file <{0}>.jpg|.png|.tif for station {0}")]
    MissingImage(String),
    /// A camera is invalid or lacks pixel size and image size.
    #[error("camera of station {station}: {reason}")]
    Camera {
        /// Station.
        station: String,
        /// Why.
        reason: String,
    },
    /// Detection failed.
    #[error("detection on station {station}: {source}")]
    Detect {
        /// Station.
        station: String,
        /// Cause.
        source: DetectError,
    },
    /// Identification failed.
    #[error("identification on station {station}: {source}")]
    Identify {
        /// Station.
        station: String,
        /// Cause.
        source: IdentifyError,
    },
    /// Multi-view identification of a first epoch failed.
    #[error("identification: {0}")]
    FirstEpoch(FirstEpochError),
    /// Too few targets could be named; the message names the stations, the cause and what to add.
    #[error("{0}")]
    Unidentified(String),
    /// A station seen for the first time without ≥ 4 seed observations.
    #[error("station {0} has no previous orientation and fewer than 4 seed observations")]
    NoPrior(String),
    /// Ingestion refused the epoch.
    #[error("ingestion: {0}")]
    Ingest(#[from] ServiceError),
    /// The blocking task panicked.
    #[error("detection task failed: {0}")]
    Task(String),
}
