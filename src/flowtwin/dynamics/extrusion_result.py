"""Result types of the extrusion dynamics: per move, time series and summary.

Volumes are mm³ of melt (filament length times the filament cross-section ``A_fil``),
flows mm³/s, forces N, slip a fraction (docs/spec.md §2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics.feed import CommandedFeed

__all__ = ["MOVE_RESULT_DTYPE", "SERIES_DTYPE", "DynamicsResult", "DynamicsSummary"]

#: One row per move of the move table.
MOVE_RESULT_DTYPE = np.dtype([
    ("cmd_mm3", np.float64),        # G-code intent: A_fil · de · flow (pressure advance excluded)
    ("fed_cmd_mm3", np.float64),    # firmware command during the move (pressure advance included)
    ("fed_mm3", np.float64),        # filament that entered the column (after slip and grinding)
    ("out_mm3", np.float64),        # melt delivered during the move
    ("stop_out_mm3", np.float64),   # melt delivered in the stop/dwell after the move
    ("ooze_mm3", np.float64),       # out_mm3 of a non-extruding move + stop_out_mm3
    ("q_mean_mm3_s", np.float64),   # out_mm3 / duration (0 for zero-length moves)
    ("q_min_mm3_s", np.float64),
    ("q_max_mm3_s", np.float64),
    ("peak_force_n", np.float64),
    ("slip", np.float64),           # slip loss / forward command during the move (fraction)
    ("slip_loss_mm3", np.float64),
    ("grind_loss_mm3", np.float64),
    ("grinding", np.bool_),         # the drive ground the filament during the move or stop
    ("duration_s", np.float64),
])

#: One row per sample of the optional time series.
SERIES_DTYPE = np.dtype([
    ("t_s", np.float64),
    ("e_cmd_mm", np.float64),       # extruder position as the firmware commands it (PA included)
    ("v_cmd_mm_s", np.float64),     # commanded filament speed
    ("v_fil_mm_s", np.float64),     # filament speed into the column (after slip/grinding)
    ("q_out_mm3_s", np.float64),    # melt flow out of the nozzle
    ("feed_force_n", np.float64),
    ("slip", np.float64),
    ("compression_mm", np.float64), # Δl, the state (negative: filament pulled off the melt)
])


@dataclass(frozen=True, slots=True)
class DynamicsSummary:
    """Totals of one integration.

    Attributes
    ----------
    cmd_mm3
        G-code intent, sum of ``A_fil · de · flow`` over the moves.
    fed_cmd_mm3
        Firmware command over the whole feed (equals ``cmd_mm3`` up to rounding: pressure
        advance moves filament in time, it does not add any).
    fed_mm3
        Filament that entered the column.
    out_mm3
        Melt out of the nozzle.
    stored_start_mm3, stored_end_mm3
        ``A_fil · Δl`` at the start and end (negative: filament pulled off the melt).
    mass_balance_error_mm3
        ``fed - out - (stored_end - stored_start)``: zero up to rounding.
    slip_loss_mm3, grind_loss_mm3
        Filament commanded but not fed because of slip / grinding.
    ooze_mm3
        Melt out during travels, retractions and stops (including before the first move).
    peak_force_n
        Largest feed force.
    grinding_moves
        Number of moves flagged as grinding.
    duration_s
        Time span of the feed.
    n_segments, n_events
        Segments integrated; regime changes (zero crossings, grinding, release).
    advance
        Pressure advance the feed was built with (``"none"``, ``"klipper"``, ...).
    """

    cmd_mm3: float
    fed_cmd_mm3: float
    fed_mm3: float
    out_mm3: float
    stored_start_mm3: float
    stored_end_mm3: float
    mass_balance_error_mm3: float
    slip_loss_mm3: float
    grind_loss_mm3: float
    ooze_mm3: float
    peak_force_n: float
    grinding_moves: int
    duration_s: float
    n_segments: int
    n_events: int
    advance: str

    def as_dict(self) -> dict[str, object]:
        """Plain dict (JSON-ready)."""
        return {name: getattr(self, name) for name in self.__slots__}


@dataclass(frozen=True, slots=True)
class DynamicsResult:
    """Prediction of what the extruder delivers for a commanded feed.

    Attributes
    ----------
    moves
        Structured array of :data:`MOVE_RESULT_DTYPE`, shape ``(n_moves,)``.
    summary
        Totals.
    series
        Structured array of :data:`SERIES_DTYPE` (decimated time series) or ``None``.
    before_first_move
        Accumulated figures before the first move (a 1-row :data:`MOVE_RESULT_DTYPE`
        array; its ``stop_out_mm3`` is the ooze before printing starts).
    final_compression_mm
        ``Δl`` at the end of the feed.
    final_grinding
        Whether the drive was still grinding at the end.
    feed
        The commanded feed that was integrated.
    warnings
        Non-fatal notes (from the feed and the integration).
    """

    moves: npt.NDArray[np.void]
    summary: DynamicsSummary
    series: npt.NDArray[np.void] | None
    before_first_move: npt.NDArray[np.void]
    final_compression_mm: float
    final_grinding: bool
    feed: CommandedFeed
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def delivered_ratio(self) -> npt.NDArray[np.float64]:
        """``out_mm3 / cmd_mm3`` per move, shape ``(n_moves,)``; NaN where nothing was asked."""
        cmd = self.moves["cmd_mm3"]
        out = self.moves["out_mm3"]
        ratio = np.full(cmd.shape, np.nan)
        mask = cmd > 0.0
        ratio[mask] = out[mask] / cmd[mask]
        return ratio
