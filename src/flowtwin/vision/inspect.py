"""Annotated frame to check a camera set-up: ROIs, trackable features, edges, gear axis."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_write_bytes
from flowtwin.errors import VisionError
from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import detect_features
from flowtwin.vision.roi import Roi
from flowtwin.vision.source import open_source
from flowtwin.vision.width import measure_width_px

__all__ = ["InspectReport", "annotate_frame", "inspect_source"]

_COLOURS = {"gear": (60, 60, 255), "before": (60, 220, 60), "after": (255, 140, 40)}


@dataclass(frozen=True, slots=True)
class InspectReport:
    """What the set-up check found in one frame.

    Attributes
    ----------
    frame, t_s
        Index and capture time of the frame used.
    width_px, height_px
        Frame size, px.
    rois
        ROIs drawn, ``{name: [x, y, w, h]}``.
    features
        Trackable Shi–Tomasi features per ROI (``gear`` and ``after``).
    filament_width_px
        Width found in the ``before`` ROI, px (None if not found).
    filament_width_mm
        The same in mm when a scale was given.
    contact_radius_px
        Distance from the gear axis to the nearer filament edge, px (if both known).
    problems
        Everything that would stop or degrade a measurement, in words.
    """

    frame: int
    t_s: float
    width_px: int
    height_px: int
    rois: dict[str, list[int]]
    features: dict[str, int]
    filament_width_px: float | None
    filament_width_mm: float | None
    contact_radius_px: float | None
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def annotate_frame(gray: npt.NDArray[np.uint8], rois: Mapping[str, Roi], *,
                   params: TrackingParams | None = None,
                   gear_center_px: tuple[float, float] | None = None,
                   mm_per_px: float | None = None, frame: int = 0, t_s: float = 0.0,
                   ) -> tuple[npt.NDArray[np.uint8], InspectReport]:
    """Draw the ROIs, their trackable features, the filament edges and the gear axis.

    Parameters
    ----------
    gray
        Grey frame, shape ``(H, W)``, uint8.
    rois
        Any of the ``gear``, ``before``, ``after`` ROIs.
    params
        Tracking parameters (feature detection thresholds).
    gear_center_px
        Gear axis ``(x, y)``, px, if known.
    mm_per_px
        Image scale, mm/px, if known.
    frame, t_s
        Frame index and time, for the report.

    Returns
    -------
    image : numpy.ndarray
        Annotated colour image, shape ``(H, W, 3)``, uint8 (BGR).
    report : InspectReport
    """
    p = params or TrackingParams()
    h, w = gray.shape[:2]
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    problems: list[str] = []
    features: dict[str, int] = {}
    width_px: float | None = None
    contact: float | None = None
    for name in ("gear", "before", "after"):
        if name not in rois:
            problems.append(f"ROI '{name}' is not set (--roi {name}=x,y,w,h)")
    for name, roi in rois.items():
        colour = _COLOURS.get(name, (255, 255, 255))
        try:
            roi.check_inside(w, h)
        except VisionError as exc:
            problems.append(str(exc))
        cv2.rectangle(out, (roi.x, roi.y), (roi.x1 - 1, roi.y1 - 1), colour, 1)
        cv2.putText(out, name, (roi.x + 3, max(roi.y + 14, 14)), cv2.FONT_HERSHEY_SIMPLEX,
                    0.45, colour, 1, cv2.LINE_AA)
        x0, y0, x1, y1 = max(roi.x, 0), max(roi.y, 0), min(roi.x1, w), min(roi.y1, h)
        if x1 - x0 < 8 or y1 - y0 < 8:
            continue
        crop = gray[y0:y1, x0:x1]
        if name in ("gear", "after"):
            pts = detect_features(crop, p)
            features[name] = int(len(pts))
            for x, y in pts:
                cv2.circle(out, (int(round(x + x0)), int(round(y + y0))), 2, colour, -1,
                           cv2.LINE_AA)
            if len(pts) < p.min_tracks:
                problems.append(f"ROI '{name}' has {len(pts)} trackable features "
                                f"(at least {p.min_tracks} needed): low texture")
        else:
            em = measure_width_px(crop, sigma_px=p.width_sigma_px,
                                  min_edge_dn_px=p.min_edge_dn_px)
            if em.ok:
                width_px = em.width_px
                for xe in (em.left_px, em.right_px):
                    xi = int(round(xe + x0))
                    cv2.line(out, (xi, y0), (xi, y1 - 1), (0, 255, 255), 1)
                if gear_center_px is not None:
                    cx = gear_center_px[0]
                    contact = min(abs(em.left_px + x0 - cx), abs(em.right_px + x0 - cx))
            else:
                problems.append(f"ROI 'before': {em.reason}")
    if gear_center_px is not None:
        cx, cy = gear_center_px
        c = (int(round(cx)), int(round(cy)))
        cv2.drawMarker(out, c, (60, 60, 255), cv2.MARKER_CROSS, 16, 1)
        if contact is not None:
            cv2.circle(out, c, int(round(contact)), (60, 60, 255), 1, cv2.LINE_AA)
    text = f"{w}x{h}"
    if width_px is not None:
        text += f"  width {width_px:.2f} px"
        if mm_per_px is not None:
            text += f" = {width_px * mm_per_px:.4f} mm"
    cv2.putText(out, text, (5, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1,
                cv2.LINE_AA)
    report = InspectReport(
        frame=frame, t_s=t_s, width_px=w, height_px=h,
        rois={n: [r.x, r.y, r.w, r.h] for n, r in rois.items()}, features=features,
        filament_width_px=width_px,
        filament_width_mm=None if width_px is None or mm_per_px is None
        else width_px * mm_per_px,
        contact_radius_px=contact, problems=problems)
    return np.asarray(out), report


def inspect_source(source: str | Path | int, rois: Mapping[str, Roi], out_png: str | Path, *,
                   frame_index: int = 0, params: TrackingParams | None = None,
                   gear_center_px: tuple[float, float] | None = None,
                   mm_per_px: float | None = None) -> InspectReport:
    """Write an annotated frame of ``source`` to ``out_png`` and report what was found.

    Parameters
    ----------
    source
        Video file, image folder or camera index.
    rois
        ROIs to check.
    out_png
        Output image (PNG), written atomically.
    frame_index
        Which frame to use (0-based).
    params, gear_center_px, mm_per_px
        As for :func:`annotate_frame`.

    Returns
    -------
    InspectReport

    Raises
    ------
    VisionError
        Unreadable source, or fewer frames than ``frame_index + 1``.
    """
    if frame_index < 0:
        raise VisionError("frame index must be >= 0", field="frame", value=frame_index,
                          allowed=">= 0")
    with open_source(source, max_frames=frame_index + 1) as src:
        chosen = None
        for fr in src:
            chosen = fr
        if chosen is None or chosen.index != frame_index:
            raise VisionError("the source has fewer frames than requested",
                              source=src.description, field="frame", value=frame_index,
                              allowed=f"0..{src.frames_read - 1}")
    image, report = annotate_frame(chosen.image, rois, params=params,
                                   gear_center_px=gear_center_px, mm_per_px=mm_per_px,
                                   frame=chosen.index, t_s=chosen.t_s)
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise VisionError("could not encode the annotated frame", source=str(out_png))
    atomic_write_bytes(out_png, buf.tobytes())
    return report
