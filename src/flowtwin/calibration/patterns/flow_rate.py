"""Flow patterns: extrusion-multiplier blocks, a max-volumetric-speed ramp, a flow line.

All three use the slicer bead ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7]; a line printed at
speed ``v`` with multiplier ``m`` asks for the volumetric flow ``Q = m·A·v``.

* **Multiplier blocks** — square blocks of perimeters and solid infill, each with its own
  extrusion multiplier ``m`` applied to every E of the block (written into E, not as
  ``M221``, whose meaning differs between firmwares). Pick the block whose top is closed
  and flat; the new multiplier is that block's ``m`` times the old one.
* **Max-volumetric-speed ramp** — straight lines, each at the speed that gives the next
  flow ``Q_i`` (``v_i = Q_i/A``); find the first line that under-extrudes.
* **Flow line** — one straight line alternating ``v/4`` and ``v`` (flows ``Q/4`` and ``Q``
  with ``Q`` the target): the step response of the nozzle lag [001 Eq. 15] written into a
  bead, for a width sensor or a camera to score. Optionally one line per advance factor.
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

__all__ = [
    "FlowBlockParams",
    "FlowLineParams",
    "MaxFlowParams",
    "flow_block_pattern",
    "flowline_pattern",
    "maxflow_pattern",
]


@dataclass(frozen=True, slots=True)
class FlowBlockParams:
    """Parameters of :func:`flow_block_pattern` (multipliers as fractions, 1 = 100 %)."""

    multiplier_start: float = 0.90
    multiplier_end: float = 1.10
    multiplier_step: float = 0.05
    block_size_mm: float = 20.0
    gap_mm: float = 5.0
    columns: int = 5
    layers: int = 4
    perimeters: int = 2
    perimeter_speed_mm_s: float = 30.0
    infill_speed_mm_s: float = 40.0

    def __post_init__(self) -> None:
        check_param("multiplier_start", self.multiplier_start,
                    0.5 <= self.multiplier_start <= 2.0, "0.5 .. 2")
        check_param("multiplier_end", self.multiplier_end, self.multiplier_end <= 2.0, "<= 2")
        check_param("block_size_mm", self.block_size_mm, 5.0 <= self.block_size_mm <= 100.0,
                    "5 .. 100 mm")
        check_param("gap_mm", self.gap_mm, 1.0 <= self.gap_mm <= 50.0, "1 .. 50 mm")
        check_param("columns", self.columns, 1 <= self.columns <= 20, "1 .. 20")
        check_param("layers", self.layers, 1 <= self.layers <= 50, "1 .. 50")
        check_param("perimeters", self.perimeters, 0 <= self.perimeters <= 5, "0 .. 5")
        for name in ("perimeter_speed_mm_s", "infill_speed_mm_s"):
            v = getattr(self, name)
            check_param(name, v, 0.0 < v <= 2000.0, "0 < v <= 2000 mm/s")

    @property
    def multipliers(self) -> tuple[float, ...]:
        """The extrusion multipliers, one per block, row by row from the front left."""
        return value_steps(self.multiplier_start, self.multiplier_end, self.multiplier_step,
                           name="multiplier", max_count=50)


def flow_block_pattern(settings: PrintSettings,
                       params: FlowBlockParams | None = None) -> Pattern:
    """Square blocks of solid layers, one extrusion multiplier per block.

    Parameters
    ----------
    settings
        Shared print settings.
    params
        Multiplier range and block geometry.

    Returns
    -------
    Pattern
        Test segments (``must_cruise = False``): roles ``"perimeter"`` and ``"infill"``,
        group = block index, flow ``m·A·v``. No advance commands.
    """
    p = params or FlowBlockParams()
    ms = p.multipliers
    s = settings
    sp = s.line_spacing_mm
    cols = min(p.columns, len(ms))
    rows = (len(ms) + cols - 1) // cols
    pitch = p.block_size_mm + p.gap_mm
    cx, cy = s.center_xy_mm
    x_left = cx - (cols * pitch - p.gap_mm) / 2.0
    y_front = cy - (rows * pitch - p.gap_mm) / 2.0
    inner = p.block_size_mm / 2.0 - sp * (p.perimeters + 0.5)
    check_param("block_size_mm", p.block_size_mm, inner > 2.0 * sp,
                "large enough for the perimeters and some infill")
    w = PatternWriter(s)
    w.start("flowtwin extrusion-multiplier blocks", [
        "multiplier " + ", ".join(f"{m:g}" for m in ms) + " (row by row from the front left)",
        f"{p.block_size_mm:g} mm blocks, {p.layers} solid layers, {p.perimeters} perimeters"])
    w.prime(x_left, x_left + max(cols * pitch - p.gap_mm, 30.0), y_front - 5.0)
    for layer in range(p.layers):
        if layer:
            w.layer(layer, s.layer_height_mm * (layer + 1))
        for b, m in enumerate(ms):
            bx = x_left + (b % cols) * pitch + p.block_size_mm / 2.0
            by = y_front + (b // cols) * pitch + p.block_size_mm / 2.0
            w.comment(f" block {b}: extrusion multiplier {m:g}")
            w.feature(f"Block {b}")
            for k in range(p.perimeters):
                r = p.block_size_mm / 2.0 - sp * (k + 0.5)
                pts = [(bx - r, by - r), (bx + r, by - r), (bx + r, by + r), (bx - r, by + r),
                       (bx - r, by - r)]
                w.travel(*pts[0])
                for x, y in pts[1:]:
                    w.extrude_to(x, y, p.perimeter_speed_mm_s, multiplier=m,
                                 role="perimeter", group=b, must_cruise=False)
            # solid rectilinear infill at the line spacing, along X or Y by layer
            n = max(1, int((2.0 * inner) // sp) + 1)
            step = 2.0 * inner / (n - 1) if n > 1 else 0.0
            for i in range(n):
                off = -inner + i * step
                a, c = (-inner, inner) if i % 2 == 0 else (inner, -inner)
                if layer % 2 == 0:
                    w.travel(bx + a, by + off)
                    w.extrude_to(bx + c, by + off, p.infill_speed_mm_s, multiplier=m,
                                 role="infill", group=b, must_cruise=False)
                else:
                    w.travel(bx + off, by + a)
                    w.extrude_to(bx + off, by + c, p.infill_speed_mm_s, multiplier=m,
                                 role="infill", group=b, must_cruise=False)
    w.end()
    notes = (f"{len(ms)} blocks, multiplier {ms[0]:g} (front left) to {ms[-1]:g}, row by row",
             "pick the block with a closed, flat top; new multiplier = its value × the old one")
    return w.finish("flow", "extrusion_multiplier", ms, notes)


@dataclass(frozen=True, slots=True)
class MaxFlowParams:
    """Parameters of :func:`maxflow_pattern` (flows mm³/s, lengths mm)."""

    flow_start_mm3_s: float = 2.0
    flow_end_mm3_s: float = 20.0
    flow_step_mm3_s: float = 2.0
    line_length_mm: float = 80.0
    line_pitch_mm: float = 4.0

    def __post_init__(self) -> None:
        check_param("flow_start_mm3_s", self.flow_start_mm3_s,
                    0.0 < self.flow_start_mm3_s <= 500.0, "0 < Q <= 500 mm³/s")
        check_param("line_length_mm", self.line_length_mm, 10.0 <= self.line_length_mm <= 500.0,
                    "10 .. 500 mm")
        check_param("line_pitch_mm", self.line_pitch_mm, 1.0 <= self.line_pitch_mm <= 50.0,
                    "1 .. 50 mm")

    @property
    def flows(self) -> tuple[float, ...]:
        """The volumetric flows, one per line, front to back, mm³/s."""
        return value_steps(self.flow_start_mm3_s, self.flow_end_mm3_s, self.flow_step_mm3_s,
                           name="flow", max_count=100)


def maxflow_pattern(settings: PrintSettings, params: MaxFlowParams | None = None) -> Pattern:
    """Straight lines of rising volumetric flow ``Q_i`` at ``v_i = Q_i/A`` [001 Eq. 7].

    Parameters
    ----------
    settings
        Shared print settings.
    params
        Flow range and line geometry.

    Returns
    -------
    Pattern
        Test segments: role ``"step"``, group = line index, flow ``Q_i``. No advance
        commands.
    """
    p = params or MaxFlowParams()
    qs = p.flows
    s = settings
    area = s.bead_area_mm2()
    speeds = [q / area for q in qs]
    check_param("flow_end_mm3_s", qs[-1], speeds[-1] <= 2000.0,
                f"<= {2000.0 * area:.1f} mm³/s (2000 mm/s with this bead)")
    cx, cy = s.center_xy_mm
    x0 = cx - p.line_length_mm / 2.0
    x1 = cx + p.line_length_mm / 2.0
    y0 = cy - (len(qs) - 1) * p.line_pitch_mm / 2.0
    w = PatternWriter(s)
    w.start("flowtwin max volumetric speed ramp", [
        "flow " + ", ".join(f"{q:g}" for q in qs) + " mm3/s, front to back",
        f"speed = flow / bead area ({area:.5f} mm2): " + ", ".join(f"{v:.1f}" for v in speeds)
        + " mm/s"])
    w.prime(x0, x1, y0 - p.line_pitch_mm)
    for i, (q, v) in enumerate(zip(qs, speeds, strict=True)):
        y = y0 + i * p.line_pitch_mm
        a, b = (x0, x1) if i % 2 == 0 else (x1, x0)
        w.comment(f" line {i}: {q:g} mm3/s at {v:.2f} mm/s")
        w.feature(f"Flow {i}")
        w.travel(a, y)
        w.extrude_to(b, y, v, role="step", group=i)
    w.end()
    notes = (f"{len(qs)} lines, {qs[0]:g} (front) to {qs[-1]:g} mm³/s (back)",
             "the last line before the bead thins or gaps is the maximum volumetric speed")
    return w.finish("maxflow", "flow_mm3_s", qs, notes)


@dataclass(frozen=True, slots=True)
class FlowLineParams:
    """Parameters of :func:`flowline_pattern` (flow mm³/s, lengths mm, K in s).

    ``k_start``/``k_end``/``k_step``: one line per advance factor (front to back); leave
    ``k_start`` as ``None`` for a single line at the printer's own factor.
    """

    flow_mm3_s: float = 8.0
    cycles: int = 3
    slow_length_mm: float = 15.0
    fast_length_mm: float = 15.0
    line_pitch_mm: float = 5.0
    k_start: float | None = None
    k_end: float | None = None
    k_step: float | None = None

    def __post_init__(self) -> None:
        check_param("flow_mm3_s", self.flow_mm3_s, 0.0 < self.flow_mm3_s <= 500.0,
                    "0 < Q <= 500 mm³/s")
        check_param("cycles", self.cycles, 1 <= self.cycles <= 50, "1 .. 50")
        check_param("slow_length_mm", self.slow_length_mm, self.slow_length_mm >= 2.0, ">= 2 mm")
        check_param("fast_length_mm", self.fast_length_mm, self.fast_length_mm >= 2.0, ">= 2 mm")
        check_param("line_pitch_mm", self.line_pitch_mm, self.line_pitch_mm >= 1.0, ">= 1 mm")
        given = [v is not None for v in (self.k_start, self.k_end, self.k_step)]
        check_param("k_start", self.k_start,  # type: ignore[arg-type]
                    all(given) or not any(given),
                    "give k_start, k_end and k_step together, or none of them")

    @property
    def k_values(self) -> tuple[float, ...] | None:
        """Advance factors, one per line, or ``None`` for one line at the printer's factor."""
        if self.k_start is None or self.k_end is None or self.k_step is None:
            return None
        check_param("k_start", self.k_start, 0.0 <= self.k_start <= 10.0, "0 .. 10 s")
        return value_steps(self.k_start, self.k_end, self.k_step, name="k")


def flowline_pattern(settings: PrintSettings, params: FlowLineParams | None = None) -> Pattern:
    """A straight line alternating ``v/4`` and ``v`` with ``v = Q/A`` [001 Eq. 7].

    Each line is ``cycles`` × (slow, fast) plus a closing slow segment.

    Parameters
    ----------
    settings
        Shared print settings.
    params
        Target flow, segment lengths, optional advance factors.

    Returns
    -------
    Pattern
        Test segments: roles ``"slow"`` (``Q/4``) and ``"fast"`` (``Q``), group = line.
        ``values``: the advance factor of each line (``value_name = "k_s"``), or the
        target flow (``"flow_mm3_s"``) for a single line at the printer's factor.
    """
    p = params or FlowLineParams()
    s = settings
    area = s.bead_area_mm2()
    v_fast = p.flow_mm3_s / area
    check_param("flow_mm3_s", p.flow_mm3_s, v_fast <= 2000.0,
                f"<= {2000.0 * area:.1f} mm³/s (2000 mm/s with this bead)")
    v_slow = v_fast / 4.0
    ks = p.k_values
    n_lines = 1 if ks is None else len(ks)
    length = p.cycles * (p.slow_length_mm + p.fast_length_mm) + p.slow_length_mm
    cx, cy = s.center_xy_mm
    x0 = cx - length / 2.0
    y0 = cy - (n_lines - 1) * p.line_pitch_mm / 2.0
    w = PatternWriter(s)
    k_text = ("at the printer's advance factor" if ks is None else
              f"one line per K from {ks[0]:g} to {ks[-1]:g} s, front to back")
    w.start("flowtwin flow line", [
        f"target flow {p.flow_mm3_s:g} mm3/s: {v_fast:.2f} mm/s, alternating with "
        f"{v_slow:.2f} mm/s ({p.flow_mm3_s / 4:g} mm3/s)", k_text])
    w.prime(x0, x0 + length, y0 - p.line_pitch_mm)
    for i in range(n_lines):
        y = y0 + i * p.line_pitch_mm
        w.feature(f"Flow line {i}")
        w.travel(x0, y)
        if ks is not None:
            w.comment(f" line {i}: K = {ks[i]:g} s")
            w.set_pa(ks[i], i)
        x = x0
        for _ in range(p.cycles):
            x += p.slow_length_mm
            w.extrude_to(x, y, v_slow, role="slow", group=i)
            x += p.fast_length_mm
            w.extrude_to(x, y, v_fast, role="fast", group=i)
        w.extrude_to(x + p.slow_length_mm, y, v_slow, role="slow", group=i)
    w.end()
    notes = (f"{n_lines} line(s) of {length:g} mm: {p.cycles} × ({p.slow_length_mm:g} mm at "
             f"{v_slow:.1f} mm/s, {p.fast_length_mm:g} mm at {v_fast:.1f} mm/s) + "
             f"{p.slow_length_mm:g} mm slow",
             "measure the width along each line (or film it) and fit the lag")
    if ks is None:
        return w.finish("flowline", "flow_mm3_s", (p.flow_mm3_s,), notes)
    return w.finish("flowline", "k_s", ks, notes)
