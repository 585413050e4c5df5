//! A small server-drawn time plot (SVG) for printed pages and the block page: one value against
//! time with its ±2σ band, horizontal threshold lines and, for inverse velocity, the straight
//! line of the forecast's law down to its zero. The interactive pages use uPlot instead.

use maud::{html, Markup};

use super::layout::level_class;
use crate::analysis::AlertLevel;

const W: f64 = 640.0;
const H: f64 = 200.0;
const LEFT: f64 = 48.0;
const BOTTOM: f64 = 24.0;
const TOP: f64 = 10.0;

/// `t` in seconds since 1970, `v` and `sigma` in the unit of `unit`; `thresholds`: (value, level).
/// Missing values (NaN) are skipped.
pub fn time_plot(
    t: &[f64],
    v: &[f64],
    sigma: &[f64],
    thresholds: &[(f64, AlertLevel)],
    unit: &str,
) -> Markup {
    time_plot_with_line(t, v, sigma, thresholds, unit, None)
}

/// [`time_plot`] with a straight line `[t0, y0, t1, y1]` (s since 1970, the plot's unit) drawn
/// over the values, the time axis extended to its end: the inverse-velocity law of a forecast
/// ([`super::plot_data::inverse_line`]), whose end at zero is the forecast failure time (its
/// `data-zero`, s since 1970).
pub fn time_plot_with_line(
    t: &[f64],
    v: &[f64],
    sigma: &[f64],
    thresholds: &[(f64, AlertLevel)],
    unit: &str,
    line: Option<[f64; 4]>,
) -> Markup {
    let pts: Vec<(f64, f64, f64)> = t
        .iter()
        .zip(v)
        .zip(sigma)
        .filter(|((t, v), _)| t.is_finite() && v.is_finite())
        .map(|((t, v), s)| (*t, *v, if s.is_finite() { *s } else { 0.0 }))
        .collect();
    if pts.is_empty() {
        return html! { p.note { "no values in the period" } };
    }
    let (t0, mut t1) = (pts[0].0, pts[pts.len() - 1].0.max(pts[0].0 + 1.0));
    let line = line.filter(|l| l.iter().all(|x| x.is_finite()) && l[2] > l[0]);
    if let Some(l) = line {
        t1 = t1.max(l[2]);
    }
    let mut lo = pts
        .iter()
        .map(|p| p.1 - 2.0 * p.2)
        .fold(f64::INFINITY, f64::min);
    let mut hi = pts
        .iter()
        .map(|p| p.1 + 2.0 * p.2)
        .fold(f64::NEG_INFINITY, f64::max);
    for (y, _) in thresholds {
        lo = lo.min(*y);
        hi = hi.max(*y);
    }
    if let Some(l) = line {
        lo = lo.min(l[1]).min(l[3]);
        hi = hi.max(l[1]).max(l[3]);
    }
    lo = lo.min(0.0);
    if hi - lo < 1e-9 {
        hi = lo + 1.0;
    }
    let x = |t: f64| LEFT + (t - t0) / (t1 - t0) * (W - LEFT - 8.0);
    let y = |v: f64| TOP + (hi - v) / (hi - lo) * (H - TOP - BOTTOM);
    let path = |k: f64| {
        pts.iter()
            .enumerate()
            .map(|(i, p)| {
                format!(
                    "{}{:.1},{:.1}",
                    if i == 0 { "M" } else { "L" },
                    x(p.0),
                    y(p.1 + k * 2.0 * p.2)
                )
            })
            .collect::<String>()
    };
    let band = {
        let upper: Vec<String> = pts
            .iter()
            .map(|p| format!("{:.1},{:.1}", x(p.0), y(p.1 + 2.0 * p.2)))
            .collect();
        let lower: Vec<String> = pts
            .iter()
            .rev()
            .map(|p| format!("{:.1},{:.1}", x(p.0), y(p.1 - 2.0 * p.2)))
            .collect();
        format!("M{}L{}Z", upper.join("L"), lower.join("L"))
    };
    let day = |t: f64| {
        chrono::DateTime::from_timestamp(t as i64, 0)
            .map(|d| d.format("%Y-%m-%d").to_string())
            .unwrap_or_default()
    };
    html! {
        svg.timeplot viewBox={ "0 0 " (W) " " (H) } xmlns="http://www.w3.org/2000/svg" {
            path.band d=(band) {}
            path.value d=(path(0.0)) {}
            @if let Some(l) = line {
                line.fit data-zero=(format!("{:.0}", l[2])) x1=(format!("{:.1}", x(l[0]))) y1=(format!("{:.1}", y(l[1]))) x2=(format!("{:.1}", x(l[2]))) y2=(format!("{:.1}", y(l[3]))) {}
            }
            @for (v, level) in thresholds {
                line class={ "threshold " (level_class(Some(*level))) } x1=(LEFT) x2=(W - 8.0) y1=(format!("{:.1}", y(*v))) y2=(format!("{:.1}", y(*v))) {}
            }
            line.axis x1=(LEFT) x2=(LEFT) y1=(TOP) y2=(H - BOTTOM) {}
            line.axis x1=(LEFT) x2=(W - 8.0) y1=(H - BOTTOM) y2=(H - BOTTOM) {}
            text x="2" y=(format!("{:.0}", TOP + 8.0)) { (format!("{hi:.1}")) }
            text x="2" y=(format!("{:.0}", H - BOTTOM)) { (format!("{lo:.1}")) }
            text x="2" y=(format!("{:.0}", H / 2.0)) { (unit) }
            text x=(LEFT) y=(H - 6.0) { (day(t0)) }
            text x=(W - 8.0) y=(H - 6.0) text-anchor="end" { (day(t1)) }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_value_band_and_thresholds() {
        let t: Vec<f64> = (0..10).map(|k| 1.7e9 + k as f64 * 86_400.0).collect();
        let v: Vec<f64> = (0..10).map(|k| k as f64).collect();
        let s = vec![0.5; 10];
        let svg = time_plot(&t, &v, &s, &[(5.0, AlertLevel::Watch)], "mm").into_string();
        assert!(svg.contains("class=\"band\"") && svg.contains("class=\"value\""));
        assert!(svg.contains("threshold watch"));
        assert!(svg.matches('L').count() >= 9, "{svg}");
        assert!(time_plot(&[], &[], &[], &[], "mm")
            .into_string()
            .contains("no values"));
    }
}
