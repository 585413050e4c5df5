//! `GET /dashboard/plot/{site}/{point}?width=N`: a point's series as columnar JSON for the
//! plots, downsampled on the server to the plot's width while it is read
//! ([`super::downsample::PlotPicker`]: min/max per bucket of dx, dy, dz and d; the first, the
//! last and every alert epoch kept; the series is never held whole), with the
//! thresholds of the rules that apply, the alert events, the inverse-velocity line and the
//! forecast failure time.
//!
//! Columns: `t` (s since 1970), `epoch`, `dx`, `dy`, `dz`, `d`, `sdx`, `sdy`, `sdz`, `sd`,
//! `along`, `velocity`, `f_dx`, `f_dy`, `f_dz`, `f_d`, `sf_d`, `f_velocity`, `sf_velocity`
//! (mm, mm/day; `null` where missing). `total` is the series' length before downsampling.

use std::collections::{HashSet, VecDeque};

use axum::extract::{Path, Query, State};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

use super::downsample::PlotPicker;
use crate::api::error::ApiError;
use crate::api::AppState;
use crate::store::series::SeriesQuery;
use crate::store::series_columns::{self, unix_seconds, SeriesColumns, SeriesRow};
use crate::store::{alerts, points, sites};

/// Query of the plot data.
#[derive(Debug, Deserialize)]
pub struct PlotParams {
    /// Plot width in pixels (100–4000, default 800).
    pub width: Option<usize>,
}

/// Epochs of the inverse-velocity line (the failure forecast's default window).
const LINE_EPOCHS: usize = 12;

/// The plot data of one point.
pub async fn plot(
    State(state): State<AppState>,
    Path((site_id, point)): Path<(String, String)>,
    Query(q): Query<PlotParams>,
) -> Result<Response, ApiError> {
    let width = q.width.unwrap_or(800).clamp(100, 4000);
    let db = state.store.reader();
    let Some(site) = sites::get(db, &site_id).await? else {
        return Err(ApiError::not_found(format!("unknown site '{site_id}'")));
    };
    let Some(p) = points::get(db, &site.id, &point).await? else {
        return Err(ApiError::not_found(format!(
            "unknown point '{point}' of site '{site_id}'"
        )));
    };
    let concerns = |a: &alerts::Alert| {
        a.point.as_deref() == Some(p.name.as_str()) || a.points.contains(&p.name)
    };
    let alert_epochs: HashSet<i64> = alerts::list(db, Some(&site.id), None, None, 100_000)
        .await?
        .into_iter()
        .filter(|(_, a)| concerns(a))
        .filter_map(|(_, a)| a.epoch)
        .collect();
    let direction = p.direction;
    let query = SeriesQuery {
        site: site.id.clone(),
        point: p.name.clone(),
        direction,
        ..SeriesQuery::default()
    };
    // One pass over the series: the picker keeps the rows drawn, `tail` the last epochs for the
    // inverse-velocity line and the forecast.
    let (picker, tail) = series_columns::fold(
        &state.store,
        query,
        move |n| {
            (
                PlotPicker::new(n, 4, width),
                VecDeque::with_capacity(LINE_EPOCHS),
            )
        },
        move |(picker, tail), r| {
            let row = SeriesRow::of(r, direction);
            picker.push(&row.d, alert_epochs.contains(&row.epoch), row);
            if tail.len() == LINE_EPOCHS {
                tail.pop_front();
            }
            tail.push_back(row);
            true
        },
    )
    .await?;
    let total = picker.fed();
    let mut drawn = SeriesColumns::default();
    for (_, row) in picker.finish() {
        drawn.push(&row);
    }
    let mut last = SeriesColumns::default();
    for row in &tail {
        last.push(row);
    }
    let events: Vec<Value> = alerts::events_of_point(db, &site.id, &p.name)
        .await?
        .into_iter()
        .map(|e| json!({"t": unix_seconds(e.at.as_bytes()), "type": e.event_type, "level": e.level, "alert": e.alert_id}))
        .collect();
    let thresholds: Vec<Value> = site
        .alert_rules
        .iter()
        .filter(|r| {
            r["group"]
                .as_str()
                .is_none_or(|g| p.group.as_deref() == Some(g))
        })
        .map(|r| json!({"metric": r["metric"], "level": r["level"], "above": r["above"], "below": r["below"]}))
        .collect();
    let mut out = columns(&drawn);
    out["total"] = json!(total);
    out["thresholds"] = json!(thresholds);
    out["events"] = json!(events);
    out["inverse_line"] = inverse_line(&last).map_or(Value::Null, |l| json!(l));
    out["forecast"] = forecast(&last);
    Ok(Json(out).into_response())
}

/// Every row of `c` as a JSON object of arrays (NaN as null).
fn columns(c: &SeriesColumns) -> Value {
    let pick = |v: &[f64]| -> Value { v.iter().map(|&x| finite(x)).collect() };
    json!({
        "t": pick(&c.t),
        "epoch": c.epoch,
        "dx": pick(&c.d[0]), "dy": pick(&c.d[1]), "dz": pick(&c.d[2]), "d": pick(&c.d[3]),
        "sdx": pick(&c.sigma[0]), "sdy": pick(&c.sigma[1]), "sdz": pick(&c.sigma[2]), "sd": pick(&c.sigma[3]),
        "along": pick(&c.along),
        "velocity": pick(&c.velocity),
        "f_dx": pick(&c.f_d[0]), "f_dy": pick(&c.f_d[1]), "f_dz": pick(&c.f_d[2]), "f_d": pick(&c.f_d[3]),
        "sf_d": pick(&c.sigma_f_d[3]),
        "f_velocity": pick(&c.f_velocity[0]), "sf_velocity": pick(&c.f_velocity[1]),
    })
}

fn finite(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

/// The weighted straight line through the inverse filtered velocities (day/mm) of the last
/// [`LINE_EPOCHS`] epochs where the velocity is significantly positive (v > 2σ), weights
/// 1/σ(1/v)²: `[t0, y0, t1, y1]` (s since 1970, day/mm) from its first epoch to where it reaches
/// zero (or its last epoch when it does not fall). None with fewer than 3 such epochs.
pub fn inverse_line(c: &SeriesColumns) -> Option<[f64; 4]> {
    let n = c.t.len();
    let start = n.saturating_sub(LINE_EPOCHS);
    let mut rows = vec![];
    for i in start..n {
        let (v, s) = (c.f_velocity[0][i], c.f_velocity[1][i]);
        if v.is_finite() && s.is_finite() && s > 0.0 && v > 2.0 * s {
            let sy = s / (v * v);
            rows.push((c.t[i] / 86_400.0, 1.0 / v, 1.0 / (sy * sy)));
        }
    }
    if rows.len() < 3 {
        return None;
    }
    let sw: f64 = rows.iter().map(|r| r.2).sum();
    let tm = rows.iter().map(|r| r.2 * r.0).sum::<f64>() / sw;
    let ym = rows.iter().map(|r| r.2 * r.1).sum::<f64>() / sw;
    let stt: f64 = rows.iter().map(|r| r.2 * (r.0 - tm).powi(2)).sum();
    let sty: f64 = rows.iter().map(|r| r.2 * (r.0 - tm) * (r.1 - ym)).sum();
    if !(stt.is_finite() && stt > 0.0) {
        return None;
    }
    let b = sty / stt;
    let a = ym - b * tm;
    let t0 = rows[0].0;
    let t1 = if b < 0.0 {
        -a / b
    } else {
        rows[rows.len() - 1].0
    };
    Some([t0 * 86_400.0, a + b * t0, t1 * 86_400.0, a + b * t1])
}

/// The latest filtered forecast: failure time and ±2σ (s since 1970), or null.
fn forecast(c: &SeriesColumns) -> Value {
    let Some(i) = c.t.len().checked_sub(1) else {
        return Value::Null;
    };
    let (h, s) = (c.f_ttf[0][i], c.f_ttf[1][i]);
    if !h.is_finite() {
        return Value::Null;
    }
    let tf = c.t[i] + h * 3600.0;
    let s = if s.is_finite() { s * 3600.0 } else { 0.0 };
    json!({"t_f": tf, "lower": (tf - 2.0 * s).max(c.t[i]), "upper": tf + 2.0 * s, "hours": h})
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Velocities of the inverse-velocity law v = B/(t_f − t) give back t_f.
    #[test]
    fn the_inverse_line_reaches_zero_at_the_failure_time() {
        let tf_day = 20_000.0;
        let mut c = SeriesColumns::default();
        for k in 0..20 {
            let t = tf_day - 20.0 + k as f64 * 0.9;
            c.t.push(t * 86_400.0);
            let v = 6.0 / (tf_day - t);
            c.f_velocity[0].push(v);
            c.f_velocity[1].push(0.01 * v);
        }
        let l = inverse_line(&c).expect("line");
        assert!((l[2] / 86_400.0 - tf_day).abs() < 1e-6, "{l:?}");
        assert!(l[3].abs() < 1e-9 && l[1] > 0.0);
    }
}
