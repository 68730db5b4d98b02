"""Fits over many test-stand records: Eq. 6, Eq. 8, Eq. 9 and the maximum feed force [000].

From the per-record results (:mod:`flowtwin.teststand.analysis`):

* :func:`fit_pinch_law` — ``s' = k_s/F_p² + k_∞`` [000 Eq. 6] over the set pinch forces
  (linear least squares in ``(k_s, k_∞)``); ``F_p,min = sqrt(k_s/(0.1·k_∞))`` [000 Eq. 9]
  with its propagated uncertainty.
* :func:`fit_velocity_law` — ``s' = a + b·exp(−c·v)`` [000 Eq. 8] over the set feed
  velocities for pinch forces of 80–130 N (variable projection: linear in ``a, b`` for a
  given ``c``, profiled over ``c``). The exponential
  is kept only if it explains significantly more than a constant (F-test) and its
  parameters are identifiable; otherwise the law is ``s' = a`` and the reason is stated —
  as for rollers #6 and #7 of [000], whose Table 3 rows read ``b, c → ∞`` / ``b → 0``.
* :func:`fit_max_feed_force` — the 2nd-order polynomial of the per-record maxima over the
  pinch force [000 Figs. 4–8].

Averaging and weighting. Like [000 Fig. 11] ("the average slip gradient ... for pinch
forces from 80 N to 130 N") the slip laws are fitted to *balanced means*: for Eq. 8 the
records of each feed velocity are averaged with equal weight per pinch force (and per
repeat), for Eq. 6 the records of each pinch force with equal weight per feed velocity. The
means are then fitted by weighted least squares, each weighted by the inverse variance
propagated from the records' regression standard errors. Balancing keeps a velocity
dependence from leaking into ``k_∞`` (every pinch force sees the same speeds) and weighting
keeps the noisy means from dominating: the precision of a record's ``s'`` differs by orders
of magnitude across the grid (at 0.5 mm/s the encoder noise is 5 % of slip per sample, at
15 mm/s 0.17 %; at 10 N pinch force a roller may feed only 5–10 N, at 100 N ~100 N), and
unweighted per-record fits of roller #6's ``k_s`` on the virtual stand scattered by up to
8 % between seeds, the balanced weighted means by 0.3 % (standard deviation, six seeds).

The maximum-force fit is ordinary least squares over records (a record's maximum has no
own error estimate) with the heteroscedasticity-robust
HC3 covariance (MacKinnon & White 1985): the scatter of the maxima grows with the force
("maximum fluctuations of 25 N" at the high end [000 §4.1]), so the classical covariance
would understate the uncertainty of the curve where it matters. Slip-law uncertainties are
one standard error from the covariance, scaled by the reduced χ² of the residuals when
that exceeds 1 (scatter beyond the records' own noise, e.g. a law that does not hold
exactly). A fit the data cannot determine raises
:class:`~flowtwin.errors.CalibrationError` with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import stats
from scipy.optimize import minimize_scalar

from flowtwin.errors import CalibrationError
from flowtwin.physics.drive import max_feed_force_n, min_pinch_force_n
from flowtwin.teststand.analysis import RecordResult

__all__ = [
    "MaxForceFit",
    "PinchLawFit",
    "VelocityLawFit",
    "fit_max_feed_force",
    "fit_pinch_law",
    "fit_velocity_law",
    "r_squared_histogram",
]

FloatArray = npt.NDArray[np.float64]


def _select(results: Sequence[RecordResult], pinch_range_n: tuple[float, float] | None, *,
            need_slip: bool) -> list[RecordResult]:
    lo, hi = pinch_range_n if pinch_range_n is not None else (-math.inf, math.inf)
    return [r for r in results if lo <= r.key.pinch_force_set_n <= hi
            and (r.slip is not None or not need_slip)]


def _linear_fit(design: FloatArray, y: FloatArray,
                sigma: FloatArray | None = None) -> tuple[FloatArray, FloatArray, float]:
    """(Weighted) least squares: parameters, covariance, RMS residual of y.

    Unweighted: the covariance is scaled by the residual variance. Weighted: it is the
    propagated covariance, scaled by the reduced χ² when that exceeds 1.
    """
    w = np.ones_like(y) if sigma is None else 1.0 / sigma
    coef = np.asarray(np.linalg.lstsq(design * w[:, None], y * w, rcond=None)[0],
                      dtype=np.float64)
    n, p = design.shape
    resid = y - design @ coef
    chi2_red = float(((resid * w) ** 2).sum()) / (n - p)
    scale = chi2_red if sigma is None else max(chi2_red, 1.0)
    weighted = design * w[:, None]
    cov = np.asarray(scale * np.linalg.inv(weighted.T @ weighted), dtype=np.float64)
    return coef, cov, math.sqrt(float(resid @ resid) / n)


def _hc3_covariance(design: FloatArray, resid: FloatArray) -> FloatArray:
    """Heteroscedasticity-robust HC3 covariance of OLS coefficients (MacKinnon & White).

    ``(XᵀX)⁻¹ Xᵀ diag(e_i²/(1 − h_i)²) X (XᵀX)⁻¹`` with ``h_i`` the leverages.
    """
    xtx_inv = np.linalg.inv(design.T @ design)
    leverage = np.einsum("ij,jk,ik->i", design, xtx_inv, design)
    scaled = resid / np.clip(1.0 - leverage, 1e-12, None)
    meat = (design * (scaled * scaled)[:, None]).T @ design
    return np.asarray(xtx_inv @ meat @ xtx_inv, dtype=np.float64)


def _balanced_means(sel: Sequence[RecordResult], *, by_speed: bool
                    ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Group records by speed (or pinch force), average with equal weight per other key.

    Returns the group values, the balanced means of ``s'`` and their standard errors
    propagated from the records' regression standard errors.
    """
    groups: dict[float, dict[float, list[tuple[float, float]]]] = {}
    for r in sel:
        assert r.slip is not None  # _select(need_slip=True)
        k = r.key
        outer, inner = ((k.nominal_speed_mm_s, k.pinch_force_set_n) if by_speed
                        else (k.pinch_force_set_n, k.nominal_speed_mm_s))
        groups.setdefault(outer, {}).setdefault(inner, []).append(
            (r.slip.gradient_per_n, r.slip.stderr_per_n))
    xs, means, sigmas = [], [], []
    for outer in sorted(groups):
        cell_means, cell_vars = [], []
        for cell in groups[outer].values():
            g = np.array(cell)
            cell_means.append(float(g[:, 0].mean()))
            cell_vars.append(float((g[:, 1] ** 2).sum()) / len(cell) ** 2)
        xs.append(outer)
        means.append(float(np.mean(cell_means)))
        sigmas.append(math.sqrt(sum(cell_vars)) / len(cell_means))
    sig = np.array(sigmas)
    if not np.all(np.isfinite(sig) & (sig > 0.0)):
        raise CalibrationError("a slip gradient has no positive standard error, so the means "
                               "cannot be weighted", field="slip", value=sigmas,
                               allowed="records with a noisy (real) regression")
    return np.array(xs), np.array(means), sig


@dataclass(frozen=True)
class PinchLawFit:
    """``s' = k_s/F_p² + k_∞`` [000 Eq. 6] fitted over the pinch force.

    Attributes
    ----------
    k_s_n, k_s_err_n
        ``k_s`` and its standard error, fraction·N (×100 for Table 3's %·N).
    k_inf_per_n, k_inf_err_per_n
        ``k_∞`` and its standard error, fraction/N (×100 for %/N).
    covariance
        Covariance of ``(k_s, k_∞)``, shape (2, 2).
    n_points
        Records used.
    pinch_forces_n
        Distinct set pinch forces used, N.
    rms_residual_per_n
        RMS residual of the per-pinch-force means of ``s'``, 1/N.
    """

    k_s_n: float
    k_s_err_n: float
    k_inf_per_n: float
    k_inf_err_per_n: float
    covariance: FloatArray
    n_points: int
    pinch_forces_n: tuple[float, ...]
    rms_residual_per_n: float

    @property
    def fp_min_n(self) -> float:
        """``F_p,min = sqrt(k_s/(0.1·k_∞))`` [000 Eq. 9], N (nan if ``k_s``, ``k_∞`` ≤ 0)."""
        if self.k_s_n <= 0.0 or self.k_inf_per_n <= 0.0:
            return math.nan
        return float(min_pinch_force_n(self.k_s_n, self.k_inf_per_n))

    @property
    def fp_min_err_n(self) -> float:
        """Standard error of :attr:`fp_min_n` by linear propagation of the covariance, N."""
        f = self.fp_min_n
        if not math.isfinite(f):
            return math.nan
        jac = np.array([f / (2.0 * self.k_s_n), -f / (2.0 * self.k_inf_per_n)])
        return math.sqrt(float(jac @ self.covariance @ jac))

    def gradient_per_n(self, pinch_force_n: npt.ArrayLike) -> FloatArray:
        """Fitted ``s'`` at the given pinch forces, 1/N (any shape)."""
        fp = np.asarray(pinch_force_n, dtype=np.float64)
        return self.k_s_n / (fp * fp) + self.k_inf_per_n


def fit_pinch_law(results: Sequence[RecordResult], *,
                  pinch_range_n: tuple[float, float] | None = None) -> PinchLawFit:
    """Fit ``s' = k_s/F_p² + k_∞`` [000 Eq. 6] to per-record slip gradients.

    Parameters
    ----------
    results
        Per-record results; those with a slip regression are averaged per set pinch
        force (balanced over speeds, module docstring) and the means fitted.
    pinch_range_n
        ``(low, high)`` set pinch forces to use, N (inclusive); ``None``: all.

    Returns
    -------
    PinchLawFit

    Raises
    ------
    CalibrationError
        Fewer than three distinct pinch forces: ``k_s`` and ``k_∞`` and their
        uncertainties cannot be determined.
    """
    sel = _select(results, pinch_range_n, need_slip=True)
    distinct = tuple(sorted({r.key.pinch_force_set_n for r in sel}))
    if len(distinct) < 3:
        raise CalibrationError("the pinch-force law [000 Eq. 6] needs slip gradients at three "
                               "or more pinch forces", field="pinch_force_set_n",
                               value=list(distinct), allowed=">= 3 distinct pinch forces")
    fp, y, sigma = _balanced_means(sel, by_speed=False)
    design = np.column_stack([1.0 / (fp * fp), np.ones_like(fp)])
    coef, cov, rms = _linear_fit(design, y, sigma)
    return PinchLawFit(k_s_n=float(coef[0]), k_s_err_n=math.sqrt(cov[0, 0]),
                       k_inf_per_n=float(coef[1]), k_inf_err_per_n=math.sqrt(cov[1, 1]),
                       covariance=cov, n_points=len(sel), pinch_forces_n=distinct,
                       rms_residual_per_n=rms)


@dataclass(frozen=True)
class VelocityLawFit:
    """``s' = a + b·exp(−c·v)`` [000 Eq. 8] over the feed velocity (80–130 N).

    Attributes
    ----------
    velocity_dependent
        True if the exponential term is significant and identifiable; else ``s' = a``.
    a_per_n, a_err_per_n
        ``a`` and its standard error, fraction/N (the mean ``s'`` when not velocity
        dependent).
    b_per_n, b_err_per_n
        ``b`` and its standard error, fraction/N (``None`` when not velocity dependent).
    c_s_per_mm, c_err_s_per_mm
        ``c`` and its standard error, s/mm (``None`` when not velocity dependent).
    p_value
        F-test of the exponential against the constant (``nan`` if not tested).
    reason
        Why the law is, or is not, velocity dependent.
    n_points
        Records used.
    speeds_mm_s
        Distinct set speeds used, mm/s.
    pinch_range_n
        Pinch-force range the records came from, N.
    rms_residual_per_n
        RMS residual of the per-speed means of ``s'`` of the chosen law, 1/N.
    """

    velocity_dependent: bool
    a_per_n: float
    a_err_per_n: float
    b_per_n: float | None
    b_err_per_n: float | None
    c_s_per_mm: float | None
    c_err_s_per_mm: float | None
    p_value: float
    reason: str
    n_points: int
    speeds_mm_s: tuple[float, ...]
    pinch_range_n: tuple[float, float]
    rms_residual_per_n: float

    def gradient_per_n(self, speed_mm_s: npt.ArrayLike) -> FloatArray:
        """Fitted ``s'`` at the given feed velocities, 1/N (any shape)."""
        v = np.asarray(speed_mm_s, dtype=np.float64)
        if not self.velocity_dependent:
            return np.full_like(v, self.a_per_n)
        assert self.b_per_n is not None and self.c_s_per_mm is not None
        return self.a_per_n + self.b_per_n * np.exp(-self.c_s_per_mm * v)


def _exp_law(v: FloatArray, a: float, b: float, c: float) -> FloatArray:
    return np.asarray(a + b * np.exp(-c * v), dtype=np.float64)


def fit_velocity_law(results: Sequence[RecordResult], *,
                     pinch_range_n: tuple[float, float] = (80.0, 130.0),
                     significance: float = 0.01, max_c_s_per_mm: float = 50.0) -> VelocityLawFit:
    """Fit ``s' = a + b·exp(−c·v_fil)`` [000 Eq. 8] to per-record slip gradients.

    Parameters
    ----------
    results
        Per-record results; those with a slip regression and a set pinch force in
        ``pinch_range_n`` are averaged per set speed (balanced over pinch forces, module
        docstring) and the means fitted.
    pinch_range_n
        ``(low, high)`` set pinch forces, N, inclusive ([000]: 80–130 N).
    significance
        Largest F-test p-value at which the exponential term counts as real.
    max_c_s_per_mm
        Upper bound of ``c``, s/mm; a fit at the bound means the term has vanished at every
        measured speed (``c → ∞``).

    Returns
    -------
    VelocityLawFit

    Raises
    ------
    CalibrationError
        Fewer than two records in the pinch-force range.
    """
    sel = _select(results, pinch_range_n, need_slip=True)
    if len(sel) < 2:
        raise CalibrationError("the velocity law [000 Eq. 8] needs two or more records with a "
                               f"pinch force in {pinch_range_n[0]:g}-{pinch_range_n[1]:g} N",
                               field="pinch_force_set_n", value=len(sel),
                               allowed=">= 2 records in the range")
    n_records = len(sel)
    v, y, sigma = _balanced_means(sel, by_speed=True)
    w2 = 1.0 / (sigma * sigma)
    speeds = tuple(v.tolist())
    n = y.size
    a0 = float((w2 * y).sum() / w2.sum())
    sse0 = float((w2 * (y - a0) ** 2).sum())
    a0_err = math.sqrt(max(sse0 / (n - 1), 1.0) / float(w2.sum())) if n > 1 else \
        math.sqrt(1.0 / float(w2.sum()))
    const = VelocityLawFit(False, a0, a0_err, None, None, None, None, math.nan, "", n_records,
                           speeds, pinch_range_n, math.sqrt(float(((y - a0) ** 2).mean())))
    if n < 4:
        return _with_reason(const, "fewer than 4 distinct speeds: only s' = a can be fitted")
    best = _fit_exponential(v, y, sigma, max_c_s_per_mm)
    if best is None:
        return _with_reason(const, "the exponential fit is singular at every decay c")
    sse1, popt, pcov = best
    dof = n - 3
    if sse1 <= 0.0:
        return _with_reason(const, "the exponential passes exactly through the means: no "
                                   "residual to test it against")
    f_stat = ((sse0 - sse1) / 2.0) / (sse1 / dof)
    p_value = float(stats.f.sf(f_stat, 2, dof))
    a, b, c = (float(x) for x in popt)
    pcov = pcov * max(sse1 / dof, 1.0)
    errs = np.sqrt(np.diag(pcov)) if np.all(np.isfinite(pcov)) else np.full(3, np.inf)
    if p_value >= significance:
        return _with_reason(const, f"the exponential term is not significant (F-test p = "
                                   f"{p_value:.3g} >= {significance:g})", p_value)
    if c >= 0.999 * max_c_s_per_mm:
        return _with_reason(const, "c -> infinity: the exponential term has vanished at every "
                                   "measured speed", p_value)
    if not (np.all(np.isfinite(errs)) and errs[1] < abs(b) and errs[2] < c):
        return _with_reason(const, "b and c are not identifiable (standard error larger than "
                                   "the value)", p_value)
    rms = math.sqrt(float(((y - _exp_law(v, a, b, c)) ** 2).mean()))
    return VelocityLawFit(True, a, float(errs[0]), b, float(errs[1]), c, float(errs[2]),
                          p_value, f"exponential term significant (F-test p = {p_value:.3g})",
                          n_records, speeds, pinch_range_n, rms)


def _fit_exponential(v: FloatArray, y: FloatArray, sigma: FloatArray,
                     max_c: float) -> tuple[float, FloatArray, FloatArray] | None:
    """Weighted fit of ``a + b·exp(−c·v)`` by variable projection.

    For fixed ``c`` the model is linear in ``(a, b)``; the weighted SSE is profiled over
    ``c`` on a log grid from 1e-3 s/mm to ``max_c``, refined by a bounded scalar search,
    and the covariance of ``(a, b, c)`` is ``(JᵀWJ)⁻¹`` with the analytic Jacobian
    ``[1, e^(−cv), −b·v·e^(−cv)]`` (to be scaled by the caller).

    Returns
    -------
    (sse, params, covariance) or None
        ``None`` if the linear sub-problem is singular everywhere.
    """
    w = 1.0 / sigma

    def sse_ab(c: float) -> tuple[float, FloatArray]:
        design = np.column_stack([np.ones_like(v), np.exp(-c * v)]) * w[:, None]
        coef = np.asarray(np.linalg.lstsq(design, y * w, rcond=None)[0], dtype=np.float64)
        resid = y * w - design @ coef
        return float(resid @ resid), coef

    grid = np.geomspace(1e-3, max_c, 80)
    sse_grid = np.array([sse_ab(float(c))[0] for c in grid])
    i = int(np.argmin(sse_grid))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    if hi > lo:
        res = minimize_scalar(lambda lc: sse_ab(float(np.exp(lc)))[0],
                              bounds=(float(np.log(lo)), float(np.log(hi))), method="bounded",
                              options={"xatol": 1e-10})
        c = float(np.exp(res.x))
    else:
        c = float(grid[i])
    sse, (a, b) = sse_ab(c)
    e = np.exp(-c * v)
    jac = np.column_stack([np.ones_like(v), e, -b * v * e]) * w[:, None]
    jtj = jac.T @ jac
    if not np.all(np.isfinite(jtj)) or np.linalg.cond(jtj) > 1e14:
        return None
    return sse, np.array([a, b, c]), np.asarray(np.linalg.inv(jtj), dtype=np.float64)


def _with_reason(fit: VelocityLawFit, reason: str, p_value: float = math.nan) -> VelocityLawFit:
    return VelocityLawFit(fit.velocity_dependent, fit.a_per_n, fit.a_err_per_n, fit.b_per_n,
                          fit.b_err_per_n, fit.c_s_per_mm, fit.c_err_s_per_mm, p_value, reason,
                          fit.n_points, fit.speeds_mm_s, fit.pinch_range_n,
                          fit.rms_residual_per_n)


@dataclass(frozen=True)
class MaxForceFit:
    """``F_f,max = c0 + c1·F_p + c2·F_p²`` fitted to per-record maxima [000 Figs. 4–8].

    Attributes
    ----------
    coeffs
        ``(c0 N, c1, c2 1/N)``.
    errors
        Standard errors of the coefficients.
    covariance
        Covariance of the coefficients, shape (3, 3).
    n_points
        Records used.
    pinch_forces_n
        Distinct set pinch forces used, N.
    rms_residual_n
        RMS residual, N.
    """

    coeffs: tuple[float, float, float]
    errors: tuple[float, float, float]
    covariance: FloatArray
    n_points: int
    pinch_forces_n: tuple[float, ...]
    rms_residual_n: float

    def max_feed_force_n(self, pinch_force_n: npt.ArrayLike) -> FloatArray:
        """Fitted maximum feed force at the given pinch forces, N (any shape)."""
        return max_feed_force_n(pinch_force_n, self.coeffs)

    def stderr_n(self, pinch_force_n: npt.ArrayLike) -> FloatArray:
        """Standard error of the fitted curve at the given pinch forces, N (any shape)."""
        fp = np.asarray(pinch_force_n, dtype=np.float64)
        basis = np.stack([np.ones_like(fp), fp, fp * fp], axis=-1)
        return np.sqrt(np.einsum("...i,ij,...j->...", basis, self.covariance, basis))


def fit_max_feed_force(results: Sequence[RecordResult], *,
                       pinch_range_n: tuple[float, float] | None = None) -> MaxForceFit:
    """Fit the 2nd-order polynomial of the maximum feed force over the pinch force.

    Parameters
    ----------
    results
        Per-record results; each gives one point ``(F_p set, F_f,max)``.
    pinch_range_n
        ``(low, high)`` set pinch forces to use, N (inclusive); ``None``: all.

    Returns
    -------
    MaxForceFit

    Raises
    ------
    CalibrationError
        Fewer than three distinct pinch forces or four records.
    """
    sel = _select(results, pinch_range_n, need_slip=False)
    fp = np.array([r.key.pinch_force_set_n for r in sel])
    distinct = tuple(sorted(set(fp.tolist())))
    if len(distinct) < 3 or len(sel) < 4:
        raise CalibrationError("the 2nd-order maximum-force fit needs records at three or more "
                               "pinch forces (and four or more records)",
                               field="pinch_force_set_n", value=list(distinct),
                               allowed=">= 3 distinct pinch forces, >= 4 records")
    y = np.array([r.max_feed_force_n for r in sel])
    design = np.column_stack([np.ones_like(fp), fp, fp * fp])
    coef, _, rms = _linear_fit(design, y)
    cov = _hc3_covariance(design, y - design @ coef)
    errs = np.sqrt(np.diag(cov))
    return MaxForceFit(coeffs=(float(coef[0]), float(coef[1]), float(coef[2])),
                       errors=(float(errs[0]), float(errs[1]), float(errs[2])),
                       covariance=cov, n_points=len(sel), pinch_forces_n=distinct,
                       rms_residual_n=rms)


def r_squared_histogram(results: Sequence[RecordResult], *, bins: int = 20,
                        low: float = 0.0) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """Histogram of the regressions' ``R²`` [000 Fig. 9b].

    Parameters
    ----------
    results
        Per-record results (those without a slip regression are left out).
    bins
        Number of equal bins on ``[low, 1]``.
    low
        Lower edge; values below it are counted in the first bin.

    Returns
    -------
    counts : ndarray of int, shape (bins,)
    edges : ndarray, shape (bins + 1,)
    """
    r2 = np.clip(np.array([r.r_squared for r in results if r.slip is not None],
                          dtype=np.float64), low, 1.0)
    counts, edges = np.histogram(r2, bins=bins, range=(low, 1.0))
    return counts.astype(np.int64), edges
