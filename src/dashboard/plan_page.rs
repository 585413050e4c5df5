//! `GET /sites/{site}/plan`: the pre-analysis of the site's own network (its latest epoch's
//! cameras and stations, its targets, stable points and a-priori σ; `service::plan::what_if` with
//! no change) beside what that epoch achieved: the face plan coloured by the predicted minimum
//! detectable displacement, the worst targets, each target's predicted and achieved σ, and the
//! report's warnings in words.

use std::collections::HashMap;

use axum::extract::{Path, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};

use super::face_plan::{nice_floor, FacePlane};
use super::layout::{num, page, seg};
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::service::ingest::EpochLimits;
use crate::service::plan::{what_if, SitePlan};
use crate::service::ServiceError;
use cliffwatch_core::analysis::site_frame::SiteFrame;
use cliffwatch_core::plan::TargetPrecision;

/// Targets listed as the worst (largest predicted 3-D MDD).
const WORST_LISTED: usize = 10;

/// The site's campaign-design page.
pub async fn plan(
    State(state): State<AppState>,
    Path(site_id): Path<String>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let site = super::page::site_or_404(state.store.reader(), &site_id).await?;
    let v = viewer(access.as_deref());
    let site_href = format!("/sites/{}", seg(&site.id));
    let crumbs = [(site.name.clone(), site_href.clone())];
    let slot = state.uploads.enter().await.map_err(ServiceError::from)?;
    let limits = EpochLimits::from_config(&state.config);
    let body = match what_if(&state.store, &site.id, Vec::new(), limits, slot).await {
        Ok(p) => body(&p, &site.frame, &site_href),
        Err(ServiceError::NoNetwork(m)) => html! {
            h1 { "Campaign design: " (site.name) }
            p.note { (m) }
        },
        Err(e) => return Err(e.into()),
    };
    let title = format!("{}: campaign design", site.name);
    Ok(Html(page(&title, &crumbs, &v, body).into_string()))
}

/// The page's body.
fn body(p: &SitePlan, frame: &SiteFrame, site_href: &str) -> Markup {
    let r = &p.report;
    let vf = p.achieved.variance_factor;
    let achieved: HashMap<&str, [f64; 3]> = p
        .achieved
        .points
        .iter()
        .map(|a| (a.point.as_str(), a.sigma_mm))
        .collect();
    let mut worst: Vec<&TargetPrecision> =
        r.targets.iter().filter(|t| t.mdd_3d_mm.is_some()).collect();
    worst.sort_by(|a, b| {
        b.mdd_3d_mm
            .unwrap_or(0.0)
            .total_cmp(&a.mdd_3d_mm.unwrap_or(0.0))
    });
    worst.truncate(WORST_LISTED);
    html! {
        h1 { "Campaign design: the network as designed and as achieved" }
        p {
            "The pre-analysis of this site's own network — the cameras and stations of epoch "
            a href={ (site_href) "/epochs/" (p.epoch) } { (p.epoch) }
            ", its " (r.targets.len()) " targets, its stable points and the a-priori σ its adjustments use — from the normal equations at zero residuals (no simulation), beside the σ that epoch's adjustment reported. "
            "Datum: " (if p.plan.datum.is_control() { "control points" } else { "free network" })
            "; degrees of freedom " (r.dof) "; minimum detectable displacement at " (num(Some(100.0 * r.confidence), 1)) " % confidence and " (num(Some(100.0 * r.power), 0)) " % power between two epochs."
            @if let Some(s) = r.sigma_c_mm { " Predicted σ of c: " (num(Some(s), 3)) " mm." }
            @if let Some(m) = r.min_redundancy { " Smallest redundancy number of an image coordinate: " (num(Some(m), 2)) "." }
        }
        p.note { "What-ifs (drop or add a station, another lens, another pixel σ): " code { "POST /api/v1/sites/{site}/plan" } " (docs/api.md, “Campaign design”)." }
        @if !r.warnings.is_empty() {
            section #warnings { h2 { "Weak points" } ul { @for w in &r.warnings { li { (w) } } } }
        }
        section #face { h2 { "Face plan, coloured by predicted 3-D minimum detectable displacement" } (mdd_plan(&r.targets, frame)) }
        section #worst {
            h2 { "Worst targets" }
            table { thead { tr { th { "Target" } th { "MDD 3-D (mm)" } th { "MDD normal (mm)" } th { "Stations" } th { "Intersection (°)" } } }
                tbody { @for t in &worst { tr {
                    td { a href={ (site_href) "/points/" (seg(&t.point)) } { (t.point) } }
                    td.num { (num(t.mdd_3d_mm, 2)) } td.num { (num(t.mdd_normal_mm, 2)) }
                    td.num { (t.cameras) } td.num { (num(t.intersection_deg, 1)) }
                } } }
            }
        }
        section #targets {
            h2 { "Predicted and achieved σ per target (mm)" }
            p.note { "Achieved: the σ epoch " (p.epoch) "'s adjustment reported (a-posteriori, variance factor " (num(vf, 3)) "), and rescaled to the a-priori σ (÷ √variance factor) as the prediction is." }
            table { thead { tr { th { "Target" } th { "Predicted σX, σY, σZ" } th { "Achieved (a-priori scale)" } th { "Achieved (reported)" } th { "MDD 3-D" } } }
                tbody { @for t in &r.targets { tr {
                    td { (t.point) @if t.known { " (stable)" } }
                    td.num { (triple(t.sigma_mm.map(|s| [s.x, s.y, s.z]))) }
                    td.num { (triple(achieved.get(t.point.as_str()).zip(vf).map(|(a, f)| a.map(|x| x / f.sqrt())))) }
                    td.num { (triple(achieved.get(t.point.as_str()).copied())) }
                    td.num { (num(t.mdd_3d_mm, 2)) }
                } } }
            }
        }
    }
}

/// σ triple as text, mm.
fn triple(v: Option<[f64; 3]>) -> String {
    v.map_or("—".into(), |v| {
        format!("{:.3}, {:.3}, {:.3}", v[0], v[1], v[2])
    })
}

/// A colour from green (best) to red (worst) for `f` in 0–1.
fn colour(f: f64) -> String {
    let f = f.clamp(0.0, 1.0);
    format!("hsl({:.0}, 70%, 45%)", 120.0 * (1.0 - f))
}

const W: f64 = 900.0;
const H: f64 = 480.0;
const PAD: f64 = 40.0;

/// The targets in the face's plane, each a disc coloured by its predicted 3-D MDD (green the
/// smallest, red the largest), labelled with its name and MDD, with the colour scale.
fn mdd_plan(targets: &[TargetPrecision], frame: &SiteFrame) -> Markup {
    let all: Vec<[f64; 3]> = targets.iter().map(|t| t.xyz).collect();
    let stable: Vec<[f64; 3]> = targets.iter().filter(|t| t.known).map(|t| t.xyz).collect();
    let Some(plane) = FacePlane::fit(frame, &stable, &all) else {
        return html! { p.note { "The face plan needs at least three targets that span a plane not near horizontal." } };
    };
    let uv: Vec<[f64; 2]> = all.iter().map(|p| plane.project(*p)).collect();
    let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in &uv {
        u0 = u0.min(p[0]);
        u1 = u1.max(p[0]);
        v0 = v0.min(p[1]);
        v1 = v1.max(p[1]);
    }
    let scale = ((W - 2.0 * PAD) / (u1 - u0).max(1e-3)).min((H - 2.0 * PAD) / (v1 - v0).max(1e-3));
    let (lo, hi) = targets
        .iter()
        .filter_map(|t| t.mdd_3d_mm)
        .fold((f64::MAX, f64::MIN), |(l, h), m| (l.min(m), h.max(m)));
    let frac = |m: f64| if hi > lo { (m - lo) / (hi - lo) } else { 0.0 };
    let bar_m = nice_floor((u1 - u0).max(v1 - v0).max(1e-3) / 5.0);
    html! {
        svg.plan viewBox={ "0 0 " (W) " " (H) } role="img" aria-label="face plan coloured by minimum detectable displacement" {
            @for (t, q) in targets.iter().zip(&uv) {
                @let (x, y) = (PAD + (q[0] - u0) * scale, H - PAD - (q[1] - v0) * scale);
                @let fill = t.mdd_3d_mm.map_or("#999".to_string(), |m| colour(frac(m)));
                g {
                    title { (t.point) ": MDD 3-D " (num(t.mdd_3d_mm, 2)) " mm" }
                    @if t.known {
                        polygon points={ (x) "," (y - 8.0) " " (x - 7.0) "," (y + 5.0) " " (x + 7.0) "," (y + 5.0) } fill=(fill) {}
                    } @else {
                        circle cx=(x) cy=(y) r="7" fill=(fill) {}
                    }
                    text x=(x + 9.0) y=(y + 4.0) font-size="11" { (t.point) " " (num(t.mdd_3d_mm, 1)) }
                }
            }
            line x1=(PAD) y1=(H - 12.0) x2=(PAD + bar_m * scale) y2=(H - 12.0) stroke="black" stroke-width="2" {}
            text x=(PAD) y=(H - 16.0) font-size="11" { (bar_m) " m" }
        }
        p.legend {
            "Colour: predicted 3-D MDD from " span style={ "color:" (colour(0.0)) } { (num(Some(lo), 2)) " mm" }
            " (green) to " span style={ "color:" (colour(1.0)) } { (num(Some(hi), 2)) " mm" } " (red); grey: not measured (fewer than two stations); triangles: stable points."
        }
    }
}
