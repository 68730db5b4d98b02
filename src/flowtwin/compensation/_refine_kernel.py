"""Compiled kernels of the refinement: the linear lag model, forward and adjoint.

State ``x`` = filament compression in E grid units (docs/spec.md §3.4 without slip):
``dx/dt = u(t) − x/K`` with the input ``u = c·v(t)`` on a segment of constant
acceleration (path speed ``v`` linear from ``v_a`` to ``v_b`` in ``T``, slope ``α``).
Exactly::

    x(T) = e·x(0) + c·G,   e = exp(−T/K),
    G = ∫₀ᵀ v(τ)·e^(−(T−τ)/K) dτ = v_b·K·(1 − e) − α·K²·(1 − e·(1 + T/K))

and the melt out of the segment is ``c·L − (x(T) − x(0))`` (mass balance). Every segment is
therefore the affine map ``x_s = A_s·x_(s−1) + B_s·c_(p(s)) + C_s`` (fixed moves put their
input into ``C_s``; a retraction holds the state: ``A = 1``). The output of move ``m`` is
``O_m = Σ_(s∈m) c·L_s − x_end(m) + x_start(m)``; the adjoint pass gives the gradient of
``Σ_m w_m·(O_m − I_m)²`` with respect to the ratios ``c``.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["first_segments", "lag_gain", "model_columns", "model_pass", "phase_point",
           "piece_segments", "row_starts", "segment_states"]


@njit(cache=True)
def lag_gain(t_s: float, k_s: float, v_a: float, v_b: float) -> tuple[float, float]:
    """``(e, G)`` of a segment (see the module docstring); stable for ``T ≪ K``."""
    if t_s <= 0.0:
        return 1.0, 0.0
    y = t_s / k_s
    e = math.exp(-y)
    one_minus_e = -math.expm1(-y)
    if y < 1e-3:  # 1 − e(1 + y) = y²/2 − y³/3 + y⁴/8 − …
        second = y * y * (0.5 - y / 3.0 + y * y / 8.0)
    else:
        second = one_minus_e - y * e
    alpha = (v_b - v_a) / t_s
    return e, v_b * k_s * one_minus_e - alpha * k_s * k_s * second


@njit(cache=True)
def model_pass(c: npt.NDArray[np.float64], seg_piece: npt.NDArray[np.int64],
               seg_fixed: npt.NDArray[np.float64], seg_len: npt.NDArray[np.float64],
               seg_a: npt.NDArray[np.float64], seg_b: npt.NDArray[np.float64],
               seg_c: npt.NDArray[np.float64], seg_row: npt.NDArray[np.int64],
               seg_first: npt.NDArray[np.bool_], seg_last: npt.NDArray[np.bool_],
               intent: npt.NDArray[np.float64], weight: npt.NDArray[np.float64],
               out_rows: npt.NDArray[np.float64], grad: npt.NDArray[np.float64]) -> float:
    """Forward model, objective and its gradient.

    Parameters
    ----------
    c
        Ratios of the free pieces, ``(p,)``.
    seg_piece
        Free piece of each segment, or −1 (fixed input), ``(s,)``.
    seg_fixed
        Ratio of fixed segments, ``(s,)``.
    seg_len
        Path length of each segment, ``(s,)``.
    seg_a, seg_b, seg_c
        Affine map of each segment (``seg_c`` already holds fixed inputs), ``(s,)``.
    seg_row
        Objective move of each segment, or −1, ``(s,)``.
    seg_first, seg_last
        Segment is the first / last of its objective move, ``(s,)``.
    intent
        Intended E of every objective move, ``(m,)``.
    weight
        Weight of each move's squared error, ``(m,)``.
    out_rows
        Output: model E out of every objective move, ``(m,)``.
    grad
        Output: gradient with respect to ``c``, ``(p,)``.

    Returns
    -------
    float
        ``Σ_m w_m·(O_m − I_m)²``.
    """
    n = seg_piece.shape[0]
    m = intent.shape[0]
    x_start = np.zeros(m)
    x_end = np.zeros(m)
    for k in range(m):
        out_rows[k] = 0.0
    x = 0.0
    for s in range(n):
        p = seg_piece[s]
        cv = c[p] if p >= 0 else seg_fixed[s]
        row = seg_row[s]
        if row >= 0 and seg_first[s]:
            x_start[row] = x
        x = seg_a[s] * x + seg_b[s] * cv + seg_c[s]
        if row >= 0:
            out_rows[row] += cv * seg_len[s]
            if seg_last[s]:
                x_end[row] = x
    total = 0.0
    g_row = np.empty(m)
    for k in range(m):
        out_rows[k] -= x_end[k] - x_start[k]
        r = out_rows[k] - intent[k]
        total += weight[k] * r * r
        g_row[k] = 2.0 * weight[k] * r
    for k in range(grad.shape[0]):
        grad[k] = 0.0
    lam = 0.0
    for s in range(n - 1, -1, -1):
        row = seg_row[s]
        p = seg_piece[s]
        if row >= 0 and seg_last[s]:
            lam -= g_row[row]
        if p >= 0:
            grad[p] += seg_b[s] * lam
            if row >= 0:
                grad[p] += g_row[row] * seg_len[s]
        lam = seg_a[s] * lam
        if row >= 0 and seg_first[s]:
            lam += g_row[row]
    return total


@njit(cache=True)
def segment_maps(t_s: npt.NDArray[np.float64], k_s: npt.NDArray[np.float64],
                 v_a: npt.NDArray[np.float64], v_b: npt.NDArray[np.float64],
                 e_out: npt.NDArray[np.float64], g_out: npt.NDArray[np.float64]) -> None:
    """:func:`lag_gain` of many segments."""
    for s in range(t_s.shape[0]):
        e, g = lag_gain(t_s[s], k_s[s], v_a[s], v_b[s])
        e_out[s] = e
        g_out[s] = g


@njit(cache=True)
def apply_holds(row_seg0: npt.NDArray[np.int64], row_seg1: npt.NDArray[np.int64],
                row_free: npt.NDArray[np.bool_], row_de: npt.NDArray[np.float64],
                row_relief: npt.NDArray[np.bool_], seg_a: npt.NDArray[np.float64],
                seg_b: npt.NDArray[np.float64], seg_c: npt.NDArray[np.float64]) -> int:
    """Hold the state through retractions (no backflow [001 Fig. 8]).

    A retraction pulls the filament off the melt: the compression goes negative, nothing
    flows and nothing decays until the filament is pushed back. From a row with negative
    E until the E since then adds up to zero again, segments keep the state
    (``A = 1, B = C = 0``); a surplus of the push-back is added at its end, a deficit
    at the end of the hold, just before the next printing move. ``row_relief`` marks
    travels that will carry a pressure-relief retraction whose push-back leaves the
    column relaxed: the next
    printing move then starts from ``x = 0``. Rows are given by their segment ranges
    ``row_seg0[i]:row_seg1[i]``. Returns the number of holds.
    """
    holding = False
    reset = False
    net = 0.0
    holds = 0
    for i in range(row_seg0.shape[0]):
        s0 = row_seg0[i]
        s1 = row_seg1[i]
        if s1 <= s0:
            if not row_free[i] and holding:
                net += row_de[i]
            continue
        if row_free[i]:
            if holding and s0 > 0:
                # end of the hold, on its last (held) segment, so that the printing move's
                # own start state already includes it
                if reset:
                    seg_a[s0 - 1] = 0.0
                    seg_c[s0 - 1] = 0.0
                else:
                    seg_c[s0 - 1] += net
            holding = False
            continue
        if not holding and (row_de[i] < 0.0 or row_relief[i]):
            holding = True
            reset = row_relief[i]
            net = 0.0
            holds += 1
        if holding:
            net += row_de[i]
            for s in range(s0, s1):
                seg_a[s] = 1.0
                seg_b[s] = 0.0
                seg_c[s] = 0.0
            if net >= -1e-9 and not reset:
                seg_c[s1 - 1] = max(net, 0.0)
                holding = False
    return holds


@njit(cache=True)
def free_piece_chain(seg_piece: npt.NDArray[np.int64], seg_a: npt.NDArray[np.float64],
                     seg_b: npt.NDArray[np.float64], seg_c: npt.NDArray[np.float64],
                     seg_len: npt.NDArray[np.float64], alpha: npt.NDArray[np.float64],
                     kappa: npt.NDArray[np.float64], e_p: npt.NDArray[np.float64],
                     b_p: npt.NDArray[np.float64], k_p: npt.NDArray[np.float64],
                     l_p: npt.NDArray[np.float64]) -> None:
    """Collapse the segment maps onto the free pieces.

    With ``x_p`` the state after free piece ``p``: the state before it is
    ``α_p·x_(p−1) + κ_p`` (everything fixed in between composed), and
    ``x_p = E_p·(α_p·x_(p−1) + κ_p) + B_p·c_p + K_p``; ``L_p`` is its path length.
    """
    big_a = 1.0
    big_k = 0.0
    cur = -1
    e = 1.0
    b = 0.0
    k = 0.0
    length = 0.0
    for s in range(seg_piece.shape[0]):
        p = seg_piece[s]
        a = seg_a[s]
        if p >= 0:
            if p != cur:
                alpha[p] = big_a
                kappa[p] = big_k
                e = 1.0
                b = 0.0
                k = 0.0
                length = 0.0
                cur = p
            e = a * e
            b = a * b + seg_b[s]
            k = a * k + seg_c[s]
            length += seg_len[s]
            e_p[p] = e
            b_p[p] = b
            k_p[p] = k
            l_p[p] = length
            big_a = 1.0
            big_k = 0.0
        else:
            big_a = a * big_a
            big_k = a * big_k + seg_c[s]
            cur = -1


@njit(cache=True)
def chain_states(alpha: npt.NDArray[np.float64], kappa: npt.NDArray[np.float64],
                 e_p: npt.NDArray[np.float64], b_p: npt.NDArray[np.float64],
                 k_p: npt.NDArray[np.float64], c: npt.NDArray[np.float64],
                 out: npt.NDArray[np.float64]) -> None:
    """``x_p = E_p·(α_p·x_(p−1) + κ_p) + B_p·c_p + K_p`` for every free piece, ``x_(−1) = 0``."""
    x = 0.0
    for p in range(c.shape[0]):
        x = e_p[p] * (alpha[p] * x + kappa[p]) + b_p[p] * c[p] + k_p[p]
        out[p] = x


@njit(cache=True)
def segment_states(c: npt.NDArray[np.float64], seg_piece: npt.NDArray[np.int64],
                   seg_fixed: npt.NDArray[np.float64], seg_a: npt.NDArray[np.float64],
                   seg_b: npt.NDArray[np.float64], seg_c: npt.NDArray[np.float64],
                   out: npt.NDArray[np.float64]) -> None:
    """State after every segment, ``x_s = A_s·x_(s−1) + B_s·c + C_s`` from ``x = 0``."""
    x = 0.0
    for s in range(seg_piece.shape[0]):
        p = seg_piece[s]
        cv = c[p] if p >= 0 else seg_fixed[s]
        x = seg_a[s] * x + seg_b[s] * cv + seg_c[s]
        out[s] = x


@njit(cache=True)
def phase_point(sv: float, cv: float, ev: float, ta: float, tc: float, td: float,
                 tau_s: float) -> tuple[float, float]:
    """Path distance and speed ``τ`` after a trapezoid's start
    (:func:`flowtwin.compensation.pieces.phase_distance_mm` for one move, the same
    operations in the same order)."""
    tau = min(max(tau_s, 0.0), ta + tc + td)
    a_up = (cv - sv) / ta if ta > 0 else 0.0
    a_dn = (cv - ev) / td if td > 0 else 0.0
    t1 = min(tau, ta)
    d = sv * t1 + 0.5 * a_up * t1 * t1
    v = sv + a_up * t1
    t2 = min(max(tau - ta, 0.0), tc)
    d = d + cv * t2
    t3 = min(max(tau - ta - tc, 0.0), td)
    d = d + cv * t3 - 0.5 * a_dn * t3 * t3
    if tau > ta:
        v = cv - a_dn * t3
    return d, v


@njit(cache=True)
def piece_segments(row: npt.NDArray[np.int64], t0_s: npt.NDArray[np.float64],
                   t1_s: npt.NDArray[np.float64], first_of_row: npt.NDArray[np.bool_],
                   t0_row: npt.NDArray[np.float64], ta: npt.NDArray[np.float64],
                   tc: npt.NDArray[np.float64], td: npt.NDArray[np.float64],
                   sv: npt.NDArray[np.float64], cv: npt.NDArray[np.float64],
                   ev: npt.NDArray[np.float64], gap: npt.NDArray[np.float64]
                   ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64],
                              npt.NDArray[np.float64], npt.NDArray[np.float64],
                              npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Segments of constant acceleration of every piece, with the rest before a row.

    A piece falls into its move's accel/cruise/decel phases (those of positive duration;
    one empty segment when none has); a rest segment (piece −1, the gap's duration, no
    path) comes before the first piece of a row that starts ``gap[row] > 0`` after the
    row before ends. Returns the piece (−1: rest), duration, path length, speeds at both
    ends and owner row of every segment.
    """
    n_p = row.shape[0]
    cap = 4 * n_p
    seg_piece = np.empty(cap, dtype=np.int64)
    seg_t = np.empty(cap)
    seg_len = np.empty(cap)
    seg_va = np.empty(cap)
    seg_vb = np.empty(cap)
    owner = np.empty(cap, dtype=np.int64)
    b = np.empty(4)
    d = np.empty(4)
    v = np.empty(4)
    k = 0
    for p in range(n_p):
        r = row[p]
        tau0 = t0_s[p] - t0_row[r]
        tau1 = t1_s[p] - t0_row[r]
        b[0] = tau0
        b[1] = min(max(ta[r], tau0), tau1)
        b[2] = min(max(ta[r] + tc[r], tau0), tau1)
        b[3] = tau1
        for j in range(4):
            d[j], v[j] = phase_point(sv[r], cv[r], ev[r], ta[r], tc[r], td[r], b[j])
        if first_of_row[p] and gap[r] > 0:
            seg_piece[k] = -1
            seg_t[k] = gap[r]
            seg_len[k] = 0.0
            seg_va[k] = 0.0
            seg_vb[k] = 0.0
            owner[k] = r
            k += 1
        for j in range(3):
            dur = b[j + 1] - b[j]
            if dur > 0.0 or (j == 0 and not (b[2] - b[1] > 0.0 or b[3] - b[2] > 0.0)):
                seg_piece[k] = p
                seg_t[k] = dur
                seg_len[k] = d[j + 1] - d[j]
                seg_va[k] = v[j]
                seg_vb[k] = v[j + 1]
                owner[k] = r
                k += 1
    return (seg_piece[:k].copy(), seg_t[:k].copy(), seg_len[:k].copy(), seg_va[:k].copy(),
            seg_vb[:k].copy(), owner[:k].copy())


@njit(cache=True)
def first_segments(seg_piece: npt.NDArray[np.int64], n_free: int) -> npt.NDArray[np.int64]:
    """First segment of every free piece (``seg_piece`` its free piece, or −1), −1 for a
    piece without one, shape ``(n_free,)``."""
    out = np.full(n_free, -1, dtype=np.int64)
    for s in range(seg_piece.shape[0]):
        p = seg_piece[s]
        if 0 <= p < n_free and out[p] < 0:
            out[p] = s
    return out


@njit(cache=True)
def row_starts(seg_gap: npt.NDArray[np.bool_], seg_owner: npt.NDArray[np.int64],
               states: npt.NDArray[np.float64], out: npt.NDArray[np.float64]) -> None:
    """State before the first own (non-gap) segment of every stretch of one row's
    segments, at ``out[row]`` (0 before the first segment; a later stretch of the same row
    overwrites an earlier one)."""
    prev = -1
    started = False
    for s in range(seg_gap.shape[0]):
        if seg_gap[s]:
            continue
        row = seg_owner[s]
        if not started or row != prev:
            out[row] = states[s - 1] if s > 0 else 0.0
        started = True
        prev = row


@njit(cache=True)
def model_columns(seg_piece: npt.NDArray[np.int64], owner: npt.NDArray[np.int64],
                  var_of_piece: npt.NDArray[np.int64], piece_ratio: npt.NDArray[np.float64],
                  g: npt.NDArray[np.float64], row_free: npt.NDArray[np.bool_],
                  row_de: npt.NDArray[np.float64], row_hold: npt.NDArray[np.bool_],
                  row_group: npt.NDArray[np.int64]):  # type: ignore[no-untyped-def]
    """The lag model's per-segment columns and its units (gaps and rows, in time order).

    For every segment (``seg_piece``: its piece, −1 for the rest before ``owner``):
    its free variable (or −1), fixed ratio (0 in a gap), ``B`` (``G`` for a free piece),
    ``C`` (``G·ratio`` otherwise), objective row (the owner's group; −1 in a gap) and
    whether it is the first / last segment of its objective row's stretch. Every unit
    (a run of segments of one gap or one row) with its first and end segment, and its
    row's freedom, E and hold (none for a gap).
    """
    n = seg_piece.shape[0]
    seg_var = np.empty(n, dtype=np.int64)
    ratio = np.empty(n)
    seg_b = np.empty(n)
    seg_c = np.empty(n)
    seg_row = np.empty(n, dtype=np.int64)
    first = np.zeros(n, dtype=np.bool_)
    last = np.zeros(n, dtype=np.bool_)
    n_units = 0
    for s in range(n):
        gap = seg_piece[s] < 0
        if s == 0 or gap != (seg_piece[s - 1] < 0) or owner[s] != owner[s - 1]:
            n_units += 1
        p = max(seg_piece[s], 0)
        seg_var[s] = -1 if gap else var_of_piece[p]
        ratio[s] = 0.0 if gap else piece_ratio[p]
        seg_b[s] = g[s] if seg_var[s] >= 0 else 0.0
        seg_c[s] = 0.0 if seg_var[s] >= 0 else g[s] * ratio[s]
        seg_row[s] = -1 if gap else row_group[owner[s]]
    unit_start = np.empty(n_units, dtype=np.int64)
    unit_end = np.empty(n_units, dtype=np.int64)
    unit_free = np.empty(n_units, dtype=np.bool_)
    unit_de = np.empty(n_units)
    unit_hold = np.empty(n_units, dtype=np.bool_)
    k = -1
    for s in range(n):
        gap = seg_piece[s] < 0
        if s == 0 or gap != (seg_piece[s - 1] < 0) or owner[s] != owner[s - 1]:
            k += 1
            unit_start[k] = s
            if k > 0:
                unit_end[k - 1] = s
            r = owner[s]
            unit_free[k] = False if gap else row_free[r]
            unit_de[k] = 0.0 if gap else row_de[r]
            unit_hold[k] = False if gap else row_hold[r]
    if n_units:
        unit_end[n_units - 1] = n
    prev = -1  # the objective rows' stretches, over segments that count
    for s in range(n):
        if seg_row[s] < 0:
            continue
        if prev < 0 or seg_row[s] != seg_row[prev]:
            first[s] = True
            if prev >= 0:
                last[prev] = True
        prev = s
    if prev >= 0:
        last[prev] = True
    return (seg_var, ratio, seg_b, seg_c, seg_row, first, last, unit_start, unit_end,
            unit_free, unit_de, unit_hold)
