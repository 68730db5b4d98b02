"""Whole-print figures accumulated section by section (for :mod:`.stream`).

Every figure of :meth:`SimulationResult.summary`, :meth:`~SimulationResult.per_layer` and
:meth:`~SimulationResult.per_feature` is a sum, a count, a maximum or a minimum over moves
(the RMS flow error is ``sqrt(Σ w·e² / Σ w)``), so it can be accumulated over sections and
gives the same number as the whole table, up to the order of summation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics import DynamicsResult
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation.parameters import MoveParameters
from flowtwin.simulation.summary import SimulationSummary

__all__ = ["Aggregates"]

# per-group columns
_TIME, _CMD, _DELIV, _WE2, _W, _WORST, _FMAX, _GRIND, _OOZE = range(9)
_NCOL = 9
_MAX_WARNINGS = 200


def _ratio(a: float, b: float) -> float:
    return a / b - 1.0 if b > 0 else 0.0


def _share(part: float, whole: float) -> float:
    return part / whole if whole > 0 else 0.0


@dataclass(slots=True)
class Aggregates:
    """Running totals of a simulation (see the module docstring)."""

    file: str
    machine: str
    printer: str
    advance: str
    firmware: str = ""
    features: list[str] = field(default_factory=list)
    moves: int = 0
    total_time_s: float = 0.0
    dwell_s: float = 0.0
    cmd: float = 0.0
    delivered: float = 0.0
    in_beads: float = 0.0
    we2: float = 0.0
    w: float = 0.0
    peak_over: float = 0.0
    peak_under: float = 0.0
    worst_width: float = 0.0
    slip_loss: float = 0.0
    fed_forward: float = 0.0
    max_force: float = 0.0
    min_margin: float = math.inf
    grinding_events: int = 0
    grinding_moves: int = 0
    last_grinding: bool = False
    ooze: float = 0.0
    narrow: int = 0
    over_flow_limit: int = 0
    max_layer: int = -1
    net_filament: dict[int, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    _warned: set[str] = field(default_factory=set)
    groups: dict[str, dict[int, npt.NDArray[np.float64]]] = field(
        default_factory=lambda: {"layer": {}, "feature": {}})

    def note_warnings(self, items: list[str] | tuple[str, ...]) -> None:
        """Keep warnings once each (at most 200)."""
        for w in items:
            if w not in self._warned and len(self.warnings) < _MAX_WARNINGS:
                self._warned.add(w)
                self.warnings.append(w)

    def add_time(self, dwells: list[tuple[int, float, str]], end_s: float | None) -> None:
        """Dwells of a section; ``end_s``: the end of the print (last section)."""
        self.dwell_s += float(sum(d[1] for d in dwells))
        if end_s is not None:
            self.total_time_s = end_s

    def add(self, moves: npt.NDArray[np.void], dyn: DynamicsResult,
            metrics: npt.NDArray[np.void], params: MoveParameters, *, first: bool) -> None:
        """Accumulate one simulated section."""
        del first
        if params.over_flow_limit is not None:
            self.over_flow_limit += int(np.count_nonzero(params.over_flow_limit))
        d = dyn.moves
        kind = moves["kind"]
        cmd = d["cmd_mm3"]
        ext = ((kind & MoveKind.EXTRUDE) != 0) & ((kind & MoveKind.XY) != 0) & (cmd > 0)
        err = metrics["flow_error"]
        out_all = d["out_mm3"] + d["stop_out_mm3"]
        self.moves += len(moves)
        self.cmd += float(np.sum(cmd))
        self.delivered += float(np.sum(out_all))
        self.in_beads += float(np.sum(d["out_mm3"][ext]))
        self.we2 += float(np.sum(cmd[ext] * err[ext] * err[ext]))
        self.w += float(np.sum(cmd[ext]))
        self.peak_over = max(self.peak_over, float(np.max(err[ext], initial=0.0)))
        self.peak_under = max(self.peak_under, float(-np.min(err[ext], initial=0.0)))
        dev = np.abs(metrics["width_mean_mm"] - metrics["width_nominal_mm"])
        self.worst_width = max(self.worst_width, float(np.max(dev[ext], initial=0.0)))
        self.slip_loss += float(np.sum(d["slip_loss_mm3"]))
        self.fed_forward += float(np.sum(np.maximum(d["fed_cmd_mm3"], 0.0)))
        self.max_force = max(self.max_force, float(np.max(d["peak_force_n"], initial=0.0)))
        margin = metrics["force_margin_n"]
        fin = margin[np.isfinite(margin)]
        if fin.size:
            self.min_margin = min(self.min_margin, float(np.min(fin)))
        g = d["grinding"].astype(np.int8)
        prev = np.int8(1 if self.last_grinding else 0)
        self.grinding_events += int(np.count_nonzero(np.diff(np.concatenate(([prev], g))) == 1))
        if g.size:
            self.last_grinding = bool(g[-1])
        self.grinding_moves += int(np.count_nonzero(g))
        self.ooze += float(np.sum(d["ooze_mm3"]))
        self.narrow += int(np.count_nonzero(metrics["narrow"] & ext))
        layer = moves["layer"].astype(np.int64)
        if layer.size:
            self.max_layer = max(self.max_layer, int(layer.max()))
        written = (kind & MoveKind.FW_RETRACT) == 0
        tools = moves["tool"]
        for tool in np.unique(tools).tolist():
            sel = written & (tools == tool)
            self.net_filament[int(tool)] = (self.net_filament.get(int(tool), 0.0)
                                            + float(np.sum(moves["de"][sel])))
        cols = np.zeros((len(moves), _NCOL))
        cols[:, _TIME] = d["duration_s"]
        cols[:, _CMD] = cmd
        cols[:, _DELIV] = out_all
        cols[:, _WE2] = np.where(ext, cmd * err * err, 0.0)
        cols[:, _W] = np.where(ext, cmd, 0.0)
        cols[:, _WORST] = np.where(ext, dev, 0.0)
        cols[:, _FMAX] = d["peak_force_n"]
        cols[:, _GRIND] = d["grinding"]
        cols[:, _OOZE] = d["ooze_mm3"]
        for name, key in (("layer", layer), ("feature", moves["feature"].astype(np.int64))):
            self._group(self.groups[name], key, cols)

    @staticmethod
    def _group(table: dict[int, npt.NDArray[np.float64]], key: npt.NDArray[np.int64],
               cols: npt.NDArray[np.float64]) -> None:
        keys, inv = np.unique(key, return_inverse=True)
        sums = np.zeros((keys.size, _NCOL))
        for c in (_TIME, _CMD, _DELIV, _WE2, _W, _GRIND, _OOZE):
            sums[:, c] = np.bincount(inv, weights=cols[:, c], minlength=keys.size)
        for c in (_WORST, _FMAX):
            mx = np.zeros(keys.size)
            np.maximum.at(mx, inv, cols[:, c])
            sums[:, c] = mx
        for k, row in zip(keys.tolist(), sums, strict=True):
            acc = table.get(k)
            if acc is None:
                table[k] = row.copy()
                continue
            for c in (_TIME, _CMD, _DELIV, _WE2, _W, _GRIND, _OOZE):
                acc[c] += row[c]
            acc[_WORST] = max(acc[_WORST], row[_WORST])
            acc[_FMAX] = max(acc[_FMAX], row[_FMAX])

    def summary(self) -> SimulationSummary:
        """The figures of ``SimulationResult.summary()``."""
        return SimulationSummary(
            file=self.file, machine=self.machine, printer=self.printer,
            firmware=self.firmware, pressure_advance=self.advance,
            total_time_s=self.total_time_s, moves=self.moves, layers=self.max_layer + 1,
            commanded_volume_mm3=self.cmd, delivered_volume_mm3=self.delivered,
            delivered_in_beads_mm3=self.in_beads,
            volume_error=_ratio(self.delivered, self.cmd),
            rms_flow_error=math.sqrt(self.we2 / self.w) if self.w > 0 else 0.0,
            peak_overextrusion=self.peak_over, peak_underextrusion=self.peak_under,
            worst_width_error_mm=self.worst_width,
            mean_slip=_share(self.slip_loss, self.fed_forward),
            max_feed_force_n=self.max_force,
            min_force_margin_n=None if math.isinf(self.min_margin) else self.min_margin,
            grinding_events=self.grinding_events, grinding_moves=self.grinding_moves,
            ooze_volume_mm3=self.ooze, narrow_beads=self.narrow,
            moves_over_flow_limit=self.over_flow_limit,
            net_filament_mm={str(k): v for k, v in sorted(self.net_filament.items())},
            warnings=tuple(self.warnings))

    def rows(self, name: str) -> list[dict[str, float | int]]:
        """Per-group rows as ``SimulationResult._grouped`` makes them."""
        out: list[dict[str, float | int]] = []
        for k in sorted(self.groups[name]):
            a = self.groups[name][k]
            out.append({name: int(k), "time_s": float(a[_TIME]),
                        "commanded_mm3": float(a[_CMD]), "delivered_mm3": float(a[_DELIV]),
                        "rms_flow_error": math.sqrt(a[_WE2] / a[_W]) if a[_W] > 0 else 0.0,
                        "worst_width_error_mm": float(a[_WORST]),
                        "max_feed_force_n": float(a[_FMAX]),
                        "grinding_moves": int(a[_GRIND]), "ooze_mm3": float(a[_OOZE])})
        return out

    def feature_rows(self) -> list[dict[str, float | int | str]]:
        """Per-feature rows with the feature names."""
        rows: list[dict[str, float | int | str]] = []
        for r in self.rows("feature"):
            k = int(r["feature"])
            name = self.features[k] if 0 <= k < len(self.features) else "unknown"
            rows.append({**r, "feature": name})
        return rows
