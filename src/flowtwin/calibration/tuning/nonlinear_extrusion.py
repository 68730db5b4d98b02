"""The twin's slip law as the firmware's own nonlinear-extrusion settings (``M592``).

The drive slips by ``s = (k_p + s'·F₀)/(1 + s'·F₀)`` in steady extrusion, with ``F₀`` the
feed force the commanded filament speed needs [000 Eqs. 6, 8] (``F₀ ∝`` flow, docs/spec.md §3.4;
:func:`flowtwin.simulation.parameters.operating_point`). To deliver a G-code's filament
speed ``v`` the drive must be commanded ``v_c`` with ``v_c·(1 − s(v_c)) = v``: the
firmware should multiply the E of a move by

``m(v) = v_c / v``

(the baked feed-forward of :mod:`flowtwin.compensation.slip` writes that into the E
words). Two firmwares can apply such a multiplier themselves, from the requested E speed:

* **Marlin** (``NONLINEAR_EXTRUSION``, ``M592 S1 A<a> B<b> C<c>``): every step of a forward
  extrusion that moves an axis is scaled by ``C + max(A·v² + B·v, 0)``, ``v`` the
  *instantaneous* requested E speed, mm/s (Marlin ``Stepper::calc_nonlinear_e``,
  bugfix-2.1.x; the first version of the feature, 2023, had ``A`` linear and ``B``
  quadratic and no ``S``);
* **RepRapFirmware** (``M592 D0 A<a> B<b> L<l>``): a printing move's E is scaled by
  ``1 + min(A·v + B·v², L)``, ``v`` its *average* requested E speed, mm/s (RRF
  ``DDA::Prepare``); the constant part of ``m`` (the slip offset ``k_p`` at ``v → 0``)
  is not in the formula: it is the E steps' or the flow's calibration (``M92``/``M221``).

:func:`fit_nonlinear_extrusion` fits those coefficients to ``m(v)`` over the printer's
feed range (least squares on an even grid of speeds) and states the residual;
:func:`apply_nonlinear_extrusion` executes a firmware's formula on a move table (what the
printer would extrude with the settings), so the settings can be checked against the baked
feed-forward by simulating both. The formulas and the command are the firmware model's
(:mod:`flowtwin.firmware.nonlinear`). Klipper (and Prusa's Buddy firmware, Repetier) has no
nonlinear extrusion: the slip can only be baked into the G-code (``flowtwin compensate
--slip``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.firmware import Firmware
from flowtwin.firmware.nonlinear import (
    RRF_DEFAULT_LIMIT,
    NonlinearFormula,
    nonlinear_command,
    nonlinear_formula,
)
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.planner.timeline import Timeline
from flowtwin.profiles.machine import Machine
from flowtwin.simulation.parameters import operating_point

__all__ = ["NonlinearExtrusionFit", "apply_nonlinear_extrusion", "fit_nonlinear_extrusion",
           "m592_command", "slip_multiplier"]

FloatArray = npt.NDArray[np.float64]

#: Fixed-point iterations of ``v_c = v / (1 − s(v_c))`` (``s'·F ≪ 1``: converges fast).
_ITERATIONS = 30


@dataclass(frozen=True, slots=True)
class NonlinearExtrusionFit:
    """Nonlinear-extrusion settings fitted to the twin's slip.

    Attributes
    ----------
    firmware
        The firmware.
    a, b, c
        The firmware's coefficients: Marlin ``C + max(A·v² + B·v, 0)``; RRF
        ``1 + min(A·v + B·v², L)`` (``c`` = 1: the constant part is the flow's); a firmware
        without nonlinear extrusion: none (0, 0, 1).
    limit
        RRF's ``L`` (``None`` for Marlin and Klipper).
    feed_min_mm_s, feed_max_mm_s
        Requested E speeds the fit covers, mm/s of filament.
    offset
        ``m`` at ``v → 0`` (the slip offset ``1/(1 − k_p)``): in Marlin's ``C``; for RRF to
        be calibrated in the E steps or the flow (``M92``/``M221``).
    rms_residual, max_residual
        RMS and largest ``|m_firmware(v)/m(v) − 1|`` over the range (for RRF against
        ``m/offset``, the part its formula can hold).
    command
        The command to send, or ``None`` (no nonlinear extrusion).
    note
        What to do with it, in words.
    """

    firmware: Firmware
    a: float
    b: float
    c: float
    limit: float | None
    feed_min_mm_s: float
    feed_max_mm_s: float
    offset: float
    rms_residual: float
    max_residual: float
    command: str | None
    note: str

    def multiplier(self, v_mm_s: npt.ArrayLike) -> FloatArray:
        """The firmware's E multiplier at requested E speed ``v`` (mm/s)."""
        v = np.asarray(v_mm_s, dtype=np.float64)
        formula = nonlinear_formula(self.firmware)
        if formula is NonlinearFormula.INSTANTANEOUS:
            return self.c + np.maximum(self.a * v * v + self.b * v, 0.0)
        if formula is NonlinearFormula.MOVE_AVERAGE:
            lim = RRF_DEFAULT_LIMIT if self.limit is None else self.limit
            return 1.0 + np.minimum(self.a * v + self.b * v * v, lim)
        return np.ones_like(v)

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able values."""
        return {"firmware": self.firmware.value, "a": self.a, "b": self.b, "c": self.c,
                "limit": self.limit, "feed_min_mm_s": self.feed_min_mm_s,
                "feed_max_mm_s": self.feed_max_mm_s, "offset": self.offset,
                "rms_residual": self.rms_residual, "max_residual": self.max_residual,
                "command": self.command, "note": self.note}


def slip_multiplier(machine: Machine, feed_mm_s: npt.ArrayLike, *,
                    temperature_c: float | None = None,
                    layer_height_mm: float | None = None) -> FloatArray:
    """``m(v) = v_c/v``: the E multiplier that delivers the requested filament speed ``v``.

    Solves ``v_c·(1 − s(v_c)) = v`` by fixed-point iteration, ``s`` the twin's steady
    slip at feed ``v_c`` (:func:`flowtwin.simulation.parameters.operating_point`, at the
    set-up's temperature and layer height unless given).

    Parameters
    ----------
    machine
        The set-up.
    feed_mm_s
        Requested filament speeds, mm/s (> 0), any shape.
    temperature_c, layer_height_mm
        Operating point (default: the set-up's).

    Returns
    -------
    ndarray
        ``m`` at every speed.
    """
    v = np.asarray(feed_mm_s, dtype=np.float64)
    if np.any(~(v > 0)):
        raise DataError("feed speeds must be positive", field="feed_mm_s",
                        value=float(np.min(v)), allowed="> 0 mm/s")
    h = machine.setup.layer_height_mm if layer_height_mm is None else layer_height_mm
    out = np.empty(v.shape)
    for idx, vi in np.ndenumerate(v):
        vc = float(vi)
        for _ in range(_ITERATIONS):
            s = operating_point(machine, feed_mm_s=vc, temperature_c=temperature_c,
                                layer_height_mm=h).slip
            vc = float(vi) / (1.0 - s)
        out[idx] = vc / float(vi)
    return out


def fit_nonlinear_extrusion(machine: Machine, firmware: Firmware | str, *,
                            feed_max_mm_s: float | None = None, feed_min_mm_s: float = 0.2,
                            points: int = 64) -> NonlinearExtrusionFit:
    """Fit a firmware's nonlinear-extrusion coefficients to the twin's slip.

    Parameters
    ----------
    machine
        The set-up (its drive, hot end, material, temperature and layer height).
    firmware
        The firmware (or its name).
    feed_max_mm_s
        Fastest requested filament speed to cover, mm/s; default: the printer's E speed
        limit or, when lower, the speed at which the feed force reaches 90 % of the
        roller's maximum (the drive would grind beyond it).
    feed_min_mm_s
        Slowest filament speed covered, mm/s.
    points
        Grid points of the least-squares fit.

    Returns
    -------
    NonlinearExtrusionFit
    """
    fw = Firmware.parse(firmware)
    formula = nonlinear_formula(fw)
    v_max = _feed_max(machine) if feed_max_mm_s is None else float(feed_max_mm_s)
    if not (0.0 < feed_min_mm_s < v_max):
        raise DataError("feed range is empty", field="feed_max_mm_s", value=v_max,
                        allowed=f"> feed_min_mm_s ({feed_min_mm_s:g} mm/s)")
    v = np.linspace(feed_min_mm_s, v_max, max(points, 8))
    m = slip_multiplier(machine, v)
    offset = float(slip_multiplier(machine, np.array([1e-3]))[0])
    if formula is NonlinearFormula.NONE:
        res = 1.0 / m - 1.0
        return NonlinearExtrusionFit(
            fw, 0.0, 0.0, 1.0, None, float(v[0]), v_max, offset,
            float(np.sqrt(np.mean(res ** 2))), float(np.max(np.abs(res))), None,
            f"{fw.label} has no nonlinear extrusion: bake the slip into the G-code "
            "(flowtwin compensate --slip); the residual is the slip left uncorrected")
    if formula is NonlinearFormula.INSTANTANEOUS:
        # m ≈ C + B·v + A·v², C = m(0) (slow moves exact), B and A by least squares on
        # the relative error
        c = offset
        w = 1.0 / m
        design = np.column_stack([v, v * v]) * w[:, None]
        (b, a), *_ = np.linalg.lstsq(design, (m - c) * w, rcond=None)
        fit = NonlinearExtrusionFit(fw, float(a), float(b), float(c), None, float(v[0]),
                                    v_max, offset, 0.0, 0.0, None,
                                    "Marlin with NONLINEAR_EXTRUSION (bugfix-2.1.x: A "
                                    "quadratic, B linear); with it on, do not bake the slip "
                                    "into the G-code as well (no --slip)")
        target = m
    else:
        # m/offset − 1 ≈ A·v + B·v² (the constant part belongs to the E steps / flow)
        target = m / offset
        w = 1.0 / target
        design = np.column_stack([v, v * v]) * w[:, None]
        (a, b), *_ = np.linalg.lstsq(design, (target - 1.0) * w, rcond=None)
        limit = max(RRF_DEFAULT_LIMIT, float(np.max(target - 1.0)) * 1.05)
        fit = NonlinearExtrusionFit(
            fw, float(a), float(b), 1.0, limit, float(v[0]), v_max, offset,
            0.0, 0.0, None,
            f"RepRapFirmware; the constant part ({100 * (offset - 1):.2f} % more E at any "
            "speed) is the E steps' or the flow's (M92 / M221), not M592's; with it on, do "
            "not bake the slip into the G-code as well (no --slip)")
    rel = fit.multiplier(v) / target - 1.0
    fit = replace(fit, rms_residual=float(np.sqrt(np.mean(rel ** 2))),
                  max_residual=float(np.max(np.abs(rel))))
    return replace(fit, command=m592_command(fit))


def m592_command(fit: NonlinearExtrusionFit) -> str | None:
    """The firmware's ``M592`` for the fitted coefficients (``None`` without nonlinear
    extrusion; :func:`flowtwin.firmware.nonlinear.nonlinear_command`)."""
    return nonlinear_command(fit.firmware, fit.a, fit.b, c=fit.c,
                             limit=RRF_DEFAULT_LIMIT if fit.limit is None else fit.limit)


def _feed_max(machine: Machine) -> float:
    """The fastest filament speed worth covering: the printer's E limit, or where the
    feed force reaches 90 % of the roller's maximum."""
    limit = math.inf
    marlin = machine.printer.marlin
    if marlin is not None:
        limit = float(marlin.max_feedrate_mm_s.e)
    op = operating_point(machine, feed_mm_s=1.0, layer_height_mm=machine.setup.layer_height_mm)
    if math.isfinite(op.max_feed_force_n) and op.nominal_force_n > 0:
        limit = min(limit, 0.9 * op.max_feed_force_n / op.nominal_force_n)
    return float(min(limit, 30.0))


def apply_nonlinear_extrusion(table: MoveTable, timeline: Timeline,
                              fit: NonlinearExtrusionFit) -> MoveTable:
    """The moves as the firmware extrudes them with the settings of ``fit``.

    Marlin scales every step of a forward extrusion with XYZ motion by the multiplier at
    the instantaneous requested E speed ``v(t) = r·u(t)`` (``r`` E per path length, ``u``
    the planned path speed, linear in time in every phase): the move's E becomes
    ``∫ m(r·u) r·u dt``, exact per phase (the multiplier is a polynomial). RRF scales a
    printing move's E by the multiplier at its average requested E speed. E-only moves
    (retractions, push-backs) are not scaled. The timing is the plan's (the multiplier
    changes E, not the motion).

    Parameters
    ----------
    table, timeline
        The read and planned G-code.
    fit
        The settings.

    Returns
    -------
    MoveTable
        The same moves with the firmware's E (``de``, and ``e`` accumulated again).
    """
    mv = table.moves.copy()
    de = np.asarray(mv["de"], dtype=np.float64)
    kind = mv["kind"]
    moving = (kind & (MoveKind.XY | MoveKind.Z)) != 0
    fwd = (de > 0) & moving & ((kind & MoveKind.FW_RETRACT) == 0)
    _, ta, tc, td, sv, cv, ev = timeline.trapezoids()
    path = sv * ta + 0.5 * (cv - sv) * ta + cv * tc + cv * td - 0.5 * (cv - ev) * td
    duration = ta + tc + td
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(path > 0, de / path, 0.0)
    new = de.copy()
    formula = nonlinear_formula(fit.firmware)
    if formula is NonlinearFormula.INSTANTANEOUS:
        # ∫ m(v) v dt with m = C + A v² + B v (the max(·, 0) never binds for A, B ≥ 0)
        def moments(v0: FloatArray, v1: FloatArray, t: FloatArray) -> FloatArray:
            # ∫ (C v + B v² + A v³) dt for v linear from v0 to v1 over t
            i1 = 0.5 * (v0 + v1) * t
            i2 = (v0 * v0 + v0 * v1 + v1 * v1) / 3.0 * t
            i3 = (v0 + v1) * (v0 * v0 + v1 * v1) / 4.0 * t
            return fit.c * i1 + fit.b * i2 + fit.a * i3

        r = np.where(fwd, ratio, 0.0)
        total = (moments(r * sv, r * cv, ta) + moments(r * cv, r * cv, tc)
                 + moments(r * cv, r * ev, td))
        new = np.where(fwd, total, de)
    elif formula is NonlinearFormula.MOVE_AVERAGE:
        with np.errstate(divide="ignore", invalid="ignore"):
            v_avg = np.where(duration > 0, de / duration, 0.0)
        new = np.where(fwd, de * fit.multiplier(v_avg), de)
    mv["de"] = new
    tools = np.asarray(mv["tool"], dtype=np.int64)
    e = np.empty(new.size)
    for t in np.unique(tools).tolist():
        sel = tools == t
        e[sel] = np.cumsum(new[sel])
    mv["e"] = e
    return replace(table, moves=mv)
