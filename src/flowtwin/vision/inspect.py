"""Check a camera set-up by drawing what the measurement finds.

Over a short window of frames the trackers of the ``gear`` and ``after`` ROIs run as in a
measurement, the width is measured in ``before`` and, when not given, the gear axis is
estimated from the motion (:mod:`flowtwin.vision.axis`). The last frame of the window is
drawn with:

* the ROIs (gear red, before green, after blue);
* **tracks** of the last step: kept (passed every check and agreed) as filled dots in
  the ROI's colour, rejected as red crosses;
* **edges** in ``before``: the rows' edge points that were used (yellow) and those that
  were not (grey), the two fitted edge lines, and competing edge pairs that were not
  taken (magenta); a refused width is written in red with its reason;
* the **gear axis** (cross) with the circle through the nearer filament edge (the contact
  radius), labelled ``given`` or ``estimated``.

Everything that would stop or degrade a measurement is listed in ``problems``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_write_bytes
from flowtwin.errors import VisionError
from flowtwin.vision.axis import estimate_gear_axis
from flowtwin.vision.capture import Frame, open_source
from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import detect_features
from flowtwin.vision.roi import Roi
from flowtwin.vision.track import RoiTracker
from flowtwin.vision.width import EdgeMeasurement, expected_width_px, measure_width_px

__all__ = ["InspectReport", "annotate_frame", "inspect_frames", "inspect_source"]

U8 = npt.NDArray[np.uint8]
_COLOURS = {"gear": (60, 60, 255), "before": (60, 220, 60), "after": (255, 140, 40)}
_KEPT_EDGE = (0, 230, 255)
_UNUSED_EDGE = (150, 150, 150)
_REJECTED = (60, 60, 255)
_COMPETING = (255, 0, 255)


@dataclass(frozen=True, slots=True)
class InspectReport:
    """What the set-up check found.

    Attributes
    ----------
    frame, t_s
        Index and capture time of the frame drawn.
    width_px, height_px
        Frame size, px.
    rois
        ROIs drawn, ``{name: [x, y, w, h]}``.
    features
        Trackable Shi–Tomasi features per ROI (``gear`` and ``after``) in the first
        frame of the window.
    tracks_kept, tracks_rejected
        Tracks of the last step that passed / failed the checks, per tracking ROI.
    filament_width_px
        Width found in the ``before`` ROI, px (None if refused).
    filament_width_mm
        The same in mm when a scale was given.
    width_status
        ``ok``, ``no_edges``, ``ambiguous`` or ``few_rows`` (None without a before ROI).
    contact_radius_px
        Distance from the gear axis to the nearer filament edge, px (if both known).
    gear_axis_px
        Gear axis drawn, ``[x, y]`` (None if neither given nor found).
    gear_axis_source
        ``"given"`` or ``"estimated"``.
    gear_axis_note
        What the axis estimate found.
    frames_used
        Frames of the window.
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
    tracks_kept: dict[str, int] = field(default_factory=dict)
    tracks_rejected: dict[str, int] = field(default_factory=dict)
    width_status: str | None = None
    gear_axis_px: list[float] | None = None
    gear_axis_source: str | None = None
    gear_axis_note: str | None = None
    frames_used: int = 1
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _inside(roi: Roi, w: int, h: int) -> bool:
    return roi.x1 <= w and roi.y1 <= h


def _draw_tracks(out: U8, tracker: RoiTracker, colour: tuple[int, int, int]) -> tuple[int, int]:
    pts, kept = tracker.last_points, tracker.last_kept
    for (x, y), ok in zip(pts, kept, strict=True):
        c = (int(round(x)), int(round(y)))
        if ok:
            cv2.circle(out, c, 2, colour, -1, cv2.LINE_AA)
        else:
            cv2.drawMarker(out, c, _REJECTED, cv2.MARKER_TILTED_CROSS, 6, 1)
    return int(kept.sum()), int((~kept).sum())


def _draw_edges(out: U8, em: EdgeMeasurement, roi: Roi) -> None:
    rows = np.arange(em.row_left_px.size)
    for xs in (em.row_left_px, em.row_right_px):
        for y, x, used in zip(rows, xs, em.row_used, strict=True):
            if math.isfinite(x):
                out[roi.y + y, min(max(int(round(x)) + roi.x, 0), out.shape[1] - 1)] = (
                    _KEPT_EDGE if used else _UNUSED_EDGE)
    for y0, y1, left, right, _ in em.rejected:
        for x in (left, right):
            xi = int(round(x)) + roi.x
            cv2.line(out, (xi, roi.y + y0), (xi, roi.y + y1 - 1), _COMPETING, 1)
    if em.ok:
        h = em.row_left_px.size
        slope = math.tan(em.tilt_rad)
        for x_mid in (em.left_px, em.right_px):
            top = x_mid - slope * 0.5 * (h - 1)
            bottom = x_mid + slope * 0.5 * (h - 1)
            cv2.line(out, (int(round(top + roi.x)), roi.y),
                     (int(round(bottom + roi.x)), roi.y1 - 1), _KEPT_EDGE, 1, cv2.LINE_AA)


def annotate_frame(gray: U8, rois: Mapping[str, Roi], *, params: TrackingParams | None = None,
                   gear_center_px: tuple[float, float] | None = None,
                   mm_per_px: float | None = None, frame: int = 0, t_s: float = 0.0,
                   diameter_mm: float | None = None) -> tuple[U8, InspectReport]:
    """Draw the ROIs, trackable features, edges and gear axis on one frame.

    A single frame has no motion: features are drawn as found (no kept/rejected tracks)
    and the axis only if given. :func:`inspect_frames` does the full check.

    Parameters
    ----------
    gray
        Grey frame, shape ``(H, W)``, uint8.
    rois
        Any of the ``gear``, ``before``, ``after`` ROIs.
    params
        Tracking parameters.
    gear_center_px
        Gear axis ``(x, y)``, px, if known.
    mm_per_px
        Image scale, mm/px, if known.
    frame, t_s
        Frame index and time, for the report.
    diameter_mm
        Nominal filament diameter (plausible widths), mm.

    Returns
    -------
    image : numpy.ndarray
        Annotated colour image, shape ``(H, W, 3)``, uint8 (BGR).
    report : InspectReport
    """
    return inspect_frames([Frame(frame, t_s, gray)], rois, params=params,
                          gear_center_px=gear_center_px, mm_per_px=mm_per_px,
                          diameter_mm=diameter_mm)


def inspect_frames(frames: Sequence[Frame], rois: Mapping[str, Roi], *,
                   params: TrackingParams | None = None,
                   gear_center_px: tuple[float, float] | None = None,
                   mm_per_px: float | None = None, diameter_mm: float | None = None,
                   direction: str = "down") -> tuple[U8, InspectReport]:
    """Run the trackers, the width and the axis estimate over ``frames``; draw the last.

    Parameters
    ----------
    frames
        Consecutive frames (one is enough for ROIs, features and edges; tracks and an
        estimated axis need motion over several).
    rois
        Any of the ``gear``, ``before``, ``after`` ROIs.
    params
        Tracking parameters.
    gear_center_px
        Gear axis ``(x, y)``, px; ``None``: estimated from the motion in the gear ROI.
    mm_per_px
        Image scale, mm/px, if known (plausible widths, width in mm).
    diameter_mm
        Nominal filament diameter, mm.
    direction
        Feed direction in the image, ``"down"`` or ``"up"``.

    Returns
    -------
    image : numpy.ndarray
        Annotated colour image of the last frame, shape ``(H, W, 3)``, uint8 (BGR).
    report : InspectReport
    """
    if not frames:
        raise VisionError("no frames to inspect")
    p = params or TrackingParams()
    last = frames[-1]
    gray = last.image
    h, w = gray.shape[:2]
    size = (w, h)
    out: U8 = np.asarray(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    problems: list[str] = []
    features: dict[str, int] = {}
    kept: dict[str, int] = {}
    rejected: dict[str, int] = {}
    for name in ("gear", "before", "after"):
        if name not in rois:
            problems.append(f"ROI '{name}' is not set (--roi {name}=x,y,w,h)")
    usable: dict[str, Roi] = {}
    for name, roi in rois.items():
        try:
            roi.check_inside(w, h)
            usable[name] = roi
        except VisionError as exc:
            problems.append(str(exc))
    # gear axis: given, or estimated from the motion
    center = gear_center_px
    axis_source: str | None = "given" if center is not None else None
    axis_note: str | None = None
    axis_problem = False
    if center is None and "gear" in usable and len(frames) > 1:
        est = estimate_gear_axis([f.image for f in frames], usable["gear"], p)
        axis_note = est.reason
        if est.is_rotation and est.center_px is not None:
            center, axis_source = est.center_px, "estimated"
        else:
            axis_problem = est.moved
    # tracks
    sign = 1.0 if direction == "down" else -1.0
    for name in ("gear", "after"):
        if name not in usable:
            continue
        roi = usable[name]
        first = frames[0].image
        features[name] = int(len(detect_features(first[roi.slices], p)))
        if features[name] < p.min_tracks:
            problems.append(f"ROI '{name}' has {features[name]} trackable features "
                            f"(at least {p.min_tracks} needed): low texture")
        if len(frames) > 1:
            if name == "gear" and center is not None:
                tracker = RoiTracker(roi, size, p, mode="rotation", center_px=center)
            else:
                tracker = RoiTracker(roi, size, p, axis=(0.0, sign),
                                     inset_px=p.win_px // 2 if name == "after" else 0)
            for fr in frames:
                tracker.update(fr.image, 1.0)
            kept[name], rejected[name] = _draw_tracks(out, tracker, _COLOURS[name])
            if kept[name] < p.min_tracks:
                problems.append(f"ROI '{name}': {kept[name]} tracks kept in the last step "
                                f"(at least {p.min_tracks} needed)")
        else:
            for x, y in detect_features(first[roi.slices], p):
                cv2.circle(out, (int(round(x + roi.x)), int(round(y + roi.y))), 2,
                           _COLOURS[name], -1, cv2.LINE_AA)
    # width
    width_px: float | None = None
    status: str | None = None
    contact: float | None = None
    if "before" in usable:
        roi = usable["before"]
        em = measure_width_px(gray[roi.slices], sigma_px=p.width_sigma_px,
                              min_edge_dn_px=p.min_edge_dn_px,
                              expected_px=expected_width_px(mm_per_px, diameter_mm))
        status = em.status
        _draw_edges(out, em, roi)
        if em.ok:
            width_px = em.width_px
            if center is not None:
                contact = min(abs(em.left_px + roi.x - center[0]),
                              abs(em.right_px + roi.x - center[0]))
        else:
            problems.append(f"ROI 'before': width refused ({em.status}): {em.reason}")
    for name, roi in rois.items():
        colour = _COLOURS.get(name, (255, 255, 255))
        cv2.rectangle(out, (roi.x, roi.y), (roi.x1 - 1, roi.y1 - 1), colour, 1)
        cv2.putText(out, name, (roi.x + 3, max(roi.y + 14, 14)), cv2.FONT_HERSHEY_SIMPLEX,
                    0.45, colour, 1, cv2.LINE_AA)
    if center is not None:
        c = (int(round(center[0])), int(round(center[1])))
        cv2.drawMarker(out, c, _COLOURS["gear"], cv2.MARKER_CROSS, 16, 1)
        cv2.putText(out, f"axis ({axis_source})", (c[0] + 6, c[1] - 6),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.4, _COLOURS["gear"], 1, cv2.LINE_AA)
        if contact is not None:
            cv2.circle(out, c, int(round(contact)), _COLOURS["gear"], 1, cv2.LINE_AA)
    elif axis_problem:
        problems.append(f"the gear moves but no axis was found: {axis_note} (tangential "
                        "mode reads the lever arm of the features; give --gear-center)")
    text = f"{w}x{h}"
    if width_px is not None:
        text += f"  width {width_px:.2f} px"
        if mm_per_px is not None:
            text += f" = {width_px * mm_per_px:.4f} mm"
    elif status is not None:
        text += f"  width refused ({status})"
    cv2.putText(out, text, (5, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (255, 255, 255) if width_px is not None else _REJECTED, 1, cv2.LINE_AA)
    report = InspectReport(
        frame=last.index, t_s=last.t_s, width_px=w, height_px=h,
        rois={n: [r.x, r.y, r.w, r.h] for n, r in rois.items()}, features=features,
        filament_width_px=width_px,
        filament_width_mm=None if width_px is None or mm_per_px is None
        else width_px * mm_per_px,
        contact_radius_px=contact, tracks_kept=kept, tracks_rejected=rejected,
        width_status=status,
        gear_axis_px=None if center is None else [float(center[0]), float(center[1])],
        gear_axis_source=axis_source, gear_axis_note=axis_note, frames_used=len(frames),
        problems=problems)
    return out, report


def inspect_source(source: str | Path | int, rois: Mapping[str, Roi], out_png: str | Path, *,
                   frame_index: int = 0, frames: int = 1,
                   params: TrackingParams | None = None,
                   gear_center_px: tuple[float, float] | None = None,
                   mm_per_px: float | None = None, diameter_mm: float | None = None,
                   direction: str = "down") -> InspectReport:
    """Write the annotated last frame of a window of ``source`` to ``out_png``.

    Parameters
    ----------
    source
        Video file, image folder or camera index.
    rois
        ROIs to check.
    out_png
        Output image (PNG), written atomically.
    frame_index
        First frame of the window (0-based).
    frames
        Frames in the window (1: ROIs, features and edges only; 30 or more: also the
        tracks kept and rejected and the gear axis estimated from the motion).
    params, gear_center_px, mm_per_px, diameter_mm, direction
        As for :func:`inspect_frames`.

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
    if frames < 1:
        raise VisionError("the window needs at least one frame", field="frames",
                          value=frames, allowed=">= 1")
    with open_source(source, max_frames=frame_index + frames) as src:
        window = [fr for fr in src if fr.index >= frame_index]
        if not window:
            raise VisionError("the source has fewer frames than requested",
                              source=src.description, field="frame", value=frame_index,
                              allowed=f"0..{src.frames_read - 1}")
    image, report = inspect_frames(window, rois, params=params, gear_center_px=gear_center_px,
                                   mm_per_px=mm_per_px, diameter_mm=diameter_mm,
                                   direction=direction)
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise VisionError("could not encode the annotated frame", source=str(out_png))
    atomic_write_bytes(out_png, buf.tobytes())
    return report
