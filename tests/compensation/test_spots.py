"""Pacing near the spots (:mod:`flowtwin.compensation.spots`, ``PaceOptions.spots``).

The spot map is checked on arrays whose distances are known by hand; the stage on the
generated walls joined by thin transitions (``thin_gcode``), against the pacing everywhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.compensation.pace import PaceOptions
from flowtwin.compensation.spots import spot_pieces
from flowtwin.errors import DataError


def test_spots_reach_along_the_printed_path() -> None:
    """Ten 1 mm pieces, a 50 mm travel, ten more; the move of piece 13 is 20 % off."""
    length = np.array([1.0] * 10 + [50.0] + [1.0] * 10)
    printing = np.array([True] * 10 + [False] + [True] * 10)
    row = np.arange(21)
    err = np.zeros(21)
    err[13] = -0.2
    near = spot_pieces(err, row, length, printing, tolerance=0.1, reach_mm=2.5)
    # printed path: piece 13 spans 12..13 mm (the travel adds none); within 2.5 mm of it:
    # the pieces ending at 9.5 mm or later and starting at 15.5 mm or sooner
    assert np.flatnonzero(near).tolist() == [9, 10, 11, 12, 13, 14, 15, 16]
    assert not spot_pieces(err, row, length, printing, tolerance=0.25, reach_mm=2.5).any()
    # two pieces per move: move 6 (pieces 12, 13: 11..13 mm) is the spot; reach 0 keeps
    # the pieces that touch it (11 ends at 11 mm, 14 starts at 13 mm)
    by_two = np.zeros(11)
    by_two[6] = 0.2
    two = spot_pieces(by_two, np.arange(21) // 2, length, printing, tolerance=0.1,
                      reach_mm=0.0)
    assert np.flatnonzero(two).tolist() == [11, 12, 13, 14]


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"tolerance": 0.0}, "tolerance"), ({"reach_mm": -1.0}, "reach_mm"),
    ({"piece_row": np.array([0, 5])}, "piece_row"), ({"printing": np.ones(3, bool)}, "piece_row"),
])
def test_spot_map_errors_name_the_field(kwargs: dict[str, object], field: str) -> None:
    args: dict[str, object] = {"flow_error": np.zeros(3), "piece_row": np.array([0, 1]),
                               "length_mm": np.ones(2), "printing": np.ones(2, bool),
                               "tolerance": 0.1, "reach_mm": 1.0}
    args.update(kwargs)
    with pytest.raises(DataError) as err:
        spot_pieces(**args)  # type: ignore[arg-type]
    assert err.value.field == field


def test_spot_pacing_costs_only_where_the_advance_falls_short(thin_gcode: Path,
                                                                tmp_path: Path) -> None:
    """On the thin transitions: with E above zero (no pull-back) the advance alone leaves a
    windowed peak of +33 %, every transition is a spot, and the spots' pacing takes it out
    as the pacing everywhere does, for no more print time. With the advance pulling back
    (the default) the peak is gone already; what the spots' pacing keeps must lower the
    RMS flow error, and costs no more than the pacing everywhere without the pull-back."""
    no_pull = AdvanceOptions(retract_ratio=0.0)
    alone = compensate(thin_gcode, tmp_path / "alone.gcode", advance=no_pull)
    # every spot (the budget would keep one of the six: tests/compensation/test_budget.py)
    spots = compensate(thin_gcode, tmp_path / "spots.gcode", advance=no_pull,
                       pace=PaceOptions(time_budget=None))
    every = compensate(thin_gcode, tmp_path / "every.gcode", advance=no_pull,
                       pace=PaceOptions(spots=False, pull_ratio=0.0))
    a, s, e = alone.after, spots.after, every.after
    print(f"\nthin transitions, E > 0: window {a.peak_overextrusion_window:+.3f} (advance) "
          f"{s.peak_overextrusion_window:+.3f} (spots, +{spots.pace_time_cost_s:.2f} s) "
          f"{e.peak_overextrusion_window:+.3f} (everywhere, +{every.pace_time_cost_s:.2f} s)")
    assert a.peak_overextrusion_window > 0.2
    assert "pace" in spots.transformations and spots.paced_moves
    assert 0 < spots.pace_time_cost_s <= every.pace_time_cost_s
    assert s.peak_overextrusion_window * 4.0 <= a.peak_overextrusion_window
    assert s.rms_flow_error <= a.rms_flow_error
    pulled = compensate(thin_gcode, tmp_path / "pulled.gcode", advance=True)
    pulled_spots = compensate(thin_gcode, tmp_path / "pulled-spots.gcode", advance=True,
                              pace=True)
    assert pulled.after.peak_overextrusion_window < 0.05  # the pull-back takes the peak out
    assert pulled_spots.after.peak_overextrusion_window < 0.05
    if pulled_spots.paced_moves:
        assert pulled_spots.after.rms_flow_error < pulled.after.rms_flow_error
    else:
        assert ((tmp_path / "pulled-spots.gcode").read_bytes()
                == (tmp_path / "pulled.gcode").read_bytes())
    assert pulled_spots.pace_time_cost_s <= every.pace_time_cost_s + 1e-9


def test_without_an_advance_the_pacing_counts_on_no_pull_back(thin_gcode: Path,
                                                              tmp_path: Path) -> None:
    """``pull_ratio`` is capped by the advance's ``retract_ratio``: paced alone (no
    advance), the default ratio of 4 writes the file the ratio 0 writes."""
    four = tmp_path / "four.gcode"
    zero = tmp_path / "zero.gcode"
    compensate(thin_gcode, four, pace=PaceOptions(spots=False))
    compensate(thin_gcode, zero, pace=PaceOptions(spots=False, pull_ratio=0.0))
    assert four.read_bytes() == zero.read_bytes()
    pulled = tmp_path / "pulled.gcode"
    compensate(thin_gcode, pulled, advance=True, pace=PaceOptions(spots=False))
    assert pulled.read_bytes() != four.read_bytes()


def test_the_advance_resumes_from_the_pacings_trial(thin_gcode: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """The pacing judges each draft by one advance pass; the advance stage goes on from
    the kept draft's pass instead of computing it again: the same file either way."""
    import flowtwin.compensation.pipeline as pipeline

    no_pull = AdvanceOptions(retract_ratio=0.0)  # spots left: the pacing is applied
    resumed = compensate(thin_gcode, tmp_path / "resumed.gcode", advance=no_pull, pace=True)
    calls: list[object] = []
    stage = pipeline.advance_stage

    def afresh(*args: object, resume: object = None, **kwargs: object) -> object:
        calls.append(resume)
        return stage(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(pipeline, "advance_stage", afresh)
    fresh = compensate(thin_gcode, tmp_path / "fresh.gcode", advance=no_pull, pace=True)
    assert calls and calls[0] is not None  # the pacing offered its trial
    assert "pace" in resumed.transformations
    assert (tmp_path / "resumed.gcode").read_bytes() == (tmp_path / "fresh.gcode").read_bytes()
    assert resumed.advance == fresh.advance  # the same passes reported
