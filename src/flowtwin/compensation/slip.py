"""Slip feed-forward [000 §6]: command the filament the drive will lose.

The drive slips by ``s = k_p + s'·F_f`` at the feed force ``F_f`` [000 Eq. 6] (``s'`` from
[000 Eq. 8] where the roller's speed dependence applies): of a commanded length ``E`` only
``(1 − s)·E`` enters the column. [000 §6] proposes to predict the force and the slip from a
model and correct for it; the twin predicts the slip of every move at its own feed force
(:attr:`flowtwin.dynamics.DynamicsResult.moves` ``"slip"``), so each printing move gets

``E' = E / (1 − s)``

which feeds ``E`` after the slip. More E raises the force and the slip a little: the
first round corrects for the steady slip at the intended feed
(:func:`flowtwin.physics.drive.steady_slip_at_intended_feed`, the fixed point where the
force is proportional to the flow), and a further round, on the corrected file, only
while the slip the twin predicts for the corrected file differs from the slip corrected
for by more than a tolerance (:func:`slip_change`; a fixed-point iteration that converges
because ``s'·F ≪ 1``). Unlike the advance this *adds* volume; the added volume is
reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.draft import Draft
from flowtwin.errors import ProfileError

__all__ = ["SlipOptions", "clipped_slip", "slip_change", "slip_feedforward"]

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
        Rounds at most (each one simulates the corrected file).
    tolerance
        A round is the last when the slip the twin predicts for its file differs from the
        slip it corrected for by at most this (:func:`slip_change`, a fraction of the
        printing flow). The default, 0.1 % of the flow, is a tenth of the 1 % steps in
        which a flow (extrusion multiplier) is calibrated; 0 runs every round.
    """

    gain: float = 1.0
    max_slip: float = 0.3
    iterations: int = 2
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        checks = {"gain": (self.gain, 0.0 <= self.gain <= 2.0, "0 .. 2"),
                  "max_slip": (self.max_slip, 0.0 <= self.max_slip < 0.9, "0 <= s < 0.9"),
                  "iterations": (self.iterations, 1 <= self.iterations <= 10, "1 .. 10"),
                  "tolerance": (self.tolerance, 0.0 <= self.tolerance <= 0.1, "0 .. 0.1")}
        for name, (value, ok, allowed) in checks.items():
            if not ok:
                raise ProfileError("invalid slip option", field=name, value=value,
                                   allowed=allowed)

    @property
    def is_identity(self) -> bool:
        """The options change nothing."""
        return self.gain == 0.0 or self.max_slip == 0.0


def clipped_slip(slip: npt.ArrayLike, options: SlipOptions) -> FloatArray:
    """The slip the feed-forward corrects for: ``slip`` in ``[0, max_slip]`` (NaN: 0),
    fraction, the shape of ``slip``."""
    return np.clip(np.nan_to_num(np.asarray(slip, dtype=np.float64), nan=0.0), 0.0,
                   options.max_slip)


def slip_change(corrected_for: FloatArray, predicted: FloatArray,
                printing: npt.NDArray[np.bool_], base_e: IntArray,
                options: SlipOptions) -> float:
    """How far a round of the feed-forward is from its fixed point.

    Parameters
    ----------
    corrected_for
        The slip the round corrected each piece for, fraction, shape ``(n,)``.
    predicted
        The slip the twin predicts for the corrected file, fraction, shape ``(n,)``.
    printing
        Pieces that print, shape ``(n,)``.
    base_e
        E of every piece before any slip correction (the weights), shape ``(n,)``.
    options
        The limits (both slips are taken as :func:`clipped_slip` gives them).

    Returns
    -------
    float
        RMS of the difference of the two slips over the printing pieces, weighted by
        their E: the share of the printing flow the round's correction is off by
        (0 without printing pieces).
    """
    w = np.asarray(base_e, dtype=np.float64)[printing]
    total = float(np.sum(w))
    if total <= 0.0:
        return 0.0
    d = (clipped_slip(predicted, options) - clipped_slip(corrected_for, options))[printing]
    return float(np.sqrt(np.sum(w * d * d) / total))


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
    s = clipped_slip(slip, options) * options.gain
    base = np.asarray(base_e, dtype=np.int64)
    scaled = np.where(printing, base / (1.0 - s), base.astype(np.float64))
    sel = np.flatnonzero(printing)
    out = base.copy()
    if sel.size:
        cum = np.rint(np.cumsum(scaled[sel])).astype(np.int64)
        new = np.diff(np.concatenate(([0], cum)))
        out[sel] = np.maximum(new, 1)
    return draft.with_e(out)
