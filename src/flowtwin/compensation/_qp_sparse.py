"""The box-constrained program of :mod:`flowtwin.compensation._qp` on ``scipy.sparse``
matrices (small programs and tests; the refinement assembles its own arrays,
:mod:`flowtwin.compensation.program`)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from flowtwin.compensation._qp import solve_program

__all__ = ["solve_box_qp"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def solve_box_qp(h: sp.spmatrix, g: FloatArray, c: sp.spmatrix, d: FloatArray, lo: FloatArray,
                 hi: FloatArray, *, max_iterations: int = 60, tolerance: float = 1e-9,
                 x0: FloatArray | None = None,
                 squares: tuple[sp.spmatrix, FloatArray] | None = None
                 ) -> tuple[FloatArray, int, float]:
    """Solve the program of the module docstring (``scipy.sparse`` matrices).

    Parameters
    ----------
    h
        Hessian, sparse ``(n, n)``.
    g
        Linear term, ``(n,)``.
    c, d
        Constraint map ``C`` (sparse ``(m, n)``) and offset ``d`` ``(m,)``.
    lo, hi
        Bounds of ``C·x + d``, ``(m,)``; ``lo < hi``; either may be infinite (a row with
        both infinite is ignored).
    max_iterations
        Newton steps at most (per block).
    tolerance
        Stop when the duality gap per constraint and the scaled residuals are below it.
    x0
        Starting point (default: least squares towards the middle of the bounds); the
        slacks start at least 0.1 % of each bound interval inside.
    squares
        ``(R, w)``: the Hessian is ``H + Rᵀ·diag(w)·R`` (``R`` sparse ``(k, n)``,
        ``w > 0``), given as rows instead of their product: a row reading ``ℓ`` variables
        adds ``ℓ²`` entries to the product, but only ``ℓ`` to the steps' factor (see
        :func:`flowtwin.compensation._qp._solve_block`).

    Returns
    -------
    tuple
        ``x`` ``(n,)``, the most iterations any block took, and 0.
    """
    n = h.shape[0]
    c = sp.csr_matrix(c, dtype=np.float64)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    upper_only = ~np.isfinite(lo) & np.isfinite(hi)  # (as solve_program does)
    keep = np.isfinite(lo) | upper_only
    sign = np.where(upper_only, -1.0, 1.0)
    c = sp.csr_matrix(sp.diags(sign) @ c)[keep]
    d = (sign * d)[keep]
    lo, hi = np.where(upper_only, -hi, lo)[keep], np.where(upper_only, np.inf, hi)[keep]
    c.sum_duplicates()
    c.eliminate_zeros()
    if x0 is None:
        from scipy.sparse.linalg import splu

        span = np.where(np.isfinite(hi), hi - lo, np.inf)
        target = np.where(np.isfinite(hi), lo + 0.5 * span,
                          lo + np.maximum(1.0, np.abs(lo)) * 0.5)
        ct = sp.csc_matrix(c.T)
        reg = sp.identity(n, format="csc") * 1e-12
        x0 = splu(sp.csc_matrix(ct @ c + reg)).solve(ct @ (target - d))
    hu = sp.csr_matrix(sp.triu(sp.coo_matrix(h)), dtype=np.float64)
    hu.eliminate_zeros()  # a structural zero couples nothing (a relaxed run start)
    hu = hu.tocoo()
    rq = sp.csr_matrix(squares[0] if squares is not None else (0, n), dtype=np.float64)
    rq.sum_duplicates()
    rq.eliminate_zeros()
    wq = np.zeros(0) if squares is None else np.asarray(squares[1], dtype=np.float64)

    def rows(a: sp.csr_matrix) -> tuple[IntArray, IntArray, FloatArray]:
        return (a.indptr.astype(np.int64), a.indices.astype(np.int64),
                a.data.astype(np.float64))

    return solve_program(n, (hu.row.astype(np.int64), hu.col.astype(np.int64),
                             hu.data.astype(np.float64)), g, rows(c), d, lo, hi,
                         np.asarray(x0, dtype=np.float64), squares=(*rows(rq), wq),
                         max_iterations=max_iterations, tolerance=tolerance)
