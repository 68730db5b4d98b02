"""Ellis-style chevrons: nested 90° corners, one advance factor per whole chevron.

Each chevron is ``walls`` nested open corners (``>``, apex towards +X, arms at ±45°) of
touching lines; the chevrons of the successive advance factors nest into each other along
X. The corner is where the factor shows: too low and the apex bulges, too high and the
lines pull apart before it. The layout follows Andrew Ellis' pressure-advance pattern
(beyond the seeds); the bead is [001 Eq. 7], the wall pitch the slicer's line spacing
``w − (1 − π/4)·h``.

One factor per *chevron*: the advance command is written once before the first wall of a
chevron, on every layer, and never between the moves of a corner. (A known bug of another
pattern tool sets the factor from the X of each move's end point, so the two arms of one
corner can run with different factors.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flowtwin.calibration.patterns.pattern import (
    Pattern,
    PatternWriter,
    PrintSettings,
    check_param,
    value_steps,
)

__all__ = ["ChevronParams", "chevron_pattern"]

_SIN45 = math.sin(math.radians(45.0))
_TICK_GAP_MM = 2.0
_TICK_LENGTH_MM = 4.0


@dataclass(frozen=True, slots=True)
class ChevronParams:
    """Parameters of :func:`chevron_pattern` (speeds mm/s, lengths mm, K in s).

    ``arm_length_mm`` is the length of each arm of the outer wall; ``gap_mm`` the clear
    gap between neighbouring chevrons, measured across the arms.
    """

    k_start: float = 0.0
    k_end: float = 0.1
    k_step: float = 0.005
    speed_mm_s: float = 100.0
    first_layer_speed_mm_s: float = 30.0
    arm_length_mm: float = 20.0
    walls: int = 3
    layers: int = 4
    gap_mm: float = 2.0
    mark_every: int = 5

    def __post_init__(self) -> None:
        check_param("k_start", self.k_start, 0.0 <= self.k_start <= 10.0, "0 .. 10 s")
        check_param("speed_mm_s", self.speed_mm_s, 0.0 < self.speed_mm_s <= 2000.0,
                    "0 < v <= 2000 mm/s")
        check_param("first_layer_speed_mm_s", self.first_layer_speed_mm_s,
                    0.0 < self.first_layer_speed_mm_s <= 2000.0, "0 < v <= 2000 mm/s")
        check_param("arm_length_mm", self.arm_length_mm, 2.0 <= self.arm_length_mm <= 200.0,
                    "2 .. 200 mm")
        check_param("walls", self.walls, 1 <= self.walls <= 20, "1 .. 20")
        check_param("layers", self.layers, 1 <= self.layers <= 100, "1 .. 100")
        check_param("gap_mm", self.gap_mm, 0.0 <= self.gap_mm <= 50.0, "0 .. 50 mm")
        check_param("mark_every", self.mark_every, self.mark_every >= 0, ">= 0 (0 = no ticks)")

    @property
    def k_values(self) -> tuple[float, ...]:
        """The advance factors, one per chevron, left to right."""
        return value_steps(self.k_start, self.k_end, self.k_step, name="k")


def chevron_pattern(settings: PrintSettings, params: ChevronParams | None = None) -> Pattern:
    """Nested 90° chevrons, one advance factor per chevron, over several layers.

    Parameters
    ----------
    settings
        Shared print settings (firmware, bead, temperatures, placement).
    params
        K range, speed, arm length, walls and layers.

    Returns
    -------
    Pattern
        Test segments: role ``"arm"`` (``"first-layer arm"`` on layer 0), group = chevron
        index; one :class:`~flowtwin.calibration.patterns.pattern.PaSetting` per chevron per
        layer, written before the chevron's first wall.
    """
    p = params or ChevronParams()
    ks = p.k_values
    s = settings
    half = p.arm_length_mm * _SIN45          # X and Y extent of one arm
    dx_wall = s.line_spacing_mm / _SIN45     # X shift that puts parallel arms touching
    pitch = p.walls * dx_wall + p.gap_mm / _SIN45
    width = half + (len(ks) - 1) * pitch + (p.walls - 1) * dx_wall
    cx, cy = s.center_xy_mm
    x0 = cx - width / 2.0
    w = PatternWriter(s)
    w.start("flowtwin chevron pattern", [
        f"K from {ks[0]:g} to {ks[-1]:g} s in steps of {p.k_step:g} s, left to right",
        f"{p.walls} nested 90-degree corners per K, arms {p.arm_length_mm:g} mm at "
        f"{p.speed_mm_s:g} mm/s, {p.layers} layers; one advance command per chevron"])
    w.prime(x0, x0 + max(width, 30.0), cy - half - 8.0)
    if p.mark_every:
        w.feature("Marks")
        for j in range(0, len(ks), p.mark_every):
            x = x0 + j * pitch
            w.travel(x, cy - half - _TICK_GAP_MM)
            w.extrude_to(x, cy - half - _TICK_GAP_MM - _TICK_LENGTH_MM,
                         p.first_layer_speed_mm_s)
    wall_count = 0
    for layer in range(p.layers):
        if layer:
            w.layer(layer, s.layer_height_mm * (layer + 1))
        speed = p.first_layer_speed_mm_s if layer == 0 else p.speed_mm_s
        role = "first-layer arm" if layer == 0 else "arm"
        for j, k in enumerate(ks):
            w.comment(f" chevron {j}: K = {k:g} s")
            w.feature(f"Chevron {j}")
            for i in range(p.walls):
                x = x0 + j * pitch + i * dx_wall
                up = wall_count % 2 == 0
                y_from, y_to = (cy - half, cy + half) if up else (cy + half, cy - half)
                w.travel(x, y_from)
                if i == 0:
                    w.set_pa(k, j)   # once per chevron, before its first corner
                w.extrude_to(x + half, cy, speed, role=role, group=j)
                w.extrude_to(x, y_to, speed, role=role, group=j)
                wall_count += 1
    w.end()
    notes = (f"{len(ks)} chevrons, K = {ks[0]:g} (left) to {ks[-1]:g} s (right)",
             "pick the chevron whose corner is sharp without a gap before the apex",
             f"a tick in front marks every {p.mark_every}th chevron, starting with the first"
             if p.mark_every else "no ticks")
    return w.finish("chevron", "k_s", ks, notes)
