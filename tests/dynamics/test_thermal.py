"""Nozzle temperature from M104/M109 with a first-order heater lag."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from flowtwin.dynamics import move_temperatures, temperature_schedule
from flowtwin.errors import ProfileError
from flowtwin.gcode.moves import Event


@pytest.fixture
def two_moves(make_print, Move):
    return make_print([Move(50, 0, de=2.0, v=20), Move(100, 0, de=2.0, v=20),
                       Move(150, 0, de=2.0, v=20)], accel=1000)


def test_m104_first_order_approach(two_moves):
    mt, tl = two_moves
    mt.events.append(Event(1, 5, "M104", {"S": 230.0}))
    tau = 4.0
    sched = temperature_schedule(mt, tl, initial_c=200.0, heater_tau_s=tau)
    t1 = float(tl.phases["t_start"][1])
    t = np.array([0.0, t1, t1 + 1.0, t1 + 3.0])
    expected = np.where(t < t1, 200.0, 230.0 - 30.0 * np.exp(-(t - t1) / tau))
    np.testing.assert_allclose(sched.at(t), expected, rtol=1e-14)
    # mean over a move = exact integral of the exponential
    temps = move_temperatures(mt, tl, initial_c=200.0, heater_tau_s=tau)
    a, b = t1, float(tl.end_time_s[1])
    ref = quad(lambda x: 230.0 - 30.0 * math.exp(-(x - a) / tau), a, b)[0] / (b - a)
    assert temps[1] == pytest.approx(ref, rel=1e-13)
    assert temps[0] == 200.0


def test_m109_waits_and_tool_filter(two_moves):
    mt, tl = two_moves
    mt.events.extend([Event(1, 5, "M109", {"S": 240.0}),
                      Event(2, 7, "M104", {"S": 180.0, "T": 1.0})])
    temps = move_temperatures(mt, tl, initial_c=200.0, heater_tau_s=10.0)
    assert temps[1] == 240.0 and temps[2] == 240.0  # reached (waited); T1 is another heater
    temps_t1 = move_temperatures(mt, tl, initial_c=200.0, heater_tau_s=0.0, tool=1)
    assert temps_t1.tolist() == [200.0, 240.0, 180.0]  # no T: the extruder simulated


def test_klipper_heater_command_and_no_lag(two_moves):
    mt, tl = two_moves
    mt.events.append(Event(2, 9, "SET_HEATER_TEMPERATURE", {"HEATER": "extruder", "TARGET": 215.0}))
    assert move_temperatures(mt, tl, initial_c=200.0).tolist() == [200.0, 200.0, 215.0]
    with pytest.raises(ProfileError, match="heater_tau_s"):
        temperature_schedule(mt, tl, initial_c=200.0, heater_tau_s=-1.0)
