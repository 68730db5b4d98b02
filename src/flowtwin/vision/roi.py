"""Regions of interest (ROIs) of the slip camera [003 §2, Fig. 2b].

Three rectangles, in pixels of the camera frame (x to the right, y down, origin at the
top-left pixel): ``gear`` over the drive gear (gear speed), ``before`` over the filament
before the gear, across both of its edges (width), and ``after`` inside the filament after
the gear (filament speed). On the command line each is written ``name=x,y,w,h``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass

from flowtwin.errors import VisionError

__all__ = ["MAX_COORD_PX", "MIN_ROI_PX", "ROI_NAMES", "Roi", "RoiSet", "parse_roi",
           "parse_rois", "roi_from_sequence"]

#: The three ROIs of [003 Fig. 2b], in the order they are reported.
ROI_NAMES = ("gear", "before", "after")
#: Smallest ROI side: a Lucas–Kanade window and an edge search both need room.
MIN_ROI_PX = 8
#: Largest coordinate accepted (no camera has frames this large).
MAX_COORD_PX = 100_000

_ROI_TEXT = re.compile(r"^\s*([A-Za-z_]+)\s*=\s*([^=]*)$")


@dataclass(frozen=True, slots=True)
class Roi:
    """One rectangular region of interest in frame pixels.

    Attributes
    ----------
    name
        One of :data:`ROI_NAMES`.
    x, y
        Top-left corner, px (column, row), ``>= 0``.
    w, h
        Width and height, px, ``>= MIN_ROI_PX``.
    """

    name: str
    x: int
    y: int
    w: int
    h: int

    def __post_init__(self) -> None:
        if self.name not in ROI_NAMES:
            raise VisionError("unknown region of interest", field="roi", value=self.name,
                              allowed=", ".join(ROI_NAMES))
        for key in ("x", "y", "w", "h"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int):
                raise VisionError(f"ROI '{self.name}' {key} must be an integer pixel count",
                                  field=f"roi.{self.name}.{key}", value=value,
                                  allowed="integers")
        if not (0 <= self.x <= MAX_COORD_PX and 0 <= self.y <= MAX_COORD_PX):
            raise VisionError(f"ROI '{self.name}' corner is outside the allowed range",
                              field=f"roi.{self.name}", value=(self.x, self.y),
                              allowed=f"0 <= x, y <= {MAX_COORD_PX}")
        if not (MIN_ROI_PX <= self.w <= MAX_COORD_PX and MIN_ROI_PX <= self.h <= MAX_COORD_PX):
            raise VisionError(f"ROI '{self.name}' is too small or too large",
                              field=f"roi.{self.name}", value=(self.w, self.h),
                              allowed=f"{MIN_ROI_PX} <= w, h <= {MAX_COORD_PX}")

    @property
    def x1(self) -> int:
        """Column one past the right edge, px."""
        return self.x + self.w

    @property
    def y1(self) -> int:
        """Row one past the bottom edge, px."""
        return self.y + self.h

    @property
    def slices(self) -> tuple[slice, slice]:
        """``(rows, columns)`` slices that cut this ROI out of a frame array."""
        return slice(self.y, self.y1), slice(self.x, self.x1)

    @property
    def center(self) -> tuple[float, float]:
        """Centre ``(x, y)`` in px (pixel centres at integer coordinates)."""
        return self.x + (self.w - 1) / 2.0, self.y + (self.h - 1) / 2.0

    def text(self) -> str:
        """The ``name=x,y,w,h`` form accepted by :func:`parse_roi`."""
        return f"{self.name}={self.x},{self.y},{self.w},{self.h}"

    def check_inside(self, width_px: int, height_px: int, *, source: str | None = None) -> None:
        """Raise :class:`VisionError` unless the ROI lies inside a ``width × height`` frame."""
        if self.x1 > width_px or self.y1 > height_px:
            over = []
            if self.x1 > width_px:
                over.append(f"x + w = {self.x1} > {width_px}")
            if self.y1 > height_px:
                over.append(f"y + h = {self.y1} > {height_px}")
            raise VisionError(
                f"ROI '{self.name}' extends beyond the {width_px}×{height_px} frame "
                f"({'; '.join(over)})", source=source, field=f"roi.{self.name}",
                value=self.text(),
                allowed=f"0 <= x, x + w <= {width_px}, 0 <= y, y + h <= {height_px}")

    def padded(self, pad_px: int, width_px: int, height_px: int) -> tuple[int, int, int, int]:
        """The ROI grown by ``pad_px`` on every side and clipped to the frame.

        Returns ``(x0, y0, x1, y1)`` with exclusive ``x1, y1``.
        """
        return (max(0, self.x - pad_px), max(0, self.y - pad_px),
                min(width_px, self.x1 + pad_px), min(height_px, self.y1 + pad_px))


@dataclass(frozen=True, slots=True)
class RoiSet:
    """The gear, before-gear and after-gear ROIs of one camera set-up [003 Fig. 2b]."""

    gear: Roi
    before: Roi
    after: Roi

    def __post_init__(self) -> None:
        for name in ROI_NAMES:
            roi = getattr(self, name)
            if roi.name != name:
                raise VisionError(f"RoiSet.{name} holds the ROI named '{roi.name}'",
                                  field=f"roi.{name}", value=roi.text(), allowed=name)

    @classmethod
    def from_mapping(cls, rois: Mapping[str, Roi], *, source: str | None = None) -> RoiSet:
        """Build from ``{name: Roi}``; every one of :data:`ROI_NAMES` must be present."""
        missing = [n for n in ROI_NAMES if n not in rois]
        if missing:
            raise VisionError(
                "missing region(s) of interest: " + ", ".join(missing)
                + " (give them as --roi NAME=x,y,w,h or in the [roi] table of a config file)",
                source=source, field="roi", allowed="gear, before and after, each x,y,w,h px")
        return cls(gear=rois["gear"], before=rois["before"], after=rois["after"])

    def __iter__(self) -> Iterator[Roi]:
        """The gear, before and after ROIs, in that order."""
        return iter((self.gear, self.before, self.after))

    def check_inside(self, width_px: int, height_px: int, *, source: str | None = None) -> None:
        """Raise :class:`VisionError` naming the first ROI that leaves the frame."""
        for roi in self:
            roi.check_inside(width_px, height_px, source=source)


def _parse_int(text: str, *, name: str, key: str, source: str) -> int:
    token = text.strip()
    if not re.fullmatch(r"[+]?\d{1,9}", token):
        raise VisionError(f"ROI '{name}' {key} is not a whole number of pixels", source=source,
                          field=f"roi.{name}.{key}", value=token,
                          allowed="non-negative integers, e.g. gear=120,80,200,160")
    return int(token)


def parse_roi(text: str, *, source: str = "--roi") -> Roi:
    """Parse one ``name=x,y,w,h`` ROI (pixels).

    Parameters
    ----------
    text
        For example ``"after=398,300,64,170"``; ``name`` is one of :data:`ROI_NAMES`.
    source
        Where the text came from, for error messages.

    Returns
    -------
    Roi

    Raises
    ------
    VisionError
        If the text is not of that form, the name is unknown or a number is out of range.
    """
    if not isinstance(text, str):
        raise VisionError("ROI must be text of the form name=x,y,w,h", source=source,
                          value=text, allowed="name=x,y,w,h with name in gear, before, after")
    match = _ROI_TEXT.match(text)
    if match is None:
        raise VisionError("ROI must be of the form name=x,y,w,h", source=source, value=text,
                          allowed="name=x,y,w,h with name in gear, before, after")
    name = match.group(1).strip().lower()
    if name not in ROI_NAMES:
        raise VisionError("unknown region of interest", source=source, field="roi",
                          value=match.group(1), allowed=", ".join(ROI_NAMES))
    parts = match.group(2).split(",")
    if len(parts) != 4:
        raise VisionError(f"ROI '{name}' needs four numbers x,y,w,h", source=source,
                          field=f"roi.{name}", value=match.group(2),
                          allowed="x,y,w,h in pixels, e.g. gear=120,80,200,160")
    x, y, w, h = (_parse_int(p, name=name, key=k, source=source)
                  for p, k in zip(parts, "xywh", strict=True))
    return Roi(name, x, y, w, h)


def parse_rois(texts: Iterable[str], *, source: str = "--roi") -> dict[str, Roi]:
    """Parse several ``name=x,y,w,h`` texts; a name given twice is an error."""
    out: dict[str, Roi] = {}
    for text in texts:
        roi = parse_roi(text, source=source)
        if roi.name in out:
            raise VisionError(f"ROI '{roi.name}' given twice", source=source,
                              field=f"roi.{roi.name}", value=text,
                              allowed="each of gear, before, after at most once")
        out[roi.name] = roi
    return out


def roi_from_sequence(name: str, value: object, *, source: str | None = None) -> Roi:
    """Build a ROI from a ``[x, y, w, h]`` list (as read from a TOML file)."""
    if name not in ROI_NAMES:
        raise VisionError("unknown region of interest", source=source, field=f"roi.{name}",
                          value=name, allowed=", ".join(ROI_NAMES))
    if not isinstance(value, list | tuple) or len(value) != 4:
        raise VisionError(f"ROI '{name}' must be a list of four integers [x, y, w, h]",
                          source=source, field=f"roi.{name}", value=value,
                          allowed="[x, y, w, h] in pixels")
    for key, item in zip("xywh", value, strict=True):
        if isinstance(item, bool) or not isinstance(item, int):
            raise VisionError(f"ROI '{name}' {key} must be an integer pixel count",
                              source=source, field=f"roi.{name}.{key}", value=item,
                              allowed="integers")
    try:
        return Roi(name, *value)
    except VisionError as exc:
        raise VisionError(exc.message, source=source, field=exc.field, value=exc.value,
                          allowed=exc.allowed) from None
