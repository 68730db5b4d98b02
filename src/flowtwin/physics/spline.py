"""The clamped cubic spline of [004 Eqs. 20–21], written out as in the paper.

[004] interpolates a road through ``m + 1`` points ``(x_i, y_i)`` with known end slopes
``S'(x_0)``, ``S'(x_m)`` (a *clamped* spline) to get the tangent for the nozzle offset. With
``h_i = x_(i+1) − x_i``, ``d_i = (y_(i+1) − y_i)/h_i``, ``u_i = 6(d_i − d_(i−1))`` and the
second derivatives ``m_i = S''(x_i)`` as unknowns, the interior rows are

``h_(i−1)·m_(i−1) + 2(h_(i−1) + h_i)·m_i + h_i·m_(i+1) = u_i``            [004 Eq. 20]

and the clamped ends ``m_0 = 3/h_0·(d_0 − S'(x_0)) − m_1/2``,
``m_m = 3/h_(m−1)·(S'(x_m) − d_(m−1)) − m_(m−1)/2`` are eliminated, which changes the first
row to ``(3h_0/2 + 2h_1)·m_1 + h_1·m_2 = u_1 − 3(d_0 − S'(x_0))`` and the last to
``h_(m−2)·m_(m−2) + (2h_(m−2) + 3h_(m−1)/2)·m_(m−1) = u_(m−1) − 3(S'(x_m) − d_(m−1))``
[004 Eq. 20]. The tridiagonal system is solved for ``m_1 … m_(m−1)``; on ``[x_i, x_(i+1)]``

``S_i(x) = −m_i/(6h_i)·(x_(i+1) − x)³ + m_(i+1)/(6h_i)·(x − x_i)³
+ (y_i/h_i − m_i·h_i/6)·(x_(i+1) − x) + (y_(i+1)/h_i − m_(i+1)·h_i/6)·(x − x_i)``
[004 Eq. 21].

(The first term of Eq. 21 is printed with a minus sign; the standard form, which satisfies
``S(x_i) = y_i``, has ``+m_i/(6h_i)·(x_(i+1) − x)³``. We use the standard form; the test
suite checks interpolation and agreement with ``scipy.interpolate.CubicSpline``.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.linalg import solve_banded

from flowtwin.errors import DataError
from flowtwin.physics._checks import as_float_array

__all__ = ["ClampedSpline", "clamped_spline"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ClampedSpline:
    """A clamped cubic spline in the moment form of [004 Eq. 21].

    Attributes
    ----------
    x
        Strictly increasing knots, shape (m + 1,).
    y
        Values at the knots, shape (m + 1,).
    moments
        Second derivatives ``m_i = S''(x_i)``, shape (m + 1,).
    """

    x: FloatArray
    y: FloatArray
    moments: FloatArray

    def _locate(self, xq: FloatArray
                ) -> tuple[npt.NDArray[np.intp], FloatArray, FloatArray, FloatArray]:
        i = np.clip(np.searchsorted(self.x, xq, side="right") - 1, 0, self.x.size - 2)
        h = self.x[i + 1] - self.x[i]
        return i, h, self.x[i + 1] - xq, xq - self.x[i]

    def __call__(self, x_query: npt.ArrayLike) -> FloatArray:
        """Evaluate ``S(x)`` [004 Eq. 21].

        Parameters
        ----------
        x_query
            Where to evaluate, any shape; outside the knots the end cubics extrapolate.

        Returns
        -------
        ndarray
            ``S(x)``, shape of ``x_query``.
        """
        xq = as_float_array(x_query)
        i, h, right, left = self._locate(xq)
        m0, m1 = self.moments[i], self.moments[i + 1]
        return (m0 / (6.0 * h) * right ** 3 + m1 / (6.0 * h) * left ** 3
                + (self.y[i] / h - m0 * h / 6.0) * right
                + (self.y[i + 1] / h - m1 * h / 6.0) * left)

    def derivative(self, x_query: npt.ArrayLike) -> FloatArray:
        """Evaluate ``S'(x)``, the derivative of [004 Eq. 21] (the road slope ``K_i``).

        Parameters
        ----------
        x_query
            Where to evaluate, any shape.

        Returns
        -------
        ndarray
            ``S'(x)``, shape of ``x_query``.
        """
        xq = as_float_array(x_query)
        i, h, right, left = self._locate(xq)
        m0, m1 = self.moments[i], self.moments[i + 1]
        return (-m0 / (2.0 * h) * right ** 2 + m1 / (2.0 * h) * left ** 2
                - (self.y[i] / h - m0 * h / 6.0) + (self.y[i + 1] / h - m1 * h / 6.0))


def clamped_spline(x: npt.ArrayLike, y: npt.ArrayLike, *, dy_start: float,
                   dy_end: float) -> ClampedSpline:
    """Build the clamped cubic spline of [004 Eq. 20] through ``(x_i, y_i)``.

    Parameters
    ----------
    x
        Knots, strictly increasing, shape (m + 1,), m ≥ 1.
    y
        Values at the knots, shape (m + 1,).
    dy_start, dy_end
        End slopes ``S'(x_0)`` and ``S'(x_m)`` (taken from the road [004]).

    Returns
    -------
    ClampedSpline
        The spline with its moments ``m_0 … m_m``.

    Raises
    ------
    DataError
        If the knots are not strictly increasing, the shapes differ, or values are not finite.
    """
    xs = as_float_array(x)
    ys = as_float_array(y)
    if xs.ndim != 1 or xs.shape != ys.shape or xs.size < 2:
        raise DataError("spline knots and values must be 1-D of equal length >= 2",
                        field="y", value=(xs.shape, ys.shape), allowed="shape (m+1,), m >= 1")
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(ys))
            and np.isfinite(dy_start) and np.isfinite(dy_end)):
        raise DataError("spline data must be finite", field="y")
    h = np.diff(xs)
    if np.any(h <= 0.0):
        raise DataError("spline knots must be strictly increasing", field="x",
                        value=float(np.min(h)), allowed="x[i+1] - x[i] > 0")
    d = np.diff(ys) / h
    m = xs.size - 1
    moments = np.empty(m + 1)
    if m == 1:
        # No interior row: the two clamped end conditions alone,
        # 2h·m0 + h·m1 = 6(d0 − S'0) and h·m0 + 2h·m1 = 6(S'1 − d0).
        rhs = np.array([6.0 * (d[0] - dy_start), 6.0 * (dy_end - d[0])]) / h[0]
        moments[:] = np.linalg.solve(np.array([[2.0, 1.0], [1.0, 2.0]]), rhs)
        return ClampedSpline(xs, ys, moments)
    u = 6.0 * (d[1:] - d[:-1])                     # u_1 … u_(m−1)
    diag = 2.0 * (h[:-1] + h[1:])                  # 2(h_(i−1) + h_i), i = 1 … m−1
    diag[0] -= h[0] / 2.0                          # → 3h_0/2 + 2h_1          [Eq. 20]
    diag[-1] -= h[-1] / 2.0                        # → 2h_(m−2) + 3h_(m−1)/2  [Eq. 20]
    rhs = u.copy()
    rhs[0] -= 3.0 * (d[0] - dy_start)
    rhs[-1] -= 3.0 * (dy_end - d[-1])
    bands = np.zeros((3, m - 1))
    bands[0, 1:] = h[1:-1]                         # super-diagonal h_i
    bands[1] = diag
    bands[2, :-1] = h[1:-1]                        # sub-diagonal h_(i−1)
    moments[1:-1] = solve_banded((1, 1), bands, rhs)
    moments[0] = 3.0 / h[0] * (d[0] - dy_start) - moments[1] / 2.0
    moments[-1] = 3.0 / h[-1] * (dy_end - d[-1]) - moments[-2] / 2.0
    return ClampedSpline(xs, ys, moments)
