//! `GET /sites/{site}/epochs/{epoch}`: the adjustment report (σ0, the global test, c ± σ,
//! iterations, datum, dropped observations with their w), for watched epochs how each station's
//! targets were identified with its image and the detections drawn over it
//! ([`super::epoch_images`]), and the image residuals of each image as a vector plot.

use std::collections::BTreeMap;

use axum::extract::{Path, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};
use serde_json::Value;

use super::epoch_images::{self, station_figure};
use super::face_plan::nice_floor;
use super::layout::{num, page, seg, with_sigma};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::epochs::{self, ObservationResidual};
use cliffwatch_core::photogrammetry::adjust::report::VarianceModel;

/// The epoch page.
pub async fn epoch(
    State(state): State<AppState>,
    Path((site_id, epoch)): Path<(String, String)>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let db = state.store.reader();
    let (site, id, item, report) = super::page::load_epoch(db, &site_id, &epoch).await?;
    let obs = epochs::observation_residuals(db, &site.id, id).await?;
    let mut by_image: BTreeMap<(usize, String), Vec<ObservationResidual>> = BTreeMap::new();
    let mut order: Vec<String> = vec![];
    for o in obs {
        if !order.contains(&o.image_id) {
            order.push(o.image_id.clone());
        }
        let k = order.iter().position(|x| *x == o.image_id).unwrap_or(0);
        by_image.entry((k, o.image_id.clone())).or_default().push(o);
    }
    let text = |v: &Value| match v {
        Value::String(s) => s.clone(),
        Value::Null => "–".into(),
        other => other.to_string(),
    };
    let test = report.global_test();
    let images: Vec<_> = epoch_images::stations(&report)
        .into_iter()
        .map(|st| {
            let there = epoch_images::available(&state, &site.id, &st);
            (st, there)
        })
        .collect();
    let v = viewer(access.as_deref());
    let s = seg(&site.id);
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    let body = html! {
        h1 { "Epoch " (item.id) " · " (when(&item.observed_at, site.time_zone.as_deref())) }
        (headline)
        table.report {
            tr { th { "status" } td { (item.status) } }
            tr { th { "model" } td { (item.model) } }
            tr { th { "σ0 (mm)" } td { (num(Some(item.sigma0_mm), 5)) } }
            tr { th { "variance factor" } td { (num(Some(report.variance_factor), 3)) } }
            tr { th { "global test" }
                 td { (if test.accepted { "accepted" } else { "rejected" }) ": "
                      (num(Some(test.variance_factor), 3)) " in [" (num(Some(test.lower), 3)) ", " (num(Some(test.upper), 3)) "]"
                      " (" (num(Some(100.0 * test.confidence), 1)) " %)" } }
            tr { th { "variance model" } td { (report.variance_model.map_or("–", variance_model_text)) } }
            tr { th { "degrees of freedom" } td { (report.dof) } }
            tr { th { "iterations" } td { (item.iterations) } }
            tr { th { "datum" } td { (if report.datum.is_empty() { "–" } else { report.datum.as_str() }) } }
            @for c in &report.cameras {
                tr { th { "c ± σ (mm), camera " (c.id) }
                     td { (with_sigma(Some(c.c_mm), c.c_sigma_mm, 3)) } }
            }
        }
        @if !report.warnings.is_empty() {
            ul.warnings { @for w in &report.warnings { li { (w) } } }
        }
        @if let Some(stations) = &report.identification {
            h2 { "Identification (watched directory)" }
            table.identification {
                thead { tr { th { "station" } th { "method" } th { "detected" } th { "identified" } th { "ambiguous" } th { "unmatched" } th.wide { "detection settings" } } }
                tbody { @for st in stations {
                    tr { td { (st.get("station").map(text).unwrap_or_default()) }
                         td { (st.get("method").map(text).unwrap_or_default()) }
                         @for k in ["detected", "identified", "ambiguous", "unmatched"] {
                             td.num { (st.get(k).map(text).unwrap_or_default()) }
                         }
                         td.detection.wide { (detection_settings(st.get("detection"))) } }
                } }
            }
            @if !images.is_empty() {
                div.station-images {
                    @for (st, there) in &images { (station_figure(&site.id, item.id, st, *there)) }
                }
            }
        }
        h2 { "Dropped observations" }
        @if report.dropped.is_empty() {
            p.note { "None: every observation passed data snooping." }
        } @else {
            table.dropped {
                thead { tr { th { "image" } th { "point" } th { "w" } } }
                tbody { @for d in &report.dropped {
                    tr { td { (d.image) }
                         td { (d.point) }
                         td.num { (num(Some(d.w), 2)) } }
                } }
            }
        }
        h2 { "Image residuals" }
        @if let Some(pruned) = &item.observations_pruned_at {
            p.note { "The image observations of this epoch were deleted "
                     (when(pruned, site.time_zone.as_deref()))
                     " (observation retention); the report above is kept." }
        }
        div.residuals {
            @for ((_, image), rows) in &by_image {
                figure { figcaption { "image " (image) } (residual_plot(rows)) }
            }
        }
    };
    let crumbs = [
        (site.name.clone(), format!("/sites/{s}")),
        (
            format!("epoch {}", item.id),
            format!("/sites/{s}/epochs/{}", item.id),
        ),
    ];
    Ok(Html(
        page(&format!("epoch {}", item.id), &crumbs, &v, body).into_string(),
    ))
}

/// How the page names the variance behind the snooping's statistics.
fn variance_model_text(m: VarianceModel) -> &'static str {
    match m {
        VarianceModel::APriori => "a priori σ (Baarda's w)",
        VarianceModel::APosteriori => "a posteriori σ̂0 (Pope's τ)",
    }
}

/// The residual vectors of one image drawn at their image positions, exaggerated so the largest
/// is a tenth of the image's extent; dropped observations in red.
fn residual_plot(rows: &[ObservationResidual]) -> Markup {
    let pos = |o: &ObservationResidual| match (o.x_mm, o.y_mm, o.col_px, o.row_px) {
        (Some(x), Some(y), _, _) => Some((x, y)),
        (_, _, Some(c), Some(r)) => Some((c, -r)),
        _ => None,
    };
    let pts: Vec<(&ObservationResidual, (f64, f64))> =
        rows.iter().filter_map(|o| pos(o).map(|p| (o, p))).collect();
    if pts.is_empty() {
        return html! { p.note { "no image coordinates" } };
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (_, (x, y)) in &pts {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    let extent = (x1 - x0).max(y1 - y0).max(1e-9);
    let (w, h, pad) = (360.0, 260.0, 20.0);
    let scale = ((w - 2.0 * pad) / (x1 - x0).max(extent * 0.05))
        .min((h - 2.0 * pad) / (y1 - y0).max(extent * 0.05));
    let vmax = pts
        .iter()
        .map(|(o, _)| o.vx_mm.unwrap_or(0.0).hypot(o.vy_mm.unwrap_or(0.0)))
        .fold(0.0f64, f64::max);
    let exaggeration = if vmax > 0.0 {
        nice_floor(0.1 * extent / vmax)
    } else {
        1.0
    };
    html! {
        svg.residual viewBox={ "0 0 " (w) " " (h) } xmlns="http://www.w3.org/2000/svg" {
            @for (o, (x, y)) in &pts {
                @let (px, py) = (pad + (x - x0) * scale, h - pad - (y - y0) * scale);
                @let (dx, dy) = (o.vx_mm.unwrap_or(0.0) * exaggeration * scale, o.vy_mm.unwrap_or(0.0) * exaggeration * scale);
                circle cx=(format!("{px:.1}")) cy=(format!("{py:.1}")) r="2" { title { (o.point) } }
                line class={ "res" @if o.dropped { " dropped" } } x1=(format!("{px:.1}")) y1=(format!("{py:.1}")) x2=(format!("{:.1}", px + dx)) y2=(format!("{:.1}", py - dy)) {
                    title { (o.point) ": " (num(o.vx_mm.map(|v| v * 1000.0), 2)) ", " (num(o.vy_mm.map(|v| v * 1000.0), 2)) " µm, w " (num(o.w, 2)) @if o.dropped { " (dropped)" } }
                }
            }
            text x="4" y=(format!("{:.0}", h - 4.0)) { "residuals × " (exaggeration) }
        }
    }
}

/// A station's detection settings as the report keeps them (`DetectionUsed`), in words:
/// "polarity auto, found dark · diameters 2.5–64 px · from site, default"; "not recorded" for
/// epochs stored before they were.
fn detection_settings(d: Option<&serde_json::Value>) -> String {
    let Some(d) = d.filter(|d| d.is_object()) else {
        return "not recorded".into();
    };
    let s = |k: &str| d.get(k).and_then(|v| v.as_str()).unwrap_or("?").to_string();
    let n = |k: &str| {
        d.get(k)
            .and_then(|v| v.as_f64())
            .map_or("?".into(), |v| format!("{v}"))
    };
    let polarity = s("polarity");
    let found = s("found");
    let pol = if polarity == "auto" {
        format!("polarity auto, found {found}")
    } else {
        format!("polarity {polarity}")
    };
    let from: Vec<&str> = d
        .get("from")
        .and_then(|v| v.as_array())
        .map(|a| a.iter().filter_map(|v| v.as_str()).collect())
        .unwrap_or_default();
    format!(
        "{pol} · diameters {}–{} px · from {}",
        n("min_diameter_px"),
        n("max_diameter_px"),
        if from.is_empty() {
            "?".into()
        } else {
            from.join(", ")
        }
    )
}
