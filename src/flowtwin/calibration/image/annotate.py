"""An annotated copy of the photo: each line's score on the line, a score plot beside it.

Every test line's found axis is drawn over the photo in a colour from green (its score the
lowest, the most even line) to red (the highest), the best line thicker and marked with its
K; a panel to the right plots the score against K with the most even line and the twin's
fitted lag ``K ± 1σ`` marked. Written atomically (:func:`flowtwin.atomic.atomic_open`).
"""

from __future__ import annotations

import itertools
import math
import os
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_open
from flowtwin.calibration.image.analyse import PhotoResult
from flowtwin.errors import VisionError

__all__ = ["annotated_image", "write_annotated"]


def _colour(t: float) -> tuple[int, int, int]:
    """BGR from green (t = 0) through yellow to red (t = 1); grey for NaN."""
    if not math.isfinite(t):
        return (160, 160, 160)
    t = min(max(t, 0.0), 1.0)
    return (0, int(255 * min(1.0, 2.0 * (1.0 - t))), int(255 * min(1.0, 2.0 * t)))


def annotated_image(image: npt.NDArray[Any], res: PhotoResult) -> npt.NDArray[np.uint8]:
    """The photo (grey or BGR) with the scores drawn on it and a score plot beside it."""
    img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    img = np.ascontiguousarray(img[:, :, :3]).astype(np.uint8)
    h, w = img.shape[:2]
    scores = np.array([r.score for r in res.lines])
    fin = scores[np.isfinite(scores)]
    lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (0.0, 1.0)
    thick = max(1, int(round(h / 500)))
    font = max(0.35, h / 1500)
    for i, (r, ends) in enumerate(zip(res.lines, res.image_lines, strict=True)):
        t = (r.score - lo) / (hi - lo) if hi > lo else 0.0
        a = tuple(int(round(v)) for v in ends[0])
        b = tuple(int(round(v)) for v in ends[1])
        best = i == res.best_index
        cv2.line(img, a, b, _colour(t), 3 * thick if best else thick, cv2.LINE_AA)
        if best:
            cv2.putText(img, f"best K={r.k_la_s:g}", (b[0] + 4 * thick, b[1]),
                        cv2.FONT_HERSHEY_SIMPLEX, font, (0, 255, 0), thick, cv2.LINE_AA)
    # score plot panel
    pw = max(240, w // 3)
    panel = np.full((h, pw, 3), 255, np.uint8)
    ks = np.array([r.k_la_s for r in res.lines])
    x0, x1 = int(0.15 * pw), int(0.95 * pw)
    y0, y1 = int(0.15 * h), int(0.85 * h)
    cv2.rectangle(panel, (x0, y0), (x1, y1), (0, 0, 0), 1)
    kmin, kmax = float(ks.min()), float(ks.max())
    kspan = (kmax - kmin) or 1.0

    def px(k: float, s: float) -> tuple[int, int]:
        return (int(x0 + (k - kmin) / kspan * (x1 - x0)),
                int(y1 - ((s - lo) / (hi - lo) if hi > lo else 0.5) * (y1 - y0)))

    pts = [px(k, s) for k, s in zip(ks, scores, strict=True) if math.isfinite(s)]
    for p, q in itertools.pairwise(pts):
        cv2.line(panel, p, q, (80, 80, 80), 1, cv2.LINE_AA)
    for k, s in zip(ks, scores, strict=True):
        if math.isfinite(s):
            cv2.circle(panel, px(k, s), max(2, thick + 1),
                       _colour((s - lo) / (hi - lo) if hi > lo else 0.0), -1)
    if res.lag is not None:
        k, e = res.lag.k_s, res.lag.k_err_s
        for kk, style in ((k, 2), (k - e, 1), (k + e, 1)):
            if kmin <= kk <= kmax:
                xx = px(kk, lo)[0]
                cv2.line(panel, (xx, y0), (xx, y1), (200, 0, 0), style)
    txt = [f"score vs K ({res.pattern})", f"best line K = {res.k_best_line_s:g} s"]
    txt.append("no lag fit" if res.lag is None else
               f"twin lag K = {res.lag.k_s:.4f} +- {res.lag.k_err_s:.2g} s")
    for j, s in enumerate(txt):
        cv2.putText(panel, s, (x0, int(0.04 * h) + j * int(22 * font + 6)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.8 * font, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(panel, f"{kmin:g}", (x0, y1 + int(20 * font)), cv2.FONT_HERSHEY_SIMPLEX,
                0.7 * font, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(panel, f"{kmax:g} s", (x1 - int(50 * font), y1 + int(20 * font)),
                cv2.FONT_HERSHEY_SIMPLEX, 0.7 * font, (0, 0, 0), 1, cv2.LINE_AA)
    return np.asarray(np.hstack([img, panel]), dtype=np.uint8)


def write_annotated(path: str | os.PathLike[str], image: str | os.PathLike[str],
                    res: PhotoResult) -> None:
    """Write the annotated copy of the photo file ``image`` to ``path`` (PNG or JPEG).

    Raises
    ------
    VisionError
        The photo cannot be read again or the extension is not an image format.
    """
    name = os.fspath(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in (".png", ".jpg", ".jpeg"):
        raise VisionError("unsupported annotated-image format", source=name, value=ext,
                          allowed=".png, .jpg, .jpeg")
    src = cv2.imread(os.fspath(image), cv2.IMREAD_COLOR)
    if src is None:
        raise VisionError("cannot read the image again", source=os.fspath(image))
    ok, buf = cv2.imencode(ext, annotated_image(src, res))
    if not ok:
        raise VisionError("cannot encode the annotated image", source=name)
    with atomic_open(name, "wb") as fh:
        fh.write(buf.tobytes())
