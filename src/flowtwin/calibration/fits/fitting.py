"""Least-squares helpers shared by the fits: parameters with standard errors.

``fit_curve`` wraps :func:`scipy.optimize.curve_fit` and turns what would be junk numbers
into a :class:`~flowtwin.errors.CalibrationError` with a reason: too few points for the
number of parameters, a singular or infinite covariance (the data do not determine the
parameters separately), or a parameter not distinguished from zero. Uncertainties are
1σ standard errors from the covariance scaled by the residual variance
(``absolute_sigma=False``: the noise level is estimated from the scatter, which is what a
user's measurements give).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import OptimizeWarning, curve_fit

from flowtwin.errors import CalibrationError

__all__ = ["CurveFit", "fit_curve", "propagate_std"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CurveFit:
    """Parameters of a least-squares fit with their covariance.

    Attributes
    ----------
    names
        Parameter names, in order.
    values
        Best estimates, shape ``(p,)``.
    covariance
        Covariance, shape ``(p, p)``.
    residuals
        ``y − f(x)`` at the optimum, shape ``(n,)``.
    """

    names: tuple[str, ...]
    values: FloatArray
    covariance: FloatArray
    residuals: FloatArray

    @property
    def stderr(self) -> FloatArray:
        """1σ standard errors, shape ``(p,)``."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def rms(self) -> float:
        """Root-mean-square residual."""
        return float(np.sqrt(np.mean(self.residuals ** 2)))

    def as_dict(self) -> dict[str, float]:
        """Name → value."""
        return dict(zip(self.names, self.values.tolist(), strict=True))


def fit_curve(model: Callable[..., FloatArray], x: FloatArray, y: FloatArray,
              start: Sequence[float], *, names: Sequence[str], what: str,
              max_relative_error: float = 1.0,
              bounds: tuple[Sequence[float], Sequence[float]] | None = None) -> CurveFit:
    """Fit ``y ≈ model(x, *p)`` and check that every parameter is determined.

    Parameters
    ----------
    model
        ``model(x, *params) -> y``.
    x, y
        Data, shape ``(n,)``.
    start
        Initial parameters, shape ``(p,)``.
    names
        Parameter names (for messages), length ``p``.
    what
        What is being fitted (for messages), e.g. ``"exponential viscosity law"``.
    max_relative_error
        A parameter whose standard error exceeds this fraction of its value is
        "not determined by the data" (1: not distinguished from zero at 1σ).
    bounds
        Optional ``(lower, upper)`` parameter bounds (trust-region fit); a parameter that
        ends on a bound is reported as undetermined.

    Returns
    -------
    CurveFit

    Raises
    ------
    CalibrationError
        Too few points, no convergence, a singular covariance or an undetermined
        parameter (the message says which and why).
    """
    p = len(start)
    n = int(x.shape[0])
    if n <= p:
        raise CalibrationError(f"the {what} has {p} parameters: it needs at least {p + 1} "
                               "points to estimate them and their uncertainty",
                               field="rows", value=n, allowed=f">= {p + 1} points")
    with warnings.catch_warnings():
        warnings.simplefilter("error", OptimizeWarning)
        try:
            if bounds is None:
                values, cov = curve_fit(model, x, y, p0=np.asarray(start, dtype=np.float64),
                                        maxfev=20000)
            else:
                values, cov = curve_fit(model, x, y, p0=np.asarray(start, dtype=np.float64),
                                        bounds=bounds, max_nfev=20000)
        except OptimizeWarning as exc:
            raise CalibrationError(f"the {what} is degenerate: {exc} (the data do not "
                                   "determine the parameters separately)",
                                   field=",".join(names)) from exc
        except RuntimeError as exc:
            raise CalibrationError(f"the {what} did not converge: {exc}",
                                   field=",".join(names)) from exc
    values = np.asarray(values, dtype=np.float64)
    cov = np.asarray(cov, dtype=np.float64)
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(cov))):
        raise CalibrationError(f"the {what} is degenerate: its covariance is not finite "
                               "(the data do not determine the parameters separately)",
                               field=",".join(names))
    if bounds is not None:
        for name, value, lo, hi in zip(names, values.tolist(), bounds[0], bounds[1],
                                       strict=True):
            if np.isclose(value, lo, rtol=1e-9, atol=0.0) or \
                    np.isclose(value, hi, rtol=1e-9, atol=0.0):
                raise CalibrationError(f"the {what} ends on the bound of {name} "
                                       f"({value:.4g}): the data do not determine it",
                                       field=name, value=value, allowed=f"({lo:g}, {hi:g})")
    residuals = y - model(x, *values)
    fit = CurveFit(tuple(names), values, cov, np.asarray(residuals, dtype=np.float64))
    for name, value, err in zip(names, values.tolist(), fit.stderr.tolist(), strict=True):
        if not err <= max_relative_error * abs(value):
            raise CalibrationError(
                f"the {what} does not determine {name}: {value:.4g} ± {err:.2g} "
                "(measure over a wider range or with less scatter)", field=name,
                value=value, allowed=f"standard error <= {max_relative_error:g}·|value|")
    return fit


def propagate_std(jacobian: FloatArray, covariance: FloatArray) -> float:
    """Standard deviation of ``g(p)`` from its gradient ``∂g/∂p`` (delta method)."""
    j = np.asarray(jacobian, dtype=np.float64)
    return float(np.sqrt(max(float(j @ covariance @ j), 0.0)))
