//! The dashboard's static files, embedded in the binary: the vendored uPlot and htmx (see
//! `assets/vendor/README.md` for versions and licences), the stylesheet, the plot script and the
//! forms' error display.
//! Served under `/assets/{file}` with a content hash as ETag and a one-hour cache.

use axum::extract::Path;
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

/// `(file name, content type, bytes)` of every asset.
const ASSETS: [(&str, &str, &[u8]); 6] = [
    (
        "uPlot.iife.min.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/vendor/uPlot.iife.min.js"),
    ),
    (
        "uPlot.min.css",
        "text/css; charset=utf-8",
        include_bytes!("assets/vendor/uPlot.min.css"),
    ),
    (
        "htmx.min.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/vendor/htmx.min.js"),
    ),
    (
        "dashboard.css",
        "text/css; charset=utf-8",
        include_bytes!("assets/dashboard.css"),
    ),
    (
        "plots.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/plots.js"),
    ),
    (
        "forms.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/forms.js"),
    ),
];

/// `GET /assets/{file}`: the embedded file, 304 when the ETag matches, 404 for any other name.
pub async fn asset(Path(file): Path<String>, headers: HeaderMap) -> Response {
    let Some((_, mime, bytes)) = ASSETS.iter().find(|(name, _, _)| *name == file) else {
        return (StatusCode::NOT_FOUND, "no such asset").into_response();
    };
    let etag = format!("\"{}\"", &hex::encode(Sha256::digest(bytes))[..16]);
    let cache = (header::CACHE_CONTROL, "public, max-age=3600");
    if headers
        .get(header::IF_NONE_MATCH)
        .is_some_and(|v| v.as_bytes() == etag.as_bytes())
    {
        return (StatusCode::NOT_MODIFIED, [cache]).into_response();
    }
    let mut resp = (
        [(header::CONTENT_TYPE, *mime), cache],
        axum::body::Bytes::from_static(bytes),
    )
        .into_response();
    if let Ok(v) = HeaderValue::from_str(&etag) {
        resp.headers_mut().insert(header::ETAG, v);
    }
    resp
}
