//! The list shape of the contract: `{"items": [...], "next_cursor": null}`, `?limit=` (default
//! 100, at most 1000) and opaque `?cursor=`.

use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use base64::Engine;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::error::ApiError;

/// Default page size.
pub const DEFAULT_LIMIT: i64 = 100;
/// Largest page size.
pub const MAX_LIMIT: i64 = 1000;

/// `?limit=&cursor=`.
#[derive(Debug, Default, Deserialize)]
pub struct PageParams {
    /// Page size (at least 1, default 100; above 1000 read as 1000).
    pub limit: Option<i64>,
    /// Cursor from the previous page's `next_cursor`.
    pub cursor: Option<String>,
}

impl PageParams {
    /// The page size: 100 when not given, at most 1000 (larger values are read as 1000); below 1
    /// is a 400 naming `limit`.
    pub fn limit(&self) -> Result<i64, ApiError> {
        match self.limit {
            Some(n) if n < 1 => Err(ApiError::bad_request(format!(
                "limit: {n} is not a page size; give 1 to {MAX_LIMIT}"
            ))),
            n => Ok(n.unwrap_or(DEFAULT_LIMIT).min(MAX_LIMIT)),
        }
    }

    /// The decoded cursor.
    pub fn cursor(&self) -> Result<Option<String>, ApiError> {
        self.cursor
            .as_deref()
            .filter(|c| !c.is_empty())
            .map(decode)
            .transpose()
    }
}

/// One page of a list.
#[derive(Debug, Serialize, ToSchema)]
pub struct Page<T> {
    /// The items.
    pub items: Vec<T>,
    /// Cursor of the next page; null on the last.
    pub next_cursor: Option<String>,
}

impl<T> Page<T> {
    /// Builds a page from up to `limit + 1` fetched items: the extra one only says there is more.
    pub fn from_fetched(mut items: Vec<T>, limit: i64, cursor_of: impl Fn(&T) -> String) -> Self {
        let more = items.len() as i64 > limit;
        items.truncate(limit as usize);
        let next_cursor = if more {
            items.last().map(|last| encode(&cursor_of(last)))
        } else {
            None
        };
        Page { items, next_cursor }
    }
}

/// Encodes a cursor (opaque to clients).
pub fn encode(raw: &str) -> String {
    URL_SAFE_NO_PAD.encode(raw.as_bytes())
}

/// The form of a cursor: unpadded base64url (no length of 1 modulo 4).
pub const CURSOR_PATTERN: &str = "^([A-Za-z0-9_-]{4})*([A-Za-z0-9_-]{2,3})?$";

/// Decodes a cursor: any string of [`CURSOR_PATTERN`] (unused trailing bits allowed; bytes that
/// are not UTF-8 read lossily, the cursor being only a position in the listing's order); other
/// strings are a 400.
pub fn decode(cursor: &str) -> Result<String, ApiError> {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    const LENIENT: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::URL_SAFE,
        GeneralPurposeConfig::new()
            .with_decode_allow_trailing_bits(true)
            .with_decode_padding_mode(DecodePaddingMode::RequireNone),
    );
    LENIENT
        .decode(cursor)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .map_err(|_| ApiError::bad_request("invalid cursor"))
}
