"""Whole-print figures accumulated section by section (for :mod:`.stream`).

Every figure of :meth:`SimulationResult.summary`, :meth:`~SimulationResult.per_layer`,
:meth:`~SimulationResult.per_feature` and :meth:`~SimulationResult.worst_moves` is a sum, a
count, a maximum, a minimum or a ranking over moves (the RMS flow error is
``sqrt(Σ w·e² / Σ w)``), so it can be accumulated over consecutive sections. The sums use
the compiled passes of the whole-table result (:mod:`._summary_kernel`: compensated sums,
carried from section to section), so the streamed figures equal the whole table's to the
bit wherever the per-move results do; the worst moves are the whole print's ranking (ties
to the earlier move, as a stable sort).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics import DynamicsResult
from flowtwin.errors import DataError
from flowtwin.simulation import _summary_kernel as sk
from flowtwin.simulation.parameters import MoveParameters
from flowtwin.simulation.result import _PRINTING_BITS, GroupTotals
from flowtwin.simulation.summary import SimulationSummary

__all__ = ["WORST_KEPT", "Aggregates"]

_MAX_WARNINGS = 200
#: Warnings that count moves or commands of a section: "N what[ (first: …)]" and
#: "what ignored Nx: why" (a whole print has one of each, with the summed count).
_COUNTED = re.compile(r"^(?P<n>\d+) (?P<what>.+?)(?: \(first: .*\))?$", re.S)
_IGNORED = re.compile(r"^(?P<what>.+ ignored )(?P<n>\d+)x: .*$", re.S)
#: Worst moves kept for each ranking (``worst_moves(count <= WORST_KEPT)``).
WORST_KEPT = 20



def _new_totals() -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    s = np.zeros(sk.N_TOTALS)
    s[sk.T_MARGIN_MIN] = math.inf
    return s, np.zeros(sk.N_TOTALS)


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
    over_flow_limit: int = 0
    #: The move furthest above its machine flow limit (largest flow / limit; ties to the
    #: earlier move): ``move``, ``line``, ``layer``, ``feature`` (index), ``flow_mm3_s``,
    #: ``limit_mm3_s``; ``None`` while no move is above.
    worst_over_flow: dict[str, float | int] | None = None
    _over_ratio: float = -math.inf
    max_layer: int = -1
    net_filament_mm: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    _warned: set[str] = field(default_factory=set)
    _counts: dict[str, tuple[int, str]] = field(default_factory=dict)
    _s: npt.NDArray[np.float64] = field(default_factory=lambda: _new_totals()[0])
    _c: npt.NDArray[np.float64] = field(default_factory=lambda: _new_totals()[1])
    _grinding: bool = False
    _layers: GroupTotals = field(default_factory=GroupTotals)
    _features: GroupTotals = field(default_factory=GroupTotals)
    # (score, move, row) of the worst moves so far, best first
    _worst: dict[str, list[tuple[float, int, dict[str, float | int]]]] = field(
        default_factory=lambda: {"width": [], "force": []})

    def note_warnings(self, items: list[str] | tuple[str, ...]) -> None:
        """Keep warnings once each (at most 200); a counted warning (``"N moves …"``,
        ``"… ignored Nx: …"``) of every section adds to one warning of the whole print,
        worded as the whole table words it (its count summed, its first occurrence)."""
        for w in items:
            counted = _COUNTED.match(w) or _IGNORED.match(w)
            if counted is not None:
                key = counted["what"]
                if key in self._counts:
                    n, first = self._counts[key]
                    self._counts[key] = (n + int(counted["n"]), first)
                    continue
                self._counts[key] = (int(counted["n"]), w)
                w = key  # its place in the list; worded when the summary is made
            if w not in self._warned and len(self.warnings) < _MAX_WARNINGS:
                self._warned.add(w)
                self.warnings.append(w)

    def warning_texts(self) -> list[str]:
        """The warnings, counted ones with their whole-print counts."""
        out = []
        for w in self.warnings:
            if w in self._counts:
                n, first = self._counts[w]
                counted = _COUNTED.match(first) or _IGNORED.match(first)
                assert counted is not None
                w = first[:counted.start("n")] + str(n) + first[counted.end("n"):]
            out.append(w)
        return out

    def add_time(self, end_s: float | None) -> None:
        """``end_s``: the end of the print (last section)."""
        if end_s is not None:
            self.total_time_s = end_s

    def add(self, moves: npt.NDArray[np.void], dyn: DynamicsResult,
            metrics: npt.NDArray[np.void], params: MoveParameters) -> None:
        """Accumulate one simulated section (the moves after those added before)."""
        if params.over_flow_limit is not None:
            self.over_flow_limit += int(np.count_nonzero(params.over_flow_limit))
            self._rank_over_flow(moves, dyn.moves, params)
        d = dyn.moves
        kind = moves["kind"]
        self._grinding = bool(sk.add_totals(
            self._s, self._c, self._grinding, kind, _PRINTING_BITS, d["cmd_mm3"], d["out_mm3"],
            d["stop_out_mm3"], d["fed_cmd_mm3"], d["slip_loss_mm3"], d["ooze_mm3"],
            d["peak_force_n"], d["grinding"], metrics["flow_error"], metrics["width_mean_mm"],
            metrics["width_nominal_mm"], metrics["force_margin_n"], metrics["narrow"]))
        if len(moves):
            self.max_layer = max(self.max_layer, int(moves["layer"].max()))
        self._layers.add(moves["layer"], kind, d, metrics)
        self._features.add(moves["feature"], kind, d, metrics)
        self._rank(moves, d, metrics)
        self.moves += len(moves)

    def _rank_over_flow(self, moves: npt.NDArray[np.void], d: npt.NDArray[np.void],
                        params: MoveParameters) -> None:
        """Keep the move furthest above its flow limit (flow = commanded volume / duration)."""
        over, limit = params.over_flow_limit, params.flow_limit_mm3_s
        if over is None or limit is None or not np.any(over):
            return
        dur = np.asarray(d["duration_s"], dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            flow = np.where(dur > 0, np.asarray(d["cmd_mm3"], dtype=np.float64) / dur, 0.0)
            ratio = np.where(over, flow / limit, 0.0)
        i = int(np.nanargmax(ratio))
        if float(ratio[i]) > self._over_ratio:
            self._over_ratio = float(ratio[i])
            self.worst_over_flow = {
                "move": self.moves + i, "line": int(moves["line"][i]),
                "layer": int(moves["layer"][i]), "feature": int(moves["feature"][i]),
                "flow_mm3_s": float(flow[i]), "limit_mm3_s": float(limit[i])}

    def _rank(self, moves: npt.NDArray[np.void], d: npt.NDArray[np.void],
              met: npt.NDArray[np.void]) -> None:
        """Merge this section's worst moves into the whole print's ranking."""
        cmd = d["cmd_mm3"]
        ext = ((moves["kind"] & _PRINTING_BITS) == _PRINTING_BITS) & (cmd > 0.0)
        dev = np.abs(met["width_mean_mm"] - met["width_nominal_mm"])
        margin = met["force_margin_n"]
        for by, cand, score in (
                ("width", np.flatnonzero(ext), -dev),
                ("force", np.flatnonzero(np.isfinite(margin)), margin)):
            if cand.size > WORST_KEPT:
                part = np.argpartition(score[cand], WORST_KEPT - 1)[:WORST_KEPT]
                # ties at the cut: keep the earliest moves, as the stable sort does
                cut = np.max(score[cand][part])
                cand = np.union1d(cand[score[cand] < cut], cand[score[cand] == cut])
            kept = self._worst[by]
            for i in cand.tolist():
                kept.append((float(score[i]), self.moves + i, {
                    "move": self.moves + i, "line": int(moves["line"][i]),
                    "layer": int(moves["layer"][i]),
                    "width_nominal_mm": float(met["width_nominal_mm"][i]),
                    "width_mean_mm": float(met["width_mean_mm"][i]),
                    "flow_error": float(met["flow_error"][i]),
                    "peak_force_n": float(d["peak_force_n"][i]),
                    "force_margin_n": float(met["force_margin_n"][i])}))
            kept.sort(key=lambda e: (e[0], e[1]))
            del kept[WORST_KEPT:]

    # -- results ----------------------------------------------------------------------------
    def summary(self) -> SimulationSummary:
        """The figures of ``SimulationResult.summary()``."""
        return SimulationSummary.from_totals(
            sk.fold_totals(self._s, self._c), file=self.file, machine=self.machine,
            printer=self.printer, firmware=self.firmware, pressure_advance=self.advance,
            total_time_s=self.total_time_s, moves=self.moves, layers=self.max_layer + 1,
            moves_over_flow_limit=self.over_flow_limit, net_filament_mm=self.net_filament_mm,
            warnings=tuple(self.warning_texts()))

    def rows(self, name: str) -> list[dict[str, float | int]]:
        """Per-layer (``"layer"``) or per-feature (``"feature"``, indices) rows."""
        return (self._layers if name == "layer" else self._features).rows(name)

    def feature_rows(self) -> list[dict[str, float | int | str]]:
        """Per-feature rows with the feature names."""
        rows: list[dict[str, float | int | str]] = []
        for r in self.rows("feature"):
            k = int(r["feature"])
            name = self.features[k] if 0 <= k < len(self.features) else "unknown"
            rows.append({**r, "feature": name})
        return rows

    def worst_moves(self, by: str = "width", count: int = 10) -> list[dict[str, float | int]]:
        """The ``count`` worst extruding moves by width error or smallest force margin, as
        ``SimulationResult.worst_moves`` ranks them (``count <= WORST_KEPT``)."""
        if by not in self._worst:
            raise DataError("unknown ranking", field="by", value=by, allowed="width, force")
        if count > WORST_KEPT:
            raise DataError("a streamed simulation keeps fewer worst moves", field="count",
                            value=count, allowed=f"<= {WORST_KEPT}")
        return [dict(row) for _s, _i, row in self._worst[by][:count]]

