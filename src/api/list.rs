//! The list shape of the contract: `{"items": [...], "next_cursor": null}`, `?limit=` (default
//! 100, at most 1000) and opaque `?cursor=`. A cursor names the listing it came from
//! ([`Listing`]): one handed to another listing is a 400, not read as a position there.

use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use base64::Engine;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::http::error::ApiError;

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

    /// The decoded cursor, which must come from `listing`; a cursor of another listing, or a
    /// string no listing gave, is a 400.
    pub fn cursor(&self, listing: Listing) -> Result<Option<String>, ApiError> {
        self.cursor
            .as_deref()
            .filter(|c| !c.is_empty())
            .map(|c| decode(listing, c))
            .transpose()
    }
}

/// The listings that page, each with the tag its cursors carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Listing {
    /// `GET /api/v1/sites`.
    Sites,
    /// `GET /api/v1/alerts`.
    Alerts,
    /// `GET /api/v1/sites/{site}/epochs`.
    Epochs,
    /// `GET /api/v1/sites/{site}/points`.
    Points,
    /// `GET /api/v1/sites/{site}/groups`.
    Groups,
    /// A point's or a block's displacement series (positions are observation times).
    Series,
}

impl Listing {
    /// The tag that starts the cursor's decoded text.
    fn tag(self) -> &'static str {
        match self {
            Listing::Sites => "sites",
            Listing::Alerts => "alerts",
            Listing::Epochs => "epochs",
            Listing::Points => "points",
            Listing::Groups => "groups",
            Listing::Series => "series",
        }
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
    /// Builds a page of `listing` from up to `limit + 1` fetched items: the extra one only says
    /// there is more; `cursor_of` gives the last item's position.
    pub fn from_fetched(
        mut items: Vec<T>,
        limit: i64,
        listing: Listing,
        cursor_of: impl Fn(&T) -> String,
    ) -> Self {
        let more = items.len() as i64 > limit;
        items.truncate(limit as usize);
        let next_cursor = if more {
            items.last().map(|last| encode(listing, &cursor_of(last)))
        } else {
            None
        };
        Page { items, next_cursor }
    }
}

/// Encodes the position `raw` in `listing` as a cursor (opaque to clients).
pub fn encode(listing: Listing, raw: &str) -> String {
    URL_SAFE_NO_PAD.encode(format!("{}:{raw}", listing.tag()).as_bytes())
}

/// The form of a cursor: unpadded base64url (no length of 1 modulo 4).
pub const CURSOR_PATTERN: &str = "^([A-Za-z0-9_-]{4})*([A-Za-z0-9_-]{2,3})?$";

/// Decodes a cursor of `listing` into its position. A string of [`CURSOR_PATTERN`] decodes
/// (unused trailing bits allowed, bytes that are not UTF-8 read lossily), but only a cursor that
/// `listing` gave is a position in it; anything else, and any other string, is a 400.
pub fn decode(listing: Listing, cursor: &str) -> Result<String, ApiError> {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    const LENIENT: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::URL_SAFE,
        GeneralPurposeConfig::new()
            .with_decode_allow_trailing_bits(true)
            .with_decode_padding_mode(DecodePaddingMode::RequireNone),
    );
    let text = LENIENT
        .decode(cursor)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .map_err(|_| ApiError::bad_request("cursor: not unpadded base64url"))?;
    match text.split_once(':') {
        Some((tag, raw)) if tag == listing.tag() => Ok(raw.to_string()),
        Some((tag, _)) if ALL.iter().any(|l| l.tag() == tag) => {
            Err(ApiError::bad_request(format!(
                "cursor: it belongs to the {tag} listing, not to the {} listing; start without \
                 a cursor",
                listing.tag()
            )))
        }
        _ => Err(ApiError::bad_request(
            "cursor: not a next_cursor of this listing; start without a cursor",
        )),
    }
}

const ALL: [Listing; 6] = [
    Listing::Sites,
    Listing::Alerts,
    Listing::Epochs,
    Listing::Points,
    Listing::Groups,
    Listing::Series,
];

#[cfg(test)]
mod tests {
    use super::*;

    /// A cursor reads back as its position in its own listing only.
    #[test]
    fn a_cursor_belongs_to_its_listing() {
        for listing in ALL {
            for raw in ["", "T105", "2026-11-27T10:00:00.000000Z|a:b", "é|x"] {
                let c = encode(listing, raw);
                assert!(regex_lite_match(&c), "{c}");
                assert_eq!(
                    decode(listing, &c).map_err(|e| e.message),
                    Ok(raw.to_string())
                );
                for other in ALL.into_iter().filter(|o| *o != listing) {
                    let e = decode(other, &c).unwrap_err().message;
                    assert!(
                        e.contains(&format!("belongs to the {} listing", listing.tag())),
                        "{e}"
                    );
                }
            }
        }
        // schema-valid strings that no listing gave
        for forged in ["QUJD", "VDEwNQ", "", "AA"] {
            let e = decode(Listing::Points, forged).unwrap_err().message;
            assert!(e.starts_with("cursor: "), "{forged}: {e}");
        }
        assert!(decode(Listing::Points, "A").is_err());
    }

    /// `c` has the form of [`CURSOR_PATTERN`]: unpadded base64url, no length of 1 modulo 4.
    fn regex_lite_match(c: &str) -> bool {
        c.len() % 4 != 1
            && c.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
    }
}
