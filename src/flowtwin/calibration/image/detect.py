"""Find the long parallel lines of a printed line pattern, whatever their polarity.

:func:`detect_lines` turns the image so the lines run along its rows
(:mod:`.signal`), measures the pitch, and for each polarity (beads lighter or darker than
the sheet) computes the bead signal, smooths it along the rows over one pitch (a textured
sheet's speckle averages out, a bead does not), thresholds it locally (at least 0.45 of
the strongest bead signal within two pitches — the light and the beads' contrast change
across a photo — and four robust standard deviations above the sheet's scatter, taken
from the values below Otsu's threshold: fat beads may cover half the photo) and keeps the
long thin connected pieces.
Pieces on one axis are one line (a bead broken by gaps). Each line's axis is fitted to
its pixels, weighted by the signal; its ends are where the signal along the axis falls to
half the line's median level, moved inwards by a quarter of the bead's thickness (the
round end cap reaches half a width beyond the path's end, and the half level is reached
inside it).

The polarity is the one whose lines carry more bead: the sum over its lines of length ×
thickness × contrast (the bead signal on the axis). A bright-bead top-hat of dark beads
finds nothing long where the beads are matt (the gaps between dark beads are wider than
its element), but a glossy dark bead has a light ridge down its middle which that top-hat
finds as a thin, faint line on every bead: counting length alone ties the two polarities,
weighting by thickness and contrast does not (a ridge is a fraction of the bead's
width and of its contrast). Both totals are kept as evidence; within a factor
:data:`POLARITY_MARGIN` of each other the polarity is not decided.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.image.signal import (
    Deskewed,
    bead_signal,
    deskew,
    line_direction_deg,
    pitch_px,
)
from flowtwin.calibration.image.smooth import local_max
from flowtwin.errors import VisionError

__all__ = ["POLARITY_MARGIN", "FoundLine", "LineSet", "detect_lines"]

FloatArray = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]

#: Smallest length / thickness of a line piece.
_MIN_ELONGATION = 8.0
#: Lines shorter than this fraction of the longest are not pattern lines.
_MIN_LINE_FRACTION = 0.5
#: Length of the smoothing along the rows before the threshold, in pitches.
_SMOOTH_PITCHES = 1.0
#: Lines further apart than this many pitches belong to different stacks.
_STACK_GAP = 2.5
#: A line at an end of the stack carrying less than this fraction of the stack's median
#: bead is a streak of the sheet, not a line.
_END_WEIGHT = 0.35
#: A bead's signal is at least this fraction of the strongest beads' within two pitches.
_LOCAL_LEVEL = 0.45
#: ... and this many robust standard deviations above the sheet's.
_SHEET_SIGMAS = 4.0
#: ... or this many, where it continues a bead that clears :data:`_SHEET_SIGMAS`.
_WEAK_SIGMAS = 2.0
#: The polarity whose lines carry this many times more bead than the other's wins.
POLARITY_MARGIN = 2.0


@dataclass(frozen=True)
class FoundLine:
    """One line in the original image (px; x right, y down).

    Attributes
    ----------
    start_px, end_px
        Axis ends (in the turned image's +x order), shape ``(2,)``.
    offset_px
        Position across the lines (row of the turned image at the line's middle).
    thickness_px
        Mean bead thickness (area / length of its pixels).
    pieces
        Pieces it was assembled from (> 1: gaps).
    cut
        An end reaches the edge of the photo.
    contrast
        Median bead signal along the axis (bead/sheet contrast, a fraction).
    """

    start_px: FloatArray
    end_px: FloatArray
    offset_px: float
    thickness_px: float
    pieces: int
    cut: bool
    contrast: float = 1.0

    @property
    def length_px(self) -> float:
        """Length of the axis, px."""
        return float(np.hypot(*(self.end_px - self.start_px)))


@dataclass(frozen=True)
class LineSet:
    """The lines of the pattern found in an image.

    Attributes
    ----------
    lines
        Sorted across the lines (turned image rows, top to bottom).
    light
        Beads lighter than the sheet.
    polarity_evidence
        Bead carried by the lines found for ``"light"`` and ``"dark"`` beads: the sum of
        length × thickness × contrast, px².
    deskewed
        The turned image and its map.
    signal
        Bead signal of the turned image for the chosen polarity (float32).
    pitch_px
        Line pitch, px.
    coherence
        Dominance of the line direction (structure tensor).
    mark_signal
        Bead signal in every direction (disc top-hat), for the marks.
    """

    lines: tuple[FoundLine, ...]
    light: bool
    polarity_evidence: dict[str, float]
    deskewed: Deskewed
    signal: F32
    pitch_px: float
    coherence: float
    mark_signal: F32
    notes: tuple[str, ...] = field(default_factory=tuple)

    @functools.cached_property
    def mark_signal_near(self) -> F32:
        """``mark_signal`` dilated by a disc of 0.15 pitch: the best signal within that
        distance of each pixel (a mark near its nominal path counts; the registration
        samples it along many paths, so it is made once per line set)."""
        r = max(1, int(round(0.15 * self.pitch_px)))
        se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        return np.asarray(cv2.dilate(self.mark_signal, se), dtype=np.float32)


@dataclass(frozen=True)
class _Piece:
    x0: float
    x1: float
    a: float          # y = a + b·x in the turned image
    b: float
    thickness: float
    rows: npt.NDArray[np.intp]
    cols: npt.NDArray[np.intp]

    def y_at(self, x: float) -> float:
        return self.a + self.b * x


def _pieces(sig: F32, valid: npt.NDArray[np.uint8], pitch: float) -> list[_Piece]:
    length = max(3, int(round(_SMOOTH_PITCHES * pitch)))
    sm = cv2.blur(sig, (length, 1))
    vals = sm[valid > 0]
    if vals.size == 0:
        return []
    med = float(np.median(vals))
    mad = float(np.median(np.abs(vals - med))) * 1.4826 + 1e-6
    top = float(np.percentile(vals, 99.5))
    if top <= med:
        return []
    u8 = np.clip((sm - med) / (top - med) * 255.0, 0, 255).astype(np.uint8)
    otsu, _ = cv2.threshold(u8[valid > 0].reshape(-1, 1), 0, 255,
                            cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    thr_otsu = med + float(otsu) / 255.0 * (top - med)
    # the sheet's own scatter, from the values below Otsu's threshold: fat beads may
    # cover half the photo, and then the median and MAD of all values are the beads'
    sheet = vals[vals <= thr_otsu]
    if sheet.size > 100:
        med = float(np.median(sheet))
        mad = float(np.median(np.abs(sheet - med))) * 1.4826 + 1e-6
    # a bead is at least _LOCAL_LEVEL of the strongest beads around it (the light and
    # the bead signal change across a photo) and clear of the sheet's scatter
    rad = max(3, int(round(2.0 * pitch)))
    env = local_max(np.where(valid > 0, sm, 0.0).astype(np.float32), rad, pitch)
    thr = np.maximum(_LOCAL_LEVEL * env, med + _SHEET_SIGMAS * mad)
    strong = (sm > thr) & (valid > 0)
    # hysteresis: a bead's fainter stretch (thin, or in the shade) continues a strong one
    # down to _WEAK_SIGMAS above the sheet (a textured sheet's scatter is wide)
    weak = ((sm > np.maximum(_LOCAL_LEVEL * env, med + _WEAK_SIGMAS * mad))
            & (valid > 0)).astype(np.uint8)
    nw, wl = cv2.connectedComponents(weak, connectivity=8)
    seeded = np.zeros(nw, bool)
    seeded[np.unique(wl[strong])] = True
    seeded[0] = False
    mask = seeded[wl].astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    out: list[_Piece] = []
    keep = [k for k in range(1, n) if stats[k, cv2.CC_STAT_WIDTH] >= 4.0 * pitch * 0.2
            and stats[k, cv2.CC_STAT_AREA] >= 12]
    if not keep:
        return out
    rows, cols = np.nonzero(labels)
    lab = labels[rows, cols]
    order = np.argsort(lab, kind="stable")
    rows, cols, lab = rows[order], cols[order], lab[order]
    bounds = np.searchsorted(lab, np.arange(1, n + 1))
    for k in keep:
        r = rows[bounds[k - 1]:bounds[k]]
        c = cols[bounds[k - 1]:bounds[k]]
        x0, x1 = float(c.min()), float(c.max())
        span = x1 - x0 + 1.0
        wts = sig[r, c].astype(np.float64) + 1e-6
        if span < 2.0:
            continue
        b, a = np.polyfit(c.astype(np.float64), r.astype(np.float64), 1, w=np.sqrt(wts))
        thickness = r.size / span
        if span < _MIN_ELONGATION * thickness or thickness > 0.6 * pitch or abs(b) > 0.15:
            continue
        out.append(_Piece(x0, x1, float(a), float(b), thickness, r, c))
    return out


def _group(pieces: list[_Piece], pitch: float) -> list[list[_Piece]]:
    """Pieces on one axis (within 0.3 pitch) and not too far apart along it (a gap of at
    most two pitches or half the longer of the piece and the line so far: a line broken
    where the nozzle ran empty, not two lines that happen to be collinear) are one line."""
    groups: list[list[_Piece]] = []
    for p in sorted(pieces, key=lambda q: q.x0 - q.x1):          # longest first
        xm = 0.5 * (p.x0 + p.x1)
        best, best_d = None, 0.3 * pitch
        for g in groups:
            d = abs(g[0].y_at(xm) - p.y_at(xm))
            g0, g1 = min(q.x0 for q in g), max(q.x1 for q in g)
            gap = max(0.0, p.x0 - g1, g0 - p.x1)
            if gap > max(2.0 * pitch, 0.5 * max(p.x1 - p.x0, g1 - g0)):
                continue
            if d < best_d:
                best, best_d = g, d
        if best is None:
            groups.append([p])
        else:
            best.append(p)
    return groups


def _trim(groups: list[list[_Piece]]) -> tuple[list[list[_Piece]], list[_Piece]]:
    """Drop short collinear pieces beyond a line's ends (a tick mark, a number's stroke on
    the axis, a blob of another line) where they reach past the ends of the neighbouring
    lines (the nearest three on each side among the groups at least half the median
    group long: specks are no neighbours)."""
    if len(groups) < 3:
        return groups, []
    groups = sorted(groups, key=lambda g: g[0].y_at(0.5 * (g[0].x0 + g[0].x1)))
    ext = np.array([[min(p.x0 for p in g), max(p.x1 for p in g)] for g in groups])
    span = ext[:, 1] - ext[:, 0]
    med = float(np.median(span))
    big = [j for j in range(len(groups)) if span[j] >= 0.5 * med]
    dropped: list[_Piece] = []
    out = []
    for i, g in enumerate(groups):
        before = [j for j in big if j < i][-3:]
        after = [j for j in big if j > i][:3]
        nb = before + after
        if not nb:
            out.append(g)
            continue
        lo = float(np.median(ext[nb, 0]))
        hi = float(np.median(ext[nb, 1]))
        g = sorted(g, key=lambda p: p.x0)
        while len(g) > 1:
            if g[-1].x1 > hi + 0.03 * med and g[-1].x1 - g[-1].x0 < 0.25 * med:
                dropped.append(g.pop())
            elif g[0].x0 < lo - 0.03 * med and g[0].x1 - g[0].x0 < 0.25 * med:
                dropped.append(g.pop(0))
            else:
                break
        out.append(g)
    return out, dropped


def _line(group: list[_Piece], sig: F32, valid: npt.NDArray[np.uint8], pitch: float
          ) -> tuple[float, float, float, float, float, bool, float] | None:
    """``(x_start, x_end, a, b, thickness, cut, contrast)`` of a group in the turned
    image."""
    r = np.concatenate([p.rows for p in group]).astype(np.float64)
    c = np.concatenate([p.cols for p in group]).astype(np.float64)
    wts = sig[r.astype(np.intp), c.astype(np.intp)].astype(np.float64) + 1e-6
    b, a = np.polyfit(c, r, 1, w=np.sqrt(wts))
    x0 = min(p.x0 for p in group)
    x1 = max(p.x1 for p in group)
    span = x1 - x0 + 1.0
    thick = r.size / span
    h, w = sig.shape
    band = max(1.0, 0.5 * thick)
    xs = np.arange(max(0.0, x0 - pitch), min(w - 1.0, x1 + pitch) + 0.5, 0.5)
    vs = np.arange(-band, band + 0.25, 0.5)
    yy = (a + b * xs)[None, :] + vs[:, None]
    xx = np.broadcast_to(xs[None, :], yy.shape)
    prof = cv2.remap(sig, xx.astype(np.float32), yy.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0).mean(axis=0)
    inside = (xs >= x0) & (xs <= x1)
    core = float(np.median(prof[inside])) if np.any(inside) else 0.0
    if not core > 0:
        return None
    ins = np.flatnonzero(inside & (prof >= 0.5 * core))
    if ins.size == 0:
        return None
    i0, i1 = int(ins[0]), int(ins[-1])
    while i0 > 0 and prof[i0 - 1] >= 0.5 * core:     # out to the half level, no further
        i0 -= 1
    while i1 < xs.size - 1 and prof[i1 + 1] >= 0.5 * core:
        i1 += 1

    def cross(i: int, j: int) -> float:
        # interpolate the half-level crossing between samples i (above) and j (below)
        if j < 0 or j >= xs.size:
            return float(xs[i])
        pa, pb = prof[i], prof[j]
        t = (pa - 0.5 * core) / (pa - pb) if pa != pb else 0.0
        return float(xs[i] + t * (xs[j] - xs[i]))

    xs0 = cross(i0, i0 - 1) + 0.25 * thick
    xs1 = cross(i1, i1 + 1) - 0.25 * thick
    margin = max(3, int(round(0.5 * thick)) + 2)
    er = cv2.erode(valid, np.ones((2 * margin + 1, 2 * margin + 1), np.uint8))
    cut = False
    for x in (xs0 - 0.5 * thick, xs1 + 0.5 * thick):
        xi, yi = int(round(x)), int(round(a + b * x))
        if not (0 <= xi < w and 0 <= yi < h) or er[yi, xi] == 0:
            cut = True
    return xs0, xs1, float(a), float(b), thick, cut, core


def _find(desk: Deskewed, pitch: float, light: bool, element: float
          ) -> tuple[list[FoundLine], F32]:
    sig = bead_signal(desk.image, desk.valid, pitch, light=light, element_pitches=element)
    groups, _ = _trim(_group(_pieces(sig, desk.valid, pitch), pitch))
    found: list[FoundLine] = []
    for g in groups:
        res = _line(g, sig, desk.valid, pitch)
        if res is None:
            continue
        xs0, xs1, a, b, thick, cut, core = res
        if xs1 - xs0 < _MIN_ELONGATION * thick:
            continue
        ends = desk.to_original(np.array([[xs0, a + b * xs0], [xs1, a + b * xs1]]))
        xm = 0.5 * (xs0 + xs1)
        found.append(FoundLine(ends[0], ends[1], float(a + b * xm), thick, len(g), cut,
                               core))
    found = _stack(found, pitch)
    if found:
        longest = max(f.length_px for f in found)
        found = [f for f in found if f.length_px >= _MIN_LINE_FRACTION * longest]
    found.sort(key=lambda f: f.offset_px)
    return found, sig


def _stack(found: list[FoundLine], pitch: float) -> list[FoundLine]:
    """The pattern's stack: the chain of lines, each between 0.6 and :data:`_STACK_GAP`
    pitches from the last, that carries the most bead (length × thickness × contrast).

    Streaks of a textured sheet beyond the pattern, a ruler's edge or a crease lie at
    irregular distances, closer than a pitch to each other or far from the pattern: a
    chain through the pattern's lines takes few of them, and those at its ends that carry
    less than :data:`_END_WEIGHT` of the chain's median bead are dropped.
    """
    if not found:
        return found
    found = sorted(found, key=lambda f: f.offset_px)
    w = [f.length_px * f.thickness_px * f.contrast for f in found]
    best = list(w)
    prev = [-1] * len(found)
    for i in range(len(found)):
        for j in range(i):
            gap = found[i].offset_px - found[j].offset_px
            if 0.6 * pitch <= gap <= _STACK_GAP * pitch and best[j] + w[i] > best[i]:
                best[i], prev[i] = best[j] + w[i], j
    i = int(np.argmax(best))
    idx = []
    while i >= 0:
        idx.append(i)
        i = prev[i]
    idx = idx[::-1]
    # faint streaks that the chain picked up at its ends
    typical = float(np.median([w[k] for k in idx]))
    while len(idx) > 2 and w[idx[0]] < _END_WEIGHT * typical:
        idx.pop(0)
    while len(idx) > 2 and w[idx[-1]] < _END_WEIGHT * typical:
        idx.pop()
    return [found[k] for k in idx]


def detect_lines(gray: npt.NDArray[np.uint8], *, polarity: str = "auto",
                 source: str = "<image>", angle_deg: float | None = None,
                 element_pitches: float = 0.6) -> LineSet:
    """Find the pattern's long parallel lines.

    Parameters
    ----------
    gray
        Grey image, uint8, shape ``(H, W)``.
    polarity
        ``"auto"`` (decided from the image), ``"light"`` (beads lighter than the sheet)
        or ``"dark"``.
    source
        Image name for messages.
    angle_deg
        Direction of the lines in the image (default: the dominant one,
        :func:`~.signal.line_direction_deg`); a chevron pattern has two.
    element_pitches
        The top-hat's element, pitches (:func:`~.signal.bead_signal`).

    Returns
    -------
    LineSet

    Raises
    ------
    VisionError
        Blank image, no line direction or pitch, no lines, or a polarity the image does
        not decide.
    """
    if polarity not in ("auto", "light", "dark"):
        raise VisionError("unknown bead polarity", field="polarity", value=polarity,
                          allowed="auto, light, dark")
    if gray.ndim != 2 or min(gray.shape) < 48:
        raise VisionError("the image is too small to hold a pattern", source=source,
                          value=gray.shape, allowed="a grey or colour image >= 48 px")
    lo, hi = np.percentile(gray, [1.0, 99.0])
    if hi - lo < 20.0:
        raise VisionError("the image is blank (no contrast between beads and sheet)",
                          source=source, value=f"grey levels {lo:.0f}..{hi:.0f}",
                          allowed="a photo or scan of a printed line pattern")
    angle, coherence = line_direction_deg(gray)
    if angle_deg is not None:
        angle = float(angle_deg)
    desk = deskew(gray, angle)
    pitch = pitch_px(desk.image, desk.valid)
    if not (math.isfinite(pitch) and pitch >= 4.0):
        raise VisionError("no printed lines found in the image (no repeating parallel "
                          "lines)", source=source,
                          value=f"direction {angle:.1f}°, coherence {coherence:.2f}",
                          allowed="a photo of a line pattern, lines at least 4 px apart")
    polarities = (True, False) if polarity == "auto" else (polarity == "light",)
    results = {light: _find(desk, pitch, light, element_pitches) for light in polarities}
    evidence = {("light" if k else "dark"): float(sum(f.length_px * f.thickness_px
                                                      * f.contrast for f in v[0]))
                for k, v in results.items()}
    if polarity == "auto":
        el, ed = evidence["light"], evidence["dark"]
        if max(el, ed) <= 0:
            raise VisionError("no printed lines found in the image", source=source,
                              value=f"pitch {pitch:.1f} px", allowed="a line pattern")
        if POLARITY_MARGIN * min(el, ed) > max(el, ed):
            raise VisionError("cannot tell whether the beads are lighter or darker than "
                              "the sheet", source=source, field="polarity",
                              value={k: round(v) for k, v in evidence.items()},
                              allowed="--polarity light or dark")
        light = el > ed
    else:
        light = polarities[0]
    lines, sig = results[light]
    if len(lines) < 2:
        raise VisionError("no printed lines found in the image", source=source,
                          value=f"{len(lines)} line(s), beads {'light' if light else 'dark'}",
                          allowed="the pattern's long parallel lines, in focus")
    marks = bead_signal(desk.image, desk.valid, pitch, light=light, isotropic=True)
    return LineSet(tuple(lines), light, evidence, desk, sig, pitch, coherence, marks)
