"""The pacing's envelopes: how fast the path may go where the melt must follow a change.

Pure functions of the twin's lag ``K·Q̇ = v_in − Q`` [001 Eq. 15] (``Q`` the outflow,
``v_in`` the volumetric feed, ``K`` the lag factor): the junction speed for a step of the
cross-section (:func:`step_speed_mm_s`), the speed bound before a falling junction
(:func:`drop_envelope`) and after a start (:func:`rise_envelope`), and the staircase of
feeds that stays under both (:func:`staircase`). :mod:`flowtwin.compensation.pace` places
them on a draft.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt

__all__ = ["drop_envelope", "rise_envelope", "staircase", "step_speed_mm_s"]

FloatArray = npt.NDArray[np.float64]

#: Relative tolerance below which a speed counts as the planned one (no new piece).
SAME = 1e-6


def step_speed_mm_s(a_before_mm2: FloatArray, a_after_mm2: FloatArray, lag_k_s: FloatArray, *,
                    adjust_mm: float) -> FloatArray:
    """Junction speed at which the melt follows a cross-section step within ``adjust_mm``.

    The outflow of the lag ``K·Q̇ = v_in − Q`` [001 Eq. 15] changes by a factor
    ``ρ = a_before/a_after`` in ``K·ln ρ`` at best (``v_in = 0`` falling); at path speed
    ``v`` that is ``v·K·ln ρ`` of path, so ``v ≤ adjust / (K·|ln ρ|)``.

    Parameters
    ----------
    a_before_mm2, a_after_mm2
        Cross-sections before and after the junction, mm², shape ``(n,)``.
    lag_k_s
        Lag factor at the junction, s, shape ``(n,)``.
    adjust_mm
        Path over which the melt may adjust, mm.

    Returns
    -------
    ndarray
        Largest junction speed, mm/s (``inf`` where the cross-section does not change).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        log_rho = np.abs(np.log(np.asarray(a_before_mm2, dtype=np.float64)
                                / np.asarray(a_after_mm2, dtype=np.float64)))
        v = np.where(log_rho > 0, adjust_mm / (np.asarray(lag_k_s, dtype=np.float64)
                                               * log_rho), np.inf)
    return np.asarray(v)


def drop_envelope(v_anchor_mm_s: float, lag_k_s: float, distance_mm: FloatArray, *,
                  margin: float) -> FloatArray:
    """Largest path speed ``d`` before a junction of speed ``v_J`` for a paced fall.

    ``d ln Q/dt ≥ −m/K`` with ``Q = a·v`` and ``a`` constant is ``dv/ds ≥ −m/K``
    (``d ln v/dt = v'(s)``), so ``v(d) = v_J + (m/K)·d``: the flow then decays as
    ``exp(−m·t/K)``, the fastest the lag [001 Eq. 15] can follow with a feed of
    ``(1 − m)·Q``.

    Parameters
    ----------
    v_anchor_mm_s
        Speed at the junction, mm/s.
    lag_k_s
        Lag factor ``K``, s.
    distance_mm
        Path distance before the junction, mm, shape ``(n,)``.
    margin
        ``m`` (0 < m < 1).

    Returns
    -------
    ndarray
        Speed bound, mm/s, shape ``(n,)``.
    """
    d = np.asarray(distance_mm, dtype=np.float64)
    return np.asarray(v_anchor_mm_s + margin / lag_k_s * d)


def rise_envelope(v_start_mm_s: float, accel_mm_s2: float, distance_mm: FloatArray
                  ) -> FloatArray:
    """Largest path speed ``s`` after a start when the flow may rise at ``a·A`` only.

    The outflow rises at most as ``Q̇ ≤ V/K`` when the feed may exceed the intent by ``V``
    (lag [001 Eq. 15]); with ``Q = a·v`` that is a path acceleration ``A = m·V/(K·a)``:
    ``v(s) = sqrt(v₀² + 2·A·s)``.

    Parameters
    ----------
    v_start_mm_s
        Speed at the start, mm/s.
    accel_mm_s2
        Paced acceleration ``A``, mm/s².
    distance_mm
        Path distance after the start, mm, shape ``(n,)``.

    Returns
    -------
    ndarray
        Speed bound, mm/s.
    """
    s = np.maximum(np.asarray(distance_mm, dtype=np.float64), 0.0)
    return np.asarray(np.sqrt(v_start_mm_s ** 2 + 2.0 * accel_mm_s2 * s))


def staircase(length_mm: float, v_plan_mm_s: float, *, end_v_mm_s: float, end_slope_1_s: float,
              start_v_mm_s: float, start_accel_mm_s2: float, step_ratio: float,
              min_piece_mm: float, floor_mm_s: float) -> tuple[list[float], list[float]]:
    """Cut a straight piece into sub-pieces whose speeds lie under both envelopes.

    The bound at distance ``s`` from the start is
    ``min(v_plan, end_v + g·(L − s), sqrt(start_v² + 2·A·s))``; a sub-piece runs at the
    bound's minimum over its extent (the drop bound is smallest at the sub-piece's end, the
    rise bound at its start), never below ``floor``. Cuts sit where the envelopes cross the
    speed levels ``v·step_ratioᵏ``, so neighbouring feeds differ by about ``step_ratio``;
    sub-pieces shorter than ``min_piece_mm`` are merged into the slower neighbour.

    This is the definition; the pacing runs the compiled
    :func:`flowtwin.compensation._pace_kernel.staircases`, held to it to the bit
    (``tests/compensation/test_pace_kernel.py``).

    Parameters
    ----------
    length_mm
        Length ``L`` of the piece, mm.
    v_plan_mm_s
        Planned top speed, mm/s (the result never exceeds it).
    end_v_mm_s, end_slope_1_s
        Drop envelope: speed at the piece's end and slope ``g = m/K``, 1/s (``inf`` end
        speed: none).
    start_v_mm_s, start_accel_mm_s2
        Rise envelope: speed at the start and acceleration ``A``, mm/s² (``inf`` start
        speed: none).
    step_ratio
        Feed ratio between sub-pieces.
    min_piece_mm
        Shortest sub-piece, mm.
    floor_mm_s
        Lowest speed, mm/s.

    Returns
    -------
    tuple of list
        End distances of the sub-pieces from the piece's start (last = ``L``) and their
        speeds (``v_plan`` where the piece is not paced), mm and mm/s.
    """
    big = v_plan_mm_s * (1.0 - SAME)
    cuts = {0.0, length_mm}
    q = step_ratio
    if math.isfinite(end_v_mm_s) and end_v_mm_s < big:
        level = max(end_v_mm_s, floor_mm_s, 1e-9)
        while level < big:
            d = (level - end_v_mm_s) / end_slope_1_s
            if 0.0 < d < length_mm:
                cuts.add(length_mm - d)
            level *= q
        d = (v_plan_mm_s - end_v_mm_s) / end_slope_1_s
        if 0.0 < d < length_mm:
            cuts.add(length_mm - d)
    if math.isfinite(start_v_mm_s) and start_v_mm_s < big:
        level = max(start_v_mm_s, floor_mm_s, 1e-9)
        while level < big:
            s = (level * level - start_v_mm_s ** 2) / (2.0 * start_accel_mm_s2)
            if 0.0 < s < length_mm:
                cuts.add(s)
            level *= q
        s = (v_plan_mm_s ** 2 - start_v_mm_s ** 2) / (2.0 * start_accel_mm_s2)
        if 0.0 < s < length_mm:
            cuts.add(s)
    pts = sorted(cuts)
    ends: list[float] = []
    speeds: list[float] = []
    for s0, s1 in itertools.pairwise(pts):
        v = v_plan_mm_s
        if math.isfinite(end_v_mm_s):
            v = min(v, end_v_mm_s + end_slope_1_s * (length_mm - s1))
        if math.isfinite(start_v_mm_s):
            v = min(v, math.sqrt(start_v_mm_s ** 2 + 2.0 * start_accel_mm_s2 * s0))
        v = max(v, min(floor_mm_s, v_plan_mm_s))
        ends.append(s1)
        speeds.append(v)
    # merge short sub-pieces into the slower neighbour (keeps every speed under the bound)
    k = 0
    while len(ends) > 1 and k < len(ends):
        start = ends[k - 1] if k > 0 else 0.0
        if ends[k] - start >= min_piece_mm:
            k += 1
            continue
        if k == 0:
            j = 1
        elif k == len(ends) - 1:
            j = k - 1
        else:
            j = k - 1 if speeds[k - 1] <= speeds[k + 1] else k + 1
        lo, hi = min(j, k), max(j, k)
        speeds[lo] = min(speeds[lo], speeds[hi])
        ends[lo] = ends[hi]
        del ends[hi], speeds[hi]
        k = max(lo - 1, 0) if lo == k else lo
    # neighbours at the same speed become one
    out_e: list[float] = []
    out_v: list[float] = []
    for e, v in zip(ends, speeds, strict=True):
        if out_v and abs(out_v[-1] - v) <= SAME * max(v, 1e-9):
            out_e[-1] = e
        else:
            out_e.append(e)
            out_v.append(v)
    return out_e, out_v
