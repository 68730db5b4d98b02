"""What a whole-print simulation returns: per move, per layer, per feature, whole print."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_open
from flowtwin.dynamics import DynamicsResult
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.plan_file import PlanResult
from flowtwin.simulation import _summary_kernel as sk
from flowtwin.simulation._deposit_kernel import bead_metrics
from flowtwin.simulation.parameters import MoveParameters
from flowtwin.simulation.summary import SimulationSummary

__all__ = ["METRIC_DTYPE", "GroupTotals", "SimulationResult"]

#: Deposition metrics per move (widths in mm; NaN where the move lays no bead).
METRIC_DTYPE = np.dtype([
    ("width_nominal_mm", np.float64),   # what the slicer meant: its E over the path [001 Eq. 7]
    ("width_mean_mm", np.float64),      # from the melt delivered over the path
    ("width_min_mm", np.float64),       # from the lowest / highest flow over the mean speed
    ("width_max_mm", np.float64),
    ("flow_error", np.float64),         # delivered / commanded - 1 (extruding moves)
    ("force_margin_n", np.float64),     # max feed force of the roller - peak feed force
    ("narrow", np.bool_),               # predicted width below the layer height (w < h)
], align=True)

_BEAD = 1.0 - math.pi / 4.0
#: A move lays a bead when it extrudes with XY motion (and has a commanded volume).
_PRINTING_BITS = int(MoveKind.EXTRUDE | MoveKind.XY)


@dataclass(slots=True)
class SimulationResult:
    """A G-code simulated on a machine.

    Attributes
    ----------
    plan
        The read and planned G-code (:class:`~flowtwin.planner.plan_file.PlanResult`).
    machine_name
        Name of the set-up.
    parameters
        Per-move physical parameters used.
    dynamics
        The integrator's per-move results, totals and optional time series.
    metrics
        Deposition metrics per move (:data:`METRIC_DTYPE`).
    advance
        Pressure advance the prediction includes (e.g. ``"klipper K=0.04 s"`` or ``"off"``).
    warnings
        Everything the user must know (extrapolations, ignored commands).
    nozzle_diameter_mm
        Nozzle diameter of the simulated hot end, mm (the window of the flow figures a
        user can act on, :mod:`flowtwin.simulation.windowed`); ``nan``: unknown.
    """

    plan: PlanResult
    machine_name: str
    parameters: MoveParameters
    dynamics: DynamicsResult
    metrics: npt.NDArray[np.void]
    advance: str
    warnings: list[str] = field(default_factory=list)
    nozzle_diameter_mm: float = math.nan

    def _repr_html_(self) -> str:
        """The report (verdict, toolpath viewer, plots) in a notebook cell."""
        from flowtwin.report.notebook import simulation_repr
        return simulation_repr(self)

    # ---- aggregates -----------------------------------------------------------------------
    def _extruding(self) -> npt.NDArray[np.bool_]:
        """Moves that lay a bead: extruding XY moves with a commanded volume."""
        out = np.empty(len(self.plan.table.moves), np.bool_)
        sk.extruding_mask(self.plan.table.moves["kind"], self.dynamics.moves["cmd_mm3"],
                       _PRINTING_BITS, out)
        return out

    def summary(self) -> SimulationSummary:
        """Whole-print figures (:class:`~flowtwin.simulation.summary.SimulationSummary`)."""
        d = self.dynamics.moves
        met = self.metrics
        t = sk.print_totals(self.plan.table.moves["kind"], _PRINTING_BITS, d["cmd_mm3"],
                         d["out_mm3"], d["stop_out_mm3"], d["fed_cmd_mm3"],
                         d["slip_loss_mm3"], d["ooze_mm3"], d["peak_force_n"], d["grinding"],
                         met["flow_error"], met["width_mean_mm"], met["width_nominal_mm"],
                         met["force_margin_n"], met["narrow"])
        plan = self.plan.summary()
        flags = self.parameters.over_flow_limit
        return SimulationSummary.from_totals(
            t, file=plan.file, machine=self.machine_name, printer=plan.printer,
            firmware=plan.firmware, pressure_advance=self.advance,
            total_time_s=plan.total_time_s, moves=plan.moves, layers=plan.layers,
            moves_over_flow_limit=0 if flags is None else int(np.count_nonzero(flags)),
            net_filament_mm=plan.net_filament_mm, warnings=tuple(self.warnings))

    def per_layer(self) -> list[dict[str, float | int]]:
        """Commanded and delivered volume, RMS flow error, worst width error per layer."""
        return self._grouped(self.plan.table.moves["layer"].astype(np.int64), "layer")

    def per_feature(self) -> list[dict[str, float | int | str]]:
        """The same as :meth:`per_layer`, per feature type."""
        rows = self._grouped(self.plan.table.moves["feature"].astype(np.int64), "feature")
        names = self.plan.table.features
        out: list[dict[str, float | int | str]] = []
        for r in rows:
            k = int(r["feature"])
            out.append({**r, "feature": names[k] if 0 <= k < len(names) else "unknown"})
        return out

    def _grouped(self, key: npt.NDArray[np.int64], name: str) -> list[dict[str, float | int]]:
        groups = GroupTotals()
        groups.add(key, self.plan.table.moves["kind"], self.dynamics.moves, self.metrics)
        return groups.rows(name)

    def worst_moves(self, by: str = "width", count: int = 10) -> list[dict[str, float | int]]:
        """The ``count`` worst extruding moves by width error (``"width"``) or by the
        smallest force margin (``"force"``), with their source lines."""
        m = self.plan.table.moves
        met = self.metrics
        ext = self._extruding()
        idx = np.flatnonzero(ext)
        if by == "width":
            score = np.abs(met["width_mean_mm"] - met["width_nominal_mm"])[idx]
            order = idx[np.argsort(-score, kind="stable")]
        elif by == "force":
            order = np.flatnonzero(np.isfinite(met["force_margin_n"]))
            order = order[np.argsort(met["force_margin_n"][order], kind="stable")]
        else:
            raise DataError("unknown ranking", field="by", value=by, allowed="width, force")
        rows = []
        for i in order[:count].tolist():
            rows.append({"move": i, "line": int(m["line"][i]), "layer": int(m["layer"][i]),
                         "width_nominal_mm": float(met["width_nominal_mm"][i]),
                         "width_mean_mm": float(met["width_mean_mm"][i]),
                         "flow_error": float(met["flow_error"][i]),
                         "peak_force_n": float(self.dynamics.moves["peak_force_n"][i]),
                         "force_margin_n": float(met["force_margin_n"][i])})
        return rows

    # ---- output ---------------------------------------------------------------------------
    def write_series(self, path: str | os.PathLike[str]) -> Path:
        """Write the time series to Parquet (``.parquet``) or CSV (``.csv``), atomically."""
        series = self.dynamics.series
        if series is None:
            raise DataError("this simulation has no time series; simulate with series_dt_s",
                            field="series_dt_s")
        out = Path(path)
        suffix = out.suffix.lower()
        names = list(series.dtype.names or ())
        if suffix == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.table({n: np.ascontiguousarray(series[n]) for n in names})
            with atomic_open(out, "wb") as fh:
                pq.write_table(table, fh)
        elif suffix == ".csv":
            with atomic_open(out, "w") as fh:
                fh.write(",".join(names) + "\n")
                cols = np.column_stack([series[n] for n in names])
                np.savetxt(fh, cols, delimiter=",", fmt="%.9g")
        else:
            raise DataError("unknown series format", field="path", value=str(out),
                            allowed=".parquet or .csv")
        return out


class GroupTotals:
    """Per-layer or per-feature sums of simulated moves, added in move order (one
    compiled pass per call, :func:`~flowtwin.simulation._summary_kernel.add_groups`);
    consecutive calls give the rows of one call on all the moves, to the bit."""

    def __init__(self) -> None:
        self.lo = 0
        self.acc = np.zeros((0, sk.N_GROUP))
        self.comp = np.zeros((0, sk.N_GROUP))
        self.count = np.zeros(0, np.int64)

    def add(self, key: npt.NDArray[np.integer], kind: npt.NDArray[np.uint8],
            dyn: npt.NDArray[np.void], metrics: npt.NDArray[np.void]) -> None:
        """Add moves: their group ``key``, ``kind``, dynamics rows and metrics rows."""
        if key.shape[0] == 0:
            return
        lo, hi = int(key.min()), int(key.max())
        if self.count.shape[0] == 0:
            self.lo = lo
            self._resize(lo, hi)
        elif lo < self.lo or hi >= self.lo + self.count.shape[0]:
            self._resize(min(lo, self.lo), max(hi, self.lo + self.count.shape[0] - 1))
        sk.add_groups(key, self.lo, self.acc, self.comp, self.count, kind, _PRINTING_BITS,
                      dyn["duration_s"], dyn["cmd_mm3"], dyn["out_mm3"], dyn["stop_out_mm3"],
                      dyn["ooze_mm3"], dyn["peak_force_n"], dyn["grinding"],
                      metrics["flow_error"], metrics["width_mean_mm"],
                      metrics["width_nominal_mm"])

    def _resize(self, lo: int, hi: int) -> None:
        size = hi - lo + 1
        acc, comp, count = np.zeros((size, sk.N_GROUP)), np.zeros((size, sk.N_GROUP)), \
            np.zeros(size, np.int64)
        k = self.lo - lo
        n = self.count.shape[0]
        acc[k:k + n], comp[k:k + n], count[k:k + n] = self.acc, self.comp, self.count
        self.lo, self.acc, self.comp, self.count = lo, acc, comp, count

    def rows(self, name: str) -> list[dict[str, float | int]]:
        """One row per group with moves: ``name`` (the key), time (s), commanded and
        delivered volume (mm³), volume-weighted RMS flow error, worst width error (mm),
        largest feed force (N), grinding moves, ooze (mm³)."""
        a = sk.fold_groups(self.acc, self.comp)
        rows: list[dict[str, float | int]] = []
        for g in np.flatnonzero(self.count).tolist():
            w = float(a[g, sk.G_W])
            rows.append({
                name: self.lo + g,
                "time_s": float(a[g, sk.G_TIME]),
                "commanded_mm3": float(a[g, sk.G_CMD]),
                "delivered_mm3": float(a[g, sk.G_DELIV]),
                "rms_flow_error": math.sqrt(float(a[g, sk.G_WEE]) / w) if w > 0.0 else 0.0,
                "worst_width_error_mm": float(a[g, sk.G_WORST]),
                "max_feed_force_n": float(a[g, sk.G_FMAX]),
                "grinding_moves": int(a[g, sk.G_GRIND]),
                "ooze_mm3": float(a[g, sk.G_OOZE]),
            })
        return rows



def deposition_metrics(plan: PlanResult, dyn: DynamicsResult, params: MoveParameters
                       ) -> npt.NDArray[np.void]:
    """Nominal and predicted bead widths, flow error and force margin per move.

    Widths follow the slicer bead model ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7], i.e.
    ``w = A/h + (1 − π/4)·h``, with ``A`` the melt volume per path length: the G-code's for
    the nominal width, the delivered melt for the predicted mean width, and the lowest and
    highest flow of the move over its mean speed for the predicted extremes.
    """
    m = plan.table.moves
    n = len(m)
    out = np.zeros(n, METRIC_DTYPE)
    d = dyn.moves

    def col(a: npt.NDArray[np.generic]) -> npt.NDArray[np.float64]:
        # record fields are strided views: the kernel reads them in place (no copies)
        return np.asarray(a, dtype=np.float64)

    bead_metrics(col(m["x"]), col(m["y"]), float(plan.table.start_xyze[0]),
                 float(plan.table.start_xyze[1]), m["kind"],
                 int(MoveKind.EXTRUDE), col(d["cmd_mm3"]), col(d["out_mm3"]),
                 col(d["duration_s"]), col(d["q_min_mm3_s"]), col(d["q_max_mm3_s"]),
                 col(d["peak_force_n"]), col(params.layer_height_mm),
                 col(params.params.max_feed_force_n), _BEAD, out["width_nominal_mm"],
                 out["width_mean_mm"], out["width_min_mm"], out["width_max_mm"],
                 out["flow_error"], out["force_margin_n"], out["narrow"])
    return out
