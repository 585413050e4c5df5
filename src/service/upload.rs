//! An epoch uploaded through the API, taken as the client sent it: the upload form as JSON
//! bytes, or CSV lines `image,point,x_mm,y_mm` with the observation time and camera of its
//! query. One use case ([`upload`]) does every read and write: the site checked, an upload slot
//! taken, the body read into the upload form (a CSV's images with one of the site's cameras),
//! the epoch ingested ([`super::ingest::ingest`]) and read back as stored
//! ([`super::stored_epoch`]).

use bytes::Bytes;

use crate::store::{epochs, sites, Store, StoreError};
use cliffwatch_core::photogrammetry::input::epoch::{is_valid_identifier, CameraInput};
use cliffwatch_core::photogrammetry::input::epoch_csv::{csv_camera, epoch_from_csv};
use cliffwatch_core::photogrammetry::EpochInput;

use super::admission::UploadGate;
use super::ingest::{self, EpochLimits};
use super::stored_epoch::{stored_epoch, StoredEpoch};
use super::ServiceError;

/// What the client says its body is (the `Content-Type` of the request).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UploadForm {
    /// The upload form as JSON (`application/json` or a `+json` type).
    Json,
    /// CSV `image,point,x_mm,y_mm` (`text/csv`), with the query's fields.
    Csv {
        /// Observation time (RFC 3339); required.
        observed_at: Option<String>,
        /// The camera of the images: needed when the site has several.
        camera: Option<String>,
    },
    /// Any other media type (lower case, without parameters; `None`: no `Content-Type`),
    /// refused as [`ServiceError::UnsupportedMedia`].
    Other(Option<String>),
}

/// An upload as the client sent it.
#[derive(Debug, Clone)]
pub struct Upload {
    /// What the body is.
    pub form: UploadForm,
    /// The body, as received.
    pub body: Bytes,
}

/// The outcome of an upload.
#[derive(Debug)]
pub struct Uploaded {
    /// True when this upload stored the epoch; false when the same body was stored before.
    pub created: bool,
    /// The epoch as stored.
    pub epoch: StoredEpoch,
}

/// Takes an upload of `site` as sent: an unknown site is named before anything is said about
/// the body ([`ServiceError::UnknownSite`]); an upload slot of `gate` is taken once the body has
/// arrived ([`ServiceError::Overloaded`]); the body becomes the upload form on a blocking
/// thread (CPU work, as the adjustment is): JSON, or CSV with the site's cameras (the one named by
/// `camera`); then the epoch is ingested within `limits` (the events' bodies linking under
/// `public_url`) and read back as stored, without residuals.
pub async fn upload(
    store: &Store,
    gate: &UploadGate,
    site: &str,
    upload: Upload,
    limits: EpochLimits,
    public_url: Option<&str>,
) -> Result<Uploaded, ServiceError> {
    // No site has an id outside the identifier rule: not asked of the database (PostgreSQL
    // would refuse a NUL in it as a value it cannot hold, where the answer is "no such site").
    if !is_valid_identifier(site) || sites::get(store.reader(), site).await?.is_none() {
        return Err(ServiceError::UnknownSite(site.to_string()));
    }
    let slot = gate.enter().await?;
    let Upload { form, body } = upload;
    let input: EpochInput = match form {
        UploadForm::Other(media) => return Err(ServiceError::UnsupportedMedia(media)),
        UploadForm::Json => tokio::task::spawn_blocking(move || parse_epoch(&body)).await??,
        UploadForm::Csv {
            observed_at,
            camera,
        } => {
            let observed_at = observed_at.ok_or_else(|| {
                ServiceError::InvalidUpload("a CSV upload needs ?observed_at=".into())
            })?;
            let cameras: Vec<CameraInput> = epochs::site_cameras(store.reader(), site)
                .await?
                .into_iter()
                .map(serde_json::from_value)
                .collect::<Result<_, _>>()
                .map_err(StoreError::from)?;
            let camera = csv_camera(cameras, camera.as_deref())?;
            tokio::task::spawn_blocking(move || {
                let text = std::str::from_utf8(&body)
                    .map_err(|_| ServiceError::BadBody("the CSV is not UTF-8".into()))?;
                Ok::<_, ServiceError>(epoch_from_csv(text, &observed_at, camera)?)
            })
            .await??
        }
    };
    let done = ingest::ingest(store, site, input, limits, slot, public_url).await?;
    let epoch = stored_epoch(store, &done.site, done.epoch, false)
        .await?
        .ok_or_else(|| {
            StoreError::Corrupt(format!(
                "epoch {} of site '{}' not found",
                done.epoch, done.site
            ))
        })?;
    Ok(Uploaded {
        created: done.created,
        epoch,
    })
}

/// The JSON upload form: [`ServiceError::BadBody`] when the body is not JSON,
/// [`ServiceError::InvalidUpload`] naming the field at fault when it is JSON of the wrong shape.
fn parse_epoch(bytes: &[u8]) -> Result<EpochInput, ServiceError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let parsed: Result<EpochInput, _> = serde_path_to_error::deserialize(&mut de);
    let input = parsed.map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        // A number beyond f64 (`1e400`) is valid JSON that serde_json reports as a syntax
        // error; it is a value out of range, named with its field like any other.
        let out_of_range = inner.to_string().starts_with("number out of range");
        match inner.classify() {
            serde_json::error::Category::Data => ServiceError::InvalidUpload(if path == "." {
                inner.to_string()
            } else {
                format!("{path}: {inner}")
            }),
            serde_json::error::Category::Syntax if out_of_range => {
                ServiceError::InvalidUpload(format!("{path}: {inner}"))
            }
            _ => ServiceError::BadBody(format!("the body is not JSON: {inner}")),
        }
    })?;
    de.end()
        .map_err(|e| ServiceError::BadBody(format!("the body is not JSON: {e}")))?;
    Ok(input)
}
