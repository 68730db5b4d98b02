"""``flowtwin calibrate``: test patterns, fits of measurements, adaptive advance tables.

A thin layer over :mod:`flowtwin.calibration`; every command that reports results has
``--json`` (one JSON object on stdout).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import typer

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
from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.cli.calibrate_image import from_image_cmd
from flowtwin.cli.lazy_group import lazy_group
from flowtwin.errors import CalibrationError

if TYPE_CHECKING:
    from flowtwin.calibration.fits.lagfit import LagFit
    from flowtwin.calibration.fits.viscosity_fit import ViscosityLawName
    from flowtwin.calibration.patterns.kline import KLineParams
    from flowtwin.calibration.patterns.pattern import PrintSettings
    from flowtwin.physics.strand import StrandModel
    from flowtwin.profiles.drive import DriveProfile
    from flowtwin.profiles.hotend import HotendProfile

__all__ = ["register"]

# ------------------------------------------------------------------------ helpers ---

def _load_hotend(name: str) -> HotendProfile:
    from flowtwin.profiles import HotendProfile, load_builtin, load_profile

    if Path(name).suffix == ".toml" or os.sep in name:
        return load_profile(name, "hotend")
    profile = load_builtin(name, "hotend")
    assert isinstance(profile, HotendProfile)  # load_builtin checked the kind
    return profile


def _load_drive(name: str) -> DriveProfile:
    from flowtwin.profiles import DriveProfile, load_builtin, load_profile

    if Path(name).suffix == ".toml" or os.sep in name:
        return load_profile(name, "drive")
    profile = load_builtin(name, "drive")
    assert isinstance(profile, DriveProfile)  # load_builtin checked the kind
    return profile


# ---------------------------------------------------------------------- commands ---

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
    from flowtwin.calibration.csvdata import read_table
    from flowtwin.calibration.fits.viscosity_fit import (
        VISCOSITY_COLUMNS,
        fit_viscosity_law,
        sweep_from_table,
    )
    from flowtwin.profiles import load_rollers

    table = read_table(data, VISCOSITY_COLUMNS, min_rows=3)
    drive_profile = None if drive is None else _load_drive(drive)
    roller = None if drive_profile is None else drive_profile.resolve_roller(load_rollers())
    sweep = sweep_from_table(table, hotend=_load_hotend(hotend),
                             filament_diameter_mm=filament_diameter, drive=drive_profile,
                             roller=roller)
    laws: dict[str, ViscosityLawName] = {
        "exponential": "exponential", "arrhenius": "arrhenius", "wlf": "wlf"}
    law_name = laws.get(law)
    if law_name is None:
        raise CalibrationError("unknown viscosity law", field="--law", value=law,
                               allowed="exponential, arrhenius, wlf")
    fit = fit_viscosity_law(sweep, law=law_name, t_ref_c=t_ref, wlf_c2_k=wlf_c2)
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
    from flowtwin.calibration.fits.strand_fit import STRAND_COLUMNS, fit_strand, strand_points
    from flowtwin.physics.strand import StrandModel

    models: dict[str, StrandModel | Literal["best"]] = {
        "best": "best", **{m.value: m for m in StrandModel}}
    strand_model = models.get(model)
    if strand_model is None:
        raise CalibrationError("unknown strand model", field="--model", value=model,
                               allowed="best, tractrix, parabola, catenary")
    if not height_mm > 0:
        raise CalibrationError("nozzle height must be positive", field="--height-mm",
                               value=height_mm, allowed="> 0 mm")
    from flowtwin.calibration.csvdata import read_table

    x, z = strand_points(read_table(data, STRAND_COLUMNS, min_rows=4))
    cal = fit_strand(x, z, height_mm=height_mm, model=strand_model)
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
    from flowtwin.calibration.csvdata import read_table
    from flowtwin.calibration.tuning.adaptive_pa import (
        ADAPTIVE_PA_COLUMNS,
        table_from_measurements,
        write_orca_model,
    )

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
    from flowtwin.calibration.patterns.kline import KLineParams
    from flowtwin.calibration.patterns.pattern import PrintSettings

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
    from flowtwin.calibration.fits.kfit import fit_k
    from flowtwin.calibration.fits.lagfit import read_width_profiles

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
        from flowtwin.calibration.tuning.adaptive_pa import append_measurement

        appended = append_measurement(append_to, fit.measurement_row())
    if json_out:
        print_json({**fit.summary(), "output": None if output is None else str(output),
                    "appended_to": None if append_to is None else str(append_to)})
        return
    _report_lag(fit, f"Lag from {profile}", output, text, appended, append_to)


def _fmt(x: float | None) -> str:  # NaN and None: "-"
    return "-" if x is None or x != x else f"{x:.4g}"


def _fit_slip_cmd(
    records: Annotated[Path, typer.Argument(help="Test-stand records CSV (schema 1).")],
    roller: Annotated[str | None, typer.Option(help="Roller id in the file (if several).")
                      ] = None,
    output: _Output = None,
    json_out: _Json = False,
) -> None:
    from flowtwin.calibration.fits.slipfit import fit_slip_records

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
    # ``pattern`` builds its options from every pattern's parameters (firmware model, numpy):
    # listed here, loaded when used
    listing = {"pattern": ("calibrate_pattern", PATTERN_HELP.split("\n\n")[0].strip())}
    sub = typer.Typer(name="calibrate", no_args_is_help=True, add_completion=False,
                      cls=lazy_group("calibrate", listing),
                      help="Calibration: test patterns, fits of measurements, profile "
                           "fragments, adaptive pressure-advance tables.")
    sub.command("fit-k", help=FIT_K_HELP)(_fit_k_cmd)
    sub.command("from-image", help=FROM_IMAGE_HELP)(from_image_cmd)
    sub.command("fit-viscosity", help=VISCOSITY_HELP)(_fit_viscosity_cmd)
    sub.command("fit-strand", help=STRAND_HELP)(_fit_strand_cmd)
    sub.command("fit-slip", help=FIT_SLIP_HELP)(_fit_slip_cmd)
    sub.command("adaptive-pa", help=ADAPTIVE_HELP)(_adaptive_pa_cmd)
    app.add_typer(sub, name="calibrate")
