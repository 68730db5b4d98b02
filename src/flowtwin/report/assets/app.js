/* flowtwin report: the page — controls, legend, hover and click details, time plots,
 * per-feature and per-layer views. Everything that comes from the G-code is put on the page
 * with textContent (never as markup). */
"use strict";
var FT = window.FT || (window.FT = {});

FT.PALETTES = {
  seq: [[68, 1, 84], [65, 68, 135], [42, 120, 142], [34, 168, 132], [122, 209, 81], [253, 231, 37]],
  div: [[33, 102, 172], [103, 169, 207], [209, 229, 240], [247, 247, 247], [253, 219, 199],
        [239, 138, 98], [178, 24, 43]],
  risk: [[178, 24, 43], [239, 138, 98], [253, 219, 199], [209, 229, 240], [103, 169, 207], [33, 102, 172]]
};

FT.ramp = function (stops) {
  var out = new Uint8Array(256 * 4);
  for (var i = 0; i < 256; i++) {
    var t = i / 255 * (stops.length - 1), k = Math.min(Math.floor(t), stops.length - 2), f = t - k;
    for (var c = 0; c < 3; c++) out[i * 4 + c] = Math.round(stops[k][c] * (1 - f) + stops[k + 1][c] * f);
    out[i * 4 + 3] = 255;
  }
  return out;
};

FT.App = function (data) {
  var self = this, H = data.header;
  this.data = data; this.variant = 0; this.qkey = H.variants[0].quantities[0].key;
  this.viewer = new FT.Viewer(document.getElementById("ft-canvas"), data);
  this.values = {};
  this.tip = document.getElementById("ft-tip");
  this._controls();
  this._applyQuantity(true);
  this.viewer.on("hover", function (h) { self._hover(h); });
  this.viewer.on("pick", function (m) { self.details(m); });
  this.viewer.on("view", function (v) {
    document.getElementById("ft-status").textContent = v.drawn.toLocaleString() + " moves in range" +
      (v.lodUsed ? " · merged below " + [0, 0.6, 2.5][v.lodUsed] + " mm (zoom in for every move)" : "") +
      " · " + v.frameMs.toFixed(1) + " ms";
  });
  this._charts();
  this._tables();
  this._spotLinks();
};

FT.App.prototype.V = function () { return this.data.header.variants[this.variant]; };

FT.App.prototype.quantity = function (key, variant) {
  var V = this.data.header.variants[variant === undefined ? this.variant : variant];
  for (var i = 0; i < V.quantities.length; i++) if (V.quantities[i].key === key) return V.quantities[i];
  return null;
};

/* Start time of every move in a variant, s (stored as millisecond differences). */
FT.App.prototype.times = function (V) {
  var key = V.t + ":s";
  if (!(key in this.values)) {
    var d = this.data.get(V.t), out = new Float64Array(d.length), acc = 0;
    for (var i = 0; i < d.length; i++) { acc += d[i]; out[i] = acc / 1000; }
    this.values[key] = out;
  }
  return this.values[key];
};

FT.App.prototype.valuesOf = function (q) {
  if (!(q.array in this.values)) this.values[q.array] = this.data.get(q.array);
  return this.values[q.array];
};

FT.App.prototype._controls = function () {
  var self = this, data = this.data, H = data.header;
  var sel = document.getElementById("ft-quantity");
  H.variants[0].quantities.forEach(function (q) {
    sel.appendChild(FT.el("option", { value: q.key }, q.label + (q.unit ? " (" + q.unit + ")" : "")));
  });
  sel.addEventListener("change", function () { self.qkey = sel.value; self._applyQuantity(true); });
  var vbox = document.getElementById("ft-variants");
  if (H.variants.length > 1) {
    H.variants.forEach(function (v, i) {
      var b = FT.el("button", { type: "button", "data-variant": String(i) }, v.label);
      b.addEventListener("click", function () { self.setVariant(i); });
      vbox.appendChild(b);
    });
    vbox.firstChild.classList.add("on");
  }
  var slider = document.getElementById("ft-layer"), mode = document.getElementById("ft-mode");
  slider.min = data.nLayers > 0 ? 1 : 0; slider.max = data.nLayers; slider.value = data.nLayers;
  function layers() {
    var v = +slider.value, z = H.layer_z[v - 1];
    self.viewer.setLayers(mode.value === "single" ? v : 0, v);
    document.getElementById("ft-layer-label").textContent = "layer " + (v - 1) + " of " +
      (data.nLayers - 1) + (z !== undefined && z !== null ? " · z " + z.toFixed(2) + " mm" : "");
  }
  this.setLayer = function (layer, single) {
    slider.value = layer + 1;
    if (single !== undefined) mode.value = single ? "single" : "upto";
    layers();
  };
  slider.addEventListener("input", layers);
  mode.addEventListener("change", layers);
  layers();
  document.getElementById("ft-travels").addEventListener("change", function (ev) { self.viewer.setTravels(ev.target.checked); });
  var tilt = document.getElementById("ft-tilt");
  tilt.addEventListener("change", function () { self.viewer.setTilt(tilt.checked); });
  self.viewer.setTilt(tilt.checked);
  document.getElementById("ft-fit").addEventListener("click", function () { self.viewer.fitDrawn(); });
  var lo = document.getElementById("ft-min"), hi = document.getElementById("ft-max");
  function range() {
    var a = parseFloat(lo.value), b = parseFloat(hi.value);
    if (isFinite(a) && isFinite(b) && b > a) { self.dom = [a, b]; self.viewer.setDomain(self.dom); self._legend(); }
  }
  lo.addEventListener("change", range); hi.addEventListener("change", range);
  document.getElementById("ft-auto").addEventListener("click", function () { self._applyQuantity(true); });
};

FT.App.prototype.setVariant = function (i) {
  this.variant = i;
  var bs = document.querySelectorAll("#ft-variants button");
  for (var k = 0; k < bs.length; k++) bs[k].classList.toggle("on", +bs[k].getAttribute("data-variant") === i);
  this._applyQuantity(false);
  this._charts(); this._tables();
  if (this.viewer.selected >= 0) this.details(this.viewer.selected);
};

/* Colour the viewer by the chosen quantity of the current variant. In a comparison the
 * colour range is shared by the variants, so before and after read on one scale. */
FT.App.prototype._applyQuantity = function (resetRange) {
  var q = this.quantity(this.qkey), H = this.data.header;
  if (resetRange || !this.dom) {
    var a = Infinity, b = -Infinity;
    for (var i = 0; i < H.variants.length; i++) {
      var qi = this.quantity(this.qkey, i);
      if (qi && qi.domain[0] !== null) { a = Math.min(a, qi.domain[0]); b = Math.max(b, qi.domain[1]); }
    }
    if (!(b > a)) { a = 0; b = 1; }
    this.dom = [a, b];
    document.getElementById("ft-min").value = +a.toPrecision(3);
    document.getElementById("ft-max").value = +b.toPrecision(3);
  }
  var pal = q.diverging ? FT.PALETTES.div : (q.reverse ? FT.PALETTES.risk : FT.PALETTES.seq);
  this.palette = pal;
  this.viewer.setValues(this.valuesOf(q), this.dom, FT.ramp(pal), q.diverging ? "abs" : (q.reverse ? "min" : "max"));
  this._legend();
};

FT.App.prototype._legend = function () {
  var q = this.quantity(this.qkey), c = document.getElementById("ft-legend"), r = window.devicePixelRatio || 1;
  var W = c.clientWidth, Hh = c.clientHeight;
  c.width = Math.round(W * r); c.height = Math.round(Hh * r);
  var g = c.getContext("2d"); g.setTransform(r, 0, 0, r, 0, 0); g.clearRect(0, 0, W, Hh);
  var grad = g.createLinearGradient(10, 0, W - 10, 0), pal = this.palette;
  for (var i = 0; i < pal.length; i++) grad.addColorStop(i / (pal.length - 1), "rgb(" + pal[i].join(",") + ")");
  g.fillStyle = grad; g.fillRect(10, 4, W - 20, 12);
  g.fillStyle = "#333"; g.font = "11px system-ui, sans-serif"; g.textAlign = "center"; g.textBaseline = "top";
  var d = this.dom;
  FT.niceTicks(d[0], d[1], 6).forEach(function (t) {
    var x = 10 + (t - d[0]) / (d[1] - d[0]) * (W - 20);
    g.fillRect(x, 16, 1, 4); g.fillText(FT.tick(t), x, 21);
  });
  document.getElementById("ft-legend-label").textContent = q.label + (q.unit ? " (" + q.unit + ")" : "") +
    (q.diverging ? " — blue: less than meant, red: more" : "") + "; grey: no value";
};

FT.App.prototype._describe = function (m) {
  var d = this.data, H = d.header, f = d.feature[m] - 1, lay = d.layer[m] - 1, z = H.layer_z[lay];
  return { line: d.line[m], layer: lay, z: z, feature: f >= 0 && f < H.features.length ? H.features[f] : "(none)" };
};

FT.App.prototype._hover = function (h) {
  var tip = this.tip;
  if (!h || h.move < 0) { tip.hidden = true; return; }
  var info = this._describe(h.move), q = this.quantity(this.qkey), v = this.data.at(q.array, h.move);
  tip.textContent = "line " + info.line + " · layer " + info.layer + " · " + info.feature + " · " +
    q.label + " " + FT.sig(v, q.unit);
  tip.style.left = (h.x + 14) + "px"; tip.style.top = (h.y + 10) + "px";
  tip.hidden = false;
};

/* The details of one move: where it is, every value, and its G-code lines. */
FT.App.prototype.details = function (m) {
  var box = document.getElementById("ft-details"), d = this.data, H = d.header, self = this;
  box.textContent = "";
  if (m < 0) { box.appendChild(FT.el("p", { "class": "muted" }, "Click a line of the toolpath for its G-code line and values.")); return; }
  var info = this._describe(m);
  box.appendChild(FT.el("h3", null, "G-code line " + info.line));
  box.appendChild(FT.el("p", null, "layer " + info.layer + (info.z !== undefined && info.z !== null ?
    " (z " + info.z.toFixed(2) + " mm)" : "") + " · " + info.feature + " · move " + (m + 1).toLocaleString()));
  var t = FT.el("table", { "class": "values" }), head = FT.el("tr");
  head.appendChild(FT.el("th", null, "quantity"));
  H.variants.forEach(function (v) { head.appendChild(FT.el("th", null, H.variants.length > 1 ? v.label : "value")); });
  t.appendChild(head);
  H.variants[0].quantities.forEach(function (q0) {
    var tr = FT.el("tr");
    tr.appendChild(FT.el("td", null, q0.label));
    H.variants.forEach(function (v, vi) {
      var q = self.quantity(q0.key, vi);
      tr.appendChild(FT.el("td", null, q ? FT.sig(d.at(q.array, m), q.unit) : "–"));
    });
    t.appendChild(tr);
  });
  box.appendChild(t);
  if (d.gcodeLines) {
    var pre = FT.el("pre", { "class": "gcode", id: "ft-gcode" });
    for (var ln = Math.max(1, info.line - 4); ln <= Math.min(d.gcodeLines.length, info.line + 4); ln++) {
      var row = FT.el("div", ln === info.line ? { "class": "hit" } : null);
      row.appendChild(FT.el("span", { "class": "ln" }, String(ln)));
      row.appendChild(document.createTextNode(d.gcodeLines[ln - 1].replace(/\r$/, "")));
      pre.appendChild(row);
    }
    box.appendChild(pre);
  } else {
    box.appendChild(FT.el("p", { "class": "muted" }, H.gcode_skipped ?
      "The G-code text is too large to embed; open the file at the line above." :
      "The G-code text was not available to embed."));
  }
};

/* Show a move: its layer alone, from above, zoomed in, selected. */
FT.App.prototype.show = function (m) {
  var lay = this.data.layer[m] - 1;
  document.getElementById("ft-tilt").checked = false;
  this.viewer.setTilt(false);
  this.setLayer(Math.max(lay, 0), true);
  this.viewer.focus(m, 40 * this.viewer.dpr);
  this.viewer.select(m);
  this.details(m);
  document.getElementById("ft-viewer").scrollIntoView({ behavior: "smooth", block: "start" });
};

FT.App.prototype._spotLinks = function () {
  var self = this, links = document.querySelectorAll("[data-line]");
  for (var i = 0; i < links.length; i++) {
    links[i].addEventListener("click", function (ev) {
      ev.preventDefault();
      self.show(FT.moveOfLine(self.data, +this.getAttribute("data-line")));
    });
  }
};

FT.App.prototype._charts = function () {
  var self = this, V = this.V(), T = V.track, d = this.data, get = d.get;
  function ch(name) {
    var c = T.channels[name];
    return { lo: get(c[0]), hi: get(c[1]), mean: get(c[2]) };
  }
  var nb = get(T.channels.q_cmd[0]).length, t1 = T.t0 + nb * T.dt, times = this.times(V);
  if (!this.link || this.link.t1 !== t1) {
    var charts = this.link ? this.link.charts : [];
    this.link = FT.TimeLink(T.t0, t1, null);
    this.link.t1 = t1;
    this.charts = null;
    charts.length = 0;
  }
  var marks = get(T.retract), fs = V.flow_scale;
  var onClick = function (t) { var m = FT.moveAtTime(times, t); if (m >= 0) self.show(m); };
  var flow = [Object.assign(ch("q_cmd"), { color: "#6c7a89", band: 0.13 }), Object.assign(ch("q_out"), { color: "#c0392b" })];
  if (!this.charts) {
    this.charts = {
      flow: new FT.TimeChart(document.getElementById("ft-flow"), { link: this.link, yLabel: "flow (mm³/s)", onClick: onClick }),
      force: new FT.TimeChart(document.getElementById("ft-force"), { link: this.link, yLabel: "force (N)", onClick: onClick,
                                                                     hline: d.header.meta.grip_n }),
      slip: new FT.TimeChart(document.getElementById("ft-slip"), { link: this.link, yLabel: "slip (%)", onClick: onClick })
    };
    var full = document.getElementById("ft-fullrange");
    full.addEventListener("change", function () { self.charts.flow.full = full.checked; self.charts.flow.draw(); });
  }
  this.charts.flow.o.onClick = this.charts.force.o.onClick = this.charts.slip.o.onClick = onClick;
  this.charts.flow.setData(flow, T.t0, T.dt, nb, marks, [-0.08 * fs, fs]);
  var f = ch("force"), fmax = 0;
  for (var i = 0; i < f.hi.length; i++) if (f.hi[i] > fmax) fmax = f.hi[i];
  var grip = d.header.meta.grip_n || 0;
  this.charts.force.setData([Object.assign(f, { color: "#8e44ad" })], T.t0, T.dt, nb, null,
                            [0, Math.max(fmax, grip) * 1.08 || 1]);
  var s = ch("slip"), smax = 0;
  for (var j = 0; j < s.hi.length; j++) if (s.hi[j] > smax) smax = s.hi[j];
  this.charts.slip.setData([Object.assign(s, { color: "#16a085" })], T.t0, T.dt, nb, null, [0, Math.max(smax * 1.08, 0.1)]);
  document.getElementById("ft-track-note").textContent = T.source === "series" ?
    "From the integrator's time series: line = mean, band = min to max per column." :
    "From per-move means (this result has no time series): line = mean, band = min to max.";
};

FT.App.prototype._tables = function () {
  var self = this, V = this.V(), H = this.data.header;
  var pct = function (v) { return v === null || v === undefined ? "–" : FT.fmt(100 * v, "%"); };
  var totalTime = V.features.reduce(function (a, r) { return a + (r.time_s || 0); }, 0) || 1;
  var ft = document.getElementById("ft-features");
  ft.textContent = "";
  var cols = ["feature", "time", "commanded (mm³)", "RMS flow error", "worst over", "worst under", "max force (N)", "ooze (mm³)"];
  var tr = FT.el("tr"); cols.forEach(function (c) { tr.appendChild(FT.el("th", null, c)); }); ft.appendChild(tr);
  V.features.forEach(function (r) {
    var row = FT.el("tr");
    row.appendChild(FT.el("td", null, r.feature));
    var tt = FT.el("td", { "class": "bar" });
    var barDiv = FT.el("div"); barDiv.style.width = (100 * r.time_s / totalTime).toFixed(1) + "%";
    tt.appendChild(barDiv); tt.appendChild(FT.el("span", null, FT.fmtTime(r.time_s)));
    row.appendChild(tt);
    [FT.fmt(r.commanded_mm3), pct(r.rms_flow_error), pct(r.worst_over), pct(r.worst_under),
     FT.fmt(r.max_feed_force_n), FT.fmt(r.ooze_mm3)].forEach(function (s) { row.appendChild(FT.el("td", null, s)); });
    ft.appendChild(row);
  });
  var F = V.features.filter(function (r) { return r.commanded_mm3 > 0; });
  FT.HBarChart(document.getElementById("ft-featurechart"), {
    labels: F.map(function (r) { return r.feature; }),
    right: F.map(function (r) { return r.worst_over === null ? NaN : 100 * r.worst_over; }),
    left: F.map(function (r) { return r.worst_under === null ? NaN : 100 * r.worst_under; }),
    note: F.map(function (r) { return (100 * r.time_s / totalTime).toFixed(0) + " % of time"; }),
    unit: " %", minSpan: 5, cap: 100
  });
  var L = this.layerRows(V).filter(function (r) { return r.layer >= 0; });
  FT.BarChart(document.getElementById("ft-layerchart"), {
    up: L.map(function (r) { return r.worst_over === null ? NaN : 100 * r.worst_over; }),
    down: L.map(function (r) { return r.worst_under === null ? NaN : 100 * r.worst_under; }),
    labels: L.map(function (r) { return r.layer; }), yLabel: "worst flow error (%)", minSpan: 5,
    onClick: function (i) { self.setLayer(L[i].layer, true); self.viewer.fitDrawn(); }
  });
  this._layerTable(L, pct);
};

/* The per-layer rows of a variant (stored as columns). */
FT.App.prototype.layerRows = function (V) {
  var key = "layers:" + V.name;
  if (!(key in this.values)) {
    var cols = {}, names = Object.keys(V.layers.columns), rows = [], self = this;
    names.forEach(function (c) { cols[c] = self.data.get(V.layers.columns[c]); });
    for (var i = 0; i < V.layers.n; i++) {
      var r = {};
      for (var k = 0; k < names.length; k++) {
        var v = cols[names[k]][i];
        r[names[k]] = v === v ? v : null;
      }
      rows.push(r);
    }
    this.values[key] = rows;
  }
  return this.values[key];
};

/* Rows shown in the per-layer table (all are sortable; the first MAX_ROWS are drawn). */
FT.MAX_ROWS = 1000;

FT.App.prototype._layerTable = function (rows, pct) {
  var self = this, tab = document.getElementById("ft-layers");
  var cols = [["layer", "layer"], ["z_mm", "z (mm)"], ["time_s", "time"], ["commanded_mm3", "commanded (mm³)"],
              ["delivered_mm3", "delivered (mm³)"], ["rms_flow_error", "RMS flow error"], ["worst_over", "worst over"],
              ["worst_under", "worst under"], ["max_feed_force_n", "max force (N)"], ["grinding_moves", "grinding moves"],
              ["ooze_mm3", "ooze (mm³)"]];
  var fmt = { time_s: FT.fmtTime, rms_flow_error: pct, worst_over: pct, worst_under: pct,
              layer: String, grinding_moves: String };
  var sortKey = this._sort || "layer", dir = this._dir || 1;
  rows = rows.slice().sort(function (a, b) {
    var x = a[sortKey], y = b[sortKey];
    x = x === null ? -Infinity : x; y = y === null ? -Infinity : y;
    return (x - y) * dir;
  });
  tab.textContent = "";
  var head = FT.el("tr");
  cols.forEach(function (c) {
    var th = FT.el("th", { "class": "sortable" }, c[1] + (c[0] === sortKey ? (dir > 0 ? " ▲" : " ▼") : ""));
    th.addEventListener("click", function () {
      self._dir = self._sort === c[0] ? -dir : (c[0] === "layer" ? 1 : -1); self._sort = c[0]; self._tables();
    });
    head.appendChild(th);
  });
  tab.appendChild(head);
  var note = document.getElementById("ft-layers-note");
  note.textContent = rows.length > FT.MAX_ROWS ? "The first " + FT.MAX_ROWS + " of " +
    rows.length.toLocaleString() + " layers in this order (click a column to sort)." : "";
  rows.slice(0, FT.MAX_ROWS).forEach(function (r) {
    var tr = FT.el("tr", { "class": "clickable" });
    cols.forEach(function (c) { tr.appendChild(FT.el("td", null, (fmt[c[0]] || FT.fmt)(r[c[0]]))); });
    tr.addEventListener("click", function () {
      self.setLayer(r.layer, true); self.viewer.fitDrawn();
      document.getElementById("ft-viewer").scrollIntoView({ behavior: "smooth", block: "start" });
    });
    tab.appendChild(tr);
  });
};

FT.start = async function () {
  var status = document.getElementById("ft-status"), t0 = performance.now();
  try {
    var data = await FT.load();
    var t1 = performance.now();
    FT.app = new FT.App(data);
    FT.timing = { load_ms: t1 - t0, build_ms: performance.now() - t1 };
    FT.app.details(-1);
    FT.app.viewer.fitDrawn();
    document.body.setAttribute("data-ready", "1");
  } catch (err) {
    status.textContent = "The interactive views could not start: " + (err && err.message ? err.message : err);
    status.classList.add("error");
    document.body.setAttribute("data-ready", "error");
    throw err;
  }
};

window.addEventListener("load", function () { FT.start(); });
