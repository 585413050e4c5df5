//! Why a watched folder failed.

use crate::service::ServiceError;
use crate::store::StoreError;
use cliffwatch_core::detect::first_epoch::FirstEpochError;
use cliffwatch_core::detect::identify::IdentifyError;
use cliffwatch_core::detect::DetectError;

/// Why a watched folder failed (written to its `error.txt`).
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// Reading or moving files failed.
    #[error("file system: {0}")]
    Io(#[from] std::io::Error),
    /// A file of the folder could not be read (`file` relative to the folder).
    #[error("{file}: {source}")]
    File {
        /// The file, relative to the folder.
        file: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The folder's site directory names no site.
    #[error(
        "no site '{0}': create it (POST /api/v1/sites) or put the folder under the directory of an existing site"
    )]
    UnknownSite(String),
    /// `epoch.json` is not the upload form.
    #[error("epoch.json: {0}")]
    Json(#[from] serde_json::Error),
    /// `epoch.json`'s `detection` is not valid detection settings (the message names the field).
    #[error("epoch.json: {0}")]
    Detection(String),
    /// A station (or image id) of `epoch.json` is not an identifier, so it names no file of the
    /// folder.
    #[error("station '{0}': letters, digits, '.', '_' and '-' only (1 to 64)")]
    BadStation(String),
    /// An image of `epoch.json` has no file.
    #[error("no image file <{0}>.jpg|.png|.tif for station {0}")]
    MissingImage(String),
    /// An image file of the folder names no station of `epoch.json`.
    #[error("image file {0} names no station of epoch.json's images: list its station (with its camera) or remove the file")]
    UnlistedImage(String),
    /// A station has more than one image file.
    #[error("station {station} has several image files ({files}): keep one")]
    SeveralImages {
        /// Station.
        station: String,
        /// The files, comma-separated.
        files: String,
    },
    /// The station's image file is larger than any image the detection reads.
    #[error(
        "image {file} of station {station}: {bytes} bytes; files above {max} bytes are not read"
    )]
    ImageFileTooLarge {
        /// Station.
        station: String,
        /// The image file's name in the folder.
        file: String,
        /// The file's size.
        bytes: u64,
        /// The limit ([`cliffwatch_core::detect::MAX_IMAGE_FILE_BYTES`]).
        max: u64,
    },
    /// A camera is invalid or lacks pixel size and image size.
    #[error("camera of station {station}: {reason}")]
    Camera {
        /// Station.
        station: String,
        /// Why.
        reason: String,
    },
    /// Detection failed (the file cannot be decoded, is too small or too large, or holds noise).
    #[error("image {file} of station {station}: {source}")]
    Detect {
        /// Station.
        station: String,
        /// The image file's name in the folder.
        file: String,
        /// Cause.
        source: DetectError,
    },
    /// No target was found in a station's image with the detection settings used.
    #[error("image {file} of station {station}: no target found (polarity {polarity}, diameters {min_diameter_px}–{max_diameter_px} px): check the site's detection settings or epoch.json's detection")]
    NoTargets {
        /// Station.
        station: String,
        /// The image file's name in the folder.
        file: String,
        /// The polarity searched: `auto`, `bright` or `dark`.
        polarity: &'static str,
        /// Smallest diameter searched, px.
        min_diameter_px: f64,
        /// Largest diameter searched, px.
        max_diameter_px: f64,
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
    /// The database failed (unreachable, restarting, or closed at shutdown): the folder stays
    /// and is taken again at the next scan.
    #[error("database: {0}")]
    Store(#[from] StoreError),
    /// Ingestion refused the epoch.
    #[error("ingestion: {0}")]
    Ingest(#[from] ServiceError),
    /// The blocking task panicked.
    #[error("detection task failed: {0}")]
    Task(String),
}

impl WatchError {
    /// Whether the failure lies with the database rather than the folder: then the folder stays
    /// where it is and is taken again at the next scan, instead of moving to `.failed/`. A value
    /// of the folder the database refuses ([`StoreError::is_data_exception`]) is the folder's
    /// fault: taken again it would fail again, at every scan.
    pub fn is_transient(&self) -> bool {
        match self {
            WatchError::Store(e) | WatchError::Ingest(ServiceError::Store(e)) => {
                !e.is_data_exception()
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_database_failures_leave_the_folder_for_the_next_scan() {
        let db = || StoreError::Url("postgres://***@db/cw".into());
        assert!(WatchError::Store(db()).is_transient());
        assert!(WatchError::Ingest(ServiceError::Store(db())).is_transient());
        assert!(!WatchError::MissingImage("S1".into()).is_transient());
        assert!(!WatchError::Ingest(ServiceError::UnknownSite("kamo".into())).is_transient());
        assert!(!WatchError::NoPrior("S1".into()).is_transient());
    }
}
