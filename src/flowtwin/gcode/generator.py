"""flowtwin's own G-code generator: small, fully known test prints.

The built-in example is a rectangular block with a round pillar: perimeters, a rounded
pillar (true ``G2`` arcs or a polygon), rectilinear infill alternating direction per
layer, travels with retractions, 0.2 mm layers. Extrusion per segment uses the slicer
cross-section model [001 Eq. 7] (``A = w·h − (1 − π/4)·h²``), so the filament each line
asks for is known exactly. Comments follow PrusaSlicer's conventions (``;LAYER_CHANGE``,
``;Z:``, ``;HEIGHT:``, ``;TYPE:``) so the reader finds layers and features. Lines are
written by :class:`~flowtwin.gcode.emitter.GcodeEmitter`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass

from flowtwin.atomic import atomic_open
from flowtwin.errors import GcodeError
from flowtwin.gcode.emitter import GcodeEmitter, Retraction, WordFormats
from flowtwin.physics.deposition import bead_area_mm2

__all__ = ["PrintSpec", "generate_print", "write_print"]


@dataclass(frozen=True, slots=True)
class PrintSpec:
    """What to print (all lengths mm, speeds mm/s, temperatures °C).

    The defaults give the demo print: 30 × 20 mm, 10 layers of 0.2 mm (~2 k lines).
    """

    size_x_mm: float = 30.0
    size_y_mm: float = 20.0
    center_xy_mm: tuple[float, float] = (100.0, 100.0)
    layers: int = 10
    layer_height_mm: float = 0.2
    line_width_mm: float = 0.45
    nozzle_diameter_mm: float = 0.4
    filament_diameter_mm: float = 1.75
    perimeters: int = 2
    infill_density: float = 0.25
    pillar_radius_mm: float = 4.0
    use_arcs: bool = True
    polygon_segments: int = 72
    perimeter_speed_mm_s: float = 35.0
    infill_speed_mm_s: float = 60.0
    travel_speed_mm_s: float = 150.0
    retract_mm: float = 0.8
    retract_speed_mm_s: float = 35.0
    z_hop_mm: float = 0.2
    min_travel_for_retract_mm: float = 2.0
    nozzle_temp_c: float = 215.0
    bed_temp_c: float = 60.0

    def __post_init__(self) -> None:
        min_size = 4 * self.line_width_mm * (self.perimeters + 1)
        checks = {
            "size_x_mm": (self.size_x_mm, self.size_x_mm > min_size),
            "size_y_mm": (self.size_y_mm, self.size_y_mm > min_size),
            "layers": (self.layers, self.layers >= 1),
            "layer_height_mm": (self.layer_height_mm,
                                0 < self.layer_height_mm <= self.nozzle_diameter_mm),
            "line_width_mm": (self.line_width_mm, self.line_width_mm >= self.layer_height_mm),
            "infill_density": (self.infill_density, 0 < self.infill_density <= 1),
            "perimeters": (self.perimeters, self.perimeters >= 1),
            "polygon_segments": (self.polygon_segments, self.polygon_segments >= 3),
        }
        for name, (value, ok) in checks.items():
            if not ok:
                raise GcodeError("invalid print specification", field=name, value=value,
                                 allowed="see PrintSpec documentation (sizes positive, "
                                 "layer height <= nozzle, line width >= layer height)")


class _Writer:
    """The print's moves on a :class:`~flowtwin.gcode.emitter.GcodeEmitter`, E from the
    bead model, retracting on long travels."""

    def __init__(self, spec: PrintSpec) -> None:
        self.spec = spec
        self.out = GcodeEmitter(WordFormats())
        area_fil = math.pi * spec.filament_diameter_mm ** 2 / 4.0
        self.e_per_mm = float(bead_area_mm2(spec.line_width_mm, spec.layer_height_mm)) / area_fil
        self.retraction = Retraction(spec.retract_mm, spec.retract_speed_mm_s * 60,
                                     spec.z_hop_mm, spec.travel_speed_mm_s * 60)

    def travel(self, x: float, y: float) -> Iterator[str]:
        s = self.spec
        out = self.out
        far = math.hypot(x - out.x, y - out.y) >= s.min_travel_for_retract_mm
        out.travel(x, y, s.travel_speed_mm_s * 60, self.retraction if far else None)
        yield from out.drain()

    def extrude(self, x: float, y: float, speed_mm_s: float) -> Iterator[str]:
        out = self.out
        dist = math.hypot(x - out.x, y - out.y)
        out.move(x=x, y=y, e_mm=dist * self.e_per_mm, f_mm_min=speed_mm_s * 60)
        yield from out.drain()

    def arc_circle(self, cx: float, cy: float, speed_mm_s: float) -> Iterator[str]:
        """A full counter-clockwise circle from the current point around (cx, cy)."""
        out = self.out
        length = 2 * math.pi * math.hypot(out.x - cx, out.y - cy)
        out.arc(x=out.x, y=out.y, i=cx - out.x, j=cy - out.y, e_mm=length * self.e_per_mm,
                f_mm_min=speed_mm_s * 60)
        yield from out.drain()


def _rect(cx: float, cy: float, hx: float, hy: float) -> list[tuple[float, float]]:
    return [(cx - hx, cy - hy), (cx + hx, cy - hy), (cx + hx, cy + hy), (cx - hx, cy + hy),
            (cx - hx, cy - hy)]


def _layer(spec: PrintSpec, em: _Writer, index: int) -> Iterator[str]:
    cx, cy = spec.center_xy_mm
    w = spec.line_width_mm
    for p in range(spec.perimeters):
        inset = w * (p + 0.5)
        pts = _rect(cx, cy, spec.size_x_mm / 2 - inset, spec.size_y_mm / 2 - inset)
        em.out.marker("TYPE", "External perimeter" if p == 0 else "Perimeter")
        yield from em.travel(*pts[0])
        for x, y in pts[1:]:
            yield from em.extrude(x, y, spec.perimeter_speed_mm_s)
    # round pillar in the middle
    if spec.pillar_radius_mm > 0:
        em.out.marker("TYPE", "External perimeter")
        r = spec.pillar_radius_mm
        yield from em.travel(cx + r, cy)
        if spec.use_arcs:
            yield from em.arc_circle(cx, cy, spec.perimeter_speed_mm_s)
        else:
            n = spec.polygon_segments
            for k in range(1, n + 1):
                a = 2 * math.pi * k / n
                yield from em.extrude(cx + r * math.cos(a), cy + r * math.sin(a),
                                      spec.perimeter_speed_mm_s)
    # rectilinear infill, direction alternating per layer, around the pillar
    em.out.marker("TYPE", "Internal infill")
    inset = w * (spec.perimeters + 0.5)
    hx = spec.size_x_mm / 2 - inset
    hy = spec.size_y_mm / 2 - inset
    spacing = w / spec.infill_density
    along_x = index % 2 == 0
    half_span, half_len = (hy, hx) if along_x else (hx, hy)
    count = max(1, int(2 * half_span / spacing))
    flip = False
    for k in range(count + 1):
        off = -half_span + k * (2 * half_span / count)
        segments: list[tuple[float, float]] = [(-half_len, half_len)]
        r = spec.pillar_radius_mm + w
        if spec.pillar_radius_mm > 0 and abs(off) < r:
            gap = math.sqrt(r * r - off * off)
            segments = [(-half_len, -gap), (gap, half_len)]
        if flip:
            segments = [(b, a) for a, b in reversed(segments)]
        for a, b in segments:
            if abs(b - a) < w:
                continue
            if along_x:
                yield from em.travel(cx + a, cy + off)
                yield from em.extrude(cx + b, cy + off, spec.infill_speed_mm_s)
            else:
                yield from em.travel(cx + off, cy + a)
                yield from em.extrude(cx + off, cy + b, spec.infill_speed_mm_s)
        flip = not flip


def generate_print(spec: PrintSpec | None = None) -> Iterator[str]:
    """Yield the lines (without line endings) of the G-code for ``spec``.

    Parameters
    ----------
    spec
        What to print; :class:`PrintSpec` defaults give the built-in demo print.

    Yields
    ------
    str
        One G-code line each: start sequence, layers, end sequence.
    """
    spec = spec or PrintSpec()
    from flowtwin import __version__

    em = _Writer(spec)
    out = em.out
    out.comment(f"generated by flowtwin {__version__}")
    out.comment(f"layer_height = {spec.layer_height_mm}")
    out.comment(f"nozzle_diameter = {spec.nozzle_diameter_mm}")
    out.comment(f"filament_diameter = {spec.filament_diameter_mm}")
    out.comment(f"extrusion_width = {spec.line_width_mm}")
    out.begin(relative_e=True)
    out.heat_bed(round(spec.bed_temp_c))
    out.heat_nozzle(round(spec.nozzle_temp_c))
    out.home()
    out.heat_bed(round(spec.bed_temp_c), wait=True)
    out.heat_nozzle(round(spec.nozzle_temp_c), wait=True)
    out.reset_e()
    # prime line along the front edge
    x0 = spec.center_xy_mm[0] - spec.size_x_mm / 2 - 5
    y0 = spec.center_xy_mm[1] - spec.size_y_mm / 2 - 5
    out.move(z=spec.layer_height_mm, f_mm_min=600)
    out.move(x=x0, y=y0, f_mm_min=spec.travel_speed_mm_s * 60)
    out.marker("TYPE", "Skirt/Brim")
    yield from out.drain()
    yield from em.extrude(x0 + spec.size_x_mm + 10, y0, spec.perimeter_speed_mm_s)
    for index in range(spec.layers):
        z = spec.layer_height_mm * (index + 1)
        out.marker("LAYER_CHANGE")
        out.marker("Z", f"{z:.3f}")
        out.marker("HEIGHT", f"{spec.layer_height_mm:.3f}")
        out.move(z=z, f_mm_min=600)
        yield from out.drain()
        yield from _layer(spec, em, index)
    out.move(e_mm=-spec.retract_mm, f_mm_min=spec.retract_speed_mm_s * 60)
    out.move(z=out.z + 10, f_mm_min=600)
    out.heat_nozzle(0)
    out.heat_bed(0)
    out.line("M84")
    yield from out.drain()


def write_print(path: str | os.PathLike[str], spec: PrintSpec | None = None) -> int:
    """Write the G-code for ``spec`` to ``path`` atomically; return the number of lines."""
    count = 0
    with atomic_open(path, "w") as fh:
        for line in generate_print(spec):
            fh.write(line)
            fh.write("\n")
            count += 1
    return count
