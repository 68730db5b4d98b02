"""Evaluation of one test-stand record: maximum feed force and slip gradient [000 §4].

For every record [000 §4]:

* **Maximum feed force** ``F_f,max``: the largest feed force of the record. Raw samples
  carry ±2 N (2σ) load-cell noise, whose maximum over the ~25 samples near the peak would
  bias ``F_f,max`` upwards by about 2σ; the maximum is therefore taken of a centred moving
  average over ``smooth_s`` (0.1 s = 5 samples at 50 Hz, during which the 4 N/s ramp rises
  only 0.4 N).
* **Slip gradient** ``s'``: the measured slip ``s_m = (v_nom − v_fil)/v_nom`` [000 Eq. 1]
  (:func:`flowtwin.physics.drive.measured_slip`) of every sample of the *loading phase*
  (start of the record up to the maximum feed force) regressed linearly on the measured
  feed force, ``s_m = k_p + s'·F_f`` [000 Eq. 6, Fig. 9a], by least squares, with the
  standard error of the slope and the coefficient of determination ``R²`` [000 Fig. 9b].

Errors in the regressor. The feed force is itself measured with noise of variance ``σ_F²``
(±2 N, 2σ: ``σ_F = 1 N`` [000 §3]). Ordinary least squares then shrinks the slope by the
reliability ratio ``λ = 1 − n·σ_F²/S_xx`` (``S_xx`` the centred sum of squares of the
measured force): a 10 N loading range (pinch force 10 N) has ``S_xx/n ≈ 8 N²`` and loses
≈ 12 % of its slope. With the load cell's ``σ_F`` known, the method-of-moments estimate
``s' = s'_OLS/λ`` removes that bias (Fuller, *Measurement Error Models*, 1987, §1.1.2);
``force_sigma_n = 0`` gives plain OLS. Both slopes are reported.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import CalibrationError
from flowtwin.physics.drive import measured_slip
from flowtwin.teststand.records import Record, RecordKey

__all__ = [
    "RecordResult",
    "SlipRegression",
    "analyse_record",
    "analyse_records",
    "loading_phase",
    "slip_regression",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class SlipRegression:
    """Linear regression of measured slip on feed force over the loading phase.

    Attributes
    ----------
    gradient_per_n
        Slope ``s'`` corrected for the force noise, 1/N (fraction per newton).
    stderr_per_n
        Standard error of the slope, 1/N.
    ols_gradient_per_n
        The uncorrected least-squares slope, 1/N.
    offset
        Intercept ``k_p``, fraction.
    r_squared
        Coefficient of determination.
    n_samples
        Samples in the regression.
    """

    gradient_per_n: float
    stderr_per_n: float
    ols_gradient_per_n: float
    offset: float
    r_squared: float
    n_samples: int


@dataclass(frozen=True)
class RecordResult:
    """What one record yields.

    Attributes
    ----------
    key
        The record's roller, set pinch force, set speed and repeat.
    max_feed_force_n
        Maximum (smoothed) feed force, N.
    slip
        The slip regression, or ``None`` if the record cannot give one.
    slip_problem
        Why there is no slip regression (``None`` when there is one).
    """

    key: RecordKey
    max_feed_force_n: float
    slip: SlipRegression | None
    slip_problem: str | None = None

    @property
    def slip_gradient_per_n(self) -> float:
        """``s'`` of the regression, 1/N; raises if the record has none."""
        if self.slip is None:
            raise CalibrationError(f"record has no slip gradient: {self.slip_problem}",
                                   field="slip", value=self.key.describe())
        return self.slip.gradient_per_n

    @property
    def r_squared(self) -> float:
        """``R²`` of the regression; raises if the record has none."""
        if self.slip is None:
            raise CalibrationError(f"record has no slip regression: {self.slip_problem}",
                                   field="slip", value=self.key.describe())
        return self.slip.r_squared


def _moving_average(x: FloatArray, width: int) -> FloatArray:
    if width <= 1 or x.size < width:
        return x.copy()
    kernel = np.full(width, 1.0 / width)
    return np.convolve(x, kernel, mode="valid")


def loading_phase(record: Record, *, smooth_s: float = 0.1) -> tuple[int, float]:
    """End of the loading phase and the maximum feed force of a record.

    Parameters
    ----------
    record
        The record.
    smooth_s
        Width of the centred moving average of the feed force, s (≥ 0).

    Returns
    -------
    end : int
        Index of the sample at the (smoothed) maximum; samples ``0 … end`` load the drive.
    max_feed_force_n : float
        The smoothed maximum, N.
    """
    dt = float(np.median(np.diff(record.t_s))) if record.n_samples > 1 else 1.0
    width = max(1, int(round(smooth_s / dt))) if dt > 0 else 1
    smooth = _moving_average(record.feed_force_n, width)
    i = int(np.argmax(smooth))
    offset = width // 2 if smooth.size < record.n_samples else 0
    return min(i + offset, record.n_samples - 1), float(smooth[i])


def slip_regression(record: Record, end: int, *, min_samples: int = 10,
                    force_sigma_n: float = 1.0) -> SlipRegression:
    """Regress measured slip [000 Eq. 1] on feed force over samples ``0 … end``.

    Parameters
    ----------
    record
        One test-stand record.
    end
        Last sample of the loading phase (:func:`loading_phase`).
    min_samples
        Fewest samples accepted (≥ 3).
    force_sigma_n
        Standard deviation of the feed-force noise, N (≥ 0), for the errors-in-variables
        correction (module docstring); 0 gives plain least squares.

    Returns
    -------
    SlipRegression

    Raises
    ------
    CalibrationError
        If the loading phase is too short, its feed force does not vary, or the force noise
        swamps the force range (reliability ratio below 0.5, where the correction becomes
        unstable); the message names the record (file and line when read from a file).
    """
    n = end + 1
    need = max(3, min_samples)
    if n < need:
        raise CalibrationError(
            f"loading phase too short for the slip regression ({record.key.describe()})",
            source=record.source, line=record.first_line, field="feed_force_n", value=n,
            allowed=f">= {need} samples before the maximum feed force")
    force = record.feed_force_n[:n]
    slip = measured_slip(record.key.nominal_speed_mm_s, record.filament_speed_mm_s[:n])
    fx = force - force.mean()
    sxx = float(fx @ fx)
    if not sxx > 0.0:
        raise CalibrationError(
            f"the feed force does not vary in the loading phase ({record.key.describe()})",
            source=record.source, line=record.first_line, field="feed_force_n",
            value=float(force[0]), allowed="a rising feed force")
    reliability = 1.0 - n * force_sigma_n * force_sigma_n / sxx
    if reliability < 0.5:
        raise CalibrationError(
            f"the feed-force range of the loading phase is too small next to the load-cell "
            f"noise ({record.key.describe()})", source=record.source, line=record.first_line,
            field="feed_force_n", value=round(math.sqrt(sxx / n), 3),
            allowed=f"a force spread (std) above {math.sqrt(2.0) * force_sigma_n:.3g} N")
    sy = slip - slip.mean()
    slope = float(fx @ sy) / sxx
    resid = sy - slope * fx
    ss_res = float(resid @ resid)
    ss_tot = float(sy @ sy)
    stderr = math.sqrt(ss_res / (n - 2) / sxx)
    return SlipRegression(gradient_per_n=slope / reliability,
                          stderr_per_n=stderr / reliability, ols_gradient_per_n=slope,
                          offset=float(slip.mean() - slope * force.mean()),
                          r_squared=1.0 - ss_res / ss_tot if ss_tot > 0.0 else 0.0,
                          n_samples=n)


def analyse_record(record: Record, *, smooth_s: float = 0.1, min_samples: int = 10,
                   force_sigma_n: float = 1.0, strict: bool = True) -> RecordResult:
    """Maximum feed force and slip-gradient regression of one record (module docstring).

    Parameters
    ----------
    record
        One test-stand record.
    smooth_s
        Moving-average width for the maximum feed force, s.
    min_samples, force_sigma_n
        See :func:`slip_regression`.
    strict
        If True a record without a usable slip regression raises; if False the result
        carries ``slip = None`` and the reason in ``slip_problem`` (its maximum feed force
        is still valid).

    Returns
    -------
    RecordResult

    Raises
    ------
    CalibrationError
        With ``strict``, when :func:`slip_regression` does.
    """
    end, fmax = loading_phase(record, smooth_s=smooth_s)
    try:
        reg = slip_regression(record, end, min_samples=min_samples,
                              force_sigma_n=force_sigma_n)
    except CalibrationError as exc:
        if strict:
            raise
        return RecordResult(key=record.key, max_feed_force_n=fmax, slip=None,
                            slip_problem=exc.message)
    return RecordResult(key=record.key, max_feed_force_n=fmax, slip=reg)


def analyse_records(records: Iterable[Record], *, smooth_s: float = 0.1,
                    min_samples: int = 10, force_sigma_n: float = 1.0,
                    strict: bool = False) -> tuple[RecordResult, ...]:
    """:func:`analyse_record` for every record, in order.

    A campaign contains records that cannot give a slip gradient (the lowest pinch forces
    feed only a few newtons, "10 N to 20 N is the minimum pinch force for reliable
    feeding" [000 §3]); by default they are kept with their reason (``strict=False``) and
    the fits skip them.

    Parameters
    ----------
    records
        Records (simulated or read by :func:`~flowtwin.teststand.records.read_records_csv`).
    smooth_s, min_samples, force_sigma_n, strict
        See :func:`analyse_record`.

    Returns
    -------
    tuple of RecordResult
    """
    return tuple(analyse_record(r, smooth_s=smooth_s, min_samples=min_samples,
                                force_sigma_n=force_sigma_n, strict=strict) for r in records)
