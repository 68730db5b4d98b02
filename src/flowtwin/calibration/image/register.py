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
The reading whose marks are there wins when it leads the next by
:data:`MARK_MARGIN`; otherwise all readings within that margin are returned and the caller
decides from the widths (a too-low K under-extrudes after a step up [001 Fig. 2]) or
refuses.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.image.detect import FoundLine, LineSet
from flowtwin.errors import VisionError

__all__ = ["MARK_MARGIN", "MARK_MARGIN_MM", "LayoutGeometry", "Reading", "register_layout"]

FloatArray = npt.NDArray[np.float64]

#: Lead in length of marks seen that decides the reading: this fraction of all the marks'
#: length, and at least :data:`MARK_MARGIN_MM`.
MARK_MARGIN = 0.05
MARK_MARGIN_MM = 5.0


@dataclass(frozen=True)
class LayoutGeometry:
    """A layout's lines and marks on the bed (mm).

    Attributes
    ----------
    starts, ends
        Test-line path ends, front to back, shape ``(n, 2)``.
    parallel
        ``(start, end, test_index)`` of every long line parallel to the test lines (test
        lines and parallel marks), front to back; ``test_index`` −1 for a mark.
    marks
        Paths of the other extrusions (polylines, ``(k, 2)`` each).
    """

    starts: FloatArray
    ends: FloatArray
    parallel: tuple[tuple[FloatArray, FloatArray, int], ...]
    marks: tuple[FloatArray, ...]


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
        RMS distance of the inlier line ends from the layout's, mm.
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
    r = max(1, int(round(0.15 * ls.pitch_px)))
    sig = cv2.dilate(ls.mark_signal, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                               (2 * r + 1, 2 * r + 1)))
    vals = cv2.remap(sig, tp[:, 0].reshape(1, -1), tp[:, 1].reshape(1, -1),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return np.asarray(vals, dtype=np.float64).ravel()


def _seen(ls: LineSet, hom: FloatArray, geo: LayoutGeometry) -> tuple[float, float]:
    """Length of the marks seen (mean signal along the mark at least half the test lines'),
    and their total length, mm."""
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
    return seen, total


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
    if len(found) == len(geo.parallel):
        seq = list(geo.parallel)
    elif len(found) == n:
        seq = [p for p in geo.parallel if p[2] >= 0]
    else:
        extra = len(geo.parallel) - n
        raise VisionError(f"found {len(found)} lines, but the pattern has {n} test lines"
                          + (f" and {extra} parallel mark(s)" if extra else ""),
                          source=source, value=len(found),
                          allowed=f"{n} lines (give the pattern and its k-start, k-end, "
                                  "k-step as printed; the whole pattern in view; crop other "
                                  "prints away)")
    length_mm = float(np.median(np.hypot(*(geo.ends - geo.starts).T)))
    length_px = float(np.median([f.length_px for f in found]))
    thr = max(2.0, 0.6 * length_px / length_mm)
    readings: list[Reading] = []
    total = 0.0
    for rev_order in (False, True):
        for rev_along in (False, True):
            order = found[::-1] if rev_order else found
            src, dst = [], []
            test_lines: dict[int, FoundLine] = {}
            for (a, b, ti), f in zip(seq, order, strict=True):
                s_px, e_px = (f.end_px, f.start_px) if rev_along else (f.start_px, f.end_px)
                src += [a, b]
                dst += [s_px, e_px]
                if ti >= 0:
                    test_lines[ti] = FoundLine(s_px, e_px, f.offset_px, f.thickness_px,
                                               f.pieces, f.cut)
            src_a = np.asarray(src, dtype=np.float64)
            dst_a = np.asarray(dst, dtype=np.float64)
            hom, inl = cv2.findHomography(src_a, dst_a, cv2.RANSAC, thr)
            if hom is None:
                continue
            keep = inl.ravel().astype(bool)
            if keep.sum() < max(6, int(0.6 * keep.size)):
                continue
            hom, _ = cv2.findHomography(src_a[keep], dst_a[keep], 0)
            if hom is None:
                continue
            centre = np.vstack([geo.starts, geo.ends]).mean(axis=0)
            # bed y up, image rows down: a view from the printed side reverses orientation
            mirrored = _jac_det(hom, centre) > 0
            if (view == "top" and mirrored) or (view == "mirrored" and not mirrored):
                continue
            proj = cv2.perspectiveTransform(src_a[keep].reshape(-1, 1, 2), hom).reshape(-1, 2)
            scale = local_scale(hom, centre)
            rms = float(np.sqrt(np.mean(np.sum((proj - dst_a[keep]) ** 2, axis=1)))) / scale
            seen, total = _seen(ls, hom, geo)
            name = (f"lines {'back to front' if rev_order else 'front to back'} across, "
                    f"printed {'leftwards' if rev_along else 'rightwards'} in the turned image")
            readings.append(Reading(name, tuple(test_lines[i] for i in range(n)),
                                    np.asarray(hom, dtype=np.float64), mirrored, seen, rms,
                                    int(keep.sum()), scale))
    if not readings:
        raise VisionError("the line ends do not fit the pattern's geometry", source=source,
                          allowed="a flat print, seen whole, lines not cut by the image edge")
    readings.sort(key=lambda r: -r.marks_seen_mm)
    best = readings[0].marks_seen_mm
    margin = max(MARK_MARGIN_MM, MARK_MARGIN * total)
    return [r for r in readings if r.marks_seen_mm > best - margin]
