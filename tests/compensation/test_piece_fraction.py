"""The smoothed law's pieces near speed changes: finer on Klipper by default."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.errors import ProfileError

from .test_relief_along import CUP, _combing


def test_klipper_gets_the_finer_pieces_by_default(tmp_path: Path) -> None:
    # on Klipper every junction is limited to icv/|Δratio|, and a later pass follows the
    # law in small steps only: the smoothed law's pieces near speed changes are cut to
    # 1/20 of the smoothing window there (1/4 elsewhere); an explicit value wins
    assert AdvanceOptions().piece_fraction("klipper") == 0.05
    assert AdvanceOptions().piece_fraction("marlin") == 0.25
    assert AdvanceOptions(piece_time_fraction=0.5).piece_fraction("klipper") == 0.5
    with pytest.raises(ProfileError, match="piece_time_fraction"):
        AdvanceOptions(piece_time_fraction=0.01)
    src = _combing(tmp_path / "comb.gcode")
    setup, cfg = CUP / "klipper-volcano.toml", CUP / "printer.cfg"
    out = {}
    for name, frac in (("auto", None), ("fine", 0.05), ("coarse", 0.25)):
        report = compensate(src, tmp_path / f"{name}.gcode", machine=setup,
                            klipper_config=cfg,
                            advance=AdvanceOptions(piece_time_fraction=frac))
        out[name] = ((tmp_path / f"{name}.gcode").read_bytes(), report.advance[0].pieces)
    assert out["auto"][0] == out["fine"][0] != out["coarse"][0]
    assert out["fine"][1] > out["coarse"][1]
    # on Marlin the default is the coarser cut
    marlin = compensate(src, tmp_path / "m.gcode", advance=AdvanceOptions())
    coarse = compensate(src, tmp_path / "mc.gcode",
                        advance=AdvanceOptions(piece_time_fraction=0.25))
    assert marlin.advance[0].pieces == coarse.advance[0].pieces
    assert (tmp_path / "m.gcode").read_bytes() == (tmp_path / "mc.gcode").read_bytes()
