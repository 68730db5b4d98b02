"""``flowtwin calibrate``: test patterns, fits of measurements, adaptive advance tables.

A thin layer over :mod:`flowtwin.calibration`; every command that reports results has
``--json`` (one JSON object on stdout).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from flowtwin.calibration.adaptive_pa import (
    ADAPTIVE_PA_COLUMNS,
    append_measurement,
    table_from_measurements,
    write_orca_model,
)
from flowtwin.calibration.csvdata import read_table
from flowtwin.calibration.firmware import parse_firmware
from flowtwin.calibration.fragment import render_fragment, write_fragment
from flowtwin.calibration.guide import (
    ADAPTIVE_HELP,
    FIT_K_HELP,
    FIT_SLIP_HELP,
    FROM_IMAGE_HELP,
    PATTERN_HELP,
    STRAND_HELP,
    VISCOSITY_HELP,
)
from flowtwin.calibration.kline import KLineParams
from flowtwin.calibration.pattern_base import PrintSettings, write_pattern
from flowtwin.calibration.patterns import PATTERN_KINDS, generate_pattern
from flowtwin.calibration.strand_fit import STRAND_COLUMNS, fit_strand, strand_points
from flowtwin.calibration.verify import verify_pattern
from flowtwin.calibration.viscosity_fit import (
    VISCOSITY_COLUMNS,
    ViscosityLawName,
    fit_viscosity_law,
    sweep_from_table,
)
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.errors import CalibrationError
from flowtwin.physics.strand import StrandModel
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.hotend import HotendProfile

if TYPE_CHECKING:
    from flowtwin.calibration.lagfit import LagFit

__all__ = ["register"]

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
    laws: dict[str, ViscosityLawName] = {"exponential": "exponential",
                                         "arrhenius": "arrhenius", "wlf": "wlf"}
    if law not in laws:
        raise CalibrationError("unknown viscosity law", field="--law", value=law,
                               allowed="exponential, arrhenius, wlf")
    fit = fit_viscosity_law(sweep, law=laws[law], t_ref_c=t_ref, wlf_c2_k=wlf_c2)
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
        console.print(text, markup=False, highlight=False, soft_wrap=True)
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
    models: dict[str, StrandModel | Literal["best"]] = {
        "best": "best", **{m.value: m for m in StrandModel}}
    if model not in models:
        raise CalibrationError("unknown strand model", field="--model", value=model,
                               allowed="best, tractrix, parabola, catenary")
    if not height_mm > 0:
        raise CalibrationError("nozzle height must be positive", field="--height-mm",
                               value=height_mm, allowed="> 0 mm")
    x, z = strand_points(read_table(data, STRAND_COLUMNS, min_rows=4))
    cal = fit_strand(x, z, height_mm=height_mm, model=models[model])
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
        console.print(text, markup=False, highlight=False, soft_wrap=True)
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


def _kline_parts(k_start: float, k_end: float, k_step: float, slow_speed: float,
                 fast_speed: float, slow_length: float, fast_length: float,
                 layer_height: float | None, line_width: float, nozzle_diameter: float,
                 filament_diameter: float, accel: float | None, mark_every: int
                 ) -> tuple[PrintSettings, KLineParams]:
    return (PrintSettings(nozzle_diameter_mm=nozzle_diameter,
                          filament_diameter_mm=filament_diameter, line_width_mm=line_width,
                          layer_height_mm=0.2 if layer_height is None else layer_height,
                          accel_mm_s2=accel),
            KLineParams(k_start=k_start, k_end=k_end, k_step=k_step, slow_speed_mm_s=slow_speed,
                        fast_speed_mm_s=fast_speed, slow_length_mm=slow_length,
                        fast_length_mm=fast_length, mark_every=mark_every))


_Machine = Annotated[str, typer.Option(help="Set-up that printed it (built-in name or "
                                            "TOML): its printer plans the line.")]
_SlowSpeed = Annotated[float, typer.Option(help="K-line slow speed, mm/s.")]
_FastSpeed = Annotated[float, typer.Option(help="K-line fast speed, mm/s.")]
_SlowLength = Annotated[float, typer.Option(help="K-line slow segment length, mm.")]
_FastLength = Annotated[float, typer.Option(help="K-line fast segment length, mm.")]
_LineWidth = Annotated[float, typer.Option(help="Line width, mm.")]
_Nozzle = Annotated[float, typer.Option(help="Nozzle, mm.")]
_Filament = Annotated[float, typer.Option(help="Filament, mm.")]
_Accel = Annotated[float | None, typer.Option(
    help="Acceleration the pattern set, mm/s2 (default: the printer's).")]
_Output = Annotated[Path | None, typer.Option("--output", "-o",
                                              help="Write the TOML fragment here.")]
_Json = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


def _lag_rows(fit: LagFit) -> list[tuple[str, str, str]]:
    p = fit.params
    rows = [("K (lag)", f"{p.k_s:.4f} s", f"{fit.stderr['k_s']:.2g}")]
    if "dead_time_s" in fit.fitted:
        rows.append(("dead time", f"{p.dead_time_s:.4f} s", f"{fit.stderr['dead_time_s']:.2g}"))
    if "gain" in fit.fitted:
        rows.append(("flow gain", f"{p.gain:.4f}", f"{fit.stderr['gain']:.2g}"))
    for k, v in fit.registration.items():
        rows.append((k, f"{v:.4g}", f"{fit.stderr[k]:.2g}"))
    return rows


def _report_lag(fit: LagFit, title: str, output: Path | None, text: str,
                appended: int | None, append_to: Path | None) -> None:
    console.print(table_from_rows(title, ["parameter", "value", "± 1σ"], _lag_rows(fit)))
    console.print(f"{fit.n_points} widths ({fit.n_excluded} left out), RMS residual "
                  f"{fit.rms_mm * 1000:.1f} µm; the machine profile predicts K = "
                  f"{fit.machine_lag_s:.4f} s")
    for note in fit.notes:
        console.print(f"  • {note}")
    if append_to is not None:
        console.print(f"added measurement {appended} to {append_to}")
    if output is None:
        console.print(text, markup=False, highlight=False, soft_wrap=True)
    else:
        console.print(f"wrote {output}")


def _fit_k_cmd(
    profile: Annotated[Path, typer.Argument(help="Width profile CSV (see above).")],
    gcode: Annotated[Path | None, typer.Option(help="G-code that printed the line(s).")
                     ] = None,
    gcode_line: Annotated[list[int] | None, typer.Option(
        help="Line of the test line's first extruding move (repeatable).")] = None,
    machine: _Machine = "tronvoll2019",
    k_la: Annotated[float, typer.Option(help="Generated K-line: advance factor it was "
                                             "printed with, s.")] = 0.0,
    slow_speed: _SlowSpeed = 20.0, fast_speed: _FastSpeed = 70.0,
    slow_length: _SlowLength = 20.0, fast_length: _FastLength = 40.0,
    layer_height: Annotated[float | None, typer.Option(
        help="Layer height, mm (default 0.2; with --gcode: from the file).")] = None,
    line_width: _LineWidth = 0.48, nozzle_diameter: _Nozzle = 0.4,
    filament_diameter: _Filament = 1.75, accel: _Accel = None,
    fit_dead_time: Annotated[bool, typer.Option(help="Also fit a dead time.")] = False,
    fit_gain: Annotated[bool, typer.Option(help="Also fit a flow gain.")] = False,
    slip: Annotated[bool, typer.Option(help="Include the drive's slip law (slower).")
                    ] = False,
    end_margin: Annotated[float, typer.Option(help="Leave out widths this close to a "
                                                   "line's ends, mm.")] = 1.0,
    output: _Output = None,
    append_to: Annotated[Path | None, typer.Option(
        help="Add k_s,k_err_s,flow_mm3_s,accel_mm_s2 to this adaptive-pa file.")] = None,
    json_out: _Json = False,
) -> None:
    from flowtwin.calibration.kfit import fit_k
    from flowtwin.calibration.lagfit import read_width_profiles

    profiles = read_width_profiles(profile)
    settings, params = _kline_parts(k_la, k_la, 0.01, slow_speed, fast_speed, slow_length,
                                    fast_length, layer_height, line_width, nozzle_diameter,
                                    filament_diameter, accel, 0)
    settings_arg = None if gcode is not None and layer_height is None else settings
    fit, _ = fit_k(profiles, gcode=None if gcode is None else str(gcode),
                   gcode_lines=gcode_line or None, settings=settings_arg, kline=params,
                   k_la_s=k_la, machine=machine, fit_dead_time=fit_dead_time,
                   fit_gain=fit_gain, slip=slip, end_margin_mm=end_margin)
    text = fit.fragment(header=[f"flowtwin calibrate fit-k: lag fitted to {profile.name} "
                                f"({fit.n_points} widths, RMS {fit.rms_mm * 1000:.1f} µm)",
                                f"machine {machine}; ± are 1-sigma errors"])
    if output is not None:
        write_fragment(output, text)
    appended = None
    if append_to is not None:
        appended = append_measurement(append_to, fit.measurement_row())
    if json_out:
        print_json({**fit.summary(), "output": None if output is None else str(output),
                    "appended_to": None if append_to is None else str(append_to)})
        return
    _report_lag(fit, f"Lag from {profile}", output, text, appended, append_to)


def _from_image_cmd(
    image: Annotated[Path, typer.Argument(help="Scan or photo of the K-line pattern.")],
    machine: _Machine = "tronvoll2019",
    k_start: Annotated[float, typer.Option(help="First K of the pattern, s.")] = 0.0,
    k_end: Annotated[float, typer.Option(help="Last K of the pattern, s.")] = 0.2,
    k_step: Annotated[float, typer.Option(help="K step of the pattern, s.")] = 0.01,
    slow_speed: _SlowSpeed = 20.0, fast_speed: _FastSpeed = 70.0,
    slow_length: _SlowLength = 20.0, fast_length: _FastLength = 40.0,
    layer_height: Annotated[float, typer.Option(help="Layer height, mm.")] = 0.2,
    line_width: _LineWidth = 0.48, nozzle_diameter: _Nozzle = 0.4,
    filament_diameter: _Filament = 1.75, accel: _Accel = None,
    mark_every: Annotated[int, typer.Option(help="Tick every N lines, as printed.")] = 5,
    dpi: Annotated[float | None, typer.Option(help="Scan resolution (sets the width "
                                                   "scale: 25.4/dpi mm/px).")] = None,
    mm_per_px: Annotated[float | None, typer.Option(help="Image resolution, mm/px.")
                         ] = None,
    view: Annotated[str, typer.Option(help="auto, top, or mirrored (scanned face down).")
                    ] = "auto",
    method: Annotated[str, typer.Option(help="Width from the bead's integrated darkness "
                                             "(area) or its edges.")] = "area",
    step: Annotated[float, typer.Option(help="Width sample spacing along a line, mm.")
                    ] = 0.25,
    fit_dead_time: Annotated[bool, typer.Option(help="Also fit a dead time.")] = False,
    output: _Output = None,
    json_out: _Json = False,
) -> None:
    from flowtwin.calibration.kfit import kline_for_machine
    from flowtwin.calibration.kimage import analyse_kline_image
    from flowtwin.profiles.machine import load_machine

    if dpi is not None and mm_per_px is not None:
        raise CalibrationError("give --dpi or --mm-per-px, not both", field="--dpi",
                               value=dpi, allowed="one of them")
    if dpi is not None:
        if not dpi > 0:
            raise CalibrationError("scan resolution must be positive", field="--dpi",
                                   value=dpi, allowed="> 0 dots per inch")
        mm_per_px = 25.4 / dpi
    m = load_machine(machine)
    settings, params = _kline_parts(k_start, k_end, k_step, slow_speed, fast_speed,
                                    slow_length, fast_length, layer_height, line_width,
                                    nozzle_diameter, filament_diameter, accel, mark_every)
    pattern = kline_for_machine(m, settings, params)
    res = analyse_kline_image(image, pattern, machine=m, mm_per_px=mm_per_px, view=view,
                              step_mm=step, method=method, fit_dead_time=fit_dead_time)
    text = None
    if res.lag is not None:
        text = res.lag.fragment(header=[
            f"flowtwin calibrate from-image: lag fitted to {image.name} "
            f"({len(res.lag.lines)} K-lines, RMS {res.lag.rms_mm * 1000:.1f} µm)",
            f"most even line K = {res.k_best_line_s:g} s; ± are 1-sigma errors"])
        if output is not None:
            write_fragment(output, text)
    elif output is not None:
        raise CalibrationError(f"no lag fit to write: {res.lag_problem}", field="--output")
    if json_out:
        print_json({**res.summary(), "output": None if output is None else str(output)})
        return
    console.print(table_from_rows(
        f"K-lines in {image}", ["K (s)", "score", "accel err", "decel err", "width (mm)",
                                "measured"],
        [(f"{r.k_la_s:g}" + (" ◀" if i == res.best_index else ""), _fmt(r.score),
          _fmt(r.accel_error), _fmt(r.decel_error), _fmt(r.steady_width_mm),
          f"{r.measured_fraction:.0%}") for i, r in enumerate(res.lines)]))
    console.print(f"most even line: K = {res.k_best_line_s:g} s; zero crossings: "
                  f"acceleration {_fmt(res.k_accel_s)} s, deceleration "
                  f"{_fmt(res.k_decel_s)} s [001 Table II]")
    console.print(f"view {res.view}, {res.px_per_mm:.2f} px/mm, line ends fit the pattern "
                  f"within {res.reprojection_rms_mm:.2f} mm RMS")
    for note in res.notes:
        console.print(f"  • {note}")
    if res.lag is None:
        err_console.print(f"[yellow]warning:[/] no lag fit: {res.lag_problem}")
        return
    assert text is not None
    _report_lag(res.lag, "Lag fitted to all lines", output, text, None, None)


def _fmt(x: float | None) -> str:  # NaN and None: "-"
    return "-" if x is None or x != x else f"{x:.4g}"


def _fit_slip_cmd(
    records: Annotated[Path, typer.Argument(help="Test-stand records CSV (schema 1).")],
    roller: Annotated[str | None, typer.Option(help="Roller id in the file (if several).")
                      ] = None,
    output: _Output = None,
    json_out: _Json = False,
) -> None:
    from flowtwin.calibration.slipfit import fit_slip_records

    cal = fit_slip_records(records, roller_id=roller)
    text = cal.fragment()
    if output is not None:
        write_fragment(output, text)
    if json_out:
        print_json({**cal.summary(), "output": None if output is None else str(output)})
        return
    values, errors = cal.overrides()
    rows = [("k_p_pct", f"{cal.k_p_pct:.4g}", f"{cal.k_p_err_pct:.2g}")]
    rows += [(k, f"{v:.5g}", f"{errors[k]:.2g}") for k, v in values.items()]
    console.print(table_from_rows(f"Slip law of roller {cal.analysis.roller_id} from "
                                  f"{records}", ["parameter", "value", "± 1σ"], rows))
    if output is None:
        console.print(text, markup=False, highlight=False, soft_wrap=True)
    else:
        console.print(f"wrote {output}")


def register(app: typer.Typer) -> None:
    """Add ``flowtwin calibrate`` (pattern, fit-k, from-image, fit-viscosity, fit-strand,
    fit-slip, adaptive-pa)."""
    sub = typer.Typer(name="calibrate", no_args_is_help=True, add_completion=False,
                      help="Calibration: test patterns, fits of measurements, profile "
                           "fragments, adaptive pressure-advance tables.")
    sub.command("pattern", help=PATTERN_HELP)(_pattern_cmd)
    sub.command("fit-k", help=FIT_K_HELP)(_fit_k_cmd)
    sub.command("from-image", help=FROM_IMAGE_HELP)(_from_image_cmd)
    sub.command("fit-viscosity", help=VISCOSITY_HELP)(_fit_viscosity_cmd)
    sub.command("fit-strand", help=STRAND_HELP)(_fit_strand_cmd)
    sub.command("fit-slip", help=FIT_SLIP_HELP)(_fit_slip_cmd)
    sub.command("adaptive-pa", help=ADAPTIVE_HELP)(_adaptive_pa_cmd)
    app.add_typer(sub, name="calibrate")
