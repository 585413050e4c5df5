//! `GET /sites/{site}`: the face plan, the alerts one row per subject with acknowledgement (open
//! ones by default; filtered by level, state and subject, [`super::alert_filter`];
//! [`super::alert_groups`]), the epochs (time, σ0, c ± σ,
//! dropped observations) and a table of the points (latest displacement ± σ, significance,
//! velocity, time to failure); the settings form for an administrator ([`super::site_edit`])
//! and the latest changes ([`super::audit_trail`]).

use std::collections::HashMap;

use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};

use super::alert_filter::{AlertFilter, AlertQuery};
use super::layout::{level_badge, num, page, seg, time_to_failure, with_sigma, Viewer};
use super::local_time::when;
use super::page::{viewer, PageError};
use super::plan_svg::{face_plan, PlanPoint};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::{alerts, displacements, epochs, points};
use cliffwatch_core::analysis::{AlertLevel, PointRole};

/// Epochs listed on the site page (newest first).
const EPOCHS_SHOWN: i64 = 30;

/// Alerts read for the alert table (newest first), before the filter.
const ALERTS_READ: i64 = 500;

/// The site page.
pub async fn site(
    State(state): State<AppState>,
    Path(site_id): Path<String>,
    query: Result<Query<AlertQuery>, QueryRejection>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let query = query.map_err(|e| PageError::bad_request(e.body_text()))?;
    let filter = AlertFilter::parse(&query.0).map_err(PageError::bad_request)?;
    let db = state.store.reader();
    let site = super::page::site_or_404(db, &site_id).await?;
    let mut pts = points::list(db, &site.id, None, 100_000).await?;
    pts.sort_by(|a, b| super::natural_order::natural_cmp(&a.name, &b.name));
    let coords = points::latest_coordinates(&mut *state.store.read().await?, &site.id).await?;
    let latest: HashMap<String, displacements::Displacement> =
        displacements::latest(&mut *state.store.read().await?, &site.id)
            .await?
            .into_iter()
            .map(|d| (d.point.clone(), d))
            .collect();
    let levels = alerts::active_levels(db, &site.id).await?;
    let roles: HashMap<&str, PointRole> = pts.iter().map(|p| (p.name.as_str(), p.role)).collect();
    let plan: Vec<PlanPoint> = coords
        .iter()
        .map(|c| PlanPoint {
            name: c.point.clone(),
            xyz: c.xyz,
            d_mm: latest.get(&c.point).map(|d| [d.dx_mm, d.dy_mm, d.dz_mm]),
            level: levels.get(&c.point).copied(),
            stable: roles.get(c.point.as_str()) == Some(&PointRole::Stable),
            mdd_mm: latest
                .get(&c.point)
                .and_then(|d| super::sensitivity::of(d, None, site.confidence))
                .map(|m| m.worst_mm),
        })
        .collect();
    let after = filter
        .before
        .as_ref()
        .map(|(t, id)| (t.as_str(), id.as_str()));
    let read = if filter.is_active() {
        alerts::list_active_after(db, &site.id, after, ALERTS_READ).await?
    } else {
        alerts::list(db, Some(&site.id), filter.store_state(), after, ALERTS_READ).await?
    };
    let older_alerts = (read.len() as i64 == ALERTS_READ)
        .then(|| read.last().map(|(t, a)| filter.older_query(t, &a.id)))
        .flatten();
    let shown: Vec<alerts::Alert> = read
        .into_iter()
        .map(|(_, a)| a)
        .filter(|a| filter.matches(a))
        .collect();
    let before = match query.0.epochs_before.as_deref() {
        Some(b) => Some(
            crate::store::parse_timestamp(b)
                .map(crate::store::timestamp)
                .ok_or_else(|| {
                    PageError::bad_request(format!(
                        "epochs_before '{}' is not an RFC 3339 time",
                        b.chars().take(40).collect::<String>()
                    ))
                })?,
        ),
        None => None,
    };
    let mut epoch_rows: Vec<_> = epochs::list(db, &site.id, before.as_deref(), EPOCHS_SHOWN + 1)
        .await?
        .into_iter()
        .collect();
    // The cursor of the next page: the oldest epoch shown, when there are older ones.
    let older = (epoch_rows.len() as i64 > EPOCHS_SHOWN).then(|| {
        epoch_rows.truncate(EPOCHS_SHOWN as usize);
        epoch_rows.last().map(|(cursor, _)| cursor.clone())
    });
    let epoch_page = EpochPage {
        rows: epoch_rows.into_iter().map(|(_, e)| e).collect(),
        older: older.flatten(),
        paged: before.is_some(),
    };
    let v = viewer(access.as_deref());
    let site_href = format!("/sites/{}", seg(&site.id));
    let tz = site.time_zone.as_deref();
    let mut blocks = crate::store::groups::list(db, &site.id).await?;
    blocks.sort_by(|a, b| super::natural_order::natural_cmp(&a.name, &b.name));
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    let health = health_section(&state, &site).await?;
    let changes =
        crate::store::audit::list(db, &site.id, None, super::audit_trail::ON_SITE_PAGE).await?;
    let configured = state.config.sites.iter().any(|s| s.id == site.id);
    let body = html! {
        h1 { (site.name) " " small { (site.id) } }
        (headline)
        p {
            a href={ (site_href) "/report" } { "Campaign report" } " (printable; add " code { "?from=YYYY-MM-DD&to=YYYY-MM-DD" } " for a period) · "
            a href={ (site_href) "/plan" } { "Campaign design" } " (the network's pre-analysis beside what it achieved) · "
            a href={ "/api/v1/cap/feed.atom?site=" (seg(&site.id)) } { "public-warning feed (CAP 1.2, Atom)" }
            @if let Some(z) = tz { " · times in UTC and " (z) }
        }
        @if !blocks.is_empty() {
            p.blocks { "Blocks: " @for (i, b) in blocks.iter().enumerate() {
                @if i > 0 { ", " } a href={ (site_href) "/groups/" (seg(&b.name)) } { (b.name) }
            } }
        }
        section {
            h2 { "Face plan" }
            (face_plan(&site.id, &site.frame, &plan))
        }
        (alerts_section(&filter, &shown, &crate::service::incidents::block_of(&blocks, &pts), older_alerts.as_deref(), &v, &site_href, tz))
        (points_table(&pts, &latest, &levels, &site_href))
        (health)
        (epochs_table(&epoch_page, &site_href, tz))
        (super::site_edit::section(&site, &v, configured))
        (super::audit_trail::section(&site_href, &changes, tz))
    };
    let crumbs = [(site.name.clone(), site_href.clone())];
    Ok(Html(page(&site.name, &crumbs, &v, body).into_string()))
}

/// Epochs the health plot draws (the newest).
const HEALTH_EPOCHS: i64 = 100;

/// The adjustment-health section ([`super::health`]): the newest [`HEALTH_EPOCHS`] epochs'
/// variance factors and the cameras' σ estimated from the recent ones.
async fn health_section(
    state: &AppState,
    site: &crate::store::sites::Site,
) -> Result<Markup, PageError> {
    let db = state.store.reader();
    let rows: Vec<epochs::EpochListItem> = epochs::list(db, &site.id, None, HEALTH_EPOCHS)
        .await?
        .into_iter()
        .map(|(_, e)| e)
        .collect();
    let sigma = crate::service::apriori_sigma::of_site(&state.store, &site.id).await?;
    Ok(super::health::section(&super::health::Health {
        epochs: &rows,
        estimate: &sigma.estimate,
        used: &sigma.used,
        first_step: sigma.first_step,
        setting: site.apriori_sigma,
    }))
}

/// The alerts matching `filter`, one row per subject ([`super::alert_groups`]; `block_of`: the
/// declared block of each point in one), each alert with its acknowledgement form where `v` may
/// acknowledge; `older`: the query of the next page when this page's [`ALERTS_READ`] alerts
/// were not all of them.
fn alerts_section(
    filter: &AlertFilter,
    shown: &[alerts::Alert],
    block_of: &HashMap<String, String>,
    older: Option<&str>,
    v: &Viewer,
    site_href: &str,
    tz: Option<&str>,
) -> Markup {
    html! {
        section #alerts {
            h2 { (filter.heading()) }
            (filter.form(site_href))
            @if shown.is_empty() {
                p.note { "No alert matches." }
            } @else {
                (super::alert_groups::table(&crate::service::incidents::group(shown, block_of), v, &shown[0].site, site_href, tz))
            }
            @if let Some(q) = older {
                p.pager { "This page searched " (ALERTS_READ) " alerts of this state; older ones may match: "
                    a.older href={ (site_href) "?" (q) "#alerts" } { "older alerts →" } }
            }
            @if filter.before.is_some() {
                p.pager { a href={ (site_href) "?" (filter.newest_query()) "#alerts" } { "← newest alerts" } }
            }
        }
    }
}

/// Every point with its role, alert level and latest displacement (mm ± σ), significance,
/// velocity (mm/day, filtered where available) and time to failure (h).
fn points_table(
    pts: &[points::Point],
    latest: &HashMap<String, displacements::Displacement>,
    levels: &HashMap<String, AlertLevel>,
    site_href: &str,
) -> Markup {
    html! {
        section {
            h2 { "Points" }
            table.points {
                thead { tr {
                    th { "point" } th.wide { "role" } th { "state" } th { "d (mm) ± σ" } th.wide { "significant" }
                    th { "velocity (mm/day)" } th { "time to failure (h)" }
                } }
                tbody {
                    @for p in pts {
                        @let d = latest.get(&p.name);
                        tr {
                            td { a href={ (site_href) "/points/" (seg(&p.name)) } { (p.name) } }
                            td.wide { (p.role) @if let Some(g) = &p.group { " · " a href={ (site_href) "/groups/" (seg(g)) } { (g) } } }
                            td { (level_badge(levels.get(&p.name).copied())) }
                            td.num { (with_sigma(d.map(|d| d.d_mm), d.map(|d| d.sigma_mm), 2)) }
                            td.wide { @if d.is_some_and(|d| d.significant) { "yes" } @else { "no" } }
                            td.num { (with_sigma(d.and_then(|d| d.f_velocity_mm_per_day.or(d.velocity_mm_per_day)), d.and_then(|d| d.sigma_f_velocity_mm_per_day), 3)) }
                            td.num { (time_to_failure(d.and_then(|d| d.f_time_to_failure_hours), d.and_then(|d| d.sigma_f_time_to_failure_hours))) }
                        }
                    }
                }
            }
        }
    }
}

/// One page of the epochs table (newest first).
struct EpochPage {
    /// The epochs shown.
    rows: Vec<epochs::EpochListItem>,
    /// The cursor of the next, older page (the oldest shown epoch's stored time), if any.
    older: Option<String>,
    /// Whether this is an older page (then it links back to the newest).
    paged: bool,
}

/// A page of epochs: time (UTC and `tz`), status, σ0 (mm), c ± σ (mm), iterations and dropped
/// observations, each linked to its epoch page; links to older epochs, back to the first.
fn epochs_table(page: &EpochPage, site_href: &str, tz: Option<&str>) -> Markup {
    let epochs = &page.rows;
    html! {
        section #epochs {
            h2 { "Epochs" }
            @if page.paged { p.pager { a href={ (site_href) "#epochs" } { "← newest epochs" } } }
            table.epochs {
                thead { tr { th { "observed at" } th { "status" } th.wide { "σ0 (mm)" } th { "c ± σ (mm)" } th.wide { "iterations" } th.wide { "dropped" } } }
                tbody {
                    @for e in epochs {
                        tr {
                            td { a href={ (site_href) "/epochs/" (e.id) } { (when(&e.observed_at, tz)) } }
                            td { (e.status) }
                            td.num.wide { (num(Some(e.sigma0_mm), 5)) }
                            td.num { (with_sigma(e.c_mm, e.c_sigma_mm, 3)) }
                            td.num.wide { (e.iterations) }
                            td.num.wide { (e.dropped_observations) }
                        }
                    }
                }
            }
            @if let Some(cursor) = &page.older {
                p.pager { a.older href={ (site_href) "?epochs_before=" (seg(cursor)) "#epochs" } { "older epochs →" } }
            } @else if !epochs.is_empty() {
                p.note { "The first epoch of the site is the last row." }
            }
        }
    }
}
