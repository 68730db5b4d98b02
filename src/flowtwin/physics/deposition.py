"""Deposition: bead cross-section and width, ooze and blobs [001 Eq. 7, 003 Eq. 2].

Slicers model the bead as a rectangle with semicircular ends (Slic3r "flow math"):

``A = w·h − (1 − π/4)·h²``  [001 Eq. 7]  ``= (w − h)·h + π·(h/2)²``  [003 Eq. 2].

It is ill-defined for ``w < h`` [001 Fig. 12] — the bead is then not squeezed onto the bed
and its shape is uncertain [001 §Results] — so every width is returned with a flag.
Inverting for the width at output flow ``Q`` and print speed ``v``:
``w = Q/(h·v) + (1 − π/4)·h`` (docs/spec.md §3.5).

Flow while the nozzle stands still is a *blob*; flow during a travel (no extrusion
commanded) is *ooze* (docs/spec.md §3.5). :func:`classify_deposit` labels samples and
:func:`deposit_volumes_mm3` totals their volumes.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.physics._checks import as_float_array, require_nonnegative, require_positive

__all__ = [
    "BeadWidth",
    "Deposit",
    "DepositVolumes",
    "bead_area_mm2",
    "bead_width_mm",
    "blob_diameter_mm",
    "classify_deposit",
    "deposit_volumes_mm3",
    "filament_length_for_bead",
]

FloatArray = npt.NDArray[np.float64]

#: ``1 − π/4``, the area a rounded bead loses against a ``w × h`` rectangle, per ``h²``.
_ROUNDING = 1.0 - np.pi / 4.0


def bead_area_mm2(width_mm: npt.ArrayLike, height_mm: npt.ArrayLike) -> FloatArray:
    """Bead cross-section ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7 = 003 Eq. 2].

    Parameters
    ----------
    width_mm
        Bead (line) width ``w``, mm, any shape.
    height_mm
        Layer height ``h``, mm (> 0).

    Returns
    -------
    ndarray
        Area, mm², broadcast shape. For ``w < h`` the model is ill-defined [001 Fig. 12];
        use :func:`bead_width_mm` to get the flag.
    """
    h = require_positive("height_mm", height_mm)
    return as_float_array(width_mm) * h - _ROUNDING * h * h


class BeadWidth(NamedTuple):
    """Predicted bead width with its validity flags (arrays of the broadcast shape)."""

    #: Width ``w`` in mm; NaN where the nozzle does not move (``stationary``).
    width_mm: FloatArray
    #: True where ``w < h``: the slicer bead model is ill-defined [001 Fig. 12].
    narrower_than_height: npt.NDArray[np.bool_]
    #: True where the print speed is ≤ 0: the flow makes a blob, not a bead.
    stationary: npt.NDArray[np.bool_]


def bead_width_mm(q_out_mm3_s: npt.ArrayLike, height_mm: npt.ArrayLike,
                  speed_mm_s: npt.ArrayLike) -> BeadWidth:
    """Predicted width ``w = Q/(h·v) + (1 − π/4)·h`` (inverse of [001 Eq. 7]; docs/spec.md §3.5).

    Parameters
    ----------
    q_out_mm3_s
        Output volume flow, mm³/s (≥ 0), any shape.
    height_mm
        Layer height, mm (> 0), broadcast.
    speed_mm_s
        Print (nozzle XY) speed, mm/s, broadcast.

    Returns
    -------
    BeadWidth
        Width (NaN where ``speed_mm_s <= 0``) and the flags ``narrower_than_height``
        (``w < h``) and ``stationary``.
    """
    q = as_float_array(q_out_mm3_s)
    h = require_positive("height_mm", height_mm)
    v = as_float_array(speed_mm_s)
    q, h, v = np.broadcast_arrays(q, h, v)
    stationary = ~(v > 0.0)
    safe_v = np.where(stationary, 1.0, v)
    width = np.where(stationary, np.nan, q / (h * safe_v) + _ROUNDING * h)
    narrow = ~stationary & (width < h)
    return BeadWidth(width, narrow, stationary)


def filament_length_for_bead(width_mm: npt.ArrayLike, height_mm: npt.ArrayLike,
                             path_length_mm: npt.ArrayLike,
                             filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Filament length (the slicer's E) for a bead: ``A_bead·L_path/A_fil`` [001 Eq. 7].

    Parameters
    ----------
    width_mm
        Line width, mm, any shape.
    height_mm
        Layer height, mm (> 0).
    path_length_mm
        Length of the printed path, mm (≥ 0).
    filament_area_mm2
        Filament cross-section, mm² (> 0).

    Returns
    -------
    ndarray
        Filament length, mm, broadcast shape.
    """
    return bead_area_mm2(width_mm, height_mm) * require_nonnegative(
        "path_length_mm", path_length_mm) / require_positive("filament_area_mm2",
                                                             filament_area_mm2)


class Deposit(IntEnum):
    """What the output flow of a sample becomes."""

    BEAD = 0   #: nozzle moving in XY on an extruding move: part of a bead
    OOZE = 1   #: nozzle moving in XY on a travel (no extrusion commanded): ooze / string
    BLOB = 2   #: nozzle not moving in XY: the flow piles up into a blob


def classify_deposit(xy_speed_mm_s: npt.ArrayLike, extruding: npt.ArrayLike, *,
                     min_speed_mm_s: float = 1e-6) -> npt.NDArray[np.int8]:
    """Label each sample :class:`Deposit` ``BEAD``, ``OOZE`` or ``BLOB`` (docs/spec.md §3.5).

    Parameters
    ----------
    xy_speed_mm_s
        Nozzle XY speed per sample, mm/s, shape (n,).
    extruding
        True where the G-code move commands extrusion, shape (n,).
    min_speed_mm_s
        XY speeds at or below this count as standing still, mm/s (≥ 0).

    Returns
    -------
    ndarray of int8
        :class:`Deposit` values, shape (n,).
    """
    speed = as_float_array(xy_speed_mm_s)
    ext = np.asarray(extruding, dtype=bool)
    if speed.shape != ext.shape:
        raise DataError("xy_speed_mm_s and extruding must have the same shape",
                        field="extruding", value=ext.shape, allowed=str(speed.shape))
    threshold = float(require_nonnegative("min_speed_mm_s", min_speed_mm_s))
    moving = speed > threshold
    out = np.full(speed.shape, Deposit.BLOB, dtype=np.int8)
    out[moving & ext] = Deposit.BEAD
    out[moving & ~ext] = Deposit.OOZE
    return out


class DepositVolumes(NamedTuple):
    """Total output volume by destination, mm³."""

    bead_mm3: float
    ooze_mm3: float
    blob_mm3: float


def deposit_volumes_mm3(q_out_mm3_s: npt.ArrayLike, dt_s: npt.ArrayLike,
                        deposit: npt.ArrayLike) -> DepositVolumes:
    """Sum ``Q_out·Δt`` per :class:`Deposit` class (docs/spec.md §3.5: account for ooze and blobs).

    Parameters
    ----------
    q_out_mm3_s
        Output flow per sample, mm³/s (≥ 0: no backflow [001 Fig. 8]), shape (n,).
    dt_s
        Sample durations, s (≥ 0), shape (n,) or scalar.
    deposit
        Labels from :func:`classify_deposit`, shape (n,).

    Returns
    -------
    DepositVolumes
        Bead, ooze and blob volumes, mm³.
    """
    q = as_float_array(q_out_mm3_s)
    if np.any(q < 0.0) or not np.all(np.isfinite(q)):
        raise DataError("output flow must be finite and non-negative (no backflow)",
                        field="q_out_mm3_s", value=float(np.nanmin(q)), allowed=">= 0")
    dt = require_nonnegative("dt_s", dt_s)
    labels = np.asarray(deposit)
    volume = np.broadcast_to(q * dt, labels.shape)
    return DepositVolumes(float(volume[labels == Deposit.BEAD].sum()),
                          float(volume[labels == Deposit.OOZE].sum()),
                          float(volume[labels == Deposit.BLOB].sum()))


def blob_diameter_mm(volume_mm3: npt.ArrayLike, height_mm: npt.ArrayLike) -> FloatArray:
    """Diameter of a blob spread as a disc of the layer height, ``sqrt(4V/(π·h))``, mm.

    A simple size measure for a blob under a standing nozzle (beyond the seeds).

    Parameters
    ----------
    volume_mm3
        Blob volume, mm³ (≥ 0), any shape.
    height_mm
        Layer height, mm (> 0).

    Returns
    -------
    ndarray
        Diameter, mm, broadcast shape.
    """
    return np.sqrt(4.0 * require_nonnegative("volume_mm3", volume_mm3)
                   / (np.pi * require_positive("height_mm", height_mm)))
