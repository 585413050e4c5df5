// cliffwatch dashboard: draws the point page's plots with uPlot from the server's downsampled
// columnar JSON (/dashboard/plot/{site}/{point}?width=N). No other host is contacted.
//
// Each plot: lines, ±2σ bands (one filled shape between value − 2σ and value + 2σ), threshold
// lines and vertical alert markers, with a legend under it naming every one drawn. The levels'
// colours are colour-blind safe (Okabe–Ito orange and vermillion, Tol's wine; the same as
// dashboard.css and src/dashboard/level_colours.rs) and thresholds differ by dash as well. The
// y-range fits the data after the first epochs, whose wide ±2σ (a velocity from two epochs)
// would flatten the rest; a plot without data says why in words instead of an empty frame.
(function () {
  "use strict";
  var LEVEL = { watch: "#E69F00", warning: "#D55E00", alarm: "#882255" };
  var LEVEL_DASH = { watch: [2, 3], warning: [8, 4], alarm: [] };
  var RAW = ["#0072B2", "#009E73", "#56B4E9", "#333333"];
  var FILTERED = "#CC79A7";
  // Epochs at the start whose ±2σ band the y-range leaves out (when there are enough after).
  var SKIP = 3;
  var EVENT_WORDS = {
    "alert.raised": "alert raised", "alert.escalated": "alert escalated", "alert.deescalated": "alert de-escalated",
    "alert.acknowledged": "alert acknowledged", "alert.resolved": "alert resolved"
  };
  var EVENT_DASH = { "alert.acknowledged": [2, 3], "alert.resolved": [8, 4] };

  function ready(fn) {
    if (document.readyState !== "loading") fn();
    else document.addEventListener("DOMContentLoaded", fn);
  }
  function shift(v, s, k) {
    return v.map(function (x, i) {
      return x == null || s[i] == null ? null : x + k * 2 * s[i];
    });
  }
  function constant(n, y) {
    var out = new Array(n);
    for (var i = 0; i < n; i++) out[i] = y;
    return out;
  }
  function rgba(hex, a) {
    var n = parseInt(hex.slice(1), 16);
    return "rgba(" + (n >> 16) + ", " + ((n >> 8) & 255) + ", " + (n & 255) + ", " + a + ")";
  }
  // Vertical lines where alerts were raised, escalated, acknowledged, resolved; `drawn` collects
  // the kinds drawn ("type|level") for the legend.
  function markers(events, drawn) {
    return {
      hooks: {
        draw: [function (u) {
          var ctx = u.ctx;
          ctx.save();
          events.forEach(function (e) {
            if (e.t == null) return;
            var x = u.valToPos(e.t, "x", true);
            if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) return;
            drawn[e.type + "|" + (e.level || "")] = e;
            ctx.strokeStyle = LEVEL[e.level] || "#555";
            ctx.setLineDash((EVENT_DASH[e.type] || []).map(function (d) { return d * devicePixelRatio; }));
            ctx.lineWidth = 1.5 * devicePixelRatio;
            ctx.beginPath();
            ctx.moveTo(x, u.bbox.top);
            ctx.lineTo(x, u.bbox.top + u.bbox.height);
            ctx.stroke();
          });
          ctx.restore();
        }]
      }
    };
  }
  // A value line and, with σ, its ±2σ band.
  function withBand(label, color, v, s) {
    var out = [{ kind: "line", label: label, stroke: color, width: 1.5, values: v }];
    if (s) out.push({ kind: "band", label: label + " ±2σ", fill: rgba(color, 0.18), upper: shift(v, s, 1), lower: shift(v, s, -1) });
    return out;
  }
  function thresholds(d, metrics, n) {
    var out = [];
    (d.thresholds || []).forEach(function (r) {
      if (metrics.indexOf(r.metric) < 0) return;
      var y = r.above != null ? r.above : r.below;
      if (y == null) return;
      out.push({ kind: "threshold", level: r.level, label: r.level + " threshold " + (r.above != null ? "> " : "< ") + y, stroke: LEVEL[r.level] || "#555", width: 1.5, dash: LEVEL_DASH[r.level], values: constant(n, y) });
    });
    return out;
  }
  // The y-range: every line and threshold, and the bands after the first SKIP epochs (all of
  // them when there are fewer than 3·SKIP), with 5 % margin.
  function yRange(specs, n) {
    var lo = Infinity, hi = -Infinity, from = n >= 3 * SKIP ? SKIP : 0;
    function take(v, start) {
      for (var i = start; i < v.length; i++) if (v[i] != null && isFinite(v[i])) { lo = Math.min(lo, v[i]); hi = Math.max(hi, v[i]); }
    }
    specs.forEach(function (s) {
      if (s.kind === "band") { take(s.upper, from); take(s.lower, from); } else take(s.values, 0);
    });
    if (!isFinite(lo)) return [0, 1];
    if (hi - lo < 1e-9) { lo -= 0.5; hi += 0.5; }
    var pad = 0.05 * (hi - lo);
    return [lo - pad, hi + pad];
  }
  // Whether a band's first epochs reach beyond `range` (they are then clipped).
  function clipped(specs, range) {
    return specs.some(function (s) {
      if (s.kind !== "band") return false;
      for (var i = 0; i < Math.min(SKIP, s.upper.length); i++) {
        if ((s.upper[i] != null && s.upper[i] > range[1]) || (s.lower[i] != null && s.lower[i] < range[0])) return true;
      }
      return false;
    });
  }
  function swatch(li, style) {
    var sw = document.createElement("span");
    sw.className = "swatch";
    for (var k in style) sw.style[k] = style[k];
    li.appendChild(sw);
  }
  function dashCss(dash) {
    return dash && dash.length ? (dash[0] <= 2 ? "dotted" : "dashed") : "solid";
  }
  // The legend: one entry per line, band, threshold and kind of marker drawn.
  function legend(el, specs, drawn, clip) {
    var ul = document.createElement("ul");
    ul.className = "legend";
    var axis = document.createElement("li");
    axis.setAttribute("data-kind", "axis");
    axis.textContent = "time (UTC)";
    ul.appendChild(axis);
    specs.forEach(function (s) {
      var li = document.createElement("li");
      li.setAttribute("data-kind", s.kind);
      if (s.kind === "band") swatch(li, { background: s.fill, height: "10px" });
      else swatch(li, { borderTop: "2px " + dashCss(s.dash) + " " + s.stroke });
      li.appendChild(document.createTextNode(s.label));
      ul.appendChild(li);
    });
    Object.keys(drawn).sort().forEach(function (k) {
      var e = drawn[k], li = document.createElement("li");
      li.setAttribute("data-kind", "marker");
      li.setAttribute("data-mark", k);
      swatch(li, { borderLeft: "2px " + dashCss(EVENT_DASH[e.type]) + " " + (LEVEL[e.level] || "#555"), height: "12px", width: "0" });
      li.appendChild(document.createTextNode((EVENT_WORDS[e.type] || e.type) + (e.level ? " (" + e.level + ")" : "")));
      ul.appendChild(li);
    });
    if (clip) {
      var li = document.createElement("li");
      li.setAttribute("data-kind", "note");
      li.textContent = "the ±2σ of the first " + SKIP + " epochs reaches beyond the plot (cut off, so that the rest is readable)";
      ul.appendChild(li);
    }
    var old = el.parentNode.querySelector("ul.legend");
    if (old) old.remove();
    el.insertAdjacentElement("afterend", ul);
  }
  function draw(el, t, specs, events) {
    var series = [{ label: "time (UTC)" }], data = [t], bands = [], drawn = {};
    specs.forEach(function (s) {
      if (s.kind === "band") {
        var iu = data.length;
        series.push({ label: s.label + " upper", stroke: "transparent", width: 0, points: { show: false } });
        series.push({ label: s.label + " lower", stroke: "transparent", width: 0, points: { show: false } });
        data.push(s.upper, s.lower);
        bands.push({ series: [iu, iu + 1], fill: s.fill });
      } else {
        series.push({ label: s.label, stroke: s.stroke, width: s.width, dash: s.dash, spanGaps: s.gaps !== true, points: s.kind === "threshold" ? { show: false } : {} });
        data.push(s.values);
      }
    });
    var range = yRange(specs, t.length), clip = clipped(specs, range);
    var opts = {
      width: Math.max(240, el.clientWidth || 800),
      height: 240,
      scales: { x: { time: true }, y: { range: function () { return range; } } },
      // axis in UTC, as every other time of the dashboard (not the browser's zone)
      tzDate: function (ts) { return uPlot.tzDate(new Date(ts * 1e3), "Etc/UTC"); },
      legend: { show: false },
      series: series,
      bands: bands,
      // the legend follows each drawing, so it names the markers that drawing showed
      plugins: [markers(events, drawn), { hooks: { draw: [function () { legend(el, specs, drawn, clip); }] } }]
    };
    var u = new uPlot(opts, data, el);
    el._uplot = u;
    el._specs = specs;
    el._drawn = drawn;
    return u;
  }
  // In place of a plot: why there is none.
  function none(el, words) {
    var p = document.createElement("p");
    p.className = "no-plot note";
    p.textContent = words;
    el.replaceWith(p);
  }
  function panel(el, name, d) {
    var n = d.t.length, ev = d.events || [];
    if (name === "xyz") {
      var s = [];
      ["dx", "dy", "dz"].forEach(function (k, i) { s = s.concat(withBand(k, RAW[i], d[k], d["s" + k])); });
      return draw(el, d.t, s, ev);
    }
    if (name === "d") {
      var s2 = withBand("d", RAW[3], d.d, d.sd).concat(withBand("filtered d", FILTERED, d.f_d, d.sf_d));
      return draw(el, d.t, s2.concat(thresholds(d, ["displacement_mm"], n)), ev);
    }
    if (name === "along") {
      return draw(el, d.t, withBand("d along", RAW[0], d.along, d.sd).concat(thresholds(d, ["displacement_along_mm"], n)), ev);
    }
    if (name === "velocity") {
      var s3 = [{ kind: "line", label: "velocity (raw)", stroke: RAW[3], width: 1, values: d.velocity }].concat(withBand("filtered velocity", FILTERED, d.f_velocity, d.sf_velocity));
      return draw(el, d.t, s3.concat(thresholds(d, ["velocity_mm_per_day"], n)), ev);
    }
    if (name === "inverse") {
      // 1/v and its σ (σ_v / v²) where the filtered velocity is significantly forward (v > 2σ),
      // as the block page draws it and as the line is fitted (plot_data::plotted_inverse).
      var sig = function (v, i) { return v != null && d.sf_velocity[i] != null && v > 2 * d.sf_velocity[i]; };
      var inv = d.f_velocity.map(function (v, i) { return sig(v, i) ? 1 / v : null; });
      var sinv = d.f_velocity.map(function (v, i) { return sig(v, i) ? d.sf_velocity[i] / (v * v) : null; });
      var f = el.parentNode.querySelector(".forecast");
      if (f) {
        f.textContent = d.forecast
          ? d.forecast.text
          : "No failure forecast: the point does not accelerate significantly.";
      }
      if (!inv.some(function (x) { return x != null; })) {
        return none(el, "No inverse-velocity plot: the filtered velocity is never significantly above zero (v > 2σ) in this series, so there is no 1/v to draw and no inverse-velocity law to fit.");
      }
      var t = d.t.slice(), line = constant(n, null);
      var l = d.inverse_line;
      if (l) {
        for (var i = 0; i < n; i++) if (t[i] >= l[0]) line[i] = l[1] + (l[3] - l[1]) * (t[i] - l[0]) / (l[2] - l[0]);
        if (l[2] > t[n - 1]) { t.push(l[2]); inv.push(null); sinv.push(null); line.push(l[3]); }
      }
      // gaps in 1/v stay gaps (a missing or insignificant velocity is not bridged)
      var s4 = withBand("1/v (filtered, where v > 2σ)", RAW[3], inv, sinv);
      s4[0].gaps = true;
      if (l) s4.push({ kind: "line", label: "forecast's inverse-velocity law", stroke: FILTERED, width: 1.5, dash: [6, 3], values: line });
      return draw(el, t, s4, ev);
    }
  }
  ready(function () {
    document.querySelectorAll(".plots[data-src]").forEach(function (box) {
      var width = Math.round(box.clientWidth || 800);
      fetch(box.getAttribute("data-src") + "?width=" + width, { credentials: "same-origin" })
        .then(function (r) { if (!r.ok) throw new Error("plot data: HTTP " + r.status); return r.json(); })
        .then(function (d) {
          box.querySelectorAll(".plot[data-panel]").forEach(function (el) { panel(el, el.getAttribute("data-panel"), d); });
          box.setAttribute("data-drawn", String(d.t.length));
          box.setAttribute("data-total", String(d.total));
        })
        .catch(function (e) {
          box.setAttribute("data-error", String(e));
          box.insertAdjacentText("afterbegin", String(e));
        });
    });
  });
})();
