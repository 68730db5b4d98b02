/* flowtwin report: the toolpath viewer (WebGL2, instanced ribbons, CPU picking, level of detail).
 * Every move is one instance: a ribbon from its start to its end, its nominal width wide (at
 * least one pixel), coloured by a value through a palette texture. Moves are drawn in layer
 * order, so a layer range is one contiguous run of instances. When zoomed out, runs of short
 * moves are merged into chords of at least LOD_MM (the worst value of the run is kept). */
"use strict";
var FT = window.FT || (window.FT = {});

FT.Viewer = (function () {
  var VS = [
    "#version 300 es",
    "precision highp float;",
    "in vec3 a_p0; in vec3 a_p1; in float a_v; in float a_cls; in float a_w;",
    "uniform vec3 u_lo; uniform vec3 u_span; uniform mat4 u_mvp; uniform vec2 u_px;",
    "uniform float u_mode; uniform vec2 u_dom; uniform float u_mmpx; uniform float u_minw;",
    "uniform sampler2D u_ramp; uniform vec4 u_flat;",
    "out vec4 v_col;",
    "void main() {",
    "  if (abs(a_cls - u_mode) > 0.5) { gl_Position = vec4(2.0, 2.0, 2.0, 1.0); return; }",
    "  vec4 c0 = u_mvp * vec4(u_lo + a_p0 * u_span, 1.0);",
    "  vec4 c1 = u_mvp * vec4(u_lo + a_p1 * u_span, 1.0);",
    "  int c = gl_VertexID % 6;",
    "  float along = (c == 1 || c == 2 || c == 4) ? 1.0 : 0.0;",
    "  float side = (c == 2 || c == 4 || c == 5) ? 1.0 : -1.0;",
    "  vec2 d = (c1.xy - c0.xy) / u_px; float len = length(d);",
    "  vec2 dir = len > 1e-6 ? d / len : vec2(1.0, 0.0); vec2 nrm = vec2(-dir.y, dir.x);",
    "  float hw = max(a_w * 0.01 * u_mmpx * 0.5, u_minw);",
    "  vec2 off = (nrm * side * hw + dir * (along * 2.0 - 1.0) * hw) * u_px;",
    "  vec4 cc = mix(c0, c1, along);",
    "  gl_Position = vec4(cc.xy + off, cc.z, 1.0);",
    "  if (u_flat.a > 0.0) { v_col = u_flat; return; }",
    "  if (a_v < -1e37) { v_col = vec4(0.6, 0.6, 0.6, 1.0); return; }",
    "  float t = clamp((a_v - u_dom.x) / max(u_dom.y - u_dom.x, 1e-12), 0.0, 1.0);",
    "  v_col = texture(u_ramp, vec2(t * 0.996 + 0.002, 0.5));",
    "}"].join("\n");
  var FS = ["#version 300 es", "precision mediump float;", "in vec4 v_col; out vec4 o;",
            "void main() { o = v_col; }"].join("\n");
  var LOD_MM = [0.6, 2.5];
  var INTERACTIVE_MIN = 50000, CHUNK_MIN = 8192, CHUNK_MAX = 1 << 24, EXPAND_MAX = 1000000;
  var NAN = -3.0e38;

  function compile(gl, type, src) {
    var s = gl.createShader(type);
    gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }

  function Viewer(canvas, data) {
    this.canvas = canvas; this.data = data;
    var gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
    if (!gl) throw new Error("this browser has no WebGL2: the toolpath viewer needs it");
    this.gl = gl;
    var prog = gl.createProgram();
    gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    this.prog = prog;
    this.loc = {};
    var names = ["u_lo", "u_span", "u_mvp", "u_px", "u_mode", "u_dom", "u_mmpx", "u_minw",
                 "u_ramp", "u_flat"];
    for (var i = 0; i < names.length; i++) this.loc[names[i]] = gl.getUniformLocation(prog, names[i]);
    this.attr = {};
    var an = ["a_p0", "a_p1", "a_v", "a_cls", "a_w"];
    for (var j = 0; j < an.length; j++) this.attr[an[j]] = gl.getAttribLocation(prog, an[j]);
    this.rampTex = gl.createTexture();
    this.levels = [this._baseLevel()];
    this.values = null; this.valueMode = "max";
    this.dom = [0, 1];
    this.range = [0, this.levels[0].count];
    this.layerSel = [0, data.nLayers];
    this.travels = false;
    this.selected = -1;
    var lo = data.lo, hi = data.hi;
    this.center = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
    this.az = 0; this.el = 90; this.scale = 1;
    this.lodUsed = 0; this.drawn = 0; this.frameMs = 0;
    this.chunk = 100000; this.idle = false; this.interactive = false;
    this.listeners = { hover: [], pick: [], view: [] };
    this._events();
    this.resize();
    this.fit();
  }

  Viewer.prototype.on = function (name, fn) { this.listeners[name].push(fn); };
  Viewer.prototype._emit = function (name, arg) {
    var ls = this.listeners[name];
    for (var i = 0; i < ls.length; i++) ls[i](arg);
  };

  /* Draw order (layer-sorted), per-instance geometry and the layer ranges. */
  Viewer.prototype._baseLevel = function () {
    var d = this.data, n = d.n, order = new Uint32Array(n), i;
    var sorted = true;
    for (i = 0; i < n; i++) { order[i] = i; if (i && d.layer[i] < d.layer[i - 1]) sorted = false; }
    if (!sorted) {
      var idx = Array.prototype.slice.call(order);
      idx.sort(function (a, b) { return d.layer[a] - d.layer[b] || a - b; });
      order = Uint32Array.from(idx);
    }
    this.order = order;
    var s = d.header.start, q = [0, 0, 0];
    for (var a = 0; a < 3; a++) {
      var span = d.hi[a] - d.lo[a];
      q[a] = Math.max(0, Math.min(65535, Math.round((s[a] - d.lo[a]) / span * 65535)));
    }
    var pos = new Uint16Array(n * 6), cls = new Uint8Array(n), w = new Uint8Array(n);
    var wn = d.get("wnom");
    for (var k = 0; k < n; k++) {
      var m = order[k], p = m - 1, o = k * 6;
      pos[o] = p >= 0 ? d.x[p] : q[0]; pos[o + 1] = p >= 0 ? d.y[p] : q[1];
      pos[o + 2] = p >= 0 ? d.z[p] : q[2];
      pos[o + 3] = d.x[m]; pos[o + 4] = d.y[m]; pos[o + 5] = d.z[m];
      var kd = d.kind[m];
      cls[k] = (kd & 10) === 10 ? 1 : ((kd & 8) && !(kd & 2) ? 2 : 0);
      w[k] = cls[k] === 1 ? wn[m] : 0;
    }
    var lev = { count: n, pos: pos, cls: cls, w: w, first: null, members: null };
    lev.layerStart = this._layerStarts(function (k) { return d.layer[order[k]]; }, n);
    this._upload(lev);
    return lev;
  };

  Viewer.prototype._layerStarts = function (layerOf, count) {
    var L = this.data.nLayers, starts = new Uint32Array(L + 2), k = 0;
    for (var l = 0; l <= L + 1; l++) {
      while (k < count && layerOf(k) < l) k++;
      starts[l] = k;
    }
    return starts;
  };

  /* A coarser level: runs of consecutive segments (same layer and class, joined end to
   * start) merged until the chord reaches tol mm. */
  Viewer.prototype._mergedLevel = function (tol) {
    var base = this.levels[0], d = this.data, n = base.count, order = this.order;
    var sx = (d.hi[0] - d.lo[0]) / 65535, sy = (d.hi[1] - d.lo[1]) / 65535;
    var pos = new Uint16Array(n * 6), cls = new Uint8Array(n), w = new Uint8Array(n);
    var first = new Uint32Array(n + 1), layerOfGroup = new Uint16Array(n), g = 0, k = 0;
    var bp = base.pos;
    while (k < n) {
      var start = k, o = k * 6, x0 = bp[o], y0 = bp[o + 1], c = base.cls[k], maxw = base.w[k];
      var lay = d.layer[order[k]];
      k++;
      while (k < n && base.cls[k] === c && d.layer[order[k]] === lay && order[k] === order[k - 1] + 1) {
        var dx = (bp[(k - 1) * 6 + 3] - x0) * sx, dy = (bp[(k - 1) * 6 + 4] - y0) * sy;
        if (dx * dx + dy * dy >= tol * tol) break;
        if (base.w[k] > maxw) maxw = base.w[k];
        k++;
      }
      var go = g * 6, e = (k - 1) * 6;
      pos[go] = x0; pos[go + 1] = y0; pos[go + 2] = bp[o + 2];
      pos[go + 3] = bp[e + 3]; pos[go + 4] = bp[e + 4]; pos[go + 5] = bp[e + 5];
      cls[g] = c; w[g] = maxw; first[g] = start; layerOfGroup[g] = lay;
      g++;
    }
    first[g] = n;
    var lev = { count: g, pos: pos.subarray(0, g * 6), cls: cls.subarray(0, g),
                w: w.subarray(0, g), first: first.subarray(0, g + 1), tol: tol };
    lev.layerStart = this._layerStarts(function (j) { return layerOfGroup[j]; }, g);
    this._upload(lev);
    if (this.values) this._levelValues(lev);
    return lev;
  };

  /* Repeat each element of `a` (groups of `k` values per instance) six times: one per
   * vertex of the instance's two triangles. */
  function six(a, k) {
    var out = new a.constructor(a.length * 6), n = a.length / k;
    for (var i = 0; i < n; i++) {
      for (var v = 0; v < 6; v++) {
        for (var j = 0; j < k; j++) out[(i * 6 + v) * k + j] = a[i * k + j];
      }
    }
    return out;
  }

  /* GPU buffers of a level. Up to EXPAND_MAX instances the per-instance data are repeated
   * for the six vertices and drawn without instancing: software WebGL (SwiftShader) draws
   * that ~16× faster than the same instanced draw (measured), for 6× the memory; larger
   * levels stay instanced (a GPU draws both alike). One shader serves both
   * (gl_VertexID % 6 is the corner either way). */
  Viewer.prototype._upload = function (lev) {
    var gl = this.gl, A = this.attr, x = lev.count <= EXPAND_MAX;
    lev.expanded = x;
    lev.vao = gl.createVertexArray();
    gl.bindVertexArray(lev.vao);
    lev.posBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, lev.posBuf);
    gl.bufferData(gl.ARRAY_BUFFER, x ? six(lev.pos, 6) : lev.pos, gl.STATIC_DRAW);
    lev.clsBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, lev.clsBuf);
    gl.bufferData(gl.ARRAY_BUFFER, x ? six(lev.cls, 1) : lev.cls, gl.STATIC_DRAW);
    lev.wBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, lev.wBuf);
    gl.bufferData(gl.ARRAY_BUFFER, x ? six(lev.w, 1) : lev.w, gl.STATIC_DRAW);
    lev.valBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, lev.valBuf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(lev.count * (x ? 6 : 1)), gl.DYNAMIC_DRAW);
    [A.a_p0, A.a_p1, A.a_v, A.a_cls, A.a_w].forEach(function (a) {
      gl.enableVertexAttribArray(a); gl.vertexAttribDivisor(a, x ? 0 : 1);
    });
    if (x) this._pointAttrs(lev, 0);
    gl.bindVertexArray(null);
  };

  /* Attribute pointers from instance `first` on (instanced levels; an expanded level keeps
   * its pointers at 0 and draws from vertex 6·first). */
  Viewer.prototype._pointAttrs = function (lev, first) {
    var gl = this.gl, A = this.attr;
    gl.bindBuffer(gl.ARRAY_BUFFER, lev.posBuf);
    gl.vertexAttribPointer(A.a_p0, 3, gl.UNSIGNED_SHORT, true, 12, first * 12);
    gl.vertexAttribPointer(A.a_p1, 3, gl.UNSIGNED_SHORT, true, 12, first * 12 + 6);
    gl.bindBuffer(gl.ARRAY_BUFFER, lev.valBuf);
    gl.vertexAttribPointer(A.a_v, 1, gl.FLOAT, false, 4, first * 4);
    gl.bindBuffer(gl.ARRAY_BUFFER, lev.clsBuf);
    gl.vertexAttribPointer(A.a_cls, 1, gl.UNSIGNED_BYTE, false, 1, first);
    gl.bindBuffer(gl.ARRAY_BUFFER, lev.wBuf);
    gl.vertexAttribPointer(A.a_w, 1, gl.UNSIGNED_BYTE, false, 1, first);
  };

  /* Draw instances [first, first + n) of a level (its VAO bound). */
  Viewer.prototype._drawRange = function (lev, first, n) {
    var gl = this.gl;
    if (lev.expanded) { gl.drawArrays(gl.TRIANGLES, first * 6, n * 6); return; }
    this._pointAttrs(lev, first);
    gl.drawArraysInstanced(gl.TRIANGLES, 0, 6, n);
  };

  /* Colour by `values` (per move, file order; NaN = none) over `dom` with `ramp` (RGBA bytes). */
  Viewer.prototype.setValues = function (values, dom, ramp, mode) {
    this.values = values; this.dom = dom; this.valueMode = mode || "max";
    var gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D, this.rampTex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, ramp.length / 4, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, ramp);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    for (var i = 0; i < this.levels.length; i++) this._levelValues(this.levels[i]);
    this.redraw();
  };

  Viewer.prototype.setDomain = function (dom) {
    this.dom = dom;
    for (var i = 1; i < this.levels.length; i++) this._levelValues(this.levels[i]);
    this.redraw();
  };

  /* Per-instance values of a level: the move's own, or for a merged run the value farthest
   * from the middle of the colour range ("max"/"min": the largest/smallest). */
  Viewer.prototype._levelValues = function (lev) {
    if (!lev || !this.values) return;
    var v = this.values, order = this.order, out = new Float32Array(lev.count), i;
    var mid = (this.dom[0] + this.dom[1]) / 2, mode = this.valueMode;
    if (!lev.first) {
      for (i = 0; i < lev.count; i++) { var x = v[order[i]]; out[i] = x === x ? x : NAN; }
    } else {
      for (i = 0; i < lev.count; i++) {
        var best = NAN, score = -Infinity;
        for (var k = lev.first[i]; k < lev.first[i + 1]; k++) {
          var y = v[order[k]];
          if (y !== y) continue;
          var s = mode === "min" ? -y : (mode === "max" ? y : Math.abs(y - mid));
          if (s > score) { score = s; best = y; }
        }
        out[i] = best;
      }
    }
    var gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, lev.valBuf);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, lev.expanded ? six(out, 1) : out);
  };

  /* Layers to draw: [a, b] inclusive (stored layer numbers: 0 = before the first layer). */
  Viewer.prototype.setLayers = function (a, b) { this.layerSel = [a, b]; this.redraw(); };
  Viewer.prototype.setTravels = function (on) { this.travels = !!on; this.redraw(); };
  Viewer.prototype.select = function (move) { this.selected = move; this.redraw(); };

  Viewer.prototype.resize = function () {
    var c = this.canvas, r = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(c.clientWidth * r)), h = Math.max(1, Math.round(c.clientHeight * r));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    this.dpr = r;
    this.redraw();
  };

  Viewer.prototype.fit = function () {
    var d = this.data, w = this.canvas.width, h = this.canvas.height;
    var sx = (d.hi[0] - d.lo[0]) || 1, sy = (d.hi[1] - d.lo[1]) || 1;
    this.center = [(d.lo[0] + d.hi[0]) / 2, (d.lo[1] + d.hi[1]) / 2, (d.lo[2] + d.hi[2]) / 2];
    this.scale = 0.92 * Math.min(w / sx, h / sy);
    this.redraw();
  };

  /* Fit the view to the extruding moves of the drawn layers. */
  Viewer.prototype.fitDrawn = function () {
    var d = this.data, r = this._range(this.levels[0]), xs = [Infinity, -Infinity], ys = [Infinity, -Infinity];
    for (var k = r[0]; k < r[1]; k++) {
      if (this.levels[0].cls[k] !== 1) continue;
      var m = this.order[k];
      if (d.x[m] < xs[0]) xs[0] = d.x[m]; if (d.x[m] > xs[1]) xs[1] = d.x[m];
      if (d.y[m] < ys[0]) ys[0] = d.y[m]; if (d.y[m] > ys[1]) ys[1] = d.y[m];
    }
    if (!(xs[1] >= xs[0])) return this.fit();
    var qx = (d.hi[0] - d.lo[0]) / 65535, qy = (d.hi[1] - d.lo[1]) / 65535;
    var w = Math.max((xs[1] - xs[0]) * qx, 1), h = Math.max((ys[1] - ys[0]) * qy, 1);
    this.center = [d.lo[0] + (xs[0] + xs[1]) / 2 * qx, d.lo[1] + (ys[0] + ys[1]) / 2 * qy, this.center[2]];
    this.scale = 0.9 * Math.min(this.canvas.width / w, this.canvas.height / h);
    this.redraw();
  };

  Viewer.prototype.setTilt = function (tilted) { this.el = tilted ? 35 : 90; this.az = tilted ? -35 : 0; this.redraw(); };

  /* Model-view-projection (column-major), orthographic: pixels per mm = this.scale. */
  Viewer.prototype._mvp = function () {
    var a = this.az * Math.PI / 180, e = (90 - this.el) * Math.PI / 180;
    var ca = Math.cos(a), sa = Math.sin(a), ce = Math.cos(e), se = Math.sin(e);
    var d = this.data, diag = Math.hypot(d.hi[0] - d.lo[0], d.hi[1] - d.lo[1], d.hi[2] - d.lo[2]) || 1;
    var kx = 2 * this.scale / this.canvas.width, ky = 2 * this.scale / this.canvas.height, kz = 1 / diag;
    // rows: right = (ca, sa, 0); up = (-sa*ce, ca*ce, se); depth = (sa*se, -ca*se, ce)
    var R = [[ca, sa, 0], [-sa * ce, ca * ce, se], [sa * se, -ca * se, ce]];
    var c = this.center, K = [kx, ky, kz], M = new Float32Array(16);
    for (var r = 0; r < 3; r++) {
      var t = -(R[r][0] * c[0] + R[r][1] * c[1] + R[r][2] * c[2]);
      for (var col = 0; col < 3; col++) M[col * 4 + r] = K[r] * R[r][col];
      M[12 + r] = K[r] * t;
    }
    M[15] = 1;
    M[2] = -M[2]; M[6] = -M[6]; M[10] = -M[10]; M[14] = -M[14];   // nearer = smaller depth
    return M;
  };

  Viewer.prototype._range = function (lev) {
    var a = this.layerSel[0], b = this.layerSel[1];
    return [lev.layerStart[a], lev.layerStart[b + 1]];
  };

  /* Level of detail: the coarsest whose chords stay under 1.5 pixels; while the view is
   * being moved, coarser still until the range fits in what this machine draws in one
   * frame (the progressive chunk, measured; at least INTERACTIVE_MIN instances). */
  Viewer.prototype._level = function () {
    var li = 0;
    for (var i = LOD_MM.length; i >= 1; i--) {
      if (LOD_MM[i - 1] * this.scale / this.dpr < 1.5) { li = i; break; }
    }
    if (this.interactive) {
      while (li < LOD_MM.length) {
        var lev = this._ensure(li), r = this._range(lev);
        if (r[1] - r[0] <= Math.max(this.chunk, INTERACTIVE_MIN)) break;
        li++;
      }
    }
    this._ensure(li);
    return li;
  };

  Viewer.prototype._ensure = function (li) {
    for (var j = this.levels.length; j <= li; j++) this.levels[j] = this._mergedLevel(LOD_MM[j - 1]);
    return this.levels[li];
  };

  Viewer.prototype.redraw = function () {
    if (this._pending) return;
    var self = this;
    this._pending = true;
    this.idle = false;
    window.requestAnimationFrame(function () { self._pending = false; self.draw(); });
  };

  Viewer.prototype._uniforms = function () {
    var gl = this.gl, c = this.canvas, L = this.loc, d = this.data;
    gl.viewport(0, 0, c.width, c.height);
    gl.useProgram(this.prog);
    gl.enable(gl.DEPTH_TEST); gl.depthFunc(gl.LEQUAL);
    gl.uniform3f(L.u_lo, d.lo[0], d.lo[1], d.lo[2]);
    gl.uniform3f(L.u_span, d.hi[0] - d.lo[0], d.hi[1] - d.lo[1], d.hi[2] - d.lo[2]);
    gl.uniformMatrix4fv(L.u_mvp, false, this._mvp());
    gl.uniform2f(L.u_px, 2 / c.width, 2 / c.height);
    gl.uniform2f(L.u_dom, this.dom[0], this.dom[1]);
    gl.uniform1f(L.u_mmpx, this.scale);
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, this.rampTex);
    gl.uniform1i(L.u_ramp, 0);
  };

  /* Draw the view. Large ranges are drawn progressively, a chunk of instances per animation
   * frame (top layers first; the chunk adapts so a frame takes ~40 ms), so the page stays
   * responsive on slow (software) WebGL; `idle` is true once the picture is complete.
   * `all`: everything in this call (measurements). */
  Viewer.prototype.draw = function (all) {
    var t0 = performance.now(), gl = this.gl;
    this._job = null;
    gl.clearColor(0.13, 0.14, 0.16, 1); gl.clearDepth(1);
    gl.viewport(0, 0, this.canvas.width, this.canvas.height);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.values) { this.idle = true; return; }
    this._uniforms();
    var li = this._level(), lev = this.levels[li], r = this._range(lev);
    this.lodUsed = li; this.drawn = r[1] - r[0];
    this._job = { lev: lev, r0: r[0], r1: r[1], end: r[1], pass: 1, last: t0,
                  passes: this.travels ? 2 : 1, all: !!all };
    this._step();
    this.frameMs = performance.now() - t0;
  };

  Viewer.prototype._step = function () {
    var job = this._job, gl = this.gl, L = this.loc, self = this;
    if (!job) return;
    var budget = job.all ? Infinity : this.chunk, n = 0;
    gl.bindVertexArray(job.lev.vao);
    while (n < budget && job.pass <= job.passes) {
      var a = Math.max(job.r0, job.end - (budget - n));
      if (job.end > a) {
        if (job.pass === 1) {
          gl.uniform1f(L.u_mode, 1); gl.uniform1f(L.u_minw, 0.5 * this.dpr);
          gl.uniform4f(L.u_flat, 0, 0, 0, 0);
        } else {
          gl.uniform1f(L.u_mode, 2); gl.uniform1f(L.u_minw, 0.5 * this.dpr);
          gl.uniform4f(L.u_flat, 0.55, 0.75, 1.0, 1.0);
        }
        this._drawRange(job.lev, a, job.end - a);
        n += job.end - a;
      }
      job.end = a;
      if (job.end <= job.r0) { job.pass++; job.end = job.r1; }
    }
    if (job.pass > job.passes) {
      if (this.selected >= 0) this._drawSelected();
      gl.bindVertexArray(null);
      this._job = null;
      this.idle = true;
      this._emit("view", this);
      return;
    }
    gl.bindVertexArray(null);
    window.requestAnimationFrame(function () {
      if (self._job !== job) return;
      var now = performance.now(), dt = now - job.last;
      job.last = now;
      if (dt > 70) self.chunk = Math.max(CHUNK_MIN, Math.floor(self.chunk / 2));
      else if (dt < 30) self.chunk = Math.min(CHUNK_MAX, Math.floor(self.chunk * 1.5));
      self._uniforms();
      self._step();
    });
  };

  Viewer.prototype._drawSelected = function () {
    var gl = this.gl, L = this.loc, lev = this.levels[0], k = this._slot(this.selected);
    if (k < 0) return;
    gl.bindVertexArray(lev.vao);
    gl.disable(gl.DEPTH_TEST);
    gl.uniform1f(L.u_mode, lev.cls[k] || 1); gl.uniform1f(L.u_minw, 3 * this.dpr);
    gl.uniform4f(L.u_flat, 1.0, 0.85, 0.0, 1.0);
    this._drawRange(lev, k, 1);
    gl.enable(gl.DEPTH_TEST);
  };

  Viewer.prototype._slot = function (move) {
    if (this._identity === undefined) {
      this._identity = true;
      for (var i = 0; i < this.order.length; i++) if (this.order[i] !== i) { this._identity = false; break; }
    }
    if (this._identity) return move;
    if (!this._inverse) {
      this._inverse = new Int32Array(this.order.length);
      for (var k = 0; k < this.order.length; k++) this._inverse[this.order[k]] = k;
    }
    return this._inverse[move];
  };

  /* The drawn move nearest to canvas pixel (px, py) (CSS pixels), within `tol` pixels of its
   * ribbon; the one nearest the viewer wins among close ones. -1 if none. */
  Viewer.prototype.pick = function (px, py, tol) {
    var lev = this.levels[0], r = this._range(lev), M = this._mvp(), d = this.data;
    var W = this.canvas.width, H = this.canvas.height, dpr = this.dpr;
    var cx = px * dpr, cy = py * dpr, best = -1, bestDepth = Infinity, bestDist = Infinity;
    var sx = (d.hi[0] - d.lo[0]) / 65535, sy = (d.hi[1] - d.lo[1]) / 65535, sz = (d.hi[2] - d.lo[2]) / 65535;
    var pos = lev.pos, want2 = this.travels, lo = d.lo;
    // screen x, y and depth of a quantised point are affine in its three 16-bit integers
    var ax = [M[0] * sx * W / 2, M[4] * sy * W / 2, M[8] * sz * W / 2,
              (M[0] * lo[0] + M[4] * lo[1] + M[8] * lo[2] + M[12] + 1) * W / 2];
    var ay = [-M[1] * sx * H / 2, -M[5] * sy * H / 2, -M[9] * sz * H / 2,
              (1 - (M[1] * lo[0] + M[5] * lo[1] + M[9] * lo[2] + M[13])) * H / 2];
    var az = [M[2] * sx, M[6] * sy, M[10] * sz, M[2] * lo[0] + M[6] * lo[1] + M[10] * lo[2] + M[14]];
    var wpx = 0.01 * this.scale * 0.5, minw = 0.5 * dpr, tolpx = tol * dpr;
    for (var k = r[0]; k < r[1]; k++) {
      var c = lev.cls[k];
      if (!(c === 1 || (c === 2 && want2))) continue;
      var o = k * 6, x0 = pos[o], y0 = pos[o + 1], z0 = pos[o + 2];
      var x1 = pos[o + 3], y1 = pos[o + 4], z1 = pos[o + 5];
      var pax = ax[0] * x0 + ax[1] * y0 + ax[2] * z0 + ax[3];
      var pay = ay[0] * x0 + ay[1] * y0 + ay[2] * z0 + ay[3];
      var vx = ax[0] * x1 + ax[1] * y1 + ax[2] * z1 + ax[3] - pax;
      var vy = ay[0] * x1 + ay[1] * y1 + ay[2] * z1 + ay[3] - pay;
      var wx = cx - pax, wy = cy - pay;
      var hw = Math.max(lev.w[k] * wpx, minw) + tolpx;
      // quick reject: the cursor is outside the segment's box grown by the half width
      if ((wx < -hw && wx - vx < -hw) || (wx > hw && wx - vx > hw) ||
          (wy < -hw && wy - vy < -hw) || (wy > hw && wy - vy > hw)) continue;
      var l2 = vx * vx + vy * vy, t = l2 > 0 ? Math.max(0, Math.min(1, (wx * vx + wy * vy) / l2)) : 0;
      var dx = wx - t * vx, dy = wy - t * vy, dist = Math.sqrt(dx * dx + dy * dy);
      if (dist > hw) continue;
      var za = az[0] * x0 + az[1] * y0 + az[2] * z0 + az[3];
      var depth = za + t * (az[0] * x1 + az[1] * y1 + az[2] * z1 + az[3] - za);
      if (depth < bestDepth - 1e-6 || (Math.abs(depth - bestDepth) <= 1e-6 && dist < bestDist)) {
        best = k; bestDepth = depth; bestDist = dist;
      }
    }
    return best < 0 ? -1 : this.order[best];
  };

  /* Centre the view on a move (its end point), keeping the zoom unless far out. */
  Viewer.prototype.focus = function (move, minScale) {
    var p = FT.pos(this.data, move);
    this.center = p;
    if (minScale && this.scale < minScale) this.scale = minScale;
    this.redraw();
  };

  /* The view is being moved: draw coarser until it rests for 250 ms. */
  Viewer.prototype._touch = function () {
    var self = this;
    this.interactive = true;
    clearTimeout(this._restTimer);
    this._restTimer = setTimeout(function () { self.interactive = false; self.redraw(); }, 250);
  };

  Viewer.prototype._events = function () {
    var self = this, c = this.canvas, drag = null, moved = false;
    c.addEventListener("wheel", function (ev) {
      ev.preventDefault();
      self._touch();
      var rect = c.getBoundingClientRect(), f = Math.exp(-ev.deltaY * 0.0015);
      var dx = (ev.clientX - rect.left - rect.width / 2) * self.dpr;
      var dy = -(ev.clientY - rect.top - rect.height / 2) * self.dpr;
      self._shift(dx / self.scale * (1 - 1 / f), dy / self.scale * (1 - 1 / f));
      self.scale *= f;
      self.redraw();
    }, { passive: false });
    c.addEventListener("pointerdown", function (ev) {
      drag = { x: ev.clientX, y: ev.clientY, rotate: ev.button === 2 || ev.shiftKey };
      moved = false;
      c.setPointerCapture(ev.pointerId);
    });
    c.addEventListener("pointermove", function (ev) {
      if (drag) {
        var dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
        if (Math.abs(dx) + Math.abs(dy) > 2) moved = true;
        drag.x = ev.clientX; drag.y = ev.clientY;
        if (moved) self._touch();
        if (drag.rotate) {
          self.az -= dx * 0.4; self.el = Math.max(5, Math.min(90, self.el + dy * 0.4));
        } else {
          self._shift(-dx * self.dpr / self.scale, dy * self.dpr / self.scale);
        }
        self.redraw();
        return;
      }
      self._hoverAt(ev);
    });
    c.addEventListener("pointerup", function (ev) {
      if (drag && !moved) {
        var rect = c.getBoundingClientRect();
        var m = self.pick(ev.clientX - rect.left, ev.clientY - rect.top, 6);
        self.select(m);
        self._emit("pick", m);
      }
      drag = null;
    });
    c.addEventListener("pointerleave", function () { self._emit("hover", { move: -1 }); });
    c.addEventListener("contextmenu", function (ev) { ev.preventDefault(); });
    window.addEventListener("resize", function () { self.resize(); });
  };

  Viewer.prototype._hoverAt = function (ev) {
    var self = this, now = performance.now();
    if (this._hoverBusy || now - (this._lastHover || 0) < 60) return;
    this._hoverBusy = true;
    var rect = this.canvas.getBoundingClientRect(), x = ev.clientX - rect.left, y = ev.clientY - rect.top;
    window.requestAnimationFrame(function () {
      var m = self.pick(x, y, 4);
      self._lastHover = performance.now(); self._hoverBusy = false;
      self._emit("hover", { move: m, x: x, y: y });
    });
  };

  /* Move the view centre by (dx, dy) mm along the screen's right and up directions. */
  Viewer.prototype._shift = function (dx, dy) {
    var a = this.az * Math.PI / 180, e = (90 - this.el) * Math.PI / 180;
    var ca = Math.cos(a), sa = Math.sin(a), ce = Math.cos(e), se = Math.sin(e);
    this.center[0] += dx * ca - dy * sa * ce;
    this.center[1] += dx * sa + dy * ca * ce;
    this.center[2] += dy * se;
  };

  return Viewer;
})();
