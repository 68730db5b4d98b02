"""Reliefs laid along their travels on Klipper: limits, geometry, and what they buy."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.relief import ALONG_LIMIT, along_ratio, insert_relief
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import simulate

CUP = Path(__file__).resolve().parents[1] / "data" / "cup"

#: Klipper's derived limits for a 0.4 mm nozzle, 1.75 mm filament, max_velocity 250,
#: max_accel 2500 (``kinematics/extruder.py``: ratio = 4·0.4²/(π·0.875²)).
_RATIO = 4 * 0.4 ** 2 / (math.pi * 0.875 ** 2)
KLIPPER = ExtruderLimits("klipper", jump_mm_s=1.0, max_ratio=_RATIO,
                         tiny_e_mm=0.4 * _RATIO, e_only_speed_mm_s=250 * _RATIO,
                         e_only_accel_mm_s2=2500 * _RATIO)


def test_the_ratio_keeps_the_travel_within_klippers_extrude_only_limits() -> None:
    # a travel at 150 mm/s, 2500 mm/s²: the acceleration binds (798·0.266/2500 …), and
    # the cross-section's ratio caps it; at 5000 mm/s² the acceleration alone
    r = along_ratio(np.array([150.0, 150.0, 250.0]), np.array([2500.0, 5000.0, 1000.0]),
                    KLIPPER)
    assert r[0] == pytest.approx(ALONG_LIMIT * _RATIO)
    assert r[1] == pytest.approx(ALONG_LIMIT * 2500 * _RATIO / 5000)
    assert r[2] == pytest.approx(ALONG_LIMIT * _RATIO)  # speed 250·r/250 and cross-section
    # Klipper's own rule: a retraction moving the head at ratio ρ is held to
    # e_only_speed/ρ and e_only_accel/ρ; at these ratios neither binds the travel
    assert KLIPPER.e_only_accel_mm_s2 / r[0] > 2500 and KLIPPER.e_only_speed_mm_s / r[0] > 150
    assert np.all(along_ratio(np.array([np.nan]), np.array([0.0]), KLIPPER) == 0.0)


def _pieces(points: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                        np.ndarray, np.ndarray, np.ndarray]:
    """One piece per row along ``points`` (row i ends at points[i + 1]), z = 0.2."""
    xyz = np.array([[x, y, 0.2] for x, y in points])
    end = xyz[1:]
    start = xyz[:-1]
    n = end.shape[0]
    return (np.arange(n, dtype=np.int64), end.copy(), np.zeros(n, dtype=np.int64),
            np.full(n, np.nan), start, end)


def test_insert_relief_lays_both_parts_on_the_path_within_the_ratio() -> None:
    # rows: 0 print, 1–3 a combing travel (0.3 mm, 8 mm, 0.2 mm), 4 print,
    # 5 a travel of 1 mm (too short at 0.24 mm of E per mm), 6 print
    pts = [(0, 0), (10, 0), (10.3, 0), (10.3, 8), (10.1, 8), (0, 8), (0, 9), (10, 9)]
    piece_of, xyz, e_piece, feed, start, end = _pieces(pts)
    e_piece[[0, 4, 6]] = 3000
    unit = 1e-4
    accel = np.full(7, 2500.0)
    speed = np.full(7, 150.0)
    travel = np.zeros(7, dtype=bool)
    travel[[1, 2, 3, 5]] = True
    reliefs = [(1, 3, 1500, 900), (5, 5, 1500, 900)]  # 0.15 mm back, 0.09 mm push
    rows, p, e, _f, laid = insert_relief(reliefs, piece_of, xyz, e_piece, feed, start, end,
                                        KLIPPER, along=(speed, accel, travel),
                                        e_unit_mm=unit)
    assert laid == 1
    assert np.all(np.diff(rows) >= 0) and set(rows.tolist()) == set(range(7))
    # the first interim: its E adds up to the relief, on its own rows, at ≤ ρ
    inter = (rows >= 1) & (rows <= 3)
    assert e[inter].sum() == -1500 + 900
    assert e[inter][0] < 0 and e[inter][-1] > 0
    prev = np.vstack((start[0][None, :], p[:-1]))
    length = np.linalg.norm(p - prev, axis=1)
    rho = ALONG_LIMIT * _RATIO
    assert np.all(np.abs(e[inter]) * unit <= rho * length[inter] * (1 + 1e-9) + 2 * unit)
    # every new point lies on its row's segment
    for k in np.flatnonzero(inter):
        a, b = start[rows[k]], end[rows[k]]
        t = np.dot(p[k] - a, b - a) / np.dot(b - a, b - a)
        assert -1e-9 <= t <= 1 + 1e-9
        assert np.allclose(a + t * (b - a), p[k])
    # the path of the retraction: 0.15 mm at ρ, laid over the 0.3 mm row and into the next
    back = np.cumsum(length[inter])[np.flatnonzero(np.cumsum(e[inter]) == -1500)[0]]
    assert back == pytest.approx(0.15 / rho, rel=1e-6)
    # the short travel gets E-only moves where it starts and ends (no XY in them)
    short = np.flatnonzero(rows == 5)
    assert e[short].tolist() == [-1500, 0, 900]
    assert np.allclose(p[short[0]], start[5]) and np.allclose(p[short[2]], end[5])
    # on Marlin, or without `along`, every relief is E-only
    marlin = ExtruderLimits("marlin", jump_mm_s=5.0, e_only_speed_mm_s=60.0)
    for lim, along in ((marlin, (speed, accel, travel)), (KLIPPER, None)):
        *_, n_laid = insert_relief(reliefs, piece_of, xyz, e_piece, feed, start, end, lim,
                                   along=along, e_unit_mm=unit)
        assert n_laid == 0


def _combing(path: Path) -> Path:
    """Short printing runs joined by unretracted G0 travels, as Cura combs inside a part
    (relative E, 0.2 mm layer, 0.45 mm lines, 120 mm/s)."""
    lines = ["G21", "G90", "M83", "M104 S215", "G28", "G1 Z0.2 F600",
             "G1 X20 Y20 F6000", "G1 X20 Y21 E0.05 F1800"]
    e_mm = 0.2 * 0.45 * 15 / (math.pi * 0.875 ** 2)
    for k in range(24):
        y = 21 + 2.0 * k
        x0, x1 = (20, 35) if k % 2 == 0 else (35, 20)
        lines.append(f"G1 X{x1} Y{y:.3f} E{e_mm:.5f} F7200")
        # a combing travel of two legs to the next run's start
        lines.append(f"G0 X{(x0 + x1) / 2:.3f} Y{y + 1.0:.3f} F9000")
        lines.append(f"G0 X{x1} Y{y + 2.0:.3f}")
        lines.append(f"G1 X{x1} Y{y + 2.0:.3f} F7200")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_along_on_klipper_is_faster_keeps_the_volume_and_the_flow(tmp_path: Path) -> None:
    src = _combing(tmp_path / "comb.gcode")
    setup, cfg = CUP / "klipper-volcano.toml", CUP / "printer.cfg"
    reports = {}
    for along in (True, False):
        out = tmp_path / f"out-{along}.gcode"
        reports[along] = compensate(src, out, machine=setup, klipper_config=cfg,
                                    advance=AdvanceOptions(relief_along=along))
    laid, e_only = reports[True], reports[False]
    first = laid.advance[0]
    assert first.relief_travels > 0 and first.relief_along == first.relief_travels
    assert e_only.advance[0].relief_along == 0
    # the same E commanded in total (the advance keeps the volume)
    assert laid.commanded_e_after_mm == pytest.approx(laid.commanded_e_before_mm, abs=1e-9)
    # the head no longer stands for two E-only moves per relief
    assert laid.time_after_s < e_only.time_after_s
    # and the melt is as well placed
    assert laid.after.rms_flow_error <= 1.05 * e_only.after.rms_flow_error
    assert laid.after.rms_flow_error < 0.5 * laid.before.rms_flow_error
    # Klipper takes the file as written: planned again from the text, the retractions
    # that move the head run at the travel's acceleration (not max_extrude_only_accel/ρ)
    res = simulate(tmp_path / "out-True.gcode", machine=setup, klipper_config=cfg)
    kind = np.asarray(res.plan.table.moves["kind"])
    feed = np.asarray(res.plan.table.moves["feed_mm_s"])
    # (printing pieces also pull back while the head slows down, at the printing feed)
    moving_back = (((kind & MoveKind.RETRACT) != 0) & ((kind & MoveKind.XY) != 0)
                   & (feed == 150.0))
    assert np.count_nonzero(moving_back) == first.relief_along
    accel = np.asarray(res.plan.timeline.phases["accel"])
    assert np.all(accel[moving_back] == pytest.approx(2500.0))
    de = np.asarray(res.plan.table.moves["de"])
    assert np.sum(de) == pytest.approx(np.sum(
        simulate(src, machine=setup, klipper_config=cfg).plan.table.moves["de"]), abs=1e-6)


def test_every_travel_row_keeps_its_piece_whatever_the_lengths() -> None:
    # a 16 mm Cura combing travel of 11 legs lost its last leg: the path's total, summed
    # pairwise, came out one ulp below its running sum (check3's Cura hook); random legs
    # from 0.006 to 8 mm, 1 to 12 of them, at several retractions
    rng = np.random.default_rng(20261128)
    unit = 1e-5
    for _ in range(300):
        legs = int(rng.integers(1, 13))
        angles = rng.uniform(0, 2 * np.pi, legs)
        lengths = np.exp(rng.uniform(np.log(0.006), np.log(8.0), legs))
        pts = [(0.0, 0.0), (10.0, 0.0)]
        for t, d in zip(angles, lengths, strict=True):
            x, y = pts[-1]
            pts.append((x + d * np.cos(t), y + d * np.sin(t)))
        pts.append((pts[-1][0] + 5, pts[-1][1]))
        piece_of, xyz, e_piece, feed, start, end = _pieces(pts)
        n = piece_of.size
        e_piece[[0, n - 1]] = 30000
        travel = np.ones(n, dtype=bool)
        travel[[0, n - 1]] = False
        ret = int(rng.integers(100, 40000))
        relief = [(1, n - 2, ret, int(ret * rng.uniform(0.2, 1.0)))]
        rows, p, e, _f, laid = insert_relief(
            relief, piece_of, xyz, e_piece, feed, start, end, KLIPPER,
            along=(np.full(n, 150.0), np.full(n, 2500.0), travel), e_unit_mm=unit)
        assert rows.tolist() == sorted(rows.tolist())
        assert set(rows.tolist()) == set(range(n))
        assert np.allclose(p[np.r_[np.flatnonzero(np.diff(rows)), rows.size - 1]], end)
        assert e.sum() == e_piece.sum() - relief[0][2] + relief[0][3]
        if laid:  # the parts stay within the ratio on every piece but the rounding
            prev = np.vstack((start[0][None, :], p[:-1]))
            length = np.linalg.norm(p - prev, axis=1)
            inter = (rows >= 1) & (rows <= n - 2)
            assert np.all(np.abs(e[inter]) * unit
                          <= ALONG_LIMIT * _RATIO * length[inter] + 2 * unit)

