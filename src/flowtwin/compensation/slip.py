"""Slip feed-forward [000 §6]: command the filament the drive will lose.

The drive slips by ``s = k_p + s'·F_f`` at the feed force ``F_f`` [000 Eq. 6] (``s'`` from
[000 Eq. 8] where the roller's speed dependence applies): of a commanded length ``E`` only
``(1 − s)·E`` enters the column. [000 §6] proposes to predict the force and the slip from a
model and correct for it; the twin predicts the slip of every move at its own feed force
(:attr:`flowtwin.dynamics.DynamicsResult.moves` ``"slip"``), so each printing move gets

``E' = E / (1 − s)``

which feeds ``E`` after the slip. More E raises the force and the slip a little, so the
correction is repeated on the corrected file (a fixed-point iteration that converges
because ``s'·F ≪ 1``). Unlike the advance this *adds* volume; the added volume is
reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.draft import Draft
from flowtwin.errors import ProfileError

__all__ = ["SlipOptions", "slip_feedforward"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class SlipOptions:
    """How to feed the slip forward.

    Attributes
    ----------
    gain
        Fraction of the predicted slip to correct (1: all of it; 0: nothing).
    max_slip
        Slip above this is corrected only up to it (a move that slips more is a grinding
        problem for the guard, not a feed-forward one).
    iterations
        Fixed-point iterations (each one re-simulates the corrected file).
    """

    gain: float = 1.0
    max_slip: float = 0.3
    iterations: int = 2

    def __post_init__(self) -> None:
        checks = {"gain": (self.gain, 0.0 <= self.gain <= 2.0, "0 .. 2"),
                  "max_slip": (self.max_slip, 0.0 <= self.max_slip < 0.9, "0 <= s < 0.9"),
                  "iterations": (self.iterations, 1 <= self.iterations <= 10, "1 .. 10")}
        for name, (value, ok, allowed) in checks.items():
            if not ok:
                raise ProfileError("invalid slip option", field=name, value=value,
                                   allowed=allowed)

    @property
    def is_identity(self) -> bool:
        """The options change nothing."""
        return self.gain == 0.0 or self.max_slip == 0.0


def slip_feedforward(draft: Draft, base_e: IntArray, printing: npt.NDArray[np.bool_],
                     slip: FloatArray, options: SlipOptions) -> Draft:
    """Scale the printing pieces' E by ``1/(1 − s)``.

    Parameters
    ----------
    draft
        The draft (its pieces are the rows ``slip`` was predicted for).
    base_e
        E of every piece before any slip correction, grid units, shape ``(n,)``.
    printing
        Pieces that print (XY motion, positive E, from a printing move), shape ``(n,)``.
    slip
        Predicted slip of every piece, fraction, shape ``(n,)``.
    options
        Gain and limits.

    Returns
    -------
    Draft
        The draft with corrected E: ``round(base_e / (1 − gain·s))`` on printing pieces,
        with the rounding residue carried from piece to piece so the added volume is the
        exactly rounded sum.
    """
    s = np.clip(np.nan_to_num(np.asarray(slip, dtype=np.float64), nan=0.0), 0.0,
                options.max_slip) * options.gain
    base = np.asarray(base_e, dtype=np.int64)
    scaled = np.where(printing, base / (1.0 - s), base.astype(np.float64))
    sel = np.flatnonzero(printing)
    out = base.copy()
    if sel.size:
        cum = np.rint(np.cumsum(scaled[sel])).astype(np.int64)
        new = np.diff(np.concatenate(([0], cum)))
        out[sel] = np.maximum(new, 1)
    return draft.with_e(out)
