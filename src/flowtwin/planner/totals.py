"""Totals of a planned print, added chunk by chunk: per tool, per feature, per layer.

:class:`PlanTotals` takes the moves of a print with their phases in move order, in one
piece (:meth:`flowtwin.planner.plan_file.PlanResult.summary`) or in consecutive pieces (a streamed
plan, :mod:`flowtwin.planner.plan_stream`), and keeps only sums whose size is the number of tools,
features and layers. Each piece is one compiled pass over its moves
(:mod:`flowtwin.planner._totals_kernel`); the sums continue across pieces with the same
additions in the same order, so a print added in pieces gives the same figures, to the
bit, as in one piece.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner._totals_kernel import accumulate, key_ranges
from flowtwin.planner.timeline import feature_seconds

__all__ = ["PlanTotals"]


def _grow(a: npt.NDArray[Any], lo: int, new_lo: int, new_hi: int,
          fill: float = 0.0) -> npt.NDArray[Any]:
    """``a`` (covering keys from ``lo``) widened to keys ``[new_lo, new_hi]``."""
    size = new_hi - new_lo + 1
    if new_lo == lo and size == a.shape[0]:
        return a
    out = np.full(size, fill, dtype=a.dtype)
    out[lo - new_lo:lo - new_lo + a.shape[0]] = a
    return out


@dataclass(slots=True)
class PlanTotals:
    """Sums over the moves of a planned print (see the module docstring).

    Attributes
    ----------
    moves
        Moves added.
    extruding_written
        Extruding moves written in the G-code (firmware retractions left out).
    dwell_s
        Dwells and restart gaps added, s (their running sum in order).
    """

    moves: int = 0
    extruding_written: int = 0
    dwell_s: float = 0.0
    _t_lo: int = 0
    _t: list[npt.NDArray[Any]] = field(default_factory=list)  # count, w, w_c, x, x_c
    _f_lo: int = 0
    _f: list[npt.NDArray[Any]] = field(default_factory=list)  # count, time, time_c
    _l_lo: int = 0
    _l: list[npt.NDArray[Any]] = field(default_factory=list)  # count, fil, time, z, dwell
    _any_dwell: bool = False
    _last_layer: int = -1

    def add(self, moves: npt.NDArray[np.void], phases: npt.NDArray[np.void],
            dwells: list[tuple[int, float, str]] | None = None) -> None:
        """Add the next moves of the print with their phases and the dwells before them.

        Parameters
        ----------
        moves, phases
            ``MOVE_DTYPE`` and ``PHASE_DTYPE`` rows, equal length, in print order.
        dwells
            ``(move index within moves, s, reason)``; a dwell belongs to the layer of the
            move it precedes, one after the last move to the last move's layer.
        """
        n = moves.shape[0]
        if phases.shape[0] != n:
            raise DataError("timeline and move table have different lengths",
                            field="phases", value=phases.shape[0], allowed=f"{n} rows")
        if n:
            self._add_moves(moves, phases)
        for index, seconds, _reason in dwells or ():
            self.dwell_s += seconds
            if not (n or self.moves):
                continue
            self._any_dwell = True
            if n:
                owner = int(moves["layer"][min(max(index, 0), n - 1)])
            else:
                owner = self._last_layer
            self._l[4][owner - self._l_lo] += seconds
        self.moves += n
        if n:
            self._last_layer = int(moves["layer"][n - 1])

    def _add_moves(self, m: npt.NDArray[np.void], p: npt.NDArray[np.void]) -> None:
        t_lo, t_hi, f_lo, f_hi, l_lo, l_hi = key_ranges(m["tool"], m["feature"], m["layer"])
        if not self._t:
            self._t_lo, self._f_lo, self._l_lo = t_lo, f_lo, l_lo
            self._t = [np.zeros(t_hi - t_lo + 1, np.int64)] + [np.zeros(t_hi - t_lo + 1)
                                                               for _ in range(4)]
            self._f = [np.zeros(f_hi - f_lo + 1, np.int64), np.zeros(f_hi - f_lo + 1),
                       np.zeros(f_hi - f_lo + 1)]
            size = l_hi - l_lo + 1
            self._l = [np.zeros(size, np.int64), np.zeros(size), np.zeros(size),
                       np.full(size, math.nan), np.zeros(size)]
        else:
            lo, hi = min(t_lo, self._t_lo), max(t_hi, self._t_lo + self._t[0].shape[0] - 1)
            self._t = [_grow(a, self._t_lo, lo, hi) for a in self._t]
            self._t_lo = lo
            lo, hi = min(f_lo, self._f_lo), max(f_hi, self._f_lo + self._f[0].shape[0] - 1)
            self._f = [_grow(a, self._f_lo, lo, hi) for a in self._f]
            self._f_lo = lo
            lo, hi = min(l_lo, self._l_lo), max(l_hi, self._l_lo + self._l[0].shape[0] - 1)
            self._l = [_grow(a, self._l_lo, lo, hi, math.nan if k == 3 else 0.0)
                       for k, a in enumerate(self._l)]
            self._l_lo = lo
        t, f, g = self._t, self._f, self._l
        self.extruding_written += int(accumulate(
            m["kind"], m["tool"], m["de"], m["flow"], m["feature"], m["layer"], m["z"],
            p["accel_t"], p["cruise_t"], p["decel_t"], int(MoveKind.EXTRUDE),
            int(MoveKind.FW_RETRACT), self._t_lo, t[0], t[1], t[2], t[3], t[4],
            self._f_lo, f[0], f[1], f[2], self._l_lo, g[0], g[1], g[2], g[3]))

    # -- results ----------------------------------------------------------------------------
    @property
    def layers(self) -> int:
        """Number of layers: the largest layer index + 1 (0 without moves)."""
        if not self._l:
            return 0
        return self._l_lo + self._l[0].shape[0]

    def filament_by_tool(self) -> dict[int, tuple[float, float]]:
        """Tool -> (E written in the G-code, ``Σ de·flow``), mm, for every tool with moves."""
        if not self._t:
            return {}
        count, w, w_c, x, x_c = self._t
        return {self._t_lo + b: (float(w[b] + w_c[b]), float(x[b] + x_c[b]))
                for b in np.flatnonzero(count).tolist()}

    def time_by_feature(self, names: list[str]) -> dict[str, float]:
        """Feature name -> move time, s, plus the dwells as one feature
        (:func:`~flowtwin.planner.timeline.feature_seconds`); ``names`` are the reader's
        feature names (``MoveTable.features``)."""
        keys: list[int] = []
        secs: list[float] = []
        if self._f:
            count, t, t_c = self._f
            present = np.flatnonzero(count)
            keys = (present + self._f_lo).tolist()
            secs = (t[present] + t_c[present]).tolist()
        return feature_seconds(names, keys, secs, [(0, self.dwell_s, "")])

    def per_layer(self, layer_z: list[float]) -> list[dict[str, float | int]]:
        """One row per layer with moves: index, Z (mm), time with its dwells (s), E written
        (mm), moves. Z is the reader's layer height where it has one, else the Z of the
        layer's first extruding move."""
        if not self._l:
            return []
        count, fil, time_s, first_z, dwell = self._l
        if self._any_dwell:
            time_s = time_s + dwell
        rows: list[dict[str, float | int]] = []
        for j in np.flatnonzero(count).tolist():
            key = self._l_lo + j
            z = layer_z[key] if 0 <= key < len(layer_z) else math.nan
            if z != z:  # NaN: the Z of the layer's first extrusion
                z = float(first_z[j])
            rows.append({"layer": key, "z_mm": z, "time_s": float(time_s[j]),
                         "filament_mm": float(fil[j]), "moves": int(count[j])})
        return rows
