"""Find the printed lines of a K-factor pattern in an image and register it to the bed.

Steps (OpenCV):

1. **Threshold.** The lighting is flattened by dividing by the background (a grey-level
   closing with a kernel of 2 % of the image size, wider than any bead), then Otsu's
   threshold separates the dark beads.
2. **Pieces.** Each connected component gets its principal axis (PCA of its pixels),
   length along it, mean thickness ``area/length`` and spread across the axis. Long,
   thin, solid components (spread at most 0.6 of the thickness: a bead's is 0.29) are
   line pieces; a line broken by a gap (over-compensation empties the nozzle [001]) gives
   several pieces on one axis.
3. **Lines.** The mean direction of the pieces deskews the image; pieces are grouped into
   lines by their offset across that direction; each line's axis is fitted to all its
   pixels, its ends are the extreme pixels moved inwards by the radius of the end cap:
   the largest distance ``a`` from the tip at which the bead is still ``2a`` wide (a
   round cap of radius ``r`` is ``2·sqrt(2ra − a²) >= 2a`` wide exactly for ``a <= r``;
   an end where the flow fades tapers and gets no correction).
4. **Reading order.** The pattern's ticks (a short bead beyond the *end* of every
   ``mark_every``-th line) give the print direction; the prime line (no tick) in front of
   the first line, or the asymmetry of the ticks, gives front and back and whether the
   image is mirrored (a print scanned face down). What the image cannot decide is an
   error that asks for ``view``, never a guess.
5. **Registration.** The line ends are matched to the pattern's line ends on the bed and a
   homography bed (mm) → image (px) is fitted (RANSAC, so a ragged end does not spoil
   it). It removes rotation, scale and perspective: the printed pattern is its own scale
   bar (its line length and pitch are known).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError

__all__ = ["ImageLine", "Registration", "find_lines", "local_scale", "register_pattern"]

FloatArray = npt.NDArray[np.float64]

#: Smallest length/thickness ratio of a line piece.
_MIN_ELONGATION = 6.0
#: A line piece is at least this fraction of the longest piece.
_MIN_PIECE_FRACTION = 0.2


@dataclass(frozen=True)
class ImageLine:
    """One printed line found in the image (pixel coordinates: column, row).

    Attributes
    ----------
    start_px, end_px
        Ends of the line's axis, corrected for the end caps, shape ``(2,)``.
    offset_px
        Position across the mean line direction, px.
    thickness_px
        Mean bead thickness, px.
    pieces
        Number of components it was assembled from (> 1: the bead has gaps).
    tick
        Side of a tick mark: +1 beyond ``end_px``, −1 beyond ``start_px``, 0 none.
    """

    start_px: FloatArray
    end_px: FloatArray
    offset_px: float
    thickness_px: float
    pieces: int
    tick: int

    @property
    def length_px(self) -> float:
        """Length of the axis, px."""
        return float(np.hypot(*(self.end_px - self.start_px)))

    def reversed(self) -> ImageLine:
        """The same line traversed the other way."""
        return ImageLine(self.end_px, self.start_px, self.offset_px, self.thickness_px,
                         self.pieces, -self.tick)


@dataclass(frozen=True)
class _Component:
    coords: FloatArray        # (n, 2) col, row
    centroid: FloatArray
    direction: FloatArray
    length: float
    thickness: float
    spread: float             # standard deviation of the pixels across the axis

    @property
    def solid_line(self) -> bool:
        """Long, thin and solid: a bead of thickness t spreads t/√12 = 0.29·t across its
        axis (0.4·t with bulges); a sparse speckle cluster spreads far more."""
        return (self.length >= _MIN_ELONGATION * self.thickness
                and self.spread <= 0.6 * self.thickness)


def _components(mask: npt.NDArray[np.uint8], min_area: int) -> list[_Component]:
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    rows, cols = np.nonzero(labels)
    lab = labels[rows, cols]
    order = np.argsort(lab, kind="stable")
    rows, cols, lab = rows[order], cols[order], lab[order]
    bounds = np.searchsorted(lab, np.arange(1, n + 1))
    out: list[_Component] = []
    for k in range(1, n):
        if stats[k, cv2.CC_STAT_AREA] < min_area:
            continue
        sel = slice(bounds[k - 1], bounds[k])
        pts = np.column_stack([cols[sel], rows[sel]]).astype(np.float64)
        c = pts.mean(axis=0)
        cov = np.cov((pts - c).T) if pts.shape[0] > 2 else np.eye(2)
        evals, evecs = np.linalg.eigh(cov)
        d = evecs[:, int(np.argmax(evals))]
        proj = (pts - c) @ d
        length = float(np.ptp(proj)) + 1.0
        spread = float(np.sqrt(max(float(np.min(evals)), 0.0)))
        out.append(_Component(pts, c, d, length, pts.shape[0] / length, spread))
    return out


def _bead_mask(gray: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """Dark beads → 255 (lighting flattened, Otsu threshold)."""
    h, w = gray.shape
    k = max(9, int(0.02 * max(h, w)) | 1)
    g = cv2.GaussianBlur(gray, (0, 0), 1.0)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    background = cv2.morphologyEx(g, cv2.MORPH_CLOSE, kernel)
    background = cv2.blur(background, (k, k)).astype(np.float32)
    flat = np.clip(200.0 * g.astype(np.float32) / np.maximum(background, 1.0), 0, 255)
    _, mask = cv2.threshold(flat.astype(np.uint8), 0, 255,
                            cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    return np.asarray(mask, dtype=np.uint8)


def find_lines(gray: npt.NDArray[np.uint8], *, line_length_mm: float,
               source: str = "<image>") -> tuple[list[ImageLine], FloatArray]:
    """Find the long printed lines and their tick marks.

    Parameters
    ----------
    gray
        Grey image, uint8, shape ``(H, W)``.
    line_length_mm
        Length of the pattern's lines, mm (to size the search for ticks).
    source
        Image name for messages.

    Returns
    -------
    lines : list of ImageLine
        Sorted by offset across the mean direction; ``start → end`` along it.
    direction : ndarray
        Mean line direction (unit vector, col/row), shape ``(2,)``.

    Raises
    ------
    VisionError
        A blank image or no long thin lines.
    """
    if gray.ndim != 2 or min(gray.shape) < 32:
        raise VisionError("the image is too small to hold a pattern", source=source,
                          value=gray.shape, allowed="a grey or colour image >= 32 px")
    lo, hi = np.percentile(gray, [1.0, 99.0])
    if hi - lo < 20.0:
        raise VisionError("the image is blank (no contrast between beads and bed)",
                          source=source, value=f"grey levels {lo:.0f}..{hi:.0f}",
                          allowed="dark beads on a light bed (or the reverse: invert it)")
    mask = _bead_mask(gray)
    comps = _components(mask, min_area=12)
    if not comps:
        raise VisionError("no printed lines found in the image", source=source)
    longest = max(c.length for c in comps)
    pieces = [c for c in comps if c.length >= _MIN_PIECE_FRACTION * longest and c.solid_line]
    if len(pieces) < 2:
        raise VisionError("no printed lines found in the image (need long, thin dark "
                          "beads)", source=source, value=f"{len(pieces)} line piece(s)",
                          allowed="the K-factor pattern, beads darker than the bed")
    ref = max(pieces, key=lambda c: c.length).direction
    u = np.zeros(2)
    for c in pieces:
        u += c.length * (c.direction if float(c.direction @ ref) >= 0 else -c.direction)
    u /= np.linalg.norm(u)
    n = np.array([-u[1], u[0]])
    thick = float(np.median([c.thickness for c in pieces]))
    offsets = np.array([float(c.centroid @ n) for c in pieces])
    order = np.argsort(offsets)
    gaps = np.diff(offsets[order])
    big = gaps[gaps > 2.0 * thick]
    split = max(0.4 * float(np.median(big)), 2.0 * thick) if big.size else math.inf
    groups: list[list[_Component]] = [[pieces[order[0]]]]
    for gap, j in zip(gaps, order[1:], strict=True):
        if gap > split:
            groups.append([])
        groups[-1].append(pieces[j])
    members = {id(c) for c in pieces}
    others = [c for c in comps if id(c) not in members]
    lines: list[ImageLine] = []
    for group in groups:
        pts = np.vstack([c.coords for c in group])
        c = pts.mean(axis=0)
        evals, evecs = np.linalg.eigh(np.cov((pts - c).T))
        d = evecs[:, int(np.argmax(evals))]
        d = d if float(d @ u) >= 0 else -d
        proj = (pts - c) @ d
        s0, s1 = float(proj.min()), float(proj.max())
        t = pts.shape[0] / (s1 - s0 + 1.0)

        def cap(s_edge: float, inward: float, proj: FloatArray = proj, t: float = t) -> float:
            # width of the bead at distance a from its tip (pixels per unit length); a
            # round cap of radius r is 2·sqrt(2ra − a²) >= 2a exactly for a <= r, a
            # tapered end (the flow fading) falls below 2a at once: r = the largest a
            # with width(a) >= 2a
            a = inward * (proj - s_edge)
            near = a[(a >= 0.0) & (a < 3.0 * t)]
            counts = np.bincount(np.floor(near).astype(np.int64), minlength=int(3.0 * t) + 1)
            dist = np.arange(counts.size) + 0.5
            ok = counts >= 2.0 * dist
            return float(dist[np.flatnonzero(ok)[-1]]) if ok[0] else 0.0

        if (s1 - s0) < _MIN_ELONGATION * t:
            continue    # pieces that do not make a thin line (speckle, a blob)
        start = c + (s0 + cap(s0, +1.0)) * d
        end = c + (s1 - cap(s1, -1.0)) * d
        lines.append(ImageLine(start, end, float(c @ n), t, len(group), 0))
    if len(lines) < 2:
        raise VisionError("no printed lines found in the image (need long, thin dark "
                          "beads)", source=source, value=f"{len(lines)} line(s)",
                          allowed="the K-factor pattern, beads darker than the bed")
    scale = float(np.median([ln.length_px for ln in lines])) / line_length_mm
    lines = [_with_tick(ln, others, scale) for ln in lines]
    lines.sort(key=lambda ln: ln.offset_px)
    return lines, u


def _with_tick(line: ImageLine, others: list[_Component], px_per_mm: float) -> ImageLine:
    d = (line.end_px - line.start_px) / max(line.length_px, 1e-9)
    n = np.array([-d[1], d[0]])
    side = 0
    for c in others:
        if c.coords.shape[0] < 0.5 * line.thickness_px ** 2:
            continue
        rel = c.centroid - line.start_px
        across = abs(float(rel @ n))
        along = float(rel @ d)
        if across > 2.5 * line.thickness_px:
            continue
        beyond_end = along - line.length_px
        if line.thickness_px < beyond_end < 12.0 * px_per_mm:
            side = side or 1
            side = side if side == 1 else 2
        elif line.thickness_px < -along < 12.0 * px_per_mm:
            side = side or -1
            side = side if side == -1 else 2
    if side == 2:
        side = 0   # marks on both sides: not a tick pattern
    return ImageLine(line.start_px, line.end_px, line.offset_px, line.thickness_px,
                     line.pieces, side)


@dataclass(frozen=True)
class Registration:
    """The image lines matched to the pattern's lines, and the bed → image homography.

    Attributes
    ----------
    lines
        The image line of each pattern line (K-lines in pattern order), start → end.
    prime_seen
        Whether the prime line was found (in front of the first K-line).
    view
        ``"top"`` or ``"mirrored"`` (a print scanned face down).
    homography
        Bed (mm) → image (px), 3 × 3.
    inliers
        Line ends that agree with the homography.
    reprojection_rms_mm
        RMS distance of the inlier ends from their pattern positions, mm.
    px_per_mm
        Mean image scale at the pattern's centre, px/mm.
    """

    lines: tuple[ImageLine, ...]
    prime_seen: bool
    view: str
    homography: FloatArray
    inliers: int
    reprojection_rms_mm: float
    px_per_mm: float


def register_pattern(lines: list[ImageLine], direction: FloatArray, *,
                     starts_mm: FloatArray, ends_mm: FloatArray,
                     prime_mm: tuple[FloatArray, FloatArray] | None,
                     ticks: Sequence[bool], view: str = "auto",
                     source: str = "<image>") -> list[Registration]:
    """Match image lines to the pattern's K-lines and fit the bed → image homography.

    The ticks fix the print direction. Front and back (a view from above or a mirrored
    one) follow from the tick layout and the prime line unless that layout reads the same
    both ways (e.g. ticks on K-lines 0 and 5 of 7 and the prime line in front: a
    palindrome); then both readings are returned and the caller decides (the widths do:
    a too-low K under-extrudes after a step up).

    Parameters
    ----------
    lines, direction
        From :func:`find_lines`.
    starts_mm, ends_mm
        Bed coordinates of each K-line's start and end (pattern order, front to back),
        shape ``(n, 2)``.
    prime_mm
        Start and end of the prime line in front of the K-lines (``None``: none printed).
    ticks
        Which K-lines have a tick mark beyond their end (pattern order).
    view
        ``"auto"``, ``"top"`` (seen from above) or ``"mirrored"`` (scanned face down).
    source
        Image name for messages.

    Returns
    -------
    list of Registration
        Every reading consistent with the ticks (one, or two when the layout is
        symmetric).

    Raises
    ------
    VisionError
        No ticks, a line count or tick pattern that does not match the pattern, or line
        ends that no homography fits.
    """
    n_k = int(starts_mm.shape[0])
    expected = [bool(t) for t in ticks]
    marked = ", ".join(str(i) for i, t in enumerate(expected) if t)
    sides = {ln.tick for ln in lines if ln.tick}
    if not any(expected):
        raise VisionError("reading a K-line image needs the tick marks to tell the start "
                          "of a line from its end", source=source, field="mark_every",
                          value=0, allowed="a pattern printed with mark_every >= 1")
    if len(sides) != 1:
        raise VisionError("cannot find the tick marks beyond the ends of the lines"
                          if not sides else "tick marks on both ends of the lines",
                          source=source, value=f"{len(lines)} lines",
                          allowed=f"a short tick beyond the end of K-lines {marked}")
    if sides == {-1}:
        lines = [ln.reversed() for ln in lines]
        direction = -direction
    # bed +y (towards the back) in the image: the print direction turned right in image
    # coordinates (rows grow downwards) for a view from above, turned left if mirrored
    back = {"top": np.array([direction[1], -direction[0]]),
            "mirrored": np.array([-direction[1], direction[0]])}
    views = ("top", "mirrored") if view == "auto" else (view,)
    if any(v not in back for v in views):
        raise VisionError("unknown view", field="view", value=view,
                          allowed="auto, top, mirrored")
    prime_options = ([True] if prime_mm is not None and len(lines) == n_k + 1 else []) + (
        [False] if len(lines) == n_k else [])
    if not prime_options:
        raise VisionError(f"found {len(lines)} lines, but the pattern has {n_k} K-lines"
                          + (" and a prime line" if prime_mm is not None else ""),
                          source=source, value=len(lines),
                          allowed=f"{n_k} or {n_k + 1} lines (give the pattern's k-start, "
                                  "k-end and k-step as printed; crop other prints away)")
    matches: list[tuple[str, bool, list[ImageLine]]] = []
    for v in views:
        ordered = sorted(lines, key=lambda ln: float(0.5 * (ln.start_px + ln.end_px)
                                                     @ back[v]))
        for prime in prime_options:
            if [ln.tick != 0 for ln in ordered] == ([False] if prime else []) + expected:
                matches.append((v, prime, ordered))
    if not matches:
        raise VisionError("the tick marks do not match the pattern", source=source,
                          value=f"ticks on {sum(ln.tick != 0 for ln in lines)} of "
                                f"{len(lines)} lines",
                          allowed=f"ticks beyond K-lines {marked} (counted from the front)")
    return [_homography(v, prime, ordered, starts_mm, ends_mm, prime_mm, source)
            for v, prime, ordered in matches]


def _homography(v: str, prime: bool, ordered: list[ImageLine], starts_mm: FloatArray,
                ends_mm: FloatArray, prime_mm: tuple[FloatArray, FloatArray] | None,
                source: str) -> Registration:
    src = []
    dst = []
    if prime:
        assert prime_mm is not None
        src += [prime_mm[0], prime_mm[1]]
        dst += [ordered[0].start_px, ordered[0].end_px]
        ordered = ordered[1:]
    for i, ln in enumerate(ordered):
        src += [starts_mm[i], ends_mm[i]]
        dst += [ln.start_px, ln.end_px]
    src_a = np.asarray(src, dtype=np.float64)
    dst_a = np.asarray(dst, dtype=np.float64)
    scale = float(np.median([ln.length_px for ln in ordered])) / float(
        np.median(np.hypot(*(ends_mm - starts_mm).T)))
    thr = max(2.0, 0.5 * scale)
    hom, inl = cv2.findHomography(src_a, dst_a, cv2.RANSAC, thr)
    if hom is None:
        raise VisionError("the line ends do not fit the pattern's geometry", source=source,
                          allowed="a flat print, seen whole")
    keep = inl.ravel().astype(bool)
    if keep.sum() < max(6, int(0.6 * keep.size)):
        raise VisionError("too few line ends agree with the pattern's geometry",
                          source=source, value=f"{int(keep.sum())} of {keep.size}",
                          allowed="a flat print, seen whole, lines not cut by the image edge")
    hom, _ = cv2.findHomography(src_a[keep], dst_a[keep], 0)
    proj = cv2.perspectiveTransform(src_a[keep].reshape(-1, 1, 2), hom).reshape(-1, 2)
    rms_px = float(np.sqrt(np.mean(np.sum((proj - dst_a[keep]) ** 2, axis=1))))
    centre = np.vstack([starts_mm, ends_mm]).mean(axis=0)
    px_per_mm = local_scale(hom, centre)
    return Registration(lines=tuple(ordered), prime_seen=prime, view=v,
                        homography=np.asarray(hom, dtype=np.float64), inliers=int(keep.sum()),
                        reprojection_rms_mm=rms_px / px_per_mm, px_per_mm=px_per_mm)


def local_scale(homography: FloatArray, xy_mm: FloatArray) -> float:
    """Mean image scale (px/mm) of ``homography`` at bed point ``xy_mm``: ``sqrt(|det J|)``."""
    x, y = float(xy_mm[0]), float(xy_mm[1])
    h = homography
    den = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    u = (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / den
    v = (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / den
    jac = np.array([[h[0, 0] - u * h[2, 0], h[0, 1] - u * h[2, 1]],
                    [h[1, 0] - v * h[2, 0], h[1, 1] - v * h[2, 1]]]) / den
    return float(math.sqrt(abs(np.linalg.det(jac))))
