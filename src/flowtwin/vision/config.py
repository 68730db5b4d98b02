"""Configuration of a slip-camera measurement: ROIs, scale, gear geometry, tracking.

A small TOML file holds what belongs to one camera set-up; command-line options override
it. Every key is checked against declared bounds and an unknown key is an error (a typo
is never silently ignored)::

    [roi]                       # pixels: [x, y, w, h]
    gear   = [80, 90, 220, 300]
    before = [372, 10, 116, 130]
    after  = [398, 300, 64, 170]

    [scale]                     # exactly one of the two (or none, then give it on the CLI)
    mm_per_px = 0.02            # known image scale
    # calib_width_mm = 1.75     # known filament width: k_cal = w_µ / w_detected [003 Eq. 4]

    [gear]                      # optional (see docs/vision.md)
    mode = "auto"               # auto | rotation | tangential
    center_px = [190.25, 240.0] # gear axis; default: estimated from the tracked motion
    radius_mm = 3.92            # effective drive radius; default: measured contact radius

    [filament]
    direction = "down"          # feed direction in the image: "down" or "up"
    diameter_mm = 1.75          # nominal diameter: plausible widths (default 1.75 or 2.85)

    [tracking]                  # optional tuning, see TrackingParams
    max_tracks = 40
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal

from flowtwin.errors import VisionError
from flowtwin.vision.roi import ROI_NAMES, Roi, RoiSet, roi_from_sequence

__all__ = ["Direction", "GearMode", "TrackingParams", "VisionConfig", "build_config",
           "load_config_file"]

Direction = Literal["down", "up"]
GearMode = Literal["auto", "rotation", "tangential"]
GEAR_MODES: tuple[GearMode, ...] = ("auto", "rotation", "tangential")


@dataclass(frozen=True, slots=True)
class TrackingParams:
    """Tuning of feature tracking, width and validity checks (defaults suit 640×480, 8-bit).

    Attributes
    ----------
    max_tracks
        Most Shi–Tomasi features kept per ROI (cost grows linearly).
    redetect_interval
        Largest age of a keyframe, frames: features are re-detected at least this often
        [003 §2.2] (and sooner when half of them left the ROI or a step failed).
    win_px
        Lucas–Kanade window side, px (odd).
    pyramid_levels
        Pyramid levels above the base image (0 = no pyramid).
    fb_max_px
        Largest forward–backward error of a kept track, px.
    min_tracks
        Fewest agreeing tracks for a valid speed sample.
    min_texture_eig
        Smallest Shi–Tomasi eigenvalue of a usable feature on the raw image, (DN/px)²
        (gradients in 8-bit grey levels per pixel, averaged over a 7×7 block).
    min_texture_snr
        A usable feature's eigenvalue must also be this many times what the image noise
        alone gives (``0.1875·σ²`` for noise ``σ`` estimated in the ROI). Noise-only
        corners reach about 0.3/0.1875 ≈ 1.6; features below are not tracked, so a
        texture-less ROI is flagged instead of guessed.
    max_se_px
        Largest standard error of the mean displacement of one sample, px.
    side_max_px, side_frac
        Sideways rejection: a track moving across the filament (or radially on the gear)
        by more than ``side_max_px + side_frac·|along|`` is dropped [003 §2.2].
    pad_px
        Margin around a tracking ROI that a feature may move into between two frames, px
        (along the filament only, for the filament ROI).
    width_sigma_px
        Gaussian smoothing across the filament before the derivative, px.
    min_edge_dn_px
        Smallest edge gradient accepted as a filament edge, DN/px.
    blank_std_dn
        A frame whose grey-level standard deviation is below this is blank, DN.
    gap_factor
        A time step longer than ``gap_factor`` × the median step means dropped frames.
    smooth_sigma_s
        Gaussian window of the smoothed columns [003 Eq. 5], s.
    min_gear_speed_mm_s, min_filament_speed_mm_s
        Speed floors, mm/s: a step slower than this is flagged GEAR_STOPPED /
        FILAMENT_STOPPED, and slip is defined only where both speeds are above their
        floors (per step, and for the whole run on the mean speeds).
    axis_frames
        Frames looked at to estimate the gear axis from the motion (when it is not given).
    min_valid_fraction
        A quantity valid in fewer than this fraction of the steps (frames, for the
        width) raises a warning (and ``--strict`` fails).
    """

    max_tracks: int = 30
    redetect_interval: int = 100
    win_px: int = 15
    pyramid_levels: int = 3
    fb_max_px: float = 0.5
    min_tracks: int = 6
    min_texture_eig: float = 1.0
    min_texture_snr: float = 3.0
    max_se_px: float = 0.05
    side_max_px: float = 0.5
    side_frac: float = 0.2
    pad_px: int = 48
    width_sigma_px: float = 0.7
    min_edge_dn_px: float = 3.0
    blank_std_dn: float = 4.0
    gap_factor: float = 1.5
    smooth_sigma_s: float = 0.2
    min_gear_speed_mm_s: float = 0.05
    min_filament_speed_mm_s: float = 0.05
    axis_frames: int = 60
    min_valid_fraction: float = 0.5

    def __post_init__(self) -> None:
        for name, (lo, hi) in _TRACKING_BOUNDS.items():
            value = getattr(self, name)
            kind = int if isinstance(_DEFAULTS[name], int) else float
            if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                    kind is int and not isinstance(value, int)):
                raise VisionError("tracking parameter has the wrong type",
                                  field=f"tracking.{name}", value=value,
                                  allowed=f"{kind.__name__} in [{lo}, {hi}]")
            if not (math.isfinite(float(value)) and lo <= value <= hi):
                raise VisionError("tracking parameter out of range", field=f"tracking.{name}",
                                  value=value, allowed=f"{lo} <= {name} <= {hi}")
        if self.win_px % 2 == 0:
            raise VisionError("the Lucas–Kanade window must have an odd side",
                              field="tracking.win_px", value=self.win_px,
                              allowed="odd integers 5..101")


_TRACKING_BOUNDS: dict[str, tuple[float, float]] = {
    "max_tracks": (4, 2000), "redetect_interval": (1, 1000), "win_px": (5, 101),
    "pyramid_levels": (0, 6), "fb_max_px": (0.01, 10.0), "min_tracks": (2, 1000),
    "min_texture_eig": (0.0, 1e6), "min_texture_snr": (0.0, 1e6), "max_se_px": (1e-4, 10.0),
    "side_max_px": (0.0, 100.0), "side_frac": (0.0, 10.0), "pad_px": (4, 1000),
    "width_sigma_px": (0.3, 20.0),
    "min_edge_dn_px": (0.1, 255.0), "blank_std_dn": (0.0, 255.0), "gap_factor": (1.05, 100.0),
    "smooth_sigma_s": (1e-4, 600.0), "min_gear_speed_mm_s": (0.0, 1000.0),
    "min_filament_speed_mm_s": (0.0, 1000.0), "axis_frames": (2, 10000),
    "min_valid_fraction": (0.0, 1.0),
}
_DEFAULTS: dict[str, Any] = {f.name: f.default for f in fields(TrackingParams)}


@dataclass(frozen=True, slots=True)
class VisionConfig:
    """Everything a measurement needs besides the frames.

    Attributes
    ----------
    rois
        Gear, before-gear and after-gear ROIs.
    mm_per_px
        Known image scale, mm/px (``None``: calibrate from ``calib_width_mm``).
    calib_width_mm
        Known filament width for ``k_cal = w_µ/w_detected`` [003 Eq. 4], mm.
    gear_center_px
        Gear axis in the image ``(x, y)``, px. Given: gear speed from the rotation
        ``ω·R`` [003 Eq. 3]. ``None``: estimated from the tracked motion
        (:mod:`flowtwin.vision.axis`) unless ``gear_method`` is ``"tangential"``.
    gear_radius_mm
        Effective drive radius ``R``, mm; ``None`` in rotation mode uses the distance from
        the gear axis to the nearer filament edge measured in the ``before`` ROI.
    gear_method
        ``"auto"``: rotation about the given axis, else about the axis estimated from
        the motion when the motion is a rotation, else tangential (the [003] method: mean
        motion along the filament in the gear ROI; biased, see docs/vision.md).
        ``"rotation"``: as auto, but an error if no axis can be found. ``"tangential"``.
    direction
        Feed direction of the filament in the image.
    diameter_mm
        Nominal filament diameter, mm: widths outside ±5 % of it are not taken for the
        filament. ``None``: within ±8 % of 1.75 or 2.85 mm.
    tracking
        Tuning parameters.
    source
        File the configuration came from (for messages), if any.
    """

    rois: RoiSet
    mm_per_px: float | None = None
    calib_width_mm: float | None = None
    gear_center_px: tuple[float, float] | None = None
    gear_radius_mm: float | None = None
    direction: Direction = "down"
    tracking: TrackingParams = field(default_factory=TrackingParams)
    source: str | None = None
    gear_method: GearMode = "auto"
    diameter_mm: float | None = None

    def __post_init__(self) -> None:
        if self.mm_per_px is not None and self.calib_width_mm is not None:
            raise VisionError("give the scale either as mm_per_px or as calib_width_mm, "
                              "not both", source=self.source, field="scale",
                              value=(self.mm_per_px, self.calib_width_mm),
                              allowed="exactly one of --mm-per-px, --calib-width-mm")
        _check_positive(self.mm_per_px, "scale.mm_per_px", self.source, 1e-5, 100.0)
        _check_positive(self.calib_width_mm, "scale.calib_width_mm", self.source, 0.01, 100.0)
        _check_positive(self.gear_radius_mm, "gear.radius_mm", self.source, 0.1, 500.0)
        _check_positive(self.diameter_mm, "filament.diameter_mm", self.source, 0.1, 20.0)
        if self.gear_method not in GEAR_MODES:
            raise VisionError("unknown gear mode", source=self.source, field="gear.mode",
                              value=self.gear_method, allowed=", ".join(GEAR_MODES))
        if self.gear_method == "tangential" and self.gear_center_px is not None:
            raise VisionError("tangential gear mode does not use the gear centre",
                              source=self.source, field="gear.mode",
                              value=self.gear_method,
                              allowed="mode auto or rotation with a centre, or no centre")
        if self.gear_center_px is not None:
            cx, cy = self.gear_center_px
            if not (math.isfinite(cx) and math.isfinite(cy)):
                raise VisionError("gear centre must be finite", source=self.source,
                                  field="gear.center_px", value=self.gear_center_px,
                                  allowed="finite x, y in px")
        if self.gear_radius_mm is not None and self.gear_method == "tangential":
            raise VisionError("gear radius given in tangential mode", source=self.source,
                              field="gear.radius_mm", value=self.gear_radius_mm,
                              allowed="gear mode auto or rotation")
        if self.direction not in ("down", "up"):
            raise VisionError("unknown filament direction", source=self.source,
                              field="filament.direction", value=self.direction,
                              allowed="down, up")

    @property
    def gear_mode(self) -> GearMode:
        """``"rotation"`` when the gear centre is given, else ``gear_method``."""
        return "rotation" if self.gear_center_px is not None else self.gear_method


def _check_positive(value: float | None, name: str, source: str | None, lo: float,
                    hi: float) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and lo <= value <= hi):
        raise VisionError("value out of range", source=source, field=name, value=value,
                          allowed=f"{lo} <= {name.split('.')[-1]} <= {hi}")


_TABLES: dict[str, tuple[str, ...]] = {
    "roi": ROI_NAMES,
    "scale": ("mm_per_px", "calib_width_mm"),
    "gear": ("mode", "center_px", "radius_mm"),
    "filament": ("direction", "diameter_mm"),
    "tracking": tuple(_DEFAULTS),
}


def _number(value: object, name: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise VisionError("expected a number", source=source, field=name, value=value,
                          allowed="a number")
    return float(value)


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a vision TOML file into keyword arguments of :func:`build_config`.

    Parameters
    ----------
    path
        The TOML file.

    Returns
    -------
    dict
        Keys ``rois`` (``{name: Roi}``), ``mm_per_px``, ``calib_width_mm``,
        ``gear_center_px``, ``gear_radius_mm``, ``gear_method``, ``direction``,
        ``diameter_mm``, ``tracking`` (dict), only those present in the file.

    Raises
    ------
    VisionError
        Unreadable file, TOML syntax error, unknown table or key, wrong type or range.
    """
    src = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except OSError as exc:
        raise VisionError(f"cannot read the vision config: {exc.strerror}", source=src) from None
    except UnicodeDecodeError:
        raise VisionError("the vision config is not UTF-8 text", source=src) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise VisionError(f"not valid TOML: {exc}", source=src) from None
    out: dict[str, Any] = {}
    for table, content in data.items():
        if table not in _TABLES:
            raise VisionError("unknown table in the vision config", source=src, field=table,
                              value=table, allowed=", ".join(f"[{t}]" for t in _TABLES))
        if not isinstance(content, dict):
            raise VisionError(f"'{table}' must be a table", source=src, field=table,
                              value=content, allowed=f"[{table}] with keys "
                              + ", ".join(_TABLES[table]))
        for key in content:
            if key not in _TABLES[table]:
                raise VisionError("unknown key in the vision config", source=src,
                                  field=f"{table}.{key}", value=key,
                                  allowed=", ".join(_TABLES[table]))
    if "roi" in data:
        out["rois"] = {name: roi_from_sequence(name, value, source=src)
                       for name, value in data["roi"].items()}
    scale = data.get("scale", {})
    for key in ("mm_per_px", "calib_width_mm"):
        if key in scale:
            out[key] = _number(scale[key], f"scale.{key}", src)
    gear = data.get("gear", {})
    if "center_px" in gear:
        c = gear["center_px"]
        if not isinstance(c, list) or len(c) != 2:
            raise VisionError("gear centre must be [x, y] in px", source=src,
                              field="gear.center_px", value=c, allowed="[x, y]")
        out["gear_center_px"] = (_number(c[0], "gear.center_px", src),
                                 _number(c[1], "gear.center_px", src))
    if "radius_mm" in gear:
        out["gear_radius_mm"] = _number(gear["radius_mm"], "gear.radius_mm", src)
    if "mode" in gear:
        out["gear_method"] = gear["mode"]
    if "direction" in data.get("filament", {}):
        out["direction"] = data["filament"]["direction"]
    if "diameter_mm" in data.get("filament", {}):
        out["diameter_mm"] = _number(data["filament"]["diameter_mm"], "filament.diameter_mm",
                                     src)
    if "tracking" in data:
        out["tracking"] = dict(data["tracking"])
    out["source"] = src
    return out


def build_config(*, config_path: str | Path | None = None,
                 rois: dict[str, Roi] | None = None,
                 mm_per_px: float | None = None,
                 calib_width_mm: float | None = None,
                 gear_center_px: tuple[float, float] | None = None,
                 gear_radius_mm: float | None = None,
                 direction: Direction | None = None,
                 tracking: dict[str, Any] | None = None,
                 gear_method: GearMode | None = None,
                 diameter_mm: float | None = None) -> VisionConfig:
    """Merge a TOML file and explicit options (explicit options win) into a config.

    Parameters
    ----------
    config_path
        Optional TOML file (see the module docstring).
    rois
        ROIs given explicitly (``--roi``), replacing the file's ROI of the same name.
    mm_per_px, calib_width_mm
        Scale given explicitly; either one replaces the file's ``[scale]`` table.
    gear_center_px, gear_radius_mm
        Gear geometry given explicitly, px and mm.
    direction
        Feed direction given explicitly.
    tracking
        Tracking parameters given explicitly, merged over the file's ``[tracking]``.
    gear_method, diameter_mm
        Gear mode and nominal filament diameter (mm) given explicitly.

    Returns
    -------
    VisionConfig

    Raises
    ------
    VisionError
        Missing ROIs, conflicting or out-of-range values, bad file.
    """
    base: dict[str, Any] = load_config_file(config_path) if config_path is not None else {}
    source = base.get("source")
    merged_rois: dict[str, Roi] = dict(base.get("rois", {}))
    merged_rois.update(rois or {})
    if mm_per_px is not None or calib_width_mm is not None:
        base.pop("mm_per_px", None)
        base.pop("calib_width_mm", None)
    scale_mm = mm_per_px if mm_per_px is not None else base.get("mm_per_px")
    scale_w = calib_width_mm if calib_width_mm is not None else base.get("calib_width_mm")
    track_kwargs: dict[str, Any] = dict(base.get("tracking", {}))
    track_kwargs.update(tracking or {})
    unknown = sorted(set(track_kwargs) - set(_DEFAULTS))
    if unknown:
        raise VisionError("unknown tracking parameter", source=source,
                          field=f"tracking.{unknown[0]}", value=unknown[0],
                          allowed=", ".join(_DEFAULTS))
    try:
        params = replace(TrackingParams(), **track_kwargs)
    except VisionError as exc:
        raise VisionError(exc.message, source=source, field=exc.field, value=exc.value,
                          allowed=exc.allowed) from None
    roi_set = RoiSet.from_mapping(merged_rois, source=source)
    return VisionConfig(
        rois=roi_set, mm_per_px=scale_mm, calib_width_mm=scale_w,
        gear_center_px=gear_center_px if gear_center_px is not None
        else base.get("gear_center_px"),
        gear_radius_mm=gear_radius_mm if gear_radius_mm is not None
        else base.get("gear_radius_mm"),
        direction=direction if direction is not None else base.get("direction", "down"),
        tracking=params, source=source,
        gear_method=gear_method if gear_method is not None
        else base.get("gear_method", "auto"),
        diameter_mm=diameter_mm if diameter_mm is not None else base.get("diameter_mm"))

