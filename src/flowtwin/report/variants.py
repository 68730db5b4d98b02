"""The value sets a report draws: a simulation's prediction, or before and after compensation.

Both are expressed on the *original* file's moves, so one geometry serves both. Per-layer
and per-feature rows are computed here from per-move arrays (time, commanded and
delivered melt, flow error, windowed extremes, force, grinding, ooze), the same way for a
plain simulation and for a compensated file's pieces summed per original move.
"""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
import numpy.typing as npt

from flowtwin.gcode.moves import MoveKind
from flowtwin.report.payload import (
    Variant,
    flow_scale,
    layer_heights_z,
    moves_track,
    series_track,
)
from flowtwin.report.quantities import Quantity, compensated_quantities, simulation_quantities
from flowtwin.report.spots import Spot, locate_spots, result_windowed
from flowtwin.simulation import SimulationResult
from flowtwin.simulation.windowed import WindowedFlow

__all__ = ["comparison_variants", "group_rows", "prediction_variant"]

FloatArray = npt.NDArray[np.float64]
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)


def group_rows(key: npt.NDArray[np.int64], *, time_s: FloatArray, cmd_mm3: FloatArray,
               delivered_mm3: FloatArray, printing: npt.NDArray[np.bool_],
               window_max: FloatArray, window_min: FloatArray, force_n: FloatArray,
               grinding: npt.NDArray[np.bool_], ooze_mm3: FloatArray
               ) -> list[dict[str, float | int]]:
    """Figures per value of ``key`` (a layer or feature index per move).

    Returns
    -------
    list of dict
        Per group: ``key``, ``time_s``, ``commanded_mm3``, ``delivered_mm3`` (all moves),
        ``rms_flow_error`` (volume-weighted over printing moves, fraction),
        ``worst_over``/``worst_under`` (windowed extremes, fraction; ``nan``: none),
        ``max_feed_force_n``, ``grinding_moves``, ``ooze_mm3``.
    """
    if key.size == 0:
        return []
    keys, inv = np.unique(key, return_inverse=True)
    g = keys.size

    def total(v: FloatArray) -> FloatArray:
        return np.asarray(np.bincount(inv, weights=v, minlength=g), dtype=np.float64)

    def extreme(v: FloatArray, fn: np.ufunc, init: float) -> FloatArray:
        acc = np.full(g, init)
        ok = np.isfinite(v)
        fn.at(acc, inv[ok], v[ok])
        acc[~np.isfinite(acc)] = np.nan
        return acc

    w = np.where(printing, cmd_mm3, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.where(printing & (cmd_mm3 > 0), delivered_mm3 / cmd_mm3 - 1.0, 0.0)
    we2 = total(w * err * err)
    ws = total(w)
    rms = np.where(ws > 0, np.sqrt(we2 / np.where(ws > 0, ws, 1.0)), 0.0)
    cols = {"time_s": total(time_s), "commanded_mm3": total(cmd_mm3),
            "delivered_mm3": total(delivered_mm3), "rms_flow_error": rms,
            "worst_over": extreme(window_max, np.maximum, -np.inf),
            "worst_under": extreme(window_min, np.minimum, np.inf),
            "max_feed_force_n": extreme(force_n, np.maximum, -np.inf),
            "grinding_moves": total(grinding.astype(np.float64)),
            "ooze_mm3": total(ooze_mm3)}
    rows: list[dict[str, float | int]] = []
    for j, k in enumerate(keys.tolist()):
        row: dict[str, float | int] = {"key": int(k)}
        for name, arr in cols.items():
            row[name] = int(arr[j]) if name == "grinding_moves" else float(arr[j])
        rows.append(row)
    return rows


def _spots_json(spots: tuple[Spot, ...]) -> list[dict[str, object]]:
    return [asdict(s) for s in spots]


def _rows_for(result: SimulationResult, *, time_s: FloatArray, delivered: FloatArray,
              windowed: WindowedFlow, force: FloatArray, grinding: npt.NDArray[np.bool_],
              ooze: FloatArray) -> tuple[list[dict[str, object]], list[dict[str, object]]]:
    m = result.plan.table.moves
    kind = m["kind"].astype(np.int64)
    cmd = np.asarray(result.dynamics.moves["cmd_mm3"], dtype=np.float64)
    printing = ((kind & _PRINTING) == _PRINTING) & (cmd > 0)
    common = {"time_s": time_s, "cmd_mm3": cmd, "delivered_mm3": delivered,
              "printing": printing, "window_max": windowed.move_max_error,
              "window_min": windowed.move_min_error, "force_n": force, "grinding": grinding,
              "ooze_mm3": ooze}
    layer_z = layer_heights_z(result)
    layers: list[dict[str, object]] = []
    for r in group_rows(m["layer"].astype(np.int64), **common):
        k = int(r["key"])
        z = layer_z[k] if 0 <= k < len(layer_z) else math.nan
        layers.append({"layer": k, "z_mm": z, **{a: b for a, b in r.items() if a != "key"}})
    names = result.plan.table.features
    features: list[dict[str, object]] = []
    for r in group_rows(m["feature"].astype(np.int64), **common):
        k = int(r["key"])
        features.append({"feature": names[k] if 0 <= k < len(names) else "(none)", "index": k,
                         **{a: b for a, b in r.items() if a != "key"}})
    return layers, features


def prediction_variant(result: SimulationResult, windowed: WindowedFlow | None = None,
                       spots: tuple[tuple[Spot, ...], tuple[Spot, ...]] | None = None
                       ) -> Variant:
    """The variant of one simulation: its quantities, time track, rows and worst spots."""
    win = windowed if windowed is not None else result_windowed(result)
    d = result.dynamics.moves
    over, under = spots if spots is not None else locate_spots(result, win)
    layers, features = _rows_for(
        result, time_s=np.asarray(d["duration_s"], dtype=np.float64),
        delivered=np.asarray(d["out_mm3"], dtype=np.float64)
        + np.asarray(d["stop_out_mm3"], dtype=np.float64),
        windowed=win, force=np.asarray(d["peak_force_n"], dtype=np.float64),
        grinding=np.asarray(d["grinding"], dtype=np.bool_),
        ooze=np.asarray(d["ooze_mm3"], dtype=np.float64))
    track = series_track(result) if (result.dynamics.series is not None
                                     and result.dynamics.series.shape[0] > 1) else \
        moves_track(result)
    return Variant("prediction", "prediction", simulation_quantities(result, win),
                   np.asarray(result.plan.timeline.phases["t_start"], dtype=np.float64),
                   track, layers, features,
                   {"over": _spots_json(over), "under": _spots_json(under)}, flow_scale(result))


def comparison_variants(original: SimulationResult, compensated: SimulationResult,
                        piece_row: npt.NDArray[np.int64]) -> tuple[Variant, Variant]:
    """Before and after compensation, both on the original's moves and against its intent.

    Parameters
    ----------
    original, compensated
        The original and the compensated file simulated on the same machine.
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.
    """
    n = len(original.plan.table)
    rows = np.asarray(piece_row, dtype=np.int64)
    before = prediction_variant(original)
    dc = compensated.dynamics.moves

    def summed(name: str) -> FloatArray:
        return np.asarray(np.bincount(rows, weights=np.asarray(dc[name], dtype=np.float64),
                                      minlength=n), dtype=np.float64)

    delivered = summed("out_mm3")
    win_after = result_windowed(original, delivered_mm3=delivered)
    over, under = locate_spots(original, win_after)
    force = np.full(n, -np.inf)
    np.maximum.at(force, rows, np.asarray(dc["peak_force_n"], dtype=np.float64))
    force[~np.isfinite(force)] = np.nan
    grinding = np.bincount(rows, weights=np.asarray(dc["grinding"], dtype=np.float64),
                           minlength=n) > 0
    layers, features = _rows_for(original, time_s=summed("duration_s"),
                                 delivered=delivered + summed("stop_out_mm3"),
                                 windowed=win_after, force=force, grinding=grinding,
                                 ooze=summed("ooze_mm3"))
    t_piece = np.asarray(compensated.plan.timeline.phases["t_start"], dtype=np.float64)
    t_after = np.full(n, np.nan)
    np.fmin.at(t_after, rows, t_piece)
    quantities: list[Quantity] = compensated_quantities(original, compensated, rows, win_after,
                                                        before.quantities)
    track = series_track(compensated) if (compensated.dynamics.series is not None and
                                          compensated.dynamics.series.shape[0] > 1) else \
        moves_track(compensated)
    after = Variant("after", "after compensation", quantities, t_after, track, layers, features,
                    {"over": _spots_json(over), "under": _spots_json(under)},
                    flow_scale(compensated))
    before = Variant("before", "before (original)", before.quantities, before.t_start_s,
                     before.track, before.layers, before.features, before.spots,
                     before.flow_scale_mm3_s)
    return before, after
