"""Flow pacing: the paced speeds against the analytic envelopes, volume kept, and the twin.

The law (``flowtwin.compensation.pace``): with the lag ``K·Q̇ = v_in − Q`` [001 Eq. 15]
and ``v_in ≥ 0`` the outflow decays at best as ``exp(−t/K)``; a paced fall keeps
``d ln Q/dt ≥ −m/K``, which for a constant cross-section is a speed falling linearly in
distance, ``v(d) = v_J + (m/K)·d`` — equivalently ``v(τ) = v_J·exp(m·τ/K)`` in the time
``τ`` left to the junction. The tests check the staircase the pacing writes against that
closed form, on G-code generated here.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.original import read_original
from flowtwin.compensation.pace import (
    PaceOptions,
    drop_envelope,
    pace_feeds,
    rise_envelope,
    staircase,
    step_speed_mm_s,
)
from flowtwin.compensation.stages import printing_pieces
from flowtwin.errors import ProfileError
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.from_profile import read_options
from flowtwin.profiles.machine import load_machine
from flowtwin.simulation import DEFAULT_MACHINE, SimulationResult, simulate

FIL_AREA = math.pi * 1.75 ** 2 / 4.0
BEAD = 0.45 * 0.2 - 0.2 ** 2 * (1.0 - math.pi / 4.0)  # slicer bead [001 Eq. 7], mm²


def _header() -> list[str]:
    return ["G21", "G90", "M83", "M104 S215", "M109 S215", "G28", "G92 E0",
            ";LAYER_CHANGE", ";Z:0.2", ";HEIGHT:0.2", "G1 Z0.2 F600",
            "G1 X60 Y60 F9000"]


def _line(x: float, y: float, length: float, share: float, feed: float) -> str:
    return f"G1 X{x:.3f} Y{y:.3f} E{BEAD * share * length / FIL_AREA:.5f} F{feed:g}"


def step_drop_gcode(path: Path, *, feed: float = 3000.0) -> None:
    """One long line at full cross-section, then a long line at a fifth of it (a step drop
    of the cross-section at one junction, no corner: the planner keeps the speed)."""
    lines = _header()
    lines.append(_line(100.0, 60.0, 40.0, 1.0, feed))
    lines.append(_line(140.0, 60.0, 40.0, 0.2, feed))
    lines += ["G1 E-0.8 F2100", "M104 S0"]
    path.write_text("\n".join(lines) + "\n")


def ramp_gcode(path: Path, *, feed: float = 3000.0) -> None:
    """A wall whose cross-section falls from 1 to 0.5 in five 0.08 mm steps (variable-width
    walls), then runs on at half width: each junction alone drops less than 1.25×."""
    lines = _header()
    x = 100.0
    lines.append(_line(x, 60.0, 40.0, 1.0, feed))
    for share in (0.87, 0.76, 0.66, 0.57, 0.5):
        x += 0.08
        lines.append(_line(x, 60.0, 0.08, share, feed))
    lines.append(_line(x + 30.0, 60.0, 30.0, 0.5, feed))
    lines += ["G1 E-0.8 F2100", "M104 S0"]
    path.write_text("\n".join(lines) + "\n")


def purge_gcode(path: Path, *, blob_e: float) -> None:
    """ideaMaker's start (ideamaker_5.1.4 lines 37-63 in small): an 80 mm purge line at
    F200, a blob of ``blob_e`` mm of filament on the Z move up, a retraction held over the
    travel, the push-back, then a skirt circle at a third of the purge's cross-section in
    0.8 mm chords at F900. Line numbers: purge 13, blob 14, skirt from 19."""
    lines = [*_header()[:-1], "G1 X60 Y20 F9000",
             f"G1 X140 Y20 E{0.325 * 80.0 / FIL_AREA:.5f} F200",
             f"G1 Z5 E{blob_e:.5f} F200", "G1 E-0.5 F2400",
             "G0 X100 Y100 F9000", "G0 Z0.2 F300", "G1 E0.5 F1500"]
    r, chords = 20.0, 150
    step_e = 0.113 * 2.0 * math.pi * r / chords / FIL_AREA
    for i in range(1, chords + 1):
        t = 2.0 * math.pi * i / chords
        lines.append(f"G1 X{80.0 + r * math.cos(t):.3f} Y{100.0 + r * math.sin(t):.3f} "
                     f"E{step_e:.5f} F900")
    lines += ["G1 E-0.8 F2100", "M104 S0"]
    path.write_text("\n".join(lines) + "\n")


def _draft(path: Path) -> tuple[Draft, SimulationResult, float]:
    m = load_machine(DEFAULT_MACHINE)
    sim = simulate(path, machine=m, pressure_advance=False)
    table = sim.plan.table
    orig = read_original(path, table, home_xyz=read_options(m.printer).home_xyz)
    return Draft.identity(orig, table), sim, orig.e_unit


def _pace(draft: Draft, sim: SimulationResult, options: PaceOptions,
          push: float = math.inf, only: np.ndarray | None = None,
          no_pull: np.ndarray | None = None) -> tuple[Draft, object]:
    ph = sim.plan.timeline.phases
    length = np.linalg.norm(draft.xyz_mm - draft.start_xyz(), axis=1)
    cmd = sim.dynamics.moves["cmd_mm3"]
    area = np.where(length > 0, cmd / np.where(length > 0, length, 1.0), 0.0)
    return pace_feeds(draft, printing=printing_pieces(sim, draft), cross_section_mm2=area,
                      lag_k_s=sim.parameters.params.lag_k_s, volume_mm3=cmd,
                      start_v_mm_s=ph["start_v"],
                      cruise_v_mm_s=ph["cruise_v"], end_v_mm_s=ph["end_v"],
                      t_start_s=ph["t_start"], t_end_s=sim.plan.timeline.end_time_s,
                      speed_factor=np.ones(len(draft)), push_mm3_s=push, options=options,
                      only=only, no_pull=no_pull)


def test_step_speed_and_envelopes_are_their_closed_forms() -> None:
    # rho = e, K = 0.1 s, 1 mm to adjust: v = 1 / (0.1 * 1) = 10 mm/s; no step: no cap
    v = step_speed_mm_s(np.array([math.e, 1.0, 0.2]), np.array([1.0, 1.0, 0.2 * math.e]),
                        np.array([0.1, 0.1, 0.2]), adjust_mm=1.0)
    assert v[0] == pytest.approx(10.0, rel=1e-12)
    assert math.isinf(v[1])
    assert v[2] == pytest.approx(5.0, rel=1e-12)  # rising steps are capped alike
    d = np.linspace(0.0, 30.0, 31)
    env = drop_envelope(5.0, 0.1, d, margin=0.8)
    # time left to the junction along v(d): tau = (K/m) ln(v/v_J) -> v = v_J exp(m tau/K)
    tau = np.array([np.trapezoid(1.0 / drop_envelope(5.0, 0.1, np.linspace(0, x, 20001),
                                                     margin=0.8), np.linspace(0, x, 20001))
                    for x in d])
    # trapezoid error ~h², h = 1.5e-3 mm
    assert np.allclose(env, 5.0 * np.exp(0.8 * tau / 0.1), rtol=1e-5)
    rise = rise_envelope(2.0, 400.0, d)
    assert np.allclose(rise ** 2 - 4.0, 800.0 * d)


def test_staircase_stays_under_both_envelopes() -> None:
    length, v_plan, v_end, g, v0, acc = 30.0, 60.0, 4.0, 8.0, 3.0, 300.0
    for min_piece in (0.001, 0.1):
        ends, speeds = staircase(length, v_plan, end_v_mm_s=v_end, end_slope_1_s=g,
                                 start_v_mm_s=v0, start_accel_mm_s2=acc, step_ratio=1.3,
                                 min_piece_mm=min_piece, floor_mm_s=1.0)
        assert ends[-1] == length
        assert all(b > a for a, b in itertools.pairwise(ends))
        starts = [0.0, *ends[:-1]]
        for s0, s1, v in zip(starts, ends, speeds, strict=True):
            assert v <= v_plan
            assert v <= v_end + g * (length - s1) + 1e-9  # drop bound: lowest at the end
            assert v <= math.sqrt(v0 ** 2 + 2 * acc * s0) + 1e-9  # rise bound: at the start
            assert s1 - s0 >= min_piece - 1e-12
        assert max(speeds) == v_plan  # the middle runs at the planned speed
        if min_piece > 0.01:
            continue  # merged short stairs are slower than needed; tightness on fine stairs
        # tight: each stair is within a step ratio of the envelope at its far end
        for s0, s1, v in zip(starts, ends, speeds, strict=True):
            bound = min(v_plan, v_end + g * (length - s0), math.sqrt(v0 ** 2 + 2 * acc * s1))
            assert v * 1.3 >= bound * (1 - 1e-9)
        ratios = np.array(speeds[1:]) / np.array(speeds[:-1])
        assert np.all((ratios <= 1.3 + 1e-9) & (ratios >= 1 / 1.3 - 1e-9))


def test_paced_step_drop_meets_the_exponential_bound(tmp_path: Path) -> None:
    """A step drop of the cross-section (×0.2) at a straight junction: the stretch before
    it is paced so that its flow decays no faster than exp(−m·τ/K) towards the capped
    junction speed ``adjust/(K·ln 5)``, and every piece keeps E in proportion to length."""
    src = tmp_path / "step.gcode"
    step_drop_gcode(src)
    draft, sim, e_unit = _draft(src)
    opts = PaceOptions(rise=False, run_ends=False, pull_ratio=0.0)
    paced, report = _pace(draft, sim, opts)
    assert report.drop_junctions == 1 and report.step_junctions == 1  # type: ignore[attr-defined]
    first = int(np.flatnonzero(sim.dynamics.moves["cmd_mm3"] > 0)[0])
    sub = np.flatnonzero(paced.row == draft.row[first])
    assert sub.size > 5
    k = float(sim.parameters.params.lag_k_s[first])
    v_cap = opts.adjust_mm / (k * math.log(5.0))
    start = paced.start_xyz()[sub]
    lengths = np.linalg.norm(paced.xyz_mm[sub] - start, axis=1)
    feed = paced.piece_feed_mm_min[sub] / 60.0
    speed = np.where(np.isfinite(feed), feed, sim.plan.timeline.phases["cruise_v"][first])
    # time left to the junction at the end of each sub-piece, along the staircase itself
    tau_end = np.concatenate((np.cumsum((lengths / speed)[::-1])[::-1][1:], [0.0]))
    v_junction = speed[-1]
    assert v_junction == pytest.approx(max(v_cap, opts.min_speed_mm_s), rel=1e-3)
    bound = v_junction * np.exp(opts.margin * tau_end / k)
    assert np.all(speed <= bound * (1 + 1e-9))
    # and it is the envelope (no needless slowdown): within a step ratio where paced
    paced_part = np.isfinite(feed)
    assert np.all(speed[paced_part] * opts.step_ratio ** 2 >= bound[paced_part])
    # E in proportion to length on the E grid, total exact
    e = paced.e_grid[sub]
    assert int(e.sum()) == int(draft.e_grid[first])
    assert np.all(np.abs(e - draft.e_grid[first] * lengths / lengths.sum()) <= 1.0)
    out = tmp_path / "paced.gcode"
    paced.render(out)
    de0 = read_gcode(src).moves["de"]
    de1 = read_gcode(out).moves["de"]
    assert abs(de1.sum() - de0.sum()) <= 1e-9 * de0.sum()
    assert e_unit > 0


def test_a_cross_section_ramp_is_paced_as_one_step(tmp_path: Path) -> None:
    """Five small steps (each < ``min_step``) within ``adjust_mm`` are one step of 2×: the
    last junction of the ramp is capped at ``adjust/(K·ln ρ)`` with ``ρ`` the largest
    cross-section within ``adjust_mm`` before it over the one after it."""
    src = tmp_path / "ramp.gcode"
    ramp_gcode(src)
    draft, sim, _ = _draft(src)
    opts = PaceOptions(rise=False, run_ends=False, pull_ratio=0.0)
    paced, report = _pace(draft, sim, opts)
    assert report.step_junctions >= 1  # type: ignore[attr-defined]
    cmd = sim.dynamics.moves["cmd_mm3"]
    length = np.linalg.norm(draft.xyz_mm - draft.start_xyz(), axis=1)
    ext = np.flatnonzero(cmd > 0)
    a = cmd[ext] / length[ext]
    last_step = ext[-2]  # the last ramp piece, before the half-width run
    k = float(sim.parameters.params.lag_k_s[last_step])
    back = np.cumsum(length[ext][-2::-1])  # path back from the junction
    window = a[-2::-1][back - length[ext][-2::-1] < opts.adjust_mm]
    rho = float(window.max() / a[-1])
    assert 1.8 < rho < 2.2 and np.all(a[1:-1] / a[2:] < opts.min_step)
    cap = opts.adjust_mm / (k * math.log(rho))
    sub = np.flatnonzero(paced.row == draft.row[last_step])
    v_end = paced.piece_feed_mm_min[sub[-1]] / 60.0
    assert v_end == pytest.approx(max(cap, opts.min_speed_mm_s), rel=1e-3)


def test_pace_never_raises_a_speed_and_keeps_the_volume(thin_gcode: Path,
                                                        tmp_path: Path) -> None:
    src = thin_gcode
    draft, sim, _ = _draft(src)
    paced, report = _pace(draft, sim, PaceOptions(), push=FIL_AREA * 2.5)
    assert report.paced_rows.size > 0  # type: ignore[attr-defined]
    feeds = paced.piece_feed_mm_min
    requested = sim.plan.table.moves["feed_mm_s"][paced.row] * 60.0
    own = np.isfinite(feeds)
    assert np.all(feeds[own] <= requested[own] + 1e-6)
    assert np.all(feeds[own] >= 60.0 * PaceOptions().min_speed_mm_s - 1e-6)
    assert np.array_equal(np.bincount(paced.row, weights=paced.e_grid,
                                      minlength=draft.n_rows),
                          np.bincount(draft.row, weights=draft.e_grid, minlength=draft.n_rows))
    out = tmp_path / "paced.gcode"
    paced.render(out)
    resim = simulate(out, pressure_advance=False)
    assert resim.plan.timeline.total_time_s > sim.plan.timeline.total_time_s
    assert np.all(resim.plan.timeline.phases["cruise_v"]
                  <= sim.plan.timeline.phases["cruise_v"][paced.row] * (1 + 1e-9))


def test_no_paced_piece_prints_nothing(tmp_path: Path) -> None:
    """A run end with 300 E grid units over 40 mm is cut into a staircase; with 3 units it
    cannot be without pieces of zero E (they would become travels), so it is left whole."""
    for e_word, cut in (("0.00300", True), ("0.00003", False)):
        src = tmp_path / "tiny.gcode"
        lines = _header()
        lines += [_line(100.0, 60.0, 40.0, 1.0, 3000.0), f"G1 X140 Y60 E{e_word} F3000",
                  "G1 E-0.8 F2100", "M104 S0"]
        src.write_text("\n".join(lines) + "\n")
        draft, sim, _ = _draft(src)
        paced, _report = _pace(draft, sim, PaceOptions(rise=False))
        tiny = int(np.flatnonzero(draft.e_grid == int(round(float(e_word) * 1e5)))[0])
        assert (np.count_nonzero(paced.row == draft.row[tiny]) > 1) == cut
        printing = paced.e_grid[np.isin(paced.row, draft.row[draft.e_grid > 0])]
        assert np.all(printing > 0)


def test_pacing_and_advance_fix_thin_transitions(thin_gcode: Path, tmp_path: Path) -> None:
    """A thin transition move between two full-speed walls dumps the stored volume K·Q:
    the advance with E above zero cannot take it out, pacing first lets it, and so does
    the advance pulling back while the head slows down (``retract_ratio``)."""
    src = thin_gcode
    no_pull = compensate(src, tmp_path / "no-pull.gcode",
                         advance=AdvanceOptions(retract_ratio=0.0))
    plain = compensate(src, tmp_path / "plain.gcode", advance=True)
    # the pacing's physics, without the time budget (it costs +27 % here)
    paced = compensate(src, tmp_path / "paced.gcode", advance=AdvanceOptions(retract_ratio=0.0),
                       pace=PaceOptions(time_budget=None))
    b, a0, a_pull, a1 = no_pull.before, no_pull.after, plain.after, paced.after
    print(f"\nthin transitions: window peak {b.peak_overextrusion_window:.3f} -> "
          f"{a0.peak_overextrusion_window:.3f} (advance, E > 0) -> "
          f"{a_pull.peak_overextrusion_window:.3f} (advance pulling back) -> "
          f"{a1.peak_overextrusion_window:.3f} (pace + advance, E > 0); RMS "
          f"{b.rms_flow_error:.4f} -> {a0.rms_flow_error:.4f} -> {a_pull.rms_flow_error:.4f} "
          f"-> {a1.rms_flow_error:.4f}; time {paced.time_before_s:.2f} -> "
          f"{paced.time_after_s:.2f} s (paced), {plain.time_after_s:.2f} s (pulling back)")
    assert "pace" in paced.transformations and paced.paced_moves
    assert paced.pace_time_cost_s > 0
    s = paced.as_dict()
    cost = s["pace_time_cost_s"]
    assert s["paced_moves"] == len(paced.paced_moves) and isinstance(cost, float) and cost > 0
    assert b.peak_overextrusion_window > 1.0  # the problem is there: > +100 %
    # measured: windowed peak +33 % (advance, E > 0) -> -1.6 % (paced: no window
    # over-extrudes), RMS 0.051 -> 0.022 (2.3x); asserted with margin
    assert a0.peak_overextrusion_window > 0.2
    assert a1.peak_overextrusion_window * 4.0 <= a0.peak_overextrusion_window
    assert a1.rms_flow_error * 1.5 <= a0.rms_flow_error
    # pulling back while slowing down (measured -2.3 %, RMS 0.025, 0.4 % print time)
    # takes it out without the pacing's time
    assert a_pull.peak_overextrusion_window * 4.0 <= a0.peak_overextrusion_window
    assert a_pull.rms_flow_error * 1.5 <= a0.rms_flow_error
    assert plain.time_after_s < paced.time_after_s
    assert any(p.pull_pieces > 0 for p in plain.advance)
    for r in (paced, plain):
        assert r.commanded_e_after_mm == pytest.approx(r.commanded_e_before_mm, rel=1e-9)


def test_pace_off_is_byte_identical(example: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.gcode"
    report = compensate(example, out, pace=False)
    assert out.read_bytes() == example.read_bytes()
    assert report.paced_moves == () and report.pace_time_cost_s == 0.0
    assert report.as_dict()["pace"] is None


@pytest.mark.parametrize(("name", "value"), [("margin", 1.0), ("min_drop", 1.0),
                                             ("step_ratio", 1.0), ("max_slowdown", 0.0),
                                             ("adjust_mm", float("nan"))])
def test_bad_options_name_the_field(name: str, value: float) -> None:
    with pytest.raises(ProfileError, match=name):
        PaceOptions(**{name: value})  # type: ignore[arg-type]


def test_a_run_start_is_paced_from_the_state_the_column_carries(tmp_path: Path) -> None:
    """ideaMaker's purge line ends into a blob on the Z move (a row that extrudes without
    printing: the flow does not stop there), and the retraction holds the blob's pressure
    over the travel into the skirt. Pacing the purge line's end as a stop and the skirt's
    start as a rise from a relaxed column made the skirt's first window +55.6 % (+35 %
    without pacing). With the column's state (column.carried_flows) neither is paced; the
    same start without the blob is (the test can fail both ways)."""
    paced_lines = {}
    for blob in (3.0, 0.0):
        src = tmp_path / f"purge{blob:g}.gcode"
        purge_gcode(src, blob_e=blob)
        draft, sim, _ = _draft(src)
        _paced, report = _pace(draft, sim, PaceOptions(), push=FIL_AREA * 2.5)
        lines = draft.table.moves["line"][report.paced_rows]  # type: ignore[attr-defined]
        paced_lines[blob] = set(lines.tolist())
        if blob:  # the blob row (line 14) extrudes on the Z move, no XY: not a run
            row = int(np.flatnonzero(draft.table.moves["line"] == 14)[0])
            assert sim.dynamics.moves["cmd_mm3"][row] > 6.0 and not printing_pieces(sim, draft)[row]
    assert 13 not in paced_lines[3.0] and 19 not in paced_lines[3.0]
    assert 13 in paced_lines[0.0] and 19 in paced_lines[0.0]


def test_pacing_does_not_slow_a_start_into_a_held_blob(tmp_path: Path) -> None:
    """The twin on the purge/blob/skirt start, paced alone: the skirt's first move gets
    the held blob (+88 %); a start slowed as if the column were relaxed dumps it over less
    path (ideamaker_5.1.4 line 63: +35 % -> +55.6 % with the advance). Paced from the
    column's real state, the skirt start is left as it is."""
    src = tmp_path / "purge.gcode"
    purge_gcode(src, blob_e=3.0)
    report = compensate(src, tmp_path / "paced.gcode", pace=True)
    table = simulate(src, pressure_advance=False).plan.table
    first = int(np.flatnonzero(table.moves["line"] == 19)[0])
    before, after = report.before.flow_error[first], report.after.flow_error[first]
    print(f"\nheld blob: skirt start {before:+.3f} -> {after:+.3f} (paced)")
    assert before > 0.5  # the held blob is there
    # same planned moves, same twin: equal to rounding (the E of line 19 is not touched)
    assert after <= before + 1e-3


def test_pulling_back_makes_the_falling_envelope_steeper(thin_gcode: Path, tmp_path: Path
                                                         ) -> None:
    """With the advance pulling back at up to r times the intent while the head slows, the
    outflow falls as d ln Q/dt >= -m(1 + r)/K: the paced speeds are never lower, and the
    paced file is faster to print; compensate passes the advance's retract_ratio."""
    draft, sim, _unit = _draft(thin_gcode)
    alone, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=0.0))
    pulled, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=4.0))
    t_alone = simulate_draft_time(alone, tmp_path / "alone.gcode")
    t_pulled = simulate_draft_time(pulled, tmp_path / "pulled.gcode")
    t0 = sim.plan.timeline.total_time_s
    assert t0 < t_pulled < t_alone
    with pytest.raises(ProfileError):
        PaceOptions(pull_ratio=-1.0)


def simulate_draft_time(draft: Draft, path: Path) -> float:
    """Planned print time of a draft's rendered file, s."""
    draft.render(path)
    return float(simulate(path, pressure_advance=False).plan.timeline.total_time_s)


def test_pacing_is_placed_only_where_allowed(thin_gcode: Path, tmp_path: Path) -> None:
    """``only``: a junction, run end or start outside it is not an anchor; allowing every
    piece is the pacing everywhere; allowing none paces nothing; allowing the pieces of one
    thin transition paces the walls before it and no other."""
    draft, sim, _unit = _draft(thin_gcode)
    opts = PaceOptions(rise=False, pull_ratio=0.0)
    everywhere, rep_all = _pace(draft, sim, opts)
    same, rep_same = _pace(draft, sim, opts, only=np.ones(len(draft), dtype=bool))
    assert np.array_equal(same.piece_feed_mm_min, everywhere.piece_feed_mm_min, equal_nan=True)
    assert np.array_equal(rep_same.paced_rows, rep_all.paced_rows)  # type: ignore[attr-defined]
    none, rep_none = _pace(draft, sim, opts, only=np.zeros(len(draft), dtype=bool))
    assert none is draft and rep_none.paced_rows.size == 0  # type: ignore[attr-defined]
    assert rep_none.drop_junctions == 0  # type: ignore[attr-defined]
    paced_all = set(rep_all.paced_rows.tolist())  # type: ignore[attr-defined]
    assert len(paced_all) >= 4  # the fixture has several transitions to pace
    # the first paced row's own piece and its neighbour only
    first = min(paced_all)
    one = np.isin(draft.row, [first, first + 1])
    _d, rep_one = _pace(draft, sim, opts, only=one)
    paced_one = set(rep_one.paced_rows.tolist())  # type: ignore[attr-defined]
    assert first in paced_one and paced_one < paced_all


def test_no_pull_pieces_are_paced_as_without_the_pull_back(thin_gcode: Path) -> None:
    """``no_pull``: where the pull-back was assumed and a spot remained, the envelope is the
    one without it (slower), elsewhere the pull-back's steeper one."""
    draft, sim, _unit = _draft(thin_gcode)
    pulled, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=4.0))
    plain, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=0.0))
    every = np.ones(len(draft), dtype=bool)
    off, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=4.0), no_pull=every)
    assert np.array_equal(off.piece_feed_mm_min, plain.piece_feed_mm_min, equal_nan=True)
    assert not np.array_equal(pulled.piece_feed_mm_min, plain.piece_feed_mm_min, equal_nan=True)
    none, _ = _pace(draft, sim, PaceOptions(rise=False, pull_ratio=4.0), no_pull=~every)
    assert np.array_equal(none.piece_feed_mm_min, pulled.piece_feed_mm_min, equal_nan=True)

