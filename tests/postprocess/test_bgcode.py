"""Prusa binary G-code through ``flowtwin postprocess``: written back as ``.bgcode``, valid
for an independent reader.

Oracle: PyPI ``pybgcode-jneilliii`` (a binding of Prusa's libbgcode; dev dependency). The
text original is the corpus' PrusaSlicer 2.8.1 file for an Original Prusa MK4S (Buddy
firmware), which carries normal and silent (stealth) mode machine limits and both
``M73 P R`` and ``M73 Q S`` progress lines.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pybgcode
import pytest

from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles.toml_io import profile_from_dict, save_profile

pytestmark = [pytest.mark.corpus]

MK4S = "prusaslicer_2.8.1_minicube_small"


def _convert(src: Path, dst: Path, to_binary: bool) -> None:
    i = pybgcode.open(str(src), "r" if to_binary else "rb")
    o = pybgcode.open(str(dst), "wb" if to_binary else "w")
    try:
        res = (pybgcode.from_ascii_to_binary(i, o, pybgcode.get_config()) if to_binary
               else pybgcode.from_binary_to_ascii(i, o, True))
    finally:
        pybgcode.close(i)
        pybgcode.close(o)
    assert res == pybgcode.EResult.Success, res


def _without_start_limits(text: str) -> str:
    """``text`` with the M201/M203/M204/M205 lines before the first G1 made comments."""
    out, moved = [], False
    for line in text.splitlines():
        moved = moved or line.startswith("G1 ")
        if not moved and re.match(r"M20[1345]\b", line):
            line = ";" + line
        out.append(line)
    return "\n".join(out) + "\n"


def _profile(data: dict[str, Any], path: Path) -> Path:
    save_profile(profile_from_dict({"kind": "printer", **data}), path)
    return path


def _progress_ok(text: str, plan_path: Path, profile: Path, letters: tuple[str, str],
                 pph: Any) -> int:
    """Check every ``M73 <P> <R>`` line against the plan with ``profile``; return how many."""
    plan = plan_gcode(plan_path, printer=profile)
    total = plan.timeline.total_time_s
    n = 0
    pat = re.compile(rf"M73 {letters[0]}(\d+) {letters[1]}(\d+)$")
    for number, line in enumerate(text.splitlines(), start=1):
        m = pat.match(line)
        if m:
            e = pph.elapsed_at(plan, number)
            assert (int(m.group(1)), int(m.group(2))) == (pph.percent(e, total),
                                                          int((total - e + 0.5) / 60)), line
            n += 1
    return n


def test_bgcode_in_bgcode_out_with_the_planners_times(flowtwin_exe: str, pph: Any,
                                                      tmp_path: Path) -> None:
    text_in = pph.corpus_copy(MK4S, tmp_path / "mk4s.gcode")
    bg = tmp_path / "mk4s.bgcode"
    _convert(text_in, bg, to_binary=True)
    header_before = bg.read_bytes()[:10]
    side = pph.flowtwin_json(flowtwin_exe, "postprocess", str(bg))
    data = bg.read_bytes()
    assert data[:10] == header_before          # GCDE, version, checksum type kept
    back = tmp_path / "back.gcode"
    _convert(bg, back, to_binary=False)        # the oracle reads every block back
    text = back.read_text()
    # the printer metadata block carries the new figures (PrusaLink and the printer show
    # them), as do the print metadata block and the flowtwin line
    normal = _profile(side["printer"]["profile"], tmp_path / "normal.toml")
    silent = _profile(side["printer"]["silent_profile"], tmp_path / "silent.toml")
    plan = pph.flowtwin_json(flowtwin_exe, "plan", str(bg), "--profile", str(normal))
    # silent mode as PrusaSlicer estimates it: the file's M201-M205 before the first move
    # set the normal mode only, the silent limits stand
    stealth = tmp_path / "stealth.gcode"
    stealth.write_text(_without_start_limits(text))
    plan_s = pph.flowtwin_json(flowtwin_exe, "plan", str(stealth), "--profile", str(silent))
    total, total_s = float(plan["total_time_s"]), float(plan_s["total_time_s"])
    assert total_s > total * 1.001      # stealth mode is slower
    assert side["times"]["silent_total_s"] == pytest.approx(total_s, rel=0, abs=1e-9)
    assert text.count(f"; estimated printing time (normal mode) = {pph.dhms(total)}\n") == 2
    assert text.count(f"; estimated printing time (silent mode) = {pph.dhms(total_s)}\n") == 2
    assert "; postprocessed by flowtwin" in text and "Prusa (Buddy) planner" in text
    assert _progress_ok(text, back, normal, ("P", "R"), pph) > 50
    assert _progress_ok(text, stealth, silent, ("Q", "S"), pph) > 50
    # the same file processed as text gives the same G-code commands
    pph.flowtwin_json(flowtwin_exe, "postprocess", str(text_in))

    def commands(t: str) -> list[str]:
        return [ln.split(";")[0].strip() for ln in t.splitlines()
                if ln.split(";")[0].strip()]
    assert commands(text) == commands(text_in.read_text())
    assert json.loads((tmp_path / "mk4s.bgcode.flowtwin.json").read_text())["written"]


def test_the_embedded_block_from_comments_equals_the_readers(tmp_path: Path) -> None:
    """``postprocess`` takes the embedded configuration from the comments alone (one cheap
    pass) instead of reading the file twice: the same mapping as the reader's metadata, on
    every corpus file and on a ``.bgcode`` converted by the oracle (metadata blocks)."""
    from flowtwin.gcode.reader import read_gcode
    from flowtwin.postprocess.stream import slicer_config_streamed

    from .conftest import CORPUS, corpus_copy

    files = sorted(CORPUS.glob("*.gcode.gz"))
    binary = tmp_path / "mk4s.bgcode"
    _convert(corpus_copy(MK4S, tmp_path / "mk4s.gcode"), binary, to_binary=True)
    with_config = 0
    for f in (*files, binary):
        embedded = slicer_config_streamed(f)
        assert embedded == read_gcode(f).metadata.get("slicer_config"), f.name
        with_config += bool(embedded)
    assert with_config >= 14  # most slicers embed their settings
