"""``flowtwin calibrate pattern KIND``: one command per pattern kind, each with its own options.

Every kind takes the shared print options (firmware, bead, temperatures, placement, the
check) and only its own parameters; an option of another kind is a usage error. A thin
layer over :func:`flowtwin.calibration.patterns.catalog.generate_pattern`.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from flowtwin.calibration.guide import PATTERN_HELP, PATTERN_KIND_HELP
from flowtwin.calibration.patterns.catalog import PATTERN_KINDS, generate_pattern
from flowtwin.calibration.patterns.chevron import ChevronParams
from flowtwin.calibration.patterns.flow_rate import FlowBlockParams, FlowLineParams, MaxFlowParams
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import PrintSettings, write_pattern
from flowtwin.calibration.patterns.tower import TowerParams
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.firmware import Firmware

__all__ = ["register"]


def _default(params_type: type[Any], name: str) -> Any:
    """The default of field ``name`` of a pattern's parameter dataclass."""
    for f in dataclasses.fields(params_type):
        if f.name == name:
            return f.default
    raise KeyError(name)


# ---------------------------------------------------------------- the kinds' options ---
# One signature per kind: the options it has, with its defaults. Option name -> parameter
# field in _FIELDS where the two differ.

_FIELDS = {
    "slow_speed": "slow_speed_mm_s", "fast_speed": "fast_speed_mm_s", "speed": "speed_mm_s",
    "first_layer_speed": "first_layer_speed_mm_s", "height": "height_mm", "size": "size_mm",
    "block_size": "block_size_mm", "flow_start": "flow_start_mm3_s",
    "flow_end": "flow_end_mm3_s", "flow_step": "flow_step_mm3_s", "flow": "flow_mm3_s",
}

_KStart = Annotated[float, typer.Option(help="First advance factor, s.")]
_KEnd = Annotated[float, typer.Option(help="Last advance factor, s.")]
_KStep = Annotated[float, typer.Option(help="Advance factor step, s.")]
_Speed = Annotated[float, typer.Option(help="Print speed, mm/s.")]
_FirstLayerSpeed = Annotated[float, typer.Option(help="First-layer speed, mm/s.")]
_MarkEvery = Annotated[int, typer.Option(help="A tick every N lines (0 = none).")]


def _kline(
    k_start: _KStart = _default(KLineParams, "k_start"),
    k_end: _KEnd = _default(KLineParams, "k_end"),
    k_step: _KStep = _default(KLineParams, "k_step"),
    slow_speed: Annotated[float, typer.Option(help="Slow speed, mm/s.")]
    = _default(KLineParams, "slow_speed_mm_s"),
    fast_speed: Annotated[float, typer.Option(help="Fast speed, mm/s.")]
    = _default(KLineParams, "fast_speed_mm_s"),
    mark_every: _MarkEvery = _default(KLineParams, "mark_every"),
) -> None: ...


def _chevron(
    k_start: _KStart = _default(ChevronParams, "k_start"),
    k_end: _KEnd = _default(ChevronParams, "k_end"),
    k_step: _KStep = _default(ChevronParams, "k_step"),
    speed: _Speed = _default(ChevronParams, "speed_mm_s"),
    first_layer_speed: _FirstLayerSpeed = _default(ChevronParams, "first_layer_speed_mm_s"),
    walls: Annotated[int, typer.Option(help="Walls (nested corners) per chevron.")]
    = _default(ChevronParams, "walls"),
    layers: Annotated[int, typer.Option(help="Layers.")] = _default(ChevronParams, "layers"),
    mark_every: _MarkEvery = _default(ChevronParams, "mark_every"),
) -> None: ...


def _tower(
    k_start: Annotated[float, typer.Option(help="Advance factor at z = 0, s.")]
    = _default(TowerParams, "k_start"),
    k_step_per_mm: Annotated[float, typer.Option(help="Advance factor added per mm of "
                                                      "height, s/mm.")]
    = _default(TowerParams, "k_step_per_mm"),
    height: Annotated[float, typer.Option(help="Height, mm.")] = _default(TowerParams,
                                                                         "height_mm"),
    size: Annotated[float, typer.Option(help="Side length, mm.")] = _default(TowerParams,
                                                                            "size_mm"),
    walls: Annotated[int, typer.Option(help="Walls.")] = _default(TowerParams, "walls"),
    speed: _Speed = _default(TowerParams, "speed_mm_s"),
    first_layer_speed: _FirstLayerSpeed = _default(TowerParams, "first_layer_speed_mm_s"),
) -> None: ...


def _flow(
    multiplier_start: Annotated[float, typer.Option(help="First extrusion multiplier "
                                                         "(1 = 100 %).")]
    = _default(FlowBlockParams, "multiplier_start"),
    multiplier_end: Annotated[float, typer.Option(help="Last extrusion multiplier.")]
    = _default(FlowBlockParams, "multiplier_end"),
    multiplier_step: Annotated[float, typer.Option(help="Multiplier step.")]
    = _default(FlowBlockParams, "multiplier_step"),
    block_size: Annotated[float, typer.Option(help="Block side, mm.")]
    = _default(FlowBlockParams, "block_size_mm"),
    layers: Annotated[int, typer.Option(help="Layers.")] = _default(FlowBlockParams, "layers"),
) -> None: ...


def _maxflow(
    flow_start: Annotated[float, typer.Option(help="First flow, mm3/s.")]
    = _default(MaxFlowParams, "flow_start_mm3_s"),
    flow_end: Annotated[float, typer.Option(help="Last flow, mm3/s.")]
    = _default(MaxFlowParams, "flow_end_mm3_s"),
    flow_step: Annotated[float, typer.Option(help="Flow step, mm3/s.")]
    = _default(MaxFlowParams, "flow_step_mm3_s"),
) -> None: ...


def _flowline(
    flow: Annotated[float, typer.Option(help="Target flow at v, mm3/s.")]
    = _default(FlowLineParams, "flow_mm3_s"),
    cycles: Annotated[int, typer.Option(help="Slow/fast cycles.")]
    = _default(FlowLineParams, "cycles"),
    k_start: Annotated[float | None, typer.Option(help="First advance factor, s (one line "
                                                       "per K; default: one line, no "
                                                       "advance command).")] = None,
    k_end: Annotated[float | None, typer.Option(help="Last advance factor, s.")] = None,
    k_step: Annotated[float | None, typer.Option(help="Advance factor step, s.")] = None,
) -> None: ...


_KIND_OPTIONS: dict[str, Callable[..., None]] = {
    "kline": _kline, "chevron": _chevron, "tower": _tower, "flow": _flow,
    "maxflow": _maxflow, "flowline": _flowline,
}


# ------------------------------------------------------------------ shared options ---

def _shared(
    output: Annotated[Path, typer.Option("--output", "-o", help="G-code file to write.")],
    firmware: Annotated[str, typer.Option(help="klipper, marlin, reprapfirmware (rrf), "
                                               "prusa (Buddy: MK4/XL/MINI; 8-bit MK3S/MK2.5 "
                                               "use marlin) or repetier.")] = "klipper",
    nozzle_diameter: Annotated[float, typer.Option(help="Nozzle, mm.")] = 0.4,
    filament_diameter: Annotated[float, typer.Option(help="Filament, mm.")] = 1.75,
    layer_height: Annotated[float, typer.Option(help="Layer height, mm.")] = 0.2,
    line_width: Annotated[float, typer.Option(help="Line width, mm.")] = 0.48,
    nozzle_temp: Annotated[float, typer.Option(help="Nozzle temperature, C.")] = 215.0,
    bed_temp: Annotated[float, typer.Option(help="Bed temperature, C.")] = 60.0,
    fan: Annotated[float, typer.Option(help="Part fan, %.")] = 0.0,
    accel: Annotated[float | None, typer.Option(
        help="Set this print/travel acceleration, mm/s2 (default: the printer's).")] = None,
    pa_smooth_time: Annotated[float | None, typer.Option(
        help="Klipper SMOOTH_TIME / Prusa W with every advance command, s.")] = None,
    center_x: Annotated[float, typer.Option(help="Pattern centre X, mm.")] = 110.0,
    center_y: Annotated[float, typer.Option(help="Pattern centre Y, mm.")] = 110.0,
    bed_x: Annotated[float, typer.Option(help="Bed size X, mm.")] = 220.0,
    bed_y: Annotated[float, typer.Option(help="Bed size Y, mm.")] = 220.0,
    retract: Annotated[float, typer.Option(help="Retraction on travels, mm.")] = 0.8,
    printer: Annotated[str | None, typer.Option(
        help="Printer profile to check the pattern with (built-in name or TOML); default "
             "generic-klipper / generic-marlin.")] = None,
    check: Annotated[bool, typer.Option("--check/--no-check",
                                        help="Read back and plan the pattern.")] = True,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None: ...


def _write(kind: str, params: dict[str, Any], *, output: Path, firmware: str,
           nozzle_diameter: float, filament_diameter: float, layer_height: float,
           line_width: float, nozzle_temp: float, bed_temp: float, fan: float,
           accel: float | None, pa_smooth_time: float | None, center_x: float,
           center_y: float, bed_x: float, bed_y: float, retract: float,
           printer: str | None, check: bool, json_out: bool) -> None:
    """Generate, check, write and report pattern ``kind`` (``params``: its fields)."""
    settings = PrintSettings(
        firmware=Firmware.parse(firmware),
        nozzle_diameter_mm=nozzle_diameter, filament_diameter_mm=filament_diameter,
        layer_height_mm=layer_height, line_width_mm=line_width, nozzle_temp_c=nozzle_temp,
        bed_temp_c=bed_temp, fan_percent=fan, accel_mm_s2=accel,
        pa_smooth_time_s=pa_smooth_time, center_xy_mm=(center_x, center_y),
        bed_size_mm=(bed_x, bed_y), retract_mm=retract)
    from flowtwin.calibration.patterns.verify import verify_pattern  # plans: numerical stack

    pattern = generate_pattern(kind, settings, params)
    result = verify_pattern(pattern, printer=printer) if check else None
    write_pattern(output, pattern)
    summary: dict[str, Any] = {"output": str(output), **pattern.summary()}
    summary["check"] = None if result is None else result.summary()
    if json_out:
        print_json(summary)
        return
    rows: list[tuple[str, object]] = [
        ("pattern", f"{kind} ({PATTERN_KINDS[kind].description})"),
        ("firmware", settings.firmware.value), ("file", f"{output} ({len(pattern.lines)} "
                                                        "lines)"),
        (pattern.value_name, ", ".join(f"{v:g}" for v in pattern.values)),
        ("filament", f"{pattern.filament_mm:.1f} mm"),
        ("bead area", f"{settings.bead_area_mm2():.5f} mm² (w {settings.line_width_mm:g}, "
                      f"h {settings.layer_height_mm:g})")]
    if result is not None:
        rows.append(("checked with", f"{result.printer} ({result.firmware} planner): "
                     f"{fmt_duration(result.total_time_s)}"))
        rows.append(("test speeds reached", f"{len(result.segments) - len(result.shortfalls)}"
                     f" of {len(result.segments)}"))
    console.print(table_from_rows("Calibration pattern", ["", ""], rows))
    for note in pattern.notes:
        console.print(f"  • {note}")
    if result is not None:
        for c in result.shortfalls[:10]:
            err_console.print(f"[yellow]warning:[/] line {c.segment.line} ({c.segment.role}, "
                              f"group {c.segment.group}) reaches {c.cruise_v_mm_s:.1f} of "
                              f"{c.segment.speed_mm_s:.1f} mm/s on {result.printer}: the "
                              "pattern does not test that speed there")
        for name, count in result.unknown_commands.items():
            err_console.print(f"[yellow]warning:[/] {count}× {name} unknown to flowtwin")


def _no_options() -> None: ...


def _command(kind: str) -> Callable[..., None]:
    """The command of pattern ``kind``: ``-o``, the kind's options, the shared options.

    A kind without an entry in :data:`_KIND_OPTIONS` gets the shared options only (its
    parameters keep their defaults); ``tests/calibration/test_cli.py`` asks for an entry.
    """
    options = _KIND_OPTIONS.get(kind, _no_options)
    own = list(inspect.signature(options, eval_str=True).parameters.values())
    shared = list(inspect.signature(_shared, eval_str=True).parameters.values())
    fields = {f.name for f in dataclasses.fields(PATTERN_KINDS[kind].params_type)}
    names = [p.name for p in own]
    assert all(_FIELDS.get(n, n) in fields for n in names), kind

    def command(**options: Any) -> None:
        params = {_FIELDS.get(n, n): options.pop(n) for n in names}
        _write(kind, {k: v for k, v in params.items() if v is not None}, **options)

    ordered = [shared[0], *own, *shared[1:]]
    # typer reads the parameters from the signature (inspect.signature honours __signature__)
    command.__dict__["__signature__"] = inspect.Signature(
        [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in ordered])
    command.__annotations__ = {p.name: p.annotation for p in ordered}
    command.__name__ = command.__qualname__ = f"pattern_{kind}"
    return command


def register(calibrate: typer.Typer) -> None:
    """Add ``flowtwin calibrate pattern`` and its one command per pattern kind (what
    :class:`~flowtwin.cli.lazy_group.LazyGroup` calls when the group is first used)."""
    group = typer.Typer(name="pattern", no_args_is_help=True, add_completion=False,
                        help=PATTERN_HELP)
    for kind, entry in PATTERN_KINDS.items():
        group.command(kind, help=PATTERN_KIND_HELP.get(kind, entry.description))(
            _command(kind))
    calibrate.add_typer(group, name="pattern")
