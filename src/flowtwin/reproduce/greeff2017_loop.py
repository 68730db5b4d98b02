"""Greeff & Schilling's print-job test [003 §3.3] on the fully simulated loop.

twin printer (prints the 40-sided polygon with the greeff2017 machine's physics)
→ twin camera (renders frames of gear and filament) → vision (OpenCV, [003 §2.2])
→ controller (Greeff's: thresholded, time-averaged slip as the speed multiplier ``M220``
[003 §2.3]) → supervisor → twin. All on a :class:`~flowtwin.control.loop.clock.SimClock`, so a
200 s print runs as fast as the physics and the image processing allow.

The same print runs twice, loop off (:class:`~flowtwin.control.loop.controllers.OpenLoopController`:
the camera measures, nothing is commanded) and loop on, and is compared like the paper:
deposited mass (the twin's melt out since layer 0 × density — the weighed object) and
slip (camera-measured, and the twin's true slip). The paper found +14 % mass with the
loop on [003 §3.3].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flowtwin.control.loop.clock import SimClock
from flowtwin.control.loop.controllers import Controller, GreeffController, OpenLoopController
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.supervisor import LoopSettings, RunSummary, run_control
from flowtwin.control.simulated.camera import CameraRecord, TwinCameraSource, twin_scene
from flowtwin.control.simulated.job import PrintJob
from flowtwin.control.simulated.runner import JobHistory, JobRunner
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.errors import ProfileError
from flowtwin.firmware import Firmware
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec, polygon_gcode
from flowtwin.vision.synth import SceneSpec

__all__ = ["PAPER_MASS_GAIN", "PrintJobComparison", "PrintJobRun", "PrintJobSettings",
           "compare_print_jobs", "job_runner", "run_print_job"]

#: [003 §3.3]: "a 14% mass increase by turning the control on" (0.198 g).
PAPER_MASS_GAIN = 0.14


@dataclass(frozen=True)
class PrintJobSettings:
    """Everything that defines a simulated print-job test.

    Attributes
    ----------
    part
        The printed polygon (default [003 §3.3]; fewer layers for quick tests).
    machine
        Set-up name (``greeff2017``: RF1000, 2.85 mm PLA, 0.5 mm nozzle).
    controller
        The loop-on controller (Greeff's: 2 % threshold, 5 s window, on ``M220``).
    period_s
        Loop tick, s.
    watchdog_s
        Supervisor watchdog, s (longer than the camera interval, so a burst the vision
        cannot measure — a retraction — does not trip it).
    camera_frames, camera_interval_s
        Frames per measurement and time between measurements (the subsample, see
        :mod:`flowtwin.control.simulated.camera`).
    camera_size_px, camera_mm_per_px
        Frame size and scale of the twin camera. Default 320×256 px at 50 µm/px — coarser
        than Greeff's ~20 µm/px [003 §2.1] to keep the rendering affordable (the vision
        reads constant slips within ~0.5 % there; 2 mm/s is still 2.8 px per frame).
    scene
        Camera scene overriding the three above.
    effect_delay_s
        Time from an acknowledged ``M220`` to its effect (moves already queued), s.
    heater_tau_s
        Heater time constant of the twin, s (default: profile, else 15 s).
    step_s
        Integration step of the twin, s.
    seed
        Seed of the camera's textures and noise.
    """

    part: PolygonSpec = field(default_factory=PolygonSpec)
    machine: str = "greeff2017"
    controller: GreeffController = field(default_factory=GreeffController)
    period_s: float = 0.5
    watchdog_s: float = 3.5
    camera_frames: int = 3
    camera_interval_s: float = 1.0
    camera_size_px: tuple[int, int] = (320, 256)
    camera_mm_per_px: float = 0.05
    scene: SceneSpec | None = None
    effect_delay_s: float = 0.5
    heater_tau_s: float | None = None
    step_s: float = 0.01
    seed: int = 2017


@dataclass(frozen=True)
class PrintJobRun:
    """One simulated print of the test part.

    Attributes
    ----------
    loop
        Whether the loop was on.
    mass_g
        Deposited mass of the object (melt out since layer 0 × density), g.
    commanded_mass_g
        Mass the G-code asks for in the object, g.
    true_slip
        The twin's slip over the whole print, ``1 − fed/forward commanded``.
    measured_slip
        Mean of the camera's slip measurements (None without any).
    camera_error
        Mean of measured − true slip over the measurements (None without any).
    print_time_s
        Clock time from start to the end of the G-code, s.
    grind_s, wait_s
        Time the drive ground the filament, and heater waits, s.
    summary
        The supervisor's summary (samples, multiplier range, faults, restored).
    history
        The twin's per-step record.
    records
        The camera's measurements with the twin's truth.
    """

    loop: bool
    mass_g: float
    commanded_mass_g: float
    true_slip: float
    measured_slip: float | None
    camera_error: float | None
    print_time_s: float
    grind_s: float
    wait_s: float
    summary: RunSummary
    history: JobHistory = field(repr=False)
    records: tuple[CameraRecord, ...] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures (no series)."""
        return {"loop": "on" if self.loop else "off", "mass_g": self.mass_g,
                "commanded_mass_g": self.commanded_mass_g, "true_slip": self.true_slip,
                "measured_slip": self.measured_slip, "camera_error": self.camera_error,
                "print_time_s": self.print_time_s, "grind_s": self.grind_s,
                "wait_s": self.wait_s, "control": self.summary.to_dict()}


@dataclass(frozen=True)
class PrintJobComparison:
    """Loop off against loop on, as [003 §3.3] reports it."""

    off: PrintJobRun
    on: PrintJobRun

    @property
    def mass_gain(self) -> float:
        """Relative mass increase with the loop on, ``m_on/m_off − 1``."""
        return self.on.mass_g / self.off.mass_g - 1.0

    @property
    def mass_difference_g(self) -> float:
        """``m_on − m_off``, g ([003]: 0.198 g)."""
        return self.on.mass_g - self.off.mass_g

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready comparison."""
        return {"off": self.off.to_dict(), "on": self.on.to_dict(),
                "mass_gain": self.mass_gain, "mass_difference_g": self.mass_difference_g,
                "paper_mass_gain": PAPER_MASS_GAIN}


def _controller(settings: PrintJobSettings, loop: bool) -> Controller[Any]:
    if loop:
        return settings.controller
    return OpenLoopController(channel=settings.controller.channel)


def run_print_job(*, loop: bool, settings: PrintJobSettings | None = None,
                  job: PrintJob | None = None, machine: Machine | None = None,
                  log_to: ControlLog | None = None) -> PrintJobRun:
    """Print the test part on the twin with the loop on or off (simulated time).

    Parameters
    ----------
    loop
        Loop on (``settings.controller``) or off (measure only).
    settings
        The test (default :class:`PrintJobSettings`).
    job, machine
        The planned part and the set-up, when already built (both or neither).
    log_to
        CSV log of the run.

    Returns
    -------
    PrintJobRun

    Raises
    ------
    ProfileError
        Unknown machine, or only one of ``job`` and ``machine`` given.
    """
    st = settings or PrintJobSettings()
    if (job is None) != (machine is None):
        raise ProfileError("give both the planned job and its machine, or neither",
                           field="job/machine")
    if machine is None or job is None:
        machine = load_machine(st.machine)
        job = PrintJob.from_gcode(polygon_gcode(st.part).encode("utf-8"), machine=machine,
                                  name=f"test polygon [003 §3.3], {st.part.layers} layers")
    clock = SimClock()
    runner = JobRunner(job, machine, start_s=clock.now(), heater_tau_s=st.heater_tau_s,
                       step_s=st.step_s)
    twin = TwinPrinter(clock, firmware=Firmware.MARLIN, effect_delay_s=st.effect_delay_s,
                       job=runner)
    scene = st.scene or twin_scene(machine.filament.diameter_mm,
                                   width_px=st.camera_size_px[0],
                                   height_px=st.camera_size_px[1],
                                   mm_per_px=st.camera_mm_per_px)
    source = TwinCameraSource(twin, scene=scene, frames=st.camera_frames,
                              interval_s=st.camera_interval_s, seed=st.seed)
    # generous bound: the slowest loop (50 % speed) doubles the print time
    bound = 2.0 * (job.end_s + 4.0 * 60.0 * len(job.heater)) + 60.0
    summary = run_control(twin, source, _controller(st, loop), clock=clock,
                          settings=LoopSettings(duration_s=bound, period_s=st.period_s,
                                                watchdog_s=st.watchdog_s),
                          log_to=log_to, stop=lambda: twin.job_done)
    if not runner.done:
        raise ProfileError("the simulated print did not finish within the time bound",
                           field="duration_s", value=bound)
    tot = runner.totals()
    hist = runner.history()
    records = tuple(source.records)
    meas = [r for r in records if not r.idle and math.isfinite(r.measured_slip)]
    both = [r for r in meas if math.isfinite(r.true_slip)]
    density = machine.material.density_g_mm3
    part_cmd = float(job.feed.position_at(job.end_s) - job.feed.position_at(job.part_start_s))
    assert runner.end_s is not None
    return PrintJobRun(
        loop=loop, mass_g=runner.part_mass_g(),
        commanded_mass_g=part_cmd * runner.area_mm2 * density,
        true_slip=1.0 - tot.fed_mm / tot.commanded_forward_mm if tot.commanded_forward_mm
        else math.nan,
        measured_slip=float(np.mean([r.measured_slip for r in meas])) if meas else None,
        camera_error=float(np.mean([r.measured_slip - r.true_slip for r in both]))
        if both else None,
        print_time_s=runner.end_s - runner.start_s, grind_s=tot.grind_s, wait_s=tot.wait_s,
        summary=summary, history=hist, records=records)


def compare_print_jobs(settings: PrintJobSettings | None = None) -> PrintJobComparison:
    """Run the print-job test with the loop off and on (same part, machine and camera).

    Parameters
    ----------
    settings
        The test (default :class:`PrintJobSettings`: the full part of [003 §3.3]).

    Returns
    -------
    PrintJobComparison
    """
    st = settings or PrintJobSettings()
    machine = load_machine(st.machine)
    job = PrintJob.from_gcode(polygon_gcode(st.part).encode("utf-8"), machine=machine,
                              name=f"test polygon [003 §3.3], {st.part.layers} layers")
    off = run_print_job(loop=False, settings=st, job=job, machine=machine)
    on = run_print_job(loop=True, settings=st, job=job, machine=machine)
    return PrintJobComparison(off, on)


def job_runner(*, machine: str | Machine = "greeff2017", gcode: str | Path | None = None,
               layers_per_set: int = 11, start_s: float = 0.0,
               heater_tau_s: float | None = None) -> JobRunner:
    """A print job for the twin printer: a G-code file, or the test polygon of [003 §3.3].

    Parameters
    ----------
    machine
        Set-up (name or object) whose physics the twin follows.
    gcode
        G-code file to print; None prints the polygon
        (:func:`~flowtwin.reproduce.greeff2017_polygon.polygon_gcode`) with
        ``layers_per_set`` layers per temperature set.
    layers_per_set
        Layers per temperature set of the polygon (11 in [003 §3.3]).
    start_s
        Clock time at which the print starts, s.
    heater_tau_s
        Heater time constant, s (default: profile, else 15 s).

    Returns
    -------
    JobRunner
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine)
    if gcode is None:
        spec = PolygonSpec.greeff(layers_per_set=layers_per_set)
        job = PrintJob.from_gcode(polygon_gcode(spec).encode("utf-8"), machine=m,
                                  name=f"test polygon [003 §3.3], {spec.layers} layers")
    else:
        job = PrintJob.from_gcode(str(gcode), machine=m)
    return JobRunner(job, m, start_s=start_s, heater_tau_s=heater_tau_s)
