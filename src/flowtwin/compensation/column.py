"""What the filament column carries into a run start: the lag state through a gap.

The melt lags the feed through ``K·Q̇ = v_in − Q`` [001 Eq. 15]; with the stored volume
``x = K·Q`` (the column's compression ``Δl`` times the filament area, docs/spec.md §3.4:
``dΔl/dt = v_in − Δl/K`` for ``Δl > 0``) the outflow is ``max(x, 0)/K`` — no backflow
[001 Fig. 8]: a retraction takes ``x`` below zero, nothing flows until the push-back has
filled it again. So a retraction *holds* the compression through a travel and a push-back
restores it, and E written between two runs (a purge blob, a prime, a push-back longer
than its retraction) charges the column that the next run starts with.

The flow pacing (:mod:`flowtwin.compensation.pace`) paces the rise of a run's start from
the outflow the column really has there: this module propagates the state through the rows
of the gap, each row feeding its commanded volume evenly over its duration (the exact
solution of the lag for a constant feed, :func:`lag_state_after`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["carried_flows", "feed_after", "lag_state_after", "run_start_flow"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


def lag_state_after(x0_mm3: float, volume_mm3: float, duration_s: float,
                    lag_k_s: float) -> float:
    """Stored volume after feeding ``volume_mm3`` evenly over ``duration_s``.

    Exact solution of ``ẋ = u − max(x, 0)/K`` with ``u = V/T`` ([001 Eq. 15] in the stored
    volume ``x = K·Q``; no backflow [001 Fig. 8], docs/spec.md §3.4): while ``x > 0``,
    ``x(t) = u·K + (x₀ − u·K)·exp(−t/K)``; while ``x ≤ 0`` nothing flows out and
    ``x(t) = x₀ + u·t``; the switch between the two is found in closed form
    (``t₀ = K·ln((x₀ − u·K)/(−u·K))`` for a retraction from a positive state, ``−x₀/u``
    for a feed into a negative one).

    Parameters
    ----------
    x0_mm3
        Stored volume at the start, mm³ (negative: a retraction not yet pushed back).
    volume_mm3
        Volume fed, mm³ (negative for a retraction).
    duration_s
        Time over which it is fed, s (≤ 0: at once).
    lag_k_s
        Lag factor ``K``, s (≤ 0: the melt follows at once, nothing is stored).

    Returns
    -------
    float
        Stored volume at the end, mm³; the outflow is ``max(x, 0)/K``.
    """
    x0 = float(x0_mm3)
    v = float(volume_mm3)
    t = float(duration_s)
    k = float(lag_k_s)
    if not k > 0.0:
        return min(min(x0, 0.0) + v, 0.0)
    if not t > 0.0:
        return x0 + v
    u = v / t
    if x0 > 0.0:
        if u >= 0.0:
            return u * k + (x0 - u * k) * math.exp(-t / k)
        t0 = k * math.log((x0 - u * k) / (-u * k))  # x reaches 0
        if t0 >= t:
            return u * k + (x0 - u * k) * math.exp(-t / k)
        return u * (t - t0)
    if u <= 0.0:
        return x0 + u * t
    t0 = -x0 / u  # the feed fills the retraction
    if t0 >= t:
        return x0 + u * t
    return u * k * (1.0 - math.exp(-(t - t0) / k))


def run_start_flow(starts: IntArray, prev_ends: IntArray, x_end_mm3: FloatArray, *,
                   volume_mm3: FloatArray, t_start_s: FloatArray, t_end_s: FloatArray,
                   lag_k_s: FloatArray) -> FloatArray:
    """Outflow the column carries into every run start.

    The state ``x`` leaves the previous run's last row at ``x_end_mm3`` and goes through
    every row between (:func:`lag_state_after`: each row's commanded volume fed evenly
    over its own time, a wait before a row with no feed); the outflow at the start of the
    run is ``max(x, 0)/K`` with the run's first row's ``K`` [001 Eq. 15].

    Parameters
    ----------
    starts
        First row of every run, shape ``(r,)``.
    prev_ends
        Last row of the run before each, shape ``(r,)`` (``prev_ends < starts``).
    x_end_mm3
        Stored volume at the end of that row, mm³, shape ``(r,)``.
    volume_mm3
        Commanded volume of every row, mm³ (retractions negative), shape ``(n,)``.
    t_start_s, t_end_s
        Start and end of every row on the printer clock, s, shape ``(n,)``.
    lag_k_s
        Lag factor of every row, s, shape ``(n,)``.

    Returns
    -------
    ndarray
        Outflow at every run start, mm³/s, shape ``(r,)``.
    """
    vol = np.asarray(volume_mm3, dtype=np.float64).tolist()
    ts = np.asarray(t_start_s, dtype=np.float64).tolist()
    te = np.asarray(t_end_s, dtype=np.float64).tolist()
    k = np.asarray(lag_k_s, dtype=np.float64).tolist()
    out = np.zeros(len(starts), dtype=np.float64)
    for n, (j, p, x0) in enumerate(zip(np.asarray(starts).tolist(),
                                       np.asarray(prev_ends).tolist(),
                                       np.asarray(x_end_mm3, dtype=np.float64).tolist(),
                                       strict=True)):
        x = float(x0)
        t = te[p]
        for r in range(p + 1, j):
            x = lag_state_after(x, 0.0, ts[r] - t, k[r])
            x = lag_state_after(x, vol[r], te[r] - ts[r], k[r])
            t = te[r]
        x = lag_state_after(x, 0.0, ts[j] - t, k[j])
        out[n] = max(x, 0.0) / k[j] if k[j] > 0 else 0.0
    return out


def carried_flows(printing: BoolArray, end_flow_mm3_s: FloatArray, *, volume_mm3: FloatArray,
                  t_start_s: FloatArray, t_end_s: FloatArray, lag_k_s: FloatArray,
                  relief_lags: float) -> tuple[IntArray, FloatArray]:
    """Every run start after an earlier run and the outflow the column carries into it.

    The state at the end of the run before is ``K·Q_end`` [001 Eq. 15] where the gap is
    shorter than ``relief_lags·K`` (no pressure relief over it), none after a longer one
    (the advance's relief leaves the column relaxed there); :func:`run_start_flow` carries
    it through the gap.

    Parameters
    ----------
    printing
        Rows that print, shape ``(n,)``; a run is a stretch of consecutive printing rows.
    end_flow_mm3_s
        Outflow at the end of every row, mm³/s, shape ``(n,)`` (used at run ends).
    volume_mm3, t_start_s, t_end_s, lag_k_s
        As in :func:`run_start_flow`.
    relief_lags
        Shortest gap the advance relieves, in lag factors of the run's last row.

    Returns
    -------
    tuple of ndarray
        First rows of the runs that have a run before them, shape ``(r,)``, and the
        outflow carried into each, mm³/s, shape ``(r,)``.
    """
    pr = np.asarray(printing, dtype=bool)
    idx = np.flatnonzero(pr)
    first = idx[np.concatenate(([False], np.diff(idx) > 1))] if idx.size else idx
    ends = idx[np.searchsorted(idx, first) - 1]
    k = np.asarray(lag_k_s, dtype=np.float64)
    gap = np.asarray(t_start_s, dtype=np.float64)[first] - np.asarray(t_end_s)[ends]
    x_end = np.where(gap < relief_lags * k[ends],
                     k[ends] * np.asarray(end_flow_mm3_s, dtype=np.float64)[ends], 0.0)
    return first.astype(np.int64), run_start_flow(
        first, ends, x_end, volume_mm3=volume_mm3, t_start_s=t_start_s, t_end_s=t_end_s,
        lag_k_s=k)


def feed_after(volume_mm3: FloatArray, t_start_s: FloatArray, t_end_s: FloatArray
               ) -> FloatArray:
    """Feed of the row after every row where that row feeds melt, mm³/s (else 0).

    A run that ends into a row extruding without printing (a purge blob on a Z move, a
    prime) does not stop the flow: the outflow goes on to that row's feed ``V/T``.

    Parameters
    ----------
    volume_mm3, t_start_s, t_end_s
        Commanded volume, start and end of every row, mm³ and s, shape ``(n,)``.

    Returns
    -------
    ndarray
        Shape ``(n,)``; 0 for the last row and where the next row feeds nothing.
    """
    vol = np.asarray(volume_mm3, dtype=np.float64)
    dur = np.asarray(t_end_s, dtype=np.float64) - np.asarray(t_start_s, dtype=np.float64)
    ok = (vol > 0) & (dur > 0)
    feed = np.where(ok, vol / np.where(ok, dur, 1.0), 0.0)
    return np.concatenate((feed[1:], [0.0])) if feed.size else feed
