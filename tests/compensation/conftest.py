"""Shared fixtures of the compensation tests: the built-in example print, in both E modes;
a compiled step checked against its numpy original through a whole compensation."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from decimal import Decimal
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import read_gcode

_E = re.compile(r"E(-?\d*\.?\d+)")


def to_absolute_e(text: str) -> str:
    """The same print with absolute E (``M82``), reset by ``G92 E0`` at every layer."""
    out = []
    e = Decimal(0)
    for line in text.splitlines():
        if line.startswith("M83"):
            out.append("M82 ; absolute E")
            continue
        if line.startswith(";LAYER_CHANGE"):
            out.append(line)
            out.append("G92 E0")
            e = Decimal(0)
            continue
        m = _E.search(line) if line[:2] in ("G1", "G0", "G2", "G3") else None
        if m:
            e += Decimal(m.group(1))
            line = line[:m.start(1)] + f"{e:.5f}" + line[m.end(1):]
        out.append(line)
    return "\n".join(out) + "\n"


def _commanded_e(path: Path) -> float:
    mv = read_gcode(path).moves
    return float(np.sum(mv["de"][(mv["kind"] & MoveKind.FW_RETRACT) == 0]))


@pytest.fixture(scope="session")
def commanded_e() -> Callable[[Path], float]:
    """Total E a G-code file writes (firmware retractions excluded), mm."""
    return _commanded_e


@pytest.fixture(scope="session")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in example print (2 layers: small and fast), relative E."""
    path = tmp_path_factory.mktemp("example") / "example.gcode"
    write_print(path, PrintSpec(layers=2))
    return path


@pytest.fixture(scope="session")
def example_abs(tmp_path_factory: pytest.TempPathFactory, example: Path) -> Path:
    """The same print with absolute E."""
    path = tmp_path_factory.mktemp("example_abs") / "example_abs.gcode"
    path.write_text(to_absolute_e(example.read_text()))
    return path


def thin_transition_gcode(path: Path, *, loops: int = 6, feed: float = 3000.0,
                          shares: tuple[float, ...] | None = None) -> None:
    """Straight full-speed walls joined by 0.9 mm thin transition moves at 6 % of their
    cross-section (Cura 2.3.1 line 22638 in small), back and forth on one layer
    (``shares``: the cross-section of every transition instead, one per loop)."""
    fil = math.pi * 1.75 ** 2 / 4.0
    bead = 0.45 * 0.2 - 0.2 ** 2 * (1.0 - math.pi / 4.0)  # slicer bead [001 Eq. 7], mm²

    def line(x: float, y: float, length: float, share: float) -> str:
        return f"G1 X{x:.3f} Y{y:.3f} E{bead * share * length / fil:.5f} F{feed:g}"

    lines = ["G21", "G90", "M83", "M104 S215", "M109 S215", "G28", "G92 E0",
             ";LAYER_CHANGE", ";Z:0.2", ";HEIGHT:0.2", "G1 Z0.2 F600", "G1 X60 Y60 F9000"]
    x, y = 60.0, 60.0
    shares = (0.06,) * loops if shares is None else shares
    for k, share in enumerate(shares):
        d = 1.0 if k % 2 == 0 else -1.0
        x += d * 20.0
        lines.append(line(x, y, 20.0, 1.0))
        y += 0.9
        lines.append(line(x, y, 0.9, share))
    x += 20.0 if len(shares) % 2 == 0 else -20.0
    lines.append(line(x, y, 20.0, 1.0))
    lines += ["G1 E-0.8 F2100", "G1 X10 Y10 F9000", "M104 S0"]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="session")
def thin_gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Full-speed walls joined by thin transition moves (:func:`thin_transition_gcode`)."""
    path = tmp_path_factory.mktemp("thin") / "thin.gcode"
    thin_transition_gcode(path)
    return path


#: The corpus print whose compensation passes the kernel checks run through.
CHECK_PRINT = "prusaslicer_2.8.1_minicube_small.gcode"


def sizes_through_compensation(monkeypatch: pytest.MonkeyPatch, module: ModuleType, name: str,
                               assert_same: Callable[[tuple[Any, ...]], object],
                               corpus_dir: Path, tmp_path: Path) -> list[int]:
    """Compensate :data:`CHECK_PRINT` (advance and slip) with ``module.name`` checked by
    ``assert_same`` on every call's arguments; the first argument's size of each call."""
    from flowtwin.compensation import compensate

    kernel = getattr(module, name)
    sizes: list[int] = []

    def checked(*args: Any) -> Any:
        assert_same(args)
        sizes.append(int(args[0].size))
        return kernel(*args)

    monkeypatch.setattr(module, name, checked)
    compensate(corpus_dir / CHECK_PRINT, tmp_path / CHECK_PRINT, advance=True, slip=True)
    return sizes
