//! `GET /`: every site with its state at a glance: highest open alert level (colour and word),
//! last epoch and its time with an overdue badge, number of points; a retired site is marked so
//! (and never overdue).

use axum::extract::State;
use axum::response::Html;
use axum::Extension;
use maud::html;

use super::layout::{level_badge, page, seg};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::{alerts, epochs, points, sites};

/// The sites page.
pub async fn sites(
    State(state): State<AppState>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let db = state.store.reader();
    let all = sites::list(db, None, 10_000).await?;
    let now = chrono::Utc::now();
    let mut rows = vec![];
    for s in &all {
        let level = alerts::list_active(db, &s.id, 10_000)
            .await?
            .iter()
            .map(|(_, a)| a.level)
            .max();
        let last = epochs::list(db, &s.id, None, 1).await?.into_iter().next();
        let n_points = points::list(db, &s.id, None, 100_000).await?.len();
        // A retired site expects no more campaigns.
        let overdue = match (&last, s.schedule_hours.filter(|_| s.retired_at.is_none())) {
            (Some((_, e)), Some(h)) => chrono::DateTime::parse_from_rfc3339(&e.observed_at)
                .is_ok_and(|t| {
                    (now - t.with_timezone(&chrono::Utc)).num_seconds() as f64 > h * 3600.0
                }),
            _ => false,
        };
        rows.push((s, level, last.map(|(_, e)| e), n_points, overdue));
    }
    let v = viewer(access.as_deref());
    let body = html! {
        h1 { "Sites" }
        @if rows.is_empty() {
            p.note { "No site yet. Create one with " code { "POST /api/v1/sites" } "." }
        } @else {
            table.sites {
                thead { tr { th { "site" } th { "state" } th { "last epoch" } th { "points" } } }
                tbody {
                    @for (s, level, last, n, overdue) in &rows {
                        tr {
                            td {
                                a href={ "/sites/" (seg(&s.id)) } { (s.name) } " " small { (s.id) }
                                @if s.retired_at.is_some() { " " span.badge.retired { "retired" } }
                            }
                            td { (level_badge(*level)) }
                            td {
                                @if let Some(e) = last {
                                    a href={ "/sites/" (seg(&s.id)) "/epochs/" (e.id) } { (when(&e.observed_at, s.time_zone.as_deref())) }
                                } @else { "none yet" }
                                @if *overdue { " " span.badge.overdue { "overdue" } }
                            }
                            td.num { (n) }
                        }
                    }
                }
            }
        }
    };
    Ok(Html(page("Sites", &[], &v, body).into_string()))
}
