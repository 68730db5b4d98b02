"""``postprocess`` streamed (bounded memory) against the in-memory path.

The size threshold is lowered (as ``tests/simulation/test_stream.py`` does for ``simulate``) so
that corpus files take the streamed path on their own: the G-code written must be the same
bytes as in memory, the sidecar the same times (the windowed plan's clock agrees with one
plan to ~1e-12 relative) and the same whole-print figures of the verdict; ``--fail-on``
still stops the export; what needs the whole file (compensation, the report) is refused.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

import flowtwin.planner.plan_stream
from flowtwin.cli.main import main
from flowtwin.errors import DataError
from flowtwin.postprocess import PostprocessOptions, postprocess

pytestmark = [pytest.mark.corpus]

KLIPPER_CFG = Path(__file__).resolve().parent.parent / "data" / "klipper" / "B.cfg"
#: Times: windows' clock offsets (1e-10 s on a 5000 s print); sums of per-move figures in
#: another order (the simulation test's tolerance).
REL = 1e-9


def _slicer_env(text: str, output: Path) -> dict[str, str]:
    """The variables PrusaSlicer sets (its embedded configuration as ``SLIC3R_*``)."""
    env = {"SLIC3R_" + m.group(1).upper(): m.group(2)
           for m in re.finditer(r"^; ([a-z_][a-z0-9_]*) = (.*)$", text, re.MULTILINE)}
    env["SLIC3R_PP_OUTPUT_NAME"] = str(output)
    return env


def _close(a: Any, b: Any, key: str = "") -> None:
    if isinstance(a, float) and isinstance(b, float):
        assert b == pytest.approx(a, rel=REL, abs=1e-9), key
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), key
        for k in a:
            _close(a[k], b[k], f"{key}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), key
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{key}[{i}]")
    else:
        assert a == b, key


#: (corpus file, Klipper config, slicer environment): Marlin with M73 already there
#: (PrusaSlicer), Marlin with M73 added per layer (Cura), PrusaSlicer's silent mode from
#: the environment, Klipper from a printer.cfg
CASES = [("prusaslicer_2.7.1_benchy", None, False), ("cura_5.9.1", None, False),
         ("prusaslicer_2.8.1_minicube_small", None, True),
         ("orcaslicer_2.3.0b2", KLIPPER_CFG, False)]


@pytest.mark.parametrize(("name", "cfg", "with_env"), CASES)
def test_streamed_postprocess_writes_the_same_file_and_times(
        corpus_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str,
        cfg: Path | None, with_env: bool) -> None:
    text = (corpus_dir / f"{name}.gcode").read_text()
    runs = {}
    for mode in ("memory", "stream"):
        path = tmp_path / mode / f"{name}.gcode"
        path.parent.mkdir()
        path.write_text(text)
        env = _slicer_env(text, path) if with_env else {}
        if mode == "stream":   # chosen by size, as the CLI does
            monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 1024)
        res = postprocess(path, PostprocessOptions(klipper_config=cfg), env=env)
        side = json.loads(res.sidecar.read_text())
        runs[mode] = (res, side, path.read_bytes())
    (mem, mside, mbytes), (st, sside, sbytes) = runs["memory"], runs["stream"]
    assert not mem.streamed and st.streamed and sside["streamed"] is True
    assert sbytes == mbytes and sbytes != text.encode()   # rewritten, identically
    assert sum(sside["times"]["rewritten"].values()) + sside["times"]["progress_added"] > 10
    _close(mside["times"], sside["times"], "times")
    if with_env:
        assert sside["times"]["silent_total_s"] is not None   # the silent mode was planned
    assert sside["melt_limit"] == mside["melt_limit"]
    # the verdict's whole-print figures are the in-memory verdict's
    mv, sv = mside["verdict"], sside["verdict"]
    assert sv["windowed"] is None and "not computed" in sv["not_computed"]
    assert "over" not in sv and "worst_over" not in sv   # no windowed place is invented
    for key in ("level", "grinding_moves", "grinding_events", "line", "layer"):
        assert sv["grinding"][key] == mv["grinding"][key], key
    for key in ("min_margin_n", "min_margin_share", "grip_n"):
        assert sv["grinding"][key] == pytest.approx(mv["grinding"][key], rel=REL), key
    for key in ("rms_flow_error", "volume_error", "mean_slip", "print_time_s"):
        assert sv[key] == pytest.approx(mv[key], rel=REL), key
    assert sv["ooze_mm3"] == pytest.approx(mv["ooze_mm3"], rel=REL, abs=1e-12)
    assert sv["narrow_beads"] == mv["narrow_beads"]
    assert any("not computed" in s.lower() for s in sside["verdict_text"])


def _cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main(args)
    return int(exc.value.code or 0), capsys.readouterr().err


def test_fail_on_grinding_stops_a_streamed_export(corpus_dir: Path, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # the default set-up grinds on this file (the in-memory verdict says "grinds" too)
    path = tmp_path / "orca.gcode"
    shutil.copy(corpus_dir / "orcaslicer_2.3.0b2.gcode", path)
    before = path.read_bytes()
    for key in [k for k in os.environ if k.startswith("SLIC3R_")]:
        monkeypatch.delenv(key)
    monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 1024)
    code, err = _cli(["postprocess", str(path), "--fail-on", "grinding"], capsys)
    assert code == 1
    assert "export stopped" in err and "grinds the filament" in err
    assert path.read_bytes() == before   # untouched
    side = json.loads((tmp_path / "orca.gcode.flowtwin.json").read_text())
    assert side["streamed"] and side["failed"] and not side["written"]
    # without --fail-on the same streamed run writes the file
    code, _err = _cli(["postprocess", str(path)], capsys)
    assert code == 0 and path.read_bytes() != before


def test_streamed_run_refuses_what_needs_the_whole_file(corpus_dir: Path, tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    path = tmp_path / "cura.gcode"
    shutil.copy(corpus_dir / "cura_5.9.1.gcode", path)
    before = path.read_bytes()
    with pytest.raises(DataError, match="--advance"):
        postprocess(path, PostprocessOptions(advance=True, stream=True), env={})
    monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 1024)
    code, err = _cli(["postprocess", str(path), "--report"], capsys)
    assert code != 0 and "--report" in err and "bounded memory" in err
    assert "Traceback" not in err
    assert path.read_bytes() == before
    # --no-stream keeps the in-memory path whatever the size
    code, _err = _cli(["postprocess", str(path), "--no-stream", "--json"], capsys)
    assert code == 0 and path.read_bytes() != before
