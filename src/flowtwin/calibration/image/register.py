"""Match found lines to a layout's lines without tick marks, and fit bed → image.

The test lines' ends and their spacing give frame and scale: the found lines (sorted
across, each oriented along the turned image's rows) are matched end for end to the
layout's parallel lines (its test lines and any long parallel mark such as flowtwin's
prime line) and a homography bed (mm) → image (px) is fitted (RANSAC, then least squares
on the inliers). A stack of equal, equally spaced lines reads the same turned by 180° or
mirrored, so four readings are tried — the order across the lines either way, each line
either way. Each reading is scored by the layout's *other* marks (prime lines, reference
marks at the speed changes, printed numbers, anchor lines, ticks): the mean bead signal
along their paths, projected into the image, relative to the signal along the test lines.
A filled area (OrcaSlicer's number box, :mod:`.geometry`) is looked for by its fill
instead: the mean grey level over the projected rectangle between the sheet's level
(midway between the test lines) and the beads' (on their axes) — at least half way to
the beads' means the area is there; it weighs as much as the bead laid in it.
The reading whose marks are there wins when it leads the next by
:data:`MARK_MARGIN`; otherwise all readings within that margin are returned and the caller
decides from the widths (a too-low K under-extrudes after a step up [001 Fig. 2]) or
refuses.

A parallel mark (a prime line along the lines, a frame) may be found among the lines or
not (it may touch the edge of the photo's frame or be merged with a neighbour): the found
lines are matched to the test lines plus every choice of that many parallel marks, in
order, and the choice whose line ends fit best is kept. One test line may be missing (a
faint line the finder did not keep): then every choice of the missing line is fitted and
the best kept only if it fits the found axes clearly better than the next
(:data:`_MISSING_RATIO`); the missing line is measured where the fit puts it.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from flowtwin.calibration.image.detect import FoundLine, LineSet
from flowtwin.calibration.image.geometry import LayoutGeometry
from flowtwin.errors import VisionError

__all__ = ["MARK_MARGIN", "MARK_MARGIN_MM", "Reading", "local_scale", "marks_seen",
           "refine_homography", "register_layout"]

FloatArray = npt.NDArray[np.float64]

#: With one test line missing, the best choice of the missing line must fit the found
#: lines' axes this much better (RMS across) than the next.
_MISSING_RATIO = 0.7
#: Lead in length of marks seen that decides the reading: this fraction of all the marks'
#: length, and at least :data:`MARK_MARGIN_MM`.
MARK_MARGIN = 0.05
MARK_MARGIN_MM = 5.0


@dataclass(frozen=True)
class Reading:
    """One way of reading the photo.

    Attributes
    ----------
    name
        Which way the found lines are taken (order across, direction along).
    lines
        Image line of each test line (layout order), start → end of its path.
    homography
        Bed (mm) → image (px), 3 × 3.
    mirrored
        The map reverses orientation (a print scanned face down).
    marks_seen_mm
        Length of the layout's marks seen where this reading puts them (a mark is seen
        when its mean bead signal is at least half the test lines').
    reprojection_rms_mm
        RMS distance across the lines of the layout's lines from the found lines' axes, mm.
    inliers
        Line ends that agree with the homography.
    px_per_mm
        Image scale at the pattern's centre.
    """

    name: str
    lines: tuple[FoundLine, ...]
    homography: FloatArray
    mirrored: bool
    marks_seen_mm: float
    reprojection_rms_mm: float
    inliers: int
    px_per_mm: float


def local_scale(homography: FloatArray, xy_mm: FloatArray) -> float:
    """Mean scale (px/mm) of ``homography`` at ``xy_mm``: ``sqrt(|det J|)``."""
    return math.sqrt(abs(_jac_det(homography, xy_mm)))


def _jac_det(h: FloatArray, xy: FloatArray) -> float:
    x, y = float(xy[0]), float(xy[1])
    den = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    u = (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / den
    v = (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / den
    jac = np.array([[h[0, 0] - u * h[2, 0], h[0, 1] - u * h[2, 1]],
                    [h[1, 0] - v * h[2, 0], h[1, 1] - v * h[2, 1]]]) / den
    return float(np.linalg.det(jac))


def _to_turned(ls: LineSet, pts: FloatArray) -> FloatArray:
    f = ls.deskewed.forward
    return np.asarray(pts @ f[:, :2].T + f[:, 2], dtype=np.float64)


def _path_samples(ls: LineSet, hom: FloatArray, path: FloatArray, step_mm: float
                  ) -> FloatArray:
    """Mark signal every ``step_mm`` along ``path`` (bed mm) mapped by ``hom``."""
    pts = []
    for a, b in itertools.pairwise(path):
        n = max(2, int(np.hypot(*(b - a)) / step_mm) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(a[None, :] * (1 - t) + b[None, :] * t)
    bed = np.vstack(pts)
    img = cv2.perspectiveTransform(bed.reshape(-1, 1, 2), hom).reshape(-1, 2)
    tp = _to_turned(ls, np.asarray(img, dtype=np.float64)).astype(np.float32)
    # a mark within 0.15 pitch of its nominal path counts (the homography is extrapolated
    # beyond the test lines to reach some marks): best of that neighbourhood
    sig = ls.mark_signal_near
    vals = cv2.remap(sig, tp[:, 0].reshape(1, -1), tp[:, 1].reshape(1, -1),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return np.asarray(vals, dtype=np.float64).ravel()


def _grey_at(ls: LineSet, hom: FloatArray, bed: FloatArray) -> FloatArray:
    """Grey level of the turned image at bed points ``(n, 2)``."""
    img = cv2.perspectiveTransform(bed.reshape(-1, 1, 2), hom).reshape(-1, 2)
    tp = _to_turned(ls, np.asarray(img, dtype=np.float64)).astype(np.float32)
    vals = cv2.remap(ls.deskewed.image, tp[:, 0].reshape(1, -1), tp[:, 1].reshape(1, -1),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return np.asarray(vals, dtype=np.float64).ravel()


def _fill(ls: LineSet, hom: FloatArray, geo: LayoutGeometry) -> list[float]:
    """Fill of each filled area: 0 at the sheet's grey level, 1 at the beads'."""
    if not geo.areas:
        return []
    t = np.linspace(0.1, 0.9, 9)[:, None]
    axes = np.vstack([a[None, :] * (1 - t) + b[None, :] * t
                      for a, b in zip(geo.starts, geo.ends, strict=True)])
    mids = 0.5 * (geo.starts[1:] + geo.starts[:-1]), 0.5 * (geo.ends[1:] + geo.ends[:-1])
    gaps = np.vstack([a[None, :] * (1 - t) + b[None, :] * t
                      for a, b in zip(*mids, strict=True)]) if len(geo.starts) > 1 else axes
    bead = float(np.median(_grey_at(ls, hom, axes)))
    sheet = float(np.median(_grey_at(ls, hom, gaps)))
    if abs(bead - sheet) < 1.0:
        return [0.0] * len(geo.areas)
    out = []
    lw = geo.line_width_mm
    for corners, _ in geo.areas:
        e1, e2 = corners[1] - corners[0], corners[3] - corners[0]
        l1, l2 = float(np.hypot(*e1)), float(np.hypot(*e2))
        n1, n2 = max(2, int(l1 / 0.5)), max(2, int(l2 / 0.5))
        s1 = np.linspace(min(lw, 0.3 * l1), l1 - min(lw, 0.3 * l1), n1) / l1
        s2 = np.linspace(min(lw, 0.3 * l2), l2 - min(lw, 0.3 * l2), n2) / l2
        pts = (corners[0][None, None, :] + s1[:, None, None] * e1[None, None, :]
               + s2[None, :, None] * e2[None, None, :]).reshape(-1, 2)
        out.append(float(np.mean(_grey_at(ls, hom, pts)) - sheet) / (bead - sheet))
    return out


def marks_seen(ls: LineSet, hom: FloatArray, geo: LayoutGeometry) -> tuple[float, float]:
    """Length of the marks seen (mean signal along the mark at least half the test lines',
    a filled area at least half filled), and their total length, mm."""
    line = np.concatenate([_path_samples(ls, hom, np.vstack([a, b]), 0.5)
                           for a, b in zip(geo.starts, geo.ends, strict=True)])
    level = 0.5 * float(np.median(line))
    seen = total = 0.0
    for mark in geo.marks:
        length = float(np.sum(np.hypot(*np.diff(mark, axis=0).T)))
        if length <= 0:
            continue
        total += length
        if level > 0 and float(np.mean(_path_samples(ls, hom, mark, 0.2))) >= level:
            seen += length
    for (_, weight), fill in zip(geo.areas, _fill(ls, hom, geo), strict=True):
        total += weight
        if fill >= 0.5:
            seen += weight
    return seen, total


@dataclass(frozen=True)
class _Fit:
    hom: FloatArray
    across_rms_px: float
    inliers: int
    test_lines: dict[int, FoundLine]


def refine_homography(hom: FloatArray,
                      pairs: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]]
                      ) -> tuple[FloatArray, FloatArray]:
    """Refine ``hom`` on the found lines' axes; the residuals across the axes, px.

    ``pairs``: ``(bed start, bed end, image start, image end)`` of each matched line. Each
    found line's axis is fitted to all its bead pixels, so it fixes the map across the
    line to a fraction of a pixel, whereas its ends (a ragged start, a gap at the end of a
    line printed with too much advance) may be off by millimetres: seven points along
    each layout line must fall on the found axis; its ends count with a fifth of the
    weight and a robust (soft-L1, 2 px) loss.
    """
    t = np.linspace(0.0, 1.0, 7)[:, None]
    bed_pts = np.vstack([a[None, :] * (1 - t) + b[None, :] * t for a, b, _, _ in pairs])
    starts = np.array([p[2] for p in pairs])
    ends = np.array([p[3] for p in pairs])
    d = ends - starts
    u = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    nrm = np.column_stack([-u[:, 1], u[:, 0]])
    rep = np.repeat(np.arange(len(pairs)), t.size)
    bed_ends = np.vstack([[p[0], p[1]] for p in pairs])

    def project(h: FloatArray, pts: FloatArray) -> FloatArray:
        q = pts @ h[:, :2].T + h[:, 2]
        return np.asarray(q[:, :2] / q[:, 2:3], dtype=np.float64)

    def residuals(x: FloatArray) -> FloatArray:
        h = np.append(x, 1.0).reshape(3, 3)
        q = project(h, bed_pts)
        across = np.sum((q - starts[rep]) * nrm[rep], axis=1)
        qe = project(h, bed_ends).reshape(-1, 2, 2)
        along = np.concatenate([np.sum((qe[:, 0] - starts) * u, axis=1),
                                np.sum((qe[:, 1] - ends) * u, axis=1)])
        return np.concatenate([across, 0.2 * along])

    h0 = hom / hom[2, 2]
    n_across = bed_pts.shape[0]

    def loss_scaled(x: FloatArray) -> FloatArray:
        r = residuals(x)
        # soft-L1 on the ends only: across residuals are trusted, ends may be wrong
        e = r[n_across:]
        r[n_across:] = np.sign(e) * np.sqrt(2.0 * (np.sqrt(1.0 + (e / 2.0) ** 2) - 1.0)) * 2.0
        return r

    sol = least_squares(loss_scaled, h0.ravel()[:8], method="lm", max_nfev=200)
    h = np.append(sol.x, 1.0).reshape(3, 3)
    return h, residuals(sol.x)[:n_across]


def _fit(seq: list[tuple[FloatArray, FloatArray, int]], found: list[FoundLine],
         rev_order: bool, rev_along: bool, thr: float) -> _Fit | None:
    """Homography of one matching of found lines to ``seq``; ``None`` if it does not fit.

    RANSAC on the line ends, least squares on the inliers, then refined on the lines'
    axes (:func:`refine_homography`).
    """
    order = found[::-1] if rev_order else found
    src, dst = [], []
    pairs = []
    test_lines: dict[int, FoundLine] = {}
    for (a, b, ti), f in zip(seq, order, strict=True):
        s_px, e_px = (f.end_px, f.start_px) if rev_along else (f.start_px, f.end_px)
        src += [a, b]
        dst += [s_px, e_px]
        pairs.append((np.asarray(a, float), np.asarray(b, float), np.asarray(s_px, float),
                      np.asarray(e_px, float)))
        if ti >= 0:
            test_lines[ti] = FoundLine(s_px, e_px, f.offset_px, f.thickness_px, f.pieces,
                                       f.cut, f.contrast)
    src_a = np.asarray(src, dtype=np.float64)
    dst_a = np.asarray(dst, dtype=np.float64)
    hom, inl = cv2.findHomography(src_a, dst_a, cv2.RANSAC, thr)
    if hom is None:
        return None
    keep = inl.ravel().astype(bool)
    if keep.sum() < max(6, int(0.6 * keep.size)):
        return None
    hom, _ = cv2.findHomography(src_a[keep], dst_a[keep], 0)
    if hom is None:
        return None
    hom, across = refine_homography(np.asarray(hom, dtype=np.float64), pairs)
    if not np.all(np.isfinite(hom)):
        return None
    return _Fit(np.asarray(hom, dtype=np.float64), float(np.sqrt(np.mean(across ** 2))),
                int(keep.sum()), test_lines)


def register_layout(ls: LineSet, geo: LayoutGeometry, *, view: str = "auto",
                    source: str = "<image>") -> list[Reading]:
    """The readings of the photo consistent with the layout, best first.

    Parameters
    ----------
    ls
        Lines found in the photo (:func:`~.detect.detect_lines`).
    geo
        The layout's geometry.
    view
        ``"auto"``, ``"top"`` (photo or scan from the printed side) or ``"mirrored"``
        (scanned face down).
    source
        Image name for messages.

    Returns
    -------
    list of Reading
        One reading when the marks decide it, else every reading within
        :data:`MARK_MARGIN` of the best (the caller decides or refuses).

    Raises
    ------
    VisionError
        A line count the layout does not have, or line ends no homography fits.
    """
    if view not in ("auto", "top", "mirrored"):
        raise VisionError("unknown view", field="view", value=view,
                          allowed="auto, top, mirrored")
    n = geo.starts.shape[0]
    found = list(ls.lines)
    mark_ids = [i for i, p in enumerate(geo.parallel) if p[2] < 0]
    test_ids = [i for i, p in enumerate(geo.parallel) if p[2] >= 0]
    extra = len(found) - n
    # the found lines are the test lines and `extra` parallel marks, or, failing that,
    # all test lines but one (a faint or broken line the finder missed) and marks
    missing_one = not 0 <= extra <= len(mark_ids)
    if missing_one and not (0 <= extra + 1 <= len(mark_ids) and n >= 5):
        raise VisionError(f"found {len(found)} lines, but the pattern has {n} test lines"
                          + (f" and {len(mark_ids)} parallel mark(s)" if mark_ids else ""),
                          source=source, value=len(found),
                          allowed=f"{n} lines (give the pattern and its k-start, k-end, "
                                  "k-step as printed; the whole pattern in view; crop other "
                                  "prints away)")
    if missing_one:
        seqs = [[p for i, p in enumerate(geo.parallel) if (p[2] >= 0 and i != skip)
                 or i in chosen]
                for skip in test_ids for chosen in itertools.combinations(mark_ids, extra + 1)]
    else:
        seqs = [[p for i, p in enumerate(geo.parallel) if p[2] >= 0 or i in chosen]
                for chosen in itertools.combinations(mark_ids, extra)]
    length_mm = float(np.median(np.hypot(*(geo.ends - geo.starts).T)))
    length_px = float(np.median([f.length_px for f in found]))
    thr = max(2.0, 0.6 * length_px / length_mm)
    centre = np.vstack([geo.starts, geo.ends]).mean(axis=0)
    readings: list[Reading] = []
    total = 0.0
    for rev_order in (False, True):
        for rev_along in (False, True):
            fits = [f for f in (_fit(seq, found, rev_order, rev_along, thr) for seq in seqs)
                    if f is not None]
            if not fits:
                continue
            fits.sort(key=lambda f: f.across_rms_px)
            best = fits[0]
            if missing_one and len(fits) > 1 and not (
                    best.across_rms_px < _MISSING_RATIO * fits[1].across_rms_px):
                continue        # which line is missing is not clear
            hom, test_lines = best.hom, dict(best.test_lines)
            for i in range(n):
                if i not in test_lines:     # where the layout puts the line not found
                    ends = cv2.perspectiveTransform(
                        np.array([[geo.starts[i], geo.ends[i]]], dtype=np.float64), hom)[0]
                    test_lines[i] = FoundLine(ends[0], ends[1], math.nan, math.nan, 0,
                                              False, 0.0)
            rms = best.across_rms_px / local_scale(hom, centre)
            # bed y up, image rows down: a view from the printed side reverses orientation
            mirrored = _jac_det(hom, centre) > 0
            if (view == "top" and mirrored) or (view == "mirrored" and not mirrored):
                continue
            scale = local_scale(hom, centre)
            seen, total = marks_seen(ls, hom, geo)
            name = (f"lines {'back to front' if rev_order else 'front to back'} across, "
                    f"printed {'leftwards' if rev_along else 'rightwards'} in the turned image")
            readings.append(Reading(name, tuple(test_lines[i] for i in range(n)), hom,
                                    mirrored, seen, rms, best.inliers, scale))
    if not readings:
        raise VisionError("the line ends do not fit the pattern's geometry", source=source,
                          allowed="a flat print, seen whole, lines not cut by the image edge")
    readings.sort(key=lambda r: -r.marks_seen_mm)
    top = readings[0].marks_seen_mm
    margin = max(MARK_MARGIN_MM, MARK_MARGIN * total)
    return [r for r in readings if r.marks_seen_mm > top - margin]
