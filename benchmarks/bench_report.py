"""The HTML report: its size, the time to write it, and how the page behaves in a browser.

Prints (``--quick``: the built-in example and the Benchy only):

* the built-in example print (budget ≤ 3 MB);
* the PrusaSlicer 2.7.1 Benchy of the corpus, 180 k lines, 112 k moves (budget ≤ 15 MB) —
  also the largest corpus file;
* every other corpus file (size per move);
* a generated print of 2.1 M moves (``bench_reader.BIG_SPEC``; its layers repeat, so it
  deflates far better than a real print);
* a real 3.2 M-line print sliced here by Debian's ``prusa-slicer`` from an ``openscad``
  model (:data:`BIG_MODEL`: a 110 mm dome on a base with twelve holes, 0.12 mm layers,
  gyroid infill), when both programs are installed.

Per file: report bytes (and the share of the embedded G-code text), the Python time to
build and write it, and — when Debian's Chromium and Playwright are installed — in headless
Chromium with software WebGL (SwiftShader, no GPU): the time until the page is ready
(decode + build), the time to draw a frame of the whole print in 3D, of one layer from
above and of the whole print zoomed out (merged level of detail), and one pick (hover or
click). Software rendering is far slower than any GPU: these frame times are an upper
bound for a machine without one, not what a user with a graphics card sees.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from benchmarks import corpus_dir
from flowtwin.gcode.generator import write_print
from flowtwin.report import write_report
from flowtwin.simulation import simulate

HERE = Path(__file__).resolve().parent
CORPUS = corpus_dir()
BENCHY = "prusaslicer_2.7.1_benchy.gcode"
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
BIG_MODEL = """$fn=200;
difference(){ union(){ sphere(r=55); translate([0,0,-55]) cylinder(r=40,h=20); }
  for (a=[0:30:330]) rotate([0,0,a]) translate([35,0,0]) cylinder(r=6,h=200,center=true);
  translate([0,0,-100]) cube(200,center=true); }
"""
SLICE_ARGS = ["--layer-height", "0.12", "--fill-pattern", "gyroid", "--fill-density", "25%",
              "--perimeters", "3", "--nozzle-diameter", "0.4", "--filament-diameter", "1.75",
              "--center", "110,110"]

_FRAMES = """() => {
  const v = FT.app.viewer, gl = v.gl, out = {};
  const frame = () => { v.draw(true); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE,
                                                 new Uint8Array(4)); };
  const time = (setup) => { setup(); frame(); const t = performance.now(); frame();
                            return [performance.now() - t, v.drawn, v.lodUsed]; };
  const top = FT.app.data.nLayers - 1;
  out.whole_3d = time(() => { FT.app.setLayer(top, false); v.setTilt(true); v.fit(); });
  out.layer_top = time(() => {
    v.setTilt(false); FT.app.setLayer(Math.floor(top / 2), true); v.fitDrawn(); });
  out.whole_zoomed_out = time(() => {
    FT.app.setLayer(top, false); v.fit(); v.scale *= 0.15; });
  v.fit();
  const t = performance.now(); v.pick(v.canvas.clientWidth / 2, v.canvas.clientHeight / 2, 4);
  out.pick_ms = performance.now() - t;
  return out;
}"""


def _real_print(folder: Path) -> Path | None:
    """Slice :data:`BIG_MODEL` with prusa-slicer (``None`` when the tools are missing)."""
    if shutil.which("openscad") is None or shutil.which("prusa-slicer") is None:
        return None
    scad, stl, gcode = folder / "dome.scad", folder / "dome.stl", folder / "dome.gcode"
    scad.write_text(BIG_MODEL)
    subprocess.run(["openscad", "-o", str(stl), str(scad)], check=True, capture_output=True,
                   timeout=3600)
    subprocess.run(["prusa-slicer", "--export-gcode", *SLICE_ARGS, "-o", str(gcode),
                    str(stl)], check=True, capture_output=True, timeout=3600)
    return gcode


def _browser_figures(page_path: Path) -> dict[str, object] | None:
    if not CHROMIUM.exists():
        return None
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            t0 = time.perf_counter()
            page.goto(page_path.resolve().as_uri())
            page.wait_for_function("document.body.getAttribute('data-ready')", timeout=600_000)
            ready = time.perf_counter() - t0
            state = page.evaluate("document.body.getAttribute('data-ready')")
            if state != "1":
                raise RuntimeError(f"the report page did not start ({state}): "
                                   + page.inner_text("#ft-status"))
            out: dict[str, object] = {"ready_s": ready, **page.evaluate("FT.timing")}
            out.update(page.evaluate(_FRAMES))
            return out
        finally:
            browser.close()


def bench_file(path: Path, out_dir: Path, *, browser: bool = True) -> dict[str, object]:
    """Simulate ``path``, write its report, measure it."""
    result = simulate(path)
    t0 = time.perf_counter()
    page = write_report(result, out_dir / (path.stem + ".html"))
    build = time.perf_counter() - t0
    size = page.stat().st_size
    gcode_bytes = path.stat().st_size
    entry: dict[str, object] = {"moves": len(result.plan.table), "gcode_mb": gcode_bytes / 1e6,
                                "report_mb": size / 1e6,
                                "bytes_per_move": size / max(len(result.plan.table), 1),
                                "build_s": build}
    if browser:
        figures = _browser_figures(page)
        if figures is not None:
            entry["browser"] = figures
    page.unlink()
    print(f"{path.name:48s} {entry['moves']:>9,} moves {entry['report_mb']:7.2f} MB "
          f"({entry['bytes_per_move']:.1f} B/move) built in {build:.1f} s"
          + (f"; ready in {entry['browser']['ready_s']:.1f} s, frames (ms) "  # type: ignore[index]
             f"{_frames(entry['browser'])}" if "browser" in entry else ""))
    return entry


def _frames(b: object) -> str:
    assert isinstance(b, dict)
    return ", ".join(f"{k} {v[0]:.0f}" for k, v in b.items() if isinstance(v, list))


def run(quick: bool = False) -> dict[str, object]:
    from benchmarks.bench_reader import BIG_SPEC
    from flowtwin.gcode.generator import PrintSpec

    out: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        example = folder / "example.gcode"
        write_print(example, PrintSpec())
        files = [example, CORPUS / BENCHY]
        if not quick:
            files += sorted(p for p in CORPUS.glob("*.gcode") if p.name != BENCHY)
            big = folder / "big.gcode"
            write_print(big, BIG_SPEC)
            files.append(big)
            real = _real_print(folder)
            if real is not None:
                files.append(real)
        for path in files:
            if path.exists():
                out[path.name] = bench_file(path, folder,
                                            browser=path.parent != CORPUS or path.name == BENCHY)
    return out
