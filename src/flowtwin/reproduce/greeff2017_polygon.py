"""The print-job test part of Greeff & Schilling [003 §3.3], as flowtwin's own G-code.

"A single track width polygon is printed. The polygon has 40 sides and each side is about
5.3 mm long. The hollow object is 10 mm tall and requires 33 layers with a layer thickness
of 0.3 mm. The first 11 layers were printed at 230 °C, the next 11 at 190 °C and the last
layers again at 230 °C" [003 §3.3]; "each object is a 40 sided polygon with a diameter of
68 mm" [003 Fig. 13] (circumscribed: a side is ``68·sin(π/40) = 5.34`` mm). "The printer
first prints an extruder test line and then the first layer at a slower speed of 1 mm/s.
The remainder is printed at a set point speed of 2 mm/s" (filament speed); the printer
"waited for the extruder to reach the set point temperature, before continuing" and
retracted between layers (the spikes of [003 Fig. 12]).

Beyond the seeds (chosen, documented): a 0.6 mm single-track wall (so 2 mm/s of 2.85 mm
filament is a 79 mm/s print speed, under the RF1000's "maximum safe print movement speed
of less than 80 mm/s" [003 §2.1]); retraction 1 mm at 16 mm/s (the retraction of
[003 §3.2]); ``M109 R`` (wait heating or cooling, Marlin) at each change of set point.
Extrusion per mm of wall comes from the slicer's bead cross-section
``A = w·h − (1 − π/4)·h²`` [001 Eq. 7, 003 Eq. 2].
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

from flowtwin.errors import GcodeError
from flowtwin.gcode.emitter import GcodeEmitter, WordFormats
from flowtwin.physics.deposition import bead_area_mm2

__all__ = ["PolygonSpec", "polygon_gcode"]


@dataclass(frozen=True, slots=True)
class PolygonSpec:
    """Greeff's test polygon (lengths mm, speeds mm/s, temperatures °C).

    Attributes
    ----------
    sides
        Number of sides (40 [003 §3.3]).
    diameter_mm
        Circumscribed diameter (68 mm [003 Fig. 13]).
    center_xy_mm
        Centre on the bed.
    layer_height_mm
        Layer thickness (0.3 mm [003 §3.3]).
    line_width_mm
        Width of the single-track wall (beyond the seeds, 0.6 mm).
    filament_diameter_mm
        Filament diameter (2.85 mm [003 §3.1]).
    feed_mm_s
        Filament speed of the walls (2 mm/s [003 §3.3]).
    first_layer_feed_mm_s
        Filament speed of the test line and the first layer (1 mm/s [003 §3.3]).
    temperature_sets
        ``(layers, temperature)`` per set, in order (11 × 230, 11 × 190, 11 × 230 °C).
    retract_mm, retract_speed_mm_s
        Retraction between layers (1 mm at 16 mm/s [003 §3.2]).
    travel_speed_mm_s
        Travel speed.
    prime_length_mm
        Length of the extruder test line.
    """

    sides: int = 40
    diameter_mm: float = 68.0
    center_xy_mm: tuple[float, float] = (110.0, 105.0)
    layer_height_mm: float = 0.3
    line_width_mm: float = 0.6
    filament_diameter_mm: float = 2.85
    nozzle_diameter_mm: float = 0.5
    feed_mm_s: float = 2.0
    first_layer_feed_mm_s: float = 1.0
    temperature_sets: tuple[tuple[int, float], ...] = ((11, 230.0), (11, 190.0), (11, 230.0))
    retract_mm: float = 1.0
    retract_speed_mm_s: float = 16.0
    travel_speed_mm_s: float = 100.0
    prime_length_mm: float = 30.0

    def __post_init__(self) -> None:
        checks = {
            "sides": self.sides >= 3,
            "diameter_mm": 1.0 <= self.diameter_mm <= 500.0,
            "layer_height_mm": 0.0 < self.layer_height_mm <= self.nozzle_diameter_mm,
            "line_width_mm": self.line_width_mm >= self.layer_height_mm,
            "feed_mm_s": 0.0 < self.feed_mm_s <= 50.0,
            "first_layer_feed_mm_s": 0.0 < self.first_layer_feed_mm_s <= 50.0,
            "temperature_sets": len(self.temperature_sets) >= 1 and all(
                n >= 1 and 150.0 <= t <= 300.0 for n, t in self.temperature_sets),
            "retract_mm": self.retract_mm >= 0.0,
            "prime_length_mm": self.prime_length_mm >= 0.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise GcodeError("invalid test-polygon specification", field=name,
                                 value=getattr(self, name),
                                 allowed="see PolygonSpec (sizes and speeds positive, "
                                 "layer height <= nozzle <= line width, sets of >= 1 layer "
                                 "at 150-300 °C)")

    @classmethod
    def greeff(cls, *, layers_per_set: int = 11) -> PolygonSpec:
        """[003 §3.3]'s part; ``layers_per_set`` < 11 gives a shorter part (tests)."""
        return cls(temperature_sets=((layers_per_set, 230.0), (layers_per_set, 190.0),
                                     (layers_per_set, 230.0)))

    @property
    def layers(self) -> int:
        """Total number of layers."""
        return sum(n for n, _ in self.temperature_sets)

    @property
    def side_mm(self) -> float:
        """Length of one side, ``D·sin(π/n)``, mm."""
        return self.diameter_mm * math.sin(math.pi / self.sides)

    @property
    def e_per_mm(self) -> float:
        """Filament per mm of wall, ``A_bead/A_fil`` [001 Eq. 7]."""
        area_fil = math.pi * self.filament_diameter_mm ** 2 / 4.0
        return float(bead_area_mm2(self.line_width_mm, self.layer_height_mm)) / area_fil

    def print_speed_mm_s(self, feed_mm_s: float) -> float:
        """Nozzle speed that makes the filament move at ``feed_mm_s``, mm/s."""
        return feed_mm_s / self.e_per_mm

    def layer_temperature_c(self, layer: int) -> float:
        """Nozzle set point of layer ``layer`` (0-based), °C."""
        first = 0
        for n, temp in self.temperature_sets:
            if layer < first + n:
                return temp
            first += n
        return self.temperature_sets[-1][1]


def polygon_gcode(spec: PolygonSpec | None = None) -> str:
    """G-code of the test polygon (Marlin dialect, relative E, PrusaSlicer comments), written
    by :class:`~flowtwin.gcode.emitter.GcodeEmitter`.

    Parameters
    ----------
    spec
        The part (default :class:`PolygonSpec`, [003 §3.3]).

    Returns
    -------
    str
        The G-code text, one command per line.
    """
    s = spec or PolygonSpec()
    cx, cy = s.center_xy_mm
    r = s.diameter_mm / 2.0
    pts = [(cx + r * math.cos(2 * math.pi * k / s.sides),
            cy + r * math.sin(2 * math.pi * k / s.sides)) for k in range(s.sides + 1)]
    f_travel = s.travel_speed_mm_s * 60.0
    f_retract = s.retract_speed_mm_s * 60.0
    out = GcodeEmitter(WordFormats())

    def retract(sign: float) -> None:
        out.move(e_mm=sign * s.retract_mm, f_mm_min=f_retract)

    t0 = s.layer_temperature_c(0)
    out.comment("flowtwin: print-job test part of Greeff & Schilling [003 sec. 3.3]")
    out.comment(f"{s.sides}-sided polygon, {s.diameter_mm:g} mm, {s.layers} layers of "
                f"{s.layer_height_mm:g} mm")
    out.comment(f"layer_height = {s.layer_height_mm}")
    out.comment(f"nozzle_diameter = {s.nozzle_diameter_mm}")
    out.comment(f"filament_diameter = {s.filament_diameter_mm}")
    out.comment(f"extrusion_width = {s.line_width_mm}")
    out.begin(relative_e=True)
    out.heat_nozzle(round(t0))
    out.home()
    out.heat_nozzle(round(t0), wait=True)
    out.reset_e()
    out.move(z=s.layer_height_mm, f_mm_min=600)
    # extruder test line, in front of the part, at the first-layer speed
    y_line = cy - r - 5.0
    x_line = cx - s.prime_length_mm / 2.0
    f_first = s.print_speed_mm_s(s.first_layer_feed_mm_s) * 60.0
    if s.prime_length_mm > 0:
        out.move(x=x_line, y=y_line, f_mm_min=f_travel)
        out.marker("TYPE", "Skirt/Brim")
        out.move(x=x_line + s.prime_length_mm, y=y_line,
                 e_mm=s.prime_length_mm * s.e_per_mm, f_mm_min=f_first)
        if s.retract_mm > 0:
            retract(-1.0)
    out.move(x=pts[0][0], y=pts[0][1], f_mm_min=f_travel)
    if s.prime_length_mm > 0 and s.retract_mm > 0:
        retract(1.0)
    current = t0
    for layer in range(s.layers):
        z = s.layer_height_mm * (layer + 1)
        temp = s.layer_temperature_c(layer)
        if layer > 0:
            if temp != current:
                out.heat_nozzle(round(temp), either_way=True,
                                comment="next layer set [003 sec. 3.3]")
                current = temp
            if s.retract_mm > 0:
                retract(-1.0)
        out.marker("LAYER_CHANGE")
        out.marker("Z", f"{z:.3f}")
        out.marker("HEIGHT", f"{s.layer_height_mm:.3f}")
        if layer > 0:
            out.move(z=z, f_mm_min=600)
            if s.retract_mm > 0:
                retract(1.0)
        out.marker("TYPE", "External perimeter")
        feed = s.first_layer_feed_mm_s if layer == 0 else s.feed_mm_s
        f_print = s.print_speed_mm_s(feed) * 60.0
        for (x0, y0), (x1, y1) in itertools.pairwise(pts):
            out.move(x=x1, y=y1, e_mm=math.hypot(x1 - x0, y1 - y0) * s.e_per_mm,
                     f_mm_min=f_print)
    if s.retract_mm > 0:
        retract(-1.0)
    out.move(z=s.layer_height_mm * s.layers + 10.0, f_mm_min=600)
    out.heat_nozzle(0)
    out.line("M84")
    return out.text()
