"""Per-move quantities the toolpath viewer colours by.

A :class:`Quantity` is one value per move of the move table with its label, unit and
colour scale. :func:`simulation_quantities` gives a curated set (the windowed flow error
first) and then *every other per-move number the result has*: any further float field of
the dynamics' per-move results, of the deposition metrics, or any ``(n_moves,)`` array of
the move parameters — so a model that adds, say, a melt temperature per move
(``melt_temperature_c``) appears in the viewer without a change here. Units are read from
the name's suffix (``_mm``, ``_n``, ``_c``, ``_mm_s``, …).

:func:`compensated_quantities` gives the same quantities for a compensated file on the
*original* moves (its pieces aggregated per original move), so before and after are drawn
on one geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import numpy.typing as npt

from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import SimulationResult
from flowtwin.simulation.windowed import WindowedFlow, path_lengths_mm

__all__ = ["Quantity", "compensated_quantities", "simulation_quantities"]

FloatArray = npt.NDArray[np.float64]
_BEAD = 1.0 - math.pi / 4.0
#: Colour range of the flow errors, %: white is exact, full colour ±25 % (beyond the
#: verdict's "visible" 15 %), the same on every print.
_FLOW_RANGE = (-25.0, 25.0)
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)

#: Per-move fields shown under another name, or not worth a colour of their own.
_SKIP = frozenset({
    "cmd_mm3", "fed_cmd_mm3", "fed_mm3", "out_mm3", "stop_out_mm3", "q_mean_mm3_s",
    "q_min_mm3_s", "q_max_mm3_s", "peak_force_n", "slip", "slip_loss_mm3", "grind_loss_mm3",
    "grinding", "duration_s", "width_nominal_mm", "width_mean_mm", "width_min_mm",
    "width_max_mm", "flow_error", "force_margin_n", "narrow", "temperature_c",
    "layer_height_mm", "ooze_mm3"})

_UNITS = (("_mm3_s", "mm³/s"), ("_mm_s2", "mm/s²"), ("_mm_s", "mm/s"), ("_mm3", "mm³"),
          ("_mm", "mm"), ("_pa_s", "Pa·s"), ("_mpa", "MPa"), ("_n", "N"), ("_c", "°C"),
          ("_k", "K"), ("_s", "s"))


@dataclass(frozen=True, slots=True)
class Quantity:
    """One value per move, ready to colour a toolpath.

    Attributes
    ----------
    key
        Identifier (a name, unique in a report).
    label, unit
        What it is, in words, and its unit as displayed.
    values
        Displayed value per move (already scaled to ``unit``), ``nan`` where the move has
        none; shape ``(n_moves,)``.
    diverging
        Zero is neutral (a red–blue scale centred on 0); else a sequential scale.
    reverse
        Low values are the bad ones (e.g. a force margin).
    aggregate
        How pieces of a compensated move combine: ``"max"``, ``"min"`` or ``"mean"``.
    fixed_domain
        A colour range that means the same on every print (``None``: from the values).
    """

    key: str
    label: str
    unit: str
    values: FloatArray
    diverging: bool = False
    reverse: bool = False
    aggregate: str = "max"
    fixed_domain: tuple[float, float] | None = None

    def domain(self) -> tuple[float, float]:
        """Default colour range: :attr:`fixed_domain`, else robust (0.5–99.5 %) extremes;
        when diverging, symmetric about 0 up to the 95th percentile of ``|value|`` (so
        ordinary values keep their colour next to a few extreme ones, which saturate)."""
        if self.fixed_domain is not None:
            return self.fixed_domain
        v = self.values[np.isfinite(self.values)]
        if v.size == 0:
            return (0.0, 1.0)
        if self.diverging:
            m = max(float(np.percentile(np.abs(v), 95.0)), 1e-9)
            return (-m, m)
        lo, hi = (float(x) for x in np.percentile(v, [0.5, 99.5]))
        if hi <= lo:
            hi = lo + max(abs(lo) * 0.01, 1e-9)
        return (lo, hi)


def _printing(result: SimulationResult) -> npt.NDArray[np.bool_]:
    kind = result.plan.table.moves["kind"].astype(np.int64)
    return ((kind & _PRINTING) == _PRINTING) & (result.dynamics.moves["cmd_mm3"] > 0)


def _f(a: npt.ArrayLike) -> FloatArray:
    return np.array(a, dtype=np.float64)  # a copy: quantities never alias the result


def _label(name: str) -> tuple[str, str]:
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return name[: -len(suffix)].replace("_", " "), unit
    return name.replace("_", " "), ""


def simulation_quantities(result: SimulationResult, windowed: WindowedFlow) -> list[Quantity]:
    """The quantities of one simulation (see the module docstring).

    Parameters
    ----------
    result
        The simulation.
    windowed
        Its windowed flow figures (:func:`flowtwin.report.verdict.result_windowed`).
    """
    n = len(result.plan.table)
    d = result.dynamics.moves
    met = result.metrics
    ext = _printing(result)
    nan = np.full(n, np.nan)
    w = windowed.window_mm
    cruise = _f(result.plan.timeline.phases["cruise_v"])
    dur = _f(d["duration_s"])
    with np.errstate(divide="ignore", invalid="ignore"):
        flow = np.where(ext & (dur > 0), _f(d["cmd_mm3"]) / dur, np.nan)
    out = [
        Quantity("flow_error_window", f"flow error over {w:g} mm of path", "%",
                 100.0 * windowed.centred_error, diverging=True, fixed_domain=_FLOW_RANGE),
        Quantity("flow_error_move", "flow error per move", "%",
                 np.where(ext, 100.0 * _f(met["flow_error"]), nan), diverging=True,
                 fixed_domain=_FLOW_RANGE),
        Quantity("width", "predicted bead width", "mm", _f(met["width_mean_mm"]),
                 aggregate="mean"),
        Quantity("force_margin", "feed force margin to grinding", "N",
                 np.where(ext, _f(met["force_margin_n"]), nan), reverse=True, aggregate="min"),
        Quantity("speed", "planned speed", "mm/s", cruise),
        Quantity("flow", "commanded volumetric flow", "mm³/s", flow, aggregate="mean"),
        Quantity("slip", "drive slip", "%", np.where(ext, 100.0 * _f(d["slip"]), nan)),
        Quantity("temperature", "nozzle temperature", "°C",
                 _f(result.parameters.temperature_c), aggregate="mean"),
        Quantity("layer_height", "layer height", "mm",
                 _f(result.parameters.layer_height_mm), aggregate="mean"),
    ]
    return out + _extras(result, {q.key for q in out})


def _extras(result: SimulationResult, taken: set[str]) -> list[Quantity]:
    """Every other per-move float array of the result (module docstring)."""
    n = len(result.plan.table)
    found: dict[str, FloatArray] = {}
    for arr in (result.dynamics.moves, result.metrics):
        for name in arr.dtype.names or ():
            if name in _SKIP or arr.dtype[name].kind != "f":
                continue
            found.setdefault(name, _f(arr[name]))
    params = result.parameters
    for f in fields(params):
        value = getattr(params, f.name)
        if f.name in _SKIP or not isinstance(value, np.ndarray):
            continue
        if value.shape == (n,) and value.dtype.kind == "f":
            found.setdefault(f.name, _f(value))
    out = []
    for name, values in found.items():
        if name in taken:
            continue
        label, unit = _label(name)
        out.append(Quantity(name, label, unit, values, aggregate="mean"))
    return out


def _per_original(values: FloatArray, piece_row: npt.NDArray[np.int64], n: int,
                  how: str) -> FloatArray:
    """Combine per-piece values onto their original moves (``nan`` where none)."""
    out = np.full(n, np.nan)
    ok = np.isfinite(values)
    rows = piece_row[ok]
    v = values[ok]
    if how == "mean":
        cnt = np.bincount(rows, minlength=n)
        tot = np.bincount(rows, weights=v, minlength=n)
        has = cnt > 0
        out[has] = tot[has] / cnt[has]
        return out
    if how == "min":
        acc = np.full(n, np.inf)
        np.minimum.at(acc, rows, v)
    else:
        acc = np.full(n, -np.inf)
        np.maximum.at(acc, rows, v)
    has = np.isfinite(acc)
    out[has] = acc[has]
    return out


def compensated_quantities(original: SimulationResult, compensated: SimulationResult,
                           piece_row: npt.NDArray[np.int64], windowed_after: WindowedFlow,
                           reference: list[Quantity]) -> list[Quantity]:
    """The quantities of a compensated file, on the original's moves.

    Parameters
    ----------
    original, compensated
        The original and the compensated file simulated on the same machine.
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.
    windowed_after
        The compensated delivery's windowed figures against the original intent.
    reference
        The original's quantities (:func:`simulation_quantities`): the same keys, labels and
        scales are given, in order.

    Returns
    -------
    list of Quantity
        Flow errors and widths against the original intent (delivered melt of the pieces
        of a move over what the move meant); other quantities combined over the pieces by
        their :attr:`Quantity.aggregate`.
    """
    n = len(original.plan.table)
    tab = original.plan.table
    m = tab.moves
    cmd = _f(original.dynamics.moves["cmd_mm3"])
    delivered = np.bincount(piece_row, weights=_f(compensated.dynamics.moves["out_mm3"]),
                            minlength=n)
    ext = _printing(original)
    bead = ext & np.isfinite(_f(original.metrics["width_nominal_mm"]))
    path = path_lengths_mm(np.column_stack([m["x"], m["y"], np.zeros(n)]).astype(np.float64),
                           np.array([tab.start_xyze[0], tab.start_xyze[1], 0.0]))
    h = _f(original.parameters.layer_height_mm)
    nan = np.full(n, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.where(bead, delivered / cmd - 1.0, nan)
        width = np.where(bead & (path > 1e-9), delivered / path / h + _BEAD * h, nan)
    direct = {"flow_error_window": 100.0 * windowed_after.centred_error,
              "flow_error_move": 100.0 * err, "width": width}
    after = {q.key: q for q in simulation_quantities(
        compensated, _empty_windowed(len(compensated.plan.table), windowed_after.window_mm))}
    out = []
    for ref in reference:
        key = ref.key
        if key in direct:
            values = direct[key]
        elif key in after:
            values = _per_original(after[key].values, piece_row, n, ref.aggregate)
        else:
            values = nan.copy()
        out.append(Quantity(key, ref.label, ref.unit, values, ref.diverging, ref.reverse,
                            ref.aggregate, ref.fixed_domain))
    return out


def _empty_windowed(n: int, window_mm: float) -> WindowedFlow:
    blank = np.full(n, np.nan)
    return WindowedFlow(window_mm, 0.0, 0.0, (), (), blank, blank, blank)
