//! `GET /sites/{site}/report?from=&to=`: the campaign report of a site and period (dates or RFC
//! 3339 times; default: everything), printable on A4 (at most three pages for a site of ≤ 30
//! points): the headline, the face plan with alert colours at the period's last epoch, each
//! block's motion, velocity, time to failure and forecast failure date, the displacement table,
//! the plots of the blocks and of the points that moved most (server-drawn SVG, so printing does
//! not wait for scripts), the epochs with their adjustment's health and the alert history with
//! the epoch that raised each alert ([`super::report_sections`]), and the changes of the site's
//! settings made in the period ([`super::audit_trail`]).

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};
use serde::Deserialize;

use super::layout::{num, page, seg};
use super::local_time::day_bound;
use super::page::{viewer, PageError};
use super::plan_svg::{face_plan, PlanPoint};
use super::report_sections::{self as sections, BlockRow};
use super::time_plot_svg::time_plot;
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::series::columns::unix_seconds;
use crate::store::sites::Site;
use crate::store::{alerts, block_motions, displacements, epochs, groups, points, Store};
use cliffwatch_core::analysis::{AlertLevel, PointRole};

/// The period of the report.
#[derive(Debug, Deserialize)]
pub struct Period {
    /// First day or time (inclusive).
    pub from: Option<String>,
    /// Last day or time (inclusive).
    pub to: Option<String>,
}

/// Quotes at most this many changes of the settings.
const CHANGES: i64 = 50;

/// Plots at most this many subjects: the blocks, then the points outside them that moved most.
const PLOTS: usize = 4;

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
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    let r = Report::read(&state.store, site, from.as_deref(), to.as_deref(), headline).await?;
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
    /// Whether the plan's colours are the open alerts' (the period reaches the latest epoch) or
    /// the highest levels the period's alerts reached.
    plan_levels_now: bool,
    /// The blocks and their motion at the period's last epoch.
    blocks: Vec<BlockRow>,
    /// `(subject, SVG)`: the blocks' displacement, then the points that moved most.
    plots: Vec<(String, Markup)>,
    /// The site's headline (worst open alert, last epoch's age, response and contacts).
    headline: Markup,
    /// The period's epochs adjusted with cameras' σ estimated from earlier epochs, with them.
    estimated_sigma: Vec<(
        i64,
        Vec<cliffwatch_core::photogrammetry::statistics::variance_components::PooledSigma>,
    )>,
    /// Alerts whose epoch lies in the period.
    history: Vec<alerts::Alert>,
    /// The changes of the site's settings made in the period, oldest first.
    changes: Vec<crate::store::audit::AuditEntry>,
}

impl Report {
    /// Reads the report of `site` between the stored time bounds `from` and `to`.
    async fn read(
        store: &Store,
        site: Site,
        from: Option<&str>,
        to: Option<&str>,
        headline: Markup,
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
        let history = alert_history(store, &site.id, from, to).await?;
        let changes = crate::store::audit::between(db, &site.id, from, to, CHANGES).await?;
        let latest_epoch = epochs::list(db, &site.id, None, 1).await?;
        let plan_levels_now = match (latest_epoch.first(), epochs.first()) {
            (Some((_, newest)), Some(last)) => newest.id == last.id,
            _ => true,
        };
        let levels: HashMap<String, AlertLevel> = if plan_levels_now {
            alerts::active_levels(db, &site.id).await?
        } else {
            let mut peak: HashMap<String, AlertLevel> = HashMap::new();
            for a in &history {
                let subjects = a.point.iter().chain(a.points.iter());
                for p in subjects {
                    let e = peak.entry(p.clone()).or_insert(a.peak_level);
                    *e = (*e).max(a.peak_level);
                }
            }
            peak
        };
        let all_points = points::list(db, &site.id, None, 100_000).await?;
        let mut blocks = Vec::new();
        let mut in_blocks: Vec<String> = Vec::new();
        for g in groups::list(db, &site.id).await? {
            let names: Vec<String> = all_points
                .iter()
                .filter(|p| {
                    g.points.contains(&p.name)
                        || (g.points.is_empty() && p.group.as_deref() == Some(&g.name))
                })
                .map(|p| p.name.clone())
                .collect();
            let members = names.len();
            in_blocks.extend(names);
            let latest = block_motions::series(db, &site.id, &g.name, from, to, None, None)
                .await?
                .pop();
            blocks.push(BlockRow {
                name: g.name.clone(),
                members,
                latest,
            });
        }
        blocks.sort_by(|a, b| super::natural_order::natural_cmp(&a.name, &b.name));
        let plan = coords
            .iter()
            .map(|c| PlanPoint {
                name: c.point.clone(),
                xyz: c.xyz,
                d_mm: disp
                    .iter()
                    .find(|d| d.point == c.point)
                    .map(|d| [d.dx_mm, d.dy_mm, d.dz_mm]),
                level: levels.get(&c.point).copied(),
                stable: roles.get(&c.point) == Some(&PointRole::Stable),
                mdd_mm: disp
                    .iter()
                    .find(|d| d.point == c.point)
                    .and_then(|d| super::sensitivity::of(d, None, site.confidence))
                    .map(|m| m.worst_mm),
            })
            .collect();
        let plots = plots(store, &site, &blocks, &disp, &roles, &in_blocks, from, to).await?;
        let estimated_sigma = crate::store::epoch_health::estimated_sigma_epochs(
            db,
            &site.id,
            from,
            until.as_deref(),
        )
        .await?;
        Ok(Report {
            site,
            epochs,
            roles,
            displacements: disp,
            plan,
            plan_levels_now,
            blocks,
            plots,
            headline,
            estimated_sigma,
            history,
            changes,
        })
    }

    /// The page's body.
    fn render(&self) -> Markup {
        let site = &self.site;
        let tz = site.time_zone.as_deref();
        let period = format!(
            "{} to {}",
            self.epochs.last().map_or("–", |e| e.observed_at.as_str()),
            self.epochs.first().map_or("–", |e| e.observed_at.as_str())
        );
        let role = |p: &str| self.roles.get(p).map_or("", |r| r.as_str());
        let mdd = |d: &displacements::Displacement| {
            super::sensitivity::of(d, None, site.confidence).map(|m| m.worst_mm)
        };
        html! {
            article.report {
                h1 { "Campaign report · " (site.name) }
                p.meta { "Site " (site.id) " · epochs " (period) " (" (self.epochs.len()) ") · confidence " (num(Some(site.confidence), 3))
                    @if let Some(z) = tz { " · times in UTC and " (z) }
                    " · generated " (chrono::Utc::now().format("%Y-%m-%d %H:%M UTC")) }
                (self.headline)
                section.plan {
                    h2 { "Face plan at the last epoch" }
                    p.note { @if self.plan_levels_now { "Colours: the open alerts' levels." } @else { "Colours: the highest level each point's alerts reached in the period." } }
                    (face_plan(&site.id, &site.frame, &self.plan))
                }
                @if !self.blocks.is_empty() {
                    section {
                        h2 { "Blocks at the last epoch" }
                        (sections::blocks(&site.id, &self.blocks, tz))
                        p.note { "A time to failure counts from the epoch it was computed at, not from when this report was printed." }
                    }
                }
                section {
                    h2 { "Displacements at the last epoch" }
                    (sections::displacements(&site.id, &self.displacements, &role, &mdd))
                }
                section {
                    h2 { "Displacement against time (d, ±2σ, thresholds)" }
                    @if self.plots.is_empty() { p.note { "No block and no point moved significantly." } }
                    div.report-plots {
                        @for (name, plot) in &self.plots {
                            figure.moving { figcaption { (name) } (plot) }
                        }
                    }
                }
                section {
                    h2 { "Epochs and the adjustment's health" }
                    (sections::epochs(&self.epochs, tz))
                    (sections::sigma_used(&self.estimated_sigma, self.epochs.len()))
                }
                section {
                    h2 { "Alert history" }
                    @if self.history.is_empty() { p.note { "No alert in the period." } }
                    @else { (sections::history(&self.history, tz)) }
                }
                section.changes {
                    h2 { "Changes of the settings in the period" }
                    @if self.changes.is_empty() { p.note { "No change of the site's settings in the period." } }
                    @else {
                        (super::audit_trail::table(&self.changes, tz))
                        @if self.changes.len() as i64 == CHANGES {
                            p.note { "The first " (CHANGES) " changes; every one: " a href={ "/sites/" (seg(&site.id)) "/audit" } { "the site's changes" } "." }
                        }
                    }
                }
            }
        }
    }
}

/// The displacement plots (d with ±2σ and the site's displacement thresholds), at most
/// [`PLOTS`]: each block's motion, then the points outside blocks that moved significantly at
/// the last epoch, the largest first.
#[allow(clippy::too_many_arguments)]
async fn plots(
    store: &Store,
    site: &Site,
    blocks: &[BlockRow],
    disp: &[displacements::Displacement],
    roles: &HashMap<String, PointRole>,
    in_blocks: &[String],
    from: Option<&str>,
    to: Option<&str>,
) -> Result<Vec<(String, Markup)>, PageError> {
    let thresholds = |group: Option<&str>| -> Vec<(f64, AlertLevel)> {
        site.alert_rules
            .iter()
            .filter(|r| {
                r["metric"] == "displacement_mm"
                    && (r["group"].is_null() || group.is_some_and(|g| r["group"] == g))
            })
            .filter_map(|r| Some((r["above"].as_f64()?, r["level"].as_str()?.parse().ok()?)))
            .collect()
    };
    let draw = |series: &[displacements::Displacement], th: &[(f64, AlertLevel)]| {
        let t: Vec<f64> = series
            .iter()
            .map(|r| unix_seconds(r.observed_at.as_bytes()))
            .collect();
        let v: Vec<f64> = series.iter().map(|r| r.d_mm).collect();
        let s: Vec<f64> = series.iter().map(|r| r.sigma_mm).collect();
        time_plot(&t, &v, &s, th, "mm")
    };
    let mut out = vec![];
    for b in blocks.iter().filter(|b| b.latest.is_some()).take(PLOTS) {
        let series =
            block_motions::series(store.reader(), &site.id, &b.name, from, to, None, None).await?;
        out.push((
            format!("block {}", b.name),
            draw(&series, &thresholds(Some(&b.name))),
        ));
    }
    let mut moving: Vec<&displacements::Displacement> = disp
        .iter()
        .filter(|d| {
            d.significant
                && roles.get(&d.point) != Some(&PointRole::Stable)
                && !in_blocks.contains(&d.point)
        })
        .collect();
    moving.sort_by(|a, b| b.d_mm.total_cmp(&a.d_mm));
    for d in moving.into_iter().take(PLOTS.saturating_sub(out.len())) {
        let series =
            displacements::series(store.reader(), &site.id, &d.point, from, to, None, None).await?;
        out.push((d.point.clone(), draw(&series, &thresholds(None))));
    }
    Ok(out)
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
