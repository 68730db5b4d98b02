"""Greeff's print-job test part [003 §3.3] as flowtwin G-code, read back and planned."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.control.simulated.job import PrintJob, WaitMode
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.physics.deposition import bead_area_mm2
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles import load_machine
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec, polygon_gcode

GREEFF = load_machine("greeff2017")


@pytest.fixture(scope="module")
def planned() -> tuple[PolygonSpec, object]:
    spec = PolygonSpec()
    return spec, plan_gcode(polygon_gcode(spec).encode(), printer=GREEFF.printer)


def test_geometry_is_the_papers(planned) -> None:
    spec, plan = planned
    # [003 §3.3]: 40 sides of about 5.3 mm, 33 layers of 0.3 mm, 10 mm tall; 68 mm [Fig. 13]
    assert spec.side_mm == pytest.approx(5.3, abs=0.05)
    m = plan.table.moves
    wall = ((m["kind"] & MoveKind.EXTRUDE) != 0) & ((m["kind"] & MoveKind.XY) != 0) \
        & (m["layer"] >= 0)
    assert int(m["layer"].max()) + 1 == 33
    for layer in (0, 16, 32):
        sel = wall & (m["layer"] == layer)
        assert int(sel.sum()) == 40
        r = np.hypot(m["x"][sel] - spec.center_xy_mm[0], m["y"][sel] - spec.center_xy_mm[1])
        assert r == pytest.approx(34.0, abs=2e-3)             # vertices on the 68 mm circle
        assert m["z"][sel] == pytest.approx(0.3 * (layer + 1))
    assert float(m["z"][wall].max()) == pytest.approx(9.9)    # "10 mm tall"


def test_filament_speed_and_mass(planned) -> None:
    spec, plan = planned
    m, ph = plan.table.moves, plan.timeline.phases
    wall = ((m["kind"] & MoveKind.EXTRUDE) != 0) & ((m["kind"] & MoveKind.XY) != 0) \
        & (m["layer"] >= 0)
    length = np.hypot(np.diff(m["x"], prepend=np.nan), np.diff(m["y"], prepend=np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = m["de"] / length                               # filament per mm of wall
    fil_speed = ph["cruise_v"] * ratio
    # "first layer at a slower speed of 1 mm/s. The remainder ... 2 mm/s" [003 §3.3]
    assert fil_speed[wall & (m["layer"] == 0)] == pytest.approx(1.0, rel=1e-3)
    assert fil_speed[wall & (m["layer"] > 0)] == pytest.approx(2.0, rel=1e-3)
    area_fil = math.pi * 2.85 ** 2 / 4
    bead = float(bead_area_mm2(0.6, 0.3))
    assert ratio[wall] == pytest.approx(bead / area_fil, rel=2e-3)   # [001 Eq. 7]
    perimeter = 40 * spec.side_mm
    mass = 33 * perimeter * bead * GREEFF.material.density_g_mm3
    assert float(np.sum(m["de"][wall])) * area_fil * GREEFF.material.density_g_mm3 == \
        pytest.approx(mass, rel=1e-4)
    assert mass == pytest.approx(1.41, abs=0.01)


def test_temperature_sets_and_waits() -> None:
    job = PrintJob.from_gcode(polygon_gcode(PolygonSpec()).encode(), machine=GREEFF)
    changes = [(h.set_c, h.wait) for h in job.heater]
    assert changes == [(230.0, WaitMode.NONE), (230.0, WaitMode.HEAT),
                       (190.0, WaitMode.BOTH), (230.0, WaitMode.BOTH), (0.0, WaitMode.NONE)]
    # 11 layers at 230 °C, 11 at 190 °C, the rest at 230 °C [003 §3.3]
    tau_190, tau_230 = job.heater[2].tau_s, job.heater[3].tau_s
    assert job.layer_at(tau_190 - 1e-6) == 10 and job.layer_at(tau_190 + 0.5) == 11
    assert job.layer_at(tau_230 - 1e-6) == 21 and job.layer_at(tau_230 + 0.5) == 22
    assert job.layer_at(0.0) == -1                           # the extruder test line
    assert job.layer_height_at(tau_190 + 0.5) == pytest.approx(0.3)
    assert job.part_start_s > 0.0 and job.end_s > job.part_start_s


def test_shorter_part_and_bad_spec() -> None:
    short = PolygonSpec.greeff(layers_per_set=2)
    assert short.layers == 6 and short.layer_temperature_c(2) == 190.0
    with pytest.raises(GcodeError, match="line_width_mm"):
        PolygonSpec(line_width_mm=0.2)
    with pytest.raises(GcodeError, match="temperature_sets"):
        PolygonSpec(temperature_sets=((0, 230.0),))
    with pytest.raises(GcodeError, match="extrudes nothing"):
        PrintJob.from_gcode(b"G28\nG1 X10 Y10 F3000\n", machine=GREEFF)
