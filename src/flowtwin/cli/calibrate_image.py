"""``flowtwin calibrate from-image``: K from a photo or scan of a printed line pattern.

A thin layer over :func:`flowtwin.calibration.image.analyse.analyse_line_photo`; the
pattern is one of :data:`flowtwin.calibration.image.layouts.LAYOUTS` with the user's
parameters (``None``: the tool's defaults).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from flowtwin.calibration.fragment import write_fragment
from flowtwin.calibration.guide import FROM_IMAGE_HELP
from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.errors import CalibrationError, VisionError

__all__ = ["FROM_IMAGE_HELP", "from_image_cmd"]

_F = float | None
_R = TypeVar("_R")


def _opt(text: str) -> typer.models.OptionInfo:
    return typer.Option(help=text)


def _fmt(x: float | None) -> str:
    return "-" if x is None or x != x else f"{x:.4g}"


def from_image_cmd(
    image: Annotated[Path, typer.Argument(help="Photo or scan of the printed pattern.")],
    pattern: Annotated[str, _opt("Pattern printed: kline, marlin, prusa, orca, "
                                 "orca-legacy, pa-camera or chevron.")] = "kline",
    machine: Annotated[str, _opt("Set-up that printed it (built-in name or TOML): its "
                                 "printer plans the lines.")] = "tronvoll2019",
    k_start: Annotated[_F, _opt("First K, s (default: the pattern's).")] = None,
    k_end: Annotated[_F, _opt("Last K, s.")] = None,
    k_step: Annotated[_F, _opt("K step, s.")] = None,
    slow_speed: Annotated[_F, _opt("Slow speed, mm/s (chevron: the first layer's).")
                          ] = None,
    fast_speed: Annotated[_F, _opt("Fast speed, mm/s (chevron: the speed of the upper "
                                   "layers).")] = None,
    slow_length: Annotated[_F, _opt("Each slow segment's length, mm.")] = None,
    fast_length: Annotated[_F, _opt("Fast segment length, mm.")] = None,
    end_length: Annotated[_F, _opt("Last slow segment's length when it differs from the "
                                   "first, mm (pa-camera).")] = None,
    pitch: Annotated[_F, _opt("Line spacing, mm.")] = None,
    numbers: Annotated[bool, typer.Option(help="The K was printed beside the lines "
                                               "(marlin, prusa, orca).")] = True,
    frame: Annotated[bool, typer.Option(help="marlin, prusa: the generator's anchor frame "
                                             "was printed (Ellis' lines tool: on).")
                     ] = False,
    prime: Annotated[bool, typer.Option(help="marlin, prusa: the generator's prime lines "
                                             "were printed.")] = True,
    mark_every: Annotated[int, _opt("kline, chevron: tick every N lines (chevrons), as "
                                    "printed.")] = 5,
    walls: Annotated[int, _opt("chevron: walls (nested corners) per chevron.")] = 3,
    arm_length: Annotated[float, _opt("chevron: arm length of the outer wall, mm.")] = 20.0,
    gap: Annotated[float, _opt("chevron: gap between chevrons, mm.")] = 2.0,
    layers: Annotated[int, _opt("chevron: layers printed.")] = 4,
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
    method: Annotated[str, _opt("Width from the bead's integrated contrast against the "
                                "local sheet (area), with one bead level for the photo "
                                "(area-global), or from its edges.")] = "area",
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
    from flowtwin.calibration.image.layouts import (
        layout_params,
        layout_settings,
        line_layout_pattern,
    )
    from flowtwin.calibration.patterns.kline import KLineParams
    from flowtwin.calibration.patterns.pattern import PrintSettings
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
    base = PrintSettings(firmware=pattern_firmware(m), nozzle_diameter_mm=nozzle_diameter,
                         filament_diameter_mm=filament_diameter, layer_height_mm=layer_height,
                         line_width_mm=0.48 if line_width is None else line_width,
                         accel_mm_s2=accel)
    if pattern == "chevron":
        _chevron(image, m, base, k_start=k_start, k_end=k_end, k_step=k_step,
                 speed=fast_speed, first_layer_speed=slow_speed, arm_length=arm_length,
                 walls=walls, layers=layers, gap=gap, mark_every=mark_every,
                 polarity=polarity, view=view, step=step, annotate=annotate, output=output,
                 json_out=json_out)
        return
    values = {"k_start": k_start, "k_end": k_end, "k_step": k_step,
              "slow_speed_mm_s": slow_speed, "fast_speed_mm_s": fast_speed,
              "slow_length_mm": slow_length, "fast_length_mm": fast_length,
              "end_length_mm": end_length, "line_pitch_mm": pitch}
    extra: dict[str, Any] = {"numbers": numbers}
    if frame:
        extra["frame"] = True
    if not prime:
        extra["prime"] = False
    params = layout_params(pattern, {**values, **extra})
    if pattern == "kline":
        if params.end_length_mm is not None:
            raise CalibrationError("the kline pattern has equal slow segments",
                                   field="--end-length", value=end_length,
                                   allowed="omit it (or use --slow-length)")
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
    res = _refusing(lambda: analyse_line_photo(
        image, pat, machine=m, mm_per_px=mm_per_px, polarity=polarity, view=view,
        step_mm=step, method=method, fit_dead_time=fit_dead_time), image, json_out)
    _report(image, pattern, res, annotate=annotate, output=output, json_out=json_out)


def _refusing(analyse: Callable[[], _R], image: Path, json_out: bool) -> _R:
    """Run the analysis; with ``--json`` a refusal also prints one JSON object stating it
    (``refused``: the reason, ``answers``: what the photo gave, when an answer check
    refused) before the error ends the command with a non-zero exit."""
    try:
        return analyse()
    except VisionError as exc:
        if json_out:
            print_json({"image": str(image), "refused": exc.message, "field": exc.field,
                        "answers": exc.value if exc.field == "k_best_line_s" else None,
                        "error": str(exc)})
        raise


def _report(image: Path, pattern: str, res: Any, *, annotate: Path | None,
            output: Path | None, json_out: bool) -> None:
    """Fragment, annotated copy, JSON or table of a line or chevron result."""
    from flowtwin.calibration.image.annotate import write_annotated

    item = "chevron" if pattern == "chevron" else "line"
    text = None
    if res.lag is not None:
        text = res.lag.fragment(header=[
            f"flowtwin calibrate from-image: lag fitted to {image.name} ({pattern} pattern, "
            f"{len(res.lag.lines)} lines, RMS {res.lag.rms_mm * 1000:.1f} µm)",
            f"most even {item} K = {res.k_best_line_s:g} s; ± are 1-sigma errors"])
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
    if item == "chevron":
        console.print(table_from_rows(
            f"chevrons in {image}", ["K (s)", "score", "error", "upper arm", "lower arm",
                                     "width (mm)", "measured"],
            [(f"{r.k_la_s:g}" + (" ◀" if i == res.best_index else ""), _fmt(r.score),
              _fmt(r.accel_error), _fmt(float(e[0])), _fmt(float(e[1])),
              _fmt(r.steady_width_mm), f"{r.measured_fraction:.0%}")
             for i, (r, e) in enumerate(zip(res.lines, res.arm_errors, strict=True))]))
        console.print(f"best chevron: K = {res.k_best_line_s:g} s (by {res.best_by}); the "
                      f"errors cross zero at {_fmt(res.k_cross_s)} s")
    else:
        console.print(table_from_rows(
            f"{pattern} lines in {image}", ["K (s)", "score", "accel err", "decel err",
                                            "width (mm)", "measured"],
            [(f"{r.k_la_s:g}" + (" ◀" if i == res.best_index else ""), _fmt(r.score),
              _fmt(r.accel_error), _fmt(r.decel_error), _fmt(r.steady_width_mm),
              f"{r.measured_fraction:.0%}") for i, r in enumerate(res.lines)]))
        console.print(f"most even line: K = {res.k_best_line_s:g} s (by {res.best_by}); "
                      f"zero crossings: all lines {_fmt(res.k_cross_s)} s, acceleration "
                      f"{_fmt(res.k_accel_s)} s, deceleration {_fmt(res.k_decel_s)} s "
                      "[001 Table II]")
    console.print(f"{res.px_per_mm:.2f} px/mm; the pattern fits the found lines within "
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


def _chevron(image: Path, m: Any, base: Any, *, k_start: float | None, k_end: float | None,
             k_step: float | None, speed: float | None, first_layer_speed: float | None,
             arm_length: float, walls: int, layers: int, gap: float, mark_every: int,
             polarity: str, view: str, step: float, annotate: Path | None,
             output: Path | None, json_out: bool) -> None:
    """``--pattern chevron``: flowtwin's chevrons as printed, read from the photo."""
    from dataclasses import replace

    from flowtwin.calibration.image.chevron_read import analyse_chevron_photo
    from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern

    given: dict[str, Any] = {"k_start": k_start, "k_end": k_end, "k_step": k_step,
                             "speed_mm_s": speed, "first_layer_speed_mm_s": first_layer_speed}
    params = replace(ChevronParams(arm_length_mm=arm_length, walls=walls, layers=layers,
                                   gap_mm=gap, mark_every=mark_every),
                     **{k: v for k, v in given.items() if v is not None})
    pat = chevron_pattern(base, params)
    res = _refusing(lambda: analyse_chevron_photo(image, pat, machine=m, polarity=polarity,
                                                  view=view, step_mm=step), image, json_out)
    _report(image, "chevron", res, annotate=annotate, output=output, json_out=json_out)
