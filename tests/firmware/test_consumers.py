"""Every consumer of the firmware model handles every firmware.

Parametrised over :class:`flowtwin.firmware.Firmware`: adding a member runs each check
below for it. The consumers: planner selection (:func:`flowtwin.planner.plan_file.plan_gcode`), the
dynamics' pressure advance, the advance command written and read back, the calibration
patterns, the closed loop's multiplier commands and the twin's firmware-settings files.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from flowtwin.calibration import PrintSettings, generate_pattern
from flowtwin.calibration.tuning.advance_settings import best_pressure_advance, pa_test_gcode
from flowtwin.control.loop.clock import SimClock
from flowtwin.control.printer import FactorTracker
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.dynamics import (
    AdvanceSettings,
    advance_schedule,
    apply_advance,
    nominal_feed,
    printer_advance,
)
from flowtwin.errors import FlowtwinError
from flowtwin.firmware import (
    PA_CODES,
    AdvanceAlgorithm,
    Channel,
    Firmware,
    PlannerFamily,
    accel_command,
    applied_percent,
    encode_factor,
    pa_command,
    read_factor_command,
)
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import KlipperSettings
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles import PrinterProfile, load_builtin
from flowtwin.profiles.machine import load_machine

ALL = list(Firmware)
IDS = [f.value for f in ALL]

#: a print line slow -> fast -> slow, with steps of the extrusion ratio between moves at
#: speed (RRF does not advance those steps, Marlin's tracking does) and a pause
LINE = b"""G21
G90
M83
G92 E0
G1 Z0.2 F600
G1 X10 Y10 F6000
G1 E0.5 F1200
G1 X20 Y10 E0.4 F1200
G1 X60 Y10 E2.4 F6000
G1 X70 Y10 E0.3 F6000
G1 X70 Y12 F6000
G1 X20 Y12 E2.0 F3000
G1 X10 Y12 E0.6 F3000
"""


def printer_for(fw: Firmware) -> PrinterProfile:
    """A built-in printer of ``fw``'s planner family, described as ``fw``."""
    base = load_builtin("generic-klipper" if fw.planner is PlannerFamily.KLIPPER
                        else "generic-marlin", "printer")
    assert isinstance(base, PrinterProfile)
    data = base.model_dump(mode="json", exclude_none=True)
    data.update(firmware=fw.value, name=f"generic-{fw.value}")
    return PrinterProfile.model_validate(data)


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_profiles_take_every_firmware_and_planning_selects_its_planner(fw: Firmware) -> None:
    printer = printer_for(fw)
    assert printer.firmware is fw
    plan = plan_gcode(LINE, printer=printer)
    assert plan.timeline.firmware == fw.planner.value
    assert isinstance(plan.settings, KlipperSettings) == (fw.planner is PlannerFamily.KLIPPER)
    assert plan.timeline.total_time_s > 0


def _advanced_feed(fw: Firmware, k_s: float = 0.05) -> np.ndarray:
    table = read_gcode(LINE)
    ks = KlipperSettings(max_velocity=300.0, max_accel=2000.0)
    feed = nominal_feed(table, plan_klipper(table, ks))
    adv = apply_advance(feed, table, AdvanceSettings(fw, k_s=k_s, smooth_time_s=0.04))
    assert adv.advance == fw.value
    t = np.linspace(feed.t_begin_s, feed.t_end_s, 400)
    seg = np.clip(np.searchsorted(adv.t0_s, t, side="right") - 1, 0, adv.n_segments - 1)
    dt = t - adv.t0_s[seg]
    c = adv.coef[seg]
    return adv.e0_mm[seg] + dt * (c[:, 0] + dt * (c[:, 1] / 2 + dt * (c[:, 2] / 3
                                                                     + dt * c[:, 3] / 4)))


def test_each_firmware_gets_the_advance_algorithm_of_its_row() -> None:
    # commanded position over time: equal for two firmwares iff they share the algorithm
    curves = {fw: _advanced_feed(fw) for fw in ALL}
    for a, b in itertools.combinations(ALL, 2):
        same = np.allclose(curves[a], curves[b], rtol=0, atol=1e-12)
        assert same == (a.advance is b.advance), (a, b)
    assert {fw.advance for fw in ALL} == set(AdvanceAlgorithm)


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_profile_advance_names_the_printer_firmware(fw: Firmware) -> None:
    adv = printer_advance(printer_for(fw))
    assert adv.firmware is fw
    assert adv.smooth_time_s == pytest.approx(0.04)


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_advance_command_round_trip_through_the_dynamics(fw: Firmware) -> None:
    # the firmware's own command, read back by the reader, sets K for the dynamics; every
    # other firmware's command word is ignored with a warning
    own = pa_command(fw, 0.0375)
    table = read_gcode(f"M83\n{own}\nG1 X10 Y0 E0.5 F1200\n".encode())
    sched = advance_schedule(table, AdvanceSettings(fw))
    assert sched.applied == 1 and sched.k_s.tolist() == [0.0375]
    for other in PA_CODES - {fw.pa_syntax.code}:
        foreign = pa_command(next(f for f in ALL if f.pa_syntax.code == other), 0.0375)
        table = read_gcode(f"M83\n{foreign}\nG1 X10 Y0 E0.5 F1200\n".encode())
        sched = advance_schedule(table, AdvanceSettings(fw))
        assert sched.applied == 0 and sched.k_s.tolist() == [0.0]
        assert f"not a {fw.value} pressure-advance command" in sched.warnings[-1]


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_calibration_patterns_speak_the_firmware(fw: Firmware) -> None:
    settings = PrintSettings(firmware=fw, accel_mm_s2=2000.0)
    pattern = generate_pattern("kline", settings, {"k_end": 0.02, "k_step": 0.01})
    assert f"; firmware = {fw.value}" in pattern.lines
    assert accel_command(fw, 2000.0) in pattern.lines
    table = read_gcode(pattern.text().encode())
    assert table.unknown_commands == {}
    pa = [ev for ev in table.events if ev.code in PA_CODES]
    assert [ev.code for ev in pa] == [fw.pa_syntax.code] * 3
    assert [ev.line for ev in pa] == [p.line for p in pattern.pa_settings]
    sched = advance_schedule(table, AdvanceSettings(fw))
    assert sched.applied == 3 and max(sched.k_s) == pytest.approx(0.02)


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_control_multipliers_are_encoded_or_refused(fw: Firmware) -> None:
    if fw.factor_decimals is None:
        for make in (lambda: encode_factor(fw, Channel.FLOW, 95.5),
                     lambda: FactorTracker(fw), lambda: TwinPrinter(SimClock(), firmware=fw)):
            with pytest.raises(FlowtwinError, match="does not model the M220/M221"):
                make()
        return
    text = encode_factor(fw, Channel.FLOW, 95.5)
    assert read_factor_command(text) == (Channel.FLOW, applied_percent(fw, 95.5))
    twin = TwinPrinter(SimClock(), firmware=fw)
    twin.connect()
    assert twin.set_flow_factor(95.5).ok
    assert twin.read_factors().flow_pct == applied_percent(fw, 95.5)


@pytest.mark.parametrize("fw", ALL, ids=IDS)
def test_firmware_settings_files(fw: Firmware) -> None:
    machine = dataclasses.replace(load_machine("tronvoll2019"), printer=printer_for(fw))
    text = pa_test_gcode(machine, flow_mm3_s=6.0, accel_mm_s2=2500.0, firmware=fw)
    assert accel_command(fw, 2500.0) in text.splitlines()
    assert read_gcode(text.encode()).unknown_commands == {}
    fit = best_pressure_advance(text.encode(), machine=machine, grid=3)
    assert fit.firmware == fw.value
    assert fit.command == pa_command(fw, fit.k_s)
    assert fw.label in fit.explanation or fw.advance is AdvanceAlgorithm.LINEAR_ADVANCE
