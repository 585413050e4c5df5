//! Errors of the HTTP layer in the contract's JSON shape `{"error": {"code", "message", "details"}}`,
//! and the extractors whose rejections answer in it ([`ApiJson`], [`ApiQuery`], [`ApiPath`]).

use axum::extract::rejection::{JsonRejection, PathRejection, QueryRejection};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde_json::{json, Value};

use serde::Serialize;
use utoipa::ToSchema;

use crate::service::ServiceError;
use crate::store::StoreError;
use cliffwatch_core::photogrammetry::input::epoch_csv::CsvError;
use cliffwatch_core::photogrammetry::AdjustError;

/// The error answer of every endpoint, as [`ApiError`] writes it.
#[derive(Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong.
    pub error: ErrorDetail,
}

/// Code, message and details of an error.
#[derive(Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code (`not_found`, `invalid_epoch`, `cannot_adjust`, `conflict`, …).
    pub code: &'static str,
    /// Human-readable message naming the field, image or point at fault.
    pub message: String,
    /// Extra JSON (or null), e.g. `{"limit_bytes": N}` for 413.
    #[schema(value_type = Option<Object>)]
    pub details: serde_json::Value,
}

/// An error answer: status, stable code, message naming what is at fault, details.
#[derive(Debug)]
pub struct ApiError {
    /// HTTP status.
    pub status: StatusCode,
    /// Machine-readable code (`not_found`, `invalid_epoch`, …).
    pub code: &'static str,
    /// Human-readable message.
    pub message: String,
    /// Extra JSON (or null).
    pub details: Value,
    /// Seconds after which to retry (the `Retry-After` header of a 503).
    pub retry_after_secs: Option<u64>,
}

impl ApiError {
    /// An error without details.
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        ApiError {
            status,
            code,
            message: message.into(),
            details: Value::Null,
            retry_after_secs: None,
        }
    }

    /// 400: the body is not JSON (or CSV) at all, or a bad query parameter.
    pub fn bad_request(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "bad_request", message)
    }

    /// 404 for a named thing.
    pub fn not_found(what: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not_found", what)
    }

    /// 422: valid JSON that is wrong for the schema.
    pub fn unprocessable(code: &'static str, message: impl Into<String>) -> Self {
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, code, message)
    }

    /// 413.
    pub fn too_large(limit: usize) -> Self {
        let mut e = Self::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "payload_too_large",
            format!("the body is over the limit of {limit} bytes"),
        );
        e.details = json!({ "limit_bytes": limit });
        e
    }

    /// 500 for a failure of the database or a task; logged, details withheld.
    pub fn internal(err: impl std::fmt::Display) -> Self {
        tracing::error!(error = %err, "internal error");
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            "internal error (see the server log)",
        )
    }

    /// Adds details.
    pub fn with_details(mut self, details: Value) -> Self {
        self.details = details;
        self
    }
}

impl IntoResponse for ApiError {
    /// The contract's JSON error; a run of the message quoted in double quotes or backticks (how
    /// serde's messages repeat a value) is cut to 80 characters and an ellipsis
    /// ([`cliffwatch_core::contract::echo::truncate_quoted`]), as the service's own messages cut what they
    /// repeat ([`cliffwatch_core::contract::truncate_for_message`]).
    fn into_response(self) -> Response {
        let message = match cliffwatch_core::contract::echo::truncate_quoted(&self.message) {
            std::borrow::Cow::Borrowed(_) => self.message,
            std::borrow::Cow::Owned(cut) => cut,
        };
        let body = ErrorBody {
            error: ErrorDetail {
                code: self.code,
                message,
                details: self.details,
            },
        };
        let mut response = (self.status, axum::Json(body)).into_response();
        if let Some(secs) = self.retry_after_secs {
            response
                .headers_mut()
                .insert(axum::http::header::RETRY_AFTER, secs.into());
        }
        response
    }
}

impl From<StoreError> for ApiError {
    /// 400 for a value the database cannot store (PostgreSQL refuses the NUL character in text),
    /// 500 for everything else.
    fn from(e: StoreError) -> Self {
        if e.is_data_exception() {
            return ApiError::bad_request(format!("a value cannot be stored: {e}"));
        }
        ApiError::internal(e)
    }
}

impl From<ServiceError> for ApiError {
    fn from(e: ServiceError) -> Self {
        match e {
            ServiceError::UnknownSite(_)
            | ServiceError::UnknownEpoch { .. }
            | ServiceError::UnknownAlert(_)
            | ServiceError::UnknownIncident(_)
            | ServiceError::UnknownGroup(_)
            | ServiceError::UnknownWebhook(_) => ApiError::not_found(e.to_string()),
            ServiceError::ConfiguredSite(_) => {
                ApiError::new(StatusCode::CONFLICT, "configured_site", e.to_string())
            }
            ServiceError::RetiredSite { .. } => {
                ApiError::new(StatusCode::CONFLICT, "site_retired", e.to_string())
            }
            ServiceError::NotDeletable(m) => {
                ApiError::new(StatusCode::CONFLICT, "not_deletable", m)
            }
            ServiceError::InvalidSite(m) => ApiError::unprocessable("invalid_site", m),
            ServiceError::UnmeasuredPoint { .. } => {
                ApiError::unprocessable("invalid_point", e.to_string())
            }
            ServiceError::InvalidWebhook(m) => ApiError::unprocessable("invalid_webhook", m),
            ServiceError::SiteExists(_) => {
                ApiError::new(StatusCode::CONFLICT, "conflict", e.to_string())
            }
            ServiceError::Invalid(err) => ApiError::unprocessable("invalid_epoch", err.to_string()),
            ServiceError::UnsupportedMedia(_) => ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported_media_type",
                e.to_string(),
            ),
            ServiceError::BadBody(m) => ApiError::bad_request(m),
            ServiceError::InvalidUpload(m) => ApiError::unprocessable("invalid_epoch", m),
            ServiceError::Csv(err) => err.into(),
            ServiceError::Adjust(err @ AdjustError::Cancelled { deadline }) => {
                let (code, retry) = if deadline {
                    ("compute_budget_exceeded", 60)
                } else {
                    ("shutting_down", 5)
                };
                let mut e = ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    code,
                    format!("{err}; nothing stored"),
                );
                e.retry_after_secs = Some(retry);
                e
            }
            ServiceError::Adjust(err) => ApiError::unprocessable("cannot_adjust", err.to_string()),
            ServiceError::TooLarge { .. } => ApiError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                "epoch_too_large",
                e.to_string(),
            ),
            ServiceError::BadAcknowledgement(_) => {
                ApiError::unprocessable("invalid_acknowledgement", e.to_string())
            }
            ServiceError::AlreadyAcknowledged { .. } => {
                ApiError::new(StatusCode::CONFLICT, "already_acknowledged", e.to_string())
            }
            ServiceError::Conflict {
                site,
                observed_at,
                epoch,
            } => ApiError::new(
                StatusCode::CONFLICT,
                "conflict",
                format!("site '{site}' has epoch {epoch} at {observed_at} with another body"),
            )
            .with_details(json!({ "epoch": epoch, "observed_at": observed_at })),
            ServiceError::Overloaded(o) => {
                let mut e =
                    ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "overloaded", o.to_string())
                        .with_details(
                            json!({ "slots": o.slots, "retry_after_secs": o.retry_after_secs }),
                        );
                e.retry_after_secs = Some(o.retry_after_secs);
                e
            }
            ServiceError::Plan(err) => ApiError::unprocessable("invalid_plan", err.to_string()),
            ServiceError::NoNetwork(m) => ApiError::new(StatusCode::CONFLICT, "no_network", m),
            ServiceError::Store(err) => err.into(),
            ServiceError::Task(err) => ApiError::internal(err),
        }
    }
}

impl From<CsvError> for ApiError {
    fn from(e: CsvError) -> Self {
        match e {
            CsvError::Malformed { .. } => ApiError::bad_request(e.to_string()),
            // CSV of the wrong shape is the contract's 422, like JSON of the wrong schema.
            CsvError::InvalidLine { .. } => ApiError::unprocessable("invalid_epoch", e.to_string()),
            // The site's state, not the body, is at fault: a JSON epoch must come first.
            CsvError::NoCameras => ApiError::new(StatusCode::CONFLICT, "no_cameras", e.to_string()),
            CsvError::Camera(_) => ApiError::unprocessable("invalid_epoch", e.to_string()),
        }
    }
}

impl From<JsonRejection> for ApiError {
    fn from(r: JsonRejection) -> Self {
        match r {
            JsonRejection::JsonDataError(e) => {
                ApiError::unprocessable("invalid_body", e.body_text())
            }
            JsonRejection::JsonSyntaxError(e) => ApiError::bad_request(e.body_text()),
            JsonRejection::MissingJsonContentType(e) => ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported_media_type",
                e.body_text(),
            ),
            JsonRejection::BytesRejection(e) if e.status() == StatusCode::PAYLOAD_TOO_LARGE => {
                ApiError::new(
                    StatusCode::PAYLOAD_TOO_LARGE,
                    "payload_too_large",
                    e.body_text(),
                )
            }
            other => ApiError::bad_request(other.body_text()),
        }
    }
}

impl From<QueryRejection> for ApiError {
    /// The message starts with the parameter at fault (`limit: invalid digit found in string`),
    /// as the service's own query checks do.
    fn from(r: QueryRejection) -> Self {
        let text = r.body_text();
        let text = text
            .strip_prefix("Failed to deserialize query string: ")
            .unwrap_or(&text);
        ApiError::bad_request(text.to_owned())
    }
}

impl From<PathRejection> for ApiError {
    fn from(r: PathRejection) -> Self {
        ApiError::bad_request(r.body_text())
    }
}

/// A JSON object body whose rejections answer in the contract's error shape: 415 when the body
/// is not `application/json` (or `+json`), 413 over the size limit, 400 when it is not JSON, 422
/// when it is JSON but not an object of the schema (an array is refused, although serde would read
/// a struct from one).
#[derive(Debug)]
pub struct ApiJson<T>(pub T);

impl<T, S> axum::extract::FromRequest<S> for ApiJson<T>
where
    T: serde::de::DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: axum::extract::Request, state: &S) -> Result<Self, ApiError> {
        // axum's Json answers 415, 413 and 400 (through `From<JsonRejection>`); the object check
        // and the typed read with the path of the field at fault are done here.
        let axum::Json(value) = axum::Json::<Value>::from_request(req, state).await?;
        if !value.is_object() {
            return Err(ApiError::unprocessable(
                "invalid_body",
                "the body must be a JSON object",
            ));
        }
        serde_path_to_error::deserialize(value)
            .map(ApiJson)
            .map_err(|e| {
                ApiError::unprocessable(
                    "invalid_body",
                    format!("Failed to deserialize the JSON body into the target type: {e}"),
                )
            })
    }
}

/// `Query` whose rejections answer in the contract's error shape.
#[derive(Debug, axum::extract::FromRequestParts)]
#[from_request(via(axum::extract::Query), rejection(ApiError))]
pub struct ApiQuery<T>(pub T);

/// `Path` whose rejections answer in the contract's error shape.
#[derive(Debug, axum::extract::FromRequestParts)]
#[from_request(via(axum::extract::Path), rejection(ApiError))]
pub struct ApiPath<T>(pub T);
