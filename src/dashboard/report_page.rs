//! `GET /sites/{site}/report?from=&to=`: the campaign report of a site and period (dates or RFC
//! 3339 times; default: everything), one printable page (A4 print stylesheet): the face plan at
//! the period's last epoch, the displacement table with σ and significance, the plots of the
//! points that moved significantly (server-drawn SVG, so printing does not wait for scripts),
//! the epochs and the alert history of the period.

use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::html;
use serde::Deserialize;

use super::layout::{level_badge, num, page, seg, with_sigma};
use super::local_time::when;
use super::plan_svg::{face_plan, PlanPoint};
use super::time_plot_svg::time_plot;
use super::{viewer, PageError};
use crate::analysis::{AlertLevel, PointRole};
use crate::api::auth::Access;
use crate::api::AppState;
use crate::store::series_columns::unix_seconds;
use crate::store::{alerts, displacements, epochs, points, sites};

/// The period of the report.
#[derive(Debug, Deserialize)]
pub struct Period {
    /// First day or time (inclusive).
    pub from: Option<String>,
    /// Last day or time (inclusive).
    pub to: Option<String>,
}

/// Plots at most this many moving points (the largest displacements first).
const PLOTS: usize = 12;

/// The campaign report.
pub async fn report(
    State(state): State<AppState>,
    Path(site_id): Path<String>,
    Query(period): Query<Period>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let bound = |s: &Option<String>, end: bool| -> Result<Option<String>, PageError> {
        s.as_deref()
            .filter(|s| !s.is_empty())
            .map(|s| crate::api::epochs::time_bound(s, end))
            .transpose()
            .map_err(|e| PageError::bad_request(e.message))
    };
    let (from, to) = (bound(&period.from, false)?, bound(&period.to, true)?);
    let db = state.store.reader();
    let Some(site) = sites::get(db, &site_id).await? else {
        return Err(PageError::not_found(format!("no site '{site_id}'")));
    };
    let in_period: Vec<epochs::EpochListItem> = epochs::list(
        db,
        &site.id,
        to.as_deref().map(|t| format!("{t}~")).as_deref(),
        100_000,
    )
    .await?
    .into_iter()
    .filter(|(raw, _)| from.as_deref().is_none_or(|f| raw.as_str() >= f))
    .map(|(_, e)| e)
    .collect();
    let pts = points::list(db, &site.id, None, 100_000).await?;
    let last = in_period.first();
    let (mut disp, coords) = match last {
        Some(e) => (
            displacements::of_epoch(&mut *state.store.read().await?, &site.id, e.id).await?,
            points::epoch_coordinates(db, &site.id, e.id).await?,
        ),
        None => (vec![], vec![]),
    };
    disp.sort_by(|a, b| super::natural_order::natural_cmp(&a.point, &b.point));
    let role = |name: &str| pts.iter().find(|p| p.name == name).map(|p| p.role);
    let plan: Vec<PlanPoint> = coords
        .iter()
        .map(|c| PlanPoint {
            name: c.point.clone(),
            xyz: c.xyz,
            d_mm: disp
                .iter()
                .find(|d| d.point == c.point)
                .map(|d| [d.dx_mm, d.dy_mm, d.dz_mm]),
            level: None,
            stable: role(&c.point) == Some(PointRole::Stable),
        })
        .collect();
    let mut moving: Vec<&displacements::Displacement> = disp
        .iter()
        .filter(|d| d.significant && role(&d.point) != Some(PointRole::Stable))
        .collect();
    moving.sort_by(|a, b| b.d_mm.total_cmp(&a.d_mm));
    moving.truncate(PLOTS);
    let thresholds: Vec<(f64, AlertLevel)> = site
        .alert_rules
        .iter()
        .filter(|r| r["metric"] == "displacement_mm" && r["group"].is_null())
        .filter_map(|r| Some((r["above"].as_f64()?, r["level"].as_str()?.parse().ok()?)))
        .collect();
    let mut plots = vec![];
    for d in &moving {
        let series = displacements::series(
            db,
            &site.id,
            &d.point,
            from.as_deref(),
            to.as_deref(),
            None,
            None,
        )
        .await?;
        let t: Vec<f64> = series
            .iter()
            .map(|r| unix_seconds(r.observed_at.as_bytes()))
            .collect();
        let v: Vec<f64> = series.iter().map(|r| r.d_mm).collect();
        let s: Vec<f64> = series.iter().map(|r| r.sigma_mm).collect();
        plots.push((d.point.clone(), time_plot(&t, &v, &s, &thresholds, "mm")));
    }
    let (t_from, t_to) = (
        from.as_deref()
            .map_or(f64::NEG_INFINITY, |f| unix_seconds(f.as_bytes())),
        to.as_deref()
            .map_or(f64::INFINITY, |t| unix_seconds(t.as_bytes())),
    );
    let history: Vec<alerts::Alert> = alerts::list(db, Some(&site.id), None, None, 100_000)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .filter(|a| {
            a.observed_at
                .as_deref()
                .map(|o| unix_seconds(o.as_bytes()))
                .is_some_and(|t| t >= t_from && t <= t_to)
        })
        .collect();
    let period_text = format!(
        "{} to {}",
        in_period.last().map_or("–", |e| e.observed_at.as_str()),
        last.map_or("–", |e| e.observed_at.as_str())
    );
    let v = viewer(access.as_deref());
    let s = seg(&site.id);
    let body = html! {
        article.report {
            h1 { "Campaign report · " (site.name) }
            p { "Site " (site.id) " · epochs " (period_text) " (" (in_period.len()) ") · confidence " (num(Some(site.confidence), 3))
                " · generated " (chrono::Utc::now().format("%Y-%m-%d %H:%M UTC")) }
            section {
                h2 { "Face plan at the last epoch" }
                (face_plan(&site.id, &plan))
            }
            section {
                h2 { "Displacements at the last epoch" }
                table.displacements {
                    thead { tr { th { "point" } th { "role" } th { "dx" } th { "dy" } th { "dz" } th { "d ± σ (mm)" } th { "significant" } th { "velocity (mm/day)" } th { "time to failure (h)" } } }
                    tbody { @for d in &disp {
                        tr {
                            td { a href={ "/sites/" (s) "/points/" (seg(&d.point)) } { (d.point) } }
                            td { (role(&d.point).map_or("", PointRole::as_str)) }
                            td.num { (num(Some(d.dx_mm), 2)) }
                            td.num { (num(Some(d.dy_mm), 2)) }
                            td.num { (num(Some(d.dz_mm), 2)) }
                            td.num { (with_sigma(Some(d.d_mm), Some(d.sigma_mm), 2)) }
                            td { @if d.significant { "yes" } @else { "no" } }
                            td.num { (with_sigma(d.f_velocity_mm_per_day, d.sigma_f_velocity_mm_per_day, 3)) }
                            td.num { (with_sigma(d.f_time_to_failure_hours, d.sigma_f_time_to_failure_hours, 0)) }
                        }
                    } }
                }
            }
            section {
                h2 { "Points that moved (d, ±2σ, thresholds)" }
                @if plots.is_empty() { p.note { "No point moved significantly." } }
                @for (name, plot) in &plots {
                    figure.moving { figcaption { (name) } (plot) }
                }
            }
            section {
                h2 { "Epochs" }
                table.epochs {
                    thead { tr { th { "observed at" } th { "status" } th { "σ0 (mm)" } th { "c ± σ (mm)" } } }
                    tbody { @for e in in_period.iter().rev() {
                        tr { td { (when(&e.observed_at, site.time_zone.as_deref())) } td { (e.status) } td.num { (num(Some(e.sigma0_mm), 5)) } td.num { (with_sigma(e.c_mm, e.c_sigma_mm, 3)) } }
                    } }
                }
            }
            section {
                h2 { "Alert history" }
                @if history.is_empty() { p.note { "No alert in the period." } }
                @else {
                    table.history {
                        thead { tr { th { "level" } th { "subject" } th { "rule" } th { "value" } th { "epoch" } th { "state" } } }
                        tbody { @for a in &history {
                            tr {
                                td { (level_badge(Some(a.level))) }
                                td { (a.point.clone().or(a.group.clone()).unwrap_or_else(|| "site".into())) }
                                td { (a.rule) }
                                td.num { (num(a.value, 2)) " " (a.unit.as_deref().unwrap_or("")) }
                                td { (when(a.observed_at.as_deref().unwrap_or(""), site.time_zone.as_deref())) }
                                td { (a.state) @if let Some(by) = &a.acknowledged_by { " by " (by) } }
                            }
                        } }
                    }
                }
            }
        }
    };
    let crumbs = [
        (site.name.clone(), format!("/sites/{s}")),
        ("report".to_string(), format!("/sites/{s}/report")),
    ];
    Ok(Html(
        page(&format!("report {}", site.name), &crumbs, &v, body).into_string(),
    ))
}
