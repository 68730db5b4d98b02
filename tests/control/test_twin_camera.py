"""The twin camera: frames rendered from the twin's print, measured by the vision pipeline."""

from __future__ import annotations

import math

import cv2
import pytest

from flowtwin.control.loop.clock import SimClock
from flowtwin.control.simulated.camera import TwinCameraSource, twin_scene
from flowtwin.control.simulated.job import PrintJob
from flowtwin.control.simulated.runner import JobRunner
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.errors import ProfileError
from flowtwin.profiles import load_machine
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec, polygon_gcode

GREEFF = load_machine("greeff2017")
SCENE = twin_scene(2.85, width_px=320, height_px=256, mm_per_px=0.05)


@pytest.fixture(autouse=True, scope="module")
def _one_opencv_thread() -> None:
    cv2.setNumThreads(1)


@pytest.fixture(scope="module")
def job() -> PrintJob:
    spec = PolygonSpec(temperature_sets=((2, 230.0), (2, 190.0)), prime_length_mm=0.0)
    return PrintJob.from_gcode(polygon_gcode(spec).encode(), machine=GREEFF)


def _rig(job: PrintJob, **kw) -> tuple[SimClock, TwinPrinter, TwinCameraSource]:
    clk = SimClock()
    twin = TwinPrinter(clk, job=JobRunner(job, GREEFF, start_s=clk.now()))
    twin.connect()
    return clk, twin, TwinCameraSource(twin, scene=SCENE, **kw)


def test_measures_the_twins_slip_while_printing(job: PrintJob) -> None:
    clk, _twin, cam = _rig(job, frames=4, interval_s=1.0)
    assert cam.read() is None                 # not enough history for a burst yet
    layer1 = job.move_t0_s[job.layer == 1]
    t_mid = 0.5 * float(layer1[0] + layer1[-1])
    clk.advance(t_mid)                        # layer 1 at 230 °C, 2 mm/s
    m = cam.read()
    assert m is not None and m.valid and m.t_s == t_mid
    rec = cam.records[-1]
    # measured against the twin's truth over the same frames; 1 percentage point is
    # three times the pipeline's rms error at this scale
    assert m.slip == pytest.approx(rec.true_slip, abs=0.01)
    assert rec.true_slip == pytest.approx(0.097, abs=0.01)   # steady slip, 230 °C, 2 mm/s
    assert m.gear_speed_mm_s == pytest.approx(2.0, rel=0.02)
    clk.advance(0.5)
    assert cam.read() is None                 # one measurement per interval


def test_heater_wait_is_idle_and_190c_slips_more(job: PrintJob) -> None:
    clk, twin, cam = _rig(job, frames=3, interval_s=1.0)
    assert twin.job is not None
    tau_wait = twin.job.job.heater[2].tau_s   # M109 R190 after the 230 °C layers
    clk.advance(tau_wait + 5.0)
    m = cam.read()
    assert m is not None and m.idle and not m.valid
    assert cam.records[-1].idle
    while twin.job.waiting.value != "none" or twin.job.temperature_c > 191.0:
        clk.advance(1.0)
        twin.sync()
    clk.advance(3.0)
    m = cam.read()
    assert m is not None and m.valid
    assert m.slip == pytest.approx(cam.records[-1].true_slip, abs=0.015)
    assert m.slip > 0.3                        # 190 °C: grinding at 2 mm/s


def test_needs_a_job_and_two_frames(job: PrintJob) -> None:
    with pytest.raises(ProfileError, match="print job"):
        TwinCameraSource(TwinPrinter(SimClock()))
    clk = SimClock()
    twin = TwinPrinter(clk, job=JobRunner(job, GREEFF, start_s=0.0))
    with pytest.raises(ProfileError, match="two frames"):
        TwinCameraSource(twin, frames=1)
    with pytest.raises(ProfileError, match="longer than"):
        TwinCameraSource(twin, frames=30, interval_s=1.0)
    assert math.isclose(TwinCameraSource(twin).scene.nominal_width_mm, 2.85)
