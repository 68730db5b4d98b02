"""The twin's extruder step: steady slip, mass balance, grinding, retraction, and agreement
with the dynamics integrator over a whole G-code."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.control.printer import Factors
from flowtwin.control.simulated.extruder import (
    ExtruderState,
    StepParams,
    step_extrusion,
    step_params,
)
from flowtwin.control.simulated.job import PrintJob
from flowtwin.control.simulated.runner import JobRunner
from flowtwin.physics.drive import steady_state_slip
from flowtwin.physics.lag import lag_step
from flowtwin.profiles import load_machine
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec, polygon_gcode
from flowtwin.simulation import simulate
from flowtwin.simulation.parameters import operating_point

GREEFF = load_machine("greeff2017")


def _run(p: StepParams, v: float, seconds: float, dt: float = 0.01,
         state: ExtruderState | None = None) -> tuple[ExtruderState, float, float, float]:
    st = state or ExtruderState()
    cmd = fed = out = 0.0
    for _ in range(int(round(seconds / dt))):
        st, fl = step_extrusion(st, v, dt, p)
        cmd += fl.commanded_mm
        fed += fl.fed_mm
        out += fl.out_mm
    return st, cmd, fed, out


@pytest.mark.parametrize(("temp_c", "layer_mm", "feed"), [
    (230.0, 0.3, 2.0), (215.0, None, 2.0), (200.0, 0.3, 1.0), (190.0, 0.3, 1.0)])
def test_steady_slip_is_the_machines_operating_point(temp_c: float, layer_mm: float | None,
                                                     feed: float) -> None:
    # In steady state the state equation's slip must equal s = (k_p + s'F0)/(1 + s'F0)
    # [000 Eq. 6 with F ∝ flow], which operating_point() evaluates independently.
    p = step_params(GREEFF, temperature_c=temp_c, layer_height_mm=layer_mm)
    op = operating_point(GREEFF, feed_mm_s=feed, temperature_c=temp_c,
                         layer_height_mm=layer_mm)
    assert p.lag_k_s == pytest.approx(op.lag_k_s, rel=1e-12)
    assert p.max_feed_force_n == pytest.approx(op.max_feed_force_n, rel=1e-12)
    st, _, _, _ = _run(p, feed, 40.0 * p.lag_k_s + 2.0)  # many time constants: settled
    _, cmd, fed, out = _run(p, feed, 1.0, state=st)
    assert 1.0 - fed / cmd == pytest.approx(op.slip, rel=1e-9)
    assert 1.0 - out / cmd == pytest.approx(op.slip, rel=1e-9)
    f0 = op.nominal_force_n
    assert op.slip == pytest.approx(float(steady_state_slip(f0, p.slip_a_per_n,
                                                            k_p=p.slip_offset)), rel=1e-12)


def test_mass_balance_in_every_regime() -> None:
    # fed − out = Δx over random commands: forward, retraction, standstill, grinding.
    p = step_params(GREEFF, temperature_c=190.0, layer_height_mm=0.3)
    rng = np.random.default_rng(7)
    st = ExtruderState()
    regimes = set()
    for _ in range(3000):
        v = float(rng.choice([2.5, 2.0, 1.0, 0.0, -16.0, 16.0], p=[.3, .3, .2, .1, .05, .05]))
        dt = float(rng.uniform(0.001, 0.05))
        x0 = st.compression_mm
        st, fl = step_extrusion(st, v, dt, p)
        assert fl.fed_mm - fl.out_mm == pytest.approx(st.compression_mm - x0, abs=1e-12)
        assert fl.out_mm >= -1e-15                    # no backflow [001 Fig. 8]
        assert fl.commanded_mm == pytest.approx(v * dt)
        assert 0.0 <= fl.grind_s <= dt + 1e-15
        assert st.compression_mm <= p.compliance_mm_per_n * p.max_feed_force_n + 1e-12
        regimes.add(("grind" if st.grinding else "feed", st.compression_mm < 0))
    assert {("grind", False), ("feed", False), ("feed", True)} <= regimes


def test_grinding_at_190c_and_full_speed_but_not_at_reduced_speed() -> None:
    # 0.3 mm layer at 190 °C: 2 mm/s needs more than the roller's maximum feed force
    # [000 §4] (nominal 82 N x (1 - s) > 38.5 N); the loop's ~60 % does not.
    p = step_params(GREEFF, temperature_c=190.0, layer_height_mm=0.3)
    op = operating_point(GREEFF, feed_mm_s=2.0, temperature_c=190.0, layer_height_mm=0.3)
    assert op.nominal_force_n * (1.0 - op.slip) > p.max_feed_force_n
    grind_s = 0.0
    st = ExtruderState()
    for _ in range(1000):
        st, fl = step_extrusion(st, 2.0, 0.01, p)
        grind_s += fl.grind_s
    assert grind_s > 1.0
    _, cmd, fed, _ = _run(p, 2.0, 5.0, state=st)
    assert 1.0 - fed / cmd > op.slip            # grinding loses more than steady slip
    st, _, _, _ = _run(p, 1.2, 10.0)
    assert not st.grinding
    assert st.compression_mm / p.compliance_mm_per_n < p.max_feed_force_n


def test_retraction_opens_a_gap_that_forward_feed_closes_without_output() -> None:
    p = step_params(GREEFF, temperature_c=230.0, layer_height_mm=0.3)
    st, _, _, _ = _run(p, 2.0, 2.0)
    st, fl = step_extrusion(st, -16.0, 1.0 / 16.0, p)   # 1 mm at 16 mm/s
    assert st.compression_mm < -0.9
    st, fl = step_extrusion(st, 16.0, 0.05, p)           # 0.8 mm forward: still a gap
    assert fl.out_mm == 0.0 and st.compression_mm < 0.0
    assert fl.fed_mm == pytest.approx(0.8)               # no force, slip = k_p = 0


def test_twin_at_100_percent_agrees_with_the_dynamics_integrator() -> None:
    # The twin steps the state equation; flowtwin simulate integrates it over the planned
    # feed. At 100 % and without heater lag both see the same commands; the twin averages
    # the commanded speed over 10 ms steps (the planner's ramps) and stops at the end of
    # the G-code, so totals agree to a few 0.1 %. Includes grinding at 190 °C.
    spec = PolygonSpec(temperature_sets=((1, 230.0), (1, 190.0), (1, 230.0)))
    g = polygon_gcode(spec).encode()
    sim = simulate(g, machine=GREEFF, pressure_advance=False)
    job = PrintJob.from_gcode(g, machine=GREEFF)
    r = JobRunner(job, GREEFF, start_s=0.0, heater_tau_s=0.0)
    r.advance_to(job.end_s + 1.0, lambda _t: Factors(100.0, 100.0))
    assert r.done
    tot, s = r.totals(), sim.dynamics.summary
    area = r.area_mm2
    assert tot.commanded_mm * area == pytest.approx(s.fed_cmd_mm3, rel=1e-9)
    assert tot.fed_mm * area == pytest.approx(s.fed_mm3, rel=5e-3)
    assert tot.out_mm * area == pytest.approx(s.out_mm3, rel=5e-3)
    assert tot.grind_s > 0.0 and s.grinding_moves > 0


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="lag_k_s"):
        StepParams(lag_k_s=0.0, compliance_mm_per_n=0.01)
    with pytest.raises(ValueError, match="bad step"):
        step_extrusion(ExtruderState(), math.nan, 0.01, StepParams(0.1, 0.01))


def test_without_slip_the_step_is_the_lag_primitive() -> None:
    # no slip, no force limit: the state equation is the lag with no backflow, which
    # flowtwin.physics.lag.lag_step solves (same closed forms, rounding apart)
    p = StepParams(lag_k_s=0.07, compliance_mm_per_n=0.015)
    rng = np.random.default_rng(17)
    st = ExtruderState()
    x = 0.0
    for _ in range(2000):
        v = float(rng.choice([3.0, 1.5, 0.0, -20.0, 20.0], p=[.35, .3, .15, .1, .1]))
        dt = float(rng.uniform(0.001, 0.08))
        st, fl = step_extrusion(st, v, dt, p)
        ref = lag_step(x, v, 0.0, dt, p.lag_k_s)
        x = ref.x_mm
        assert st.compression_mm == pytest.approx(x, abs=1e-14)
        assert fl.out_mm == pytest.approx(ref.out_mm, abs=1e-14)
        assert fl.fed_mm == pytest.approx(ref.fed_mm, abs=1e-14)
