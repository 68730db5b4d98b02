"""Marlin-style K-factor test lines: slow / fast / slow, one advance factor per line.

The layout of Marlin's linear-advance calibration pattern that Tronvoll et al. printed
[001 "Experimental setup", Fig. 10, Table I]: each line is 20 mm slow, 40 mm fast, 20 mm
slow, so the flow steps up and down by the speed ratio; with the advance factor ``K`` too
low the line is thin after the step up and thick after the step down [001 Fig. 2], too high
the other way round. Lines are stacked front to back, one ``K`` per line (set once, before
the line's first move), ``K`` from ``k_start`` to ``k_end``; [001 Table I] used 0–0.2 s in
0.01 s steps at 0.48 mm lines, which are the defaults here. A tick to the right of every
``mark_every``-th line helps count them.
"""

from __future__ import annotations

from dataclasses import dataclass

from flowtwin.calibration.patterns.pattern import (
    Pattern,
    PatternWriter,
    PrintSettings,
    check_param,
    value_steps,
)

__all__ = ["KLineParams", "kline_pattern"]

_TICK_GAP_MM = 3.0
_TICK_LENGTH_MM = 4.0


@dataclass(frozen=True, slots=True)
class KLineParams:
    """Parameters of :func:`kline_pattern` (speeds mm/s, lengths mm, K in s)."""

    k_start: float = 0.0
    k_end: float = 0.2
    k_step: float = 0.01
    slow_speed_mm_s: float = 20.0
    fast_speed_mm_s: float = 70.0
    slow_length_mm: float = 20.0
    fast_length_mm: float = 40.0
    line_pitch_mm: float = 5.0
    mark_every: int = 5

    def __post_init__(self) -> None:
        check_param("k_start", self.k_start, 0.0 <= self.k_start <= 10.0, "0 .. 10 s")
        check_param("slow_speed_mm_s", self.slow_speed_mm_s,
                    0.0 < self.slow_speed_mm_s < self.fast_speed_mm_s,
                    f"0 < slow < fast ({self.fast_speed_mm_s:g} mm/s)")
        check_param("fast_speed_mm_s", self.fast_speed_mm_s,
                    self.fast_speed_mm_s <= 2000.0, "<= 2000 mm/s")
        check_param("slow_length_mm", self.slow_length_mm, self.slow_length_mm >= 1.0, ">= 1 mm")
        check_param("fast_length_mm", self.fast_length_mm, self.fast_length_mm >= 1.0, ">= 1 mm")
        check_param("line_pitch_mm", self.line_pitch_mm, self.line_pitch_mm >= 1.0, ">= 1 mm")
        check_param("mark_every", self.mark_every, self.mark_every >= 0, ">= 0 (0 = no ticks)")

    @property
    def k_values(self) -> tuple[float, ...]:
        """The advance factors, one per line, front to back."""
        return value_steps(self.k_start, self.k_end, self.k_step, name="k")


def kline_pattern(settings: PrintSettings, params: KLineParams | None = None) -> Pattern:
    """K-factor test lines [001 Fig. 10]: one line of slow/fast/slow per advance factor.

    Parameters
    ----------
    settings
        Shared print settings (firmware, bead, temperatures, placement).
    params
        K range, speeds and segment lengths; defaults follow [001 Table I].

    Returns
    -------
    Pattern
        Test segments: roles ``"slow"``, ``"fast"``, ``"slow"`` per line, group = line
        index; one :class:`~flowtwin.calibration.patterns.pattern.PaSetting` per line.
    """
    p = params or KLineParams()
    ks = p.k_values
    s = settings
    length = 2 * p.slow_length_mm + p.fast_length_mm
    cx, cy = s.center_xy_mm
    x0 = cx - length / 2.0
    y0 = cy - (len(ks) - 1) * p.line_pitch_mm / 2.0
    w = PatternWriter(s)
    w.start("flowtwin K-factor lines", [
        f"K from {ks[0]:g} to {ks[-1]:g} s in steps of {p.k_step:g} s, front to back",
        f"each line: {p.slow_length_mm:g} mm at {p.slow_speed_mm_s:g} mm/s, "
        f"{p.fast_length_mm:g} mm at {p.fast_speed_mm_s:g} mm/s, "
        f"{p.slow_length_mm:g} mm at {p.slow_speed_mm_s:g} mm/s"])
    w.prime(x0, x0 + length, y0 - p.line_pitch_mm)
    for i, k in enumerate(ks):
        y = y0 + i * p.line_pitch_mm
        w.comment(f" K line {i}: K = {k:g} s")
        w.feature(f"K-line {i}")
        w.travel(x0, y)
        w.set_pa(k, i)
        w.extrude_to(x0 + p.slow_length_mm, y, p.slow_speed_mm_s, role="slow", group=i)
        w.extrude_to(x0 + p.slow_length_mm + p.fast_length_mm, y, p.fast_speed_mm_s,
                     role="fast", group=i)
        w.extrude_to(x0 + length, y, p.slow_speed_mm_s, role="slow", group=i)
        if p.mark_every and i % p.mark_every == 0:
            w.travel(x0 + length + _TICK_GAP_MM, y, retract=False)
            w.extrude_to(x0 + length + _TICK_GAP_MM + _TICK_LENGTH_MM, y, p.slow_speed_mm_s)
    w.end()
    notes = (f"{len(ks)} lines, K = {ks[0]:g} (front) to {ks[-1]:g} s (back)",
             "pick the line whose width stays even across both speed steps",
             f"a tick right of the line marks every {p.mark_every}th K"
             if p.mark_every else "no ticks")
    return w.finish("kline", "k_s", ks, notes)
