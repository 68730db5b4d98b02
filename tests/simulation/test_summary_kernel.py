"""The compiled whole-print totals against the numpy expressions they replace."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import _summary_kernel as sk


def test_totals_match_numpy() -> None:
    rng = np.random.default_rng(11)
    n = 20_000
    kinds = np.array([MoveKind.TRAVEL, MoveKind.EXTRUDE | MoveKind.XY, MoveKind.EXTRUDE,
                      MoveKind.RETRACT, MoveKind.EXTRUDE | MoveKind.XY | MoveKind.Z],
                     dtype=np.uint8)
    rec = np.zeros(n, dtype=[("kind", np.uint8), ("cmd", np.float64), ("out", np.float64),
                             ("stop", np.float64), ("fed", np.float64), ("slip", np.float64),
                             ("ooze", np.float64), ("force", np.float64),
                             ("grind", np.bool_), ("err", np.float64), ("wm", np.float64),
                             ("wn", np.float64), ("margin", np.float64), ("narrow", np.bool_)])
    rec["kind"] = rng.choice(kinds, n)
    rec["cmd"] = np.where(rng.uniform(size=n) < 0.9, rng.uniform(0, 2, n), 0.0)
    rec["out"] = rng.uniform(0, 2, n)
    rec["stop"] = rng.uniform(0, 0.1, n)
    rec["fed"] = rng.normal(1, 1, n)
    rec["slip"] = rng.uniform(0, 0.05, n)
    rec["ooze"] = rng.uniform(0, 0.01, n)
    rec["force"] = rng.uniform(0, 50, n)
    rec["grind"] = rng.uniform(size=n) < 0.05
    rec["err"] = rng.normal(0, 0.1, n)
    rec["wm"] = rng.uniform(0.3, 0.6, n)
    rec["wn"] = rng.uniform(0.3, 0.6, n)
    rec["margin"] = np.where(rng.uniform(size=n) < 0.1, np.inf, rng.uniform(-5, 40, n))
    rec["narrow"] = rng.uniform(size=n) < 0.1
    bits = int(MoveKind.EXTRUDE | MoveKind.XY)
    t = sk.print_totals(rec["kind"], bits, rec["cmd"], rec["out"], rec["stop"], rec["fed"],
                        rec["slip"], rec["ooze"], rec["force"], rec["grind"], rec["err"],
                        rec["wm"], rec["wn"], rec["margin"], rec["narrow"])
    ext = ((rec["kind"] & MoveKind.EXTRUDE) != 0) & ((rec["kind"] & MoveKind.XY) != 0) \
        & (rec["cmd"] > 0)
    mask = np.empty(n, np.bool_)
    sk.extruding_mask(rec["kind"], rec["cmd"], bits, mask)
    np.testing.assert_array_equal(mask, ext)
    g = rec["grind"].astype(np.int8)
    finite = rec["margin"][np.isfinite(rec["margin"])]
    w, e = rec["cmd"][ext], rec["err"][ext]
    # compensated sums vs numpy's pairwise ones: both within a few ulp of the exact sum
    rel = 1e-13
    assert t[sk.T_CMD] == pytest.approx(np.sum(rec["cmd"]), rel=rel)
    assert t[sk.T_DELIVERED] == pytest.approx(np.sum(rec["out"] + rec["stop"]), rel=rel)
    assert t[sk.T_EXT_OUT] == pytest.approx(np.sum(rec["out"][ext]), rel=rel)
    assert math.sqrt(t[sk.T_RMS_WEE] / t[sk.T_RMS_W]) == pytest.approx(
        np.sqrt(np.sum(w * e * e) / np.sum(w)), rel=rel)
    assert t[sk.T_OVER] == np.max(e, initial=0.0)
    assert t[sk.T_UNDER] == -np.min(e, initial=0.0)
    assert t[sk.T_WIDTH_DEV] == np.max(np.abs(rec["wm"] - rec["wn"])[ext], initial=0.0)
    assert t[sk.T_SLIP_LOSS] == pytest.approx(np.sum(rec["slip"]), rel=rel)
    assert t[sk.T_FED_FWD] == pytest.approx(np.sum(np.maximum(rec["fed"], 0.0)), rel=rel)
    assert t[sk.T_OOZE] == pytest.approx(np.sum(rec["ooze"]), rel=rel)
    assert t[sk.T_FORCE_MAX] == np.max(rec["force"])
    assert t[sk.T_MARGIN_MIN] == np.min(finite) and t[sk.T_MARGIN_N] == finite.size
    assert t[sk.T_GRIND_EVENTS] == np.count_nonzero(np.diff(np.concatenate(([0], g))) == 1)
    assert t[sk.T_GRIND_MOVES] == np.count_nonzero(g)
    assert t[sk.T_NARROW] == np.count_nonzero(rec["narrow"] & ext)
