"""A sparse convex quadratic program with two-sided linear bounds (primal-dual interior point).

Solves ::

    minimise   ½·xᵀHx + ½·Σ_k w_k·(R_k·x)² + gᵀx
    subject to lo ≤ C·x + d ≤ hi          (lo finite; hi may be +inf)

with ``H`` symmetric positive (semi)definite, ``w > 0`` and ``H + Cᵀ·D·C`` positive
definite for positive diagonals ``D``. Mehrotra's predictor–corrector on the slacks
``s = Cx + d − lo ≥ 0``, ``t = hi − Cx − d ≥ 0`` and their multipliers ``z, w ≥ 0``
(centring ``σ = min(1, (μ_aff/μ)³)``, one step length for primal and dual; a corrected
step that would not lower the gap is replaced by the centred step without the
second-order term); the starting point is the predictor's full step from the given ``x``
with slacks and multipliers moved away from zero (§16.6's heuristic). Every Newton step
solves ``(H + Rᵀ·W·R + Cᵀ(z/s + w/t)C)·Δx = r``. Nocedal & Wright, *Numerical
Optimization* (2nd ed.), §16.6.

The squared rows ``R_k`` are kept as rows: a row reading ``ℓ`` variables (a move of the
lag model cut into ``ℓ`` pieces) would put a dense ``ℓ × ℓ`` block into ``Rᵀ·W·R``. The
step instead solves the equivalent quasi-definite system
``[[H + Cᵀ·D·C, Rᵀ], [R, −W⁻¹]]·[Δx; ν] = [r; 0]`` (``ν = W·R·Δx``), every ``ν_k`` ordered
right after the last variable its row reads; its ``L·D·Lᵀ`` factor (Vanderbei, *SIAM J.
Optim.* 5 (1995): a quasi-definite matrix has one in every symmetric order) fills only the
envelope, which grows with ``ℓ``, not ``ℓ²``.

The program falls apart into **independent blocks** wherever no entry of ``H``, no row of
``C`` and no squared row joins a variable to the next one (the lag model's runs between
relieved travels: their states do not carry over). Every block is solved on its own by a
compiled interior-point loop (:func:`_solve_blocks`), whose steps factorise in envelope
storage (:func:`envelope_ldl`), so the cost is linear in the number of variables; the
blocks are solved in parallel.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import set_parallel_chunksize

from flowtwin._jit import njit, prange
from flowtwin.compensation._qp_blocks import block_layout, qp_blocks

__all__ = ["envelope_ldl", "envelope_ldl_solve", "qp_blocks", "solve_program"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Blocks a thread takes at a time in :func:`_solve_blocks`.
_CHUNK_BLOCKS = 4
#: Least decrease of the gap per unit step the corrected step must give.
_MIN_GAP_DECREASE = 0.01
#: Largest product slack × multiplier the starting point's floor gives a pair.
_START_GAP = 10.0


@njit(cache=True, error_model="numpy")
def envelope_ldl(first: IntArray, ptr: IntArray, m: FloatArray, sign: npt.NDArray[np.int8],
                 out: FloatArray) -> bool:
    """``M = L·D·Lᵀ`` (``L`` unit lower) of a symmetric matrix in envelope storage.

    Row ``i`` of the lower triangle holds columns ``first[i] … i`` at
    ``m[ptr[i] : ptr[i + 1]]`` (so ``M[i, j] = m[ptr[i] + j − first[i]]``); the factor
    fills no entry outside the envelope and is stored the same way in ``out``, ``D`` on the
    diagonal. The work is ``Σ (i − first[i])²/2``: a move cut into many pieces widens the
    envelope of its own rows only. ``M`` must be *quasi-definite* with the pivot signs
    ``sign`` (``+1``: positive, ``−1``: negative; Vanderbei 1995: such a matrix has this
    factorisation in every symmetric ordering); returns ``False`` when a pivot has the
    wrong sign or is zero (numerically).
    """
    n = first.shape[0]
    u = np.empty(n)  # L[i, k]·D[k] of the current row
    for i in range(n):
        fi = first[i]
        pi = ptr[i] - fi
        for j in range(fi, i):
            fj = first[j]
            pj = ptr[j] - fj
            s = m[pi + j]
            for k in range(max(fi, fj), j):
                s -= u[k] * out[pj + k]
            u[j] = s
            out[pi + j] = s / out[pj + j]
        s = m[pi + i]
        for k in range(fi, i):
            s -= u[k] * out[pi + k]
        if not s * sign[i] > 0.0:
            return False
        out[pi + i] = s
    return True


@njit(cache=True, error_model="numpy")
def envelope_ldl_solve(first: IntArray, ptr: IntArray, f: FloatArray, rhs: FloatArray,
                       out: FloatArray) -> None:
    """Solve ``L·D·Lᵀ·x = rhs`` with the factor of :func:`envelope_ldl`."""
    n = first.shape[0]
    for i in range(n):  # L y = rhs
        fi = first[i]
        pi = ptr[i] - fi
        s = rhs[i]
        for k in range(fi, i):
            s -= f[pi + k] * out[k]
        out[i] = s
    for i in range(n):  # D z = y
        out[i] /= f[ptr[i + 1] - 1]
    for i in range(n - 1, -1, -1):  # Lᵀ x = z
        fi = first[i]
        pi = ptr[i] - fi
        xi = out[i]
        for k in range(fi, i):
            out[k] -= f[pi + k] * xi


@njit(cache=True, error_model="numpy", inline="always")
def _step_to_zero(value: float, change: float, step: float) -> float:
    """``−value/change`` when ``change < 0`` and that is below ``step`` (a NaN is no
    candidate), else ``step``. The division is made every time, so that the test
    compiles without a branch."""
    ratio = -value / change
    return ratio if change < 0.0 and ratio < step else step


@njit(cache=True, error_model="numpy")
def _augmented_envelope(a, e, h_ptr0, h_ptr1, h_r, h_c, c_ptr, c_col, r0, r1,  # type: ignore[no-untyped-def]
                        r_ptr, r_col, q0, q1):
    """Order and envelope of a block's step matrix with one extra row per squared row.

    Variable ``i`` of the block (``a ≤ a + i < e``) goes to ``pos[i]``; squared row
    ``q0 + k`` to ``pos_r[k]``, right after the last variable it reads (rows sorted by
    that variable). Returns ``pos, pos_r, first, ptr, sign``.
    """
    n = e - a
    nr = q1 - q0
    pos = np.empty(n, dtype=np.int64)
    pos_r = np.empty(nr, dtype=np.int64)
    big = n + nr
    sign = np.ones(big, dtype=np.int8)
    last = np.empty(nr, dtype=np.int64)
    for k in range(nr):
        last[k] = -1
        for t in range(r_ptr[q0 + k], r_ptr[q0 + k + 1]):
            last[k] = max(last[k], r_col[t] - a)
    k = 0
    p = 0
    for i in range(n):
        pos[i] = p
        p += 1
        while k < nr and last[k] <= i:
            pos_r[k] = p
            sign[p] = -1
            p += 1
            k += 1
    first = np.arange(big)
    for t in range(h_ptr0, h_ptr1):
        lo_c = pos[min(h_r[t], h_c[t]) - a]
        hi_c = pos[max(h_r[t], h_c[t]) - a]
        if lo_c < first[hi_c]:
            first[hi_c] = lo_c
    for q in range(r0, r1):
        mn = big
        for t in range(c_ptr[q], c_ptr[q + 1]):
            mn = min(mn, pos[c_col[t] - a])
        for t in range(c_ptr[q], c_ptr[q + 1]):
            cj = pos[c_col[t] - a]
            if mn < first[cj]:
                first[cj] = mn
    for k in range(nr):
        for t in range(r_ptr[q0 + k], r_ptr[q0 + k + 1]):
            cj = pos[r_col[t] - a]
            if cj < first[pos_r[k]]:
                first[pos_r[k]] = cj
    ptr = np.empty(big + 1, dtype=np.int64)
    ptr[0] = 0
    for i in range(big):
        ptr[i + 1] = ptr[i] + i - first[i] + 1
    return pos, pos_r, first, ptr, sign


@njit(cache=True, error_model="numpy")
def _solve_block(x, h_ptr0, h_ptr1, h_r, h_c, h_v, g, c_ptr, c_col, c_val, r0, r1, d, lo, hi,  # type: ignore[no-untyped-def]
                 r_ptr, r_col, r_val, r_w, q0, q1, a, e, max_iterations, tolerance):
    """Interior-point loop on variables ``a:e``, constraint rows ``r0:r1`` and squared rows
    ``q0:q1``; ``x`` (the whole vector) is updated in place. Returns the iterations.

    The step matrix ``H + Rᵀ·W·R + Cᵀ·D·C`` is never formed: with ``ν = W·R·Δx`` the step
    solves the quasi-definite system ``[[H + Cᵀ·D·C, Rᵀ], [R, −W⁻¹]]`` (one ``ν`` per
    squared row, ordered after the last variable it reads), whose envelope grows with the
    length of a row, not with its square.
    """
    n = e - a
    m = r1 - r0
    nr = q1 - q0
    fin = np.empty(m, dtype=np.bool_)
    s = np.empty(m)
    t = np.empty(m)
    z = np.ones(m)
    w = np.empty(m)
    y = np.empty(m)
    r_l = np.empty(m)
    r_u = np.empty(m)
    xl = x[a:e].copy()
    for q in range(m):
        i = r0 + q
        fin[q] = hi[i] < np.inf
        v = d[i]
        for p in range(c_ptr[i], c_ptr[i + 1]):
            v += c_val[p] * xl[c_col[p] - a]
        span = hi[i] - lo[i] if fin[q] else 1.0
        s[q] = max(v - lo[i], 1e-3 * span)
        t[q] = max(hi[i] - v, 1e-3 * span) if fin[q] else 1.0
        w[q] = 1.0 if fin[q] else 0.0
    n_c = m
    for q in range(m):
        if fin[q]:
            n_c += 1
    gmax = 1.0
    for i in range(a, e):
        if abs(g[i]) > gmax:
            gmax = abs(g[i])
    lomax = 0.0
    for q in range(m):
        if abs(lo[r0 + q]) > lomax:
            lomax = abs(lo[r0 + q])
    mu0 = 0.0
    for q in range(m):
        mu0 += s[q] * z[q] + t[q] * w[q]
    mu0 = max(mu0 / max(n_c, 1), 1e-300)
    pos, pos_r, first, ptr, sign = _augmented_envelope(a, e, h_ptr0, h_ptr1, h_r, h_c, c_ptr,
                                                       c_col, r0, r1, r_ptr, r_col, q0, q1)
    big = n + nr
    size = ptr[big]
    hb = np.zeros(size)  # the constant part: H, R and −W⁻¹
    for p in range(h_ptr0, h_ptr1):
        lo_c = pos[min(h_r[p], h_c[p]) - a]
        hi_c = pos[max(h_r[p], h_c[p]) - a]
        hb[ptr[hi_c] + lo_c - first[hi_c]] += h_v[p]
    for k in range(nr):
        row = pos_r[k]
        for p in range(r_ptr[q0 + k], r_ptr[q0 + k + 1]):
            hb[ptr[row] + pos[r_col[p] - a] - first[row]] += r_val[p]
        hb[ptr[row + 1] - 1] -= 1.0 / r_w[q0 + k]
    p_0 = c_ptr[r0]
    nnz = c_ptr[r1] - p_0
    lcol = np.empty(nnz, dtype=np.int64)  # local column and position of every entry
    lpos = np.empty(nnz, dtype=np.int64)
    for p in range(p_0, c_ptr[r1]):
        lcol[p - p_0] = c_col[p] - a
        lpos[p - p_0] = pos[c_col[p] - a]
    n_pairs = 0
    for q in range(m):
        i = r0 + q
        for p in range(c_ptr[i], c_ptr[i + 1]):
            for p2 in range(c_ptr[i], c_ptr[i + 1]):
                if lpos[p - p_0] <= lpos[p2 - p_0]:
                    n_pairs += 1
    pair_at = np.empty(n_pairs, dtype=np.int64)  # C^T D C: entry of the envelope and the
    pair_c = np.empty(n_pairs)                   # two constraint entries, by row
    pair_c2 = np.empty(n_pairs)
    pair_ptr = np.empty(m + 1, dtype=np.int64)
    k = 0
    for q in range(m):
        i = r0 + q
        pair_ptr[q] = k
        for p in range(c_ptr[i], c_ptr[i + 1]):
            ci = lpos[p - p_0]
            for p2 in range(c_ptr[i], c_ptr[i + 1]):
                cj = lpos[p2 - p_0]
                if ci <= cj:
                    pair_at[k] = ptr[cj] + ci - first[cj]
                    pair_c[k] = c_val[p]
                    pair_c2[k] = c_val[p2]
                    k += 1
    pair_ptr[m] = k
    diag_at = np.empty(n, dtype=np.int64)
    for i in range(n):
        diag_at[i] = ptr[pos[i] + 1] - 1
    ab = np.empty(size)
    uf = np.empty(size)
    r_d = np.empty(n)
    rhs = np.zeros(big)
    sol = np.empty(big)
    dx = np.empty(n)
    ds = np.empty(m)
    dt = np.empty(m)
    dz = np.empty(m)
    dw = np.empty(m)
    rc_l = np.empty(m)
    rc_u = np.empty(m)
    dd = np.empty(m)
    it = 0
    while it < max_iterations:
        it += 1
        # residuals
        for i in range(n):
            r_d[i] = g[a + i]
        for p in range(h_ptr0, h_ptr1):  # H x (symmetric, one triangle stored)
            i = h_r[p] - a
            j = h_c[p] - a
            r_d[i] += h_v[p] * xl[j]
            if i != j:
                r_d[j] += h_v[p] * xl[i]
        for k in range(nr):  # Rᵀ W R x
            v = 0.0
            for p in range(r_ptr[q0 + k], r_ptr[q0 + k + 1]):
                v += r_val[p] * xl[r_col[p] - a]
            v *= r_w[q0 + k]
            for p in range(r_ptr[q0 + k], r_ptr[q0 + k + 1]):
                r_d[r_col[p] - a] += r_val[p] * v
        mu = 0.0
        pmax = 0.0
        for q in range(m):
            i = r0 + q
            v = d[i]
            for p in range(c_ptr[i], c_ptr[i + 1]):
                v += c_val[p] * xl[lcol[p - p_0]]
            y[q] = v
            zw = z[q] - w[q]
            for p in range(c_ptr[i], c_ptr[i + 1]):
                r_d[lcol[p - p_0]] -= c_val[p] * zw
            r_l[q] = v - lo[i] - s[q]
            r_u[q] = hi[i] - v - t[q] if fin[q] else 0.0
            mu += s[q] * z[q] + t[q] * w[q]
            if abs(r_l[q]) > pmax:
                pmax = abs(r_l[q])
            dd[q] = z[q] / s[q] + w[q] / t[q]  # (for the step matrix; w = 0 without hi)
        mu /= max(n_c, 1)
        dual = 0.0
        for i in range(n):
            if abs(r_d[i]) > dual:
                dual = abs(r_d[i])
        if pmax < tolerance * (1.0 + lomax) and (mu < tolerance or mu < 1e-12 * mu0):
            if dual < tolerance * gmax or (mu < 1e-3 * tolerance and dual < 1e-3 * gmax):
                break
        # the step matrix [[H + Cᵀ·diag(z/s + w/t)·C, Rᵀ], [R, −W⁻¹]], factorised
        for k in range(size):
            ab[k] = hb[k]
        for q in range(m):
            dq = dd[q]
            for k in range(pair_ptr[q], pair_ptr[q + 1]):
                ab[pair_at[k]] += dq * pair_c[k] * pair_c2[k]
        diag_max = 0.0
        for i in range(n):
            v = abs(ab[diag_at[i]])
            if v > diag_max:
                diag_max = v
        delta = 1e-13 * diag_max
        ok = False
        for _ in range(4):
            for i in range(n):
                ab[diag_at[i]] += delta
            if envelope_ldl(first, ptr, ab, sign, uf):
                ok = True
                break
            for i in range(n):
                ab[diag_at[i]] -= delta
            delta = max(delta * 1e3, 1e-300)
        if not ok:
            break
        sigma_mu = 0.0
        start = it == 1
        corr = 0  # 0: predictor, 1: corrector (σμ and Δs·Δz), 2: centring only (σμ)
        while True:
            for i in range(n):
                rhs[pos[i]] = -r_d[i]
            for q in range(m):
                rc_l[q] = s[q] * z[q] - sigma_mu + (ds[q] * dz[q] if corr == 1 else 0.0)
                rc_u[q] = (t[q] * w[q] - sigma_mu + (dt[q] * dw[q] if corr == 1 else 0.0)
                           if fin[q] else 0.0)
                i = r0 + q
                v = (-rc_l[q] - z[q] * r_l[q]) / s[q]
                v_u = v - (-rc_u[q] - w[q] * r_u[q]) / t[q]
                v = v_u if fin[q] else v
                for p in range(c_ptr[i], c_ptr[i + 1]):
                    rhs[lpos[p - p_0]] += c_val[p] * v
            envelope_ldl_solve(first, ptr, uf, rhs, sol)
            for i in range(n):
                dx[i] = sol[pos[i]]
            a_p = 1.0  # the longest steps that keep s, t (primal) and z, w (dual) ≥ 0
            a_d = 1.0
            for q in range(m):
                i = r0 + q
                v = 0.0
                for p in range(c_ptr[i], c_ptr[i + 1]):
                    v += c_val[p] * dx[lcol[p - p_0]]
                ds[q] = v + r_l[q]
                dt[q] = -v + r_u[q] if fin[q] else 0.0
                dz[q] = (-rc_l[q] - z[q] * ds[q]) / s[q]
                dw_q = (-rc_u[q] - w[q] * dt[q]) / t[q]
                dw[q] = dw_q if fin[q] else 0.0
                # (dt = dw = 0 for a row without upper bound: no ratio)
                a_p = _step_to_zero(s[q], ds[q], a_p)
                a_p = _step_to_zero(t[q], dt[q], a_p)
                a_d = _step_to_zero(z[q], dz[q], a_d)
                a_d = _step_to_zero(w[q], dw[q], a_d)
            if corr == 0:
                mu_aff = 0.0
                for q in range(m):
                    mu_aff += (s[q] + a_p * ds[q]) * (z[q] + a_d * dz[q])
                    mu_u = mu_aff + (t[q] + a_p * dt[q]) * (w[q] + a_d * dw[q])
                    mu_aff = mu_u if fin[q] else mu_aff
                mu_aff /= max(n_c, 1)
                # Mehrotra's centring, never above the current gap
                sigma = min(1.0, (mu_aff / mu) ** 3) if mu > 0.0 else 0.0
                sigma_mu = sigma * mu
                if start:
                    break
                corr = 1
                continue
            if corr == 1:
                # the corrector's second-order term can make the gap grow (two ratio
                # steps side by side took turns at their bound for 150 steps): then the
                # step is taken with the centring alone
                al = min(0.995 * min(a_p, a_d), 1.0)
                mu_new = 0.0
                for q in range(m):
                    mu_new += (s[q] + al * ds[q]) * (z[q] + al * dz[q])
                    mu_u = mu_new + (t[q] + al * dt[q]) * (w[q] + al * dw[q])
                    mu_new = mu_u if fin[q] else mu_new
                if mu_new > (1.0 - _MIN_GAP_DECREASE * al) * mu * max(n_c, 1):
                    corr = 2
                    continue
            break
        if start:
            # the starting point (Nocedal & Wright §16.6): the predictor's full step from
            # the given x, with slacks at least 1 and multipliers at least 1 or
            # _START_GAP/slack where that is less (a bound far away starts with a small
            # multiplier). The given x alone, often far outside a ratio step's bounds,
            # left slacks of 1e-3 that the steps crept away from (20 steps of < 1e-4)
            for i in range(n):
                xl[i] += dx[i]
            mu0 = 0.0
            for q in range(m):
                s[q] = max(abs(s[q] + ds[q]), 1.0)
                z[q] = max(abs(z[q] + dz[q]), min(1.0, _START_GAP / s[q]))
                if fin[q]:
                    t[q] = max(abs(t[q] + dt[q]), 1.0)
                    w[q] = max(abs(w[q] + dw[q]), min(1.0, _START_GAP / t[q]))
                mu0 += s[q] * z[q] + t[q] * w[q]
            mu0 = max(mu0 / max(n_c, 1), 1e-300)
            continue
        # one step for primal and dual: with H in the dual residual, separate steps would
        # break the Newton direction (a two-variable run start oscillated between the
        # bounds of its ratio box with them)
        alpha = min(0.995 * min(a_p, a_d), 1.0)
        for i in range(n):
            xl[i] += alpha * dx[i]
        for q in range(m):
            s[q] += alpha * ds[q]
            t[q] = t[q] + alpha * dt[q] if fin[q] else 1.0
            z[q] += alpha * dz[q]
            w[q] = w[q] + alpha * dw[q] if fin[q] else 0.0
    for i in range(n):
        x[a + i] = xl[i]
    return it


@njit(cache=True, parallel=True, error_model="numpy")
def _solve_blocks(x, block_a, block_e, h_ptr, h_r, h_c, h_v, g, row_ptr,  # type: ignore[no-untyped-def]
                  c_ptr, c_col, c_val, d, lo, hi, sq_ptr, r_ptr, r_col, r_val, r_w,
                  max_iterations, tolerance, iters, order):
    for kk in prange(order.shape[0]):
        k = order[kk]
        iters[k] = _solve_block(x, h_ptr[k], h_ptr[k + 1], h_r, h_c, h_v, g, c_ptr, c_col,
                                c_val, row_ptr[k], row_ptr[k + 1], d, lo, hi, r_ptr, r_col,
                                r_val, r_w, sq_ptr[k], sq_ptr[k + 1], block_a[k], block_e[k],
                                max_iterations, tolerance)


def _take_rows(ptr: IntArray, col: IntArray, val: FloatArray, rows: IntArray
               ) -> tuple[IntArray, IntArray, FloatArray]:
    """The given rows of a CSR matrix, in the given order."""
    from flowtwin.compensation._program_kernel import take_rows

    return take_rows(ptr, col, val, np.ascontiguousarray(rows, dtype=np.int64))


def solve_program(n: int, h: tuple[IntArray, IntArray, FloatArray], g: FloatArray,
                  c: tuple[IntArray, IntArray, FloatArray], d: FloatArray, lo: FloatArray,
                  hi: FloatArray, x0: FloatArray, *,
                  squares: tuple[IntArray, IntArray, FloatArray, FloatArray],
                  max_iterations: int = 60, tolerance: float = 1e-9
                  ) -> tuple[FloatArray, int, float]:
    """Solve the program of the module docstring, given as arrays.

    Parameters
    ----------
    n
        Variables.
    h
        Upper triangle of ``H``: rows, columns and values, ordered by row then column,
        no zero value.
    g, d, lo, hi, x0
        Linear term ``(n,)``, offset and bounds of ``C·x + d`` ``(m,)`` (a row bounded
        above only is negated, one bounded on neither side dropped), starting point.
    c
        ``C`` as compressed rows ``(ptr, col, val)``, columns ascending in every row, no
        zero value.
    squares
        ``R`` as compressed rows (as ``c``) and the weights ``w``.
    max_iterations, tolerance
        Newton steps at most (per block); stop when the duality gap per constraint and
        the scaled residuals are below ``tolerance``.

    Returns
    -------
    tuple
        ``x`` ``(n,)``, the most iterations any block took, and 0.
    """
    c_ptr, c_col, c_val = c
    del c
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    # rows bounded above only: negate them (−hi ≤ −C·x − d); unbounded rows: drop
    upper_only = ~np.isfinite(lo) & np.isfinite(hi)
    keep = np.isfinite(lo) | upper_only
    if np.any(upper_only) or not np.all(keep):
        sign = np.where(upper_only, -1.0, 1.0)
        c_val = c_val * np.repeat(sign, np.diff(c_ptr))
        kept = np.flatnonzero(keep)
        c_ptr, c_col, c_val = _take_rows(c_ptr, c_col, c_val, kept)
        d = (sign * d)[keep]
        lo, hi = np.where(upper_only, -hi, lo)[keep], np.where(upper_only, np.inf, hi)[keep]
    x = np.array(x0, dtype=np.float64)
    h_r, h_c, h_v = h
    r_ptr, r_col, r_val, wq = squares
    used = np.flatnonzero((wq > 0) & (np.diff(r_ptr) > 0))  # an empty row is a constant
    if used.size < wq.size:
        r_ptr, r_col, r_val = _take_rows(r_ptr, r_col, r_val, used)
        wq = wq[used]
    # H entries, constraint rows and squared rows ordered by block (squared rows by their
    # last variable); an order is empty where nothing moves (copies only then)
    starts, ends, h_order, h_ptr, rorder, row_ptr, sorder, sq_ptr = block_layout(
        n, np.asarray(h_r, dtype=np.int64), np.asarray(h_c, dtype=np.int64), c_ptr, c_col,
        r_ptr, r_col)
    if h_order.size:
        h_r, h_c, h_v = h_r[h_order], h_c[h_order], h_v[h_order]
    if rorder.size:
        c_ptr, c_col, c_val = _take_rows(c_ptr, c_col, c_val, rorder)
        d, lo, hi = d[rorder], lo[rorder], hi[rorder]
    if sorder.size:
        r_ptr, r_col, r_val = _take_rows(r_ptr, r_col, r_val, sorder)
        wq = wq[sorder]
    iters = np.zeros(starts.size, dtype=np.int64)
    # blocks differ in size by 100× and more: the threads take a few at a time, the
    # largest first, so that no large block is left to one thread at the end (results do
    # not depend on which thread solves a block, nor when)
    order = np.argsort(-((ends - starts) + np.diff(row_ptr) + np.diff(sq_ptr)),
                       kind="stable").astype(np.int64)
    chunk = set_parallel_chunksize(_CHUNK_BLOCKS)
    try:
        _solve_blocks(x, starts, ends, h_ptr, h_r, h_c, h_v, np.asarray(g, np.float64),
                      row_ptr, c_ptr, c_col, c_val, d, lo, hi, sq_ptr, r_ptr, r_col, r_val,
                      wq, int(max_iterations), float(tolerance), iters, order)
    finally:
        set_parallel_chunksize(chunk)
    return x, int(iters.max(initial=0)), 0.0
