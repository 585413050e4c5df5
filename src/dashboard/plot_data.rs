//! `GET /dashboard/plot/{site}/{point}?width=N`: a point's series as columnar JSON for the
//! plots, downsampled on the server to the plot's width while it is read
//! ([`super::downsample::PlotPicker`]: min/max per bucket of dx, dy, dz and d; the first, the
//! last and every alert epoch kept; the series is never held whole), with the
//! thresholds of the rules that apply, the alert events, the inverse-velocity line and the
//! forecast failure time.
//!
//! When a bucket spans a packed block of the store or more (a long history), the read takes
//! each block's extremes (its first and last rows and those of its minimum and maximum of dx, dy,
//! dz and d; [`crate::store::series_record::extremes`]) instead of its 128 rows, and the picker
//! works on those: a bucket's minimum and maximum are then those of the blocks it holds, so
//! peaks still survive, and the alert epochs a block's extremes leave out are read one by one.
//!
//! Columns: `t` (s since 1970), `epoch`, `dx`, `dy`, `dz`, `d`, `sdx`, `sdy`, `sdz`, `sd`,
//! `along`, `velocity`, `f_dx`, `f_dy`, `f_dz`, `f_d`, `sf_d`, `f_velocity`, `sf_velocity`
//! (mm, mm/day; `null` where missing). `total` is the series' length before downsampling.

use std::collections::{HashSet, VecDeque};

use axum::extract::{Path, Query, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{json, Value};

use super::downsample::{bucket_count, PlotPicker};
use super::local_time::text;
use crate::http::error::ApiError;
use crate::http::AppState;
use crate::store::series::blocks::BLOCK_EPOCHS;
use crate::store::series::columns::{
    self as series_columns, unix_seconds, SeriesColumns, SeriesRow, SeriesSize,
};
use crate::store::series::SeriesQuery;
use crate::store::Store;
use crate::store::{alerts, points, sites};

/// Query of the plot data.
#[derive(Debug, Deserialize)]
pub struct PlotParams {
    /// Plot width in pixels (100–4000, default 800).
    pub width: Option<usize>,
}

/// Epochs of the inverse-velocity line drawn on the plot: the last 12, where the acceleration
/// shows (the forecast itself fits the creep before the onset as well, over
/// `FailureConfig::acceleration_window`).
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
    let alert_epochs: HashSet<i64> = alerts::epochs_of_point(db, &site.id, &p.name)
        .await?
        .into_iter()
        .collect();
    let direction = p.direction;
    let query = SeriesQuery {
        site: site.id.clone(),
        point: p.name.clone(),
        direction,
        // each bucket spans a block or more: the blocks' extremes are enough
        extremes_above: Some(bucket_count(width) * BLOCK_EPOCHS),
        ..SeriesQuery::default()
    };
    let (drawn_rows, tail) = read_drawn(&state.store, query, alert_epochs, width).await?;
    let total = drawn_rows.total;
    let mut drawn = SeriesColumns::default();
    for row in &drawn_rows.rows {
        drawn.push(row);
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
    let rest = json!({
        "total": total,
        "thresholds": thresholds,
        "events": events,
        "inverse_line": inverse_line(&last).map_or(Value::Null, |l| json!(l)),
        "forecast": forecast(&last, site.time_zone.as_deref()),
    });
    let mut body = Vec::with_capacity(drawn.t.len() * 19 * 20 + 4096);
    write_columns(&drawn, &mut body);
    // the other members after the columns: `{…columns…,` + `"total":…}` without its `{`
    body.push(b',');
    let tail = serde_json::to_vec(&rest).map_err(|e| ApiError::internal(e.to_string()))?;
    body.extend_from_slice(&tail[1..]);
    Ok(([(header::CONTENT_TYPE, "application/json")], body).into_response())
}

/// The rows a plot draws, and the series' length before downsampling.
struct Drawn {
    rows: Vec<SeriesRow>,
    total: usize,
}

/// What a read keeps of the rows it is given.
enum Picking {
    /// Every row of the series: fed to the picker as it is read.
    Rows(Box<PlotPicker<SeriesRow>>),
    /// The blocks' extremes (and the last block and tail whole): picked from at the end.
    Extremes(Vec<SeriesRow>),
}

/// The state of one read: the rows kept so far, and the last [`LINE_EPOCHS`] rows.
struct Reading {
    size: SeriesSize,
    picking: Picking,
    tail: VecDeque<SeriesRow>,
}

/// Reads `query`'s series once and downsamples it to `width` px, keeping the rows of
/// `alert_epochs`: the drawn rows in time order, and the last [`LINE_EPOCHS`] rows.
async fn read_drawn(
    store: &Store,
    query: SeriesQuery,
    alert_epochs: HashSet<i64>,
    width: usize,
) -> Result<(Drawn, VecDeque<SeriesRow>), ApiError> {
    let (site, point, direction) = (query.site.clone(), query.point.clone(), query.direction);
    let flagged = alert_epochs.clone();
    let reading = series_columns::fold(
        store,
        query,
        move |size: SeriesSize| Reading {
            size,
            picking: if size.extremes {
                Picking::Extremes(Vec::new())
            } else {
                Picking::Rows(Box::new(PlotPicker::new(size.records, 4, width)))
            },
            tail: VecDeque::with_capacity(LINE_EPOCHS),
        },
        move |s, r| {
            let row = SeriesRow::of(r, direction);
            match &mut s.picking {
                Picking::Rows(picker) => picker.push(&row.d, flagged.contains(&row.epoch), row),
                Picking::Extremes(rows) => rows.push(row),
            }
            if s.tail.len() == LINE_EPOCHS {
                s.tail.pop_front();
            }
            s.tail.push_back(row);
            true
        },
    )
    .await?;
    let Reading {
        size,
        picking,
        tail,
    } = reading;
    let extremes = match picking {
        Picking::Rows(picker) => {
            let total = picker.fed();
            let rows = picker.finish().into_iter().map(|(_, r)| r).collect();
            return Ok((Drawn { rows, total }, tail));
        }
        Picking::Extremes(rows) => rows,
    };
    let mut picker = PlotPicker::new(extremes.len(), 4, width);
    for row in extremes {
        picker.push(&row.d, alert_epochs.contains(&row.epoch), row);
    }
    let mut rows: Vec<SeriesRow> = picker.finish().into_iter().map(|(_, r)| r).collect();
    let missing: Vec<i64> = alert_epochs
        .iter()
        .copied()
        .filter(|e| !rows.iter().any(|r| r.epoch == *e))
        .collect();
    if !missing.is_empty() {
        rows.extend(
            series_columns::rows_at_epochs(store, &site, &point, &missing, direction).await?,
        );
        rows.sort_by(|a, b| a.t.total_cmp(&b.t));
    }
    Ok((
        Drawn {
            rows,
            total: size.records,
        },
        tail,
    ))
}

/// Every row of `c` as the opening of a JSON object of arrays (NaN as null; numbers as
/// serde_json writes them), without the closing brace: `{"epoch":[…],"t":[…],…,"sf_velocity":[…]`.
/// Written straight into bytes: a long history's plot holds ~1 600 rows of 19 columns.
fn write_columns(c: &SeriesColumns, out: &mut Vec<u8>) {
    let floats: [(&str, &[f64]); 18] = [
        ("t", &c.t),
        ("dx", &c.d[0]),
        ("dy", &c.d[1]),
        ("dz", &c.d[2]),
        ("d", &c.d[3]),
        ("sdx", &c.sigma[0]),
        ("sdy", &c.sigma[1]),
        ("sdz", &c.sigma[2]),
        ("sd", &c.sigma[3]),
        ("along", &c.along),
        ("velocity", &c.velocity),
        ("f_dx", &c.f_d[0]),
        ("f_dy", &c.f_d[1]),
        ("f_dz", &c.f_d[2]),
        ("f_d", &c.f_d[3]),
        ("sf_d", &c.sigma_f_d[3]),
        ("f_velocity", &c.f_velocity[0]),
        ("sf_velocity", &c.f_velocity[1]),
    ];
    let mut float = zmij::Buffer::new();
    let mut int = itoa::Buffer::new();
    out.extend_from_slice(b"{\"epoch\":[");
    for (k, e) in c.epoch.iter().enumerate() {
        if k > 0 {
            out.push(b',');
        }
        out.extend_from_slice(int.format(*e).as_bytes());
    }
    out.push(b']');
    for (name, values) in floats {
        out.extend_from_slice(b",\"");
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(b"\":[");
        for (k, &x) in values.iter().enumerate() {
            if k > 0 {
                out.push(b',');
            }
            if x.is_finite() {
                out.extend_from_slice(float.format_finite(x).as_bytes());
            } else {
                out.extend_from_slice(b"null");
            }
        }
        out.push(b']');
    }
}

/// The inverse velocity the plots draw at epoch `k`: `(1/v, σ of 1/v)` in day/mm where the
/// filtered velocity is significantly forward (v > 2σ), else `None` (a gap: no 1/v to draw).
/// σ(1/v) = σ_v / v² (first order).
pub fn plotted_inverse(c: &SeriesColumns, k: usize) -> Option<(f64, f64)> {
    let (v, sv) = (c.f_velocity[0][k], c.f_velocity[1][k]);
    (v.is_finite() && sv.is_finite() && v > 2.0 * sv).then(|| (1.0 / v, sv / (v * v)))
}

/// The inverse-velocity line of the latest filtered forecast (Fukuzono 1985): the forecast's
/// law `v = B/(t_f − t)` is a straight line `1/v = (t_f − t)/B` that reaches zero at the
/// forecast failure time itself. `t_f` is the forecast's; the slope `1/B` is fitted by weighted
/// least squares (weights 1/σ² of [`plotted_inverse`]) to the inverse velocities the plot draws
/// over the forecast's window, the last [`LINE_EPOCHS`] epochs, so the line runs through the
/// points it is drawn over. `[t0, y0, t_f, 0]` (s since 1970, day/mm) from the window's first
/// epoch; None without a forecast, for one the pages do not state
/// ([`cliffwatch_core::analysis::failure::stated`]: "no forecast yet"), with fewer than 3
/// plotted points in the window, or when the law does not advance.
pub fn inverse_line(c: &SeriesColumns) -> Option<[f64; 4]> {
    let i = c.t.len().checked_sub(1)?;
    let (h, s) = (c.f_ttf[0][i], c.f_ttf[1][i]);
    if !cliffwatch_core::analysis::failure::stated(h, s) {
        return None;
    }
    let day = |t: f64| t / 86_400.0;
    let tf = day(c.t[i]) + h / 24.0;
    let start = c.t.len().saturating_sub(LINE_EPOCHS);
    let (mut sxy, mut sxx, mut n) = (0.0, 0.0, 0);
    for k in start..=i {
        let rest = tf - day(c.t[k]);
        if let Some((y, sy)) = plotted_inverse(c, k).filter(|(_, sy)| *sy > 0.0) {
            if rest > 0.0 {
                let w = 1.0 / (sy * sy);
                sxy += w * rest * y;
                sxx += w * rest * rest;
                n += 1;
            }
        }
    }
    let slope = sxy / sxx;
    if n < 3 || !(slope.is_finite() && slope > 0.0) {
        return None;
    }
    let t0 = day(c.t[start]);
    Some([c.t[start], (tf - t0) * slope, tf * 86_400.0, 0.0])
}

/// The latest filtered forecast: failure time and ±2σ (s since 1970), the one-sided bound
/// before which failure is likely (`likely_before`, at
/// [`cliffwatch_core::analysis::failure::BOUND_CONFIDENCE`]), the window its line was fitted over, and the
/// sentence the page shows (UTC and the site's time zone `tz`), or null. A forecast whose bound
/// lies beyond a week reads "No forecast yet" (`stated: false`, no line).
fn forecast(c: &SeriesColumns, tz: Option<&str>) -> Value {
    let Some(i) = c.t.len().checked_sub(1) else {
        return Value::Null;
    };
    let (h, s) = (c.f_ttf[0][i], c.f_ttf[1][i]);
    if !h.is_finite() {
        return Value::Null;
    }
    let confidence = cliffwatch_core::analysis::failure::BOUND_CONFIDENCE;
    let sigma_hours = if s.is_finite() { s } else { 0.0 };
    let bound_hours =
        cliffwatch_core::analysis::failure::upper_bound_hours(h, sigma_hours, confidence)
            .unwrap_or(f64::INFINITY);
    let tf = c.t[i] + h * 3600.0;
    let s = sigma_hours * 3600.0;
    let (lower, upper) = ((tf - 2.0 * s).max(c.t[i]), tf + 2.0 * s);
    let likely_before = c.t[i] + bound_hours * 3600.0;
    let from = c.t[c.t.len().saturating_sub(LINE_EPOCHS)];
    let epochs = c.t.len().min(LINE_EPOCHS);
    let stated = cliffwatch_core::analysis::failure::stated(h, sigma_hours);
    let percent = 100.0 * confidence;
    let text = if stated {
        format!(
            "Failure likely before {} ({percent:.0} %, one-sided, counted from the last epoch). \
             Forecast failure (filtered): {} (±2σ: {} to {}), {:.0} ± {:.0} h (1σ) after the last epoch. \
             The line is the inverse-velocity law ending at the forecast failure time, fitted to the 1/v plotted over the last {epochs} epochs \
             ({} to {}).",
            text(likely_before, tz),
            text(tf, tz),
            text(lower, tz),
            text(upper, tz),
            h,
            sigma_hours,
            // the window in UTC only: the zone is given with the forecast
            text(from, None),
            text(c.t[i], None),
        )
    } else {
        format!(
            "No forecast yet: the point accelerates, but failure is not likely within {:.0} h \
             ({h:.0} ± {sigma_hours:.0} h, 1σ: the {percent:.0} % bound is {bound_hours:.0} h after the last epoch).",
            cliffwatch_core::analysis::failure::NO_FORECAST_BEYOND_HOURS,
        )
    };
    json!({"t_f": tf, "lower": lower, "upper": upper, "likely_before": likely_before,
           "hours": h, "stated": stated,
           "window": {"from": from, "to": c.t[i], "epochs": epochs}, "text": text})
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The columns are JSON that serde_json reads back to the same numbers, NaN as null.
    #[test]
    fn columns_are_json_with_the_values() {
        let mut c = SeriesColumns::default();
        for k in 0..3 {
            let x = 0.1 * k as f64 - 1e-17;
            c.push(&SeriesRow {
                epoch: k - 1,
                t: 1.7e9 + 3600.5 * k as f64,
                d: [x, -x, 1e300, f64::NAN],
                sigma: [0.1; 4],
                along: f64::NAN,
                velocity: 2.5e-7,
                ttf: f64::NAN,
                f_d: [x; 4],
                sigma_f_d: [0.05; 4],
                f_velocity: [f64::INFINITY, 0.01],
                f_ttf: [f64::NAN; 2],
            });
        }
        let mut out = Vec::new();
        write_columns(&c, &mut out);
        out.extend_from_slice(b",\"total\":3}");
        let v: Value = serde_json::from_slice(&out).expect("JSON");
        assert_eq!(v["epoch"], json!([-1, 0, 1]));
        // serde_json's default parse may be one ulp off
        let near = |a: &Value, b: f64| {
            a.as_f64()
                .is_some_and(|a| (a - b).abs() <= 1e-15 * b.abs().max(1e-300))
        };
        for k in 0..3 {
            assert!(near(&v["t"][k], c.t[k]));
            assert!(near(&v["dx"][k], c.d[0][k]));
            assert!(near(&v["dy"][k], c.d[1][k]));
            assert!(near(&v["dz"][k], 1e300));
            assert!(near(&v["velocity"][k], 2.5e-7));
        }
        assert_eq!(v["d"], json!([null, null, null]));
        assert_eq!(v["f_velocity"], json!([null, null, null]));
        assert_eq!(v["along"], json!([null, null, null]));
        assert_eq!(v.as_object().map(|o| o.len()), Some(20));
    }

    /// A series on the inverse-velocity law `d = a − B ln(t_f − t)` with gaps, its forecast
    /// stored as the analysis stores it: the plotted line reaches zero at the printed forecast
    /// time (within one epoch spacing; here to the second), and its slope is the law's −1/B.
    #[test]
    fn the_inverse_line_reaches_zero_at_the_forecast_time() {
        let tf_day = 20_000.0;
        let b = 6.0;
        let mut c = SeriesColumns::default();
        for k in 0..20 {
            if k % 7 == 3 {
                continue; // a missing epoch
            }
            let t = tf_day - 20.0 + k as f64 * 0.9;
            let row = SeriesRow {
                epoch: k,
                t: t * 86_400.0,
                d: [0.0, 0.0, 0.0, 40.0 - b * (tf_day - t).ln()],
                sigma: [0.3; 4],
                along: f64::NAN,
                velocity: f64::NAN,
                ttf: f64::NAN,
                f_d: [f64::NAN; 4],
                sigma_f_d: [f64::NAN; 4],
                f_velocity: [b / (tf_day - t), 0.01],
                f_ttf: [(tf_day - t) * 24.0, 0.1 * (tf_day - t) * 24.0],
            };
            c.push(&row);
        }
        let l = inverse_line(&c).expect("line");
        let f = forecast(&c, None);
        assert!(
            (l[2] - f["t_f"].as_f64().expect("t_f")).abs() < 1.0,
            "{l:?} {f}"
        );
        assert_eq!(l[3], 0.0);
        let slope = (l[3] - l[1]) / ((l[2] - l[0]) / 86_400.0);
        assert!((slope + 1.0 / b).abs() < 1e-9, "{slope}");
        // The window the page names is the line's.
        assert_eq!(f["window"]["from"].as_f64(), Some(l[0]));
        assert!(f["text"]
            .as_str()
            .is_some_and(|t| t.contains("last 12 epochs")));
        assert_eq!(f["stated"], json!(true));
        // 26 ± 35 h: a wide interval whose bound is near is stated, with its bound.
        let last = c.t.len() - 1;
        c.f_ttf[0][last] = 26.0;
        c.f_ttf[1][last] = 35.0;
        let f = forecast(&c, None);
        assert_eq!(f["stated"], json!(true), "{f}");
        let bound = f["likely_before"].as_f64().expect("bound");
        assert!(
            (bound - (c.t[last] + (26.0 + 1.6449 * 35.0) * 3600.0)).abs() < 10.0,
            "{f}"
        );
        assert!(f["text"]
            .as_str()
            .is_some_and(|t| t.starts_with("Failure likely before ")));
        // A bound beyond a week: no line, and the page says "no forecast yet".
        c.f_ttf[0][last] = 70.0;
        c.f_ttf[1][last] = 70.0;
        assert!(inverse_line(&c).is_none());
        let f = forecast(&c, None);
        assert_eq!(f["stated"], json!(false));
        assert!(f["text"]
            .as_str()
            .is_some_and(|t| t.starts_with("No forecast yet")));
    }

    /// Filtered velocities that lag the displacements' law (half its velocity, as a Kalman
    /// filter lags an acceleration): the line is fitted to the 1/v the plot draws, so it runs
    /// through those points (within their ±2σ at every epoch of its window), not beside them.
    #[test]
    fn the_inverse_line_runs_through_the_plotted_points() {
        let tf_day = 20_000.0;
        let b = 6.0;
        let mut c = SeriesColumns::default();
        for k in 0..20 {
            let t = tf_day - 20.0 + k as f64 * 0.9;
            let v = 0.5 * b / (tf_day - t);
            c.push(&SeriesRow {
                epoch: k,
                t: t * 86_400.0,
                d: [0.0, 0.0, 0.0, 40.0 - b * (tf_day - t).ln()],
                sigma: [0.3; 4],
                along: f64::NAN,
                velocity: f64::NAN,
                ttf: f64::NAN,
                f_d: [f64::NAN; 4],
                sigma_f_d: [f64::NAN; 4],
                f_velocity: [v, 0.05 * v],
                f_ttf: [(tf_day - t) * 24.0, 0.1 * (tf_day - t) * 24.0],
            });
        }
        let l = inverse_line(&c).expect("line");
        let mut inside = 0;
        for k in 0..c.t.len() {
            let Some((y, sy)) = plotted_inverse(&c, k).filter(|_| c.t[k] >= l[0]) else {
                continue;
            };
            let line = l[1] * (l[2] - c.t[k]) / (l[2] - l[0]);
            assert!(
                (line - y).abs() <= 2.0 * sy,
                "epoch {k}: line {line}, 1/v {y} ± {sy}"
            );
            inside += 1;
        }
        assert_eq!(inside, LINE_EPOCHS);
    }
}
