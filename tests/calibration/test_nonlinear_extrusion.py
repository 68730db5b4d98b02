"""The twin's slip law as M592 nonlinear-extrusion settings (Marlin, RepRapFirmware), and
Klipper's lack of one; checked by simulating a print with the settings applied against the
slip baked into the G-code."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.calibration.tuning.nonlinear_extrusion import (
    NonlinearExtrusionFit,
    apply_nonlinear_extrusion,
    fit_nonlinear_extrusion,
    m592_command,
    slip_multiplier,
)
from flowtwin.compensation import compensate
from flowtwin.compensation.metrics import flow_figures
from flowtwin.errors import DataError, ProfileError
from flowtwin.firmware import Firmware
from flowtwin.firmware.nonlinear import NonlinearFormula, nonlinear_formula
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.planner.plan_file import PlanResult
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.simulation import SimulationResult, simulate, simulate_plan


@pytest.fixture(scope="module")
def machine() -> Machine:
    return load_machine("tronvoll2019")


def test_multiplier_delivers_the_requested_speed(machine: Machine) -> None:
    """``v·m(v)·(1 − s(v·m(v))) = v``: the commanded speed, less the slip at it, is the
    requested one."""
    from flowtwin.simulation.parameters import operating_point

    v = np.array([0.5, 3.0, 12.0])
    m = slip_multiplier(machine, v)
    for vi, mi in zip(v, m, strict=True):
        s = operating_point(machine, feed_mm_s=vi * mi,
                            layer_height_mm=machine.setup.layer_height_mm).slip
        assert vi * mi * (1.0 - s) == pytest.approx(vi, rel=1e-9)
    assert np.all(np.diff(m) > 0) and m[0] > 1.0  # slip grows with the feed force


@pytest.mark.parametrize("firmware", ["marlin", "reprapfirmware"])
def test_fit_is_within_its_stated_residual(machine: Machine, firmware: str) -> None:
    fit = fit_nonlinear_extrusion(machine, firmware)
    v = np.linspace(fit.feed_min_mm_s, fit.feed_max_mm_s, 301)
    target = slip_multiplier(machine, v)
    if firmware == "reprapfirmware":
        target = target / fit.offset  # the constant part is the flow's
    rel = np.abs(fit.multiplier(v) / target - 1.0)
    assert float(np.max(rel)) <= fit.max_residual * 1.2 + 1e-9  # finer grid than the fit's
    assert fit.max_residual < 0.01 and fit.rms_residual < 0.005
    assert fit.feed_max_mm_s > 5.0  # covers what a hot end of this size is printed at
    assert fit.command is not None and fit.command.startswith("M592 ")


def test_firmware_formulas_and_commands() -> None:
    marlin = NonlinearExtrusionFit(Firmware.MARLIN, 0.001, 0.01, 1.02, None, 0.2, 10.0, 1.02, 0.0,
                                   0.0, None, "")
    # C + max(A·v² + B·v, 0) [Marlin Stepper::calc_nonlinear_e]
    assert float(marlin.multiplier(5.0)) == pytest.approx(1.02 + 0.025 + 0.05)
    assert m592_command(marlin) == "M592 S1 A0.001 B0.01 C1.02"
    rrf = NonlinearExtrusionFit(Firmware.REPRAPFIRMWARE, 0.01, 0.001, 1.0, 0.2, 0.2, 10.0, 1.0, 0.0,
                                0.0, None, "")
    # 1 + min(A·v + B·v², L) [RRF DDA::Prepare]
    assert float(rrf.multiplier(5.0)) == pytest.approx(1.0 + 0.05 + 0.025)
    assert float(rrf.multiplier(100.0)) == pytest.approx(1.2)
    assert m592_command(rrf) == "M592 D0 A0.01 B0.001 L0.2"


@pytest.mark.parametrize("firmware", list(Firmware), ids=[f.value for f in Firmware])
def test_every_firmware_gets_settings_or_the_baked_slip(machine: Machine,
                                                        firmware: Firmware) -> None:
    """Marlin and RRF get an M592; the others (Klipper among them) have none, and the fit
    says so and points to the baked slip."""
    fit = fit_nonlinear_extrusion(machine, firmware)
    assert fit.firmware is firmware
    if nonlinear_formula(firmware) is NonlinearFormula.NONE:
        assert fit.command is None and "--slip" in fit.note
        assert fit.max_residual > 0.1  # the slip left uncorrected without any setting
    else:
        assert fit.command is not None and fit.command.startswith("M592 ")
        assert fit.max_residual < 0.01


def test_bad_requests_are_refused(machine: Machine) -> None:
    with pytest.raises(ProfileError, match="firmware"):
        fit_nonlinear_extrusion(machine, "smoothie")
    with pytest.raises(DataError, match="feed range"):
        fit_nonlinear_extrusion(machine, "marlin", feed_max_mm_s=0.1)


def _volume_error(sim: SimulationResult, original: SimulationResult) -> float:
    d, o = sim.dynamics.moves, original.dynamics.moves
    return float(np.sum(d["out_mm3"] + d["stop_out_mm3"]) / np.sum(o["cmd_mm3"]) - 1.0)


@pytest.mark.parametrize("firmware", ["marlin", "reprapfirmware"])
def test_settings_deliver_like_the_baked_slip(machine: Machine, firmware: str,
                                              tmp_path: Path) -> None:
    """The built-in print with the fitted M592 executed by the firmware's formula, and
    with the slip baked into its E words (``compensate --slip``): both deliver the
    intended volume (the uncorrected print loses 1.5 % to slip) and the same flow error."""
    src = tmp_path / "print.gcode"
    write_print(src, PrintSpec())
    original = simulate(src, machine=machine, pressure_advance=False)
    out = tmp_path / "slip.gcode"
    compensate(src, out, machine=machine, slip=True, firmware_pressure_advance=False)
    baked = simulate(out, machine=machine, pressure_advance=False)
    fit = fit_nonlinear_extrusion(machine, firmware)
    table = apply_nonlinear_extrusion(original.plan.table, original.plan.timeline, fit)
    plan = PlanResult(table, original.plan.timeline, original.plan.printer,
                      original.plan.settings)
    applied = simulate_plan(plan, machine=machine, pressure_advance=False)
    before = _volume_error(original, original)
    assert before < -0.01  # a real loss to correct
    for sim in (baked, applied):
        assert abs(_volume_error(sim, original)) <= 0.3 * abs(before)
    assert abs(_volume_error(applied, original) - _volume_error(baked, original)) < 0.01
    rows = np.arange(len(table))
    rms_applied = flow_figures(original, applied, rows).rms_flow_error
    rms_baked = flow_figures(original, baked, rows).rms_flow_error
    assert rms_applied <= 1.05 * rms_baked
    assert rms_applied < original.summary().rms_flow_error
