"""``flowtwin calibrate from-image``: K from a photo or scan of a printed line pattern.

A thin layer over :func:`flowtwin.calibration.image.analyse.analyse_line_photo`; the
pattern is one of :data:`flowtwin.calibration.image.layouts.LAYOUTS` with the user's
parameters (``None``: the tool's defaults).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from flowtwin.calibration.fragment import write_fragment
from flowtwin.calibration.guide import FROM_IMAGE_HELP
from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.errors import CalibrationError

__all__ = ["FROM_IMAGE_HELP", "from_image_cmd"]

_F = float | None


def _opt(text: str) -> typer.models.OptionInfo:
    return typer.Option(help=text)


def _fmt(x: float | None) -> str:
    return "-" if x is None or x != x else f"{x:.4g}"


def from_image_cmd(
    image: Annotated[Path, typer.Argument(help="Photo or scan of the printed pattern.")],
    pattern: Annotated[str, _opt("Pattern printed: kline, marlin, prusa, orca or "
                                 "orca-legacy.")] = "kline",
    machine: Annotated[str, _opt("Set-up that printed it (built-in name or TOML): its "
                                 "printer plans the lines.")] = "tronvoll2019",
    k_start: Annotated[_F, _opt("First K, s (default: the pattern's).")] = None,
    k_end: Annotated[_F, _opt("Last K, s.")] = None,
    k_step: Annotated[_F, _opt("K step, s.")] = None,
    slow_speed: Annotated[_F, _opt("Slow speed, mm/s.")] = None,
    fast_speed: Annotated[_F, _opt("Fast speed, mm/s.")] = None,
    slow_length: Annotated[_F, _opt("Each slow segment's length, mm.")] = None,
    fast_length: Annotated[_F, _opt("Fast segment length, mm.")] = None,
    pitch: Annotated[_F, _opt("Line spacing, mm.")] = None,
    numbers: Annotated[bool, typer.Option(help="The K was printed beside the lines "
                                               "(marlin, prusa, orca).")] = True,
    mark_every: Annotated[int, _opt("kline: tick every N lines, as printed.")] = 5,
    layer_height: Annotated[float, _opt("Layer height, mm.")] = 0.2,
    line_width: Annotated[_F, _opt("Line width, mm (default: the pattern's).")] = None,
    nozzle_diameter: Annotated[float, _opt("Nozzle, mm.")] = 0.4,
    filament_diameter: Annotated[float, _opt("Filament, mm.")] = 1.75,
    accel: Annotated[_F, _opt("Acceleration the pattern set, mm/s2 (default: the "
                              "pattern's, else the printer's).")] = None,
    dpi: Annotated[_F, _opt("Scan resolution (sets the width scale: 25.4/dpi mm/px).")
                   ] = None,
    mm_per_px: Annotated[_F, _opt("Image resolution, mm/px.")] = None,
    polarity: Annotated[str, _opt("auto, light or dark beads (auto: from the image).")
                        ] = "auto",
    view: Annotated[str, _opt("auto, top, or mirrored (scanned face down).")] = "auto",
    method: Annotated[str, _opt("Width from the bead's integrated contrast (area) or its "
                                "edges.")] = "area",
    step: Annotated[float, _opt("Width sample spacing along a line, mm.")] = 0.25,
    fit_dead_time: Annotated[bool, _opt("Also fit a dead time.")] = False,
    annotate: Annotated[Path | None, _opt("Write an annotated copy of the photo here "
                                          "(PNG or JPEG).")] = None,
    output: Annotated[Path | None, typer.Option("--output", "-o",
                                                help="Write the TOML fragment here.")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    from flowtwin.calibration.fits.kfit import kline_for_machine, pattern_firmware
    from flowtwin.calibration.image.analyse import analyse_line_photo
    from flowtwin.calibration.image.annotate import write_annotated
    from flowtwin.calibration.image.layouts import (
        layout_params,
        layout_settings,
        line_layout_pattern,
    )
    from flowtwin.calibration.patterns.kline import KLineParams
    from flowtwin.calibration.patterns.pattern import PrintSettings
    from flowtwin.profiles.machine import load_machine

    if pattern == "chevron":
        raise CalibrationError("chevron images are not read: from-image reads line "
                               "patterns (a chevron's corner needs a 2-D shape "
                               "measurement)", field="--pattern", value=pattern,
                               allowed="kline, marlin, prusa, orca, orca-legacy")
    if dpi is not None and mm_per_px is not None:
        raise CalibrationError("give --dpi or --mm-per-px, not both", field="--dpi",
                               value=dpi, allowed="one of them")
    if dpi is not None:
        if not dpi > 0:
            raise CalibrationError("scan resolution must be positive", field="--dpi",
                                   value=dpi, allowed="> 0 dots per inch")
        mm_per_px = 25.4 / dpi
    m = load_machine(machine)
    base = PrintSettings(firmware=pattern_firmware(m), nozzle_diameter_mm=nozzle_diameter,
                         filament_diameter_mm=filament_diameter, layer_height_mm=layer_height,
                         line_width_mm=0.48 if line_width is None else line_width,
                         accel_mm_s2=accel)
    values = {"k_start": k_start, "k_end": k_end, "k_step": k_step,
              "slow_speed_mm_s": slow_speed, "fast_speed_mm_s": fast_speed,
              "slow_length_mm": slow_length, "fast_length_mm": fast_length,
              "line_pitch_mm": pitch}
    params = layout_params(pattern, {**values, "numbers": numbers})
    if pattern == "kline":
        kp = KLineParams(k_start=params.k_start, k_end=params.k_end, k_step=params.k_step,
                         slow_speed_mm_s=params.slow_speed_mm_s,
                         fast_speed_mm_s=params.fast_speed_mm_s,
                         slow_length_mm=params.slow_length_mm,
                         fast_length_mm=params.fast_length_mm,
                         line_pitch_mm=params.line_pitch_mm, mark_every=mark_every)
        pat = kline_for_machine(m, base, kp)
    else:
        settings = layout_settings(pattern, base, line_width_given=line_width is not None,
                                   accel_given=accel is not None)
        pat = line_layout_pattern(pattern, settings, params)
    res = analyse_line_photo(image, pat, machine=m, mm_per_px=mm_per_px, polarity=polarity,
                             view=view, step_mm=step, method=method,
                             fit_dead_time=fit_dead_time)
    text = None
    if res.lag is not None:
        text = res.lag.fragment(header=[
            f"flowtwin calibrate from-image: lag fitted to {image.name} ({pattern} pattern, "
            f"{len(res.lag.lines)} lines, RMS {res.lag.rms_mm * 1000:.1f} µm)",
            f"most even line K = {res.k_best_line_s:g} s; ± are 1-sigma errors"])
        if output is not None:
            write_fragment(output, text)
    elif output is not None:
        raise CalibrationError(f"no lag fit to write: {res.lag_problem}", field="--output")
    if annotate is not None:
        write_annotated(annotate, image, res)
    if json_out:
        print_json({**res.summary(), "output": None if output is None else str(output),
                    "annotated": None if annotate is None else str(annotate)})
        return
    console.print(table_from_rows(
        f"{pattern} lines in {image}", ["K (s)", "score", "accel err", "decel err",
                                        "width (mm)", "measured"],
        [(f"{r.k_la_s:g}" + (" ◀" if i == res.best_index else ""), _fmt(r.score),
          _fmt(r.accel_error), _fmt(r.decel_error), _fmt(r.steady_width_mm),
          f"{r.measured_fraction:.0%}") for i, r in enumerate(res.lines)]))
    console.print(f"most even line: K = {res.k_best_line_s:g} s; zero crossings: "
                  f"acceleration {_fmt(res.k_accel_s)} s, deceleration "
                  f"{_fmt(res.k_decel_s)} s [001 Table II]")
    console.print(f"{res.px_per_mm:.2f} px/mm; line ends fit the pattern within "
                  f"{res.reprojection_rms_mm:.2f} mm RMS")
    for note in res.notes:
        console.print(f"  • {note}")
    if annotate is not None:
        console.print(f"wrote {annotate}")
    if res.lag is None:
        err_console.print(f"[yellow]warning:[/] no lag fit: {res.lag_problem}")
        return
    p = res.lag.params
    console.print(f"twin's lag K = {p.k_s:.4f} ± {res.lag.stderr['k_s']:.2g} s (1σ)")
    if output is None:
        console.print(text, markup=False, highlight=False, soft_wrap=True)
    else:
        console.print(f"wrote {output}")
