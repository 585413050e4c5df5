// cliffwatch dashboard: draws the point page's plots with uPlot from the server's downsampled
// columnar JSON (/dashboard/plot/{site}/{point}?width=N). No other host is contacted.
(function () {
  "use strict";
  var LEVEL = { watch: "#b8860b", warning: "#e8730c", alarm: "#c0392b" };
  var RAW = ["#1f77b4", "#2ca02c", "#9467bd", "#333333"];
  var FILTERED = "#d62728";

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
  // Vertical lines where alerts were raised, escalated, acknowledged, resolved.
  function markers(events) {
    return {
      hooks: {
        draw: [function (u) {
          var ctx = u.ctx;
          ctx.save();
          events.forEach(function (e) {
            if (e.t == null) return;
            var x = u.valToPos(e.t, "x", true);
            if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) return;
            ctx.strokeStyle = LEVEL[e.level] || "#555";
            ctx.setLineDash(e.type === "alert.acknowledged" ? [2, 3] : e.type === "alert.resolved" ? [8, 4] : []);
            ctx.lineWidth = 1.5;
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
  // Value ±2σ as three series (the band's edges dashed and thin).
  function withBand(label, color, v, s) {
    var out = [{ label: label, stroke: color, width: 1.5, values: v }];
    if (s) {
      out.push({ label: label + " +2σ", stroke: color, width: 0.7, dash: [4, 4], values: shift(v, s, 1) });
      out.push({ label: label + " −2σ", stroke: color, width: 0.7, dash: [4, 4], values: shift(v, s, -1) });
    }
    return out;
  }
  function thresholds(d, metrics, n) {
    var out = [];
    (d.thresholds || []).forEach(function (r) {
      if (metrics.indexOf(r.metric) < 0) return;
      var y = r.above != null ? r.above : r.below;
      if (y == null) return;
      out.push({ label: r.level + " " + (r.above != null ? "> " : "< ") + y, stroke: LEVEL[r.level] || "#555", width: 1, dash: [10, 5], values: constant(n, y) });
    });
    return out;
  }
  function draw(el, t, series, events) {
    var opts = {
      width: Math.max(240, el.clientWidth || 800),
      height: 240,
      scales: { x: { time: true } },
      // axis and legend in UTC, as every other time of the dashboard (not the browser's zone)
      tzDate: function (ts) { return uPlot.tzDate(new Date(ts * 1e3), "Etc/UTC"); },
      series: [{ label: "time (UTC)" }].concat(series.map(function (s) {
        return { label: s.label, stroke: s.stroke, width: s.width, dash: s.dash, spanGaps: s.gaps !== true };
      })),
      plugins: [markers(events)]
    };
    return new uPlot(opts, [t].concat(series.map(function (s) { return s.values; })), el);
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
      var s3 = [{ label: "velocity", stroke: RAW[3], width: 1, values: d.velocity }].concat(withBand("filtered velocity", FILTERED, d.f_velocity, d.sf_velocity));
      return draw(el, d.t, s3.concat(thresholds(d, ["velocity_mm_per_day"], n)), ev);
    }
    if (name === "inverse") {
      var inv = d.f_velocity.map(function (v, i) { return v != null && d.sf_velocity[i] != null && v > 2 * d.sf_velocity[i] ? 1 / v : null; });
      var t = d.t.slice(), line = constant(n, null);
      var l = d.inverse_line;
      if (l) {
        for (var i = 0; i < n; i++) if (t[i] >= l[0]) line[i] = l[1] + (l[3] - l[1]) * (t[i] - l[0]) / (l[2] - l[0]);
        if (l[2] > t[n - 1]) { t.push(l[2]); inv.push(null); line.push(l[3]); }
      }
      var f = el.parentNode.querySelector(".forecast");
      if (f) {
        f.textContent = d.forecast
          ? d.forecast.text
          : "No failure forecast: the point does not accelerate significantly.";
      }
      // gaps in 1/v stay gaps (a missing or insignificant velocity is not bridged)
      return draw(el, t, [{ label: "1/v", stroke: RAW[3], width: 1.5, values: inv, gaps: true }, { label: "forecast's law", stroke: FILTERED, width: 1, dash: [6, 3], values: line }], ev);
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
