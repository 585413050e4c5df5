//! `GET /sites/{site}/report?from=&to=`: the campaign report of a site and period (dates or RFC
//! 3339 times; default: everything), one printable page (A4 print stylesheet): the face plan at
//! the period's last epoch, the displacement table with σ and significance, the plots of the
//! points that moved significantly (server-drawn SVG, so printing does not wait for scripts),
//! the epochs and the alert history of the period.

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};
use serde::Deserialize;

use super::layout::{level_badge, num, page, seg, with_sigma};
use super::local_time::{day_bound, when};
use super::page::{viewer, PageError};
use super::plan_svg::{face_plan, PlanPoint};
use super::time_plot_svg::time_plot;
use crate::analysis::{AlertLevel, PointRole};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::series::columns::unix_seconds;
use crate::store::sites::Site;
use crate::store::{alerts, displacements, epochs, points, Store};

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
    let site = super::page::site_or_404(state.store.reader(), &site_id).await?;
    let zone = site.time_zone.as_deref();
    let (from, to) = (
        bound(&period.from, false, zone)?,
        bound(&period.to, true, zone)?,
    );
    let r = Report::read(&state.store, site, from.as_deref(), to.as_deref()).await?;
    let v = viewer(access.as_deref());
    let s = seg(&r.site.id);
    let crumbs = [
        (r.site.name.clone(), format!("/sites/{s}")),
        ("report".to_string(), format!("/sites/{s}/report")),
    ];
    let title = format!("report {}", r.site.name);
    Ok(Html(page(&title, &crumbs, &v, r.render()).into_string()))
}

/// A `from` / `to` parameter as the stored time bound (`end`: the last instant of a date), a
/// date being a day of the site's zone `tz` ([`day_bound`]).
fn bound(s: &Option<String>, end: bool, tz: Option<&str>) -> Result<Option<String>, PageError> {
    s.as_deref()
        .filter(|s| !s.is_empty())
        .map(|s| day_bound(s, end, tz))
        .transpose()
        .map_err(PageError::bad_request)
}

/// What the report shows, read from the store.
struct Report {
    site: Site,
    /// The epochs of the period, newest first.
    epochs: Vec<epochs::EpochListItem>,
    /// Every point's role.
    roles: HashMap<String, PointRole>,
    /// Displacements at the period's last epoch, in natural order of the names.
    displacements: Vec<displacements::Displacement>,
    /// The face plan's points at the last epoch.
    plan: Vec<PlanPoint>,
    /// `(point, SVG)` of the points that moved significantly, the largest first.
    plots: Vec<(String, Markup)>,
    /// Alerts whose epoch lies in the period.
    history: Vec<alerts::Alert>,
}

impl Report {
    /// Reads the report of `site` between the stored time bounds `from` and `to`.
    async fn read(
        store: &Store,
        site: Site,
        from: Option<&str>,
        to: Option<&str>,
    ) -> Result<Report, PageError> {
        let db = store.reader();
        let until = to.map(|t| format!("{t}~"));
        let epochs: Vec<epochs::EpochListItem> =
            epochs::list(db, &site.id, until.as_deref(), 100_000)
                .await?
                .into_iter()
                .filter(|(raw, _)| from.is_none_or(|f| raw.as_str() >= f))
                .map(|(_, e)| e)
                .collect();
        let roles: HashMap<String, PointRole> = points::list(db, &site.id, None, 100_000)
            .await?
            .into_iter()
            .map(|p| (p.name, p.role))
            .collect();
        let (mut disp, coords) = match epochs.first() {
            Some(e) => (
                displacements::of_epoch(&mut *store.read().await?, &site.id, e.id).await?,
                points::epoch_coordinates(db, &site.id, e.id).await?,
            ),
            None => (vec![], vec![]),
        };
        disp.sort_by(|a, b| super::natural_order::natural_cmp(&a.point, &b.point));
        let plan = coords
            .iter()
            .map(|c| PlanPoint {
                name: c.point.clone(),
                xyz: c.xyz,
                d_mm: disp
                    .iter()
                    .find(|d| d.point == c.point)
                    .map(|d| [d.dx_mm, d.dy_mm, d.dz_mm]),
                level: None,
                stable: roles.get(&c.point) == Some(&PointRole::Stable),
                mdd_mm: disp
                    .iter()
                    .find(|d| d.point == c.point)
                    .and_then(|d| super::sensitivity::of(d, None, site.confidence))
                    .map(|m| m.worst_mm),
            })
            .collect();
        let plots = moving_plots(store, &site, &disp, &roles, from, to).await?;
        let history = alert_history(store, &site.id, from, to).await?;
        Ok(Report {
            site,
            epochs,
            roles,
            displacements: disp,
            plan,
            plots,
            history,
        })
    }

    /// The page's body.
    fn render(&self) -> Markup {
        let site = &self.site;
        let period = format!(
            "{} to {}",
            self.epochs.last().map_or("–", |e| e.observed_at.as_str()),
            self.epochs.first().map_or("–", |e| e.observed_at.as_str())
        );
        html! {
            article.report {
                h1 { "Campaign report · " (site.name) }
                p { "Site " (site.id) " · epochs " (period) " (" (self.epochs.len()) ") · confidence " (num(Some(site.confidence), 3))
                    " · generated " (chrono::Utc::now().format("%Y-%m-%d %H:%M UTC")) }
                section {
                    h2 { "Face plan at the last epoch" }
                    (face_plan(&site.id, &self.plan))
                }
                section {
                    h2 { "Displacements at the last epoch" }
                    (self.displacement_table())
                }
                section {
                    h2 { "Points that moved (d, ±2σ, thresholds)" }
                    @if self.plots.is_empty() { p.note { "No point moved significantly." } }
                    @for (name, plot) in &self.plots {
                        figure.moving { figcaption { (name) } (plot) }
                    }
                }
                section {
                    h2 { "Epochs" }
                    (self.epoch_table())
                }
                section {
                    h2 { "Alert history" }
                    @if self.history.is_empty() { p.note { "No alert in the period." } }
                    @else { (self.history_table()) }
                }
            }
        }
    }

    fn displacement_table(&self) -> Markup {
        let s = seg(&self.site.id);
        let role = |p: &str| self.roles.get(p).map_or("", |r| r.as_str());
        html! {
            table.displacements {
                thead { tr { th { "point" } th { "role" } th { "dx" } th { "dy" } th { "dz" } th { "d ± σ (mm)" } th { "significant" } th title="the smallest movement, in its worst direction, that this epoch detects 80 % of the time at the site's confidence" { "detects ≥ (mm)" } th { "velocity (mm/day)" } th { "time to failure (h)" } } }
                tbody { @for d in &self.displacements {
                    tr {
                        td { a href={ "/sites/" (s) "/points/" (seg(&d.point)) } { (d.point) } }
                        td { (role(&d.point)) }
                        td.num { (num(Some(d.dx_mm), 2)) }
                        td.num { (num(Some(d.dy_mm), 2)) }
                        td.num { (num(Some(d.dz_mm), 2)) }
                        td.num { (with_sigma(Some(d.d_mm), Some(d.sigma_mm), 2)) }
                        td { @if d.significant { "yes" } @else { "no" } }
                        td.num { (num(super::sensitivity::of(d, None, self.site.confidence).map(|m| m.worst_mm), 2)) }
                        td.num { (with_sigma(d.f_velocity_mm_per_day, d.sigma_f_velocity_mm_per_day, 3)) }
                        td.num { (with_sigma(d.f_time_to_failure_hours, d.sigma_f_time_to_failure_hours, 0)) }
                    }
                } }
            }
        }
    }

    fn epoch_table(&self) -> Markup {
        let zone = self.site.time_zone.as_deref();
        html! {
            table.epochs {
                thead { tr { th { "observed at" } th { "status" } th { "σ0 (mm)" } th { "c ± σ (mm)" } } }
                tbody { @for e in self.epochs.iter().rev() {
                    tr { td { (when(&e.observed_at, zone)) } td { (e.status) } td.num { (num(Some(e.sigma0_mm), 5)) } td.num { (with_sigma(e.c_mm, e.c_sigma_mm, 3)) } }
                } }
            }
        }
    }

    fn history_table(&self) -> Markup {
        let zone = self.site.time_zone.as_deref();
        html! {
            table.history {
                thead { tr { th { "level" } th { "subject" } th { "rule" } th { "value" } th { "epoch" } th { "state" } } }
                tbody { @for a in &self.history {
                    tr {
                        td { (level_badge(Some(a.level))) }
                        td { (a.point.clone().or(a.group.clone()).unwrap_or_else(|| "site".into())) }
                        td { (a.rule) }
                        td.num { (num(a.value, 2)) " " (a.unit.as_deref().unwrap_or("")) }
                        td { (when(a.observed_at.as_deref().unwrap_or(""), zone)) }
                        td { (a.state) @if let Some(by) = &a.acknowledged_by { " by " (by) } }
                    }
                } }
            }
        }
    }
}

/// The displacement plots (d with ±2σ and the site's displacement thresholds) of at most
/// [`PLOTS`] points that moved significantly at the last epoch, the largest first.
async fn moving_plots(
    store: &Store,
    site: &Site,
    disp: &[displacements::Displacement],
    roles: &HashMap<String, PointRole>,
    from: Option<&str>,
    to: Option<&str>,
) -> Result<Vec<(String, Markup)>, PageError> {
    let mut moving: Vec<&displacements::Displacement> = disp
        .iter()
        .filter(|d| d.significant && roles.get(&d.point) != Some(&PointRole::Stable))
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
    for d in moving {
        let series =
            displacements::series(store.reader(), &site.id, &d.point, from, to, None, None).await?;
        let t: Vec<f64> = series
            .iter()
            .map(|r| unix_seconds(r.observed_at.as_bytes()))
            .collect();
        let v: Vec<f64> = series.iter().map(|r| r.d_mm).collect();
        let s: Vec<f64> = series.iter().map(|r| r.sigma_mm).collect();
        plots.push((d.point.clone(), time_plot(&t, &v, &s, &thresholds, "mm")));
    }
    Ok(plots)
}

/// The site's alerts whose epoch was observed between `from` and `to`.
async fn alert_history(
    store: &Store,
    site: &str,
    from: Option<&str>,
    to: Option<&str>,
) -> Result<Vec<alerts::Alert>, PageError> {
    let t_from = from.map_or(f64::NEG_INFINITY, |f| unix_seconds(f.as_bytes()));
    let t_to = to.map_or(f64::INFINITY, |t| unix_seconds(t.as_bytes()));
    Ok(
        alerts::list(store.reader(), Some(site), None, None, 100_000)
            .await?
            .into_iter()
            .map(|(_, a)| a)
            .filter(|a| {
                a.observed_at
                    .as_deref()
                    .map(|o| unix_seconds(o.as_bytes()))
                    .is_some_and(|t| t >= t_from && t <= t_to)
            })
            .collect(),
    )
}
