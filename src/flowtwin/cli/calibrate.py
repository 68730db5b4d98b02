"""``flowtwin calibrate``: test patterns, fits of measurements, adaptive advance tables.

A thin layer over :mod:`flowtwin.calibration`; every command that reports results has
``--json`` (one JSON object on stdout).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Annotated, Any

import typer

from flowtwin.calibration.adaptive_pa import (
    ADAPTIVE_PA_COLUMNS,
    table_from_measurements,
    write_orca_model,
)
from flowtwin.calibration.csvdata import read_table
from flowtwin.calibration.firmware import parse_firmware
from flowtwin.calibration.fragment import render_fragment, write_fragment
from flowtwin.calibration.pattern_base import PrintSettings, write_pattern
from flowtwin.calibration.patterns import PATTERN_KINDS, generate_pattern
from flowtwin.calibration.strand_fit import STRAND_COLUMNS, fit_strand, strand_points
from flowtwin.calibration.verify import verify_pattern
from flowtwin.calibration.viscosity_fit import (
    VISCOSITY_COLUMNS,
    fit_viscosity_law,
    sweep_from_table,
)
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.errors import CalibrationError
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.hotend import HotendProfile

__all__ = ["register"]

_PATTERN_HELP = """Write a calibration test pattern as G-code for your firmware.

KIND is one of:

kline: K-factor lines (Marlin style). Each line is 20 mm slow, 40 mm
fast, 20 mm slow, one advance factor K per line, front to back. Where
the speed steps up and down, pick the K whose line keeps an even width.

chevron: Ellis-style chevrons, nested 90-degree corners, one K per
whole chevron, left to right. Pick the chevron with a sharp apex and
no gap before it.

tower: a square tower with K = k_start + k_step_per_mm * z. Measure
with calipers the height z of the best corners; K follows from it.

flow: extrusion-multiplier blocks, front left first. Pick the block
with a closed, flat top; multiply your flow setting by its value.

maxflow: lines of rising volumetric flow (mm3/s), front to back. The
last line that is still full and even is your maximum volumetric speed.

flowline: one line alternating v/4 and v for a target flow (one line
per K if --k-start/--k-end/--k-step are given). Measure its width along
the line (microscope, scanner, camera) every ~0.5 mm for a lag fit.

Every extrusion uses the slicer bead A = w*h - (1 - pi/4)*h^2. Unless
--no-check, the file is read back and planned with flowtwin's reader
and planner for --printer, and the test speeds are checked to be
reached (a warning names every move that falls short).
"""

_VISCOSITY_HELP = """Fit a viscosity law to a temperature sweep; write a [viscosity] fragment.

What to measure: extrude into air (no bed) at ONE constant volumetric
flow (e.g. 5 mm3/s) while stepping the nozzle temperature (e.g. 190 to
240 C in 5 C steps, 3 repeats each); at each step wait until the force
is steady, then record it.

DATA.csv has a header line naming its columns (# starts a comment):
temp_c (melt temperature, C; required) and ONE of
feed_force_n with flow_mm3_s (steady force on the filament, load cell),
slip_pct with flow_mm3_s (steady drive slip, %; needs --drive),
viscosity_pa_s (viscosity measured elsewhere, Pa*s).

A force becomes a viscosity through the hot end's Hagen-Poiseuille
resistance (--hotend); a slip becomes a force through the drive's slip
law s = k_p + s'*F. The fragment holds the law's parameters with their
1-sigma errors as comments: paste it into a material profile in place
of its [viscosity] table.
"""

_STRAND_HELP = """Fit the strand shape (tractrix, parabola, catenary) to profile points.

What to measure: film from the side (or section) the strand between
the nozzle and the bed while printing a straight line at constant
speed. DATA.csv has the columns x_mm (distance behind the nozzle axis;
the strand trails towards +x) and z_mm (height above the layer below).

Give --height-mm, the nozzle height above the layer below. The points
must reach past where the strand meets the bed. The fragment's lag_mm
is how far behind the nozzle the strand reaches the bed.
"""

_ADAPTIVE_HELP = """Build OrcaSlicer's adaptive pressure-advance table from measured K.

What to measure: run a K test (kline or chevron pattern) at several
print speeds (e.g. 50, 100, 150, 200 mm/s) and accelerations (e.g.
1000, 2000, 4000 mm/s2), two or more speeds per acceleration, and note
the best K of each test.

MEASUREMENTS.csv has the columns k_s (best K, s), accel_mm_s2 (whole
number) and flow_mm3_s, or instead of flow_mm3_s the three columns
speed_mm_s, line_width_mm, layer_height_mm (flow = bead area * speed).

The output has one "K,flow,accel" line per measurement: paste it into
OrcaSlicer's filament setting "Adaptive pressure advance measurements".
Between measurements K is interpolated (monotone cubic in flow, then
in acceleration) and held at the edge values outside them.
"""


# ------------------------------------------------------------------------ helpers ---

def _load_hotend(name: str) -> HotendProfile:
    from flowtwin.profiles import load_builtin, load_profile

    if Path(name).suffix == ".toml" or os.sep in name:
        return load_profile(name, "hotend")
    profile = load_builtin(name, "hotend")
    assert isinstance(profile, HotendProfile)  # load_builtin checked the kind
    return profile


def _load_drive(name: str) -> DriveProfile:
    from flowtwin.profiles import load_builtin, load_profile

    if Path(name).suffix == ".toml" or os.sep in name:
        return load_profile(name, "drive")
    profile = load_builtin(name, "drive")
    assert isinstance(profile, DriveProfile)  # load_builtin checked the kind
    return profile


#: CLI option → pattern parameter field.
_PATTERN_OPTIONS = {
    "k-start": "k_start", "k-end": "k_end", "k-step": "k_step",
    "k-step-per-mm": "k_step_per_mm", "slow-speed": "slow_speed_mm_s",
    "fast-speed": "fast_speed_mm_s", "speed": "speed_mm_s",
    "first-layer-speed": "first_layer_speed_mm_s", "layers": "layers", "walls": "walls",
    "height": "height_mm", "size": "size_mm", "block-size": "block_size_mm",
    "multiplier-start": "multiplier_start", "multiplier-end": "multiplier_end",
    "multiplier-step": "multiplier_step", "flow-start": "flow_start_mm3_s",
    "flow-end": "flow_end_mm3_s", "flow-step": "flow_step_mm3_s", "flow": "flow_mm3_s",
    "cycles": "cycles", "mark-every": "mark_every",
}


def _pattern_params(kind: str, options: dict[str, Any]) -> dict[str, Any]:
    entry = PATTERN_KINDS.get(kind)
    if entry is None:
        raise CalibrationError("unknown pattern", field="KIND", value=kind,
                               allowed=", ".join(PATTERN_KINDS))
    fields = {f.name for f in dataclasses.fields(entry.params_type)}
    usable = sorted(f"--{opt}" for opt, fld in _PATTERN_OPTIONS.items() if fld in fields)
    params: dict[str, Any] = {}
    for opt, value in options.items():
        if value is None:
            continue
        fld = _PATTERN_OPTIONS[opt]
        if fld not in fields:
            raise CalibrationError(f"--{opt} does not apply to the {kind} pattern",
                                   field=f"--{opt}", value=value,
                                   allowed="options of " + kind + ": " + ", ".join(usable))
        params[fld] = value
    return params


# ---------------------------------------------------------------------- commands ---

def _pattern_cmd(
    kind: Annotated[str, typer.Argument(help="kline, chevron, tower, flow, maxflow or "
                                             "flowline.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="G-code file to write.")],
    firmware: Annotated[str, typer.Option(help="klipper, marlin, reprapfirmware (rrf) or "
                                               "prusa (Buddy: MK4/XL/MINI; 8-bit MK3S/MK2.5 "
                                               "use marlin).")] = "klipper",
    k_start: Annotated[float | None, typer.Option(help="First advance factor, s.")] = None,
    k_end: Annotated[float | None, typer.Option(help="Last advance factor, s.")] = None,
    k_step: Annotated[float | None, typer.Option(help="Advance factor step, s.")] = None,
    k_step_per_mm: Annotated[float | None, typer.Option(
        help="tower: advance factor added per mm of height, s/mm.")] = None,
    slow_speed: Annotated[float | None, typer.Option(help="kline: slow speed, mm/s.")] = None,
    fast_speed: Annotated[float | None, typer.Option(help="kline: fast speed, mm/s.")] = None,
    speed: Annotated[float | None, typer.Option(help="chevron/tower: print speed, "
                                                     "mm/s.")] = None,
    first_layer_speed: Annotated[float | None, typer.Option(
        help="chevron/tower: first-layer speed, mm/s.")] = None,
    layers: Annotated[int | None, typer.Option(help="chevron/flow: layers.")] = None,
    walls: Annotated[int | None, typer.Option(help="chevron/tower: walls.")] = None,
    height: Annotated[float | None, typer.Option(help="tower: height, mm.")] = None,
    size: Annotated[float | None, typer.Option(help="tower: side length, mm.")] = None,
    block_size: Annotated[float | None, typer.Option(help="flow: block side, mm.")] = None,
    multiplier_start: Annotated[float | None, typer.Option(
        help="flow: first extrusion multiplier (1 = 100 %).")] = None,
    multiplier_end: Annotated[float | None, typer.Option(
        help="flow: last extrusion multiplier.")] = None,
    multiplier_step: Annotated[float | None, typer.Option(
        help="flow: multiplier step.")] = None,
    flow_start: Annotated[float | None, typer.Option(help="maxflow: first flow, "
                                                          "mm3/s.")] = None,
    flow_end: Annotated[float | None, typer.Option(help="maxflow: last flow, mm3/s.")] = None,
    flow_step: Annotated[float | None, typer.Option(help="maxflow: flow step, "
                                                         "mm3/s.")] = None,
    flow: Annotated[float | None, typer.Option(help="flowline: target flow at v, "
                                                    "mm3/s.")] = None,
    cycles: Annotated[int | None, typer.Option(help="flowline: slow/fast cycles.")] = None,
    mark_every: Annotated[int | None, typer.Option(
        help="kline/chevron: a tick every N lines (0 = none).")] = None,
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
) -> None:
    params = _pattern_params(kind, {
        "k-start": k_start, "k-end": k_end, "k-step": k_step, "k-step-per-mm": k_step_per_mm,
        "slow-speed": slow_speed, "fast-speed": fast_speed, "speed": speed,
        "first-layer-speed": first_layer_speed, "layers": layers, "walls": walls,
        "height": height, "size": size, "block-size": block_size,
        "multiplier-start": multiplier_start, "multiplier-end": multiplier_end,
        "multiplier-step": multiplier_step, "flow-start": flow_start, "flow-end": flow_end,
        "flow-step": flow_step, "flow": flow, "cycles": cycles, "mark-every": mark_every})
    settings = PrintSettings(
        firmware=parse_firmware(firmware),
        nozzle_diameter_mm=nozzle_diameter, filament_diameter_mm=filament_diameter,
        layer_height_mm=layer_height, line_width_mm=line_width, nozzle_temp_c=nozzle_temp,
        bed_temp_c=bed_temp, fan_percent=fan, accel_mm_s2=accel,
        pa_smooth_time_s=pa_smooth_time, center_xy_mm=(center_x, center_y),
        bed_size_mm=(bed_x, bed_y), retract_mm=retract)
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


def _fit_viscosity_cmd(
    data: Annotated[Path, typer.Argument(help="Temperature sweep CSV (see above).")],
    law: Annotated[str, typer.Option(help="exponential (mu0*exp(-b*T)), arrhenius or "
                                          "wlf.")] = "exponential",
    t_ref: Annotated[float | None, typer.Option(
        help="Reference temperature of arrhenius/wlf, C (default: mean of the data).")
    ] = None,
    wlf_c2: Annotated[float | None, typer.Option(help="Hold WLF C2 at this value, "
                                                      "K.")] = None,
    hotend: Annotated[str, typer.Option(help="Hot-end profile (for a force or slip "
                                             "sweep).")] = "e3d-v6-0.4",
    filament_diameter: Annotated[float, typer.Option(help="Filament diameter, mm.")] = 1.75,
    drive: Annotated[str | None, typer.Option(help="Drive profile (for a slip "
                                                   "sweep).")] = None,
    output: Annotated[Path | None, typer.Option("--output", "-o",
                                                help="Write the TOML fragment here.")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    from flowtwin.profiles import load_rollers

    table = read_table(data, VISCOSITY_COLUMNS, min_rows=3)
    drive_profile = None if drive is None else _load_drive(drive)
    roller = None if drive_profile is None else drive_profile.resolve_roller(load_rollers())
    sweep = sweep_from_table(table, hotend=_load_hotend(hotend),
                             filament_diameter_mm=filament_diameter, drive=drive_profile,
                             roller=roller)
    if law not in ("exponential", "arrhenius", "wlf"):
        raise CalibrationError("unknown viscosity law", field="--law", value=law,
                               allowed="exponential, arrhenius, wlf")
    fit = fit_viscosity_law(sweep, law=law, t_ref_c=t_ref,  # type: ignore[arg-type]
                            wlf_c2_k=wlf_c2)
    values = fit.profile_table()
    text = render_fragment("viscosity", values, stderr=fit.stderr, header=[
        f"flowtwin calibrate fit-viscosity: {law} law fitted to {data.name}",
        f"{fit.n_points} points, {fit.t_min_c:g}-{fit.t_max_c:g} C, measured: {sweep.basis}",
        *sweep.notes,
        f"RMS residual of log10(viscosity): {fit.rms_log10:.3g}; ± are 1-sigma errors",
        "paste into a material profile in place of its [viscosity] table"])
    if output is not None:
        write_fragment(output, text)
    summary = fit.summary()
    summary["output"] = None if output is None else str(output)
    if json_out:
        print_json(summary)
        return
    console.print(table_from_rows(f"Viscosity law ({law}) from {data}", ["parameter", "value",
                                                                        "± 1σ"],
                                  [(k, f"{v:.6g}", f"{fit.stderr[k]:.2g}" if k in fit.stderr
                                    else "fixed") for k, v in {**fit.params,
                                                               **fit.fixed}.items()]))
    console.print(f"{fit.n_points} points, {fit.t_min_c:g}–{fit.t_max_c:g} °C, RMS of "
                  f"log10 μ {fit.rms_log10:.3g}")
    if output is None:
        console.print(text, markup=False, highlight=False)
    else:
        console.print(f"wrote {output}")


def _fit_strand_cmd(
    data: Annotated[Path, typer.Argument(help="Strand profile CSV: x_mm, z_mm.")],
    height_mm: Annotated[float, typer.Option(help="Nozzle height above the layer below, "
                                                  "mm.")],
    model: Annotated[str, typer.Option(help="best, tractrix, parabola or catenary.")
                     ] = "best",
    output: Annotated[Path | None, typer.Option("--output", "-o",
                                                help="Write the TOML fragment here.")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    if model not in ("best", "tractrix", "parabola", "catenary"):
        raise CalibrationError("unknown strand model", field="--model", value=model,
                               allowed="best, tractrix, parabola, catenary")
    if not height_mm > 0:
        raise CalibrationError("nozzle height must be positive", field="--height-mm",
                               value=height_mm, allowed="> 0 mm")
    x, z = strand_points(read_table(data, STRAND_COLUMNS, min_rows=4))
    cal = fit_strand(x, z, height_mm=height_mm, model=model)  # type: ignore[arg-type]
    errors = {**cal.stderr, "lag_mm": cal.lag_stderr_mm}
    text = render_fragment("strand", cal.profile_table(), stderr=errors, header=[
        f"flowtwin calibrate fit-strand: {cal.fit.model.value} [004] fitted to {data.name}",
        f"{cal.n_points} points; RMS residual {cal.fit.rms_mm:.3g} mm; ± are 1-sigma errors",
        "no profile schema has a [strand] table yet: keep this file with the set-up"])
    if output is not None:
        write_fragment(output, text)
    summary = cal.summary()
    summary["output"] = None if output is None else str(output)
    if json_out:
        print_json(summary)
        return
    console.print(table_from_rows(f"Strand shape from {data}", ["parameter", "value (mm)",
                                                               "± 1σ"],
                                  [(k, f"{v:.5g}", f"{errors[k]:.2g}")
                                   for k, v in {**cal.fit.params, "lag_mm": cal.lag_mm}.items()]))
    console.print("RMS by model: " + ", ".join(f"{k} {v:.3g} mm"
                                               for k, v in cal.rms_by_model.items()))
    if output is None:
        console.print(text, markup=False, highlight=False)
    else:
        console.print(f"wrote {output}")


def _adaptive_pa_cmd(
    measurements: Annotated[Path, typer.Argument(help="Measurements CSV (see above).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Table to write.")],
    at: Annotated[list[str] | None, typer.Option(
        "--at", help="Also report the interpolated K at FLOW,ACCEL (repeatable).")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    table = table_from_measurements(read_table(measurements, ADAPTIVE_PA_COLUMNS))
    queries: list[tuple[float, float]] = []
    for item in at or []:
        parts = item.split(",")
        try:
            q, a = float(parts[0]), float(parts[1])
            if len(parts) != 2:
                raise ValueError(item)
        except (ValueError, IndexError):
            raise CalibrationError("--at takes FLOW,ACCEL", field="--at", value=item,
                                   allowed="two numbers, e.g. 10,3000") from None
        queries.append((q, a))
    write_orca_model(output, table)
    results = [{"flow_mm3_s": q, "accel_mm_s2": a, "k_s": float(table.k_at(q, a))}
               for q, a in queries]
    warnings = table.orca_warnings()
    if json_out:
        print_json({"output": str(output), "points": len(table),
                    "accelerations": table.accelerations.tolist(),
                    "table": table.to_orca_text().splitlines(), "queries": results,
                    "warnings": warnings})
        return
    console.print(table_from_rows(f"Adaptive pressure advance ({len(table)} points)",
                                  ["K (s)", "flow (mm³/s)", "accel (mm/s²)"],
                                  [(f"{k:.4f}", f"{q:.2f}", f"{a:.0f}") for k, q, a in zip(
                                      table.k_s, table.flow_mm3_s, table.accel_mm_s2,
                                      strict=True)]))
    for r in results:
        console.print(f"K at {r['flow_mm3_s']:g} mm³/s, {r['accel_mm_s2']:g} mm/s²: "
                      f"{r['k_s']:.4f} s")
    for w in warnings:
        err_console.print(f"[yellow]warning:[/] {w}")
    console.print(f"wrote {output}")


def register(app: typer.Typer) -> None:
    """Add ``flowtwin calibrate`` (pattern, fit-viscosity, fit-strand, adaptive-pa)."""
    sub = typer.Typer(name="calibrate", no_args_is_help=True, add_completion=False,
                      help="Calibration: test patterns, fits of measurements, profile "
                           "fragments, adaptive pressure-advance tables.")
    sub.command("pattern", help=_PATTERN_HELP)(_pattern_cmd)
    sub.command("fit-viscosity", help=_VISCOSITY_HELP)(_fit_viscosity_cmd)
    sub.command("fit-strand", help=_STRAND_HELP)(_fit_strand_cmd)
    sub.command("adaptive-pa", help=_ADAPTIVE_HELP)(_adaptive_pa_cmd)
    app.add_typer(sub, name="calibrate")
