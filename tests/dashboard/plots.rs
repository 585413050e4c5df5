//! The point page's plots as a reader sees them in Chromium: each ±2σ is one filled band whose
//! edges are the API's value ± 2σ (no dashed edge lines); the legend names every line, band,
//! threshold and kind of alert marker drawn; the three levels have distinct colours, the same on
//! the badges and the threshold lines; the velocity's y-range fits the data after the first
//! epochs; and a still point shows, in words, why it has no inverse-velocity plot instead of an
//! empty frame.

use crate::browser::Driver;
use crate::support;

use serde_json::{json, Value};
use support::dashboard::{fill, name, POINTS, SITE};
use support::server::TestServer;

/// What the plot of `panel` holds: uPlot's bands, series, data and y-scale, the specs drawn,
/// the legend's entries and the markers drawn.
const READ_PANEL: &str = "var el = document.querySelector('.plot[data-panel=' + arguments[0] + ']'); var u = el._uplot; return {bands: u.bands.map(function (b) { return b.series; }), widths: u.series.map(function (s) { return s.width == null ? null : s.width; }), dashed: u.series.map(function (s) { return !!(s.dash && s.dash.length); }), data: u.data, y: [u.scales.y.min, u.scales.y.max], specs: el._specs.map(function (s) { return [s.kind, s.label, s.stroke || s.fill, s.level || null]; }), legend: Array.from(el.parentNode.querySelectorAll('ul.legend li')).map(function (li) { return [li.getAttribute('data-kind'), li.textContent, li.getAttribute('data-mark'), li.querySelector('.swatch') ? getComputedStyle(li.querySelector('.swatch')).borderTopColor : null]; }), drawn: Object.keys(el._drawn).sort()};";

fn rgb(hex: &str) -> String {
    let c = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).unwrap();
    format!("rgb({}, {}, {})", c(1), c(3), c(5))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bands_legends_level_colours_ranges_and_no_empty_frame() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 10, None).await;
    let moving = name(POINTS - 1);
    let (_, series) = s
        .get(&format!(
            "/api/v1/sites/{SITE}/points/{moving}/displacements?limit=1000"
        ))
        .await;
    let items = series["items"].as_array().unwrap().clone();

    driver
        .goto(&s.url(&format!("/sites/{SITE}/points/{moving}")))
        .await;
    driver
        .wait_for("var b = document.querySelector('.plots'); return b.getAttribute('data-drawn') && document.querySelector('.plot[data-panel=inverse]') && document.querySelectorAll('ul.legend').length >= 4")
        .await;
    let call = |panel: &str| {
        format!(
            "return (function () {{ {} }}).apply(null, ['{panel}'])",
            READ_PANEL
        )
    };
    let d = driver.script(&call("d")).await;

    // The d panel: two bands (raw and filtered d), each one filled shape between two
    // invisible series, the raw one's edges the API's d ± 2σ at every epoch.
    let bands = d["bands"].as_array().unwrap();
    assert_eq!(bands.len(), 2, "{d}");
    let t: Vec<f64> = d["data"][0]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(t.len(), items.len(), "every epoch drawn");
    let (upper, lower) = (
        bands[0][0].as_u64().unwrap() as usize,
        bands[0][1].as_u64().unwrap() as usize,
    );
    for (k, item) in items.iter().enumerate() {
        let (v, sigma) = (
            item["d_mm"].as_f64().unwrap(),
            item["sigma_mm"].as_f64().unwrap(),
        );
        let (hi, lo) = (
            d["data"][upper][k].as_f64().unwrap(),
            d["data"][lower][k].as_f64().unwrap(),
        );
        assert!(
            (hi - (v + 2.0 * sigma)).abs() < 1e-6,
            "epoch {k}: {hi} vs {v} + 2·{sigma}"
        );
        assert!(
            (lo - (v - 2.0 * sigma)).abs() < 1e-6,
            "epoch {k}: {lo} vs {v} − 2·{sigma}"
        );
    }
    for b in bands {
        for i in [b[0].as_u64().unwrap(), b[1].as_u64().unwrap()] {
            assert_eq!(
                d["widths"][i as usize],
                json!(0),
                "a band edge draws no line: {d}"
            );
        }
    }

    // The legend: one entry per line, band and threshold drawn, in order, and one per kind of
    // marker drawn; markers were drawn (the point's alert was raised and escalated).
    let legend = d["legend"].as_array().unwrap();
    let specs = d["specs"].as_array().unwrap();
    let of_specs: Vec<Value> = legend
        .iter()
        .filter(|l| l[0] != "marker" && l[0] != "note" && l[0] != "axis")
        .map(|l| json!([l[0], l[1]]))
        .collect();
    let want: Vec<Value> = specs.iter().map(|s| json!([s[0], s[1]])).collect();
    assert_eq!(
        of_specs, want,
        "the legend names every line, band and threshold"
    );
    let marks: Vec<Value> = legend
        .iter()
        .filter(|l| l[0] == "marker")
        .map(|l| l[2].clone())
        .collect();
    assert_eq!(
        json!(marks),
        d["drawn"],
        "one legend entry per kind of marker drawn"
    );
    let drawn = d["drawn"].as_array().unwrap();
    assert!(
        drawn.contains(&json!("alert.raised|watch"))
            && drawn.contains(&json!("alert.escalated|warning")),
        "{drawn:?}"
    );
    assert!(
        legend.iter().any(|l| l[1] == "alert escalated (warning)"),
        "{legend:?}"
    );
    let dashed = d["dashed"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| **x == json!(true))
        .count();
    let threshold_specs = specs.iter().filter(|s| s[0] == "threshold").count();
    assert!(threshold_specs >= 2, "{specs:?}");
    assert_eq!(
        dashed, threshold_specs,
        "only the thresholds are dashed: {d}"
    );

    // Level colours: three distinct ones, the badge's and the threshold line's the same.
    let badges = driver
        .script("return ['watch', 'warning', 'alarm'].map(function (l) { var b = document.createElement('span'); b.className = 'badge ' + l; document.body.appendChild(b); var c = getComputedStyle(b).backgroundColor; b.remove(); return c; })")
        .await;
    let badges: Vec<String> = serde_json::from_value(badges).unwrap();
    assert_eq!(
        badges,
        [rgb("#E69F00"), rgb("#D55E00"), rgb("#882255")],
        "the levels' colours"
    );
    for (level, colour) in [("watch", &badges[0]), ("warning", &badges[1])] {
        let line = legend
            .iter()
            .find(|l| l[0] == "threshold" && l[1].as_str().unwrap().starts_with(level))
            .unwrap_or_else(|| panic!("a {level} threshold in the legend: {legend:?}"));
        assert_eq!(&line[3], colour, "{level}: {line}");
    }

    // The velocity's y-range: every line and threshold, and the bands after the first 3
    // epochs, with at most 5 % margin each side; the first epochs' wider band does not set it.
    let v = driver.script(&call("velocity")).await;
    let (y0, y1) = (v["y"][0].as_f64().unwrap(), v["y"][1].as_f64().unwrap());
    let band_edges: Vec<usize> = v["bands"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|b| {
            [
                b[0].as_u64().unwrap() as usize,
                b[1].as_u64().unwrap() as usize,
            ]
        })
        .collect();
    let (mut lo, mut hi, mut lo_all, mut hi_all) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (i, col) in v["data"].as_array().unwrap().iter().enumerate().skip(1) {
        let from = if band_edges.contains(&i) { 3 } else { 0 };
        for (k, x) in col.as_array().unwrap().iter().enumerate() {
            if let Some(x) = x.as_f64() {
                lo_all = lo_all.min(x);
                hi_all = hi_all.max(x);
                if k >= from {
                    lo = lo.min(x);
                    hi = hi.max(x);
                }
            }
        }
    }
    let pad = 0.05 * (hi - lo);
    assert!(
        (y0 - (lo - pad)).abs() < 1e-6 && (y1 - (hi + pad)).abs() < 1e-6,
        "y-range {y0}..{y1} vs the data after 3 epochs {lo}..{hi}"
    );
    eprintln!(
        "velocity y-range {y0:.2}..{y1:.2} mm/day; with the first epochs' band it would be {lo_all:.2}..{hi_all:.2}"
    );
    // The cut-off first epochs are said, not hidden.
    assert!(
        lo_all < y0 || hi_all > y1,
        "the first epochs' band is wider: {v}"
    );
    let note = v["legend"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l[0] == "note")
        .unwrap_or_else(|| panic!("a note on the cut-off band: {v}"))
        .clone();
    assert!(
        note[1]
            .as_str()
            .unwrap()
            .starts_with("the ±2σ of the first 3 epochs reaches beyond the plot"),
        "{note}"
    );
    driver
        .script(
            "document.querySelector('.plot[data-panel=velocity]').scrollIntoView(); return true",
        )
        .await;
    driver.screenshot("plots-moving.png").await;

    // A still point: no inverse-velocity frame, the reason in words instead.
    driver
        .goto(&s.url(&format!("/sites/{SITE}/points/{}", name(0))))
        .await;
    let still = driver
        .wait_for("var b = document.querySelector('.plots'); return b.getAttribute('data-drawn') && document.querySelectorAll('ul.legend').length >= 3 ? [document.querySelectorAll('.plot[data-panel=inverse]').length, Array.from(document.querySelectorAll('.plots figure')).pop().querySelectorAll('canvas').length, (document.querySelector('p.no-plot') || {}).textContent || null, document.querySelector('p.forecast').textContent] : null")
        .await;
    assert_eq!(still[0], json!(0), "no inverse-velocity frame: {still}");
    assert_eq!(still[1], json!(0), "no canvas in its figure: {still}");
    assert!(
        still[2].as_str().is_some_and(|t| t.starts_with(
            "No inverse-velocity plot: the filtered velocity is never significantly above zero"
        )),
        "{still}"
    );
    driver
        .script("document.querySelector('p.no-plot').scrollIntoView(); return true")
        .await;
    driver.screenshot("plots-still.png").await;
    driver.quit().await;
    s.stop().await;
}
