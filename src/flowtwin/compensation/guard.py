"""Grinding guard: slow the moves that would push the drive past its grip [000 §4].

When the feed force exceeds the roller's maximum feed force the teeth eat into the
filament and feeding stops [000 §4, 003]. The force follows the melt flow (Hagen–Poiseuille
[002, 001 Eq. 4]: ``F ∝ Q``), so a move whose force ``F`` — the larger of the twin's
predicted peak and the steady force ``K·v_E/k`` of its intended flow (the predicted peak
saturates where the drive grinds) — exceeds ``safety · F_max`` is slowed by the factor
``safety · F_max / F`` — its flow falls in proportion, and so does the force. A user
limit on the volumetric flow ``Q_max`` (mm³/s) slows a move by ``Q_max / Q`` likewise.
The planner's own speed of the move is the starting point (a feed rate the printer never
reaches is not a speed to scale), and only ever lowered. Because the force also depends
on what came before (the pressure builds over several moves), the check is repeated on the
slowed file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError

if TYPE_CHECKING:
    from flowtwin.compensation.draft import Draft

__all__ = ["GuardOptions", "guard_feeds"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class GuardOptions:
    """Limits of the grinding guard.

    Attributes
    ----------
    safety
        Allowed share of the roller's maximum feed force (0 < safety ≤ 1).
    max_flow_mm3_s
        Largest volumetric flow of a printing move, mm³/s (``None``: no flow limit).
    iterations
        Re-simulations to confirm the slowed moves stay below the limit.
    min_speed_mm_s
        Never slow a move below this, mm/s.
    """

    safety: float = 0.8
    max_flow_mm3_s: float | None = None
    iterations: int = 3
    min_speed_mm_s: float = 2.0

    def __post_init__(self) -> None:
        checks = {"safety": (self.safety, 0.0 < self.safety <= 1.0, "0 < safety <= 1"),
                  "iterations": (self.iterations, 1 <= self.iterations <= 10, "1 .. 10"),
                  "min_speed_mm_s": (self.min_speed_mm_s, 0.1 <= self.min_speed_mm_s <= 100.0,
                                     "0.1 .. 100 mm/s")}
        if self.max_flow_mm3_s is not None:
            checks["max_flow_mm3_s"] = (self.max_flow_mm3_s,
                                        0.0 < self.max_flow_mm3_s <= 1e4, "0 < Q <= 1e4 mm³/s")
        for name, (value, ok, allowed) in checks.items():
            if not (ok and math.isfinite(float(value))):
                raise ProfileError("invalid grinding-guard option", field=name, value=value,
                                   allowed=allowed)


def guard_feeds(draft: Draft, cruise_mm_s: FloatArray, peak_force_n: FloatArray,
                steady_force_n: FloatArray, max_force_n: FloatArray, flow_mm3_s: FloatArray,
                printing: npt.NDArray[np.bool_], speed_factor: FloatArray,
                options: GuardOptions) -> tuple[Draft, npt.NDArray[np.bool_]]:
    """Lower the feed of the original moves whose pieces exceed the limits.

    Parameters
    ----------
    draft
        The draft (its pieces are the rows the other arrays describe).
    cruise_mm_s
        Planned top speed of every piece, mm/s.
    peak_force_n
        Predicted peak feed force of every piece, N.
    steady_force_n
        Feed force the piece's intended flow needs once the pressure has settled,
        ``F = K·v_E/k`` (docs/spec.md §3.4), N — the twin's peak saturates at the limit where the
        drive grinds, so the larger of the two sets the slowdown.
    max_force_n
        The roller's maximum feed force during every piece, N (``inf``: unknown).
    flow_mm3_s
        Intended volumetric flow of every piece at its top speed, mm³/s.
    printing
        Pieces that print.
    speed_factor
        ``M220`` factor in force on every original row (G-code F = 60·v / factor).
    options
        Limits.

    Returns
    -------
    tuple
        The draft with lowered feeds and the original rows slowed in this step.
    """
    factor = np.ones(len(draft))
    force = np.maximum(peak_force_n, steady_force_n)
    with np.errstate(divide="ignore", invalid="ignore"):
        over_f = printing & np.isfinite(max_force_n) & (force > options.safety * max_force_n)
        factor = np.where(over_f, options.safety * max_force_n / force, factor)
        if options.max_flow_mm3_s is not None:
            over_q = printing & (flow_mm3_s > options.max_flow_mm3_s)
            factor = np.minimum(factor, np.where(over_q, options.max_flow_mm3_s / flow_mm3_s,
                                                 1.0))
    slow = factor < 1.0 - 1e-9
    n_rows = draft.n_rows
    feed = draft.feed_mm_min.copy()
    slowed = np.zeros(n_rows, dtype=bool)
    if np.any(slow):
        target_v = np.maximum(cruise_mm_s * factor, options.min_speed_mm_s)
        # one feed per original row: the lowest any of its pieces needs
        row_v = np.full(n_rows, np.inf)
        np.minimum.at(row_v, draft.row[slow], target_v[slow])
        rows = np.flatnonzero(np.isfinite(row_v))
        new_f = 60.0 * row_v[rows] / np.asarray(speed_factor, dtype=np.float64)[rows]
        old = feed[rows]
        lower = ~np.isfinite(old) | (new_f < old)
        feed[rows[lower]] = np.round(new_f[lower], 3)
        slowed[rows[lower]] = True
    return draft.with_feed(feed), slowed
