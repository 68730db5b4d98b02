"""Pressure-advance tower: a thin square tower whose advance factor grows with height.

The factor of each layer is ``K = k_start + k_step_per_mm·z`` with ``z`` the nozzle height
of that layer (the rule of Klipper's ``TUNING_TOWER ... START= FACTOR=``; beyond the
seeds). It is written once at the start of each layer, before the layer's first move. Find
the height where the corners look best and read ``K`` from it (the file's comments and
:attr:`Pattern.pa_settings` list every layer's ``K``).
"""

from __future__ import annotations

from dataclasses import dataclass

from flowtwin.calibration.patterns.pattern import Pattern, PatternWriter, PrintSettings, check_param

__all__ = ["TowerParams", "tower_k_at", "tower_pattern"]


@dataclass(frozen=True, slots=True)
class TowerParams:
    """Parameters of :func:`tower_pattern` (K in s, K per mm of height in s/mm)."""

    k_start: float = 0.0
    k_step_per_mm: float = 0.005
    height_mm: float = 30.0
    size_mm: float = 40.0
    walls: int = 1
    speed_mm_s: float = 100.0
    first_layer_speed_mm_s: float = 30.0

    def __post_init__(self) -> None:
        check_param("k_start", self.k_start, 0.0 <= self.k_start <= 10.0, "0 .. 10 s")
        check_param("k_step_per_mm", self.k_step_per_mm, 0.0 < self.k_step_per_mm <= 1.0,
                    "0 < step <= 1 s/mm")
        check_param("height_mm", self.height_mm, 1.0 <= self.height_mm <= 500.0, "1 .. 500 mm")
        check_param("size_mm", self.size_mm, 5.0 <= self.size_mm <= 300.0, "5 .. 300 mm")
        check_param("walls", self.walls, 1 <= self.walls <= 10, "1 .. 10")
        check_param("speed_mm_s", self.speed_mm_s, 0.0 < self.speed_mm_s <= 2000.0,
                    "0 < v <= 2000 mm/s")
        check_param("first_layer_speed_mm_s", self.first_layer_speed_mm_s,
                    0.0 < self.first_layer_speed_mm_s <= 2000.0, "0 < v <= 2000 mm/s")
        top = self.k_start + self.k_step_per_mm * self.height_mm
        check_param("k_step_per_mm", self.k_step_per_mm, top <= 10.0,
                    f"k_start + k_step_per_mm·height <= 10 s (got {top:g} at the top)")


def tower_k_at(params: TowerParams, z_mm: float) -> float:
    """The tower's advance factor at nozzle height ``z_mm``: ``k_start + k_step_per_mm·z``."""
    return params.k_start + params.k_step_per_mm * z_mm


def tower_pattern(settings: PrintSettings, params: TowerParams | None = None) -> Pattern:
    """A square tower of ``walls`` perimeters with ``K = k_start + k_step_per_mm·z``.

    Parameters
    ----------
    settings
        Shared print settings (firmware, bead, temperatures, placement).
    params
        Factor ramp, tower size and speed.

    Returns
    -------
    Pattern
        Test segments: role ``"side"`` (``"first-layer side"`` on layer 0), group = layer;
        one :class:`~flowtwin.calibration.patterns.pattern.PaSetting` per layer with its ``z``.
    """
    p = params or TowerParams()
    s = settings
    h = s.layer_height_mm
    layers = max(1, int(round(p.height_mm / h)))
    cx, cy = s.center_xy_mm
    half = p.size_mm / 2.0
    check_param("size_mm", p.size_mm, p.size_mm > 2 * p.walls * s.line_spacing_mm + 2.0,
                "larger than the walls")
    w = PatternWriter(s)
    w.start("flowtwin pressure-advance tower", [
        f"K = {p.k_start:g} + {p.k_step_per_mm:g}*z s (z = nozzle height, mm), set at "
        "each layer",
        f"{p.size_mm:g} mm square, {p.walls} wall(s), {layers} layers of {h:g} mm at "
        f"{p.speed_mm_s:g} mm/s"])
    w.prime(cx - half, cx + half, cy - half - 5.0)
    ks: list[float] = []
    for layer in range(layers):
        z = h * (layer + 1)
        if layer:
            w.layer(layer, z)
        speed = p.first_layer_speed_mm_s if layer == 0 else p.speed_mm_s
        role = "first-layer side" if layer == 0 else "side"
        k = round(tower_k_at(p, z), 6)
        ks.append(k)
        w.feature("Tower")
        for i in range(p.walls):
            r = half - s.line_spacing_mm * (i + 0.5)
            corners = [(cx - r, cy - r), (cx + r, cy - r), (cx + r, cy + r), (cx - r, cy + r),
                       (cx - r, cy - r)]
            w.travel(*corners[0])
            if i == 0:
                w.comment(f" layer {layer}: z = {z:.3f} mm, K = {k:g} s")
                w.set_pa(k, layer)
            for x, y in corners[1:]:
                w.extrude_to(x, y, speed, role=role, group=layer)
    w.end()
    notes = (f"{layers} layers; K = {ks[0]:g} s at z = {h:g} mm to {ks[-1]:g} s at "
             f"z = {h * layers:g} mm",
             f"measure the height z of the best corners: K = {p.k_start:g} + "
             f"{p.k_step_per_mm:g}·z")
    return w.finish("tower", "k_s", tuple(ks), notes)
