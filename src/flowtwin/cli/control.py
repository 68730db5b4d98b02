"""``flowtwin control``: closed-loop slip control on a printer (or the twin)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from flowtwin.cli._common import console, err_console, print_json, table_from_rows
from flowtwin.control.transports.credentials import DEFAULT_KEY_ENV
from flowtwin.errors import FlowtwinError
from flowtwin.firmware import Channel, Firmware

if TYPE_CHECKING:
    from rich.table import Table

    from flowtwin.control.loop.clock import Clock
    from flowtwin.control.loop.measurement import MeasurementSource
    from flowtwin.control.loop.supervisor import RunSummary, Status
    from flowtwin.control.printer import Factors, Printer
    from flowtwin.control.simulated.twin import TwinPrinter

__all__ = ["register", "render_summary"]

#: Run length when neither ``--duration`` nor a twin print job bounds the run, s.
DEFAULT_DURATION_S = 60.0


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


def render_summary(summary: RunSummary, job: dict[str, Any] | None = None) -> None:
    """Print a run's summary (and the twin's print job, if any) with rich."""
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
    if job is not None:
        rows += [
            ("twin job", f"{job['source']} ({'done' if job['done'] else 'not finished'})"),
            ("deposited mass", f"{job['mass_g']:.4f} g of {job['commanded_mass_g']:.4f} g"),
            ("twin's true slip", f"{100 * job['true_slip']:.2f} %"),
        ]
    console.print(table_from_rows("Control run", ["", ""], rows))


def _job_dict(twin: TwinPrinter) -> dict[str, Any] | None:
    runner = twin.job
    if runner is None:
        return None
    twin.sync()
    tot = runner.totals()
    job = runner.job
    part_cmd = job.position_mm(job.end_s) - job.position_mm(job.part_start_s)
    density = runner.machine.material.density_g_mm3
    return {
        "source": job.source, "done": runner.done,
        "mass_g": runner.part_mass_g(),
        "commanded_mass_g": part_cmd * runner.area_mm2 * density,
        "true_slip": (1.0 - tot.fed_mm / tot.commanded_forward_mm
                      if tot.commanded_forward_mm > 0 else None),
        "grind_s": tot.grind_s, "wait_s": tot.wait_s,
        "print_time_s": None if runner.end_s is None else runner.end_s - runner.start_s,
    }


def _check_sources(synthetic: bool, camera: str | None, video: Path | None,
                   twin_camera: bool) -> None:
    given = [name for name, on in (("--synthetic", synthetic), ("--camera", camera is not None),
                                   ("--video", video is not None),
                                   ("--twin-camera", twin_camera)) if on]
    if not given:
        raise FlowtwinError("no measurement source given", field="source",
                            allowed="--synthetic, --camera N, --video FILE or --twin-camera")
    if len(given) > 1:
        raise FlowtwinError("more than one measurement source given", field="source",
                            value=given, allowed="exactly one")


def register(app: typer.Typer) -> None:
    """Add ``flowtwin control``."""

    @app.command("control")
    def control_cmd(
        printer: Annotated[str, typer.Option(
            "--printer", help="octoprint://HOST:PORT[?port=VIRTUAL], moonraker://HOST:PORT, "
            "serial:///dev/ttyUSB0[?baud=N] or twin[?firmware=klipper&delay=S].")],
        synthetic: Annotated[bool, typer.Option(
            "--synthetic", help="Use a synthetic slip signal (low/high/low thirds).")] = False,
        camera: Annotated[str | None, typer.Option(
            "--camera", help="Measure with a live camera (index, e.g. 0).")] = None,
        video: Annotated[Path | None, typer.Option(
            "--video", help="Measure a recorded video, replayed on the loop's clock.")] = None,
        twin_camera: Annotated[bool, typer.Option(
            "--twin-camera", help="Twin only: film the twin's print with the synthetic "
            "camera and measure the frames with the vision pipeline.")] = False,
        vision_config: Annotated[Path | None, typer.Option(
            "--vision-config", help="Vision TOML (ROIs, scale, gear) for --camera/--video.")
        ] = None,
        window_frames: Annotated[int, typer.Option(
            "--window-frames", help="Frames per measurement (--camera/--video).")] = 8,
        gcode: Annotated[Path | None, typer.Option(
            "--gcode", help="Twin only: G-code the twin prints physically.")] = None,
        layers_per_set: Annotated[int, typer.Option(
            "--layers-per-set", help="Twin camera without --gcode: layers per temperature "
            "set of Greeff's test polygon (11 in [003]).")] = 11,
        machine: Annotated[str, typer.Option(
            "--machine", help="Twin only: set-up whose physics the twin follows.")
        ] = "greeff2017",
        camera_interval: Annotated[float, typer.Option(
            "--camera-interval", help="Twin camera: time between measurements (s).")] = 1.0,
        duration: Annotated[float | None, typer.Option(
            "--duration", help="Run length (s); default 60 s, or until the twin's print "
            "job ends.")] = None,
        controller: Annotated[str, typer.Option(
            "--controller", help="greeff | feedforward | pi | off")] = "greeff",
        channel: Annotated[Channel | None, typer.Option(
            "--channel", help="Override the multiplier (speed=M220, flow=M221).")] = None,
        firmware: Annotated[Firmware | None, typer.Option(
            "--firmware", help="Firmware behind OctoPrint / of the twin.")] = None,
        min_pct: Annotated[float, typer.Option("--min-pct")] = 50.0,
        max_pct: Annotated[float, typer.Option("--max-pct")] = 150.0,
        rate_limit: Annotated[float, typer.Option(
            "--rate-limit", help="Largest multiplier change (%/s).")] = 20.0,
        period: Annotated[float, typer.Option("--period", help="Loop tick (s).")] = 0.5,
        watchdog: Annotated[float | None, typer.Option(
            "--watchdog", help="Safe state after this long without measurements (s); "
            "default 2 s (3.5 × the interval with the twin camera).")] = None,
        speedup: Annotated[float, typer.Option(
            "--speedup", help="Twin only: run this many times faster than real time.")] = 1.0,
        sim_time: Annotated[bool, typer.Option(
            "--sim-time", help="Twin only: simulated time, as fast as the computer can.")
        ] = False,
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
        from rich.live import Live

        from flowtwin.control.connect import open_printer
        from flowtwin.control.loop.clock import AcceleratedClock, RealClock, SimClock
        from flowtwin.control.loop.controllers import Limits, make_controller
        from flowtwin.control.loop.log import ControlLog
        from flowtwin.control.loop.supervisor import LoopSettings, run_control
        from flowtwin.control.simulated.twin import TwinPrinter
        from flowtwin.control.transports.credentials import load_api_key

        _check_sources(synthetic, camera, video, twin_camera)
        if duration is not None and not (math.isfinite(duration) and duration > 0):
            raise FlowtwinError("duration must be positive", field="--duration",
                                value=duration, allowed="> 0 s")
        is_twin = printer.strip().startswith("twin")
        for flag, used in (("--speedup", speedup != 1.0), ("--sim-time", sim_time),
                           ("--twin-camera", twin_camera), ("--gcode", gcode is not None)):
            if used and not is_twin:
                raise FlowtwinError(f"{flag} only applies to the twin", field=flag,
                                    allowed="--printer twin")
        if (camera is not None or video is not None) and vision_config is None:
            raise FlowtwinError("a camera or video needs a vision configuration",
                                field="--vision-config",
                                allowed="a vision TOML with [roi] and [scale] (see "
                                "docs/vision.md)")
        clock: Clock
        if sim_time:
            clock = SimClock()
        elif is_twin:
            clock = AcceleratedClock(speedup)
        else:
            clock = RealClock()
        key = load_api_key(file=api_key_file, env=api_key_env)
        conn = open_printer(printer, api_key=key, clock=clock, firmware=firmware)
        ctl = make_controller(controller, channel=channel,
                              limits=Limits(min_pct, max_pct, rate_limit))
        stops: list[Callable[[], bool]] = []
        if isinstance(conn, TwinPrinter) and (twin_camera or gcode is not None):
            from flowtwin.reproduce.greeff2017_loop import job_runner

            conn.job = job_runner(machine=machine, gcode=gcode,
                                  layers_per_set=layers_per_set, start_s=clock.now())
            twin = conn
            stops.append(lambda: twin.job_done)
        if duration is not None:
            run_for = duration
        elif stops:
            run_for = math.inf
        else:
            run_for = DEFAULT_DURATION_S
        wd = watchdog if watchdog is not None else (
            3.5 * camera_interval if twin_camera else 2.0)
        settings = LoopSettings(duration_s=run_for if math.isfinite(run_for) else 1e9,
                                period_s=period, watchdog_s=wd)
        last: list[Status] = []

        def remember(st: Status) -> None:
            last[:] = [st]

        def stop() -> bool:
            return any(s() for s in stops)

        source = _source(conn, clock, synthetic=synthetic, camera=camera, video=video,
                         vision_config=vision_config, window_frames=window_frames,
                         camera_interval=camera_interval, seed=seed, duration=duration,
                         stops=stops, commanded=lambda: _commanded(last, ctl.channel))
        with ControlLog(log_file, keep_rows=False) as clog:
            if json_out:
                summary = run_control(conn, source, ctl, clock=clock, settings=settings,
                                      log_to=clog, on_status=remember, stop=stop)
            else:
                with Live(_status_table(None, conn.description), console=console,
                          refresh_per_second=4, transient=True) as live:
                    def show(st: Status) -> None:
                        remember(st)
                        live.update(_status_table(st, conn.description))

                    summary = run_control(conn, source, ctl, clock=clock, settings=settings,
                                          log_to=clog, on_status=show, stop=stop)
        job = _job_dict(conn) if isinstance(conn, TwinPrinter) else None
        if json_out:
            out = summary.to_dict()
            if job is not None:
                out["job"] = job
            print_json(out)
        else:
            render_summary(summary, job)
        if not summary.restored:
            err_console.print("[bold red]warning:[/] the multiplier could not be restored "
                              "to 100 %; check the printer")
            raise typer.Exit(1)


def _commanded(last: list[Status], channel: Channel) -> Factors:
    from flowtwin.control.printer import Factors

    pct = last[-1].command_pct if last else 100.0
    if channel is Channel.SPEED:
        return Factors(pct, 100.0, "commanded")
    return Factors(100.0, pct, "commanded")


def _source(conn: Printer, clock: Clock, *, synthetic: bool, camera: str | None,
            video: Path | None, vision_config: Path | None, window_frames: int,
            camera_interval: float, seed: int, duration: float | None,
            stops: list[Callable[[], bool]], commanded: Callable[[], Factors]
            ) -> MeasurementSource:
    """The measurement source the options ask for (``stops`` gets its end condition)."""
    from flowtwin.control.loop.measurement import SyntheticSlipSource
    from flowtwin.control.simulated.twin import TwinPrinter

    if synthetic:
        factors = commanded
        if isinstance(conn, TwinPrinter):
            twin = conn

            def factors() -> Factors:
                return twin.factors_at(clock.now())
        return SyntheticSlipSource(clock, duration_s=duration or DEFAULT_DURATION_S,
                                   seed=seed, factors=factors)
    if camera is not None or video is not None:
        from flowtwin.control.loop.video import CameraSource, VideoSource
        from flowtwin.vision import build_config

        config = build_config(config_path=vision_config)
        if video is not None:
            vsrc = VideoSource(video, config, clock, window_frames=window_frames)
            stops.append(lambda: vsrc.finished)
            return vsrc
        assert camera is not None
        index: int | str = int(camera) if camera.isdigit() else camera
        return CameraSource(index, config, clock, window_frames=window_frames)
    from flowtwin.control.simulated.camera import TwinCameraSource, twin_scene
    from flowtwin.reproduce.greeff2017_loop import PrintJobSettings

    assert isinstance(conn, TwinPrinter) and conn.job is not None
    st = PrintJobSettings()  # the print-job test's camera: 320×256 px at 50 µm/px
    scene = twin_scene(conn.job.machine.filament.diameter_mm, width_px=st.camera_size_px[0],
                       height_px=st.camera_size_px[1], mm_per_px=st.camera_mm_per_px,
                       seed=seed)
    return TwinCameraSource(conn, scene=scene, frames=st.camera_frames,
                            interval_s=camera_interval, seed=seed)
