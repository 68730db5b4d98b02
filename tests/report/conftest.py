"""Fixtures of the report tests: small prints simulated once, and a real headless Chromium.

The browser is Debian's ``chromium`` driven by Playwright for Python
(``browser_install.py`` installs both when missing; ``make test`` runs it first). Chromium
runs headless with software WebGL (SwiftShader), no sandbox (tests run as root), no
network services, and a fresh profile per launch.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.simulation import SimulationResult, simulate

HERE = Path(__file__).resolve().parent

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


@pytest.fixture(scope="session")
def demo_gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in example print (``flowtwin demo``'s)."""
    path = tmp_path_factory.mktemp("demo") / "demo.gcode"
    write_print(path, PrintSpec())
    return path


@pytest.fixture(scope="session")
def demo_result(demo_gcode: Path) -> SimulationResult:
    return simulate(demo_gcode)


@dataclass
class Page:
    """A loaded report page and what its scripts said."""

    page: Any
    errors: list[str] = field(default_factory=list)

    def pixels(self) -> bytes:
        """PNG screenshot of the toolpath canvas once its picture is complete."""
        self.page.wait_for_function("FT.app.viewer.idle && !FT.app.viewer._pending",
                                    timeout=120_000)
        return bytes(self.page.locator("#ft-canvas").screenshot())


@pytest.fixture(scope="session")
def chromium() -> Iterator[Any]:
    """A headless Debian Chromium under Playwright (installed when missing)."""
    proc = subprocess.run([sys.executable, str(HERE / "browser_install.py")],
                          capture_output=True, text=True, timeout=1800, check=False)
    if proc.returncode != 0:
        pytest.fail(f"installing the browser failed:\n{proc.stdout}\n{proc.stderr}")
    executable = proc.stdout.strip().splitlines()[-1]
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS,
                                     headless=True)
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def open_page(chromium: Any) -> Iterator[Any]:
    """``open_page(path_or_html)``: a new page at a file (or with that HTML), waited until the
    report's scripts are ready; console errors and page errors are collected."""
    contexts = []

    def _open(target: Path | str, *, ready: bool = True) -> Page:
        ctx = chromium.new_context(viewport={"width": 1400, "height": 1000})
        contexts.append(ctx)
        page = ctx.new_page()
        out = Page(page)
        page.on("console", lambda m: out.errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: out.errors.append(f"page error: {e}"))
        if isinstance(target, Path):
            page.goto(target.resolve().as_uri())
        else:
            page.set_content(target)
        if ready:
            page.wait_for_function("document.body.getAttribute('data-ready')", timeout=120_000)
            state = page.evaluate("document.body.getAttribute('data-ready')")
            assert state == "1", (state, out.errors)
        return out

    yield _open
    for ctx in contexts:
        ctx.close()
