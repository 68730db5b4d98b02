"""The pacing's print-time budget (``PaceOptions.time_budget``,
:mod:`flowtwin.compensation.budget`, :func:`flowtwin.compensation.spots.rank_spots`).

The bisection and the ranking are checked on known answers; the stage on walls joined by
thin transition moves generated here (``thin_transition_gcode``), where the pacing near
every spot costs +25 % of the print time: three transitions at 5 % of the walls'
cross-section (the advance alone leaves them +51 to +56 %) and three at 20 % (+13 %).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli.compensate import register
from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.compensation.budget import largest_fitting
from flowtwin.compensation.pace import DEFAULT_TIME_BUDGET, PaceOptions
from flowtwin.compensation.spots import count_spots, rank_spots
from flowtwin.errors import DataError, ProfileError
from flowtwin.postprocess import PostprocessOptions

from .conftest import thin_transition_gcode

#: transition cross-sections, share of the walls': thin (5 %) and mild (20 %) by turns
SHARES = (0.2, 0.05, 0.2, 0.05, 0.2, 0.05)
#: the advance with E above zero (no pull-back): it leaves every transition a spot
NO_PULL = AdvanceOptions(retract_ratio=0.0)


@pytest.fixture(scope="module")
def graded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("graded") / "graded.gcode"
    thin_transition_gcode(path, shares=SHARES)
    return path


def _transition_lines(path: Path) -> tuple[list[int], list[int]]:
    """File lines (1-based) of the thin and of the mild transition moves."""
    thin, mild = [], []
    fil = math.pi * 1.75 ** 2 / 4.0
    bead = 0.45 * 0.2 - 0.2 ** 2 * (1.0 - math.pi / 4.0)
    for no, text in enumerate(path.read_text().splitlines(), start=1):
        for share, into in ((0.05, thin), (0.2, mild)):
            if text.endswith(f"E{bead * share * 0.9 / fil:.5f} F3000"):
                into.append(no)
    return thin, mild


@pytest.mark.parametrize("threshold", [0, 1, 5, 6, 12, 99])
def test_bisection_finds_the_largest_count_that_fits(threshold: int) -> None:
    """``fits(n) = n ≤ t`` over 100 candidates (the 100th known not to fit): the answer is
    ``min(t, 99)`` after at most ⌈log2 100⌉ = 7 calls."""
    asked: list[int] = []

    def fits(n: int) -> bool:
        asked.append(n)
        return n <= threshold

    n, calls = largest_fitting(100, fits)
    assert n == min(threshold, 99)
    assert calls == len(asked) <= 7
    assert 0 not in asked and 100 not in asked  # both ends are the caller's


def test_bisection_returns_a_count_that_fits_when_not_monotonic() -> None:
    """Where the time is not monotonic in the count the answer still fits and the next
    count does not."""
    ok = {0, 1, 2, 3, 7, 8}
    n, _ = largest_fitting(10, lambda k: k in ok)
    assert n in ok and n + 1 not in ok
    assert largest_fitting(1, lambda _k: True) == (0, 0)
    with pytest.raises(DataError, match="count"):
        largest_fitting(0, lambda _k: True)


def test_spots_are_stretches_ranked_by_their_share_of_the_squared_error() -> None:
    """Rows 1, 2, 4 are one spot (row 3 is not scored: it does not part them), Σ V·e² =
    0.04 + 0.18 + 0.04 = 0.26; row 6 (−50 % of 0.5 mm³) 0.125; row 8 (+15 % of 10 mm³)
    0.225; row 10 (+11 % of 0.1 mm³) 0.00121."""
    err = np.array([0.0, 0.2, 0.3, 0.4, 0.2, 0.0, -0.5, 0.0, 0.15, 0.05, 0.11])
    vol = np.array([1.0, 1.0, 2.0, 0.0, 1.0, 1.0, 0.5, 1.0, 10.0, 1.0, 0.1])
    scored = vol > 0
    r = rank_spots(err, vol, scored, tolerance=0.1)
    assert r.count == 4
    assert r.rank.tolist() == [-1, 0, 0, -1, 0, -1, 2, -1, 1, -1, 3]
    assert r.weight == pytest.approx([0.26, 0.225, 0.125, 0.1 * 0.11 ** 2])
    assert np.flatnonzero(r.worst(2)).tolist() == [1, 2, 4, 8]
    bad = scored & (np.abs(err) > 0.1)
    assert count_spots(bad, scored, np.zeros(err.size, dtype=bool)) == (4, 0)
    assert count_spots(bad, scored, r.worst(1)) == (4, 1)
    # row 9 beyond the tolerance too: rows 8 to 10 are one spot
    err[9] = 0.3
    assert rank_spots(err, vol, scored, tolerance=0.1).count == 3
    with pytest.raises(DataError, match="tolerance"):
        rank_spots(err, vol, scored, tolerance=0.0)
    with pytest.raises(DataError, match="volume_mm3"):
        rank_spots(err, vol[:3], scored, tolerance=0.1)


def test_the_budget_holds_and_the_worst_spots_are_paced(graded: Path, tmp_path: Path) -> None:
    """Unbudgeted, the pacing near the six spots adds +25 % of the print time (measured
    +24.7 %); under a 20 % budget the two worst spots fit (+14.4 %), both thin
    transitions, and nothing is paced next to a mild one; the four left are reported."""
    free = compensate(graded, tmp_path / "free.gcode", advance=NO_PULL,
                      pace=PaceOptions(time_budget=None))
    capped = compensate(graded, tmp_path / "capped.gcode", advance=NO_PULL,
                        pace=PaceOptions(time_budget=0.2))
    t0 = free.time_before_s
    print(f"\ngraded transitions: pacing +{100 * free.pace_time_cost_s / t0:.1f} % "
          f"(every spot) -> +{100 * capped.pace_time_cost_s / t0:.1f} % (budget 20 %); RMS "
          f"{100 * free.after.rms_flow_error:.2f} / {100 * capped.after.rms_flow_error:.2f} %")
    assert free.pace_time_cost_s > 0.2 * t0  # the budget has work to do
    assert 0 < capped.pace_time_cost_s <= 0.2 * t0
    assert capped.pace is not None and free.pace is not None
    p = capped.pace
    assert p.time_budget == 0.2 and p.time_added_s == capped.pace_time_cost_s
    assert (p.spots, p.spots_paced, p.spots_over_budget) == (6, 2, 4)
    assert (free.pace.spots, free.pace.spots_paced, free.pace.spots_over_budget) == (6, 6, 0)
    thin, mild = _transition_lines(graded)
    assert len(thin) == 3 and len(mild) == 3
    # the walls before and after two of the thin transitions, none next to a mild one
    paced = set(capped.paced_moves)
    assert len(paced) == 4 and paced < set(free.paced_moves)
    next_to_thin = {n + d for n in thin for d in (-1, 1)}
    assert paced <= next_to_thin
    assert sum(1 for n in thin if {n - 1, n + 1} <= paced) == 2
    # the paced spots lower the error of their transitions: better than the advance alone
    alone = compensate(graded, tmp_path / "alone.gcode", advance=NO_PULL)
    assert capped.after.rms_flow_error < alone.after.rms_flow_error
    for r in (free, capped):
        assert r.commanded_e_after_mm == pytest.approx(r.commanded_e_before_mm, rel=1e-9)
    d = capped.as_dict()["pace"]
    assert isinstance(d, dict)
    assert d["time_budget"] == 0.2 and d["spots_over_budget"] == 4


def test_no_cap_is_the_unbudgeted_pacing_to_the_byte(graded: Path, tmp_path: Path) -> None:
    """``None``, ``inf`` and a budget that does not bind write the same file: the budget
    changes nothing until it is exceeded."""
    outs = []
    for k, budget in enumerate((None, math.inf, 10.0)):
        out = tmp_path / f"{k}.gcode"
        r = compensate(graded, out, advance=NO_PULL, pace=PaceOptions(time_budget=budget))
        assert r.pace is not None and r.pace.spots_over_budget == 0
        outs.append((out.read_bytes(), r.after.rms_flow_error, r.pace_time_cost_s))
    assert outs[0] == outs[1] == outs[2]
    assert PaceOptions().time_budget == DEFAULT_TIME_BUDGET == 0.10
    assert PostprocessOptions().pace_budget == DEFAULT_TIME_BUDGET


def test_a_budget_nothing_fits_leaves_the_file_as_it_is(graded: Path, tmp_path: Path) -> None:
    """Pacing alone (no advance) under a budget of 0: no spot fits, the file is copied
    byte for byte and every spot is reported as left by the budget."""
    out = tmp_path / "out.gcode"
    r = compensate(graded, out, pace=PaceOptions(time_budget=0.0))
    assert out.read_bytes() == graded.read_bytes()
    assert r.transformations == () and r.pace_time_cost_s == 0.0
    assert r.pace is not None and r.pace.spots > 0
    assert r.pace.spots_paced == 0 and r.pace.spots_over_budget == r.pace.spots


@pytest.mark.parametrize("value", [-0.1, float("nan"), "10 %", True])
def test_bad_budgets_name_the_field(value: object) -> None:
    with pytest.raises(ProfileError, match="time_budget"):
        PaceOptions(time_budget=value)  # type: ignore[arg-type]


def _app() -> typer.Typer:
    application = typer.Typer(pretty_exceptions_enable=False)
    register(application)
    return application


def test_cli_pace_budget_end_to_end(graded: Path, tmp_path: Path) -> None:
    """``--pace-budget 20`` is ``PaceOptions(time_budget=0.2)`` (the same file), the JSON
    carries the budget and the spots left, the text names them; ``inf`` is no cap; a
    negative budget is refused naming the option, and no file is written."""
    runner = CliRunner()
    out = tmp_path / "cli.gcode"
    ref = tmp_path / "api.gcode"
    # pacing alone: the spots are the original's own errors, every transition is one
    api = compensate(graded, ref, pace=PaceOptions(time_budget=0.2))
    args = ["compensate", str(graded), "-o", str(out), "--pace", "--pace-budget", "20"]
    res = runner.invoke(_app(), [*args, "--json"])
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    assert out.read_bytes() == ref.read_bytes()
    assert s["pace"] == api.as_dict()["pace"]
    assert s["pace"]["time_budget"] == 0.2 and s["pace"]["spots_over_budget"] > 0
    assert 0 < s["pace_time_cost_s"] <= 0.2 * s["time_before_s"]
    text = runner.invoke(_app(), args)
    assert text.exit_code == 0, text.output
    assert "spots paced" in text.output and "budget 20 % of the print time" in text.output
    res = runner.invoke(_app(), ["compensate", str(graded), "-o", str(out), "--advance",
                                 "--pace", "--pace-budget", "inf", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["pace"]["time_budget"] is None
    bad = tmp_path / "bad.gcode"
    res = runner.invoke(_app(), ["compensate", str(graded), "-o", str(bad), "--pace",
                                 "--pace-budget", "-5"])
    assert res.exit_code != 0
    assert "--pace-budget" in str(res.exception) and not bad.exists()


def test_postprocess_pace_budget_end_to_end(graded: Path, tmp_path: Path) -> None:
    """``flowtwin postprocess --pace --pace-budget 20``: the sidecar's compensation carries
    the budget and the spots left, the log line names them, the file is paced within it;
    a negative budget stops before the file is touched."""
    from flowtwin.cli.postprocess import register as register_postprocess

    application = typer.Typer(pretty_exceptions_enable=False)
    register_postprocess(application)  # the only command: invoked without its name
    runner = CliRunner()
    work = tmp_path / "pp.gcode"
    work.write_bytes(graded.read_bytes())
    res = runner.invoke(application, [str(work), "--pace", "--pace-budget",
                                      "20", "--json"])
    assert res.exit_code == 0, res.output
    c = json.loads(res.stdout)["compensation"]
    assert c["pace"]["time_budget"] == 0.2 and c["pace"]["spots_over_budget"] > 0
    assert 0 < c["pace_time_cost_s"] <= 0.2 * c["time_before_s"]
    assert "spots left: budget" in res.stderr
    again = tmp_path / "again.gcode"
    again.write_bytes(graded.read_bytes())
    res = runner.invoke(application, [str(again), "--pace", "--pace-budget",
                                      "-5"])
    assert res.exit_code != 0 and "--pace-budget" in str(res.exception)
    assert again.read_bytes() == graded.read_bytes()
