/* flowtwin report: small canvas charts (time tracks with min/max envelopes, bar charts).
 * A TimeChart draws channels given as min and max per time bucket; its y range is set by the
 * caller (e.g. the printing flow), values beyond it are clipped and marked at the edge.
 * Wheel zooms the time axis at the cursor, drag pans, double click resets; charts given the
 * same `link` object share their time window. */
"use strict";
var FT = window.FT || (window.FT = {});

FT.niceTicks = function (lo, hi, count) {
  var span = hi - lo;
  if (!(span > 0)) return [lo];
  var step = Math.pow(10, Math.floor(Math.log10(span / count)));
  var err = span / count / step;
  if (err >= 7.5) step *= 10; else if (err >= 3.5) step *= 5; else if (err >= 1.5) step *= 2;
  var out = [];
  for (var v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  return out;
};

/* An axis tick: no trailing zeros. */
FT.tick = function (v) { return String(+v.toPrecision(6)); };

FT.fmtTime = function (s) {
  if (!isFinite(s)) return "–";
  var h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  if (h) return h + ":" + String(m).padStart(2, "0") + ":" + String(Math.floor(sec)).padStart(2, "0");
  if (m) return m + ":" + sec.toFixed(0).padStart(2, "0");
  return sec.toFixed(sec < 10 ? 2 : 1) + " s";
};

FT.TimeChart = (function () {
  var PAD = { l: 58, r: 14, t: 10, b: 26 };

  function TimeChart(canvas, opts) {
    this.canvas = canvas; this.o = opts; this.series = opts.series; this.link = opts.link;
    this.full = false;
    this.link.charts.push(this);
    this._events();
  }

  TimeChart.prototype.setData = function (series, t0, dt, nb, marks, yRange) {
    this.series = series; this.t0 = t0; this.dt = dt; this.nb = nb; this.marks = marks;
    this.yRange = yRange;
    this.draw();
  };

  TimeChart.prototype._x = function (t, w) { var L = this.link; return PAD.l + (t - L.a) / (L.b - L.a) * w; };

  TimeChart.prototype.draw = function () {
    var c = this.canvas, r = window.devicePixelRatio || 1;
    var W = Math.max(1, c.clientWidth), H = Math.max(1, c.clientHeight);
    if (c.width !== Math.round(W * r)) { c.width = Math.round(W * r); c.height = Math.round(H * r); }
    var g = c.getContext("2d");
    g.setTransform(r, 0, 0, r, 0, 0);
    g.clearRect(0, 0, W, H);
    if (!this.series) return;
    var w = W - PAD.l - PAD.r, h = H - PAD.t - PAD.b, L = this.link;
    var y0 = this.full ? this._fullRange()[0] : this.yRange[0];
    var y1 = this.full ? this._fullRange()[1] : this.yRange[1];
    var Y = function (v) { return PAD.t + (1 - (v - y0) / (y1 - y0)) * h; };
    g.font = "11px system-ui, sans-serif"; g.fillStyle = "#555"; g.strokeStyle = "#e3e3e3";
    g.lineWidth = 1;
    var yt = FT.niceTicks(y0, y1, 4);
    g.textAlign = "right"; g.textBaseline = "middle";
    for (var i = 0; i < yt.length; i++) {
      var yy = Math.round(Y(yt[i])) + 0.5;
      g.beginPath(); g.moveTo(PAD.l, yy); g.lineTo(PAD.l + w, yy); g.stroke();
      g.fillText(FT.tick(yt[i]), PAD.l - 4, yy);
    }
    var xt = FT.niceTicks(L.a, L.b, Math.max(2, Math.floor(w / 90)));
    g.textAlign = "center"; g.textBaseline = "top";
    for (var j = 0; j < xt.length; j++) {
      var xx = Math.round(this._x(xt[j], w)) + 0.5;
      g.beginPath(); g.moveTo(xx, PAD.t); g.lineTo(xx, PAD.t + h); g.stroke();
      g.fillText(FT.fmtTime(xt[j]), xx, PAD.t + h + 4);
    }
    g.save();
    g.translate(11, PAD.t + h / 2); g.rotate(-Math.PI / 2); g.textAlign = "center";
    g.textBaseline = "middle"; g.fillText(this.o.yLabel, 0, 0);
    g.restore();
    g.save();
    g.beginPath(); g.rect(PAD.l, PAD.t, w, h); g.clip();
    for (var s = 0; s < this.series.length; s++) this._drawSeries(g, this.series[s], w, h, Y, y0, y1);
    if (this.o.hline !== undefined && isFinite(this.o.hline)) {
      g.strokeStyle = "#c0392b"; g.setLineDash([5, 4]);
      var hy = Y(this.o.hline); g.beginPath(); g.moveTo(PAD.l, hy); g.lineTo(PAD.l + w, hy); g.stroke();
      g.setLineDash([]);
    }
    g.restore();
    if (this.marks && this.marks.length) this._drawMarks(g, w, h);
    if (this.cursor !== undefined) {
      g.strokeStyle = "rgba(0,0,0,0.35)";
      var cxp = this._x(this.cursor, w); g.beginPath(); g.moveTo(cxp, PAD.t); g.lineTo(cxp, PAD.t + h); g.stroke();
    }
    g.strokeStyle = "#999"; g.strokeRect(PAD.l + 0.5, PAD.t + 0.5, w, h);
  };

  TimeChart.prototype._fullRange = function () {
    var lo = Infinity, hi = -Infinity;
    for (var s = 0; s < this.series.length; s++) {
      var S = this.series[s];
      for (var i = 0; i < S.lo.length; i++) {
        if (S.lo[i] < lo) lo = S.lo[i]; if (S.hi[i] > hi) hi = S.hi[i];
      }
    }
    if (!(hi > lo)) return this.yRange;
    var pad = (hi - lo) * 0.05;
    return [lo - pad, hi + pad];
  };

  /* One column per pixel: the min and max of the buckets under it; a line through the
   * bucket means when zoomed in. Values beyond the range are drawn at the edge in red. */
  TimeChart.prototype._drawSeries = function (g, S, w, h, Y, y0, y1) {
    var L = this.link, dt = this.dt, t0 = this.t0, nb = S.lo.length;
    var perPx = (L.b - L.a) / w / dt, clipTop = [], clipBot = [];
    var clampY = function (v) { return Y(Math.max(y0, Math.min(y1, v))); };
    g.strokeStyle = S.color; g.fillStyle = S.color; g.lineWidth = 1;
    var cols = [];           // [x, lo, hi, mean] per pixel column or per bucket
    if (perPx >= 1) {
      for (var px = 0; px < w; px++) {
        var ta = L.a + px / w * (L.b - L.a), tb = ta + (L.b - L.a) / w;
        var ia = Math.max(0, Math.floor((ta - t0) / dt)), ib = Math.min(nb, Math.ceil((tb - t0) / dt));
        var lo = Infinity, hi = -Infinity, sum = 0, cnt = 0;
        for (var i = ia; i < ib; i++) {
          var a = S.lo[i], b = S.hi[i], m = S.mean[i];
          if (a === a && a < lo) lo = a; if (b === b && b > hi) hi = b;
          if (m === m) { sum += m; cnt++; }
        }
        cols.push(hi >= lo ? [PAD.l + px + 0.5, lo, hi, sum / cnt] : null);
      }
    } else {
      var ia2 = Math.max(0, Math.floor((L.a - t0) / dt) - 1), ib2 = Math.min(nb, Math.ceil((L.b - t0) / dt) + 1);
      for (var k = ia2; k < ib2; k++) {
        cols.push(S.lo[k] === S.lo[k] ? [this._x(t0 + (k + 0.5) * dt, w), S.lo[k], S.hi[k], S.mean[k]] : null);
      }
    }
    var half = perPx >= 1 ? 0.5 : Math.max(0.5, w / ((L.b - L.a) / dt) / 2);
    g.globalAlpha = S.band === undefined ? 0.28 : S.band; g.beginPath();
    for (var c = 0; c < cols.length; c++) {
      var C = cols[c];
      if (!C) continue;
      if (C[2] > y1) clipTop.push(C[0]); if (C[1] < y0) clipBot.push(C[0]);
      var top = clampY(C[2]), bot = clampY(C[1]);
      g.rect(C[0] - half, top, 2 * half, Math.max(bot - top, 1));
    }
    g.fill(); g.globalAlpha = 1;
    g.beginPath();
    var started = false;
    for (var q = 0; q < cols.length; q++) {
      var D = cols[q];
      if (!D) { started = false; continue; }
      var ym = clampY(D[3]);
      if (started) g.lineTo(D[0], ym); else { g.moveTo(D[0], ym); started = true; }
    }
    g.lineWidth = 1.3; g.stroke(); g.lineWidth = 1;
    g.fillStyle = "#c0392b";
    for (var u = 0; u < clipTop.length; u++) g.fillRect(clipTop[u] - 0.5, PAD.t, 1, 4);
    for (var v = 0; v < clipBot.length; v++) g.fillRect(clipBot[v] - 0.5, PAD.t + h - 4, 1, 4);
  };

  TimeChart.prototype._drawMarks = function (g, w, h) {
    var L = this.link, last = -10;
    g.fillStyle = "#7f8c8d";
    for (var i = 0; i < this.marks.length; i++) {
      var t = this.marks[i];
      if (t < L.a || t > L.b) continue;
      var x = this._x(t, w);
      if (x - last < 2) continue;
      last = x;
      g.beginPath(); g.moveTo(x, PAD.t + h + 1); g.lineTo(x - 3, PAD.t + h + 6); g.lineTo(x + 3, PAD.t + h + 6);
      g.fill();
    }
  };

  TimeChart.prototype._timeAt = function (ev) {
    var rect = this.canvas.getBoundingClientRect(), w = rect.width - PAD.l - PAD.r, L = this.link;
    return L.a + (ev.clientX - rect.left - PAD.l) / w * (L.b - L.a);
  };

  TimeChart.prototype._events = function () {
    var self = this, c = this.canvas, drag = null, moved = false;
    c.addEventListener("wheel", function (ev) {
      ev.preventDefault();
      var L = self.link, t = self._timeAt(ev), f = Math.exp(ev.deltaY * 0.0015);
      var a = t - (t - L.a) * f, b = t + (L.b - t) * f;
      L.set(a, b);
    }, { passive: false });
    c.addEventListener("pointerdown", function (ev) { drag = ev.clientX; moved = false; c.setPointerCapture(ev.pointerId); });
    c.addEventListener("pointermove", function (ev) {
      var L = self.link;
      if (drag !== null) {
        var rect = c.getBoundingClientRect(), w = rect.width - PAD.l - PAD.r;
        var dt = (ev.clientX - drag) / w * (L.b - L.a);
        if (Math.abs(ev.clientX - drag) > 2) moved = true;
        drag = ev.clientX;
        L.set(L.a - dt, L.b - dt);
        return;
      }
      L.hover(self._timeAt(ev));
    });
    c.addEventListener("pointerup", function (ev) {
      if (drag !== null && !moved && self.o.onClick) self.o.onClick(self._timeAt(ev));
      drag = null;
    });
    c.addEventListener("pointerleave", function () { self.link.hover(undefined); });
    c.addEventListener("dblclick", function () { self.link.reset(); });
  };

  return TimeChart;
})();

/* Shared time window of several charts. */
FT.TimeLink = function (t0, t1, onHover) {
  var link = {
    a: t0, b: t1, charts: [],
    set: function (a, b) {
      var span = Math.max(b - a, (t1 - t0) * 1e-6);
      if (span > t1 - t0) { a = t0; b = t1; } else {
        if (a < t0) { a = t0; b = t0 + span; }
        if (b > t1) { b = t1; a = t1 - span; }
      }
      link.a = a; link.b = b;
      link.charts.forEach(function (c) { c.draw(); });
    },
    reset: function () { link.set(t0, t1); },
    hover: function (t) {
      link.charts.forEach(function (c) { c.cursor = t; c.draw(); });
      if (onHover) onHover(t);
    }
  };
  return link;
};

/* Bars per category: up to two values per bar (above and below zero), optional click. */
FT.BarChart = function (canvas, opts) {
  var c = canvas, r = window.devicePixelRatio || 1, W = c.clientWidth, H = c.clientHeight;
  c.width = Math.round(W * r); c.height = Math.round(H * r);
  var g = c.getContext("2d"), PAD = { l: 52, r: 10, t: 10, b: 22 };
  g.setTransform(r, 0, 0, r, 0, 0); g.clearRect(0, 0, W, H);
  var up = opts.up, down = opts.down || null, n = up.length, w = W - PAD.l - PAD.r, h = H - PAD.t - PAD.b;
  var vals = [];
  for (var i = 0; i < n; i++) {
    if (isFinite(up[i])) vals.push(Math.abs(up[i]));
    if (down && isFinite(down[i])) vals.push(Math.abs(down[i]));
  }
  vals.sort(function (a, b) { return a - b; });
  var cap = vals.length ? vals[Math.min(vals.length - 1, Math.floor(vals.length * 0.97))] * 1.3 : 1;
  cap = Math.max(cap, opts.minSpan || 1e-9);
  var lo = down ? -cap : 0, hi = cap;
  var Y = function (v) { return PAD.t + (1 - (v - lo) / (hi - lo)) * h; };
  g.font = "11px system-ui, sans-serif"; g.fillStyle = "#555"; g.strokeStyle = "#e3e3e3";
  g.textAlign = "right"; g.textBaseline = "middle";
  FT.niceTicks(lo, hi, 4).forEach(function (t) {
    var y = Math.round(Y(t)) + 0.5;
    g.beginPath(); g.moveTo(PAD.l, y); g.lineTo(PAD.l + w, y); g.stroke();
    g.fillText(FT.tick(t), PAD.l - 4, y);
  });
  var bw = w / Math.max(n, 1);
  function bar(v, color) {
    if (!isFinite(v)) return;
    var clipped = v > hi || v < lo, vv = Math.max(lo, Math.min(hi, v));
    g.fillStyle = clipped ? "#7b241c" : color;
    var y0 = Y(0), y1 = Y(vv);
    g.fillRect(PAD.l + k * bw + (bw > 3 ? 0.5 : 0), Math.min(y0, y1), Math.max(bw - (bw > 3 ? 1 : 0), 0.6), Math.max(Math.abs(y1 - y0), 0.5));
  }
  for (var k = 0; k < n; k++) {
    bar(up[k], opts.upColor || "#d35400");
    if (down) bar(down[k], opts.downColor || "#2471a3");
  }
  g.textAlign = "center"; g.textBaseline = "top"; g.fillStyle = "#555";
  var step = Math.max(1, Math.ceil(n / Math.max(1, Math.floor(w / 40))));
  for (var j = 0; j < n; j += step) g.fillText(String(opts.labels[j]), PAD.l + (j + 0.5) * bw, PAD.t + h + 4);
  g.save(); g.translate(11, PAD.t + h / 2); g.rotate(-Math.PI / 2); g.textAlign = "center";
  g.textBaseline = "middle"; g.fillText(opts.yLabel, 0, 0); g.restore();
  g.strokeStyle = "#999"; g.strokeRect(PAD.l + 0.5, PAD.t + 0.5, w, h);
  if (opts.onClick && !c._ftClick) {
    c._ftClick = true;
    c.addEventListener("click", function (ev) {
      var rect = c.getBoundingClientRect(), x = ev.clientX - rect.left - PAD.l;
      var idx = Math.floor(x / (rect.width - PAD.l - PAD.r) * c._ftN);
      if (idx >= 0 && idx < c._ftN) c._ftOnClick(idx);
    });
  }
  c._ftN = n; c._ftOnClick = opts.onClick;
};

/* Horizontal bars per category around zero (e.g. worst under- and over-extrusion per
 * feature); names are drawn as canvas text. */
FT.HBarChart = function (canvas, opts) {
  var n = opts.labels.length, rowH = 22, PAD = { l: 170, r: 100, t: 18, b: 6 };
  canvas.style.height = (PAD.t + PAD.b + rowH * Math.max(n, 1)) + "px";
  var c = canvas, r = window.devicePixelRatio || 1, W = c.clientWidth, H = c.clientHeight;
  c.width = Math.round(W * r); c.height = Math.round(H * r);
  var g = c.getContext("2d"), w = W - PAD.l - PAD.r;
  g.setTransform(r, 0, 0, r, 0, 0); g.clearRect(0, 0, W, H);
  var vals = [];
  for (var i = 0; i < n; i++) {
    if (isFinite(opts.right[i])) vals.push(Math.abs(opts.right[i]));
    if (isFinite(opts.left[i])) vals.push(Math.abs(opts.left[i]));
  }
  var cap = Math.max(opts.minSpan || 1, vals.length ? Math.max.apply(null, vals) : 1);
  if (opts.cap) cap = Math.min(cap, opts.cap);
  var X = function (v) { return PAD.l + (v + cap) / (2 * cap) * w; };
  g.font = "12px system-ui, sans-serif"; g.textBaseline = "middle";
  g.fillStyle = "#555"; g.textAlign = "center";
  [-cap, -cap / 2, 0, cap / 2, cap].forEach(function (t) { g.fillText(FT.tick(+t.toPrecision(3)) + (opts.unit || ""), X(t), 8); });
  for (var k = 0; k < n; k++) {
    var y = PAD.t + k * rowH;
    g.fillStyle = k % 2 ? "#fafbfc" : "#f1f3f5"; g.fillRect(0, y, W, rowH);
    g.fillStyle = "#222"; g.textAlign = "left";
    var name = String(opts.labels[k]);
    g.fillText(name.length > 26 ? name.slice(0, 25) + "…" : name, 6, y + rowH / 2);
    [[opts.left[k], opts.leftColor || "#2471a3"], [opts.right[k], opts.rightColor || "#d35400"]].forEach(function (b) {
      if (!isFinite(b[0])) return;
      var v = Math.max(-cap, Math.min(cap, b[0]));
      g.fillStyle = Math.abs(b[0]) > cap ? "#7b241c" : b[1];
      g.fillRect(Math.min(X(0), X(v)), y + 4, Math.abs(X(v) - X(0)), rowH - 8);
    });
    if (opts.note) { g.fillStyle = "#555"; g.textAlign = "right"; g.fillText(opts.note[k], W - 4, y + rowH / 2); }
  }
  g.strokeStyle = "#888"; g.beginPath(); g.moveTo(X(0) + 0.5, PAD.t); g.lineTo(X(0) + 0.5, H - PAD.b); g.stroke();
};
