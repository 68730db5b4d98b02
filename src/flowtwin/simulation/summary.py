"""Whole-print figures of a simulation, as one typed, frozen object.

Both :meth:`flowtwin.simulation.SimulationResult.summary` (the whole move table) and the
streamed simulation (:class:`flowtwin.simulation.aggregate.Aggregates`, section by
section) return a :class:`SimulationSummary`; :meth:`SimulationSummary.as_dict` is the
``--json`` object of ``flowtwin simulate`` (keys in this order).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.simulation import _summary_kernel as sk

__all__ = ["SimulationSummary", "StreamSummary"]


@dataclass(frozen=True, slots=True)
class SimulationSummary:
    """What the twin predicts for a whole print.

    Attributes
    ----------
    file, machine, printer, firmware
        The G-code's name, the set-up, the printer (profile or ``printer.cfg``) and the
        firmware the plan follows.
    pressure_advance
        The firmware's pressure advance the prediction includes (``"off"`` when none).
    total_time_s
        Planned print time, s.
    moves, layers
        Move rows and layers.
    commanded_volume_mm3, delivered_volume_mm3
        Melt the G-code commands (after M221) and the melt the twin predicts leaves the
        nozzle, mm³.
    delivered_in_beads_mm3
        The part of it laid by extruding XY moves, mm³.
    volume_error
        ``delivered / commanded − 1``.
    rms_flow_error
        Volume-weighted RMS of the per-move flow error of the bead-laying moves.
    peak_overextrusion, peak_underextrusion
        Largest per-move over-extrusion, and largest shortfall (``−min``), fractions.
    worst_width_error_mm
        Largest distance of a predicted bead width from its nominal width, mm.
    mean_slip
        Filament lost to drive slip over the filament fed forward.
    max_feed_force_n
        Largest predicted feed force, N.
    min_force_margin_n
        Smallest margin of the feed force to the roller's maximum, N (``None``: no move
        has one).
    grinding_events, grinding_moves
        Stretches and moves where the twin predicts the drive grinds.
    ooze_volume_mm3
        Melt lost over travels and stops, mm³.
    narrow_beads
        Bead-laying moves whose predicted width is below the layer height.
    moves_over_flow_limit
        Moves whose flow exceeds what the hot end can melt.
    net_filament_mm
        Net filament written per tool (E words, before M221), mm, keyed by tool number.
    warnings
        Everything the user must know.
    """

    file: str
    machine: str
    printer: str
    firmware: str
    pressure_advance: str
    total_time_s: float
    moves: int
    layers: int
    commanded_volume_mm3: float
    delivered_volume_mm3: float
    delivered_in_beads_mm3: float
    volume_error: float
    rms_flow_error: float
    peak_overextrusion: float
    peak_underextrusion: float
    worst_width_error_mm: float
    mean_slip: float
    max_feed_force_n: float
    min_force_margin_n: float | None
    grinding_events: int
    grinding_moves: int
    ooze_volume_mm3: float
    narrow_beads: int
    moves_over_flow_limit: int
    net_filament_mm: Mapping[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        """The figures as plain JSON-able values (the ``--json`` object of ``simulate``)."""
        return {
            "file": self.file, "machine": self.machine, "printer": self.printer,
            "firmware": self.firmware, "pressure_advance": self.pressure_advance,
            "total_time_s": self.total_time_s, "moves": self.moves, "layers": self.layers,
            "commanded_volume_mm3": self.commanded_volume_mm3,
            "delivered_volume_mm3": self.delivered_volume_mm3,
            "delivered_in_beads_mm3": self.delivered_in_beads_mm3,
            "volume_error": self.volume_error, "rms_flow_error": self.rms_flow_error,
            "peak_overextrusion": self.peak_overextrusion,
            "peak_underextrusion": self.peak_underextrusion,
            "worst_width_error_mm": self.worst_width_error_mm, "mean_slip": self.mean_slip,
            "max_feed_force_n": self.max_feed_force_n,
            "min_force_margin_n": self.min_force_margin_n,
            "grinding_events": self.grinding_events, "grinding_moves": self.grinding_moves,
            "ooze_volume_mm3": self.ooze_volume_mm3, "narrow_beads": self.narrow_beads,
            "moves_over_flow_limit": self.moves_over_flow_limit,
            "net_filament_mm": dict(self.net_filament_mm),
            "warnings": list(self.warnings),
        }

    @classmethod
    def from_totals(cls, t: npt.NDArray[np.float64], *, file: str, machine: str, printer: str,
                    firmware: str, pressure_advance: str, total_time_s: float, moves: int,
                    layers: int, moves_over_flow_limit: int,
                    net_filament_mm: Mapping[str, float], warnings: tuple[str, ...]
                    ) -> SimulationSummary:
        """The figures from the compiled print totals ``t`` (``_summary_kernel``'s ``T_*``
        slots, whole table or folded sections) and what the totals do not hold."""
        w = float(t[sk.T_RMS_W])
        cmd, delivered = float(t[sk.T_CMD]), float(t[sk.T_DELIVERED])
        fed = float(t[sk.T_FED_FWD])
        return cls(
            file=file, machine=machine, printer=printer, firmware=firmware,
            pressure_advance=pressure_advance, total_time_s=total_time_s, moves=moves,
            layers=layers, commanded_volume_mm3=cmd, delivered_volume_mm3=delivered,
            delivered_in_beads_mm3=float(t[sk.T_EXT_OUT]),
            volume_error=delivered / cmd - 1.0 if cmd > 0 else 0.0,
            rms_flow_error=math.sqrt(float(t[sk.T_RMS_WEE]) / w) if w > 0.0 else 0.0,
            peak_overextrusion=float(t[sk.T_OVER]), peak_underextrusion=float(t[sk.T_UNDER]),
            worst_width_error_mm=float(t[sk.T_WIDTH_DEV]),
            mean_slip=float(t[sk.T_SLIP_LOSS]) / fed if fed > 0 else 0.0,
            max_feed_force_n=float(t[sk.T_FORCE_MAX]),
            min_force_margin_n=float(t[sk.T_MARGIN_MIN]) if t[sk.T_MARGIN_N] > 0 else None,
            grinding_events=int(t[sk.T_GRIND_EVENTS]),
            grinding_moves=int(t[sk.T_GRIND_MOVES]),
            ooze_volume_mm3=float(t[sk.T_OOZE]), narrow_beads=int(t[sk.T_NARROW]),
            moves_over_flow_limit=moves_over_flow_limit,
            net_filament_mm=dict(net_filament_mm), warnings=warnings)


@dataclass(frozen=True, slots=True)
class StreamSummary:
    """The whole-print figures of a streamed simulation and the stream's own counts.

    Attributes
    ----------
    figures
        The whole-print figures (those of ``SimulationResult.summary()``).
    stream_windows, stream_sections
        Planning windows and simulated sections used.
    unverified_moves
        Moves whose plan two windows did not confirm.
    cuts_not_at_rest
        Sections cut where the smoothed advance could see across the cut.
    lines
        G-code lines read.
    """

    figures: SimulationSummary
    stream_windows: int
    stream_sections: int
    unverified_moves: int
    cuts_not_at_rest: int
    lines: int

    def as_dict(self) -> dict[str, object]:
        """The figures, then the stream's counts (the ``simulate --stream --json`` object)."""
        out = self.figures.as_dict()
        out.update({"stream_windows": self.stream_windows,
                    "stream_sections": self.stream_sections,
                    "unverified_moves": self.unverified_moves,
                    "cuts_not_at_rest": self.cuts_not_at_rest, "lines": self.lines})
        return out
