"""The pacing's print-time budget: pace only the worst spots when all of them cost too much.

Pacing near every spot an advance alone leaves wrong (:mod:`flowtwin.compensation.spots`)
can slow a fast print by far more than a user asked for (the fastest Klipper prints: +40 to
+73 % of print time, their spots paced without the advance's pull-back). Under a budget
(:attr:`~flowtwin.compensation.pace.PaceOptions.time_budget`, a share of the planned print
time) the spots are ranked worst first (:func:`~flowtwin.compensation.spots.rank_spots`)
and the largest number of the worst spots whose paced draft, re-planned, adds no more than
the budget is found by bisection on that number (:func:`largest_fitting`): every step
paces the draft and plans it (no simulation, no advance trial).
"""

from __future__ import annotations

from collections.abc import Callable

from flowtwin.errors import DataError

__all__ = ["largest_fitting"]


def largest_fitting(count: int, fits: Callable[[int], bool]) -> tuple[int, int]:
    """The largest ``n`` in ``0 .. count − 1`` for which ``fits(n)`` holds, by bisection.

    ``fits(0)`` is taken to hold and ``fits(count)`` not to (both already known to the
    caller); ``fits`` is assumed to turn false once as ``n`` grows (the time added by
    pacing the ``n`` worst spots grows with ``n``). Where it does not, the ``n`` returned
    still fits (``fits(n)`` held, or ``n`` is 0), and ``n + 1`` did not.

    Parameters
    ----------
    count
        Number of candidates (≥ 1).
    fits
        Whether the ``n`` first candidates fit.

    Returns
    -------
    tuple of int
        ``n`` and the number of calls of ``fits`` (``ceil(log2(count))`` at most).

    Raises
    ------
    DataError
        ``count`` below 1.
    """
    if count < 1:
        raise DataError("nothing to bisect", field="count", value=count, allowed=">= 1")
    lo, hi, calls = 0, count, 0
    while hi - lo > 1:
        mid = (lo + hi) // 2
        calls += 1
        if fits(mid):
            lo = mid
        else:
            hi = mid
    return lo, calls
