/* flowtwin report: unpack the embedded data (header JSON + deflated base64 blob).
 * Plain JavaScript, no dependency; the browser's DecompressionStream inflates the blob.
 * Arrays stored as byte planes (see payload.py) are interleaved back here. */
"use strict";
var FT = window.FT || (window.FT = {});

FT.base64Bytes = function (text) {
  var bin = atob(text.replace(/\s+/g, ""));
  var n = bin.length, out = new Uint8Array(n);
  for (var i = 0; i < n; i++) out[i] = bin.charCodeAt(i);
  return out;
};

FT.inflate = async function (bytes) {
  var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
};

FT.half = (function () {
  var table = new Float32Array(65536);
  for (var h = 0; h < 65536; h++) {
    var s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff, v;
    if (e === 0) v = s * Math.pow(2, -14) * (f / 1024);
    else if (e === 31) v = f ? NaN : s * Infinity;
    else v = s * Math.pow(2, e - 15) * (1 + f / 1024);
    table[h] = v;
  }
  return table;
})();

var SIZES = { u8: 1, i8: 1, u16: 2, i16: 2, u32: 4, i32: 4, f16: 2, f32: 4, f64: 8 };
var TYPES = { u8: Uint8Array, i8: Int8Array, u16: Uint16Array, i16: Int16Array, u32: Uint32Array,
              i32: Int32Array, f16: Uint16Array, f32: Float32Array, f64: Float64Array };

/* One array of the blob as a typed array (float16 → Float32Array). */
FT.array = function (raw, info) {
  var size = SIZES[info.type], n = info.length, bytes = new Uint8Array(n * size);
  var src = raw.subarray(info.offset, info.offset + n * size);
  if (info.planes) {
    for (var p = 0; p < size; p++) {
      var base = p * n;
      for (var i = 0; i < n; i++) bytes[i * size + p] = src[base + i];
    }
  } else {
    bytes.set(src);
  }
  var arr = new TYPES[info.type](bytes.buffer);
  if (info.type !== "f16") return arr;
  var out = new Float32Array(n), tab = FT.half;
  for (var j = 0; j < n; j++) out[j] = tab[arr[j]];
  return out;
};

/* Load everything the page needs: header, typed arrays, derived per-move figures. */
FT.load = async function () {
  var header = JSON.parse(document.getElementById("ft-header").textContent);
  var raw = await FT.inflate(FT.base64Bytes(document.getElementById("ft-blob").textContent));
  var arrays = {};
  function get(name) {
    if (!(name in arrays)) arrays[name] = FT.array(raw, header.arrays[name]);
    return arrays[name];
  }
  /* One element of an array, read from the blob without decoding the whole array. */
  function at(name, i) {
    if (name in arrays) return arrays[name][i];
    var info = header.arrays[name], size = SIZES[info.type], buf = new Uint8Array(size);
    for (var p = 0; p < size; p++) {
      buf[p] = raw[info.offset + (info.planes ? p * info.length + i : i * size + p)];
    }
    var v = new TYPES[info.type](buf.buffer)[0];
    return info.type === "f16" ? FT.half[v] : v;
  }
  var n = header.n, lo = header.lo, hi = header.hi;
  var dline = get("dline"), line = new Int32Array(n), acc = 0;
  for (var i = 0; i < n; i++) { acc += dline[i]; line[i] = acc; }
  var data = {
    header: header, n: n, lo: lo, hi: hi, x: get("x"), y: get("y"), z: get("z"),
    kind: get("kind"), layer: get("layer"), feature: get("feature"), line: line,
    get: get, at: at, gcodeLines: null
  };
  data.nLayers = 0;
  for (var k = 0; k < n; k++) if (data.layer[k] > data.nLayers) data.nLayers = data.layer[k];
  if (header.gcode) {
    var text = new TextDecoder("utf-8", { fatal: false }).decode(get(header.gcode));
    data.gcodeLines = text.split("\n");
  }
  return data;
};

/* Position of move i's end in mm (from the 16-bit grid). */
FT.pos = function (data, i) {
  var q = 1 / 65535;
  return [data.lo[0] + data.x[i] * q * (data.hi[0] - data.lo[0]),
          data.lo[1] + data.y[i] * q * (data.hi[1] - data.lo[1]),
          data.lo[2] + data.z[i] * q * (data.hi[2] - data.lo[2])];
};

/* First move whose G-code line is >= line (lines never decrease along the moves). */
FT.moveOfLine = function (data, line) {
  var a = 0, b = data.n - 1;
  while (a < b) { var m = (a + b) >> 1; if (data.line[m] < line) a = m + 1; else b = m; }
  return a;
};

/* Last move starting at or before time t (times never decrease). */
FT.moveAtTime = function (times, t) {
  var a = 0, b = times.length - 1;
  if (b < 0) return -1;
  while (a < b) { var m = (a + b + 1) >> 1; if (times[m] <= t) a = m; else b = m - 1; }
  return a;
};

/* A value of the viewer: three significant figures (the precision it is stored with). */
FT.sig = function (v, unit) {
  if (v === null || v === undefined || !isFinite(v)) return "–";
  var s = Math.abs(v) >= 1000 ? v.toFixed(0) : String(+v.toPrecision(3));
  return unit ? s + " " + unit : s;
};

FT.fmt = function (v, unit) {
  if (v === null || v === undefined || !isFinite(v)) return "–";
  var a = Math.abs(v), s;
  if (a >= 1000) s = v.toFixed(0);
  else if (a >= 100) s = v.toFixed(1);
  else if (a >= 10) s = v.toFixed(2);
  else s = v.toFixed(3);
  return unit ? s + " " + unit : s;
};

FT.el = function (tag, attrs, text) {
  var e = document.createElement(tag);
  if (attrs) for (var k in attrs) e.setAttribute(k, attrs[k]);
  if (text !== undefined && text !== null) e.textContent = String(text);
  return e;
};
