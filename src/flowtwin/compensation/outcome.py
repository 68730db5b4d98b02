"""What ``compensate`` did and what the twin predicts before and after: typed, frozen.

:class:`CompensationReport` is the result of :func:`flowtwin.compensation.compensate`;
:meth:`CompensationReport.as_dict` is the ``flowtwin compensate --json`` object (keys in
that order). The figures of every advance pass are an :class:`AdvancePassSummary`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.bake import PassReport
from flowtwin.compensation.corner import CornerVelocityCost
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.metrics import FlowFigures
from flowtwin.compensation.pace import PaceReport
from flowtwin.compensation.trajectory import TrajectoryReport

if TYPE_CHECKING:
    from flowtwin.simulation import SimulationResult

__all__ = ["AdvancePassSummary", "CompensationReport", "pace_note"]


def pace_note(pace: Mapping[str, object] | None, time_s: float) -> str | None:
    """One line on the pacing's spots and its time budget, from
    :meth:`~flowtwin.compensation.pace.PaceReport.as_dict` (``None`` when no spot was
    looked for: no pacing, or pacing everywhere).

    Parameters
    ----------
    pace
        The pacing's report as a dict, or ``None``.
    time_s
        The print time before compensation, s (the budget's reference).
    """
    if not pace or not pace.get("spots"):
        return None
    b = pace.get("time_budget")
    budget = ("no time budget" if b is None else
              f"budget {100 * float(b):g} % of the print time")  # type: ignore[arg-type]
    added = float(pace.get("time_added_s") or 0.0)  # type: ignore[arg-type]
    share = 100 * added / time_s if time_s > 0 else 0.0
    line = (f"pacing: {pace['spots_paced']} of {pace['spots']} spots paced "
            f"(+{share:.1f} % print time; {budget})")
    if pace.get("spots_over_budget"):
        line += f"; {pace['spots_over_budget']} spots left: budget"
    return line


@dataclass(frozen=True, slots=True)
class AdvancePassSummary:
    """Figures of one advance pass (one attempt: a pass may be tried twice).

    Attributes
    ----------
    pieces, runs
        Pieces after the pass (relief retractions included) and printing runs.
    law_clipping
        Pieces moved off the law's target by the firmware's limits, by reason.
    refinement
        Figures of the refinement (empty without it).
    relief_travels, relief_mm
        Travels given a pressure-relief retraction, and the length retracted, mm.
    relief_along
        Of those, the reliefs laid along their travels (Klipper).
    relief_retractions, relief_retraction_mm
        Slicer retractions whose push-back was shortened, and the length taken off, mm.
    relief_precharge_mm
        Pre-charge the relieved travels leave for the next runs, mm of filament.
    pull_pieces, pull_mm
        Printing pieces that pull the filament back while the head slows down, and the
        length they pull, mm.
    rms_flow_error
        The twin's RMS flow error of the pass's result (fraction).
    twin_correction
        The pass aimed the model by the twin's correction.
    kept
        The pass's result was kept (it did not raise the twin's RMS flow error, nor, for
        a pass after the second, the weaker of the RMS and windowed improvements).
    retimed_share
        Share of the printing time whose planned time the pass's result moved from the
        timeline the pass modelled (rows changed by more than 5 %; ``nan``: not measured).
    """

    pieces: int
    runs: int
    law_clipping: Mapping[str, int]
    refinement: Mapping[str, float]
    relief_travels: int
    relief_mm: float
    relief_retractions: int
    relief_retraction_mm: float
    relief_precharge_mm: float
    rms_flow_error: float
    twin_correction: bool
    kept: bool = True
    pull_pieces: int = 0
    pull_mm: float = 0.0
    retimed_share: float = float("nan")
    relief_along: int = 0

    @classmethod
    def of(cls, report: PassReport, *, rms_flow_error: float, twin_correction: bool,
           kept: bool = True, retimed_share: float = float("nan")) -> AdvancePassSummary:
        """The summary of a pass's :class:`~flowtwin.compensation.bake.PassReport`."""
        return cls(report.pieces, report.runs, dict(report.law_counts),
                   dict(report.refinement), report.relief_travels, report.relief_mm,
                   report.relief_retractions, report.relief_retraction_mm,
                   report.relief_precharge_mm, rms_flow_error, twin_correction, kept,
                   report.pull_pieces, report.pull_mm, retimed_share, report.relief_along)

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able values (``kept`` only when the pass was not kept)."""
        out: dict[str, object] = {
            "pieces": self.pieces, "runs": self.runs, "law_clipping": dict(self.law_clipping),
            "refinement": dict(self.refinement), "relief_travels": self.relief_travels,
            "relief_mm": self.relief_mm, "relief_along": self.relief_along,
            "relief_retractions": self.relief_retractions,
            "relief_retraction_mm": self.relief_retraction_mm,
            "relief_precharge_mm": self.relief_precharge_mm,
            "pull_pieces": self.pull_pieces, "pull_mm": self.pull_mm,
            "rms_flow_error": self.rms_flow_error, "twin_correction": self.twin_correction,
            "retimed_share": None if np.isnan(self.retimed_share) else self.retimed_share}
        if not self.kept:
            out["kept"] = False
        return out


@dataclass(frozen=True, slots=True)
class CompensationReport:
    """What ``compensate`` did and what the twin predicts before and after.

    Attributes
    ----------
    source, destination
        The files.
    machine
        Name of the set-up simulated.
    firmware_pressure_advance
        Whether the simulations include the firmware's own pressure advance.
    transformations
        Names of the stages that changed the file, in order.
    before, after
        Flow figures of the original and of the compensated file, both against the
        original intent (:class:`~flowtwin.compensation.metrics.FlowFigures`).
    time_before_s, time_after_s
        Planned print time, s.
    commanded_e_before_mm, commanded_e_after_mm
        Total E written in the G-code (before M221), mm of filament.
    added_volume_mm3
        Volume the slip feed-forward added (mm³ of melt; 0 without it).
    slip_rounds, slip_change
        Rounds the slip feed-forward simulated (0 without it) and how far its last round
        is from the fixed point (:func:`~flowtwin.compensation.slip.slip_change`, a share
        of the printing flow).
    slowed_moves
        Source lines the grinding guard slowed.
    guard_time_cost_s
        Print time the guard added (planned with and without it), s.
    grinding_moves_before, grinding_moves_after
        Moves the twin flags as grinding.
    max_force_before_n, max_force_after_n
        Largest predicted feed force, N.
    advance
        Figures of every advance pass tried.
    trajectory
        Figures of the trajectory stage, or ``None``.
    limits
        The firmware limits the advance respected.
    lines_rewritten
        Source lines replaced (motion lines only).
    warnings
        Everything the user should know.
    seconds
        Wall time of the compensation, s.
    lag_factor_changed_moves
        Original moves some piece of which the twin simulates with a different lag factor
        than the move itself (0 when the twin is consistent).
    paced_moves
        Source lines the flow pacing slowed (part of).
    pace_time_cost_s
        Print time the pacing added (re-planned with and without it), s.
    pace
        Figures of the pacing stage, or ``None`` when it did not run.
    corner_velocity
        On Klipper, where the advance made the file more than 5 % slower: its print time
        at larger extruder corner velocities (:mod:`flowtwin.compensation.corner`), or
        ``None``.
    original_simulation
        The original file's simulation, or how to simulate it again (the compensation
        lets it go once its figures are taken: :attr:`original_result` simulates it when
        it is first read); not part of :meth:`as_dict`.
    compensated_result, piece_row
        The compensated file's simulation and the original move of every compensated
        move (with :attr:`original_result`, for the before/after report,
        :func:`flowtwin.report.write_comparison`); not part of :meth:`as_dict`.
    """

    source: str
    destination: str
    machine: str
    firmware_pressure_advance: bool
    transformations: tuple[str, ...]
    before: FlowFigures
    after: FlowFigures
    time_before_s: float
    time_after_s: float
    commanded_e_before_mm: float
    commanded_e_after_mm: float
    limits: ExtruderLimits
    added_volume_mm3: float = 0.0
    slip_rounds: int = 0
    slip_change: float = 0.0
    slowed_moves: tuple[int, ...] = ()
    guard_time_cost_s: float = 0.0
    grinding_moves_before: int = 0
    grinding_moves_after: int = 0
    max_force_before_n: float = 0.0
    max_force_after_n: float = 0.0
    advance: tuple[AdvancePassSummary, ...] = ()
    trajectory: TrajectoryReport | None = None
    lines_rewritten: int = 0
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0
    lag_factor_changed_moves: int = 0
    paced_moves: tuple[int, ...] = ()
    pace_time_cost_s: float = 0.0
    pace: PaceReport | None = None
    corner_velocity: CornerVelocityCost | None = None
    original_simulation: SimulationResult | Callable[[], SimulationResult] | None = field(
        default=None, repr=False, compare=False)
    compensated_result: SimulationResult | None = field(default=None, repr=False,
                                                        compare=False)
    piece_row: npt.NDArray[np.int64] | None = field(default=None, repr=False, compare=False)

    @property
    def original_result(self) -> SimulationResult | None:
        """The original file's simulation (simulated again the first time it is read when
        the compensation let it go: the same machine, the same bits)."""
        sim = self.original_simulation
        if sim is None or not callable(sim):
            return sim
        sim = sim()
        object.__setattr__(self, "original_simulation", sim)  # (kept once simulated)
        return sim

    def _repr_html_(self) -> str:
        from flowtwin.report.notebook import compensation_repr
        return compensation_repr(self)

    def as_dict(self) -> dict[str, object]:
        """The figures as plain JSON-able values (the ``--json`` object)."""
        def ratio(a: float, b: float) -> float | None:
            return a / b if b > 0 else None

        b, a = self.before, self.after
        return {
            "file": self.source, "output": self.destination, "machine": self.machine,
            "firmware_pressure_advance": self.firmware_pressure_advance,
            "transformations": list(self.transformations),
            "rms_flow_error_before": b.rms_flow_error,
            "rms_flow_error_after": a.rms_flow_error,
            "rms_improvement": ratio(b.rms_flow_error, a.rms_flow_error),
            "peak_overextrusion_before": b.peak_overextrusion,
            "peak_overextrusion_after": a.peak_overextrusion,
            "peak_improvement": ratio(b.peak_overextrusion, a.peak_overextrusion),
            "peak_overextrusion_window_before": b.peak_overextrusion_window,
            "peak_overextrusion_window_after": a.peak_overextrusion_window,
            "peak_window_improvement": ratio(b.peak_overextrusion_window,
                                             a.peak_overextrusion_window),
            "peak_window_mm": b.window_mm,
            "peak_underextrusion_before": b.peak_underextrusion,
            "peak_underextrusion_after": a.peak_underextrusion,
            "delivered_volume_before_mm3": b.delivered_volume_mm3,
            "delivered_volume_after_mm3": a.delivered_volume_mm3,
            "intended_volume_mm3": b.intended_volume_mm3,
            "commanded_e_before_mm": self.commanded_e_before_mm,
            "commanded_e_after_mm": self.commanded_e_after_mm,
            "added_volume_mm3": self.added_volume_mm3,
            "slip_rounds": self.slip_rounds,
            "slip_change": self.slip_change,
            "slowed_moves": len(self.slowed_moves),
            "slowed_lines": list(self.slowed_moves[:1000]),
            "guard_time_cost_s": self.guard_time_cost_s,
            "paced_moves": len(self.paced_moves),
            "paced_lines": list(self.paced_moves[:1000]),
            "pace_time_cost_s": self.pace_time_cost_s,
            "pace": None if self.pace is None else self.pace.as_dict(),
            "time_before_s": self.time_before_s, "time_after_s": self.time_after_s,
            "grinding_moves_before": self.grinding_moves_before,
            "grinding_moves_after": self.grinding_moves_after,
            "max_force_before_n": self.max_force_before_n,
            "max_force_after_n": self.max_force_after_n,
            "advance": [p.as_dict() for p in self.advance],
            "trajectory": None if self.trajectory is None else self.trajectory.as_dict(),
            "extruder_corner_velocity": (None if self.corner_velocity is None
                                         else self.corner_velocity.as_dict()),
            "limits": self.limits.as_dict(), "lines_rewritten": self.lines_rewritten,
            "lag_factor_changed_moves": self.lag_factor_changed_moves,
            "warnings": list(self.warnings), "seconds": self.seconds,
        }
