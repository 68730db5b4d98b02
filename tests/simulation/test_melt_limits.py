"""The melt model in the twin: steady extrusion, the maximum volumetric flow, the flags of
``simulate`` on the max-volumetric-speed pattern, and [003 Fig. 6]'s trends from physics."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path

import numpy as np
import pytest

from flowtwin.calibration.patterns.flow_rate import MaxFlowParams, maxflow_pattern
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.firmware import Firmware
from flowtwin.profiles import load_builtin, load_machine
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.simulation import simulate
from flowtwin.simulation.limits import flow_limit, flow_limit_table, steady_extrusion


def test_default_set_up_has_a_low_double_digit_limit() -> None:
    m = load_machine("tronvoll2019")
    lim = flow_limit(m)
    assert 10.0 <= lim.max_volumetric_flow_mm3_s <= 15.0
    assert lim.reason == "slip"
    assert lim.at_limit.delivered_ratio == pytest.approx(0.95, abs=1e-9)
    assert lim.at_limit.melt_temperature_c < 205.0          # the melt is what gave out
    iso = flow_limit(m, melt=False)
    assert iso.max_volumetric_flow_mm3_s > 2.0 * lim.max_volumetric_flow_mm3_s
    # printing on a bed adds the tip back-pressure: a lower limit
    assert flow_limit(m, layer_height_mm=0.2).max_volumetric_flow_mm3_s < \
        lim.max_volumetric_flow_mm3_s


def test_limit_rises_with_temperature() -> None:
    rows = flow_limit_table(load_machine("tronvoll2019"), [200.0, 215.0, 230.0])
    qs = [r.max_volumetric_flow_mm3_s for r in rows]
    assert all(b > a for a, b in itertools.pairwise(qs))


def test_without_a_melt_zone_the_melt_is_at_the_set_temperature() -> None:
    # greeff2017's RF1000 hot end has no melt zone in its profile: today's isothermal model
    m = load_machine("greeff2017")
    st = steady_extrusion(m, 12.0)
    assert st.melt_temperature_c == m.temperature_c
    assert flow_limit(m).melt_model is False


def test_slip_rises_as_temperature_falls_and_feed_rises_from_the_melt_physics() -> None:
    """[003 Fig. 6]: with the melt model, slip grows faster than the isothermal force law
    alone gives — the melt cools as the feed rises, the viscosity [002] and the force rise,
    and the drive slips more [000 Eq. 6]."""
    base = load_machine("greeff2017")
    v6 = load_builtin("e3d-v6-0.4")
    assert isinstance(v6, HotendProfile)
    hot = base.hotend.model_copy(update={"heated_length_mm": v6.heated_length_mm})
    m = dataclasses.replace(base, hotend=hot)
    area = m.filament.area_mm2
    temps = [230.0, 215.0, 200.0, 195.0]
    feeds = [1.0, 1.5, 2.0]          # mm/s of filament [003 §3.1]
    slip = np.array([[steady_extrusion(m, v * area, temperature_c=t).slip for t in temps]
                     for v in feeds])
    assert np.all(np.diff(slip, axis=1) > 0.0)    # colder → more slip
    assert np.all(np.diff(slip, axis=0) > 0.0)    # faster → more slip
    iso = np.array([[steady_extrusion(m, v * area, temperature_c=t, melt=False).slip
                     for t in temps] for v in feeds])
    assert np.all(slip >= iso)
    # the melt's share grows with the feed: convex in feed where the isothermal law is not
    gain = slip / iso
    assert np.all(np.diff(gain, axis=0) > 0.0)


def test_maxflow_pattern_shows_the_hot_ends_limit() -> None:
    """The project's max-volumetric-speed pattern (5–60 mm³/s) on ``tronvoll2019``: the
    lines above the limit are flagged and under-extrude; before the melt model the twin
    predicted 27 N peak force and no warning (issue #20)."""
    pattern = maxflow_pattern(PrintSettings(firmware=Firmware.MARLIN),
                              MaxFlowParams(flow_start_mm3_s=5.0, flow_end_mm3_s=60.0,
                                            flow_step_mm3_s=5.0))
    res = simulate(("\n".join(pattern.lines) + "\n").encode(), machine="tronvoll2019")
    p = res.parameters
    assert p.over_flow_limit is not None and p.flow_mm3_s is not None
    assert p.flow_limit_mm3_s is not None and p.melt_temperature_c is not None
    summary = res.summary()
    flagged = p.over_flow_limit
    assert summary.moves_over_flow_limit == int(np.count_nonzero(flagged)) > 0
    limit = p.flow_limit_mm3_s[flagged]
    assert np.all(p.flow_mm3_s[flagged] > limit)
    assert 6.0 < float(np.min(limit)) < 15.0          # low double digits (0.2 mm layers)
    ok = ~flagged & (p.flow_mm3_s > 1.0) & np.isfinite(p.flow_limit_mm3_s)
    assert np.all(p.flow_mm3_s[ok] <= p.flow_limit_mm3_s[ok])
    # the flagged lines under-extrude by more than 5 %; the melt cooled on the way
    err = res.metrics["flow_error"][flagged]
    assert float(np.mean(err)) < -0.05
    # the melt cooled on the way: once the pattern's first zone volume (~58 mm³) reaches the
    # nozzle the leaving melt falls line by line (plug residence, physics.melt_history)
    melt = p.melt_temperature_c[flagged]
    assert float(melt[-1]) < 210.0 and np.all(np.diff(melt) <= 1e-9)
    assert any("maximum volumetric flow" in w for w in summary.warnings)
    assert summary.max_feed_force_n > 27.3


def test_unretracted_filament_is_not_fed_cold_again() -> None:
    """Only filament beyond the furthest point fed so far is cold material (per tool)."""
    from flowtwin.simulation.parameters import fresh_filament_mm

    de = np.array([1.0, 2.0, -0.8, 0.8, 0.5, -1.0, 1.2, 0.3])
    fresh, below = fresh_filament_mm(de, np.zeros(8, np.int16))
    np.testing.assert_allclose(fresh, [1.0, 2.0, 0.0, 0.0, 0.5, 0.0, 0.2, 0.3])
    assert below == ((0, 0.0),)
    tools = np.array([0, 0, 1, 1, 0, 0, 1, 1], np.int16)  # tool 1 starts retracted
    fresh, below = fresh_filament_mm(de, tools)
    np.testing.assert_allclose(fresh, [1.0, 2.0, 0.0, 0.0, 0.5, 0.0, 1.2, 0.3])
    assert below == ((0, 1.0), (1, 0.0))
    # split anywhere, the carry gives the same
    for cut in range(1, 8):
        a, carry = fresh_filament_mm(de[:cut], tools[:cut])
        b, end = fresh_filament_mm(de[cut:], tools[cut:], retracted_mm=carry)
        np.testing.assert_allclose(np.concatenate((a, b)), fresh, atol=1e-12)
        assert dict(end) == pytest.approx(dict(below))


def test_retraction_pairs_do_not_cool_the_melt(tmp_path) -> None:
    """A retraction and its unretraction between printing moves move no cold filament
    into the melt zone: the printing moves' melt is no colder with them (the pause only
    lets it heat), and no unretraction is flagged over the flow limit."""
    moves = [f"G1 X{10 + 20 * (i % 2)} Y{10 + 2 * i} E{0.7:.3f} F2400" for i in range(40)]
    plain = ["G90", "M83", "M104 S215", "G1 Z0.2 F600", "G1 X10 Y10 F6000", *moves]
    with_pairs = plain[:5]
    for line in moves:
        with_pairs += [line, "G1 E-0.8 F2100", "G1 E0.8 F2100"]
    a, b = tmp_path / "plain.gcode", tmp_path / "pairs.gcode"
    a.write_text("\n".join(plain) + "\n")
    b.write_text("\n".join(with_pairs) + "\n")
    ra, rb = simulate(a), simulate(b)
    ta = ra.parameters.melt_temperature_c
    tb = rb.parameters.melt_temperature_c
    assert ta is not None and tb is not None
    def printing(r):  # XY moves that extrude
        m = r.plan.table.moves
        return np.flatnonzero(((m["kind"] & 8) != 0) & (m["de"] > 0))

    printing_a, printing_b = printing(ra), printing(rb)
    assert printing_a.size == printing_b.size == 39  # the first sits on the start point
    assert np.all(tb[printing_b] >= ta[printing_a] - 1e-9)
    assert rb.summary().moves_over_flow_limit == 0


def test_a_move_feeding_more_than_a_spool_is_refused_with_its_line(tmp_path: Path) -> None:
    """``make fuzz`` found a 5 kB file with ``E1e9`` moves (1000 km of filament) that the
    integrator would have followed for 4·10⁷ s of print time: refused with the line."""
    from flowtwin.errors import DataError
    from flowtwin.simulation import simulate
    from flowtwin.simulation.parameters import MAX_MOVE_FILAMENT_MM

    path = tmp_path / "huge.gcode"
    path.write_text("M83\nG1 X10 Y10 F3000\nG1 Z0.3 E1000000000 F1500\nG1 X20 E1 F1200\n")
    with pytest.raises(DataError, match=r"huge.gcode:3 \[E\].*1e\+09 mm of filament"):
        simulate(path, machine="tronvoll2019")
    path.write_text(f"M83\nG1 X10 Y10 F3000\nG1 E{MAX_MOVE_FILAMENT_MM:.0f} F6000\n")
    assert simulate(path, machine="tronvoll2019").summary().moves == 2
    # what the move feeds counts, its E times the M221 flow in force (a fuzzed Bambu start
    # G-code's "M221 S999999999" made its purge lines feed 150 km: 5 minutes of grinding
    # in the integrator, fuzz seed 20261129)
    path.write_text("M83\nM221 S999999999\nG1 X10 Y10 F3000\nG1 X240 E15 F6000\n")
    with pytest.raises(DataError, match=r"huge.gcode:4 \[E\].*1\.5e\+08 mm of filament "
                                        r"\(E 15 at M221 1e\+09 %\)"):
        simulate(path, machine="tronvoll2019")


def test_flow_flags_give_each_row_the_limit_of_its_own_temperature_and_height() -> None:
    """The limits are looked up once per distinct (temperature, layer height), found among
    runs of equal rows: every row must still get the limit computed for its own pair."""
    from flowtwin.simulation.limits import _limit_mm3_s, flow_flags

    m = load_machine("tronvoll2019")
    rng = np.random.default_rng(7)
    n = 3000
    # runs of repeated pairs, pairs coming back later, a temperature at the inlet, NaN heights
    temps = np.repeat(rng.choice([205.0, 215.2, 230.0, 25.0], size=60), 50)
    heights = np.repeat(rng.choice([0.2, 0.1, 0.28, np.nan], size=60), 50)
    temps[::7] = 215.0
    extruding = rng.random(n) > 0.2
    flow = rng.uniform(0.0, 40.0, n)
    got = flow_flags(m, flow, temps, extruding, heights)
    want = np.full(n, np.nan)
    for i in range(n):
        t = float(np.round(temps[i]))
        if extruding[i] and t > m.hotend.melt_inlet_temperature_c:
            h = float(np.round(heights[i], 2))
            want[i] = _limit_mm3_s(m, t, None if np.isnan(h) else h)
    np.testing.assert_array_equal(got.limit_mm3_s, want)
    np.testing.assert_array_equal(got.over, extruding & ~np.isnan(want)
                                  & (flow > np.where(np.isnan(want), np.inf, want)))
    assert 0 < got.count < n
