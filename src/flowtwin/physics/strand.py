"""Shape of the strand between nozzle and bed: tractrix, parabola, catenary [004].

Coordinates of [004 Fig. 2]: the nozzle exit is at ``x = 0, z = H`` (``H`` = nozzle height
above the layer below), the strand trails behind the nozzle towards ``+x`` and meets the bed
(``z = 0``) at a distance ``L`` (parabola, catenary) or asymptotically (tractrix).

* Tractrix [004 Eq. 5]: ``x = −sqrt(H² − z²) + H·ln((H + sqrt(H² − z²))/z)``, ``0 < z ≤ H``.
  With ``z = H·sech t`` it is ``x = H·(t − tanh t)`` (used to invert it for ``z(x)``). Its
  tangent from any point to the ``z`` axis has the constant length ``H`` (Eq. 1–4; Eq. 4's
  ``r`` and ``C`` are the free parameters of the general form ``x = …(r)… + C``).
* Parabola [004 Eq. 6]: ``z = H/L²·(x − L)²`` (axis ``x = L``, passes ``(0, H)``).
* Catenary [004 Eq. 7] under "the same assumptions": ``z = a·cosh((x − L)/b) + c``. The
  constant printed in Eq. 7, ``1 − H``, is dimensionally inconsistent (it adds 1 mm to a
  0.012 mm height) and cannot pass ``(0, H)`` with a bed-touching minimum; we take
  ``c = H − a·cosh(L/b)`` so the curve passes ``(0, H)`` like the parabola, and fit ``a``,
  ``b`` (and ``L``) to the measured points as [004] does.

Outside ``0 ≤ x ≤ L`` the parabola and catenary are continued physically: ``z = H`` ahead
of the nozzle and ``z = 0`` on the bed behind ``L``. [004 Fig. 3] finds the tractrix the best
fit of a measured strand; :func:`fit_strand_profile` fits any of the three by least squares
(``scipy.optimize.least_squares``) and reports the RMS residual so the models can be ranked.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
import numpy.typing as npt

from flowtwin.errors import CalibrationError, DataError
from flowtwin.physics._checks import as_float_array, require_positive

__all__ = [
    "StrandFit",
    "StrandModel",
    "catenary_z_mm",
    "fit_strand_profile",
    "parabola_z_mm",
    "tractrix_contact_length_mm",
    "tractrix_x_mm",
    "tractrix_z_mm",
]

FloatArray = npt.NDArray[np.float64]


def tractrix_x_mm(z_mm: npt.ArrayLike, height_mm: npt.ArrayLike) -> FloatArray:
    """Tractrix ``x = −sqrt(H² − z²) + H·ln((H + sqrt(H² − z²))/z)`` [004 Eq. 5].

    Parameters
    ----------
    z_mm
        Height above the bed, mm, in ``(0, H]``, any shape.
    height_mm
        Nozzle height ``H`` (the tangent length), mm (> 0).

    Returns
    -------
    ndarray
        Distance behind the nozzle, mm (0 at ``z = H``, → ∞ as ``z → 0``).

    Raises
    ------
    DataError
        If a ``z`` lies outside ``(0, H]``.
    """
    h = require_positive("height_mm", height_mm)
    z = as_float_array(z_mm)
    if np.any(~(z > 0.0)) or np.any(z > h * (1.0 + 1e-12)):
        raise DataError("the tractrix is defined for 0 < z <= H", field="z_mm",
                        value=z.tolist() if z.ndim else float(z), allowed="0 < z <= H")
    root = np.sqrt(np.maximum(h * h - z * z, 0.0))
    return -root + h * np.log((h + root) / z)


def _tractrix_t(u: FloatArray) -> FloatArray:
    """Solve ``t − tanh t = u`` (u ≥ 0) for t ≥ 0 by bisection and a Newton polish."""
    lo = np.zeros_like(u)
    hi = u + 1.0 + np.cbrt(3.0 * u)  # t − tanh t ≥ t − 1 and the bracket is generous
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        above = mid - np.tanh(mid) > u
        hi = np.where(above, mid, hi)
        lo = np.where(above, lo, mid)
    t = 0.5 * (lo + hi)
    for _ in range(2):
        slope = np.tanh(t) ** 2
        step = np.where(slope > 1e-12, (t - np.tanh(t) - u) / np.maximum(slope, 1e-300), 0.0)
        t = np.clip(t - step, lo, hi)
    return t


def tractrix_z_mm(x_mm: npt.ArrayLike, height_mm: npt.ArrayLike) -> FloatArray:
    """Height of the tractrix strand at distance ``x`` behind the nozzle [004 Eq. 5 inverted].

    Uses ``x = H·(t − tanh t)``, ``z = H·sech t`` (equivalent to Eq. 5). Ahead of the nozzle
    (``x < 0``) the strand is at the nozzle exit, ``z = H``.

    Parameters
    ----------
    x_mm
        Distance behind the nozzle, mm, any shape.
    height_mm
        ``H``, mm (> 0), scalar.

    Returns
    -------
    ndarray
        ``z`` in ``(0, H]``, mm, shape of ``x_mm``.
    """
    h = float(require_positive("height_mm", height_mm))
    u = np.maximum(as_float_array(x_mm), 0.0) / h
    return h / np.cosh(_tractrix_t(np.atleast_1d(u))).reshape(u.shape)


def tractrix_contact_length_mm(height_mm: npt.ArrayLike, *,
                               z_fraction: float = 0.005) -> FloatArray:
    """Distance behind the nozzle where the tractrix has sunk to ``z_fraction·H``.

    The tractrix reaches the bed only asymptotically; ``L = H·(t − tanh t)`` with
    ``t = arccosh(1/z_fraction)``. For ``z_fraction = 0.005`` this is ``4.99·H``, i.e.
    0.060 mm for ``H = 0.012`` mm — the ``L`` that [004] pairs with that ``H`` in Fig. 7.

    Parameters
    ----------
    height_mm
        ``H``, mm (> 0), any shape.
    z_fraction
        Remaining height as a fraction of ``H``, in (0, 1).

    Returns
    -------
    ndarray
        ``L``, mm, shape of ``height_mm``.
    """
    h = require_positive("height_mm", height_mm)
    frac = float(require_positive("z_fraction", z_fraction))
    if frac >= 1.0:
        raise DataError("z_fraction must lie in (0, 1)", field="z_fraction", value=frac,
                        allowed="(0, 1)")
    t = np.arccosh(1.0 / frac)
    return h * (t - np.tanh(t))


def parabola_z_mm(x_mm: npt.ArrayLike, height_mm: float, length_mm: float) -> FloatArray:
    """Parabola strand ``z = H/L²·(x − L)²`` on ``0 ≤ x ≤ L`` [004 Eq. 6].

    Continued as ``z = H`` for ``x < 0`` and ``z = 0`` (on the bed) for ``x > L``.

    Parameters
    ----------
    x_mm
        Distance behind the nozzle, mm, any shape.
    height_mm
        ``H``, mm (> 0).
    length_mm
        ``L``, where the strand touches the bed, mm (> 0).

    Returns
    -------
    ndarray
        ``z``, mm, shape of ``x_mm``.
    """
    h = require_positive("height_mm", height_mm)
    length = require_positive("length_mm", length_mm)
    x = np.clip(as_float_array(x_mm), 0.0, length)
    return h / (length * length) * (x - length) ** 2


def catenary_z_mm(x_mm: npt.ArrayLike, *, a_mm: float, b_mm: float, length_mm: float,
                  height_mm: float) -> FloatArray:
    """Catenary strand ``z = a·cosh((x − L)/b) + c`` with ``c = H − a·cosh(L/b)`` [004 Eq. 7].

    See the module docstring for the constant ``c`` (Eq. 7 prints ``1 − H``). Defined on
    ``0 ≤ x ≤ L``; ``z = H`` ahead of the nozzle, and ``z`` stays at its value at ``L``
    behind ``L``.

    Parameters
    ----------
    x_mm
        Distance behind the nozzle, mm, any shape.
    a_mm
        ``a``, mm (> 0).
    b_mm
        ``b``, mm (> 0).
    length_mm
        ``L``, the axis of the catenary, mm (> 0).
    height_mm
        ``H``, mm (> 0).

    Returns
    -------
    ndarray
        ``z``, mm, shape of ``x_mm``.
    """
    a = require_positive("a_mm", a_mm)
    b = require_positive("b_mm", b_mm)
    length = require_positive("length_mm", length_mm)
    h = require_positive("height_mm", height_mm)
    x = np.clip(as_float_array(x_mm), 0.0, length)
    return a * np.cosh((x - length) / b) + (h - a * np.cosh(length / b))


class StrandModel(Enum):
    """The strand curves of [004]."""

    TRACTRIX = "tractrix"
    PARABOLA = "parabola"
    CATENARY = "catenary"


@dataclass(frozen=True)
class StrandFit:
    """Result of :func:`fit_strand_profile`.

    Attributes
    ----------
    model
        The fitted curve.
    params
        Fitted parameters, mm: tractrix ``r_mm``, ``shift_mm`` (Eq. 4's ``r`` and ``C``);
        parabola ``length_mm``; catenary ``a_mm``, ``b_mm``, ``length_mm``.
    rms_mm
        Root-mean-square residual in ``z``, mm.
    height_mm
        The nozzle height ``H`` the fit used, mm.
    """

    model: StrandModel
    params: dict[str, float]
    rms_mm: float
    height_mm: float

    def z_mm(self, x_mm: npt.ArrayLike) -> FloatArray:
        """Evaluate the fitted curve.

        Parameters
        ----------
        x_mm
            Distance behind the nozzle, mm, any shape.

        Returns
        -------
        ndarray
            ``z``, mm, shape of ``x_mm``.
        """
        return _evaluate(self.model, self.params, as_float_array(x_mm), self.height_mm)


_PARAM_NAMES = {
    StrandModel.TRACTRIX: ("r_mm", "shift_mm"),
    StrandModel.PARABOLA: ("length_mm",),
    StrandModel.CATENARY: ("a_mm", "b_mm", "length_mm"),
}


def _evaluate(model: StrandModel, params: dict[str, float], x: FloatArray,
              height_mm: float) -> FloatArray:
    if model is StrandModel.TRACTRIX:
        return tractrix_z_mm(x - params["shift_mm"], params["r_mm"])
    if model is StrandModel.PARABOLA:
        return parabola_z_mm(x, height_mm, params["length_mm"])
    return catenary_z_mm(x, a_mm=params["a_mm"], b_mm=params["b_mm"],
                         length_mm=params["length_mm"], height_mm=height_mm)


def fit_strand_profile(x_mm: npt.ArrayLike, z_mm: npt.ArrayLike, *, model: StrandModel,
                       height_mm: float) -> StrandFit:
    """Least-squares fit of a strand curve of [004] to a measured profile ``z(x)``.

    Parameters
    ----------
    x_mm
        Distances behind the nozzle of the measured points, mm, shape (n,).
    z_mm
        Measured heights, mm, shape (n,).
    model
        Which curve to fit.
    height_mm
        Nozzle height ``H`` (the layer height in [004]'s measurement), mm (> 0). It fixes
        the parabola and catenary at ``(0, H)`` and starts the tractrix's ``r``. The bed
        contact ``L`` of the parabola and catenary is searched in ``(0, max(x)]``: the
        measured profile must reach the bed.

    Returns
    -------
    StrandFit
        Parameters and RMS residual in ``z``.

    Raises
    ------
    DataError
        If the profile is empty, not 1-D, of unequal lengths or not finite.
    CalibrationError
        If the optimiser does not converge (the reason is in the message).
    """
    x = as_float_array(x_mm)
    z = as_float_array(z_mm)
    if x.ndim != 1 or x.shape != z.shape or x.size < 3:
        raise DataError("a strand profile needs two 1-D arrays of equal length >= 3",
                        field="z_mm", value=(x.shape, z.shape), allowed="shape (n,), n >= 3")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(z))):
        raise DataError("the strand profile contains non-finite values", field="z_mm")
    h = float(require_positive("height_mm", height_mm))
    x_max = float(np.max(x))
    if not x_max > 0.0:
        raise DataError("the strand profile must reach behind the nozzle (some x > 0)",
                        field="x_mm", value=x_max, allowed="max(x) > 0")
    names = _PARAM_NAMES[model]
    # Positive parameters are fitted as logarithms (scale-free, and a → 0 / b → ∞ valleys
    # of the catenary stay well conditioned); the bed contact L must lie inside the
    # measured profile, 0 < L <= max(x). The tractrix's shift C is fitted directly.
    if model is StrandModel.TRACTRIX:
        start = np.array([np.log(h), 0.0])
        lower = np.array([np.log(1e-3 * h), -x_max])
        upper = np.array([np.log(1e3 * h), x_max])
        positive = np.array([True, False])
    elif model is StrandModel.PARABOLA:
        start = np.array([np.log(0.5 * x_max)])
        lower, upper = np.array([np.log(1e-3 * x_max)]), np.array([np.log(x_max)])
        positive = np.array([True])
    else:
        start = np.log([h, 0.5 * x_max, 0.5 * x_max])
        lower = np.log([1e-9 * h, 1e-4 * x_max, 1e-3 * x_max])
        upper = np.log([1e3 * h, 1e3 * x_max, x_max])
        positive = np.array([True, True, True])

    def unpack(p: FloatArray) -> dict[str, float]:
        return dict(zip(names, np.where(positive, np.exp(p), p).tolist(), strict=True))

    def residual(p: FloatArray) -> FloatArray:
        return _evaluate(model, unpack(p), x, h) - z

    from scipy.optimize import least_squares  # (0.3 s to import: only for a fit)

    with np.errstate(over="ignore", invalid="ignore"):
        result = least_squares(residual, start, bounds=(lower, upper), xtol=1e-12,
                               ftol=1e-12, gtol=1e-12, max_nfev=2000)
    if not result.success:
        raise CalibrationError(f"the {model.value} fit did not converge: {result.message}",
                               field="z_mm")
    params = unpack(result.x)
    rms = float(np.sqrt(np.mean(result.fun ** 2)))
    return StrandFit(model, params, rms, h)
