"""The report in a real browser (Debian's Chromium, headless, software WebGL, via Playwright).

Loads without console errors; the layer slider changes what is drawn; a click on a drawn
segment shows its G-code line; markup in G-code comments and feature names is shown as
text and never runs; the notebook representation renders the viewer in its frame; the
before/after report switches colours.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from flowtwin.compensation import compensate
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.moves import MoveKind
from flowtwin.report import write_comparison, write_report
from flowtwin.simulation import SimulationResult, simulate

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("browser")]

_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)


def _differing_share(a: bytes, b: bytes) -> float:
    """Share of pixels that differ visibly between two PNG screenshots."""
    x = np.asarray(Image.open(io.BytesIO(a)).convert("RGB"), dtype=np.int16)
    y = np.asarray(Image.open(io.BytesIO(b)).convert("RGB"), dtype=np.int16)
    assert x.shape == y.shape
    return float(np.mean(np.abs(x - y).sum(axis=2) > 30))


def _lit_share(png: bytes) -> float:
    """Share of canvas pixels that are not the viewer's background."""
    x = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)
    background = np.array([0x21, 0x24, 0x29])  # clear colour (0.13, 0.14, 0.16)
    return float(np.mean(np.abs(x - background).sum(axis=2) > 30))


def _top_view_layer(page: Any, layer: int) -> None:
    """Single layer ``layer`` from above, through the page's own controls."""
    page.uncheck("#ft-tilt")
    page.select_option("#ft-mode", "single")
    page.locator("#ft-layer").fill(str(layer + 1))
    page.click("#ft-fit")
    page.wait_for_function("FT.app.viewer.idle && !FT.app.viewer._pending", timeout=120_000)


def _click_move(page: Any, move: int) -> None:
    """A real mouse click on the middle of a drawn move (its screen position from the
    viewer's projection)."""
    xy = page.evaluate("""(m) => {
        const v = FT.app.viewer, d = FT.app.data, M = v._mvp();
        const a = m > 0 ? FT.pos(d, m - 1) : d.header.start, b = FT.pos(d, m);
        const p = [0, 1, 2].map(k => (a[k] + b[k]) / 2);
        const w = v.canvas.clientWidth, h = v.canvas.clientHeight;
        return [(M[0]*p[0] + M[4]*p[1] + M[8]*p[2] + M[12] + 1) / 2 * w,
                (1 - (M[1]*p[0] + M[5]*p[1] + M[9]*p[2] + M[13])) / 2 * h]; }""", move)
    canvas = page.locator("#ft-canvas")
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    assert 0 <= box["y"] + xy[1] < page.viewport_size["height"]
    page.mouse.click(box["x"] + xy[0], box["y"] + xy[1])
    page.wait_for_function("FT.app.viewer.idle && !FT.app.viewer._pending", timeout=120_000)


def _longest_printing_move(result: SimulationResult, layer: int) -> int:
    m = result.plan.table.moves
    x0 = np.concatenate(([result.plan.table.start_xyze[0]], m["x"][:-1]))
    y0 = np.concatenate(([result.plan.table.start_xyze[1]], m["y"][:-1]))
    length = np.hypot(m["x"] - x0, m["y"] - y0)
    sel = ((m["kind"].astype(int) & _PRINTING) == _PRINTING) & (m["layer"] == layer)
    return int(np.flatnonzero(sel)[np.argmax(length[sel])])


def test_demo_report_loads_slider_redraws_and_click_shows_the_line(
        open_page: Any, demo_result: SimulationResult, demo_gcode: Path,
        tmp_path: Path) -> None:
    out = write_report(demo_result, tmp_path / "report.html")
    p = open_page(out)
    page = p.page
    whole = p.pixels()
    assert _lit_share(whole) > 0.05          # the print is drawn
    _top_view_layer(page, 3)
    layer3 = p.pixels()
    page.locator("#ft-layer").fill(str(2 + 1))     # layer 2
    page.wait_for_timeout(300)
    layer2 = p.pixels()
    # layers 2 and 3 of the demo differ (the infill pattern alternates)
    assert _differing_share(layer3, layer2) > 0.01
    assert _differing_share(whole, layer3) > 0.05
    assert "moves in range" in page.inner_text("#ft-status")
    page.locator("#ft-layer").fill(str(3 + 1))
    page.wait_for_timeout(300)
    move = _longest_printing_move(demo_result, 3)
    line = int(demo_result.plan.table.moves["line"][move])
    _click_move(page, move)
    assert page.inner_text("#ft-details h3") == f"G-code line {line}"
    source = demo_gcode.read_text().splitlines()[line - 1]
    hit = page.inner_text("#ft-details pre .hit")
    assert hit.endswith(source.strip()) and hit.startswith(str(line))
    # the selected move is drawn highlighted: the picture changed where it is
    assert p.errors == []


def test_gcode_markup_is_text_and_nothing_runs(open_page: Any, tmp_path: Path) -> None:
    src = tmp_path / "plain.gcode"
    write_print(src, PrintSpec(layers=3))
    lines = src.read_text().splitlines()
    feature = "<img src=x onerror=window.__pwned=1>"
    comment = "<script>window.__pwned=2</script><img src=y onerror=\"window.__pwned=3\">"
    target = None
    for i, text in enumerate(lines):
        if text.startswith(";TYPE:External perimeter"):
            lines[i] = ";TYPE:" + feature
        elif target is None and i > 60 and re.match(r"G1 X[\d.]+ Y[\d.]+ E", text):
            lines[i] = text + " ; " + comment
            target = i + 1
    assert target is not None
    evil = tmp_path / "evil<b>.gcode"
    evil.write_text("\n".join(lines) + "\n")
    result = simulate(evil)
    out = write_report(result, tmp_path / "report.html")
    doc = out.read_text()
    assert "<script>window" not in doc and "<img" not in doc and "<b>.gcode" not in doc
    p = open_page(out)
    page = p.page
    move = int(np.searchsorted(result.plan.table.moves["line"], target))
    assert int(result.plan.table.moves["line"][move]) == target
    layer = int(result.plan.table.moves["layer"][move])
    _top_view_layer(page, layer)
    _click_move(page, move)
    assert page.inner_text("#ft-details h3") == f"G-code line {target}"
    assert comment in page.inner_text("#ft-details pre .hit")       # shown as text
    assert feature in page.inner_text("#ft-features")
    assert page.evaluate("window.__pwned") is None                  # nothing ran
    assert page.evaluate("document.querySelectorAll('img').length") == 0
    assert page.evaluate("document.scripts.length") == 6            # header, data, 4 assets
    assert p.errors == []


def test_notebook_repr_renders_the_viewer_in_its_frame(open_page: Any,
                                                       demo_result: SimulationResult) -> None:
    p = open_page("<!DOCTYPE html><html><body>" + demo_result._repr_html_() + "</body></html>",
                  ready=False)
    frame = p.page.frame_locator("iframe.flowtwin-report")
    frame.locator("body[data-ready='1']").wait_for(timeout=120_000)
    assert frame.locator("#ft-canvas").count() == 1
    assert "G-code" in frame.locator("#ft-details").inner_text()
    assert p.errors == []


def test_comparison_report_toggles_before_and_after(open_page: Any, demo_gcode: Path,
                                                    tmp_path: Path) -> None:
    report = compensate(demo_gcode, tmp_path / "comp.gcode", advance=True)
    out = write_comparison(report, tmp_path / "compare.html")
    assert report._repr_html_().startswith('<iframe class="flowtwin-report"')
    p = open_page(out)
    page = p.page
    _top_view_layer(page, 5)
    before = p.pixels()
    page.click("#ft-variants button[data-variant='1']")
    page.wait_for_timeout(300)
    after = p.pixels()
    assert _differing_share(before, after) > 0.002
    move = _longest_printing_move(report.original_result, 5)  # type: ignore[arg-type]
    _click_move(page, move)
    header = page.inner_text("#ft-details table.values tr:first-child")
    assert "before" in header and "after" in header
    assert p.errors == []


@pytest.mark.corpus
def test_benchy_report_within_budget_and_interactive(open_page: Any, corpus_dir: Path,
                                                     tmp_path: Path) -> None:
    result = simulate(corpus_dir / "prusaslicer_2.7.1_benchy.gcode")
    out = write_report(result, tmp_path / "benchy.html")
    assert out.stat().st_size <= 15_000_000
    p = open_page(out)
    page = p.page
    assert page.evaluate("FT.app.data.n") == len(result.plan.table)
    _top_view_layer(page, 30)
    a = p.pixels()
    page.locator("#ft-layer").fill(str(200 + 1))
    page.wait_for_timeout(500)
    assert _differing_share(a, p.pixels()) > 0.01
    assert p.errors == []


@pytest.mark.corpus
def test_spiral_vase_with_a_layer_per_move(open_page: Any, corpus_dir: Path,
                                           tmp_path: Path) -> None:
    # FullControl's ripple vase rises continuously: 14 k "layers" of one move each
    result = simulate(corpus_dir / "fullcontrol_ripple_vase.gcode")
    n_layers = int(result.plan.table.moves["layer"].max()) + 1
    assert n_layers > 10_000
    out = write_report(result, tmp_path / "vase.html")
    assert out.stat().st_size < 3_000_000       # per-layer rows travel as columns
    p = open_page(out)
    note = p.page.inner_text("#ft-layers-note")
    assert f"{n_layers:,}" in note
    assert p.page.locator("#ft-layers tr").count() == 1000 + 1   # header + the first rows
    assert p.errors == []
