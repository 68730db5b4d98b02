"""The commanded extruder motion: piecewise-polynomial filament speed against time.

The planner gives every move three phases of constant acceleration along its path
(:class:`~flowtwin.planner.timeline.Timeline`). The extruder follows the toolhead: during
a move it turns ``de · flow`` (M221 included) over the move's path length ``L``, so its
speed is ``v_E(t) = r · v_path(t)`` with ``r = de · flow / L`` — piecewise linear in time,
with the same breakpoints as the toolhead (extrude-only moves have their own trapezoid,
whose "path" is the E distance). ``L`` is taken from the phases themselves
(``(v0 + v1)/2 · t`` per phase), so the E motion of each move integrates exactly to
``de · flow`` whatever length convention the planner used.

:class:`CommandedFeed` stores that motion as segments with a cubic speed
``v(τ) = c0 + c1 τ + c2 τ² + c3 τ³`` in local time ``τ ∈ [0, dt]`` (cubic because
Klipper's smoothed pressure advance is cubic, :mod:`flowtwin.dynamics.advance`), the
commanded position at each segment start, and which move (or which stop between moves)
each segment belongs to. Stops between moves (dwells, forced stops) are segments with
``v = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics._feed_kernel import (
    BAD_NONE,
    BAD_OVERLAP,
    BAD_PHASE_TIME,
    build_segments,
    count_segments,
    prepare_moves,
)
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["PHASE_ACCEL", "PHASE_CRUISE", "PHASE_DECEL", "PHASE_GAP", "PHASE_MIXED",
           "CommandedFeed", "nominal_feed"]

PHASE_ACCEL = 0
PHASE_CRUISE = 1
PHASE_DECEL = 2
PHASE_GAP = 3
PHASE_MIXED = -1  # segment made by pressure-advance smoothing (spans phases)

#: Relative time tolerance when checking that moves do not overlap on the timeline.
_OVERLAP_TOL_S = 1e-9
#: Negative phase times down to this are rounding residue of the planner, taken as 0.
_PHASE_RESIDUE_S = 1e-12


@dataclass(frozen=True, slots=True)
class CommandedFeed:
    """Commanded filament motion of one extruder (filament mm, after M221).

    Attributes
    ----------
    t0_s
        Segment start times, s, shape ``(n,)``, increasing; segments are contiguous
        (``t0_s[i] + dt_s[i] == t0_s[i + 1]`` up to rounding).
    dt_s
        Segment durations, s, shape ``(n,)``, ``> 0``.
    coef
        Speed polynomial per segment, shape ``(n, 4)``: ``v(τ) = c0 + c1 τ + c2 τ² + c3 τ³``
        in mm/s, mm/s², mm/s³, mm/s⁴.
    e0_mm
        Commanded extruder position at each segment start, mm, shape ``(n,)``.
    move
        Owning move index per segment, shape ``(n,)``; for stop segments the index of the
        move before the stop (``-1`` before the first move). In *move order* (what
        :func:`~flowtwin.dynamics.integrator.integrate` requires): a move's segments are
        contiguous, its stop segments follow them, moves come in index order
        (``2 · move + gap`` never decreases).
    gap
        ``True`` for segments between moves (stops, dwells, lead-in and tail), shape ``(n,)``.
    phase
        Planner phase of the segment (``PHASE_*``), shape ``(n,)``.
    move_t0_s, move_t1_s
        Start and end time of every move, shape ``(n_moves,)``.
    move_de_mm
        Filament commanded by each move as written (``de · flow``), shape ``(n_moves,)``.
    e_start_mm
        Extruder position before the first segment.
    advance
        Which pressure advance shaped the feed: ``"none"``, or the value of the
        :class:`~flowtwin.firmware.Firmware` whose advance it is.
    warnings
        Non-fatal notes.
    """

    t0_s: npt.NDArray[np.float64]
    dt_s: npt.NDArray[np.float64]
    coef: npt.NDArray[np.float64]
    e0_mm: npt.NDArray[np.float64]
    move: npt.NDArray[np.int64]
    gap: npt.NDArray[np.bool_]
    phase: npt.NDArray[np.int8]
    move_t0_s: npt.NDArray[np.float64]
    move_t1_s: npt.NDArray[np.float64]
    move_de_mm: npt.NDArray[np.float64]
    e_start_mm: float = 0.0
    advance: str = "none"
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        n = self.t0_s.shape[0]
        shapes = {"dt_s": self.dt_s.shape, "e0_mm": self.e0_mm.shape, "move": self.move.shape,
                  "gap": self.gap.shape, "phase": self.phase.shape}
        for name, shape in shapes.items():
            if shape != (n,):
                raise DataError("commanded feed arrays differ in length", field=name,
                                value=shape, allowed=f"({n},)")
        if self.coef.shape != (n, 4):
            raise DataError("commanded feed coefficients must be (n, 4)", field="coef",
                            value=self.coef.shape, allowed=f"({n}, 4)")
        m = self.move_t0_s.shape[0]
        if self.move_t1_s.shape != (m,) or self.move_de_mm.shape != (m,):
            raise DataError("per-move arrays differ in length", field="move_t1_s",
                            value=(self.move_t1_s.shape, self.move_de_mm.shape),
                            allowed=f"({m},)")

    @property
    def n_segments(self) -> int:
        """Number of segments."""
        return int(self.t0_s.shape[0])

    @property
    def n_moves(self) -> int:
        """Number of moves of the move table the feed was built from."""
        return int(self.move_t0_s.shape[0])

    @property
    def t_begin_s(self) -> float:
        """Start of the first segment, s."""
        return float(self.t0_s[0]) if self.n_segments else 0.0

    @property
    def t_end_s(self) -> float:
        """End of the last segment, s."""
        return float(self.t0_s[-1] + self.dt_s[-1]) if self.n_segments else 0.0

    def segment_mm(self) -> npt.NDArray[np.float64]:
        """Filament commanded per segment, ``∫ v dτ``, mm, shape ``(n,)``."""
        t = self.dt_s
        c = self.coef
        return t * (c[:, 0] + t * (0.5 * c[:, 1] + t * (c[:, 2] / 3.0 + t * 0.25 * c[:, 3])))

    def e_end_mm(self) -> float:
        """Commanded position at the end of the feed, mm."""
        if not self.n_segments:
            return self.e_start_mm
        t = float(self.dt_s[-1])
        c0, c1, c2, c3 = (float(v) for v in self.coef[-1])
        # segment_mm() of the last segment alone, the same expression
        return float(self.e0_mm[-1] + t * (c0 + t * (0.5 * c1 + t * (c2 / 3.0 + t * 0.25 * c3))))

    def _locate(self, t_s: npt.ArrayLike) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        t = np.asarray(t_s, dtype=np.float64)
        idx = np.searchsorted(self.t0_s, t, side="right") - 1
        idx = np.clip(idx, 0, self.n_segments - 1)
        tau = np.clip(t - self.t0_s[idx], 0.0, self.dt_s[idx])
        return idx, tau

    def velocity_at(self, t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Commanded filament speed at times ``t_s`` (right-continuous), mm/s.

        Outside the feed the extruder is at rest (0).
        """
        t = np.asarray(t_s, dtype=np.float64)
        idx, tau = self._locate(t)
        c = self.coef[idx]
        v = c[..., 0] + tau * (c[..., 1] + tau * (c[..., 2] + tau * c[..., 3]))
        return np.where((t < self.t_begin_s) | (t >= self.t_end_s), 0.0, v)

    def position_at(self, t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Commanded extruder position at times ``t_s``, mm (held outside the feed)."""
        t = np.asarray(t_s, dtype=np.float64)
        idx, tau = self._locate(np.clip(t, self.t_begin_s, self.t_end_s))
        c = self.coef[idx]
        e = self.e0_mm[idx] + tau * (c[..., 0] + tau * (0.5 * c[..., 1] + tau * (
            c[..., 2] / 3.0 + tau * 0.25 * c[..., 3])))
        return np.where(t < self.t_begin_s, self.e_start_mm, e)


def nominal_feed(moves: MoveTable, timeline: Timeline, *, tool: int | None = None,
                 e_start_mm: float = 0.0, lead_s: float = 0.0, tail_s: float = 0.0
                 ) -> CommandedFeed:
    """Commanded extruder motion of a planned move table, without pressure advance.

    Parameters
    ----------
    moves
        Move table, ``n_moves`` rows.
    timeline
        Planner output aligned with ``moves`` (``phases`` of shape ``(n_moves,)``).
    tool
        Only moves of this tool drive the extruder (others count as travels for it);
        ``None``: every move's E drives it (single extruder; pseudo-tools included).
    e_start_mm
        Extruder position before the first move, mm.
    lead_s, tail_s
        Extra rest time before the first and after the last move, s (``>= 0``).

    Returns
    -------
    CommandedFeed
        Piecewise-linear speed (``coef[:, 2:] == 0``), one segment per non-empty phase
        and per stop between moves.

    Raises
    ------
    DataError
        Tables of different length, negative or non-finite phase times, overlapping
        moves, or a move with ``de != 0`` but no motion.
    """
    n = len(moves)
    ph = timeline.phases
    if ph.shape != (n,):
        raise DataError("timeline does not match the move table", source=moves.source,
                        field="timeline.phases", value=ph.shape, allowed=f"({n},)")
    if lead_s < 0.0 or tail_s < 0.0 or not np.isfinite(lead_s + tail_s):
        raise DataError("lead/tail time must be finite and >= 0", field="lead_s/tail_s",
                        value=(lead_s, tail_s), allowed=">= 0")
    # one compiled pass: planner residue like -2e-18 s in phase times is clamped to 0, the
    # phase times, move order and motion of extruding moves are checked
    ts, te, de = (np.empty(n) for _ in range(3))
    err = np.zeros(7)
    bad = prepare_moves(ph, moves.moves, -1 if tool is None else int(tool), tool is None,
                        _PHASE_RESIDUE_S, _OVERLAP_TOL_S, ts, te, de, err)
    if bad != BAD_NONE:
        i = int(err[0])
        line = int(moves.moves["line"][i])
        if bad == BAD_PHASE_TIME:
            raise DataError("phase times must be finite and >= 0", source=moves.source,
                            line=line, field="timeline.phases",
                            value=(float(err[1]), float(err[2]), float(err[3]),
                                   float(err[4])),
                            allowed=">= 0")
        if bad == BAD_OVERLAP:
            raise DataError("move starts before the previous one ends", source=moves.source,
                            line=line, field="timeline.t_start", value=float(ts[i]),
                            allowed=f">= {float(err[1])!r}")
        raise DataError("move extrudes but the planner gives it no motion (zero path length "
                        "or zero duration)", source=moves.source, line=line,
                        field="timeline.phases", value=float(err[1]),
                        allowed="moves with de != 0 need a duration > 0")
    # the segments, with the E speeds at the phase ends computed on the way (no move-sized
    # temporaries)
    m = count_segments(ph, ts, te, _PHASE_RESIDUE_S, float(lead_s), float(tail_s))
    t0_s, dt_s, e0_mm = np.empty(m), np.empty(m), np.empty(m)
    coef = np.empty((m, 4))
    move = np.empty(m, dtype=np.int64)
    phase_k = np.empty(m, dtype=np.int8)
    gap = np.empty(m, dtype=np.bool_)
    build_segments(ph, ts, te, de, _PHASE_RESIDUE_S, float(e_start_mm), float(lead_s),
                   float(tail_s), t0_s, dt_s, coef, e0_mm, move, phase_k, gap)
    return CommandedFeed(t0_s=t0_s, dt_s=dt_s, coef=coef, e0_mm=e0_mm, move=move, gap=gap,
                         phase=phase_k, move_t0_s=ts, move_t1_s=te,
                         move_de_mm=de, e_start_mm=float(e_start_mm))
