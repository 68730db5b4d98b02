"""Findings of ``make fuzz`` that only the command line reaches (the campaign runs the CLI on
a small sample of documents, so the regression corpus alone would rarely replay them)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from flowtwin.cli.main import main

FOUND = Path(__file__).parents[1] / "data" / "fuzz" / "gcode"


def test_simulate_of_a_file_without_printing_moves_skips_the_advance_fit(
        capsys: pytest.CaptureFixture[str]) -> None:
    """``G0 E1.46694 F3285`` alone: the verdict's pressure-advance fit had no printing move
    to fit and crashed (``min`` of an empty array); simulate now answers, tune refuses."""
    path = FOUND / "e-only-travel-no-printing-moves.gcode"
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(path), "--json"])
    assert exc.value.code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["moves"] == 1 and out["verdict"]["fit"] is None
    with pytest.raises(SystemExit) as exc:
        main(["tune", str(path)])
    assert exc.value.code == 2
    assert "no printing moves" in capsys.readouterr().err
