"""The lag model of the refinement: exact segments, exact gradient, same as the twin."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp
from scipy.optimize import lsq_linear

from flowtwin.compensation._qp_sparse import solve_box_qp
from flowtwin.compensation._refine_kernel import lag_gain, model_pass
from flowtwin.compensation.advance import eligible_rows
from flowtwin.compensation.original import read_original
from flowtwin.compensation.pieces import Pieces, split_rows
from flowtwin.compensation.refine import LagModel, RefineOptions, build_lag_model, refine_qp
from flowtwin.dynamics import ExtrusionParams, predict
from flowtwin.simulation import simulate


@pytest.mark.parametrize(("t", "k", "va", "vb"), [(0.03, 0.06, 0.0, 30.0),
                                                  (0.2, 0.05, 40.0, 40.0),
                                                  (1e-5, 0.1, 10.0, 12.0),
                                                  (0.01, 0.02, 50.0, 5.0)])
def test_segment_map_solves_the_lag_equation(t: float, k: float, va: float, vb: float) -> None:
    # dx/dt = c·v(τ) − x/K with v linear: (e, G) from x(0) = 1, c = 0 and x(0) = 0, c = 1
    e, g = lag_gain(t, k, va, vb)

    def rhs(tau: float, x: np.ndarray, c: float) -> np.ndarray:
        return c * (va + (vb - va) * tau / t) - x / k

    x_e = solve_ivp(rhs, (0, t), [1.0], args=(0.0,), rtol=1e-12, atol=1e-14).y[0, -1]
    x_g = solve_ivp(rhs, (0, t), [0.0], args=(1.0,), rtol=1e-12, atol=1e-14).y[0, -1]
    assert e == pytest.approx(x_e, rel=1e-9)
    assert g == pytest.approx(x_g, rel=1e-8, abs=1e-15)


def test_model_gradient_matches_finite_differences() -> None:
    rng = np.random.default_rng(3)
    n_seg, n_free, n_rows = 30, 12, 6
    seg_piece = np.sort(rng.integers(-1, n_free, n_seg))
    seg_row = np.where(seg_piece >= 0, seg_piece // 2, -1)
    first = np.zeros(n_seg, bool)
    last = np.zeros(n_seg, bool)
    for r in range(n_rows):
        idx = np.flatnonzero(seg_row == r)
        if idx.size:
            first[idx[0]] = last[idx[-1]] = True
    args = (seg_piece, rng.uniform(0, 2, n_seg), rng.uniform(0.1, 2, n_seg),
            rng.uniform(0.3, 0.99, n_seg), rng.uniform(0, 0.5, n_seg), rng.uniform(0, 0.2, n_seg),
            seg_row, first, last, rng.uniform(1, 3, n_rows), rng.uniform(0.5, 2, n_rows))
    c = rng.uniform(0.5, 2.0, n_free)
    out = np.zeros(n_rows)
    grad = np.zeros(n_free)
    f0 = model_pass(c, *args, out, grad)
    for p in range(n_free):
        h = 1e-6
        cp, cm = c.copy(), c.copy()
        cp[p] += h
        cm[p] -= h
        fd = (model_pass(cp, *args, out.copy(), np.zeros(n_free))
              - model_pass(cm, *args, out.copy(), np.zeros(n_free))) / (2 * h)
        assert grad[p] == pytest.approx(fd, rel=1e-6, abs=1e-9)
    assert f0 > 0


def test_model_equals_the_twin_without_slip(tmp_path: Path) -> None:
    """Travels without retraction (the state decays) and moves of all kinds of trapezoid."""
    path = tmp_path / "lines.gcode"
    lines = ["G21", "G90", "M83", "M104 S215", "G1 X10 Y10 F9000"]
    for k in range(6):
        y = 10 + 2 * k
        lines += [f"G1 X40 Y{y} E{0.9 + 0.1 * k:.4f} F{1500 + 600 * k}",
                  f"G1 X41 Y{y + 0.5} E0.02", f"G1 X10 Y{y + 2} F9000"]
    lines.append("G4 P500")
    path.write_text("\n".join(lines) + "\n")
    res = simulate(path, pressure_advance=False)
    p = res.parameters.params
    bare = ExtrusionParams.build(len(res.plan.table), lag_k_s=p.lag_k_s,
                                 compliance_mm_per_n=p.compliance_mm_per_n,
                                 filament_diameter_mm=float(np.sqrt(p.filament_area_mm2 * 4
                                                                    / np.pi)))
    twin = predict(res.plan.table, res.plan.timeline, bare).moves["out_mm3"]
    table, tl = res.plan.table, res.plan.timeline
    scanned = read_original(path, table)
    rows_e = scanned.row_e.astype(float)
    pieces = split_rows(tl, np.zeros(len(table), bool))
    elig = eligible_rows(table, scanned.row_e)
    length = pieces.row_length_mm
    ratio = np.where(length > 0, rows_e / np.where(length > 0, length, 1), 0)
    group = np.where(elig, np.cumsum(elig) - 1, -1)
    model = build_lag_model(pieces, tl, p.lag_k_s, elig, ratio, rows_e, group,
                            int(elig.sum()))
    out, _ = model.evaluate(ratio[elig], rows_e[elig])
    expected = twin[elig] / p.filament_area_mm2 / scanned.e_unit
    np.testing.assert_allclose(out, expected, rtol=1e-7)


def test_box_qp_equals_bounded_least_squares() -> None:
    rng = np.random.default_rng(11)
    a = rng.normal(size=(40, 25))
    b = rng.normal(size=40)
    lo = rng.uniform(-0.5, 0.0, 25)
    hi = lo + rng.uniform(0.05, 1.0, 25)
    hi[::5] = np.inf
    ref = lsq_linear(a, b, bounds=(lo, hi), tol=1e-12).x
    x, it, _ = solve_box_qp(sp.csc_matrix(a.T @ a), -a.T @ b, sp.identity(25, format="csr"),
                            np.zeros(25), lo, hi)
    np.testing.assert_allclose(x, ref, atol=1e-6)
    assert it < 60


def test_box_qp_with_a_bidiagonal_map() -> None:
    # bounds on differences (as on ratios over states): min ½|x − t|² s.t. 0.1 ≤ x_i − x_(i−1)
    n = 50
    rng = np.random.default_rng(5)
    target = np.cumsum(rng.normal(0.3, 1.0, n))
    c = sp.diags([np.ones(n), -np.ones(n - 1)], [0, -1], format="csr")
    x, _, _ = solve_box_qp(sp.identity(n, format="csc"), -target, c, np.zeros(n),
                           np.full(n, 0.1) - np.r_[0.0, np.zeros(n - 1)], np.full(n, np.inf))
    steps = np.diff(np.r_[0.0, x])
    assert np.all(steps >= 0.1 - 1e-6)
    # isotonic-type solution: no feasible move lowers the objective (KKT: spot check)
    f = 0.5 * np.sum((x - target) ** 2)
    for i in range(n):
        y = x.copy()
        y[i:] += 1e-4
        if np.all(np.diff(np.r_[0.0, y]) >= 0.1 - 1e-9):
            assert 0.5 * np.sum((y - target) ** 2) >= f - 1e-9


def _refine_problem(path: Path, lines: list[str], *, relieve: bool = False
                    ) -> tuple[LagModel, Pieces, np.ndarray, np.ndarray, np.ndarray,
                               np.ndarray]:
    """Write ``lines``, simulate them and build the refinement's problem: the lag model,
    the pieces (acceleration phases in 3), the free pieces, their ratios, the intent per
    printing move and the move of every free piece; ``relieve`` marks retractions as
    relieved holds (the next run starts relaxed)."""
    path.write_text("\n".join(lines) + "\n")
    res = simulate(path, pressure_advance=False)
    table, tl, p = res.plan.table, res.plan.timeline, res.parameters.params
    rows_e = read_original(path, table).row_e
    elig = eligible_rows(table, rows_e)
    pieces = split_rows(tl, elig, accel_pieces=3)
    free = elig[pieces.row]
    length = pieces.row_length_mm
    ratio = np.where(length > 0, rows_e / np.where(length > 0, length, 1), 0)
    group = np.where(elig, np.cumsum(elig) - 1, -1)
    model = build_lag_model(pieces, tl, p.lag_k_s, free, ratio[pieces.row],
                            rows_e.astype(float), group, int(elig.sum()),
                            travel_holds=rows_e < 0 if relieve else None)
    sel = np.flatnonzero(free)
    return model, pieces, sel, ratio[pieces.row[sel]], rows_e[elig].astype(float), \
        group[pieces.row[sel]]


def test_refinement_keeps_the_ratio_steps_within_the_firmware_jump(tmp_path: Path) -> None:
    """Without the step limit the optimum steps the ratio between pieces of a run (it
    wants less E in every deceleration); with it, no step between neighbouring pieces
    exceeds its limit (the planner would slow that junction down, see ``limits.py``)."""
    path = tmp_path / "lines.gcode"
    lines = ["G21", "G90", "M83", "M104 S215", "G1 X10 Y10 F9000"]
    for k in range(4):
        lines += [f"G1 X{40 + 5 * k} Y{10 + 2 * k} E{1.2 + 0.2 * k:.4f} F{3000 + 900 * k}"]
    model, pieces, sel, c0, intent, pg = _refine_problem(path, lines)
    start = c0 * pieces.length_mm[sel]
    opts = RefineOptions()
    e_free, _, _ = refine_qp(model, pieces, start, intent, pg, 0.05 * c0, 10.0 * c0, opts)
    step = np.abs(np.diff(e_free / pieces.length_mm[sel]))
    limit = 0.02 * float(np.mean(c0))  # 2 % of the ratio per junction
    assert np.max(step) > 3.0 * limit  # the unconstrained optimum steps (else no test)
    jump = np.full(sel.size, limit)
    jump[0] = np.inf  # the run's first piece: no neighbour in the run
    e_lim, _, _ = refine_qp(model, pieces, start, intent, pg, 0.05 * c0, 10.0 * c0, opts,
                         jump=jump)
    step = np.abs(np.diff(e_lim / pieces.length_mm[sel]))
    # interior point: feasible to its tolerance (1e-6 relative of the bounds' scale)
    assert np.max(step) <= limit * (1 + 1e-4)
    c = e_lim / pieces.length_mm[sel]
    assert np.all(c >= 0.05 * c0 * (1 - 1e-9)) and np.all(c <= 10.0 * c0 * (1 + 1e-9))


def test_precharge_feeds_a_short_first_move_after_a_relieved_travel(tmp_path: Path) -> None:
    """A run after a relieved retraction starts relaxed in the lag model; its first move
    is 0.06 mm long and must build its pressure from rest within the ratio box, so it
    under-extrudes. A pre-charge left by the push-back (``0 ≤ y ≤ y_max``) feeds it: the
    model's error of that move falls, ``y`` stays in its box, the QP's own outputs are
    the model's (``LagModel.evaluate`` with the pre-charge), and a zero bound gives the
    program without the variable, bit for bit."""
    path = tmp_path / "runs.gcode"
    lines = ["G21", "G90", "M83", "M104 S215", "G1 X10 Y10 F9000",
             "G1 X50 Y10 E1.6 F3600", "G1 E-0.8 F2100", "G1 X50 Y30 F9000",
             "G1 E0.8 F2100", "G1 X50.06 Y30 E0.0024 F3600", "G1 X90 Y30 E1.6"]
    # the retraction's push-back leaves the column relaxed
    model, pieces, sel, c0, intent, pg = _refine_problem(path, lines, relieve=True)
    start = c0 * pieces.length_mm[sel]
    opts = RefineOptions()
    lo, hi = 0.05 * c0, 3.0 * c0
    short_move = 1  # group of the 0.06 mm move (second printing move)
    first_var = np.array([int(np.flatnonzero(pg == short_move)[0])])
    e0, f0, y0 = refine_qp(model, pieces, start, intent, pg, lo, hi, opts)
    assert y0.shape == (0,)
    out0, _ = model.evaluate(e0 / pieces.length_mm[sel], intent)
    err0 = out0[short_move] / intent[short_move] - 1
    assert err0 < -0.3  # from rest it cannot (else no test)
    # the bound: the compression the first run ends with (what the hold would keep)
    states = model.states(start / pieces.length_mm[sel])
    y_max = np.array([float(states[np.flatnonzero(model.seg_piece == first_var[0] - 1)[-1]])])
    assert y_max[0] > 0
    e1, f1, y1 = refine_qp(model, pieces, start, intent, pg, lo, hi, opts,
                           precharge=(first_var, y_max))
    assert 0.0 < y1[0] <= y_max[0] * (1 + 1e-6)
    out1, _ = model.evaluate(e1 / pieces.length_mm[sel], intent, (first_var, y1))
    err1 = out1[short_move] / intent[short_move] - 1
    assert abs(err1) < 0.5 * abs(err0)
    assert f1["flow_after"] < f0["flow_after"]
    # the QP's objective is the model's: recompute it from evaluate + the track terms
    w = 1 / intent + opts.peak_weight * np.mean(intent) / intent ** 2
    track = opts.track_weight * (e1 - start) ** 2 / intent[pg]
    obj = 0.5 * np.sum(w * (out1 - intent) ** 2) + 0.5 * np.sum(track) \
        + 0.5 * opts.track_weight * y1[0] ** 2 / intent[short_move]
    # c is clipped to the box after the solve: agreement to the solver's tolerance
    assert 2 * obj / np.sum(intent) == pytest.approx(f1["flow_after"], rel=1e-5)
    e2, _f2, y2 = refine_qp(model, pieces, start, intent, pg, lo, hi, opts,
                           precharge=(first_var, np.zeros(1)))
    assert np.array_equal(e2, e0) and y2[0] == 0.0


def test_the_program_solved_part_by_part_is_the_whole_program(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The refinement assembles and solves its program part by part, cut between runs
    the program does not join (``Chain.cuts``): the pieces' E, the pre-charges and the
    figures are those of the program solved whole, to the bit, with pre-charges, ratio
    steps and pieces that pull back in play; and with the state cap's second round (on
    this made-up problem the capped solve ends without a finite solution for some
    pieces, whole or in parts alike, which ``advance_pass`` refuses)."""
    from flowtwin.compensation import program

    path = tmp_path / "runs.gcode"
    lines = ["G21", "G90", "M83", "M104 S215", "G1 X10 Y10 F9000"]
    for k in range(6):  # runs between relieved retractions, each with a short first move
        y = 10 + 8 * k
        lines += [f"G1 X10 Y{y} F9000", "G1 E0.8 F2100",
                  f"G1 X10.06 Y{y} E0.0024 F3600",
                  f"G1 X{40 + 3 * k} Y{y} E{1.2 + 0.1 * k:.4f} F{3000 + 600 * k}",
                  f"G1 X{60 + 3 * k} Y{y + 2} E{0.6 + 0.05 * k:.4f} F1200",
                  "G1 E-0.8 F2100"]
    model, pieces, sel, c0, intent, pg = _refine_problem(path, lines, relieve=True)
    start = c0 * pieces.length_mm[sel]
    lo = 0.05 * c0
    lo[1::7] = -2.0 * c0[1::7]  # some pieces may pull back
    hi = 3.0 * c0
    jump = np.full(sel.size, 0.3 * float(np.mean(c0)))
    firsts = np.flatnonzero(np.r_[True, pg[1:] != pg[:-1]])
    jump[firsts[::2]] = np.inf
    states = model.states(start / pieces.length_mm[sel])
    first_var = firsts[1:]
    y_max = np.array([max(float(states[np.flatnonzero(model.seg_piece == v - 1)[-1]]), 1.0)
                      for v in first_var])
    opts = RefineOptions()

    def solve(cap: np.ndarray | None) -> tuple[np.ndarray, dict[str, float], np.ndarray]:
        return refine_qp(model, pieces, start, intent, pg, lo, hi, opts, state_max=cap,
                         jump=jump, precharge=(first_var, y_max))

    seen: list[int] = []
    parts = program.program_parts

    def counted(cuts: np.ndarray, n: int, size: int | None = None) -> list[tuple[int, int]]:
        out = parts(cuts, n, size)
        seen.append(len(out))
        return out

    monkeypatch.setattr("flowtwin.compensation.refine.program_parts", counted)
    cap = np.full(sel.size, 0.5 * float(np.max(states)))
    whole, whole_cap = solve(None), solve(cap)
    monkeypatch.setattr(program, "_PART_PIECES", 1)
    split, split_cap = solve(None), solve(cap)
    assert seen[:2] == [1, 1] and min(seen[2:]) >= 3  # (else no test)
    assert np.all(np.isfinite(whole[0])) and np.any(whole[2] > 0.5)
    assert np.array_equal(whole[0], split[0]) and np.array_equal(whole[2], split[2])
    assert whole[1] == split[1]
    assert whole_cap[1]["iterations"] > whole[1]["iterations"]  # the cap's round ran
    assert np.array_equal(whole_cap[0], split_cap[0], equal_nan=True)
    assert np.array_equal(whole_cap[2], split_cap[2], equal_nan=True)
