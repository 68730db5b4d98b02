"""CLI commands: ``flowtwin vision measure | inspect | calibrate | synth``.

A thin layer over :mod:`flowtwin.vision`: ROIs come from ``--config FILE.toml`` and/or
``--roi NAME=x,y,w,h`` (pixels), the scale from ``--mm-per-px`` or ``--calib-width-mm``
(a known filament width, [003 Eq. 4]). See docs/vision.md.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.errors import VisionError

if TYPE_CHECKING:
    from flowtwin.vision.config import Direction, VisionConfig

__all__ = ["register"]

vision_app = typer.Typer(
    name="vision",
    help="Measure filament speed, gear speed, slip and width from a camera [003].",
    no_args_is_help=True,
)

_ROI_HELP = "Region of interest NAME=x,y,w,h in pixels (NAME: gear, before, after); repeat."
_CONFIG_HELP = "Vision TOML file with [roi], [scale], [gear], [filament], [tracking]."
_SOURCE_HELP = "Video file, image folder, or camera index."


def _pair(text: str | None, option: str) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError(text)
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise VisionError("expected two numbers x,y", field=option, value=text,
                          allowed="x,y in pixels, e.g. 190.5,240") from None


def _source(text: str) -> str | int:
    return int(text) if text.isdigit() and not Path(text).exists() else text


def _config(config: Path | None, roi: list[str] | None, mm_per_px: float | None,
            calib_width_mm: float | None, gear_center: str | None,
            gear_radius_mm: float | None, direction: str | None,
            gear_mode: str | None = None, diameter_mm: float | None = None) -> VisionConfig:
    from flowtwin.vision import build_config, parse_rois
    from flowtwin.vision.config import GEAR_MODES

    if mm_per_px is not None and calib_width_mm is not None:
        raise VisionError("give the scale either as --mm-per-px or as --calib-width-mm",
                          field="--mm-per-px/--calib-width-mm",
                          value=(mm_per_px, calib_width_mm), allowed="one of them")
    feeds: dict[str, Direction] = {"down": "down", "up": "up"}
    feed = None if direction is None else feeds.get(direction)
    if direction is not None and feed is None:
        raise VisionError("unknown filament direction", field="--direction",
                          value=direction, allowed="down, up")
    mode = None
    if gear_mode is not None:
        mode = next((m for m in GEAR_MODES if m == gear_mode), None)
        if mode is None:
            raise VisionError("unknown gear mode", field="--gear-mode", value=gear_mode,
                              allowed=", ".join(GEAR_MODES))
    return build_config(config_path=config, rois=parse_rois(roi or []), mm_per_px=mm_per_px,
                        calib_width_mm=calib_width_mm,
                        gear_center_px=_pair(gear_center, "--gear-center"),
                        gear_radius_mm=gear_radius_mm, direction=feed, gear_method=mode,
                        diameter_mm=diameter_mm)


@vision_app.command("measure")
def measure_cmd(
    source: str = typer.Argument(..., help=_SOURCE_HELP),
    config: Path | None = typer.Option(None, "--config", "-c", help=_CONFIG_HELP),
    roi: list[str] | None = typer.Option(None, "--roi", help=_ROI_HELP),
    mm_per_px: float | None = typer.Option(None, "--mm-per-px", help="Image scale, mm/px."),
    calib_width_mm: float | None = typer.Option(
        None, "--calib-width-mm", help="Known filament width (micrometer), mm: k_cal "
        "= w/w_detected [003 Eq. 4]."),
    gear_center: str | None = typer.Option(
        None, "--gear-center", help="Gear axis x,y in px: gear speed from the rotation "
        "(default: estimated from the motion in the gear ROI)."),
    gear_radius_mm: float | None = typer.Option(
        None, "--gear-radius-mm", help="Effective drive radius, mm (default: measured)."),
    gear_mode: str | None = typer.Option(
        None, "--gear-mode", help="auto (default), rotation or tangential."),
    diameter_mm: float | None = typer.Option(
        None, "--filament-diameter-mm", help="Nominal filament diameter, mm: widths "
        "beyond ±5 % are refused (default: 1.75 or 2.85 mm ± 8 %)."),
    direction: str | None = typer.Option(None, "--direction",
                                         help="Feed direction in the image: down or up."),
    timestamps: Path | None = typer.Option(
        None, "--timestamps", help="Timestamp file, one time in ms per frame."),
    frames: int | None = typer.Option(None, "--frames", help="Stop after N frames."),
    csv: Path | None = typer.Option(None, "--csv", help="Write the series as CSV."),
    parquet: Path | None = typer.Option(None, "--parquet", help="Write the series as Parquet."),
    plot: Path | None = typer.Option(None, "--plot", help="Write a PNG plot."),
    strict: bool = typer.Option(False, "--strict", help="Exit with status 1 when the "
                                "summary has warnings (e.g. few valid gear steps)."),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as one JSON object."),
) -> None:
    """Measure gear speed, filament speed, slip, width and volume flow."""
    from flowtwin.vision import measure, write_csv, write_parquet, write_plot

    cfg = _config(config, roi, mm_per_px, calib_width_mm, gear_center, gear_radius_mm,
                  direction, gear_mode, diameter_mm)
    result = measure(_source(source), cfg, timestamps=timestamps, max_frames=frames)
    written: dict[str, str] = {}
    if csv is not None:
        write_csv(result, csv)
        written["csv"] = str(csv)
    if parquet is not None:
        write_parquet(result, parquet)
        written["parquet"] = str(parquet)
    if plot is not None:
        write_plot(result, plot)
        written["plot"] = str(plot)
    summary = result.summary.to_dict()
    s = result.summary
    if s.truncated:
        err_console.print(f"[yellow]warning:[/] {s.source}: decoded {s.frames} of "
                          f"{s.frames_expected} declared frames (truncated or damaged file)")
    for text in s.warnings:
        err_console.print(f"[bold red]WARNING:[/] {text}")
    if json_out:
        print_json({**summary, "outputs": written})
    else:
        slip_text = (f"{s.slip_pct:.3f} % (from {s.slip_steps} steps)"
                     if math.isfinite(s.slip_pct) else f"undefined: {s.slip_note}")
        axis = ("-" if s.gear_axis_px is None else
                f"({s.gear_axis_px[0]:.1f}, {s.gear_axis_px[1]:.1f}) px, {s.gear_axis_source}")
        gear_text = (f"refused ({s.gear_state}, no gear axis)" if s.gear_note else
                     f"{s.gear_speed_mm_s:.4f} mm/s ({s.gear_mode}, {s.gear_state})")
        width_text = ("refused in every frame (see the warning)" if s.width_note else
                      f"{s.width_mm:.4f} ± {s.width_std_mm:.4f} mm "
                      f"({s.width_valid_frames} of {s.frames} frames"
                      + (f"; each from a line through {s.width_window_frames} frames"
                         if s.width_window_frames > 1 else "") + ")")
        rows = [
            ("gear speed", gear_text),
            ("gear axis", axis),
            ("filament speed", f"{s.filament_speed_mm_s:.4f} mm/s ({s.filament_state})"),
            ("slip", slip_text),
            ("width", width_text),
            ("volume flow", f"{s.volume_flow_mm3_s:.3f} mm³/s"),
            ("frames", f"{s.valid_frames} valid of {s.frames} ({s.dropped_frames} dropped, "
                       f"{s.blank_frames} blank, {s.duplicate_frames} duplicate)"),
            ("scale", f"{s.mm_per_px:.6f} mm/px ({s.scale_source})"),
            ("timestamps", s.timestamp_source),
            ("speed", f"{s.processing_fps:.0f} frames/s"),
        ]
        console.print(table_from_rows(f"vision measure: {s.source}", ["", ""], rows))
        for kind, path in written.items():
            console.print(f"wrote {kind}: {path}")
    if strict and s.warnings:
        err_console.print(f"[bold red]--strict:[/] {len(s.warnings)} warning(s)")
        raise typer.Exit(code=1)


@vision_app.command("inspect")
def inspect_cmd(
    source: str = typer.Argument(..., help=_SOURCE_HELP),
    out: Path = typer.Option(Path("vision-inspect.png"), "--out", "-o",
                             help="Annotated PNG to write."),
    frame: int = typer.Option(0, "--frame", help="First frame of the window."),
    frames: int = typer.Option(30, "--frames", help="Frames in the window (tracks and the "
                               "gear axis need motion; 1: features and edges only)."),
    config: Path | None = typer.Option(None, "--config", "-c", help=_CONFIG_HELP),
    roi: list[str] | None = typer.Option(None, "--roi", help=_ROI_HELP),
    mm_per_px: float | None = typer.Option(None, "--mm-per-px", help="Image scale, mm/px."),
    gear_center: str | None = typer.Option(None, "--gear-center", help="Gear axis x,y, px "
                                           "(default: estimated from the motion)."),
    diameter_mm: float | None = typer.Option(
        None, "--filament-diameter-mm", help="Nominal filament diameter, mm."),
    json_out: bool = typer.Option(False, "--json", help="Print the report as one JSON object."),
) -> None:
    """Draw what the measurement finds: edges, tracks kept and rejected, the gear axis."""
    from flowtwin.vision import TrackingParams, inspect_source, load_config_file, parse_rois

    base: dict[str, Any] = load_config_file(config) if config is not None else {}
    rois = dict(base.get("rois", {}))
    rois.update(parse_rois(roi or []))
    tracking = TrackingParams(**base.get("tracking", {}))
    center = _pair(gear_center, "--gear-center") or base.get("gear_center_px")
    scale = mm_per_px if mm_per_px is not None else base.get("mm_per_px")
    diameter = diameter_mm if diameter_mm is not None else base.get("diameter_mm")
    report = inspect_source(_source(source), rois, out, frame_index=frame, frames=frames,
                            params=tracking, gear_center_px=center, mm_per_px=scale,
                            diameter_mm=diameter, direction=base.get("direction", "down"))
    if json_out:
        print_json({**report.to_dict(), "output": str(out)})
    else:
        rows = [(name, f"{r}", str(report.features.get(name, "-")),
                 str(report.tracks_kept.get(name, "-")),
                 str(report.tracks_rejected.get(name, "-")))
                for name, r in report.rois.items()]
        console.print(table_from_rows(
            f"vision inspect: frames {report.frame - report.frames_used + 1}–{report.frame}",
            ["ROI", "x, y, w, h", "features", "kept", "rejected"], rows))
        if report.filament_width_px is not None:
            console.print(f"filament width: {report.filament_width_px:.2f} px")
        if report.gear_axis_px is not None:
            console.print(f"gear axis: ({report.gear_axis_px[0]:.1f}, "
                          f"{report.gear_axis_px[1]:.1f}) px, {report.gear_axis_source}")
        console.print(f"wrote {out}")
    for problem in report.problems:
        err_console.print(f"[yellow]warning:[/] {problem}")
    if report.problems:
        raise typer.Exit(code=1)


@vision_app.command("calibrate")
def calibrate_cmd(
    source: str = typer.Argument(..., help=_SOURCE_HELP),
    width_mm: float = typer.Option(..., "--width-mm",
                                   help="Filament width measured with a micrometer, mm."),
    config: Path | None = typer.Option(None, "--config", "-c", help=_CONFIG_HELP),
    roi: list[str] | None = typer.Option(None, "--roi", help="The before ROI, "
                                         "before=x,y,w,h (px), across both edges."),
    frames: int | None = typer.Option(None, "--frames", help="Use at most N frames."),
    json_out: bool = typer.Option(False, "--json", help="Print the result as one JSON object."),
) -> None:
    """Image scale from a filament of known width: k_cal = w / w_detected [003 Eq. 4]."""
    import numpy as np

    from flowtwin.vision import (
        TrackingParams,
        calibration_factor,
        load_config_file,
        measure_width_px,
        open_source,
        parse_rois,
    )

    base: dict[str, Any] = load_config_file(config) if config is not None else {}
    rois = dict(base.get("rois", {}))
    rois.update(parse_rois(roi or []))
    if "before" not in rois:
        raise VisionError("the before ROI is needed to calibrate", field="roi.before",
                          allowed="--roi before=x,y,w,h across both filament edges")
    before = rois["before"]
    params = TrackingParams(**base.get("tracking", {}))
    widths: list[float] = []
    with open_source(_source(source), max_frames=frames) as src:
        before.check_inside(src.width_px, src.height_px, source=src.description)
        n = 0
        for fr in src:
            n += 1
            em = measure_width_px(fr.image[before.slices], sigma_px=params.width_sigma_px,
                                  min_edge_dn_px=params.min_edge_dn_px)
            if em.ok:
                widths.append(em.width_px)
    detected = float(np.mean(widths)) if widths else float("nan")
    k_cal = calibration_factor(width_mm, detected)
    out = {"mm_per_px": k_cal, "width_px": detected,
           "width_px_std": float(np.std(widths)) if widths else None,
           "frames": n, "frames_used": len(widths), "width_mm": width_mm}
    if json_out:
        print_json(out)
    else:
        console.print(f"k_cal = {k_cal:.6f} mm/px  (detected {detected:.3f} px over "
                      f"{len(widths)} of {n} frames; use --mm-per-px {k_cal:.6f})")


@vision_app.command("synth")
def synth_cmd(
    out: Path = typer.Argument(..., help="Video to write (.avi or .mkv)."),
    speed: float = typer.Option(2.0, "--speed", help="Gear surface speed, mm/s."),
    slip: float = typer.Option(0.1, "--slip", help="Slip as a fraction (0.1 = 10 %)."),
    duration: float = typer.Option(3.0, "--duration", help="Length, s."),
    fps: float = typer.Option(30.0, "--fps", help="Frame rate, 1/s."),
    seed: int = typer.Option(0, "--seed", help="Random seed of textures and noise."),
    fourcc: str = typer.Option("FFV1", "--fourcc", help="Codec, e.g. FFV1 or MJPG."),
    config_out: Path | None = typer.Option(None, "--config-out",
                                           help="Also write a matching vision TOML file."),
    json_out: bool = typer.Option(False, "--json", help="Print the truth as one JSON object."),
) -> None:
    """Render a synthetic camera recording with a known speed and slip (for trying out)."""
    from flowtwin.vision.synth import (
        MotionSeries,
        SceneSpec,
        SyntheticCamera,
        write_config_toml,
        write_video,
    )

    if not (0.0 <= slip < 1.0):
        raise VisionError("slip must be a fraction in [0, 1)", field="--slip", value=slip,
                          allowed="0 <= slip < 1")
    if not (0.0 < duration <= 600.0):
        raise VisionError("duration out of range", field="--duration", value=duration,
                          allowed="0 < duration <= 600 s")
    if not (-100.0 <= speed <= 100.0):
        raise VisionError("speed out of range", field="--speed", value=speed,
                          allowed="-100..100 mm/s")
    scene = SceneSpec(fps=fps, seed=seed)
    motion = MotionSeries.constant(duration_s=duration, gear_speed_mm_s=speed, slip=slip)
    write_video(SyntheticCamera(scene, motion).frames(), out, fps=fps, fourcc=fourcc)
    truth = {"video": str(out), "gear_speed_mm_s": speed,
             "filament_speed_mm_s": speed * (1 - slip), "slip": slip,
             "mm_per_px": scene.mm_per_px, "width_mm": scene.nominal_width_mm,
             "gear_center_px": list(scene.gear_center_px),
             "gear_radius_mm": scene.drive_radius_mm}
    if config_out is not None:
        write_config_toml(scene.vision_config(), config_out)
        truth["config"] = str(config_out)
    if json_out:
        print_json(truth)
    else:
        console.print(f"wrote {out}" + (f" and {config_out}" if config_out else ""))


def register(app: typer.Typer) -> None:
    """Add the ``vision`` command group to ``app``."""
    app.add_typer(vision_app, name="vision")
