"""``flowtwin compensate`` and ``flowtwin tune``: fix the G-code, or set the firmware.

Thin layer over :func:`flowtwin.compensation.compensate`,
:func:`flowtwin.calibration.tuning.advance_settings.best_pressure_advance` and
:func:`flowtwin.calibration.tuning.advance_settings.adaptive_pa_table`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.defaults import DEFAULT_MACHINE

if TYPE_CHECKING:
    from flowtwin.calibration.tuning.nonlinear_extrusion import NonlinearExtrusionFit
    from flowtwin.compensation import CompensationReport, PaceOptions

__all__ = ["nonlinear_settings", "pace_budget_share", "register", "render_nonlinear",
           "render_report"]


def _pct(v: float) -> str:
    return f"{100.0 * v:.2f} %"


def _times(a: float, b: float) -> str:
    if b <= 0:
        return "∞" if a > 0 else "-"
    return f"{a / b:.1f}×"


def render_report(report: CompensationReport) -> None:
    """Print the before/after figures of one compensated file with rich."""
    from flowtwin.compensation.outcome import pace_note

    b, a = report.before, report.after
    rows = [
        ("RMS flow error", _pct(b.rms_flow_error), _pct(a.rms_flow_error),
         _times(b.rms_flow_error, a.rms_flow_error)),
        ("peak over-extrusion", _pct(b.peak_overextrusion), _pct(a.peak_overextrusion),
         _times(b.peak_overextrusion, a.peak_overextrusion)),
        (f"peak over-extrusion over {b.window_mm:g} mm of path",
         _pct(b.peak_overextrusion_window), _pct(a.peak_overextrusion_window),
         _times(b.peak_overextrusion_window, a.peak_overextrusion_window)),
        ("peak under-extrusion", _pct(b.peak_underextrusion), _pct(a.peak_underextrusion),
         _times(b.peak_underextrusion, a.peak_underextrusion)),
        ("delivered / intended (mm³)",
         f"{b.delivered_volume_mm3:.1f} / {b.intended_volume_mm3:.1f}",
         f"{a.delivered_volume_mm3:.1f} / {a.intended_volume_mm3:.1f}", ""),
        ("commanded E (mm)", f"{report.commanded_e_before_mm:.5f}",
         f"{report.commanded_e_after_mm:.5f}", ""),
        ("print time", fmt_duration(report.time_before_s), fmt_duration(report.time_after_s),
         ""),
        ("max feed force (N)", f"{report.max_force_before_n:.1f}",
         f"{report.max_force_after_n:.1f}", ""),
        ("grinding moves", str(report.grinding_moves_before),
         str(report.grinding_moves_after), ""),
    ]
    console.print(table_from_rows(
        f"{report.source} → {report.destination} ({report.machine}; "
        f"{', '.join(report.transformations) or 'no transformation'})",
        ["", "before", "after", "better"], rows))
    notes = [f"lines rewritten: {report.lines_rewritten:,}"]
    if "slip" in report.transformations:
        notes.append(f"slip feed-forward added {report.added_volume_mm3:.2f} mm³ "
                     f"({report.slip_rounds} round{'s' if report.slip_rounds != 1 else ''}, "
                     f"{100 * report.slip_change:.3f} % of the flow from its fixed point)")
    if "pace" in report.transformations:
        notes.append(f"pacing slowed {len(report.paced_moves)} moves "
                     f"(+{report.pace_time_cost_s:.1f} s)")
    spots = pace_note(None if report.pace is None else report.pace.as_dict(),
                      report.time_before_s)
    if spots is not None:
        notes.append(spots)
    if "guard" in report.transformations:
        notes.append(f"guard slowed {len(report.slowed_moves)} moves "
                     f"(+{report.guard_time_cost_s:.1f} s)")
    for p in report.advance:
        kept = "" if p.kept else " (not kept)"
        along = f" ({p.relief_along} along the travel)" if p.relief_along else ""
        notes.append(f"advance pass: {p.pieces:,} pieces in {p.runs:,} runs, "
                     f"{p.relief_travels} relief retractions added{along}, "
                     f"{p.relief_precharge_mm:.3f} mm pre-charge, "
                     f"{p.pull_pieces:,} pieces pulling back while slowing{kept}")
    if report.trajectory is not None:
        t = report.trajectory
        notes.append(f"trajectory: L = {t.lag_mm:.3f} mm, {t.pivots} pivots, laid road "
                     f"within {t.road_deviation_before_mm:.3f} → "
                     f"{t.road_deviation_after_mm:.3f} mm of the intended one")
    if report.corner_velocity is not None:
        notes.append(report.corner_velocity.note())
    for n in notes:
        console.print(n, markup=False)
    for w in report.warnings:
        err_console.print(f"[yellow]warning:[/] {w}", markup=True)


def register(app: typer.Typer) -> None:
    """Add ``flowtwin compensate`` and ``flowtwin tune``."""

    @app.command("compensate")
    def compensate_cmd(
        gcode: Annotated[Path, typer.Argument(help="G-code file to compensate.")],
        output: Annotated[Path, typer.Option("--output", "-o", help="Where to write the "
                                             "compensated G-code.")],
        profile: Annotated[str, typer.Option(
            "--profile", "-p", help="Machine set-up: built-in name or set-up TOML."
        )] = DEFAULT_MACHINE,
        klipper_config: Annotated[Path | None, typer.Option(
            "--klipper-config", help="Plan with this Klipper printer.cfg.")] = None,
        advance: Annotated[bool, typer.Option(
            "--advance", help="Bake pressure advance into the G-code [001].")] = False,
        slip: Annotated[bool, typer.Option(
            "--slip", help="Feed the predicted drive slip forward [000 §6].")] = False,
        guard: Annotated[bool, typer.Option(
            "--guard", help="Slow moves that would grind the filament [000 §4].")] = False,
        trajectory: Annotated[bool, typer.Option(
            "--trajectory", help="Nozzle paths that lay the intended road [004].")] = False,
        pace: Annotated[bool, typer.Option(
            "--pace", help="Slow the path where the flow would change faster than the melt "
                           "can follow (before the advance): near the spots the advance "
                           "alone leaves wrong.")] = False,
        pace_spot_error: Annotated[float, typer.Option(
            "--pace-spot-error", help="Pacing: flow error the advance may leave before a "
                                      "spot is paced (fraction).")] = 0.1,
        pace_budget: Annotated[float, typer.Option(
            "--pace-budget", metavar="PCT",
            help="Pacing: largest share of the print time it may add, percent (over it "
                 "only the worst spots are paced; inf: no cap).")] = 10.0,
        pace_everywhere: Annotated[bool, typer.Option(
            "--pace-everywhere", help="Pacing: every junction the envelopes name, as if the "
                                      "advance could not pull back (slower prints).")
        ] = False,
        pace_min_speed: Annotated[float, typer.Option(
            "--pace-min-speed", help="Pacing: lowest paced speed, mm/s.")] = 2.0,
        pace_max_slowdown: Annotated[float, typer.Option(
            "--pace-max-slowdown", help="Pacing: lowest share of a move's planned speed.")
        ] = 0.1,
        law: Annotated[str, typer.Option(
            "--law", help="Advance law: smoothed ([001 Eq. 11]) or discrete ([001 Eq. 13])."
        )] = "smoothed",
        k_scale: Annotated[float, typer.Option(
            "--k-scale", help="K_LA as a multiple of the twin's lag factor.")] = 1.0,
        refine: Annotated[bool, typer.Option(
            "--refine/--no-refine", help="Refine the law with the twin's lag model.")] = True,
        relief: Annotated[bool, typer.Option(
            "--relief/--no-relief", help="Relieve the pressure over travels.")] = True,
        relief_min_lags: Annotated[float | None, typer.Option(
            "--relief-min-lags", metavar="LAGS",
            help="Relieve travels lasting at least this many lag factors (default 0.5 on "
                 "Klipper, where a relief costs ~50 ms, 0.25 elsewhere; lower is stronger "
                 "where slicers travel unretracted; docs/compensation.md).")] = None,
        relief_along: Annotated[bool, typer.Option(
            "--relief-along/--relief-e-only",
            help="On Klipper, retract and push back while the head travels (default) "
                 "instead of in E-only moves the head stops for.")] = True,
        safety: Annotated[float, typer.Option(
            "--safety", help="Guard: allowed share of the maximum feed force.")] = 0.8,
        max_flow: Annotated[float | None, typer.Option(
            "--max-flow", help="Guard: largest volumetric flow, mm³/s.")] = None,
        max_shift: Annotated[float, typer.Option(
            "--max-shift", help="Trajectory: largest path displacement, mm.")] = 0.5,
        report_out: Annotated[Path | None, typer.Option(
            "--report", help="Also write the before/after report: an .html file, or a folder "
            "(report.html in it).")] = None,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """Rewrite a G-code so the printer extrudes what it means (nothing without a flag)."""
        from flowtwin.compensation import (
            AdvanceLaw,
            AdvanceOptions,
            GuardOptions,
            RefineOptions,
            SlipOptions,
            TrajectoryOptions,
            compensate,
        )

        adv = AdvanceOptions(law=AdvanceLaw(law), k_scale=k_scale,
                             refine=RefineOptions() if refine else None,
                             relief=relief and refine,
                             relief_min_lags=relief_min_lags,
                             relief_along=relief_along) if advance else None
        report = compensate(
            gcode, output, machine=profile, klipper_config=klipper_config, advance=adv,
            slip=SlipOptions() if slip else None,
            guard=GuardOptions(safety=safety, max_flow_mm3_s=max_flow) if guard else None,
            trajectory=TrajectoryOptions(max_shift_mm=max_shift) if trajectory else None,
            pace=_pace_options(pace_min_speed, pace_max_slowdown, pace_spot_error,
                               pace_everywhere, pace_budget) if pace or pace_everywhere
            else None)
        written = None
        if report_out is not None:
            from flowtwin.report import write_comparison

            target = report_out if report_out.suffix.lower() in (".html", ".htm") else \
                report_out / "report.html"
            target.parent.mkdir(parents=True, exist_ok=True)
            written = write_comparison(report, target)
        if json_out:
            out = report.as_dict()
            if written is not None:
                out["report"] = str(written)
            print_json(out)
        else:
            render_report(report)
            if written is not None:
                console.print(f"wrote {written}")

    @app.command("tune")
    def tune_cmd(
        gcode: Annotated[Path | None, typer.Argument(
            help="Print to fit on (default: the built-in example print).")] = None,
        profile: Annotated[str, typer.Option(
            "--profile", "-p", help="Machine set-up: built-in name or set-up TOML."
        )] = DEFAULT_MACHINE,
        klipper_config: Annotated[Path | None, typer.Option(
            "--klipper-config", help="Plan with this Klipper printer.cfg.")] = None,
        adaptive: Annotated[bool, typer.Option(
            "--adaptive", help="Also compute OrcaSlicer's adaptive PA table.")] = False,
        table_out: Annotated[Path | None, typer.Option(
            "--table-out", help="Write the adaptive table (PA, flow, accel) to this file."
        )] = None,
        flows: Annotated[str, typer.Option(
            "--flows", help="Adaptive table flows, mm³/s, comma-separated.")] = "2,5,8,12,16",
        accels: Annotated[str, typer.Option(
            "--accels", help="Adaptive table accelerations, mm/s², comma-separated."
        )] = "1000,3000,6000",
        nonlinear: Annotated[bool, typer.Option(
            "--nonlinear", help="Also fit the firmware's nonlinear extrusion (M592) to the "
                                "twin's slip.")] = False,
        firmware: Annotated[str | None, typer.Option(
            "--firmware", help="Nonlinear extrusion for this firmware (marlin, "
                               "reprapfirmware, klipper, …; default: the printer's).")
        ] = None,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """The firmware's pressure advance that best fits the machine, and why."""
        from flowtwin.calibration.tuning.adaptive_pa import write_orca_model
        from flowtwin.calibration.tuning.advance_settings import (
            adaptive_pa_table,
            best_pressure_advance,
        )

        fit = best_pressure_advance(gcode, machine=profile, klipper_config=klipper_config)
        out: dict[str, object] = {"best": fit.as_dict()}
        slip_fit = None
        if nonlinear or firmware is not None:
            slip_fit = nonlinear_settings(profile, klipper_config, firmware)
            out["nonlinear_extrusion"] = slip_fit.as_dict()
        table_text = None
        if adaptive or table_out is not None:
            table, _fits = adaptive_pa_table(
                machine=profile, klipper_config=klipper_config,
                flows_mm3_s=[float(v) for v in flows.split(",") if v.strip()],
                accels_mm_s2=[float(v) for v in accels.split(",") if v.strip()])
            table_text = table.to_orca_text()
            out["adaptive_table"] = table_text
            out["adaptive_notes"] = table.orca_warnings()
            if table_out is not None:
                write_orca_model(table_out, table)
        if json_out:
            print_json(out)
            return
        console.print(table_from_rows("Pressure advance", ["", ""], [
            ("best K", f"{fit.k_s:g} s"), ("command", fit.command),
            ("RMS flow error", f"{_pct(fit.rms_at_best)} (without {_pct(fit.rms_without)})"),
            ("twin lag factor", f"{fit.lag_k_s:.4f} s"), ("fitted on", fit.source)]))
        console.print(fit.explanation)
        if table_text is not None:
            console.print("OrcaSlicer adaptive pressure advance (PA, flow, accel):")
            console.print(table_text.rstrip())
        if slip_fit is not None:
            render_nonlinear(slip_fit)


def nonlinear_settings(profile: str, klipper_config: Path | None,
                       firmware: str | None) -> NonlinearExtrusionFit:
    """The nonlinear-extrusion fit for the set-up's (or the given) firmware."""
    from flowtwin.calibration.tuning.nonlinear_extrusion import fit_nonlinear_extrusion
    from flowtwin.profiles.machine import load_machine

    m = load_machine(profile)
    fw = firmware or ("klipper" if klipper_config is not None else m.printer.firmware)
    return fit_nonlinear_extrusion(m, fw)


def render_nonlinear(fit: NonlinearExtrusionFit) -> None:
    """Print a nonlinear-extrusion fit with rich."""
    rows = [("firmware", fit.firmware.label), ("command", fit.command or "(none)"),
            ("feed range", f"{fit.feed_min_mm_s:g}–{fit.feed_max_mm_s:.1f} mm/s of filament"),
            ("residual", f"{100 * fit.rms_residual:.2f} % RMS, "
                         f"{100 * fit.max_residual:.2f} % worst")]
    console.print(table_from_rows("Nonlinear extrusion (the twin's slip)", ["", ""], rows))
    console.print(fit.note)


def pace_budget_share(percent: float) -> float | None:
    """``--pace-budget PCT`` as :attr:`PaceOptions.time_budget` (a share; ``None``: no cap).

    Raises
    ------
    FlowtwinError
        Not a number, or negative.
    """
    import math

    from flowtwin.errors import FlowtwinError

    if math.isnan(percent) or percent < 0.0:
        raise FlowtwinError("invalid pacing time budget", field="--pace-budget",
                            value=percent, allowed="a percentage >= 0 (inf: no cap)")
    return None if math.isinf(percent) else percent / 100.0


def _pace_options(min_speed: float, max_slowdown: float, spot_error: float,
                  everywhere: bool, budget_pct: float) -> PaceOptions:
    """The pacing the options ask for: near the spots (default), or everywhere as if the
    advance could not pull back (the pacing before spots existed)."""
    from dataclasses import replace

    from flowtwin.compensation import PaceOptions

    opts = PaceOptions(min_speed_mm_s=min_speed, max_slowdown=max_slowdown,
                       spot_error=spot_error, time_budget=pace_budget_share(budget_pct))
    return replace(opts, spots=False, pull_ratio=0.0) if everywhere else opts
