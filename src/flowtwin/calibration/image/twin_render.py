"""Synthetic images of a printed pattern, rendered from the twin (known-answer test images).

Every run of extruding moves of a G-code (prime line, test lines, tick marks) is drawn as
a dark bead on a light background, its width along the path the twin's prediction for a
given lag (:class:`~flowtwin.calibration.fits.lagmodel.LagModel`, [001 Eqs. 7, 15]). The bead
has round end caps (radius half the width at the end) and round joins at corners. Where
the predicted width is below half the layer height the bead is left out: the slicer's
bead model is ill-defined there [001 Fig. 12] and the print shows a gap.

Then the image is degraded like a scan or a photo: uneven lighting, a rotation about the
image centre, a perspective tilt (OpenCV ``warpPerspective``), Gaussian blur and Gaussian
noise, optionally mirrored (a print scanned face down). The homography from the pattern's
bed coordinates (mm) to the output pixels is returned with the image, so the tests know
the exact geometry as well as the lag the image was rendered with.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import BinaryIO

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.lagmodel import LagParams, lag_model
from flowtwin.errors import CalibrationError
from flowtwin.profiles.machine import Machine

__all__ = ["ImageConditions", "RenderedImage", "render_pattern_image"]

FloatArray = npt.NDArray[np.float64]

#: Widest bead drawn, as a multiple of the layer height (a start blob is not a disc of
#: arbitrary size: the melt spreads).
_MAX_WIDTH_PER_HEIGHT = 6.0


@dataclass(frozen=True, slots=True)
class ImageConditions:
    """How the pattern is imaged.

    Attributes
    ----------
    px_per_mm
        Scale of the undistorted image, px/mm (a 600 dpi scan: 23.6).
    rotation_deg
        Rotation of the print in the image, degrees (counter-clockwise).
    perspective
        Foreshortening from one side of the image to the other (0.05: the far side 5 %
        smaller), along a direction ``perspective_axis_deg``.
    perspective_axis_deg
        Direction of the tilt in the image, degrees.
    blur_px
        Gaussian blur sigma, px (0: none).
    noise_dn
        Gaussian noise standard deviation, grey levels.
    shading
        Lighting falls off by this fraction from the centre to the corners.
    mirrored
        Mirror the print (scanned face down).
    background_dn, bead_dn
        Grey level of the bed and of the bead.
    margin_mm
        Empty border around the pattern, mm.
    seed
        Seed of the noise.
    """

    px_per_mm: float = 12.0
    rotation_deg: float = 0.0
    perspective: float = 0.0
    perspective_axis_deg: float = 30.0
    blur_px: float = 0.0
    noise_dn: float = 0.0
    shading: float = 0.0
    mirrored: bool = False
    background_dn: float = 220.0
    bead_dn: float = 50.0
    margin_mm: float = 6.0
    seed: int = 0

    def __post_init__(self) -> None:
        checks = (("px_per_mm", 2.0 <= self.px_per_mm <= 200.0, "2 .. 200 px/mm"),
                  ("rotation_deg", abs(self.rotation_deg) <= 180.0, "-180 .. 180"),
                  ("perspective", 0.0 <= self.perspective <= 0.5, "0 .. 0.5"),
                  ("blur_px", 0.0 <= self.blur_px <= 20.0, "0 .. 20 px"),
                  ("noise_dn", 0.0 <= self.noise_dn <= 100.0, "0 .. 100"),
                  ("shading", 0.0 <= self.shading < 1.0, "0 .. < 1"),
                  ("bead_dn", 0.0 <= self.bead_dn < self.background_dn <= 255.0,
                   "0 <= bead < background <= 255"),
                  ("margin_mm", 0.0 <= self.margin_mm <= 100.0, "0 .. 100 mm"))
        for name, ok, allowed in checks:
            if not ok:
                raise CalibrationError("invalid image condition", field=name,
                                       value=getattr(self, name), allowed=allowed)


@dataclass(frozen=True)
class RenderedImage:
    """A rendered pattern image and its ground truth.

    Attributes
    ----------
    image
        Grey image, uint8, shape ``(H, W)``.
    homography
        Bed coordinates (mm, ``[x, y, 1]``) → output pixels (``[col, row, 1]``), 3 × 3.
    params
        The lag, dead time and gain the widths were predicted with.
    conditions
        How the image was degraded.
    """

    image: npt.NDArray[np.uint8]
    homography: FloatArray
    params: LagParams
    conditions: ImageConditions

    def to_px(self, xy_mm: npt.ArrayLike) -> FloatArray:
        """Map bed points (mm), shape ``(n, 2)``, to image pixels ``(col, row)``."""
        pts = np.asarray(xy_mm, dtype=np.float64).reshape(-1, 1, 2)
        return np.asarray(cv2.perspectiveTransform(pts, self.homography).reshape(-1, 2))


def _draw_run(coverage: FloatArray, vertices_px: FloatArray, s_px: FloatArray,
              half_px: FloatArray) -> None:
    """Max-composite one bead (polyline with varying half-width) into ``coverage``.

    For every pixel near a segment: the distance ``d`` to the segment and the half-width
    ``r`` at the pixel's foot point; coverage ``clip(min(r − d + 0.5, 2r), 0, 1)`` (a
    one-pixel antialiasing ramp, the area a straight edge covers; a bead thinner than a
    pixel covers at most its width). Beyond the run's two ends the
    distance is to the end point (round end caps); a corner gets a round join (a disc),
    a straight joint none, so the bead is exactly as wide as the width profile says.
    """
    h, w = coverage.shape
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(vertices_px, axis=0).T))))
    reach = float(np.max(half_px)) + 2.0
    last = vertices_px.shape[0] - 2
    for k in range(last + 1):
        a, b = vertices_px[k], vertices_px[k + 1]
        seg = b - a
        length = float(np.hypot(*seg))
        if length <= 0.0:
            continue
        c0 = max(int(math.floor(min(a[0], b[0]) - reach)), 0)
        c1 = min(int(math.ceil(max(a[0], b[0]) + reach)) + 1, w)
        r0 = max(int(math.floor(min(a[1], b[1]) - reach)), 0)
        r1 = min(int(math.ceil(max(a[1], b[1]) + reach)) + 1, h)
        if c0 >= c1 or r0 >= r1:
            continue
        cols, rows = np.meshgrid(np.arange(c0, c1) + 0.0, np.arange(r0, r1) + 0.0)
        t = ((cols - a[0]) * seg[0] + (rows - a[1]) * seg[1]) / length
        lo = -math.inf if k == 0 else 0.0
        hi = math.inf if k == last else length
        inside = (t >= lo) & (t <= hi)
        tc = np.clip(t, 0.0, length)
        d = np.hypot(cols - (a[0] + seg[0] * tc / length), rows - (a[1] + seg[1] * tc / length))
        r = np.interp(cum[k] + tc, s_px, half_px)
        cov = np.where(inside, np.clip(np.minimum(r - d + 0.5, 2.0 * r), 0.0, 1.0), 0.0)
        if k < last:
            nxt = vertices_px[k + 2] - b
            turn = float(np.dot(seg, nxt) / max(length * float(np.hypot(*nxt)), 1e-12))
            if turn < math.cos(math.radians(20.0)):     # a corner: round join
                rj = float(np.interp(cum[k + 1], s_px, half_px))
                dj = np.hypot(cols - b[0], rows - b[1])
                cov = np.maximum(cov, np.clip(np.minimum(rj - dj + 0.5, 2.0 * rj), 0.0, 1.0))
        np.maximum(coverage[r0:r1, c0:c1], cov, out=coverage[r0:r1, c0:c1])


def _distortion(shape: tuple[int, int], c: ImageConditions) -> tuple[FloatArray,
                                                                      tuple[int, int]]:
    """Homography flat image → output image, and the output size (W, H)."""
    h, w = shape
    centre = np.array([[1.0, 0.0, -w / 2.0], [0.0, 1.0, -h / 2.0], [0.0, 0.0, 1.0]])
    th = math.radians(c.rotation_deg)
    rot = np.array([[math.cos(th), math.sin(th), 0.0], [-math.sin(th), math.cos(th), 0.0],
                    [0.0, 0.0, 1.0]])
    # perspective: points at +D along the axis shrink by (1 - p), at -D grow (p split evenly)
    ax = math.radians(c.perspective_axis_deg)
    span = max(w, h) / 2.0
    g = c.perspective / (2.0 * span)
    persp = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                      [g * math.cos(ax), g * math.sin(ax), 1.0]])
    m = persp @ rot @ centre
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64).reshape(-1, 1, 2)
    out = cv2.perspectiveTransform(corners, m).reshape(-1, 2)
    lo, hi = out.min(axis=0), out.max(axis=0)
    shift = np.array([[1.0, 0.0, -lo[0]], [0.0, 1.0, -lo[1]], [0.0, 0.0, 1.0]])
    size = (int(math.ceil(hi[0] - lo[0])), int(math.ceil(hi[1] - lo[1])))
    return shift @ m, size


def render_pattern_image(source: str | os.PathLike[str] | bytes | BinaryIO,
                         params: LagParams, *,
                         machine: Machine | str | os.PathLike[str] | None = None,
                         conditions: ImageConditions | None = None) -> RenderedImage:
    """Render a top view of what ``source`` prints, with the twin's widths for ``params``.

    Parameters
    ----------
    source
        The pattern's G-code.
    params
        Lag, dead time and gain of the printer being imitated.
    machine
        Set-up whose printer plans the file (default: the lag model's default).
    conditions
        Scale, rotation, perspective, blur, noise, lighting, mirroring.

    Returns
    -------
    RenderedImage
        The image and its ground truth.
    """
    c = conditions or ImageConditions()
    model = lag_model(source, None, machine=machine)
    step_mm = 0.5 / c.px_per_mm
    beads = []
    for line in model.lines:
        s = np.arange(0.0, line.length_mm + step_mm, step_mm)
        s[-1] = min(s[-1], line.length_mm)
        beads.append((line, s))
    widths = model.widths(params, [s for _, s in beads])
    pts = np.vstack([ln.vertices_xy_mm for ln in model.lines])
    lo = pts.min(axis=0) - c.margin_mm
    hi = pts.max(axis=0) + c.margin_mm
    k = c.px_per_mm
    w_px, h_px = int(math.ceil((hi[0] - lo[0]) * k)), int(math.ceil((hi[1] - lo[1]) * k))
    if w_px * h_px > 40_000_000:
        raise CalibrationError("the rendered image would be too large", field="px_per_mm",
                               value=k, allowed=f"at most 40 Mpx ({w_px} × {h_px} asked)")
    # top view: bed x to the right, bed y up (row = (hi_y - y)·k); mirrored: x to the left
    if c.mirrored:
        flat = np.array([[-k, 0.0, (hi[0]) * k], [0.0, -k, hi[1] * k], [0.0, 0.0, 1.0]])
    else:
        flat = np.array([[k, 0.0, -lo[0] * k], [0.0, -k, hi[1] * k], [0.0, 0.0, 1.0]])
    coverage = np.zeros((h_px, w_px))
    for (line, s), w in zip(beads, widths, strict=True):
        half = np.where(w >= 0.5 * line.layer_height_mm,
                        0.5 * np.minimum(w, _MAX_WIDTH_PER_HEIGHT * line.layer_height_mm),
                        0.0)
        half = np.where(np.isfinite(half), half, 0.0)
        verts = np.asarray(cv2.perspectiveTransform(line.vertices_xy_mm.reshape(-1, 1, 2)
                                                    .astype(np.float64), flat).reshape(-1, 2),
                           dtype=np.float64)
        _draw_run(coverage, verts, s * k, half * k)
    img = c.background_dn - (c.background_dn - c.bead_dn) * coverage
    if c.shading > 0.0:
        rows, cols = np.mgrid[0:h_px, 0:w_px]
        rr = np.hypot((cols - w_px / 2) / (w_px / 2), (rows - h_px / 2) / (h_px / 2)) / math.sqrt(2)
        img = img * (1.0 - c.shading * rr ** 2)
    warp, size = _distortion((h_px, w_px), c)
    out = cv2.warpPerspective(np.asarray(img, dtype=np.float32), warp, size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT,
                              borderValue=float(c.background_dn * (1.0 - c.shading)))
    if c.blur_px > 0.0:
        out = cv2.GaussianBlur(out, (0, 0), sigmaX=c.blur_px)
    if c.noise_dn > 0.0:
        rng = np.random.default_rng(c.seed)
        out = np.asarray(out + rng.normal(0.0, c.noise_dn, out.shape), dtype=np.float32)
    image = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    return RenderedImage(image=image, homography=warp @ flat, params=params, conditions=c)
