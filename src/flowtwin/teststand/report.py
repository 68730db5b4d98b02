"""Whole-campaign evaluation and the comparison with a roller's published parameters.

:func:`analyse_campaign` runs the evaluation of [000 §4] over the records of one roller:
per-record results, the Eq. 6 fit with Eq. 9, the Eq. 8 fit at 80–130 N, the maximum-force
fit and the ``R²`` distribution. A fit the data cannot support is reported with its reason
(``problems``) instead of a number.

:func:`compare_with_roller` checks recovered against published values. Table 3 of [000]
gives an uncertainty for ``k_s``, ``k_∞``, ``a``, ``b``, ``c``: a recovered value passes when
it lies within that uncertainty. ``F_p,min`` has none printed; it passes when within the
uncertainty propagated from ``k_s`` and ``k_∞`` (linear propagation of the two published
errors, taken as independent). The maximum-force fits of Figs. 4–8 have none either; the
recovered *curve* passes when it stays within three standard errors of its own fit (plus
0.5 N for the smoothing of the maximum, :mod:`flowtwin.teststand.analysis`) of the
published curve at every tested pinch force — i.e. the published curve is statistically
indistinguishable from the recovered one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from flowtwin.errors import CalibrationError
from flowtwin.physics.drive import max_feed_force_n
from flowtwin.profiles import Roller
from flowtwin.teststand.analysis import RecordResult
from flowtwin.teststand.fits import (
    MaxForceFit,
    PinchLawFit,
    VelocityLawFit,
    fit_max_feed_force,
    fit_pinch_law,
    fit_velocity_law,
)

__all__ = [
    "MAX_FORCE_SMOOTHING_ALLOWANCE_N",
    "CampaignAnalysis",
    "ParameterCheck",
    "analyse_campaign",
    "compare_with_roller",
]

#: Extra allowance on the maximum-force curve for the moving-average maximum, N.
MAX_FORCE_SMOOTHING_ALLOWANCE_N = 0.5


@dataclass(frozen=True)
class CampaignAnalysis:
    """Evaluation of one roller's records [000 §4].

    Attributes
    ----------
    roller_id
        The roller the records belong to.
    results
        Per-record results.
    pinch_law
        Eq. 6 fit (``None`` if it could not be made; see ``problems``).
    velocity_law
        Eq. 8 fit at 80–130 N (``None`` if it could not be made).
    max_force
        2nd-order maximum-force fit (``None`` if it could not be made).
    problems
        Reasons, by fit name (``pinch_law``, ``velocity_law``, ``max_force``).
    """

    roller_id: str
    results: tuple[RecordResult, ...]
    pinch_law: PinchLawFit | None
    velocity_law: VelocityLawFit | None
    max_force: MaxForceFit | None
    problems: dict[str, str] = field(default_factory=dict)

    @property
    def rejected(self) -> tuple[RecordResult, ...]:
        """Records without a slip regression (their reasons are in ``slip_problem``)."""
        return tuple(r for r in self.results if r.slip is None)

    @property
    def r_squared(self) -> np.ndarray:
        """``R²`` of every record with a regression."""
        return np.array([r.slip.r_squared for r in self.results if r.slip is not None])


def analyse_campaign(results: Sequence[RecordResult], *,
                     velocity_pinch_range_n: tuple[float, float] = (80.0, 130.0),
                     max_force_pinch_range_n: tuple[float, float] | None = None,
                     ) -> CampaignAnalysis:
    """Fit Eq. 6, Eq. 8 and the maximum-force curve to one roller's record results.

    Parameters
    ----------
    results
        Per-record results of one roller (:func:`~flowtwin.teststand.analysis.
        analyse_records`).
    velocity_pinch_range_n
        Pinch forces for the Eq. 8 fit, N ([000]: 80–130 N).
    max_force_pinch_range_n
        Pinch forces for the maximum-force fit, N (``None``: all).

    Returns
    -------
    CampaignAnalysis

    Raises
    ------
    CalibrationError
        If ``results`` is empty or mixes rollers.
    """
    ids = sorted({r.key.roller_id for r in results})
    if len(ids) != 1:
        raise CalibrationError("a campaign analysis needs the records of exactly one roller",
                               field="roller_id", value=ids, allowed="one roller id")
    problems: dict[str, str] = {}
    pinch: PinchLawFit | None = None
    velocity: VelocityLawFit | None = None
    fmax: MaxForceFit | None = None
    try:
        pinch = fit_pinch_law(results)
    except CalibrationError as exc:
        problems["pinch_law"] = exc.message
    try:
        velocity = fit_velocity_law(results, pinch_range_n=velocity_pinch_range_n)
    except CalibrationError as exc:
        problems["velocity_law"] = exc.message
    try:
        fmax = fit_max_feed_force(results, pinch_range_n=max_force_pinch_range_n)
    except CalibrationError as exc:
        problems["max_force"] = exc.message
    return CampaignAnalysis(ids[0], tuple(results), pinch, velocity, fmax, problems)


@dataclass(frozen=True)
class ParameterCheck:
    """One recovered parameter against its published value.

    Attributes
    ----------
    name
        Parameter (``k_s``, ``k_inf``, ``F_p,min``, ``a``, ``b``, ``c``, ``velocity law``,
        ``F_f,max curve``).
    unit
        Unit of the numbers (the paper's: %·N, %/N, s/mm, N).
    published
        Published value (``None`` where the paper states only a property).
    tolerance
        Allowed deviation and where it comes from.
    recovered
        Recovered value (``None`` if the fit could not be made).
    recovered_err
        Its standard error (``None`` if not available).
    deviation
        ``recovered − published`` (or the largest deviation of a curve).
    passed
        Whether the recovered value is within the tolerance.
    note
        Context (e.g. why a check could not be made).
    """

    name: str
    unit: str
    published: float | None
    tolerance: float | None
    recovered: float | None
    recovered_err: float | None
    deviation: float | None
    passed: bool
    note: str = ""


def _check(name: str, unit: str, published: float, tol: float, recovered: float | None,
           err: float | None, note: str = "") -> ParameterCheck:
    if recovered is None or not math.isfinite(recovered):
        return ParameterCheck(name, unit, published, tol, None, None, None, False,
                              note or "not recovered")
    dev = recovered - published
    return ParameterCheck(name, unit, published, tol, recovered, err, dev, abs(dev) <= tol,
                          note)


def compare_with_roller(analysis: CampaignAnalysis, roller: Roller, *,
                        pinch_forces_n: Sequence[float] | None = None,
                        ) -> tuple[ParameterCheck, ...]:
    """Recovered parameters of a campaign against a roller's published ones [000 Table 3].

    Parameters
    ----------
    analysis
        The campaign evaluation.
    roller
        The roller with its published parameters (:func:`flowtwin.profiles.load_rollers`).
    pinch_forces_n
        Pinch forces at which to compare the maximum-force curves, N (default: the pinch
        forces of the maximum-force fit).

    Returns
    -------
    tuple of ParameterCheck
        Units as in Table 3 (%·N, %/N, s/mm) and N.
    """
    checks: list[ParameterCheck] = []
    pl = analysis.pinch_law
    note = analysis.problems.get("pinch_law", "")
    ks_err = roller.k_s_pct_N_err if roller.k_s_pct_N_err is not None else math.nan
    ki_err = roller.k_inf_pct_per_N_err if roller.k_inf_pct_per_N_err is not None else math.nan
    checks.append(_check("k_s", "%·N", roller.k_s_pct_N, ks_err,
                         None if pl is None else 100.0 * pl.k_s_n,
                         None if pl is None else 100.0 * pl.k_s_err_n, note))
    checks.append(_check("k_inf", "%/N", roller.k_inf_pct_per_N, ki_err,
                         None if pl is None else 100.0 * pl.k_inf_per_n,
                         None if pl is None else 100.0 * pl.k_inf_err_per_n, note))
    fp = roller.fp_min_eq9_n
    fp_err = 0.5 * fp * math.hypot(ks_err / roller.k_s_pct_N, ki_err / roller.k_inf_pct_per_N)
    checks.append(_check("F_p,min (Eq. 9)", "N", fp, fp_err,
                         None if pl is None else pl.fp_min_n,
                         None if pl is None else pl.fp_min_err_n,
                         note or "published: Eq. 9 of Table 3's k_s, k_inf; tolerance "
                                 "propagated from their errors"))
    checks.extend(_velocity_checks(analysis, roller))
    checks.append(_max_force_check(analysis, roller, pinch_forces_n))
    return tuple(checks)


def _velocity_checks(analysis: CampaignAnalysis, roller: Roller) -> list[ParameterCheck]:
    vl = analysis.velocity_law
    note = analysis.problems.get("velocity_law", "")
    if not roller.velocity_dependent:
        a = roller.a_pct_per_N if roller.a_pct_per_N is not None else math.nan
        a_err = roller.a_pct_per_N_err if roller.a_pct_per_N_err is not None else math.nan
        found = None if vl is None else vl.velocity_dependent
        return [
            _check("a", "%/N", a, a_err, None if vl is None else 100.0 * vl.a_per_n,
                   None if vl is None else 100.0 * vl.a_err_per_n, note),
            ParameterCheck("velocity law", "-", None, None, None, None, None,
                           found is False,
                           note or ("published: no velocity dependence (b·exp(-c·v) -> 0); "
                                    f"recovered: {vl.reason if vl else 'no fit'}")),
        ]
    out: list[ParameterCheck] = []
    names = (("a", "%/N", roller.a_pct_per_N, roller.a_pct_per_N_err, 100.0),
             ("b", "%/N", roller.b_pct_per_N, roller.b_pct_per_N_err, 100.0),
             ("c", "s/mm", roller.c_s_per_mm, roller.c_s_per_mm_err, 1.0))
    for name, unit, pub, err, scale in names:
        value: float | None = None
        value_err: float | None = None
        if vl is not None:
            if name == "a":
                value, value_err = vl.a_per_n, vl.a_err_per_n
            elif vl.velocity_dependent:
                value = vl.b_per_n if name == "b" else vl.c_s_per_mm
                value_err = vl.b_err_per_n if name == "b" else vl.c_err_s_per_mm
        if value is not None:
            value *= scale
            value_err = None if value_err is None else value_err * scale
        why = note or ("" if vl is None or vl.velocity_dependent or name == "a"
                       else f"no velocity term recovered: {vl.reason}")
        out.append(_check(name, unit, math.nan if pub is None else pub,
                          math.nan if err is None else err, value, value_err, why))
    return out


def _max_force_check(analysis: CampaignAnalysis, roller: Roller,
                     pinch_forces_n: Sequence[float] | None) -> ParameterCheck:
    fit = roller.max_feed_force_fit
    mf = analysis.max_force
    if fit is None or mf is None:
        return ParameterCheck("F_f,max curve", "N", None, None, None, None, None, False,
                              analysis.problems.get("max_force", "no published fit"
                                                    if fit is None else "not recovered"))
    fp = np.asarray(pinch_forces_n if pinch_forces_n is not None else mf.pinch_forces_n,
                    dtype=np.float64)
    published = max_feed_force_n(fp, (fit.c0_N, fit.c1, fit.c2_per_N))
    recovered = mf.max_feed_force_n(fp)
    dev = recovered - published
    allowed = 3.0 * mf.stderr_n(fp) + MAX_FORCE_SMOOTHING_ALLOWANCE_N
    worst = int(np.argmax(np.abs(dev) / allowed))
    return ParameterCheck(
        "F_f,max curve", "N", float(published[worst]), float(allowed[worst]),
        float(recovered[worst]), float(mf.stderr_n(fp[worst])), float(dev[worst]),
        bool(np.all(np.abs(dev) <= allowed)),
        f"worst of {fp.size} pinch forces ({fp[worst]:g} N); tolerance 3 standard errors of "
        f"the recovered curve + {MAX_FORCE_SMOOTHING_ALLOWANCE_N:g} N")
