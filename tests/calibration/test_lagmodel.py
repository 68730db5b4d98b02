"""The twin as a width forward model: against the analytic step response and [001 Eq. 7]."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from flowtwin.calibration.fits.kfit import kline_for_machine
from flowtwin.calibration.fits.lagmodel import LagParams, _path_kinematics, lag_model, printed_runs
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.errors import CalibrationError
from flowtwin.physics.deposition import bead_area_mm2
from flowtwin.planner.plan_file import load_printer
from flowtwin.planner.timeline import PHASE_DTYPE
from flowtwin.profiles.machine import Machine, load_machine


@pytest.fixture(scope="module")
def klipper_machine() -> Machine:
    """Tronvoll's set-up planned on a Klipper printer (its advance with K = 0 is off)."""
    m = load_machine("tronvoll2019")
    return dataclasses.replace(m, printer=load_printer("generic-klipper"))


def test_path_kinematics_is_the_trapezoid() -> None:
    ph = np.zeros(1, dtype=PHASE_DTYPE)
    ph[0] = (2.0, 5.0, 25.0, 10.0, 400.0, 0.05, 0.3, 0.0375)
    t = np.array([2.0, 2.025, 2.05, 2.2, 2.35, 2.37, 2.3875, 3.0])
    s, v = _path_kinematics(ph, np.zeros(t.size, dtype=np.int64), t)
    # accelerate 5 -> 25 in 0.05 s (0.75 mm), cruise 0.3 s (7.5 mm), brake 25 -> 10 (0.65625 mm)
    s_exp = [0.0, 5 * 0.025 + 200 * 0.025 ** 2, 0.75, 0.75 + 25 * 0.15, 8.25,
             8.25 + 25 * 0.02 - 200 * 0.02 ** 2, 8.25 + 0.65625, 8.25 + 0.65625]
    v_exp = [5.0, 15.0, 25.0, 25.0, 25.0, 17.0, 10.0, 10.0]
    np.testing.assert_allclose(s, s_exp, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(v, v_exp, rtol=1e-6, atol=1e-9)


def test_width_after_a_speed_step_is_bellinis_response(klipper_machine: Machine) -> None:
    """A step of the commanded flow through ``g·e^(−τs)/(1 + K·s)`` [001 Eq. 15, Bellini].

    At 1e6 mm/s² the speed step takes 50 µs, so the commanded flow is a step to within
    (50 µs / K)/2 = 5e-4 of its height: the tolerance of 1e-3 covers that.
    """
    p = kline_for_machine(klipper_machine, PrintSettings(accel_mm_s2=1e6),
                          KLineParams(k_start=0.0, k_end=0.0, mark_every=0))
    model = lag_model(p.text().encode(), [p.segments[0].line], machine=klipper_machine)
    line = model.lines[0]
    assert line.cruise_mm_s.tolist() == [20.0, 70.0, 20.0]
    k, tau, g = 0.05, 0.02, 0.95
    x = np.linspace(20.3, 59.0, 80)
    w = model.widths(LagParams(k, tau, g), [x])[0]
    h = line.layer_height_mm
    q_fast = line.flow_mm3_s
    q_slow = q_fast * 20.0 / 70.0
    t = (x - 20.0) / 70.0
    q = np.where(t > tau, q_fast - (q_fast - q_slow) * np.exp(-(t - tau) / k), q_slow)
    expected = g * q / (h * 70.0) + (1.0 - math.pi / 4.0) * h
    np.testing.assert_allclose(w, expected, rtol=1e-3)


def test_widths_from_passes_made_once_are_the_same(klipper_machine: Machine) -> None:
    """``widths(..., passes=model.passes(x))`` is ``widths(x)`` to the bit (the lag fit
    makes the passing times once per registration), and a pass list for other lines is
    refused with the count."""
    p = kline_for_machine(klipper_machine, PrintSettings(accel_mm_s2=2000.0),
                          KLineParams(k_start=0.0, k_end=0.02, k_step=0.01, mark_every=0))
    model = lag_model(p.text().encode(), [seg.line for seg in p.segments],
                      machine=klipper_machine)
    xs = [np.linspace(1.0, ln.length_mm - 1.0, 57) for ln in model.lines]
    at = model.passes(xs)
    assert [(t.shape, v.shape) for t, v in at] == [((57,), (57,))] * len(xs)
    for params in (LagParams(0.03), LagParams(0.05, 0.01, 0.97)):
        direct = model.widths(params, xs)
        reused = model.widths(params, xs, passes=at)
        for a, b in zip(direct, reused, strict=True):
            np.testing.assert_array_equal(a, b)
    with pytest.raises(CalibrationError, match="one pass array per test line"):
        model.widths(LagParams(0.03), xs, passes=at[:-1])


def test_steady_width_is_the_slicer_bead(klipper_machine: Machine) -> None:
    """After the transient the bead is the slicer's ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7],
    for the filament really fed: the G-code is written for 1.75 mm, the set-up's PLA is
    1.752 mm (docs/spec.md §4), so the bead carries (1.752/1.75)² more melt."""
    s = PrintSettings(accel_mm_s2=2000.0, line_width_mm=0.45, layer_height_mm=0.25)
    p = kline_for_machine(klipper_machine, s, KLineParams(k_start=0.0, k_end=0.0,
                                                          mark_every=0))
    model = lag_model(p.text().encode(), [p.segments[0].line], machine=klipper_machine)
    ratio = (klipper_machine.filament.diameter_mm / 1.75) ** 2
    area = float(bead_area_mm2(0.45, 0.25)) * ratio
    expected = area / 0.25 + (1.0 - math.pi / 4.0) * 0.25
    # well into each segment's cruise (>= 17 lags): e^-17 < 1e-7 of the step is left; the
    # G-code's E is rounded to 1e-5 mm, <= 8e-6 of the 0.63 mm of a 20 mm segment
    w = model.widths(LagParams(0.03), [np.array([19.0, 58.0, 79.0])])[0]
    np.testing.assert_allclose(w, expected, rtol=2e-5)
    assert expected == pytest.approx(0.4509, abs=1e-4)
    assert model.lines[0].flow_mm3_s == pytest.approx(area * 70.0, rel=1e-4)


def test_lines_of_a_file_and_their_advance(klipper_machine: Machine) -> None:
    p = kline_for_machine(klipper_machine, PrintSettings(),
                          KLineParams(k_start=0.0, k_end=0.04, k_step=0.02))
    model = lag_model(p.text().encode(), None, machine=klipper_machine)
    runs = printed_runs(model.plan)
    assert [ln.gcode_line for ln in model.lines] == runs
    firsts = [s.line for s in p.segments if s.role == "slow"][::2]
    k_lines = model.subset([runs.index(f) for f in firsts])
    assert [ln.advance_k_s for ln in k_lines.lines] == pytest.approx([0.0, 0.02, 0.04])
    assert all(ln.length_mm == pytest.approx(80.0) for ln in k_lines.lines)
    np.testing.assert_allclose(k_lines.lines[1].vertices_xy_mm[:, 1], 110.0)


def test_bad_test_lines(klipper_machine: Machine) -> None:
    p = kline_for_machine(klipper_machine, PrintSettings(),
                          KLineParams(k_start=0.0, k_end=0.0, mark_every=0))
    text = p.text().encode()
    with pytest.raises(CalibrationError, match="must start at a move that extrudes"):
        lag_model(text, [1], machine=klipper_machine)
    first = p.segments[0].line
    with pytest.raises(CalibrationError, match="twice"):
        lag_model(text, [first, first], machine=klipper_machine)
    with pytest.raises(CalibrationError, match="layer height out of range"):
        lag_model(text, [first], machine=klipper_machine, layer_height_mm=0.9)
    with pytest.raises(CalibrationError, match="lag factor must be > 0"):
        LagParams(0.0)
    with pytest.raises(CalibrationError, match="dead time out of range"):
        LagParams(0.05, dead_time_s=1.0)
