//! A small server-drawn time plot (SVG) for printed pages and the block page: one value against
//! time with its ±2σ band (one filled shape), horizontal threshold lines and, for inverse
//! velocity, the straight line of the forecast's law down to its zero; value ticks at round
//! steps, date ticks, and a legend under it naming each line, band and threshold drawn. The
//! interactive pages use uPlot instead.

use maud::{html, Markup};

use super::layout::level_class;
use cliffwatch_core::analysis::AlertLevel;

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
/// `data-zero`, s since 1970; its start `data-t0`, s since 1970, at `data-y0`, the plot's unit).
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
    let y_ticks = ticks(lo, hi);
    // Date ticks: about five, at whole days when the period spans days.
    let x_ticks: Vec<f64> = {
        let n = 4.0;
        let step = ((t1 - t0) / n / 86_400.0).ceil().max(1.0) * 86_400.0;
        let first = (t0 / 86_400.0).ceil() * 86_400.0;
        // The last label is the end's (e.g. the forecast failure day): none too close to it.
        (0..)
            .map(|k| first + k as f64 * step)
            .take_while(|t| *t <= t1 - 0.6 * step)
            .take(8)
            .collect()
    };
    let banded = pts.iter().any(|p| p.2 > 0.0);
    html! {
        svg.timeplot viewBox={ "0 0 " (W) " " (H) } xmlns="http://www.w3.org/2000/svg" {
            path.band d=(band) {}
            path.value d=(path(0.0)) {}
            @if let Some(l) = line {
                line.fit data-zero=(format!("{:.0}", l[2])) data-t0=(format!("{:.0}", l[0])) data-y0=(format!("{}", l[1])) x1=(format!("{:.1}", x(l[0]))) y1=(format!("{:.1}", y(l[1]))) x2=(format!("{:.1}", x(l[2]))) y2=(format!("{:.1}", y(l[3]))) {}
            }
            @for (v, level) in thresholds {
                line class={ "threshold " (level_class(Some(*level))) } x1=(LEFT) x2=(W - 8.0) y1=(format!("{:.1}", y(*v))) y2=(format!("{:.1}", y(*v))) {}
            }
            line.axis x1=(LEFT) x2=(LEFT) y1=(TOP) y2=(H - BOTTOM) {}
            line.axis x1=(LEFT) x2=(W - 8.0) y1=(H - BOTTOM) y2=(H - BOTTOM) {}
            @for v in &y_ticks {
                line.grid x1=(LEFT) x2=(W - 8.0) y1=(format!("{:.1}", y(*v))) y2=(format!("{:.1}", y(*v))) {}
                text.tick x=(LEFT - 3.0) y=(format!("{:.1}", y(*v) + 3.0)) text-anchor="end" { (tick_text(*v, &y_ticks)) }
            }
            text x="2" y=(format!("{:.0}", TOP + 2.0)) { (unit) }
            @for t in &x_ticks {
                line.grid x1=(format!("{:.1}", x(*t))) x2=(format!("{:.1}", x(*t))) y1=(TOP) y2=(H - BOTTOM) {}
                text.tick x=(format!("{:.1}", x(*t))) y=(H - 8.0) text-anchor="middle" { (day(*t)) }
            }
            text.tick x=(W - 8.0) y=(H - 8.0) text-anchor="end" { (day(t1)) }
        }
        ul.legend {
            li data-kind="line" { span.swatch.value {} "value (" (unit) ")" }
            @if banded { li data-kind="band" { span.swatch.band {} "±2σ" } }
            @if line.is_some() { li data-kind="line" { span.swatch.fit {} "forecast's inverse-velocity law (zero: failure time)" } }
            @for (v, level) in thresholds {
                li data-kind="threshold" { span class={ "swatch threshold " (level_class(Some(*level))) } {} (level_class(Some(*level))) " threshold " (v) " " (unit) }
            }
        }
    }
}

/// Round value ticks within `[lo, hi]`: steps of 1, 2 or 5 × 10ⁿ, three to seven of them.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    if raw.is_nan() || raw <= 0.0 || !raw.is_finite() {
        return vec![lo];
    }
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|k| k * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick's text with as many decimals as the step needs.
fn tick_text(v: f64, ticks: &[f64]) -> String {
    let step = match ticks {
        [a, b, ..] => (b - a).abs(),
        _ => 1.0,
    };
    let digits = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    format!("{v:.digits$}")
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
        // The legend names the line, the band and the threshold; the value ticks are round.
        assert!(svg.contains("data-kind=\"band\"") && svg.contains("watch threshold 5 mm"));
        assert_eq!(ticks(-0.3, 10.7), [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(tick_text(0.25, &[0.0, 0.05]), "0.25");
        assert!(time_plot(&[], &[], &[], &[], "mm")
            .into_string()
            .contains("no values"));
    }
}
