//! `GET /sites/{site}/groups/{group}`: a block's page. Its latest motion (displacement ± σ,
//! velocity, time to failure and the forecast failure time), the motion series drawn against
//! time (3-D displacement, along its direction, filtered velocity, inverse velocity; server-drawn
//! SVG, missing values left out), how the forecast failure time moved epoch by epoch ("no
//! forecast yet" where its one-sided bound lies beyond a week), its member points with
//! links, and the open alerts of the block and of its members.

use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::html;

use super::headline::{bound_confidence_words, failure_time, FailureTime};
use super::layout::{level_badge, num, page, seg, time_to_failure, with_sigma};
use super::local_time::{text, when};
use super::page::{site_or_404, viewer, PageError};
use super::plot_data::{inverse_line, plotted_inverse};
use super::time_plot_svg::{time_plot, time_plot_with_line};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::displacements::Displacement;
use crate::store::series::columns::{unix_seconds, SeriesColumns};
use crate::store::{alerts, block_motions, groups, points};
use cliffwatch_core::analysis::AlertLevel;

/// Rows of the forecast history shown (the newest).
const FORECASTS_SHOWN: usize = 30;

/// The thresholds of the site's rules on `metric` that apply to `group` (value, level).
fn thresholds(rules: &[serde_json::Value], metric: &str, group: &str) -> Vec<(f64, AlertLevel)> {
    rules
        .iter()
        .filter(|r| r["metric"] == metric && (r["group"].is_null() || r["group"] == group))
        .filter_map(|r| {
            let v = r["above"].as_f64().or_else(|| r["below"].as_f64())?;
            Some((v, r["level"].as_str()?.parse().ok()?))
        })
        .collect()
}

/// The block page's query: which page of the forecast history (`forecasts_skip` newest rows
/// skipped, a multiple of [`FORECASTS_SHOWN`]).
#[derive(Debug, Default, serde::Deserialize)]
pub struct BlockQuery {
    /// Newest forecast rows to skip (older pages).
    pub forecasts_skip: Option<usize>,
}

/// The block page.
pub async fn block(
    State(state): State<AppState>,
    Path((site_id, group)): Path<(String, String)>,
    query: Result<Query<BlockQuery>, QueryRejection>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let skip = query
        .map_err(|e| PageError::bad_request(e.body_text()))?
        .0
        .forecasts_skip
        .unwrap_or(0);
    let db = state.store.reader();
    let site = site_or_404(db, &site_id).await?;
    let Some(g) = groups::get(db, &site.id, &group).await? else {
        return Err(PageError::not_found(format!(
            "no block '{group}' in site '{site_id}'"
        )));
    };
    let mut members: Vec<points::Point> = points::list(db, &site.id, None, 100_000)
        .await?
        .into_iter()
        .filter(|p| {
            g.points.contains(&p.name)
                || (g.points.is_empty() && p.group.as_deref() == Some(&g.name))
        })
        .collect();
    members.sort_by(|a, b| super::natural_order::natural_cmp(&a.name, &b.name));
    let levels = alerts::active_levels(db, &site.id).await?;
    let open: Vec<alerts::Alert> = alerts::list_active(db, &site.id, 500)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .filter(|a| {
            a.group.as_deref() == Some(&g.name)
                || a.point
                    .as_ref()
                    .is_some_and(|p| members.iter().any(|m| &m.name == p))
        })
        .collect();
    let level = open
        .iter()
        .filter(|a| a.group.as_deref() == Some(&g.name))
        .map(|a| a.level)
        .max();
    let rows: Vec<Displacement> =
        block_motions::series(db, &site.id, &g.name, None, None, None, None).await?;
    let tz = site.time_zone.as_deref();
    let t: Vec<f64> = rows
        .iter()
        .map(|r| unix_seconds(r.observed_at.as_bytes()))
        .collect();
    let col = |f: &dyn Fn(&Displacement) -> Option<f64>| -> Vec<f64> {
        rows.iter().map(|r| f(r).unwrap_or(f64::NAN)).collect()
    };
    let d = col(&|r| Some(r.d_mm));
    let sd = col(&|r| Some(r.sigma_mm));
    let along = col(&|r| r.d_along_mm);
    let v = col(&|r| r.f_velocity_mm_per_day);
    let sv = col(&|r| r.sigma_f_velocity_mm_per_day);
    let none = vec![f64::NAN; rows.len()];
    // The columns of the inverse velocity and its line, as on a point's plot.
    let columns = SeriesColumns {
        t: t.clone(),
        f_velocity: [v.clone(), sv.clone()],
        f_ttf: [
            col(&|r| r.f_time_to_failure_hours),
            col(&|r| r.sigma_f_time_to_failure_hours),
        ],
        ..SeriesColumns::default()
    };
    // 1/v ± 2σ where the block moves significantly forward (v > 2σ); elsewhere a gap.
    let (inv, sinv): (Vec<f64>, Vec<f64>) = (0..rows.len())
        .map(|k| plotted_inverse(&columns, k).unwrap_or((f64::NAN, f64::NAN)))
        .unzip();
    let fit = inverse_line(&columns);
    // Every epoch with a forecast; the failure time only where the pages state it.
    let history: Vec<(&Displacement, Option<FailureTime>)> = rows
        .iter()
        .filter(|r| {
            r.f_time_to_failure_hours
                .or(r.time_to_failure_hours)
                .is_some_and(f64::is_finite)
        })
        .map(|r| (r, failure_time(r)))
        .collect();
    let latest = rows.last();
    let (s, n) = (seg(&site.id), seg(&g.name));
    let site_href = format!("/sites/{s}");
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    let rules = &site.alert_rules;
    let incident = super::incident_panel::panel(
        db,
        &site.id,
        &crate::service::incidents::Subject::Block(g.name.clone()),
        &viewer(access.as_deref()),
    )
    .await?;
    let body = html! {
        h1 { "Block " (g.name) " " (level_badge(level)) }
        (headline)
        (incident)
        p {
            (members.len()) " member points"
            @if let Some(dir) = g.direction { " · direction [" (num(Some(dir[0]), 3)) ", " (num(Some(dir[1]), 3)) ", " (num(Some(dir[2]), 3)) "]" }
            " · " a href={ "/api/v1/sites/" (s) "/groups/" (n) "/motion?format=csv" } download { "CSV of the motion" }
        }
        @if let Some(r) = latest {
            table.latest {
                tr { th { "latest epoch" } td { a href={ (site_href) "/epochs/" (r.epoch) } { (when(&r.observed_at, tz)) } } }
                tr { th { "d (mm)" } td { (with_sigma(Some(r.d_mm), Some(r.sigma_mm), 2)) @if r.significant { " (significant)" } } }
                tr { th { "along the direction (mm)" } td { (num(r.d_along_mm, 2)) } }
                tr { th { "filtered velocity (mm/day)" } td { (with_sigma(r.f_velocity_mm_per_day, r.sigma_f_velocity_mm_per_day, 3)) } }
                tr { th { "filtered time to failure (h)" } td { (time_to_failure(r.f_time_to_failure_hours, r.sigma_f_time_to_failure_hours)) } }
                @if let Some(f) = failure_time(r) {
                    tr { th { "failure likely before" } td { strong { (text(f.likely_before, tz)) } " (" (bound_confidence_words()) ", one-sided), counted from this epoch" } }
                    tr { th { "forecast failure" } td { (text(f.at, tz)) " (±2σ: " (text(f.lower, tz)) " to " (text(f.upper, tz)) ")" } }
                } @else if r.f_time_to_failure_hours.is_some_and(f64::is_finite) {
                    tr { th { "forecast failure" } td { "no forecast yet: failure is not likely within a week by this epoch's forecast" } }
                }
            }
        } @else {
            p.note { "No motion yet: the block needs 2 measured members in an epoch after its reference." }
        }
        section #members {
            h2 { "Member points" }
            ul.members {
                @for p in &members {
                    li { a href={ (site_href) "/points/" (seg(&p.name)) } { (p.name) } " " (level_badge(levels.get(&p.name).copied())) }
                }
            }
        }
        section #block-alerts {
            h2 { "Open alerts of the block and its points" }
            @if open.is_empty() { p.note { "None." } }
            @else {
                ul { @for a in &open {
                    li { (level_badge(Some(a.level))) " "
                        @if let Some(p) = &a.point { "point " (p) } @else { "block " (g.name) }
                        " · " (super::layout::metric_name(&a.rule)) " · "
                        a href={ (site_href) "/alerts/" (seg(&a.id)) } { "history" } }
                } }
            }
        }
        @if !rows.is_empty() {
            section.block-plots {
                h2 { "Motion" }
                figure { figcaption { "3-D displacement d (mm), ±2σ" } (time_plot(&t, &d, &sd, &thresholds(rules, "displacement_mm", &g.name), "mm")) }
                @if g.direction.is_some() {
                    figure { figcaption { "displacement along the direction (mm)" } (time_plot(&t, &along, &none, &thresholds(rules, "displacement_along_mm", &g.name), "mm")) }
                }
                figure { figcaption { "filtered velocity (mm/day), ±2σ" } (time_plot(&t, &v, &sv, &thresholds(rules, "velocity_mm_per_day", &g.name), "mm/day")) }
                figure.inverse {
                    figcaption {
                        "inverse velocity 1/v (day/mm) of the filtered velocity, ±2σ, where the block moves significantly forward (v > 2σ)"
                        @if fit.is_some() { "; dashed: the latest forecast's law, fitted to the 1/v plotted over its last 12 epochs; its zero is the forecast failure time" }
                        @else { "; no line: the latest epoch has no forecast yet" }
                    }
                    (time_plot_with_line(&t, &inv, &sinv, &[], "day/mm", fit))
                }
            }
        }
        section #forecasts {
            h2 { "Forecast history" }
            @if history.is_empty() {
                p.note { "No epoch had a forecast: the block is not accelerating, or the inverse-velocity law does not fit." }
            } @else {
                p { "How the forecast failure time moved epoch by epoch (newest first; each counted from its own epoch): "
                    (history.len().min(skip + 1)) "–" (history.len().min(skip + FORECASTS_SHOWN)) " of " (history.len()) "." }
                table.forecasts {
                    thead { tr { th { "epoch" } th { "time to failure (h, ± 1σ)" } th { "failure likely before (" (bound_confidence_words()) ")" } th.wide { "forecast failure (±2σ)" } } }
                    tbody { @for (r, f) in history.iter().rev().skip(skip).take(FORECASTS_SHOWN) {
                        tr {
                            td { a href={ (site_href) "/epochs/" (r.epoch) } { (when(&r.observed_at, tz)) } }
                            @if r.f_time_to_failure_hours.is_some_and(f64::is_finite) {
                                td.num { (time_to_failure(r.f_time_to_failure_hours, r.sigma_f_time_to_failure_hours)) }
                            } @else {
                                td.num { (time_to_failure(r.time_to_failure_hours, r.time_to_failure_sigma_hours)) }
                            }
                            @if let Some(f) = f {
                                td { (text(f.likely_before, tz)) }
                                td.wide { (text(f.at, tz)) " (" (text(f.lower, tz)) " to " (text(f.upper, tz)) ")" }
                            } @else {
                                td { "no forecast yet" }
                                td.wide { "—" }
                            }
                        }
                    } }
                }
                p.pager {
                    @if skip > 0 { a href={ (site_href) "/groups/" (n) "?forecasts_skip=" (skip.saturating_sub(FORECASTS_SHOWN)) "#forecasts" } { "← newer forecasts" } " " }
                    @if skip + FORECASTS_SHOWN < history.len() { a.older href={ (site_href) "/groups/" (n) "?forecasts_skip=" (skip + FORECASTS_SHOWN) "#forecasts" } { "older forecasts →" } }
                }
            }
        }
    };
    let v = viewer(access.as_deref());
    let crumbs = [
        (site.name.clone(), site_href.clone()),
        (
            format!("block {}", g.name),
            format!("{site_href}/groups/{n}"),
        ),
    ];
    Ok(Html(
        page(&format!("Block {}", g.name), &crumbs, &v, body).into_string(),
    ))
}
