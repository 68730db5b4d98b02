"""Result objects of a vision measurement and their CSV / Parquet form.

One row per delivered frame. Speeds of a row are over the step that *ends* at that
frame (from the previous processed frame, ``dt_s`` earlier); the width is measured in the
frame itself. Invalid values are NaN and the row's ``flags`` say why (:class:`Quality`).
Slip is a fraction in the objects and a percentage in the files (docs/spec.md §2).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass
from enum import IntFlag
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_open, atomic_write_bytes

__all__ = ["FILAMENT_INVALID", "GEAR_INVALID", "MIN_SLIP_STEPS", "WIDTH_INVALIDATING",
           "Quality",
           "VisionResult", "VisionSeries", "VisionSummary", "write_csv", "write_parquet"]

FloatArray = npt.NDArray[np.float64]


class Quality(IntFlag):
    """Quality flags of one row (column ``flags``).

    ``*_STALE`` marks a region that repeats the previous frame's pixels (a damaged frame
    the decoder concealed with old data) and the step right after it (the decoder may
    have lost frames there, which constant-rate timestamps cannot show).
    ``*_LOW_TEXTURE`` means no trackable texture: no feature stands out of the noise, the
    aligned windows match no better than noise would, or the tracks scatter by more than
    0.5 px rms (they follow noise, not the surface). ``*_TRACKING`` means the tracks
    were too few or disagreed for another reason. Either way the value is NaN.
    ``*_STOPPED`` keeps the (tiny) measured speed but makes the slip undefined: slip
    needs both speeds above their floors. ``GEAR_NO_AXIS``: the gear turns, no axis was
    given and none could be estimated from the motion; the tangential reading of [003]
    that remains depends on the lever arm of the tracked features, not on the drive
    radius, so it is not reported (``--gear-mode tangential`` asks for it explicitly).
    """

    FIRST = 1                   #: first frame: nothing to compare with, no speeds
    GAP = 2                     #: frames were dropped before this one (speeds still valid)
    DUPLICATE = 4               #: exact repeat of the previous image: skipped
    BLANK = 8                   #: blank frame (no contrast): skipped
    GEAR_LOW_TEXTURE = 16       #: no trackable texture in the gear ROI (see below)
    GEAR_TRACKING = 32          #: gear tracks too few or disagreeing
    FILAMENT_LOW_TEXTURE = 64   #: no trackable texture in the after ROI (see below)
    FILAMENT_TRACKING = 128     #: filament tracks too few or disagreeing
    WIDTH_INVALID = 256         #: no plausible filament width in the before ROI (refused)
    GEAR_STOPPED = 512          #: gear slower than its floor: slip undefined
    GEAR_STALE = 1024           #: gear ROI repeats old pixels (damaged frame), or follows
    FILAMENT_STALE = 2048       #: after ROI repeats old pixels (damaged frame), or follows
    WIDTH_AMBIGUOUS = 4096      #: refused because several edge pairs compete (with INVALID)
    FILAMENT_STOPPED = 8192     #: filament slower than its floor: slip undefined
    GEAR_NO_AXIS = 16384        #: gear turns but no axis was found: its speed is refused

    def names(self) -> str:
        """``"GAP|WIDTH_INVALID"`` style text (empty when no flag is set)."""
        return "|".join(f.name for f in Quality if f in self and f.name)


#: Fewest steps with both speeds valid and above their floors for a run's slip.
MIN_SLIP_STEPS = 2

#: Flags that make the gear speed invalid.
GEAR_INVALID = (Quality.FIRST | Quality.DUPLICATE | Quality.BLANK | Quality.GEAR_LOW_TEXTURE
                | Quality.GEAR_TRACKING | Quality.GEAR_STALE | Quality.GEAR_NO_AXIS)
#: Flags that make the filament speed invalid.
FILAMENT_INVALID = (Quality.FIRST | Quality.DUPLICATE | Quality.BLANK
                    | Quality.FILAMENT_LOW_TEXTURE | Quality.FILAMENT_TRACKING
                    | Quality.FILAMENT_STALE)
#: Flags that make the width invalid.
WIDTH_INVALIDATING = (Quality.DUPLICATE | Quality.BLANK | Quality.WIDTH_INVALID
                      | Quality.WIDTH_AMBIGUOUS)


@dataclass(frozen=True, slots=True)
class VisionSeries:
    """Per-frame series of a measurement (all arrays have shape ``(N,)``).

    Attributes
    ----------
    frame
        Index of the frame in the source.
    t_s
        Capture time since the first frame, s.
    dt_s
        Time since the previous processed frame, s (NaN for skipped/first rows).
    gear_speed_mm_s, filament_speed_mm_s
        Gear surface speed and filament speed over the step, mm/s.
    slip
        ``(gear − filament)/gear`` [000 Eq. 1], fraction.
    width_mm
        Filament width in the ``before`` ROI, mm.
    volume_flow_mm3_s
        ``v·π·w²/4``, mm³/s.
    gear_speed_smooth_mm_s, filament_speed_smooth_mm_s, width_smooth_mm
        Gaussian-smoothed in time [003 Eq. 5].
    slip_smooth, volume_flow_smooth_mm3_s
        From the smoothed speeds and width.
    flags
        :class:`Quality` bits.
    gear_tracks, filament_tracks
        Agreeing tracks of the step.
    gear_se_px, filament_se_px
        Standard error of the step, px.
    width_px
        Width in pixels.
    """

    frame: npt.NDArray[np.int64]
    t_s: FloatArray
    dt_s: FloatArray
    gear_speed_mm_s: FloatArray
    filament_speed_mm_s: FloatArray
    slip: FloatArray
    width_mm: FloatArray
    volume_flow_mm3_s: FloatArray
    gear_speed_smooth_mm_s: FloatArray
    filament_speed_smooth_mm_s: FloatArray
    slip_smooth: FloatArray
    width_smooth_mm: FloatArray
    volume_flow_smooth_mm3_s: FloatArray
    flags: npt.NDArray[np.int64]
    gear_tracks: npt.NDArray[np.int64]
    filament_tracks: npt.NDArray[np.int64]
    gear_se_px: FloatArray
    filament_se_px: FloatArray
    width_px: FloatArray

    def __len__(self) -> int:
        return int(self.t_s.size)

    def columns(self) -> dict[str, npt.NDArray[np.generic]]:
        """Columns as written to files (slip in %, flag names added), in order."""
        out: dict[str, npt.NDArray[np.generic]] = {}
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if name in ("slip", "slip_smooth"):
                out[name.replace("slip", "slip_pct")] = 100.0 * value
            else:
                out[name] = value
        out["flag_names"] = np.array([Quality(int(f)).names() for f in self.flags], dtype=object)
        return out


@dataclass(frozen=True, slots=True)
class VisionSummary:
    """Summary of a measurement; speeds are distance over time of the valid steps.

    Attributes
    ----------
    gear_speed_mm_s, filament_speed_mm_s
        Mean speeds over their valid steps: travelled distance / time, mm/s.
    slip
        ``1 − L_filament/L_gear`` over the steps where both speeds are valid and above
        their floors, distances counted along the gear's direction (retractions add up,
        they do not cancel) [000 Eq. 1], fraction. NaN (``null`` in JSON) when undefined:
        fewer than :data:`MIN_SLIP_STEPS` such steps, or a mean speed below its floor;
        ``slip_note`` says why.
    slip_pct
        The same in %.
    slip_steps
        Steps the slip was computed from.
    slip_note
        Why the slip is undefined (None when it is defined).
    gear_state, filament_state
        ``"moving"`` (mean speed above its floor), ``"still"`` or ``"unknown"`` (no valid
        step). A gear whose speed was refused for want of an axis (``gear_note``) is
        ``"moving"``.
    gear_speed_floor_mm_s, filament_speed_floor_mm_s
        The floors, mm/s.
    width_mm, width_std_mm
        Mean and standard deviation of the valid widths, mm.
    volume_flow_mm3_s
        Mean volume flow over valid steps, mm³/s.
    frames
        Frames read.
    valid_frames
        Rows with valid gear speed, filament speed and width.
    gear_valid_frames, filament_valid_frames, width_valid_frames
        Rows valid for each quantity.
    dropped_frames
        Frames estimated missing from the timestamp gaps.
    gap_frames, duplicate_frames, blank_frames
        Rows flagged GAP, DUPLICATE, BLANK.
    gear_low_texture_frames, filament_low_texture_frames
        Rows flagged for missing texture.
    width_ambiguous_frames
        Rows whose width was refused because several edge pairs competed.
    frames_expected
        Frames the container declares (None if unknown).
    truncated
        Fewer frames decoded than declared.
    duration_s
        Capture time from first to last frame, s.
    frame_period_s
        Median time step, s.
    mm_per_px
        Image scale used (``k_cal``), mm/px.
    scale_source
        ``"mm_per_px"`` or ``"calib_width_mm"`` [003 Eq. 4].
    gear_mode
        ``"rotation"`` or ``"tangential"``.
    gear_radius_mm
        Drive radius used in rotation mode, mm (None in tangential mode).
    gear_radius_source
        ``"config"`` or ``"measured contact radius"``.
    gear_axis_px
        Gear axis used, ``[x, y]`` px (None in tangential mode).
    gear_axis_source
        ``"config"`` or ``"estimated from the motion"`` (None in tangential mode).
    gear_axis_note
        What the axis estimate found (None when the axis was given or not looked for).
    warnings
        Problems a user must see: few valid steps of a quantity, tangential mode on a
        turning gear, an unplausible set-up (empty when all is well).
    source, source_kind, timestamp_source
        What was read and where its times came from.
    opencv_version
        OpenCV that measured.
    processing_fps
        Frames per second of this run (decoding included).
    gear_note
        Why the gear speed was refused (None if it was not): the gear turns but no axis
        was found, and the tangential reading left is not the drive's surface speed.
    width_note
        Why every width of the run was refused (None if they were not): edges that are
        not a clean silhouette, or a ``before`` ROI in the gear's contact zone.
    width_blur_px
        The edges' blur σ fitted over the clip (optics and pixel), px (NaN if no edges).
    width_window_frames
        Frames in the local line each width is taken from
        (:mod:`flowtwin.vision.width_series`; 1: every frame's width is its own reading).
    """

    gear_speed_mm_s: float
    filament_speed_mm_s: float
    slip: float
    slip_pct: float
    width_mm: float
    width_std_mm: float
    volume_flow_mm3_s: float
    frames: int
    valid_frames: int
    gear_valid_frames: int
    filament_valid_frames: int
    width_valid_frames: int
    dropped_frames: int
    gap_frames: int
    duplicate_frames: int
    blank_frames: int
    gear_low_texture_frames: int
    filament_low_texture_frames: int
    width_ambiguous_frames: int
    frames_expected: int | None
    truncated: bool
    duration_s: float
    frame_period_s: float
    mm_per_px: float
    scale_source: str
    gear_mode: str
    gear_radius_mm: float | None
    gear_radius_source: str | None
    gear_axis_px: tuple[float, float] | None
    gear_axis_source: str | None
    gear_axis_note: str | None
    slip_steps: int
    slip_note: str | None
    gear_state: str
    filament_state: str
    gear_speed_floor_mm_s: float
    filament_speed_floor_mm_s: float
    warnings: tuple[str, ...]
    source: str
    source_kind: str
    timestamp_source: str
    opencv_version: str
    processing_fps: float
    width_note: str | None = None
    width_blur_px: float = math.nan
    gear_note: str | None = None
    width_window_frames: int = 1

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (NaN becomes None)."""
        out: dict[str, object] = {}
        for key, value in asdict(self).items():
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            elif isinstance(value, tuple):
                value = list(value)
            out[key] = value
        return out


@dataclass(frozen=True, slots=True)
class VisionResult:
    """Series and summary of one measurement."""

    series: VisionSeries
    summary: VisionSummary


def _cell(value: object) -> str:
    if isinstance(value, float | np.floating):
        return "" if not math.isfinite(float(value)) else repr(float(value))
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def write_csv(result: VisionResult, path: str | Path) -> None:
    """Write the series as CSV (atomically); empty cells are invalid values.

    Parameters
    ----------
    result
        The measurement.
    path
        Output file.
    """
    cols = result.series.columns()
    names = list(cols)
    with atomic_open(path, "w") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(names)
        for i in range(len(result.series)):
            writer.writerow([_cell(cols[n][i]) for n in names])


def write_parquet(result: VisionResult, path: str | Path) -> None:
    """Write the series as Parquet (atomically), the summary as JSON in the metadata.

    Parameters
    ----------
    result
        The measurement.
    path
        Output file.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = result.series.columns()
    arrays = {}
    for name, values in cols.items():
        if values.dtype == object:
            arrays[name] = pa.array([str(v) for v in values], type=pa.string())
        else:
            arrays[name] = pa.array(values)
    table = pa.table(arrays)
    meta = {b"flowtwin.vision.summary": json.dumps(result.summary.to_dict()).encode()}
    table = table.replace_schema_metadata(meta)
    buf = io.BytesIO()
    pq.write_table(table, buf)
    atomic_write_bytes(path, buf.getvalue())
