"""The measurement equations of the slip camera: speed, slip, volume flow [003, 000].

Small pure functions on arrays; the pipeline in :mod:`flowtwin.vision.measure` only
feeds them. Speeds are in mm/s, widths in mm, slip as a fraction (docs/spec.md §2).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["gaussian_smooth", "slip_fraction", "speed_mm_s", "surface_speed_mm_s",
           "volume_flow_mm3_s"]

FloatArray = npt.NDArray[np.float64]


def speed_mm_s(step_px: npt.ArrayLike, dt_s: npt.ArrayLike, k_cal_mm_per_px: float
               ) -> FloatArray:
    """Transport speed from the mean step between frames: ``v = (k_cal/Δt)·S_pxl`` [003 Eq. 5].

    [003] divides by the *average* frame period from the CPU clock; here ``dt_s`` is each
    step's own capture-time difference, so dropped frames and jitter do not bias ``v``.
    The Gaussian window ``f`` of Eq. 5 is :func:`gaussian_smooth`.

    Parameters
    ----------
    step_px
        Mean displacement of the tracked points between two frames, px, shape ``(N,)``.
    dt_s
        Time between the two frames, s, shape ``(N,)``.
    k_cal_mm_per_px
        Image scale ``k_cal`` [003 Eq. 4], mm/px.

    Returns
    -------
    numpy.ndarray
        Speed, mm/s, shape ``(N,)``.
    """
    return (k_cal_mm_per_px / np.asarray(dt_s, dtype=np.float64)) * np.asarray(
        step_px, dtype=np.float64)


def surface_speed_mm_s(omega_rad_s: npt.ArrayLike, radius_mm: float) -> FloatArray:
    """Feed speed of a roller: ``v_feed = ω_r·R_r`` [003 Eq. 3] (nominal ``ω·r`` of [000]).

    Parameters
    ----------
    omega_rad_s
        Angular speed, rad/s.
    radius_mm
        Effective drive radius, mm.

    Returns
    -------
    numpy.ndarray
        Surface speed, mm/s.
    """
    return np.asarray(omega_rad_s, dtype=np.float64) * radius_mm


def slip_fraction(gear_speed_mm_s: npt.ArrayLike, filament_speed_mm_s: npt.ArrayLike, *,
                  min_gear_speed_mm_s: float = 0.0, min_filament_speed_mm_s: float = 0.0
                  ) -> FloatArray:
    """Slip ``s = (ω·r − v_fil)/(ω·r)`` [000 Eq. 1], as a fraction.

    Parameters
    ----------
    gear_speed_mm_s
        Gear surface speed ``ω·r``, mm/s.
    filament_speed_mm_s
        Filament transport speed, mm/s.
    min_gear_speed_mm_s, min_filament_speed_mm_s
        Where ``|ω·r|`` is not above its floor, or ``|v_fil|`` is below its floor, the
        slip is undefined and NaN is returned (a ratio of noise readings is no slip).

    Returns
    -------
    numpy.ndarray
        Slip (0 = no slip), NaN where undefined.
    """
    g = np.asarray(gear_speed_mm_s, dtype=np.float64)
    f = np.asarray(filament_speed_mm_s, dtype=np.float64)
    ok = (np.abs(g) > max(min_gear_speed_mm_s, 0.0)) & ~(
        np.abs(f) < min_filament_speed_mm_s)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ok, (g - f) / np.where(ok, g, 1.0), np.nan)


def volume_flow_mm3_s(filament_speed_mm_s: npt.ArrayLike, width_mm: npt.ArrayLike
                      ) -> FloatArray:
    """Volume flow of filament fed, ``Q = v·π·w²/4`` [003 §3.1, width taken as diameter].

    [003] estimates the volume fed from the integrated speed and the measured width,
    "assuming perfect roundness"; the flow rate is the same product per unit time.

    Parameters
    ----------
    filament_speed_mm_s
        Filament speed, mm/s.
    width_mm
        Filament width (diameter), mm.

    Returns
    -------
    numpy.ndarray
        Volume flow, mm³/s.
    """
    w = np.asarray(width_mm, dtype=np.float64)
    return np.asarray(filament_speed_mm_s, dtype=np.float64) * (math.pi / 4.0) * w * w


def gaussian_smooth(t_s: npt.ArrayLike, values: npt.ArrayLike, sigma_s: float
                    ) -> FloatArray:
    """Gaussian-window smoothing in time that skips invalid samples [003 Eq. 5, ``f *``].

    ``y_i = Σ_j g_ij·x_j / Σ_j g_ij`` over valid ``x_j``, ``g_ij = exp(−(t_j − t_i)²/2σ²)``
    over the samples within (at least) ``±4σ``. Using the capture times (not sample
    counts) keeps the window right across dropped frames. A sample whose window holds no
    valid value stays NaN.

    Parameters
    ----------
    t_s
        Sample times, increasing, s, shape ``(N,)``.
    values
        Samples, NaN where invalid, shape ``(N,)``.
    sigma_s
        Standard deviation of the window, s.

    Returns
    -------
    numpy.ndarray
        Smoothed samples, shape ``(N,)``.
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(values, dtype=np.float64)
    n = t.size
    if n == 0:
        return x.copy()
    valid = np.isfinite(x)
    xv = np.where(valid, x, 0.0)
    num = np.zeros(n)
    den = np.zeros(n)
    lo = np.searchsorted(t, t - 4 * sigma_s, side="left")
    hi = np.searchsorted(t, t + 4 * sigma_s, side="right")
    reach = int(np.max(np.maximum(np.arange(n) - lo, hi - 1 - np.arange(n))))
    idx = np.arange(n)
    for off in range(-reach, reach + 1):
        j = idx + off
        inside = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        wgt = np.where(inside & valid[jj],
                       np.exp(-0.5 * ((t[jj] - t) / sigma_s) ** 2), 0.0)
        num += wgt * xv[jj]
        den += wgt
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
