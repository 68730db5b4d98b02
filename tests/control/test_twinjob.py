"""The twin printing a job: multipliers act like the firmware's, heater waits, physics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.control.loop.clock import SimClock
from flowtwin.control.printer import Factors
from flowtwin.control.simulated.job import PrintJob
from flowtwin.control.simulated.runner import JobRunner
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.errors import ProfileError
from flowtwin.profiles import load_machine
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec, polygon_gcode
from flowtwin.simulation.parameters import operating_point

GREEFF = load_machine("greeff2017")


@pytest.fixture(scope="module")
def job_230() -> PrintJob:
    spec = PolygonSpec(temperature_sets=((4, 230.0),))
    return PrintJob.from_gcode(polygon_gcode(spec).encode(), machine=GREEFF)


@pytest.fixture(scope="module")
def job_two_sets() -> PrintJob:
    spec = PolygonSpec(temperature_sets=((1, 230.0), (2, 190.0)), prime_length_mm=0.0)
    return PrintJob.from_gcode(polygon_gcode(spec).encode(), machine=GREEFF)


def _print(job: PrintJob, speed: float = 100.0, flow: float = 100.0, **kw) -> JobRunner:
    r = JobRunner(job, GREEFF, start_s=0.0, **kw)
    t = 0.0
    while not r.done:
        t += 1.0
        r.advance_to(t, lambda _t: Factors(speed, flow))
        assert t < 2000.0
    return r


def _layer_slip(r: JobRunner, layer: int) -> float:
    """Slip over the wall of ``layer`` (the 16 mm/s un-retraction excluded)."""
    h = r.history()
    sel = (h.layer == layer) & (h.gear_speed_mm_s > 0) & (h.gear_speed_mm_s < 5.0)
    return 1.0 - float(np.sum(h.filament_speed_mm_s[sel] * h.dt_s[sel])
                       / np.sum(h.gear_speed_mm_s[sel] * h.dt_s[sel]))


def test_speed_multiplier_stretches_time_and_lowers_slip(job_230: PrintJob) -> None:
    full, half = _print(job_230), _print(job_230, speed=50.0)
    assert full.end_s is not None and half.end_s is not None
    # M220 scales every move's feed rate: the print takes twice as long (no waits here)
    assert half.end_s == pytest.approx(2.0 * full.end_s, abs=0.02)
    assert half.totals().commanded_mm == pytest.approx(full.totals().commanded_mm, rel=1e-9)
    # slip follows the machine's physics at the commanded feed [003 §2.3]: steady slip at
    # 2 and 1 mm/s; the wall also holds the pressure build-up after the layer change
    # (a few K = 0.03 s) and the slowdowns at its 40 corners, hence 3 % relative.
    for runner, feed in ((full, 2.0), (half, 1.0)):
        op = operating_point(GREEFF, feed_mm_s=feed, temperature_c=230.0, layer_height_mm=0.3)
        assert _layer_slip(runner, 2) == pytest.approx(op.slip, rel=0.03)
    assert _layer_slip(half, 2) < 0.6 * _layer_slip(full, 2)
    assert half.part_mass_g() > full.part_mass_g()


def test_flow_multiplier_scales_every_extruder_move(job_230: PrintJob) -> None:
    full, less = _print(job_230), _print(job_230, flow=90.0)
    assert less.totals().commanded_mm == pytest.approx(0.9 * full.totals().commanded_mm,
                                                       rel=1e-9)
    assert less.end_s == pytest.approx(full.end_s, abs=0.02)   # M221 does not change time


def test_m109_waits_for_the_first_order_heater(job_two_sets: PrintJob) -> None:
    r = _print(job_two_sets, heater_tau_s=15.0)
    tot = r.totals()
    # from 230 °C to within 1 °C of 190 °C: t = τ ln(40/1) (dynamics.thermal's law)
    assert tot.wait_s == pytest.approx(15.0 * math.log(40.0), abs=0.02)
    h = r.history()
    waiting = (h.gear_speed_mm_s == 0.0) & (h.temperature_c > 191.0) & (h.layer == 0)
    assert waiting.sum() > 0
    # nothing is printed at 190 °C before the nozzle is there
    printing = h.gear_speed_mm_s > 0
    assert float(h.temperature_c[printing & (h.layer == 1)].max()) <= 191.0
    assert float(h.temperature_c[printing & (h.layer == 2)].min()) >= 189.0


def test_slip_rises_at_190c(job_two_sets: PrintJob) -> None:
    r = _print(job_two_sets)
    assert _layer_slip(r, 2) > 0.3 > 0.1 > _layer_slip(r, 0)
    assert r.totals().grind_s > 0.0          # the drive grinds at 190 °C, 2 mm/s


def test_twin_printer_prints_while_the_loop_commands(job_230: PrintJob) -> None:
    clk = SimClock()
    twin = TwinPrinter(clk, effect_delay_s=0.5,
                       job=JobRunner(job_230, GREEFF, start_s=clk.now()))
    twin.connect()
    clk.advance(10.0)
    twin.send_gcode("M220 S60")
    twin.drop_connection()                    # the printer goes on printing
    clk.advance(10.0)
    assert twin.job is not None
    twin.sync()
    h = twin.job.history()
    assert h.t_s[-1] == pytest.approx(20.0)
    assert set(h.speed_pct[h.t_s <= 10.5].tolist()) == {100.0}   # delay of the queue
    assert set(h.speed_pct[h.t_s > 10.6].tolist()) == {60.0}
    twin.connect()
    assert not twin.job_done
    clk.advance(60.0)                         # the 4 layers end well before (~30 s at 60 %)
    assert twin.job_done


def test_bad_runner_settings() -> None:
    job = PrintJob.from_gcode(polygon_gcode(PolygonSpec.greeff(layers_per_set=1)).encode(),
                              machine=GREEFF)
    with pytest.raises(ProfileError, match="heater"):
        JobRunner(job, GREEFF, start_s=0.0, heater_tau_s=-1.0)
    with pytest.raises(ProfileError, match="step"):
        JobRunner(job, GREEFF, start_s=0.0, step_s=0.0)
