"""An independent renderer of photos of printed line patterns (validation only).

Different code, and a different model, from :mod:`flowtwin.calibration.image.twin_render` (which
draws the twin's widths and warps the drawing): nothing here calls the planner or the
twin, so the analysis is tested on images it did not make.

* **Widths.** Each test line's nozzle speed is a trapezoid per segment written in closed
  form (start and end at rest, speed changes at the ``accel`` given, the change centred on
  the junction so each segment keeps its length). The commanded flow ``Q_n = A·v`` with the
  bead area ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7]; the firmware's advance adds
  ``K_la·dQ_n/dt`` [001 Eq. 11]; the melt leaving the nozzle lags the extruder by a
  first-order lag ``τ`` (no backflow) [001 Eq. 15], integrated exactly per time step
  (``Q_o ← Q_e + (Q_o − Q_e)·e^{−Δt/τ}``); the bead is ``Q_o/(h·v) + (1 − π/4)·h``, capped
  at 3 line widths where the nozzle nearly stops, missing (a gap) below half the layer
  height. With ``K_la = τ`` the bead is even: the best line is the one printed at the lag.
* **Camera.** A pinhole camera above the bed, tilted and turned: ``H = K·[r1 r2 t]``
  (bed mm → pixels), every pixel mapped back to the bed; beads are anti-aliased by their
  distance from the path in bed millimetres (round end caps), marks (prime lines, digits,
  ticks, anchor lines, boxes) are beads of the line width along their paths.
* **Scene.** The sheet's colour and texture (speckled PEI, a woven/diamond pattern,
  smooth), generated on the bed so perspective applies; a glossy highlight; lighting
  falling off across the photo; a hand-written label beside the lines; Gaussian optical
  blur; shot and read noise; JPEG compression.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.patterns.pattern import Pattern

__all__ = ["PhotoConditions", "SynthPhoto", "render_photo", "scene_from_pattern",
           "synthetic_widths"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class PhotoConditions:
    """How the synthetic photo is taken (lengths mm, angles degrees, grey levels 0–255)."""

    px_per_mm: float = 9.0
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 30.0
    roll_deg: float = 0.0
    light_beads: bool = True
    bead_bgr: tuple[int, int, int] = (235, 235, 230)
    sheet_bgr: tuple[int, int, int] = (35, 32, 30)
    sheet: str = "textured"
    texture: float = 0.25
    gloss: float = 0.0
    falloff: float = 0.3
    label: bool = True
    blur_px: float = 0.8
    read_noise: float = 3.0
    shot_noise: float = 0.3
    jpeg_quality: int = 85
    margin_mm: float = 12.0
    seed: int = 0


@dataclass(frozen=True)
class SynthPhoto:
    """A rendered photo (BGR uint8) and its bed (mm) → image (px) homography."""

    image: npt.NDArray[np.uint8]
    homography: FloatArray


def _trapezoid_speed(lengths: FloatArray, speeds: FloatArray, accel: float, dt: float
                     ) -> tuple[FloatArray, FloatArray]:
    """Time samples of the nozzle position and speed along a line of segments."""
    # speed as a function of path position: ramps centred on each junction (one at
    # each end from / to rest), then time from ds/v
    edges = np.concatenate(([0.0], np.cumsum(lengths)))
    total = float(edges[-1])
    ds = 1e-3
    s = np.arange(0.0, total + ds / 2, ds)
    v2 = np.full(s.shape, np.inf)
    for j, v in enumerate(speeds):
        seg = (s >= edges[j]) & (s <= edges[j + 1])
        v2[seg] = np.minimum(v2[seg], v * v)
    # acceleration limits: v² ≤ v_j² + 2a|s − junction| around each junction
    knots = [(0.0, 0.0), (total, 0.0)]
    for j in range(1, len(speeds)):
        knots.append((float(edges[j]), float(min(speeds[j - 1], speeds[j]) ** 2)))
    for pos, base in knots:
        v2 = np.minimum(v2, base + 2.0 * accel * np.abs(s - pos))
    v = np.sqrt(np.maximum(v2, 0.0))
    vmid = np.maximum(0.5 * (v[1:] + v[:-1]), 1e-3)
    t = np.concatenate(([0.0], np.cumsum(ds / vmid)))
    tt = np.arange(0.0, float(t[-1]), dt)
    return np.interp(tt, t, s), np.interp(tt, t, v)


def synthetic_widths(lengths: FloatArray, speeds: FloatArray, *, k_la_s: float, lag_s: float,
                     accel_mm_s2: float, line_width_mm: float, layer_height_mm: float,
                     step_mm: float = 0.05) -> tuple[FloatArray, FloatArray]:
    """Bead width along one test line (module docstring).

    Returns
    -------
    positions_mm, widths_mm
        Every ``step_mm`` along the line; NaN width: a gap.
    """
    h, w = layer_height_mm, line_width_mm
    area = w * h - (1.0 - math.pi / 4.0) * h * h
    dt = 2e-4
    s, v = _trapezoid_speed(np.asarray(lengths, float), np.asarray(speeds, float),
                            accel_mm_s2, dt)
    qn = area * v
    qe = qn + k_la_s * np.gradient(qn, dt)
    qo = np.empty_like(qe)
    decay = math.exp(-dt / lag_s) if lag_s > 0 else 0.0
    acc = 0.0
    for i, q in enumerate(qe):
        acc = q + (acc - q) * decay
        qo[i] = acc
    width = qo / (h * np.maximum(v, 1e-3)) + (1.0 - math.pi / 4.0) * h
    width = np.minimum(width, 3.0 * w)
    pos = np.arange(0.0, float(np.sum(lengths)) + step_mm / 2, step_mm)
    # position is monotone: average the width over time samples per position bin
    idx = np.clip(np.searchsorted(pos, s), 0, pos.size - 1)
    sums = np.bincount(idx, weights=width, minlength=pos.size)
    cnt = np.bincount(idx, minlength=pos.size)
    out = np.where(cnt > 0, sums / np.maximum(cnt, 1), np.nan)
    good = np.isfinite(out)
    out = np.interp(pos, pos[good], out[good])
    return pos, np.where(out < 0.5 * h, np.nan, out)


def _camera(c: PhotoConditions, centre: FloatArray, size: tuple[int, int]) -> FloatArray:
    """Bed mm → image px of a pinhole camera 250 mm above the pattern's centre."""
    dist = 250.0
    f = c.px_per_mm * dist
    w, h = size
    kmat = np.array([[f, 0, w / 2.0], [0, f, h / 2.0], [0, 0, 1.0]])
    # camera looking down: x right, image y towards the front, z down
    r0 = np.diag([1.0, -1.0, -1.0])
    ax = math.radians(c.tilt_axis_deg)
    axis = np.array([math.cos(ax), math.sin(ax), 0.0])
    rt, _ = cv2.Rodrigues(axis * math.radians(c.tilt_deg))
    rr, _ = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(c.roll_deg)]))
    rot = rr @ rt @ r0
    # the optical axis through the pattern's centre, ``dist`` from it
    cam = np.array([centre[0], centre[1], 0.0]) - dist * (rot.T @ np.array([0.0, 0.0, 1.0]))
    t = -rot @ cam
    hom = kmat @ np.column_stack([rot[:, 0], rot[:, 1], t])
    return np.asarray(hom / hom[2, 2], dtype=np.float64)


def _seg_distance(px: FloatArray, py: FloatArray, a: FloatArray, b: FloatArray
                  ) -> tuple[FloatArray, FloatArray]:
    """Distance of points from segment a→b and the position along it (clamped), mm."""
    d = b - a
    length = float(np.hypot(*d))
    u = d / length
    rx, ry = px - a[0], py - a[1]
    along = rx * u[0] + ry * u[1]
    cl = np.clip(along, 0.0, length)
    dx, dy = rx - cl * u[0], ry - cl * u[1]
    return np.hypot(dx, dy), along


def render_photo(pattern: Pattern, runs: list[FloatArray], test_runs: dict[int, tuple[
        FloatArray, FloatArray]], conditions: PhotoConditions) -> SynthPhoto:
    """Render a photo of ``pattern``.

    Parameters
    ----------
    pattern
        The printed pattern (for its bounds and line width).
    runs
        Every printed path (polylines, bed mm) other than the test lines: the marks.
    test_runs
        For each test line, its path's two ends and its widths: ``{i: (ends (2, 2),
        widths (k,) every 0.05 mm)}`` (:func:`synthetic_widths`).
    conditions
        The camera and the scene.

    Returns
    -------
    SynthPhoto
    """
    c = conditions
    rng = np.random.default_rng(c.seed)
    x0, y0, x1, y1 = pattern.bounds_xy_mm
    centre = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    wpx = int((x1 - x0 + 2 * c.margin_mm) * c.px_per_mm)
    hpx = int((y1 - y0 + 2 * c.margin_mm) * c.px_per_mm)
    hom = _camera(c, centre, (wpx, hpx))
    # frame the turned, tilted pattern: its bounds plus the margin, all in view
    m = c.margin_mm
    corners = np.array([[x0 - m, y0 - m], [x1 + m, y0 - m], [x1 + m, y1 + m], [x0 - m, y1 + m]])
    proj = cv2.perspectiveTransform(corners.reshape(-1, 1, 2), hom).reshape(-1, 2)
    lo = proj.min(axis=0)
    shift = np.array([[1.0, 0.0, -lo[0]], [0.0, 1.0, -lo[1]], [0.0, 0.0, 1.0]])
    hom = shift @ hom
    wpx, hpx = (int(math.ceil(v)) for v in proj.max(axis=0) - lo)
    inv = np.linalg.inv(hom)
    u, v = np.meshgrid(np.arange(wpx, dtype=np.float64), np.arange(hpx, dtype=np.float64))
    den = inv[2, 0] * u + inv[2, 1] * v + inv[2, 2]
    bx = (inv[0, 0] * u + inv[0, 1] * v + inv[0, 2]) / den
    by = (inv[1, 0] * u + inv[1, 1] * v + inv[1, 2]) / den
    pix_mm = 1.0 / c.px_per_mm
    cover = np.zeros((hpx, wpx))
    ridge = np.zeros((hpx, wpx))
    lw = pattern.settings.line_width_mm

    def paint(dist: FloatArray, half: FloatArray | float, rows: slice, cols: slice) -> None:
        cov = np.clip(0.5 + (half - dist) / pix_mm, 0.0, 1.0)
        hh = np.maximum(half, 1e-6)
        rid = np.clip(1.0 - (dist / hh) ** 2, 0.0, 1.0)
        cover[rows, cols] = np.maximum(cover[rows, cols], cov)
        ridge[rows, cols] = np.maximum(ridge[rows, cols], rid * cov)

    def window(pts: FloatArray, pad_mm: float) -> tuple[slice, slice]:
        img = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), hom).reshape(-1, 2)
        pad = pad_mm * c.px_per_mm * 1.5 + 2
        c0 = max(0, int(img[:, 0].min() - pad))
        c1 = min(wpx, int(img[:, 0].max() + pad) + 1)
        r0 = max(0, int(img[:, 1].min() - pad))
        r1 = min(hpx, int(img[:, 1].max() + pad) + 1)
        return slice(r0, r1), slice(c0, c1)

    for path in runs:
        for a, b in itertools.pairwise(path):
            if float(np.hypot(*(b - a))) < 1e-6:
                continue
            rows, cols = window(np.vstack([a, b]), lw)
            dist, _ = _seg_distance(bx[rows, cols], by[rows, cols], a, b)
            paint(dist, 0.5 * lw, rows, cols)
    for ends, widths in test_runs.values():
        a, b = ends[0], ends[1]
        rows, cols = window(np.vstack([a, b]), 3 * lw)
        dist, along = _seg_distance(bx[rows, cols], by[rows, cols], a, b)
        pos = np.arange(widths.size) * 0.05
        wal = np.interp(np.clip(along, 0.0, pos[-1]), pos, np.nan_to_num(widths, nan=0.0))
        paint(dist, 0.5 * wal, rows, cols)
    # the sheet: colour, texture on the bed, gloss, light
    sheet = np.ones((hpx, wpx))
    if c.sheet in ("textured", "patterned"):
        tex_res = 8.0
        gx0, gy0 = x0 - 2 * c.margin_mm, y0 - 2 * c.margin_mm
        tw = int((x1 - x0 + 4 * c.margin_mm) * tex_res)
        th = int((y1 - y0 + 4 * c.margin_mm) * tex_res)
        noise = rng.standard_normal((th, tw)).astype(np.float32)
        noise = np.asarray(cv2.GaussianBlur(noise, (0, 0), 0.7), dtype=np.float32)
        noise /= float(noise.std()) + 1e-9
        mx = ((bx - gx0) * tex_res).astype(np.float32)
        my = ((by - gy0) * tex_res).astype(np.float32)
        tex = cv2.remap(noise, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        sheet = sheet + c.texture * tex
        if c.sheet == "patterned":
            sheet = sheet + 0.5 * c.texture * np.sign(
                np.sin(2 * np.pi * (bx + by) / 3.0) * np.sin(2 * np.pi * (bx - by) / 3.0))
    light = 1.0 - c.falloff * (((u - 0.3 * wpx) / wpx) ** 2 + ((v - 0.2 * hpx) / hpx) ** 2)
    bead = np.array(c.bead_bgr, float)
    base = np.array(c.sheet_bgr, float)
    img = (base[None, None, :] * sheet[..., None] * (1 - cover[..., None])
           + bead[None, None, :] * (0.8 + 0.2 * ridge[..., None]) * cover[..., None])
    img = img * light[..., None]
    if c.gloss > 0:
        gx, gy = 0.65 * wpx, 0.35 * hpx
        blob = np.exp(-(((u - gx) / (0.18 * wpx)) ** 2 + ((v - gy) / (0.12 * hpx)) ** 2))
        img = img + 255.0 * c.gloss * blob[..., None] * (0.6 + 0.4 * cover[..., None])
    if c.label:
        org = (int(0.04 * wpx), int(0.97 * hpx))
        ink = np.zeros((hpx, wpx), np.uint8)
        cv2.putText(ink, "PLA 215C  PA test", org, cv2.FONT_HERSHEY_SCRIPT_SIMPLEX,
                    max(0.5, wpx / 900), 255, max(1, wpx // 600), cv2.LINE_AA)
        inkf = (ink.astype(np.float64) / 255.0)[..., None]
        img = img * (1 - inkf) + (bead * 0.9)[None, None, :] * inkf
    if c.blur_px > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), c.blur_px), dtype=np.float64)
    sd = np.sqrt(c.read_noise ** 2 + c.shot_noise * np.clip(img, 0, None))
    img = img + sd * rng.standard_normal(img.shape)
    out = np.clip(np.round(img), 0, 255).astype(np.uint8)
    if c.jpeg_quality < 100:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(c.jpeg_quality)])
        assert ok
        out = np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), dtype=np.uint8)
    return SynthPhoto(np.asarray(out, dtype=np.uint8), hom)


def scene_from_pattern(pattern: Pattern, *, lag_s: float, accel_mm_s2: float = 1000.0
                       ) -> tuple[list[FloatArray], dict[int, tuple[FloatArray, FloatArray]]]:
    """Marks and test lines of ``pattern`` from its G-code text, read here (not by
    flowtwin's reader): absolute ``G1 X Y``, relative ``E`` > 0 extrudes; each test line's
    segments, speeds and advance factor from the pattern's records.

    Returns
    -------
    tuple
        ``(marks, test_runs)`` for :func:`render_photo`.
    """
    seg_of = {sg.line: sg for sg in pattern.segments}
    k_of = {ps.group: ps.k_s for ps in pattern.pa_settings if ps.group >= 0}
    x = y = 0.0
    runs: list[list[tuple[float, float]]] = []
    cur: list[tuple[float, float]] = []
    tests: dict[int, list[tuple[float, float, float, float]]] = {}
    for no, text in enumerate(pattern.lines, start=1):
        words = text.split(";")[0].split()
        if not words or words[0] not in ("G0", "G1"):
            continue
        vals = {w[0]: float(w[1:]) for w in words[1:] if w[0] in "XYEF"}
        nx, ny = vals.get("X", x), vals.get("Y", y)
        moves = (nx, ny) != (x, y)
        if moves and vals.get("E", 0.0) > 0 and no in seg_of:
            sg = seg_of[no]
            tests.setdefault(sg.group, []).append((x, y, nx, ny))
            if cur:
                runs.append(cur)
            cur = []
        elif moves and vals.get("E", 0.0) > 0:
            if not cur:
                cur = [(x, y)]
            cur.append((nx, ny))
        elif moves and cur:
            runs.append(cur)
            cur = []
        x, y = nx, ny
    if cur:
        runs.append(cur)
    marks = [np.asarray(r, dtype=np.float64) for r in runs if len(r) >= 2]
    out: dict[int, tuple[FloatArray, FloatArray]] = {}
    for g, segs in tests.items():
        recs = [sg for sg in pattern.segments if sg.group == g]
        lengths = np.array([sg.length_mm for sg in recs])
        speeds = np.array([sg.speed_mm_s for sg in recs])
        _, wid = synthetic_widths(lengths, speeds, k_la_s=k_of[g], lag_s=lag_s,
                                  accel_mm_s2=accel_mm_s2,
                                  line_width_mm=pattern.settings.line_width_mm,
                                  layer_height_mm=pattern.settings.layer_height_mm)
        ends = np.array([[segs[0][0], segs[0][1]], [segs[-1][2], segs[-1][3]]])
        out[g] = (ends, wid)
    return marks, out
