"""Compiled integrator of the extrusion state equation (docs/spec.md §3.4) over a commanded feed.

Private: called by :func:`flowtwin.dynamics.integrator.integrate`, which validates and
casts everything first. One pass over the segments, O(number of segments + events).

State ``x = Δl`` (mm of column compression) and a grinding flag. On every segment the
commanded filament speed is a cubic ``v(τ)``; the segment is first split where ``v``
changes sign, then each piece is advanced regime by regime (``_expint`` FREE / LAG /
SLIP / GRIND) until one of these events ends the regime:

* ``x`` rises through 0 (FREE → LAG/SLIP) or falls through 0 while retracting
  (LAG → FREE): no backflow [001 Fig. 8], the melt never flows back; with ``x < 0`` the
  filament has been pulled away from the melt and nothing comes out until ``x > 0``;
* the feed force ``x/k`` reaches the roller's maximum feed force [000 §4]: the drive
  grinds and stops feeding (GRIND) until the force falls below ``(1 - release)`` times
  the maximum (hysteresis);
* that release.

A segment at constant speed in the slip regime has a constant coefficient and is solved in
closed form; otherwise collocation substeps with the fewest stages that meet the error
bound (:mod:`flowtwin.dynamics._expint`). Speed polynomials travel as four floats and the
accumulators are indexed in place: no array views in the loops (numba reference counts
each view and each array argument with atomic operations).

Event times are located by safeguarded Newton iteration to rounding. Extremes of the
force and flow inside a regime are found at the end points and at the turning point of
``x`` where ``x'`` changes sign between them (at most one turning point is assumed per
regime interval: exact for piecewise-linear feeds; a double turning point inside one
Klipper smoothing piece, shorter than ``smooth_time/2``, is not searched for).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.dynamics._acc_kernel import (
    A_CMD,
    A_FED,
    A_FMAX,
    A_FWD,
    A_GRIND,
    A_GTIME,
    A_OUT,
    A_QMAX,
    A_QMIN,
    A_SEEN,
    A_SLIP,
    A_TIME,
    BAD_FEED,
    BAD_ORDER,
    BUF_ROWS,
    CHUNK,
    N_ACC,
    PRE_ROW,
    S_E,
    S_F,
    S_Q,
    S_SLIP,
    S_T,
    S_VCMD,
    S_VFIL,
    S_X,
    add_row,
    clear_row,
    finish_chunk,
    finish_totals,
)
from flowtwin.dynamics._expint import (
    FREE,
    GRIND,
    LAG,
    SLIP,
    ipoly4,
    poly4,
    shift4,
    slope_factor,
    unowned,
)
from flowtwin.dynamics._regime import advance, constant_speed, event_root, slope, turn_x
from flowtwin.dynamics._roots import hermite_root, speed_roots

__all__ = ["integrate_kernel"]

_EV_NONE = 0
_EV_LEVEL = 1      # x reached a level (0, release) inside the interval
_EV_THRESHOLD = 2  # force reached the maximum feed force
_EV_RELEASE = 3    # force fell to the release level


@njit(cache=True, nogil=True)
def _flush(acc: npt.NDArray[np.float64], row: int, cmd: float, fwd: float, fed: float,
           out: float, slip: float, grind: float, gtime: float, time: float, xhi: float,
           xlo: float, k_s: float, kc: float) -> None:
    """Add a run of pieces of one accumulator row (``xhi``, ``xlo``: extremes of ``Δl``)."""
    acc[row, A_CMD] += cmd
    acc[row, A_TIME] += time
    acc[row, A_FWD] += fwd
    acc[row, A_GRIND] += grind
    acc[row, A_FED] += fed
    acc[row, A_SLIP] += slip
    acc[row, A_GTIME] += gtime
    acc[row, A_OUT] += out
    acc[row, A_SEEN] = 1.0
    # (division is monotone: the largest quotient is the quotient of the largest)
    if xhi / kc > acc[row, A_FMAX]:
        acc[row, A_FMAX] = xhi / kc
    if xhi / k_s > acc[row, A_QMAX]:
        acc[row, A_QMAX] = xhi / k_s
    if xlo / k_s < acc[row, A_QMIN]:
        acc[row, A_QMIN] = xlo / k_s


@njit(cache=True, nogil=True)
def _room(stops: npt.NDArray[np.float64], rows: int) -> npt.NDArray[np.float64]:
    """``stops`` with room for ``rows`` rows (doubled and copied when too small)."""
    if stops.shape[0] >= rows:
        return stops
    grown = np.empty((max(rows, 2 * stops.shape[0]), stops.shape[1]))
    grown[:stops.shape[0]] = stops
    return grown


@njit(cache=True, inline="always")
def _step(values: npt.NDArray[np.float64], nmoves: int) -> int:
    """Index step of a per-move parameter: 1 for ``(nmoves,)``, 0 for one value, -1 for
    any other length."""
    if values.shape[0] == nmoves:
        return 1
    return 0 if values.shape[0] == 1 else -1


@njit(cache=True, nogil=True)
def integrate_kernel(t0: npt.NDArray[np.float64], dt: npt.NDArray[np.float64],
                     coef: npt.NDArray[np.float64], e0: npt.NDArray[np.float64],
                     move: npt.NDArray[np.int64], gap: npt.NDArray[np.bool_],
                     k_s: npt.NDArray[np.float64], kc: npt.NDArray[np.float64],
                     kp: npt.NDArray[np.float64], sa: npt.NDArray[np.float64],
                     sb: npt.NDArray[np.float64], sc: npt.NDArray[np.float64],
                     fmax: npt.NDArray[np.float64], release: float,
                     x_init: float, grind_init: bool, stiffness: float, min_stages: int,
                     sample_t: npt.NDArray[np.float64],
                     samples: npt.NDArray[np.float64], area: float,
                     move_de: npt.NDArray[np.float64], move_t0: npt.NDArray[np.float64],
                     move_t1: npt.NDArray[np.float64],
                     cols: tuple[npt.NDArray[np.float64], ...],
                     grind_col: npt.NDArray[np.bool_], tot: npt.NDArray[np.float64],
                     pre: npt.NDArray[np.float64], ws_own: npt.NDArray[np.float64],
                     roots_own: npt.NDArray[np.float64], buf_own: npt.NDArray[np.float64]
                     ) -> tuple[float, bool, int, int]:
    """Integrate all segments; write the per-move results, ``samples``, the totals and the
    rest before the first move.

    ``k_s`` … ``fmax``: the per-move parameters, each of shape ``(n_moves,)`` or ``(1,)``
    (one value for every move; any other length: ``BAD_FEED``).
    ``move``, ``gap``: owner and stop flag of each segment. The feed is checked on the way
    (no separate pass over it): a move index out of ``[-1, n)``, a move segment without a
    move, a duration not > 0 or a coefficient not finite stops the kernel with
    ``_acc_kernel.BAD_FEED``, segments out of move order (``2 · move + gap`` decreasing)
    with ``BAD_ORDER``; the results are then incomplete. ``cols``, ``grind_col``: the
    result columns (``_acc_kernel.finish_chunk``); ``pre`` ``(N_ACC,)`` receives the
    accumulators of the rest before the first move, ``tot`` ``(2, N_ACC)`` the totals in
    row ``T_SUM`` (``_acc_kernel.add_row``: moves, the rest before them, the stops).

    ``min_stages``: fewest stages a collocation substep may use (6: the fixed 6-stage
    method). ``ws_own`` ``(WS_ROWS, MAX_STAGES)``, ``roots_own`` ``(8,)`` and ``buf_own``
    ``(BUF_ROWS, BUF_WIDTH)``: scratch arrays held by the caller, used through
    ``_expint.unowned`` views (no reference counting in the calls of the loop). Returns
    the final ``Δl`` (mm), the final grinding flag, the number of events and a status (0
    or a ``BAD_*`` code).
    """
    ws = unowned(ws_own)
    roots = unowned(roots_own)
    # a parameter of length 1 is the same for every move (index 0)
    st_k = _step(k_s, move_de.shape[0])
    st_kc = _step(kc, move_de.shape[0])
    st_kp = _step(kp, move_de.shape[0])
    st_sa = _step(sa, move_de.shape[0])
    st_sb = _step(sb, move_de.shape[0])
    st_sc = _step(sc, move_de.shape[0])
    st_fm = _step(fmax, move_de.shape[0])
    if min(st_k, st_kc, st_kp, st_sa, st_sb, st_sc, st_fm) < 0:
        return x_init, grind_init, 0, BAD_FEED
    x = x_init
    grinding = grind_init
    n_events = 0
    ns = sample_t.shape[0]
    js = 0
    nseg = t0.shape[0]
    nmoves = move_de.shape[0]
    buf = unowned(buf_own)
    for r in range(BUF_ROWS):
        clear_row(buf, r)
    for r in range(2):
        for q in range(N_ACC):
            tot[r, q] = 0.0
    base = 0         # first move of the buffer (the moves before it are written)
    n_stops = 0
    stops = np.empty((CHUNK, N_ACC))  # accumulators of the stops, for the totals
    # samples before the first segment: initial state at rest
    while js < ns and nseg > 0 and sample_t[js] < t0[0]:
        samples[js, S_T] = sample_t[js]
        samples[js, S_E] = e0[0]
        samples[js, S_X] = x
        js += 1
    k_last = 1.0
    kc_last = 1.0
    p_par = -1  # the move whose parameters are loaded
    kpp = saa = sbb = scc = thr = rel = 0.0
    has_slip = False
    # accumulators of the current row, kept in registers and flushed when the row changes
    # (same additions in the same order as into the row itself: bit-identical sums)
    cur = -2
    kk = kcc = 1.0
    l_cmd = l_fwd = l_fed = l_out = l_slip = l_grind = l_gtime = l_time = 0.0
    l_xhi = 0.0
    l_xlo = math.inf
    for i in range(nseg):
        c0 = coef[i, 0]
        c1 = coef[i, 1]
        c2 = coef[i, 2]
        c3 = coef[i, 3]
        seg_len = dt[i]
        # parameters of the owning move (a stop: of the move before it); accumulator row
        mi = move[i]
        if mi >= nmoves or mi < -1 or (mi < 0 and not gap[i]) or not seg_len > 0.0 or not (
                math.isfinite(c0) and math.isfinite(c1) and math.isfinite(c2)
                and math.isfinite(c3)):
            return x, grinding, n_events, BAD_FEED
        p = min(max(mi, 0), nmoves - 1)
        slot = 2 * mi + (1 if gap[i] else 0)  # -1: the rest before the first move
        if slot != cur:
            if slot < cur:
                return x, grinding, n_events, BAD_ORDER
            if cur >= -1:
                _flush(buf, PRE_ROW if cur < 0 else cur - 2 * base, l_cmd, l_fwd, l_fed, l_out,
                       l_slip, l_grind, l_gtime, l_time, l_xhi, l_xlo, kk, kcc)
            while mi >= base + CHUNK:
                # past the buffered moves: write their results
                stops = _room(stops, n_stops + CHUNK)
                n_stops = finish_chunk(buf, base, CHUNK, area, move_de, move_t0, move_t1,
                                       cols, grind_col, stops, n_stops, tot)
                base += CHUNK
            cur = slot
            l_cmd = l_fwd = l_fed = l_out = l_slip = l_grind = l_gtime = l_time = 0.0
            l_xhi = 0.0
            l_xlo = math.inf
        if p != p_par:
            # (a move's segments and its stop share its parameters: read once)
            p_par = p
            kk = k_s[p * st_k]
            kcc = kc[p * st_kc]
            k_last = kk
            kc_last = kcc
            kpp = kp[p * st_kp]
            saa = sa[p * st_sa]
            sbb = sb[p * st_sb]
            scc = sc[p * st_sc]
            has_slip = saa != 0.0 or sbb != 0.0
            thr = kcc * fmax[p * st_fm]
            rel = (1.0 - release) * thr
        nr = speed_roots(c0, c1, c2, c3, seg_len, roots)
        pa = 0.0
        for q in range(nr + 1):
            pb = roots[q] if q < nr else seg_len
            if pb <= pa:
                continue
            vpos = poly4(c0, c1, c2, c3, 0.5 * (pa + pb)) > 0.0
            tau = pa
            while tau < pb:
                # regime of the state equation
                if x > 0.0 or (x == 0.0 and vpos):
                    if vpos:
                        if grinding:
                            regime = GRIND
                            ascale = 0.0
                        elif has_slip:
                            regime = SLIP
                            ascale = 1.0 - kpp
                        else:
                            regime = LAG
                            ascale = 1.0 - kpp
                    else:
                        regime = LAG
                        ascale = 1.0
                else:
                    regime = FREE
                    ascale = 1.0 - kpp if vpos else 1.0
                if (regime == LAG or regime == SLIP) and vpos and x >= thr:
                    grinding = True  # starts above the maximum feed force: grind at once
                    n_events += 1
                    continue
                xe, ix, igx = advance(regime, x, c0, c1, c2, c3, tau, pb, ascale, kk, kcc,
                                      saa, sbb, scc, stiffness, min_stages, ws)
                tend = pb
                x_hi_end = xe  # x at the end of the bracket of an event
                event = _EV_NONE
                level = 0.0
                turn_t = -1.0
                if regime == FREE:
                    if vpos and xe > 0.0:
                        event = _EV_LEVEL
                        level = 0.0
                elif regime == GRIND:
                    if xe <= rel:
                        event = _EV_RELEASE
                        level = rel
                        tend = tau + kk * math.log(x / rel)
                        if tend > pb:
                            tend = pb
                        if tend < tau:
                            tend = tau
                elif not vpos:
                    if grinding and xe <= rel:
                        event = _EV_RELEASE
                        level = rel
                    elif xe < 0.0:
                        event = _EV_LEVEL
                        level = 0.0
                else:
                    ya = 0.0
                    yb = 0.0
                    dya = 0.0
                    dyb = 0.0
                    if not constant_speed(c1, c2, c3):
                        # (at constant speed the coefficients are constant: x moves
                        # monotonically towards α/β, no turning point inside)
                        ya, dya = slope(regime, c0, c1, c2, c3, tau, x, ascale, kk, kcc, saa,
                                        sbb, scc)
                        yb, dyb = slope(regime, c0, c1, c2, c3, pb, xe, ascale, kk, kcc, saa,
                                        sbb, scc)
                    if (ya > 0.0 and yb < 0.0) or (ya < 0.0 and yb > 0.0):
                        turn_t = -1.0
                        if regime == LAG and c2 == 0.0 and c3 == 0.0:
                            # linear input: x' = K b1 + (x'(tau) - K b1) e^{-(τ-tau)/K}
                            kb1 = kk * ascale * c1
                            ratio = kb1 / (kb1 - ya)
                            if 0.0 < ratio < 1.0:
                                turn_t = min(max(tau - kk * math.log(ratio), tau), pb)
                        if turn_t < 0.0:
                            turn_t = event_root(1, regime, x, c0, c1, c2, c3, tau, tau, pb, ya, yb,
                                                0.0, 1e-6, ascale, kk, kcc, saa, sbb, scc,
                                                stiffness, min_stages, ws,
                                                hermite_root(tau, pb, ya, dya, yb, dyb))
                    if thr < math.inf:
                        if xe >= thr:
                            event = _EV_THRESHOLD
                            level = thr
                        elif turn_t >= 0.0 and ya > 0.0:
                            xt = turn_x(regime, c0, c1, c2, c3, turn_t, ascale, kk, kcc, saa,
                                        sbb, scc)
                            if xt >= thr:
                                event = _EV_THRESHOLD
                                level = thr
                                tend = turn_t
                                x_hi_end = xt
                if event != _EV_NONE and regime != GRIND:
                    tend = event_root(0, regime, x, c0, c1, c2, c3, tau, tau, tend, x - level,
                                      x_hi_end - level, level, 1e-15, ascale, kk, kcc, saa, sbb,
                                      scc, stiffness, min_stages, ws, -1.0)
                if event != _EV_NONE:
                    n_events += 1
                    xe, ix, igx = advance(regime, x, c0, c1, c2, c3, tau, tend, ascale, kk,
                                          kcc, saa, sbb, scc, stiffness, min_stages, ws)
                    xe = level
                # ---- accumulate over [tau, tend]
                length = tend - tau
                b0, b1, b2, b3 = shift4(c0, c1, c2, c3, tau, 1.0)
                cmd = ipoly4(b0, b1, b2, b3, length)
                l_cmd += cmd
                l_time += length
                if vpos:
                    l_fwd += cmd
                if regime == GRIND:
                    l_grind += cmd
                else:
                    l_fed += ascale * cmd - igx
                    if vpos:
                        l_slip += kpp * cmd + igx
                if grinding:
                    l_gtime += length
                if regime != FREE:
                    l_out += ix / kk
                    xhi = max(x, xe)
                    xlo = min(x, xe)
                    if event == _EV_NONE and turn_t > tau and turn_t < tend:
                        xt = turn_x(regime, c0, c1, c2, c3, turn_t, ascale, kk, kcc, saa, sbb,
                                    scc)
                        xhi = max(xhi, xt)
                        xlo = min(xlo, xt)
                    xlo = max(xlo, 0.0)
                    xhi = max(xhi, 0.0)
                else:
                    xlo = 0.0
                    xhi = 0.0
                if xhi > l_xhi:
                    l_xhi = xhi
                if xlo < l_xlo:
                    l_xlo = xlo
                # ---- samples inside [tau, tend)
                while js < ns and sample_t[js] < t0[i] + tend:
                    ts = sample_t[js] - t0[i]
                    if ts < tau:
                        ts = tau
                    xs = advance(regime, x, c0, c1, c2, c3, tau, ts, ascale, kk, kcc, saa,
                                 sbb, scc, stiffness, min_stages, ws)[0]
                    v = poly4(c0, c1, c2, c3, ts)
                    if regime == GRIND:
                        vfil = 0.0
                    elif regime == SLIP:
                        vfil = ascale * v - v * slope_factor(v, saa, sbb, scc) / kcc * xs
                    else:
                        vfil = ascale * v
                    samples[js, S_T] = sample_t[js]
                    samples[js, S_E] = e0[i] + ipoly4(c0, c1, c2, c3, ts)
                    samples[js, S_VCMD] = v
                    samples[js, S_VFIL] = vfil
                    xp = max(xs, 0.0)
                    samples[js, S_Q] = xp / kk
                    samples[js, S_F] = xp / kcc
                    samples[js, S_SLIP] = 1.0 - vfil / v if v > 0.0 else 0.0
                    samples[js, S_X] = xs
                    js += 1
                # ---- state change
                x = xe
                tau = tend
                if event == _EV_THRESHOLD:
                    grinding = True
                elif event == _EV_RELEASE:
                    grinding = False
            pa = pb
    if cur >= -1:
        _flush(buf, PRE_ROW if cur < 0 else cur - 2 * base, l_cmd, l_fwd, l_fed, l_out, l_slip,
               l_grind, l_gtime, l_time, l_xhi, l_xlo, k_last, kc_last)
    while base < nmoves:
        count = min(CHUNK, nmoves - base)
        stops = _room(stops, n_stops + count)
        n_stops = finish_chunk(buf, base, count, area, move_de, move_t0, move_t1, cols,
                               grind_col, stops, n_stops, tot)
        base += count
    # totals in the order moves, rest before the first move, stops
    add_row(tot, buf, PRE_ROW)
    for r in range(n_stops):
        add_row(tot, stops, r)
    finish_totals(tot)
    for q in range(N_ACC):
        pre[q] = buf[PRE_ROW, q]
    # samples after the end: final state at rest
    e_end = 0.0
    if nseg > 0:
        e_end = e0[nseg - 1] + ipoly4(coef[nseg - 1, 0], coef[nseg - 1, 1], coef[nseg - 1, 2],
                                      coef[nseg - 1, 3], dt[nseg - 1])
    while js < ns:
        samples[js, S_T] = sample_t[js]
        samples[js, S_E] = e_end
        xp = max(x, 0.0)
        samples[js, S_Q] = xp / k_last
        samples[js, S_F] = xp / kc_last
        samples[js, S_X] = x
        js += 1
    return x, grinding, n_events, 0
