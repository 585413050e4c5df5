//! `GET /sites/{site}/points/{point}`: plots against time of dx, dy, dz, the 3-D displacement
//! and the displacement along the direction of interest, each with its ±2σ band; threshold
//! lines of the rules that apply and markers where alerts were raised, escalated, acknowledged
//! and resolved; the velocity and the inverse velocity with its fitted line and the forecast
//! failure time; the filtered series beside the raw one; CSV download of the same data.
//!
//! The page holds the plot containers; `plots.js` draws them with uPlot from
//! [`super::plot_data`].

use axum::extract::{Path, State};
use axum::response::Html;
use axum::Extension;
use maud::html;

use super::layout::{level_badge, num, page, seg, time_to_failure, with_sigma};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::displacements::Displacement;
use crate::store::sites::Site;
use crate::store::{alerts, displacements, points, pooled_forecasts};
use cliffwatch_core::analysis::site_frame::{FaceAxes, SiteFrame};
use cliffwatch_core::analysis::PointRole;

/// The point page.
pub async fn point(
    State(state): State<AppState>,
    Path((site_id, point)): Path<(String, String)>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let db = state.store.reader();
    let site = super::page::site_or_404(db, &site_id).await?;
    let Some(p) = points::get(db, &site.id, &point).await? else {
        return Err(PageError::not_found(format!(
            "no point '{point}' in site '{site_id}'"
        )));
    };
    let level = alerts::active_levels(db, &site.id)
        .await?
        .get(&p.name)
        .copied();
    let latest = displacements::latest(&mut *state.store.read().await?, &site.id)
        .await?
        .into_iter()
        .find(|d| d.point == p.name);
    let pooled_with = match &latest {
        Some(d) => pooled_forecasts::of_point(db, &site.id, &p.name, d.epoch).await?,
        None => vec![],
    };
    let axes = face_axes(&state, &site).await?;
    let (s, n) = (seg(&site.id), seg(&p.name));
    let data = format!("/dashboard/plot/{s}/{n}");
    let csv = format!("/api/v1/sites/{s}/points/{n}/displacements?format=csv");
    let v = viewer(access.as_deref());
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    let incident = super::incident_panel::panel(
        db,
        &site.id,
        &crate::service::incidents::Subject::Point(p.name.clone()),
        &v,
    )
    .await?;
    let body = html! {
        h1 { (p.name) " " (level_badge(level)) }
        (headline)
        (incident)
        p {
            (p.role)
            @if let Some(g) = &p.group { " · block " a href={ "/sites/" (seg(&site.id)) "/groups/" (seg(g)) } { (g) } }
            @if let Some(d) = p.direction { " · direction [" (num(Some(d[0]), 3)) ", " (num(Some(d[1]), 3)) ", " (num(Some(d[2]), 3)) "]" }
            " · " a href=(csv) download { "CSV of the series" }
        }
        @if let Some(d) = &latest {
            table.latest {
                tr { th { "latest epoch" } td { a href={ "/sites/" (s) "/epochs/" (d.epoch) } { (when(&d.observed_at, site.time_zone.as_deref())) } } }
                tr { th { "d (mm)" } td { (with_sigma(Some(d.d_mm), Some(d.sigma_mm), 2)) @if d.significant { " (significant)" } } }
                @if let Some(a) = &axes {
                    @let (c, var) = (a.components([d.dx_mm, d.dy_mm, d.dz_mm]), a.component_variances(&covariance(d)));
                    tr.face {
                        th { "in the face (mm): along · height · out of the face" }
                        td {
                            (with_sigma(Some(c[0]), Some(var[0].sqrt()), 2)) " along · "
                            (with_sigma(Some(c[1]), Some(var[1].sqrt()), 2)) " height · "
                            (with_sigma(Some(c[2]), Some(var[2].sqrt()), 2)) " out"
                            small { " (up " (SiteFrame::describe(site.frame.up)) ", out of the face " (SiteFrame::describe(a.out)) "; + is right, up, towards the cameras)" }
                        }
                    }
                }
                tr { th { "filtered d (mm)" } td { (with_sigma(d.f_d_mm, d.sigma_f_d_mm, 2)) } }
                tr { th { "filtered velocity (mm/day)" } td { (with_sigma(d.f_velocity_mm_per_day, d.sigma_f_velocity_mm_per_day, 3)) } }
                tr { th { "raw velocity (mm/day)" } td { (num(d.velocity_mm_per_day, 3)) } }
                tr {
                    th { "filtered time to failure (h)" }
                    td {
                        (time_to_failure(d.f_time_to_failure_hours, d.sigma_f_time_to_failure_hours))
                        @if !pooled_with.is_empty() {
                            br;
                            small.pooled { "pooled: the forecast of the mean series of " (p.name) " with " (names_in_words(&pooled_with)) ", which move together (not a declared block)" }
                        }
                    }
                }
                @if let Some(m) = super::sensitivity::of(d, p.direction, site.confidence) {
                    tr.mdd {
                        th { "smallest movement this epoch detects (" (num(Some(100.0 * m.power), 0)) " % of the time, " (num(Some(100.0 * site.confidence), 1)) " % confidence)" }
                        td {
                            @if let Some(a) = m.along_mm { (num(Some(a), 2)) " mm along the direction · " }
                            (num(Some(m.worst_mm), 2)) " mm in the worst direction"
                            @if !d.significant { " — no movement above this is seen" }
                        }
                    }
                }
            }
        } @else {
            p.note { "No displacement yet: the point has no epoch after the reference." }
        }
        div.plots data-src=(data) {
            figure { figcaption { "dx, dy, dz (mm), ±2σ" } div.plot data-panel="xyz" {} }
            figure { figcaption { "3-D displacement d (mm), raw and filtered, ±2σ" } div.plot data-panel="d" {} }
            @if p.direction.is_some() {
                figure { figcaption { "displacement along the direction of interest (mm), ±2σ" } div.plot data-panel="along" {} }
            }
            figure { figcaption { "velocity (mm/day), raw and filtered ±2σ" } div.plot data-panel="velocity" {} }
            figure { figcaption { "inverse velocity 1/v (day/mm) of the filtered velocity, ±2σ, where it is significantly forward (v > 2σ); dashed: the forecast's inverse-velocity law, fitted to the 1/v plotted over its last 12 epochs; its zero is the forecast failure time" } div.plot data-panel="inverse" {} p.forecast {} }
        }
        noscript { p.note { "The plots need JavaScript; the CSV link above has the same data." } }
    };
    let crumbs = [
        (site.name.clone(), format!("/sites/{s}")),
        (p.name.clone(), format!("/sites/{s}/points/{n}")),
    ];
    Ok(Html(page(&p.name, &crumbs, &v, body).into_string()))
}

/// The site's face axes from its frame and its points' latest coordinates (the stable points'
/// plane when the normal is not declared); `None` when no face can be fitted.
pub(super) async fn face_axes(
    state: &AppState,
    site: &Site,
) -> Result<Option<FaceAxes>, PageError> {
    let roles: std::collections::HashMap<String, PointRole> =
        points::list(state.store.reader(), &site.id, None, 100_000)
            .await?
            .into_iter()
            .map(|p| (p.name, p.role))
            .collect();
    let coords = points::latest_coordinates(&mut *state.store.read().await?, &site.id).await?;
    let all: Vec<[f64; 3]> = coords.iter().map(|c| c.xyz).collect();
    let stable: Vec<[f64; 3]> = coords
        .iter()
        .filter(|c| roles.get(&c.point) == Some(&PointRole::Stable))
        .map(|c| c.xyz)
        .collect();
    Ok(FaceAxes::of(&site.frame, &stable, &all))
}

/// Names in words: "T1", "T1 and T2", "T1, T2 and T3".
fn names_in_words(names: &[String]) -> String {
    match names {
        [] => String::new(),
        [one] => one.clone(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
    }
}

/// The displacement's 3×3 covariance in mm² (diagonal only for rows stored before the
/// covariances were).
fn covariance(d: &Displacement) -> [[f64; 3]; 3] {
    let (xy, xz, yz) = (
        d.cov_dxdy_mm2.unwrap_or(0.0),
        d.cov_dxdz_mm2.unwrap_or(0.0),
        d.cov_dydz_mm2.unwrap_or(0.0),
    );
    [
        [d.sigma_dx_mm.powi(2), xy, xz],
        [xy, d.sigma_dy_mm.powi(2), yz],
        [xz, yz, d.sigma_dz_mm.powi(2)],
    ]
}
