//! What every page handler shares: the error page, the site and epoch of a path, the viewer.

use axum::http::StatusCode;
use axum::response::{Html, IntoResponse, Response};
use maud::html;

use super::layout;
use crate::store::epoch_report::EpochReport;
use crate::store::epochs::{self, EpochListItem};
use crate::store::{sites, ReadPool, StoreError};

/// A page that cannot be shown: an HTML page with the status and a plain message.
#[derive(Debug)]
pub struct PageError {
    status: StatusCode,
    message: String,
}

impl PageError {
    /// 400 with `message`.
    pub fn bad_request(message: impl Into<String>) -> Self {
        PageError {
            status: StatusCode::BAD_REQUEST,
            message: message.into(),
        }
    }

    /// 404 with `message`.
    pub fn not_found(message: impl Into<String>) -> Self {
        PageError {
            status: StatusCode::NOT_FOUND,
            message: message.into(),
        }
    }

    /// 500 with `message` (also logged).
    pub fn internal(message: impl Into<String>) -> Self {
        let message = message.into();
        tracing::error!(error = %message, "dashboard");
        PageError {
            status: StatusCode::INTERNAL_SERVER_ERROR,
            message,
        }
    }
}

impl From<crate::service::ServiceError> for PageError {
    fn from(e: crate::service::ServiceError) -> Self {
        let e = crate::http::error::ApiError::from(e);
        PageError {
            status: e.status,
            message: e.message,
        }
    }
}

impl From<StoreError> for PageError {
    fn from(e: StoreError) -> Self {
        tracing::error!(error = %e, "dashboard: database read failed");
        PageError {
            status: StatusCode::INTERNAL_SERVER_ERROR,
            message: "the database could not be read; see the service log".into(),
        }
    }
}

impl IntoResponse for PageError {
    fn into_response(self) -> Response {
        let body = layout::page(
            self.status.canonical_reason().unwrap_or("error"),
            &[],
            &layout::Viewer::default(),
            html! { h1 { (self.status.as_u16()) " " (self.status.canonical_reason().unwrap_or("")) } p { (self.message) } },
        );
        (self.status, Html(body.into_string())).into_response()
    }
}

/// The site `site_id`, or the 404 page naming it.
pub(crate) async fn site_or_404(
    db: &crate::store::ReadPool,
    site_id: &str,
) -> Result<crate::store::sites::Site, PageError> {
    crate::store::sites::get(db, site_id)
        .await?
        .ok_or_else(|| PageError::not_found(format!("no site '{site_id}'")))
}

/// The viewer of a request as the auth middleware let it in.
pub fn viewer(access: Option<&crate::http::auth::Access>) -> layout::Viewer {
    let a = access.cloned().unwrap_or_default();
    layout::Viewer {
        can_acknowledge: a.allows(crate::config::Role::Upload),
        can_administer: a.allows(crate::config::Role::Admin),
        signed_in: a.cookie,
        csrf: a.csrf,
    }
}

/// The site `site_id` and its epoch `epoch` (id as in the URL) with the epoch's list item and
/// report; 404 naming what is missing.
pub(super) async fn load_epoch(
    db: &ReadPool,
    site_id: &str,
    epoch: &str,
) -> Result<(sites::Site, i64, EpochListItem, EpochReport), PageError> {
    let site = site_or_404(db, site_id).await?;
    let Ok(id) = epoch.parse::<i64>() else {
        return Err(PageError::not_found(format!("no epoch '{epoch}'")));
    };
    let Some((item, report)) = epochs::get(db, &site.id, id).await? else {
        return Err(PageError::not_found(format!(
            "no epoch {id} in site '{site_id}'"
        )));
    };
    Ok((site, id, item, report))
}
