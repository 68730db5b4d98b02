"""``flowtwin control``: closed-loop slip control on a printer (or the twin)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.live import Live
from rich.table import Table

from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.control.clock import AcceleratedClock, Clock, RealClock
from flowtwin.control.connect import open_printer
from flowtwin.control.controllers import Limits, make_controller
from flowtwin.control.credentials import DEFAULT_KEY_ENV, load_api_key
from flowtwin.control.firmware import Channel, Firmware
from flowtwin.control.log import ControlLog
from flowtwin.control.measurement import SyntheticSlipSource
from flowtwin.control.printer import Factors
from flowtwin.control.supervisor import LoopSettings, RunSummary, Status, run_control
from flowtwin.control.twin import TwinPrinter
from flowtwin.errors import FlowtwinError

__all__ = ["register", "render_summary"]


def _status_table(st: Status | None, printer: str) -> Table:
    rows: list[tuple[str, object]] = [("printer", printer)]
    if st is not None:
        rows += [
            ("time", f"{st.t_s:7.1f} s"), ("mode", st.mode),
            ("slip", "-" if st.slip is None else f"{100 * st.slip:5.1f} %"),
            ("multiplier", f"{st.command_pct:6.1f} %"), ("samples", st.samples),
            ("faults", st.faults), ("last reply", st.last_response[:60]),
        ]
    return table_from_rows("flowtwin control", ["", ""], rows)


def render_summary(summary: RunSummary) -> None:
    """Print a run's summary with rich."""
    d = summary.to_dict()
    ff = d["final_factors"]
    rows = [
        ("printer", d["printer"]), ("controller", f"{d['controller']} on {d['channel']}"),
        ("duration", f"{d['duration_s']:.1f} s"), ("samples", d["samples"]),
        ("mean slip with the loop",
         "-" if d["mean_slip_pct"] is None else f"{d['mean_slip_pct']:.2f} %"),
        ("multiplier range", f"{d['multiplier_min_pct']:.1f} – {d['multiplier_max_pct']:.1f} %"),
        ("commands acknowledged", d["commands"]),
        ("faults", ", ".join(f"{f['kind']} @ {f['t_s']:.1f} s" for f in d["faults"]) or "none"),
        ("restored to 100 %", "yes" if d["restored"] else "NO"),
        ("final factors", "-" if ff is None else
         f"speed {ff['speed_pct']:.1f} %, flow {ff['flow_pct']:.1f} % ({ff['source']})"),
    ]
    console.print(table_from_rows("Control run", ["", ""], rows))


def register(app: typer.Typer) -> None:
    """Add ``flowtwin control``."""

    @app.command("control")
    def control_cmd(
        printer: Annotated[str, typer.Option(
            "--printer", help="octoprint://HOST:PORT[?port=VIRTUAL], moonraker://HOST:PORT, "
            "serial:///dev/ttyUSB0[?baud=N] or twin[?firmware=klipper&delay=S].")],
        synthetic: Annotated[bool, typer.Option(
            "--synthetic", help="Use a synthetic slip signal (low/high/low thirds).")] = False,
        duration: Annotated[float, typer.Option("--duration", help="Run length (s).")] = 60.0,
        controller: Annotated[str, typer.Option(
            "--controller", help="greeff | feedforward | pi")] = "greeff",
        channel: Annotated[Channel | None, typer.Option(
            "--channel", help="Override the multiplier (speed=M220, flow=M221).")] = None,
        firmware: Annotated[Firmware | None, typer.Option(
            "--firmware", help="Firmware behind OctoPrint / of the twin.")] = None,
        min_pct: Annotated[float, typer.Option("--min-pct")] = 50.0,
        max_pct: Annotated[float, typer.Option("--max-pct")] = 150.0,
        rate_limit: Annotated[float, typer.Option(
            "--rate-limit", help="Largest multiplier change (%/s).")] = 20.0,
        period: Annotated[float, typer.Option("--period", help="Loop tick (s).")] = 0.5,
        watchdog: Annotated[float, typer.Option(
            "--watchdog", help="Safe state after this long without measurements (s).")] = 2.0,
        speedup: Annotated[float, typer.Option(
            "--speedup", help="Twin only: run this many times faster than real time.")] = 1.0,
        seed: Annotated[int, typer.Option("--seed", help="Synthetic noise seed.")] = 0,
        log_file: Annotated[Path | None, typer.Option(
            "--log", help="CSV log of measurements, commands and responses.")] = None,
        api_key_file: Annotated[Path | None, typer.Option(
            "--api-key-file", help="File with the API key (must be chmod 600).")] = None,
        api_key_env: Annotated[str, typer.Option(
            "--api-key-env", help="Environment variable with the API key.")] = DEFAULT_KEY_ENV,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")
                            ] = False,
    ) -> None:
        """Run the slip control loop: measure, command M220/M221, restore 100 % at the end."""
        if not synthetic:
            raise FlowtwinError("no measurement source given", field="source",
                                allowed="--synthetic (camera and video sources come with "
                                "the vision module)")
        if not (math.isfinite(duration) and duration > 0):
            raise FlowtwinError("duration must be positive", field="--duration",
                                value=duration, allowed="> 0 s")
        is_twin = printer.strip().startswith("twin")
        if speedup != 1.0 and not is_twin:
            raise FlowtwinError("--speedup only applies to the twin", field="--speedup",
                                value=speedup, allowed="1 for a real printer")
        clock: Clock = AcceleratedClock(speedup) if is_twin else RealClock()
        key = load_api_key(file=api_key_file, env=api_key_env)
        conn = open_printer(printer, api_key=key, clock=clock, firmware=firmware)
        ctl = make_controller(controller, channel=channel,
                              limits=Limits(min_pct, max_pct, rate_limit))
        settings = LoopSettings(duration_s=duration, period_s=period, watchdog_s=watchdog)
        last: list[Status] = []

        def commanded() -> Factors:
            pct = last[-1].command_pct if last else 100.0
            if ctl.channel is Channel.SPEED:
                return Factors(pct, 100.0, "commanded")
            return Factors(100.0, pct, "commanded")

        factors = ((lambda: conn.factors_at(clock.now())) if isinstance(conn, TwinPrinter)
                   else commanded)
        def remember(st: Status) -> None:
            last[:] = [st]

        source = SyntheticSlipSource(clock, duration_s=duration, seed=seed, factors=factors)
        with ControlLog(log_file, keep_rows=False) as clog:
            if json_out:
                summary = run_control(conn, source, ctl, clock=clock, settings=settings,
                                      log_to=clog, on_status=remember)
            else:
                with Live(_status_table(None, conn.description), console=console,
                          refresh_per_second=4, transient=True) as live:
                    def show(st: Status) -> None:
                        remember(st)
                        live.update(_status_table(st, conn.description))

                    summary = run_control(conn, source, ctl, clock=clock, settings=settings,
                                          log_to=clog, on_status=show)
        if json_out:
            print_json(summary.to_dict())
        else:
            render_summary(summary)
        if not summary.restored:
            err_console.print("[bold red]warning:[/] the multiplier could not be restored "
                              "to 100 %; check the printer")
            raise typer.Exit(1)
