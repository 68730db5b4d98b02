"""Splitting moves at the planner's phase boundaries.

The planner gives every move a trapezoid: accelerate for ``accel_t``, cruise for
``cruise_t``, decelerate for ``decel_t`` (:class:`~flowtwin.planner.timeline.Timeline`).
A firmware turns the E of one ``G1`` in proportion to the path it covers, so the only way
to give an accelerating stretch more filament than the cruising one is to cut the move
there: each piece then gets its own E. :func:`split_rows` cuts every selected move at its
phase boundaries, optionally into ``n`` equal-time sub-pieces per acceleration and
deceleration phase, and merges pieces shorter than a minimum length into their neighbour
(so no piece is too short for a stepper driver or the reader's row rules).

Within a phase of constant acceleration ``a`` starting at speed ``v₀`` the path covered
after ``τ`` is ``s = v₀·τ + a·τ²/2``; the distances are computed with the planner's own
phase speeds, so the pieces of a move add up to the move's planned length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.compensation._refine_kernel import phase_point
from flowtwin.errors import DataError
from flowtwin.planner.timeline import Timeline

__all__ = ["Pieces", "phase_distance_mm", "split_rows"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: At most this many pieces per acceleration or deceleration phase.
_MAX_PIECES_PER_PHASE = 12


@dataclass(frozen=True, slots=True)
class Pieces:
    """Pieces of moves, in move order (rows not split are one piece).

    Attributes
    ----------
    row
        Move row each piece belongs to, shape ``(n,)``.
    t0_s, t1_s
        Start and end of each piece on the printer clock, s, shape ``(n,)``.
    s0_mm, s1_mm
        Path distance from the start of the row at the piece's start and end, mm.
    v0_mm_s, v1_mm_s
        Path speed at the piece's start and end, mm/s (linear in time in between only
        when the piece lies in one phase).
    offsets
        ``offsets[i]:offsets[i + 1]`` are the pieces of row ``i``, shape ``(n_rows + 1,)``.
    row_length_mm
        Planned path length of every row, mm, shape ``(n_rows,)``.
    """

    row: IntArray
    t0_s: FloatArray
    t1_s: FloatArray
    s0_mm: FloatArray
    s1_mm: FloatArray
    v0_mm_s: FloatArray
    v1_mm_s: FloatArray
    offsets: IntArray
    row_length_mm: FloatArray

    def __len__(self) -> int:
        return int(self.row.shape[0])

    @property
    def counts(self) -> IntArray:
        """Pieces per row, shape ``(n_rows,)``."""
        return np.diff(self.offsets)

    @property
    def length_mm(self) -> FloatArray:
        """Path length of each piece, mm."""
        return self.s1_mm - self.s0_mm

    @property
    def fraction_end(self) -> FloatArray:
        """Share of its row's path covered at each piece's end (1 for the last piece)."""
        length = self.row_length_mm[self.row]
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.where(length > 0, self.s1_mm / length, 1.0)
        last = self.offsets[1:] - 1
        f[last[self.counts > 0]] = 1.0
        return np.asarray(f)


def phase_distance_mm(start_v: FloatArray, cruise_v: FloatArray, end_v: FloatArray,
                      accel_t: FloatArray, cruise_t: FloatArray, decel_t: FloatArray,
                      tau_s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Path distance and speed ``τ`` after the start of a trapezoid move.

    Parameters
    ----------
    start_v, cruise_v, end_v
        Trapezoid speeds, mm/s, shape ``(n,)``.
    accel_t, cruise_t, decel_t
        Phase durations, s, shape ``(n,)``.
    tau_s
        Time since the move's start, s, shape ``(n,)``, clipped to the move.

    Returns
    -------
    tuple of ndarray
        Distance (mm) and speed (mm/s), shape ``(n,)``. Accelerations are taken from the
        phase speeds and durations (``(v_c − v_s)/t_a``), so the distances match the
        planner's own lengths exactly.
    """
    tau = np.clip(tau_s, 0.0, accel_t + cruise_t + decel_t)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_up = np.where(accel_t > 0, (cruise_v - start_v) / accel_t, 0.0)
        a_dn = np.where(decel_t > 0, (cruise_v - end_v) / decel_t, 0.0)
    ta = np.minimum(tau, accel_t)
    d = start_v * ta + 0.5 * a_up * ta * ta
    v = start_v + a_up * ta
    tc = np.clip(tau - accel_t, 0.0, cruise_t)
    d = d + cruise_v * tc
    td = np.clip(tau - accel_t - cruise_t, 0.0, decel_t)
    d = d + cruise_v * td - 0.5 * a_dn * td * td
    in_cruise = tau > accel_t
    v = np.where(in_cruise, cruise_v - a_dn * td, v)
    return np.asarray(d), np.asarray(v)


def split_rows(timeline: Timeline, select: npt.NDArray[np.bool_], *, accel_pieces: int = 1,
               max_piece_s: float = 0.0, cruise_edge_s: float = 0.0,
               min_piece_mm: float = 0.1,
               phase_only: npt.NDArray[np.bool_] | None = None) -> Pieces:
    """Cut the selected moves at their accel/cruise/decel boundaries.

    Parameters
    ----------
    timeline
        The planner's phases, ``n_rows`` moves.
    select
        Which rows to cut, shape ``(n_rows,)``; the others stay one piece.
    accel_pieces
        Least number of equal-time pieces per acceleration and deceleration phase (≥ 1).
    max_piece_s
        Longest piece within acceleration and deceleration phases and within the cruise
        edges, s (0: no limit).
    cruise_edge_s
        Also cut the first and last ``cruise_edge_s`` of a cruise into pieces of at most
        ``max_piece_s`` (0: no); used by the smoothed advance, whose target bends there.
    min_piece_mm
        Pieces shorter than this are merged into a neighbour, mm (≥ 0).
    phase_only
        Rows cut at their phase boundaries only (no sub-pieces), shape ``(n_rows,)``.

    Returns
    -------
    Pieces
    """
    n = timeline.phases.shape[0]
    if select.shape != (n,):
        raise DataError("selection does not match the timeline", field="select",
                        value=select.shape, allowed=f"({n},)")
    if accel_pieces < 1:
        raise DataError("accel_pieces must be at least 1", field="accel_pieces",
                        value=accel_pieces, allowed=">= 1")
    t_start, ta, tc, td, sv, cv, ev = timeline.trapezoids()
    duration = ta + tc + td
    length, _ = phase_distance_mm(sv, cv, ev, ta, tc, td, duration)
    if not np.any(select) and (phase_only is None or not np.any(phase_only)):
        # nothing to cut (a later pass): one piece per row, as the general path gives it
        one = np.arange(n + 1, dtype=np.int64)
        return Pieces(row=one[:-1].copy(), t0_s=t_start + 0.0, t1_s=t_start + duration,
                      s0_mm=np.zeros(n), s1_mm=length.copy(), v0_mm_s=sv.copy(),
                      v1_mm_s=ev.copy(),
                      offsets=one, row_length_mm=length)

    # candidate cut times (relative to the move start) per cut row, kept in time order
    # when at least min_piece_mm from the last kept cut and from the row's end
    ones = np.ones(n)
    n_acc = np.maximum(accel_pieces, np.ceil(ta / max_piece_s) if max_piece_s > 0 else ones)
    n_dec = np.maximum(accel_pieces, np.ceil(td / max_piece_s) if max_piece_s > 0 else ones)
    n_acc = np.minimum(n_acc, _MAX_PIECES_PER_PHASE)
    n_dec = np.minimum(n_dec, _MAX_PIECES_PER_PHASE)
    coarse = np.zeros(n, dtype=bool) if phase_only is None else phase_only & ~select
    n_acc = np.where(coarse, 1.0, n_acc)
    n_dec = np.where(coarse, 1.0, n_dec)
    step = max_piece_s if max_piece_s > 0 else cruise_edge_s
    m_edge = int(np.ceil(cruise_edge_s / step - 1e-9)) if cruise_edge_s > 0 else 0
    row, tau0, tau1, s0, s1, v0, v1, offsets = _cut_rows(
        select | coarse, ~coarse, n_acc, n_dec, ta, tc, td, sv, cv, ev, duration, length,
        m_edge, float(step) if m_edge else 0.0, float(cruise_edge_s), float(min_piece_mm))
    return Pieces(row=row, t0_s=t_start[row] + tau0, t1_s=t_start[row] + tau1, s0_mm=s0,
                  s1_mm=s1, v0_mm_s=v0, v1_mm_s=v1, offsets=offsets, row_length_mm=length)


@njit(cache=True)
def _row_cuts(i: int, n_acc: FloatArray, n_dec: FloatArray, ta: FloatArray, tc: FloatArray,
              td: FloatArray, edge_ok: npt.NDArray[np.bool_], m_edge: int, step: float,
              cruise_edge_s: float, out: FloatArray) -> int:
    """Candidate cut times of row ``i`` into ``out``, sorted; returns how many."""
    k_n = 0
    a, c, d = ta[i], tc[i], td[i]
    k = 1
    while k < n_acc[i] or k < n_dec[i]:
        if a > 0 and k < n_acc[i]:
            out[k_n] = k / n_acc[i] * a
            k_n += 1
        if d > 0 and k < n_dec[i]:
            out[k_n] = a + c + k / n_dec[i] * d
            k_n += 1
        k += 1
    if a > 0 and c + d > 0:
        out[k_n] = a
        k_n += 1
    if c > 0 and d > 0:
        out[k_n] = a + c
        k_n += 1
    for k in range(1, m_edge + 1):
        off = min(k * step, cruise_edge_s)
        if c > 2.0 * off and edge_ok[i]:
            out[k_n] = a + off
            out[k_n + 1] = a + c - off
            k_n += 2
    for p in range(1, k_n):  # insertion sort
        x = out[p]
        q = p - 1
        while q >= 0 and out[q] > x:
            out[q + 1] = out[q]
            q -= 1
        out[q + 1] = x
    return k_n


@njit(cache=True)
def _cut_rows(cut: npt.NDArray[np.bool_], edge_ok: npt.NDArray[np.bool_], n_acc: FloatArray,
              n_dec: FloatArray, ta: FloatArray, tc: FloatArray, td: FloatArray,
              sv: FloatArray, cv: FloatArray, ev: FloatArray, duration: FloatArray,
              length: FloatArray, m_edge: int, step: float, cruise_edge_s: float,
              min_piece_mm: float):  # type: ignore[no-untyped-def]
    """The pieces of every row (see :func:`split_rows`): row, start and end times after
    the row's start, distances and speeds at both ends, offsets."""
    n = cut.shape[0]
    width = 2 * _MAX_PIECES_PER_PHASE + 2 + 2 * m_edge
    cand = np.empty(width)
    counts = np.ones(n, dtype=np.int64)
    for twice in range(2):
        if twice:
            offsets = np.zeros(n + 1, dtype=np.int64)
            for i in range(n):
                offsets[i + 1] = offsets[i] + counts[i]
            total = offsets[n]
            row = np.empty(total, dtype=np.int64)
            tau0 = np.zeros(total)
            tau1 = np.empty(total)
        for i in range(n):
            kept = 0
            if cut[i]:
                k_n = _row_cuts(i, n_acc, n_dec, ta, tc, td, edge_ok, m_edge, step,
                                cruise_edge_s, cand)
                last_d = 0.0
                for j in range(k_n):
                    dj, _v = phase_point(sv[i], cv[i], ev[i], ta[i], tc[i], td[i], cand[j])
                    if dj - last_d >= min_piece_mm and length[i] - dj >= min_piece_mm:
                        if twice:
                            o = offsets[i] + kept
                            tau1[o] = cand[j]
                            tau0[o + 1] = cand[j]
                        kept += 1
                        last_d = dj
            if not twice:
                counts[i] = 1 + kept
            else:
                for o in range(offsets[i], offsets[i + 1]):
                    row[o] = i
                tau1[offsets[i + 1] - 1] = duration[i]
    s0 = np.empty(total)
    s1 = np.empty(total)
    v0 = np.empty(total)
    v1 = np.empty(total)
    for o in range(total):
        i = row[o]
        s0[o], v0[o] = phase_point(sv[i], cv[i], ev[i], ta[i], tc[i], td[i], tau0[o])
        s1[o], v1[o] = phase_point(sv[i], cv[i], ev[i], ta[i], tc[i], td[i], tau1[o])
    for i in range(n):  # exact ends: the row's start speed, its length and end speed
        s0[offsets[i]] = 0.0
        v0[offsets[i]] = sv[i]
        s1[offsets[i + 1] - 1] = length[i]
        v1[offsets[i + 1] - 1] = ev[i]
    return row, tau0, tau1, s0, s1, v0, v1, offsets


@njit(cache=True, error_model="numpy")
def piece_points(row: IntArray, s1_mm: FloatArray, row_length_mm: FloatArray,
                 offsets: IntArray, start: FloatArray, end: FloatArray) -> FloatArray:
    """Toolhead position at every piece's end, ``(n, 3)``: along its row's straight path
    from ``start`` to ``end`` (``(n_rows, 3)``) at the share :attr:`Pieces.fraction_end`,
    every row's last piece exactly at the row's end. As the array expressions give it:
    ``start + f·(end − start)``, then the rows' ends put at ``offsets[r + 1] − 1`` in row
    order (a row without pieces puts its end on the piece before, as they did)."""
    n = row.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        r = row[k]
        length = row_length_mm[r]
        f = s1_mm[k] / length if length > 0 else 1.0
        if k == offsets[r + 1] - 1:
            f = 1.0
        for c in range(3):
            out[k, c] = start[r, c] + f * (end[r, c] - start[r, c])
    if n:
        for r in range(offsets.shape[0] - 1):
            at = offsets[r + 1] - 1
            if at < 0:
                at += n
            for c in range(3):
                out[at, c] = end[r, c]
    return out
